//! Irregular centers (docs/method.md §6): those whose whole trajectory stays
//! farthest from every other center's.

use crate::math::Real;
use crate::model::Trajectories;
use rayon::prelude::*;

/// Indices of the `count` centers with the largest irregularity, largest
/// first (ties to the lower index).
pub fn most_irregular(irregularity: &[Real], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..irregularity.len()).collect();
    order.sort_by(|&a, &b| irregularity[b].total_cmp(&irregularity[a]).then(a.cmp(&b)));
    order.truncate(count);
    order
}

/// Each center's irregularity relative to its spacing: I_i over F times
/// the squared distance from c_i^0 to the nearest other center in frame 0.
/// About 1 for a center that keeps its distance to a neighbour (a rigid
/// part's, however sparse), far above for one that wanders off from all.
///
/// Why not I_i itself: it is the squared distance to the nearest other
/// trajectory, which is about F times the local spacing squared for every
/// center that moves with its neighbours, so where centers are sparse (a
/// thin limb one or two centers wide, an extremity) the whole part ranks as
/// the most irregular, and removing irregular centers removes the part.
pub fn relative_irregularity(traj: &Trajectories, irregularity: &[Real]) -> Vec<Real> {
    let first = traj.frame(0);
    let points: Vec<[Real; 3]> = first.iter().map(|p| [p.x, p.y, p.z]).collect();
    if points.len() < 2 {
        return irregularity.to_vec();
    }
    let tree = kiddo::ImmutableKdTree::<Real, 3>::new_from_slice(&points).expect("finite centers");
    let frames = traj.frames.max(1) as Real;
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            let near = tree
                .query(&points[i])
                .nearest_n::<kiddo::SquaredEuclidean<Real>>(
                    std::num::NonZeroUsize::new(2).expect("2 > 0"),
                )
                .execute();
            // The nearest other: the first found may be i itself, or another at the same place.
            let d2 = near
                .iter()
                .filter(|n| n.item as usize != i)
                .map(|n| n.distance)
                .fold(Real::INFINITY, Real::min);
            let d2 = if d2.is_finite() {
                d2
            } else {
                near.iter().map(|n| n.distance).fold(0.0, Real::max)
            };
            irregularity[i] / (frames * d2.max(Real::MIN_POSITIVE))
        })
        .collect()
}

/// Irregularity I_i = min over j ≠ i of Σ_f ‖c_i^f − c_j^f‖² (docs/method.md §6):
/// how far a center's whole trajectory is from its nearest other trajectory.
/// Infinite for a lone center.
///
/// Exact, without the N² F sum: Σ_f ‖a_f − b_f‖² ≥ F ‖ā − b̄‖² (the mean
/// trajectories), so the candidates are visited by that bound and the scan
/// stops once it exceeds the best sum found; each sum stops early too. The
/// result does not depend on the thread count (each I_i is one sequential
/// minimum over exact sums in frame order).
pub fn irregularity(traj: &Trajectories) -> Vec<Real> {
    let (frames, n) = (traj.frames, traj.centers);
    // Read in place (frame-major, strided), not copied center by center: a
    // long sequence's trajectories are not held twice.
    let point = |f: usize, i: usize| -> [Real; 3] {
        let p = traj.get(f, i);
        [p.x, p.y, p.z]
    };
    let means: Vec<[Real; 3]> = (0..n)
        .map(|i| {
            let s = (0..frames)
                .map(|f| point(f, i))
                .fold([0.0; 3], |s, q| [s[0] + q[0], s[1] + q[1], s[2] + q[2]]);
            s.map(|c| c / frames.max(1) as Real)
        })
        .collect();
    let squared =
        |a: &[Real; 3], b: &[Real; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<Real>();
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut order: Vec<(Real, usize)> = (0..n)
                .filter(|&j| j != i)
                .map(|j| (frames as Real * squared(&means[i], &means[j]), j))
                .collect();
            order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let mut best = Real::INFINITY;
            for (bound, j) in order {
                if bound >= best {
                    break;
                }
                let mut sum = 0.0;
                for f in 0..frames {
                    sum += squared(&point(f, i), &point(f, j));
                    if sum >= best {
                        break;
                    }
                }
                best = best.min(sum);
            }
            best
        })
        .collect()
}
