//! Volume that a cell holds only by stretching is claimed by starved cells.
//!
//! A thin part that moves several of its widths in a frame leaves its
//! centers behind: their Voronoi cells in the new frame are empty or nearly
//! (no voxel is nearest to them), while the cells of the few centers nearest
//! to where the part went stretch across it. The centroid term, which only
//! sees a center's own cell, has nothing to pull the stranded centers with,
//! and the stretched cells' centers cannot cover the part alone.
//!
//! Each volume element keeps about its volume from frame to frame (the
//! subject's volume is nearly conserved), so a cell far below its frame-0
//! share is starved, and the voxels a cell holds beyond its frame-0 reach
//! are loose. A starved center takes, as its data target, the centroid of
//! its own voxels and as many loose voxels as it lacks, those it would win
//! first if its cell grew as a power cell: the ones least nearer to their
//! owner than to it (|v − c_i|² − |v − c_owner|² smallest). It then moves
//! toward the part it lost, with its neighbours' rigid motion, until its
//! Voronoi cell holds voxels again and it is no longer starved.

use crate::math::{Point3, Real};
use crate::model::GridSpec;
use crate::spatial::cells::{Assignment, CellStats};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// A cell is starved below this share of its frame-0 voxels (scaled by the
/// frame's volume).
pub(crate) const STARVED: Real = 0.3;

/// A voxel is loose when it lies farther than this many times its cell's
/// frame-0 reach from the cell's center.
pub(crate) const LOOSE_REACH: Real = 1.5;

/// Each center's volume in frame 0: what it should keep.
#[derive(Clone, Debug)]
pub(crate) struct Capacity {
    /// Voxels of each cell in frame 0.
    count: Vec<Real>,
    /// Each cell's reach in frame 0: its farthest voxel from its center.
    reach: Vec<Real>,
    /// Occupied voxels of frame 0.
    total: Real,
}

impl Capacity {
    /// Of the centers `centers0` placed in `seq`'s frame `placed`, their
    /// cells assigned afresh.
    pub(crate) fn of_first_frame(
        seq: &crate::voxel::VoxelSequence,
        placed: usize,
        centers0: &[Point3],
    ) -> Self {
        use crate::spatial::cells::{assign, CenterIndex, NO_OWNER};
        let voxels0 = seq.frames[placed].indices();
        let mut owners = vec![NO_OWNER; voxels0.len()];
        assign(
            &seq.grid,
            &voxels0,
            &CenterIndex::new(centers0),
            &mut owners,
            false,
        );
        Capacity::new(&seq.grid, &voxels0, &owners, centers0)
    }

    /// From frame 0's voxels, their owners and the centers.
    pub(crate) fn new(grid: &GridSpec, voxels: &[u32], owners: &[u32], centers: &[Point3]) -> Self {
        let n = centers.len();
        let mut count = vec![0.0; n];
        let mut reach: Vec<Real> = vec![0.0; n];
        for (&v, &o) in voxels.iter().zip(owners) {
            let o = o as usize;
            count[o] += 1.0;
            reach[o] = reach[o].max((grid.voxel_center(v as usize) - centers[o]).norm());
        }
        // A one-voxel cell still reaches half a voxel.
        let floor = 0.5 * grid.voxel_size;
        reach.iter_mut().for_each(|r| *r = r.max(floor));
        Capacity {
            count,
            reach,
            total: voxels.len() as Real,
        }
    }

    /// The data targets of the starved centers of `cur` whose cells `cells`
    /// and `stats` hold: (center, centroid of its voxels and its claim); and
    /// how many voxels are loose.
    pub(crate) fn claims(
        &self,
        grid: &GridSpec,
        cells: &Assignment,
        cur: &[Point3],
        stats: &CellStats,
    ) -> (Vec<(usize, Point3)>, usize) {
        let Some(coords) = cells.voxel_coords() else {
            return (Vec::new(), 0);
        };
        let scale = coords.len() as Real / self.total;
        let starved: Vec<usize> = (0..cur.len())
            .filter(|&i| (stats.count[i] as Real) < STARVED * self.count[i] * scale)
            .collect();
        let at = |c: &[u16; 3]| grid.center_at(c.map(usize::from));
        // Loose voxels: (position, squared distance to their owner).
        let loose: Vec<(Point3, Real)> = coords
            .par_iter()
            .zip(&cells.owners)
            .filter_map(|(c, &o)| {
                let p = at(c);
                let d2 = (p - cur[o as usize]).norm_squared();
                let r = LOOSE_REACH * self.reach[o as usize];
                (d2 > r * r).then_some((p, d2))
            })
            .collect();
        if loose.is_empty() || starved.is_empty() {
            return (Vec::new(), loose.len());
        }
        let points: Vec<[Real; 3]> = loose.iter().map(|(p, _)| [p.x, p.y, p.z]).collect();
        let tree =
            ImmutableKdTree::<Real, 3>::new_from_slice(&points).expect("finite voxel positions");
        let claims = starved
            .par_iter()
            .map(|&i| {
                let want = (self.count[i] * scale).round() as usize;
                let lack = want.saturating_sub(stats.count[i] as usize).max(1);
                let c = cur[i];
                let k = (4 * lack).clamp(1, loose.len());
                let found = tree
                    .query(&[c.x, c.y, c.z])
                    .nearest_n::<SquaredEuclidean<Real>>(
                        std::num::NonZeroUsize::new(k).expect("k > 0"),
                    )
                    .execute();
                let mut by_excess: Vec<(Real, usize)> = found
                    .iter()
                    .map(|nb| (nb.distance - loose[nb.item as usize].1, nb.item as usize))
                    .collect();
                by_excess.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                by_excess.truncate(lack);
                let own = stats.count[i] as Real;
                let mut sum = match stats.centroid(i, grid) {
                    Some(x) => x.coords * own,
                    None => nalgebra::Vector3::zeros(),
                };
                for &(_, j) in &by_excess {
                    sum += loose[j].0.coords;
                }
                (i, Point3::from(sum / (own + by_excess.len() as Real)))
            })
            .collect();
        (claims, loose.len())
    }
}
