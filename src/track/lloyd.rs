//! Frame 0: N distinct random occupied voxels, relaxed by over-relaxed Lloyd
//! iterations into an even cover (docs/method.md §2).

use crate::math::{Point3, Real};
use crate::model::rng::SplitMix64;
use crate::model::GridSpec;
use crate::spatial::cells::{Assignment, CenterIndex, NO_OWNER};

/// Centers after at most `iterations` Lloyd steps c += ω (x̄ - c) from a
/// seeded random choice of `n` distinct voxels (`n` <= voxels.len()),
/// stopping once no center moves farther than `threshold`. Returns the
/// centers and the number of steps taken; None once `stop` says so (it is
/// asked at every step: a step over a large frame takes seconds).
///
/// Why converge rather than stop at the reference's 100 steps: an unconverged
/// frame 0 keeps relaxing during tracking (each tracked frame moves centers
/// halfway to their centroids), which shows as drift from the true motion,
/// plainest on a rigid body, whose centers should not drift at all.
#[allow(clippy::too_many_arguments)]
pub(crate) fn seed_centers_until(
    grid: &GridSpec,
    voxels: &[u32],
    n: usize,
    seed: u64,
    iterations: usize,
    omega: Real,
    threshold: Real,
    stop: &dyn Fn() -> bool,
) -> Option<(Vec<Point3>, usize)> {
    assert!(n >= 1 && n <= voxels.len());
    // Partial Fisher-Yates over the voxel list.
    let mut rng = SplitMix64::new(seed);
    let mut order: Vec<u32> = voxels.to_vec();
    for k in 0..n {
        let r = k + rng.below(order.len() - k);
        order.swap(k, r);
    }
    let mut centers: Vec<Point3> = order[..n]
        .iter()
        .map(|&v| grid.voxel_center(v as usize))
        .collect();
    let mut cells = Assignment::new(grid, voxels, vec![NO_OWNER; voxels.len()]);
    let mut moved = Vec::new();
    let mut steps = 0;
    let mut index = CenterIndex::new(&centers);
    while steps < iterations {
        if stop() {
            return None;
        }
        steps += 1;
        if !moved.is_empty() {
            index = index.moved_to(&centers, &moved);
        }
        let stats = cells.update(&index, &moved, false);
        moved.clear();
        for (i, c) in centers.iter_mut().enumerate() {
            let step = stats
                .centroid(i, grid)
                .map_or(nalgebra::Vector3::zeros(), |x| (x - *c) * omega);
            *c += step;
            moved.push(step.norm());
        }
        if moved.iter().all(|&m| m < threshold) {
            break;
        }
    }
    Some((centers, steps))
}
