//! Input volume the tracked centers do not reach: the mark of a part the
//! tracker lost (a fast, thin limb whose centers were pulled into the body
//! or onto another limb, while the captured limb stands empty). Not in the
//! paper, which reports no such failure.
//!
//! Every occupied voxel of a frame belongs to the Voronoi cell of its
//! nearest center, as in tracking. In the reference frame, where the
//! centers were placed (frame 0 unless the tracking chose another), each
//! cell's reach is the distance from its center to its farthest voxel. In
//! any other frame a voxel is *unreached* when it lies farther from its
//! cell's center than [`CoverageParams::reach`] times that cell's reach
//! there ("frame-0 reach" below): the cells of a
//! well-tracked part move with it and keep their size, but the cells that
//! cover a region the centers have left stretch across it. A lost limb
//! leaves a connected region of such voxels; stray ones (along a surface
//! that slid, on a capture's loose pieces) are scattered or small, so only
//! regions of at least [`CoverageParams::min_region`] cells' volume count as
//! lost.
//!
//! A lost part can also be covered by the wrong centers (the leg's centers
//! swapped with another leg's as they passed): no volume is left empty, but
//! the mesh that follows them is torn between the two. The fit of the
//! final mesh to the input shows that instead: [`fit_outliers`].
//!
//! Each cell's own reach rather than one typical cell radius: cells in a
//! thin part are stretched along it already in frame 0, so a common radius
//! would flag every thin part in every frame.

use crate::math::Real;
use crate::metrics::SequenceFit;
use crate::model::GridSpec;
use crate::model::Trajectories;
use crate::params::CoverageParams;
use crate::spatial::cells::{assign, carry_owners, CenterIndex, NO_OWNER};
use crate::voxel::VoxelSequence;
use rayon::prelude::*;

/// One frame's input volume that no tracked cell reaches.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameCoverage {
    /// Occupied voxels of the frame.
    pub occupied: usize,
    /// Voxels farther from their cell's center than the cell reaches.
    pub unreached: usize,
    /// Of those, the voxels in connected regions of at least
    /// `min_region` cells' volume: the volume counted as lost.
    pub lost: usize,
    /// `lost` / `occupied` (in JSON `lost_percent`, in percent as every
    /// share there).
    #[serde(rename = "lost_percent", serialize_with = "super::as_percent")]
    pub lost_share: Real,
    /// Voxels in the largest connected unreached region.
    pub largest_region: usize,
    /// The largest distance of a voxel from its cell's center over that
    /// cell's frame-0 reach (1 or a little more when every cell keeps its
    /// size).
    pub farthest: Real,
}

/// Every frame's [`FrameCoverage`] and the frames flagged.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Coverage {
    /// Per frame, what the cells left unreached.
    pub frames: Vec<FrameCoverage>,
    /// Frames whose `lost_share` is at least `params.min_share`, in order.
    pub flagged: Vec<usize>,
    /// Mean occupied voxels per cell in frame 0: the unit of `min_region`.
    pub cell_voxels: Real,
    /// The parameters measured with.
    pub params: CoverageParams,
}

impl Coverage {
    /// The flagged frames as runs of consecutive frames, (first, last).
    pub fn flagged_runs(&self) -> Vec<(usize, usize)> {
        runs(&self.flagged)
    }

    /// The largest lost share of any frame, and that frame (the first of
    /// equals); None without frames.
    pub fn worst(&self) -> Option<(usize, Real)> {
        self.frames
            .iter()
            .enumerate()
            .map(|(f, c)| (f, c.lost_share))
            .reduce(|a, b| if b.1 > a.1 { b } else { a })
    }
}

/// Sorted frame numbers as runs of consecutive ones, (first, last).
pub fn runs(frames: &[usize]) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &f in frames {
        match out.last_mut() {
            Some((_, last)) if *last + 1 == f => *last = f,
            _ => out.push((f, f)),
        }
    }
    out
}

