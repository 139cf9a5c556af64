//! Every frame's Voronoi cells, kept up to date as all trajectories move
//! (the global optimisation moves every frame in every step).
//!
//! A frame's assignment (owner and distance bounds of each voxel) lets the
//! next update re-examine only the voxels whose owner may have changed; it
//! costs about 18 bytes per occupied voxel (no runner-ups: see
//! [`Assignment::without_runner_ups`]). So that memory does not grow with
//! the sequence or the resolution, only the first
//! [`SequenceCells::cached_frames`] frames keep theirs, as many as a budget in
//! bytes holds and at most [`KEPT_CELL_FRAMES`]; the others are assigned
//! afresh at every update. Both give the same cells: the bounds only skip
//! voxels whose nearest center cannot have changed.

use crate::math::{Point3, Real};
use crate::model::Trajectories;
use crate::params::{KEPT_CELL_BYTES_PER_VOXEL, KEPT_CELL_FRAMES};
use crate::progress::Progress;
use crate::spatial::cells::{Assignment, CellStats, CenterIndex, NO_OWNER};
use crate::voxel::VoxelSequence;
use rayon::prelude::*;
use std::ops::Range;

/// Frames visited together by [`SequenceCells::update_frames`]'s callers:
/// only a block's cell sums (and what is derived from them) are held at once.
pub const FRAME_BLOCK: usize = 32;

/// `frames` cut into consecutive blocks of at most [`FRAME_BLOCK`] frames.
pub fn frame_blocks(frames: Range<usize>) -> impl Iterator<Item = Range<usize>> {
    let end = frames.end;
    frames
        .step_by(FRAME_BLOCK)
        .map(move |start| start..(start + FRAME_BLOCK).min(end))
}

/// Every frame's Voronoi cells of a [`VoxelSequence`], kept up to date as
/// the trajectories move; the first frames keep their assignments between
/// updates.
pub struct SequenceCells<'a> {
    seq: &'a VoxelSequence,
    /// The kept assignments (the first `cached_frames` frames), created on
    /// first use.
    frames: Vec<Option<Assignment>>,
    /// Center positions each kept assignment was last computed for.
    last: Vec<Vec<Point3>>,
    /// The center index of each kept assignment, carried from update to
    /// update: its candidate lists and bounds outlive small moves, and
    /// rebuilding them for every frame at every evaluation was most of the
    /// refinement's time.
    indices: Vec<Option<CenterIndex>>,
    /// Asked before each frame's update: once it asks to stop, updates
    /// skip their frames' work (see [`SequenceCells::cancelled`]).
    progress: Progress<'a>,
}

impl<'a> SequenceCells<'a> {
    /// Keeps the assignments of the first frames, as many as `budget`
    /// bytes hold ([`KEPT_CELL_BYTES_PER_VOXEL`] per occupied voxel) and at
    /// most [`KEPT_CELL_FRAMES`].
    pub fn new(seq: &'a VoxelSequence, budget: usize) -> Self {
        let mut used = 0usize;
        let kept = seq.frames[..seq.frames.len().min(KEPT_CELL_FRAMES)]
            .iter()
            .take_while(|f| {
                used = used.saturating_add(f.len().saturating_mul(KEPT_CELL_BYTES_PER_VOXEL));
                used <= budget
            })
            .count();
        Self::with_cache(seq, kept)
    }

    /// For one pass over the frames: keeps no assignment, since none would
    /// be used again (the cells are the same, and the kept frames' memory is
    /// not taken).
    pub fn single_pass(seq: &'a VoxelSequence) -> Self {
        Self::with_cache(seq, 0)
    }

    /// Keeps the assignments of the first `cached_frames` frames (0: none).
    pub fn with_cache(seq: &'a VoxelSequence, cached_frames: usize) -> Self {
        let kept = cached_frames.min(seq.frames.len());
        SequenceCells {
            seq,
            frames: (0..kept).map(|_| None).collect(),
            last: vec![Vec::new(); kept],
            indices: (0..kept).map(|_| None).collect(),
            progress: Progress::none(),
        }
    }

