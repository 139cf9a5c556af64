//! Irregular centers (method.md §6): those whose whole trajectory stays
//! farthest from every other center's.

use crate::math::Real;

/// Indices of the `count` centers with the largest irregularity, largest
/// first (ties to the lower index).
pub fn most_irregular(irregularity: &[Real], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..irregularity.len()).collect();
    order.sort_by(|&a, &b| irregularity[b].total_cmp(&irregularity[a]).then(a.cmp(&b)));
    order.truncate(count);
    order
}
