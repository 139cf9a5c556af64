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
/// the squared distance from c_i^r to the nearest other center in the
/// reference frame r, where the centers were placed.
/// About 1 for a center that keeps its distance to a neighbour (a rigid
/// part's, however sparse), far above for one that wanders off from all.
///
/// Why not I_i itself: it is the squared distance to the nearest other
/// trajectory, which is about F times the local spacing squared for every
/// center that moves with its neighbours, so where centers are sparse (a
/// thin limb one or two centers wide, an extremity) the whole part ranks as
/// the most irregular, and removing irregular centers removes the part.
pub fn relative_irregularity(traj: &Trajectories, irregularity: &[Real]) -> Vec<Real> {
    let first = traj.frame(traj.reference);
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
