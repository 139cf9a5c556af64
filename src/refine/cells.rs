//! Every frame's Voronoi cells at once, kept up to date as all trajectories
//! move (the global optimisation moves every frame in every step).

use crate::math::{Point3, Real};
use crate::spatial::cells::{Assignment, CellStats, CenterIndex, NO_OWNER};
use crate::model::Trajectories;
use crate::voxel::VoxelSequence;
use rayon::prelude::*;

pub struct SequenceCells<'a> {
    seq: &'a VoxelSequence,
    frames: Vec<Assignment>,
    /// Center positions each frame's assignment was last computed for.
    last: Vec<Vec<Point3>>,
}

impl<'a> SequenceCells<'a> {
    pub fn new(seq: &'a VoxelSequence) -> Self {
        let frames = seq.frames.iter().map(|o| Assignment::new(&seq.grid, &o.indices, vec![NO_OWNER; o.len()])).collect();
        SequenceCells { seq, frames, last: vec![Vec::new(); seq.frames.len()] }
    }

    /// Each frame's cell sums for the centers in `traj` (frames in parallel).
    pub fn update(&mut self, traj: &Trajectories, with_moments: bool) -> Vec<CellStats> {
        self.frames
            .par_iter_mut()
            .zip(self.last.par_iter_mut())
            .enumerate()
            .map(|(f, (cells, last))| {
                let now = traj.frame(f);
                // A change in the number of centers invalidates the bounds.
                if last.len() != now.len() {
                    *cells = Assignment::new(&self.seq.grid, &self.seq.frames[f].indices, vec![NO_OWNER; self.seq.frames[f].len()]);
                    last.clear();
                }
                let moved: Vec<Real> = last.iter().zip(now).map(|(a, b)| (a - b).norm()).collect();
                let stats = cells.update(&CenterIndex::new(now), &moved, with_moments);
                *last = now.to_vec();
                stats
            })
            .collect()
    }
}