    /// These cells, whose updates stop doing their frames' work once
    /// `progress` asks to stop: a pass over a long sequence then ends within
    /// a frame's update. The sums such an update returns are not the cells';
    /// callers check [`cancelled`](Self::cancelled) after every update.
    pub fn stopping_with(mut self, progress: Progress<'a>) -> Self {
        self.progress = progress;
        self
    }

    /// Whether the updates were asked to stop.
    pub fn cancelled(&self) -> bool {
        self.progress.cancelled()
    }

    /// How many frames keep their assignment between updates.
    pub fn cached_frames(&self) -> usize {
        self.frames.len()
    }

    /// Drops the centers not in `keep` (their old indices, ascending, as
    /// [`Trajectories::remove_centers`] returns them) from the kept
    /// assignments, which keep their bounds for the others: after a batch of
    /// removals only the removed centers' voxels are searched afresh.
    pub fn keep_centers(&mut self, keep: &[usize]) {
        self.frames
            .par_iter_mut()
            .zip(self.last.par_iter_mut())
            .zip(self.indices.par_iter_mut())
            .for_each(|((cells, last), index)| {
                if let Some(cells) = cells.as_mut().filter(|_| !last.is_empty()) {
                    cells.keep_centers(keep, last.len());
                    *last = keep.iter().map(|&i| last[i]).collect();
                    // Its candidate lists name the old indices.
                    *index = None;
                }
            });
    }

    /// The cell sums of frames `range` (in parallel), the same as all
    /// frames at once give for them: a long sequence is visited a block of
    /// frames at a time, so that only a block's sums are held.
    /// `traj` holds the centers of frames `offset..`: its frame k is the
    /// sequence's frame `offset + k`.
    pub fn update_frames(
        &mut self,
        traj: &Trajectories,
        offset: usize,
        range: Range<usize>,
        with_moments: bool,
    ) -> Vec<CellStats> {
        let (seq, progress) = (self.seq, self.progress);
        let n = traj.centers;
        let skipped = || CellStats {
            count: vec![0; n],
            sum: vec![[0; 3]; n],
            second: with_moments.then(|| vec![[0; 6]; n]),
        };
        let fresh = |f: usize| {
            Assignment::new(
                &seq.grid,
                &seq.frames[f].indices(),
                vec![NO_OWNER; seq.frames[f].len()],
            )
            .without_runner_ups()
        };
        let kept = range.start.min(self.frames.len())..range.end.min(self.frames.len());
        let mut stats: Vec<CellStats> = self.frames[kept.clone()]
            .par_iter_mut()
            .zip(self.last[kept.clone()].par_iter_mut())
            .zip(self.indices[kept.clone()].par_iter_mut())
            .enumerate()
            .map(|(k, ((cells, last), index))| {
                if progress.cancelled() {
                    return skipped();
                }
                let now = traj.frame(kept.start + k - offset);
                // A change in the number of centers invalidates the bounds.
                if cells.is_none() || last.len() != now.len() {
                    *cells = Some(fresh(kept.start + k));
                    last.clear();
                    *index = None;
                }
                let moved: Vec<Real> = last.iter().zip(now).map(|(a, b)| (a - b).norm()).collect();
                let moved_index = match index.take() {
                    Some(carried) => carried.moved_to(now, &moved),
                    None => CenterIndex::new(now),
                };
                let stats =
                    cells
                        .as_mut()
                        .expect("just made")
                        .update(&moved_index, &moved, with_moments);
                *index = Some(moved_index);
                *last = now.to_vec();
                stats
            })
            .collect();
        let rest: Vec<CellStats> = (range.start.max(kept.end)..range.end)
            .into_par_iter()
            .map(|f| {
                if progress.cancelled() {
                    return skipped();
                }
                fresh(f).update(&CenterIndex::new(traj.frame(f - offset)), &[], with_moments)
            })
            .collect();
        stats.extend(rest);
        stats
    }
}