/// Measures, in every frame of `seq`, the occupied volume that the cells of
/// the centers `traj` (tracked on `seq`, at least one center) do not reach.
/// The result does not depend on the thread count: ties between centers go to
/// the lower index, and regions are grown in voxel order.
pub fn coverage(
    traj: &Trajectories,
    seq: &VoxelSequence,
    params: &CoverageParams,
) -> crate::Result<Coverage> {
    params.validate()?;
    if traj.frames != seq.frames.len() {
        return Err(crate::Error::InvalidInput(format!(
            "{} frames of centers for {} frames of input",
            traj.frames,
            seq.frames.len()
        )));
    }
    let grid = &seq.grid;
    let n = traj.centers;
    // The reference frame, where the centers were placed: their cells there
    // are the volume they stand for.
    let r = traj.reference;
    let first = &seq.frames[r].indices();
    let cell_voxels = first.len() as Real / n.max(1) as Real;
    // Each cell's frame-0 reach; a cell empty in frame 0 (a center the
    // refinement moved off the volume) takes the typical cell radius.
    let (owners0, dist0) = nearest(grid, first, traj.frame(r), vec![NO_OWNER; first.len()]);
    let typical = 0.5 * (cell_voxels.max(1.0)).cbrt() * grid.voxel_size;
    let mut reach = vec![0.0 as Real; n];
    for (&o, &d) in owners0.iter().zip(&dist0) {
        reach[o as usize] = reach[o as usize].max(d);
    }
    // At least half a voxel: a one-voxel cell's reach is 0.
    let floor = 0.5 * grid.voxel_size;
    for r in &mut reach {
        *r = if *r > 0.0 {
            r.max(floor)
        } else {
            typical.max(floor)
        };
    }
    let min_region = params.min_region * cell_voxels;
    let frames: Vec<FrameCoverage> = (0..traj.frames)
        .into_par_iter()
        .map(|f| {
            let voxels = &seq.frames[f].indices();
            // The reference's owners are a good start for any frame's search.
            let hints = if f == r {
                owners0.clone()
            } else {
                carry_owners(first, &owners0, voxels)
            };
            let (owners, dist) = if f == r {
                (owners0.clone(), dist0.clone())
            } else {
                nearest(grid, voxels, traj.frame(f), hints)
            };
            frame_coverage(
                grid,
                voxels,
                &owners,
                &dist,
                &reach,
                params.reach,
                min_region,
            )
        })
        .collect();
    let flagged = frames
        .iter()
        .enumerate()
        .filter(|(_, c)| c.lost > 0 && c.lost_share >= params.min_share)
        .map(|(f, _)| f)
        .collect();
    Ok(Coverage {
        frames,
        flagged,
        cell_voxels,
        params: params.clone(),
    })
}

/// Every voxel's nearest center and its distance to it.
fn nearest(
    grid: &GridSpec,
    voxels: &[u32],
    centers: &[crate::math::Point3],
    hints: Vec<u32>,
) -> (Vec<u32>, Vec<Real>) {
    let mut owners = hints;
    assign(grid, voxels, &CenterIndex::new(centers), &mut owners, false);
    let dist = voxels
        .par_iter()
        .zip(&owners)
        .map(|(&v, &o)| (grid.voxel_center(v as usize) - centers[o as usize]).norm())
        .collect();
    (owners, dist)
}

fn frame_coverage(
    grid: &GridSpec,
    voxels: &[u32],
    owners: &[u32],
    dist: &[Real],
    reach: &[Real],
    factor: Real,
    min_region: Real,
) -> FrameCoverage {
    let mut farthest: Real = 0.0;
    // Sorted, as `voxels` is.
    let mut unreached = Vec::new();
    for ((&v, &o), &d) in voxels.iter().zip(owners).zip(dist) {
        let r = d / reach[o as usize];
        farthest = farthest.max(r);
        if r > factor {
            unreached.push(v);
        }
    }
    let regions = regions(grid, &unreached);
    let lost: usize = regions.iter().filter(|&&s| s as Real >= min_region).sum();
    FrameCoverage {
        occupied: voxels.len(),
        unreached: unreached.len(),
        lost,
        lost_share: if voxels.is_empty() {
            0.0
        } else {
            lost as Real / voxels.len() as Real
        },
        largest_region: regions.iter().copied().max().unwrap_or(0),
        farthest,
    }
}

/// Sizes of the 26-connected regions of `voxels` (sorted linear indices):
/// the diagonal neighbours join a thin part that crosses the grid at a slant.
fn regions(grid: &GridSpec, voxels: &[u32]) -> Vec<usize> {
    let mut seen = vec![false; voxels.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    let [nx, ny, nz] = grid.dims.map(|d| d as i64);
    for start in 0..voxels.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut size = 0;
        while let Some(k) = stack.pop() {
            size += 1;
            let [x, y, z] = grid.voxel_coords(voxels[k] as usize).map(|c| c as i64);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (a, b, c) = (x + dx, y + dy, z + dz);
                        if (dx, dy, dz) == (0, 0, 0)
                            || a < 0
                            || b < 0
                            || c < 0
                            || a >= nx
                            || b >= ny
                            || c >= nz
                        {
                            continue;
                        }
                        let index = grid.linear_index([a as usize, b as usize, c as usize]) as u32;
                        if let Ok(j) = voxels.binary_search(&index) {
                            if !seen[j] {
                                seen[j] = true;
                                stack.push(j);
                            }
                        }
                    }
                }
            }
        }
        sizes.push(size);
    }
    sizes
}

/// Frames whose fit to the input is far worse than the sequence's usual.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FitOutliers {
    /// Per frame, the 95th percentile of the two-sided distance between the
    /// result and the input, in percent of the bounding-box diagonal.
    pub p95: Vec<Real>,
    /// The lower quartile of `p95` over the frames but those that are their
    /// input (the reference frames).
    pub usual: Real,
    /// max(`fit_ratio` × `usual`, `fit_floor`): frames above it are flagged.
    pub limit: Real,
    /// Frames whose `p95` is above `limit`, in order (never a reference
    /// frame).
    pub flagged: Vec<usize>,
}

/// Flags the frames of `fit` whose two-sided 95th percentile is above
/// max(`params.fit_ratio` × its lower quartile, `params.fit_floor`), both
/// over the frames but `exact`, those whose result is their input (the
/// frames a mesh was deformed from: frame 0 unless the tracking or the
/// segments chose others).
pub fn fit_outliers(
    fit: &SequenceFit,
    exact: &[usize],
    params: &CoverageParams,
) -> crate::Result<FitOutliers> {
    params.validate()?;
    let p95: Vec<Real> = fit.frames.iter().map(|f| f.two_sided.p95).collect();
    let mut later: Vec<Real> = p95
        .iter()
        .enumerate()
        .filter(|(f, _)| !exact.contains(f))
        .map(|(_, &v)| v)
        .filter(|v| v.is_finite())
        .collect();
    later.sort_by(Real::total_cmp);
    let usual = if later.is_empty() {
        0.0
    } else {
        later[(later.len() - 1) / 4]
    };
    let limit = (params.fit_ratio * usual).max(params.fit_floor);
    let flagged = p95
        .iter()
        .enumerate()
        .filter(|(f, _)| !exact.contains(f))
        .filter(|(_, &v)| v > limit)
        .map(|(f, _)| f)
        .collect();
    Ok(FitOutliers {
        p95,
        usual,
        limit,
        flagged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Point3;

    fn grid(n: usize) -> GridSpec {
        GridSpec {
            origin: Point3::origin(),
            voxel_size: 1.0,
            dims: [n, n, n],
        }
    }

    #[test]
    fn regions_join_diagonal_neighbours_only() {
        let g = grid(10);
        let mut v: Vec<u32> = [[1, 1, 1], [2, 2, 2], [3, 3, 2], [7, 7, 7], [7, 7, 9]]
            .iter()
            .map(|&c| g.linear_index(c) as u32)
            .collect();
        v.sort();
        let mut sizes = regions(&g, &v);
        sizes.sort();
        assert_eq!(sizes, vec![1, 1, 3]);
    }

    #[test]
    fn runs_group_consecutive_frames() {
        assert_eq!(runs(&[1, 2, 3, 7, 9, 10]), vec![(1, 3), (7, 7), (9, 10)]);
        assert!(runs(&[]).is_empty());
    }
}
