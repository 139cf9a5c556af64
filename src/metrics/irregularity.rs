//! Irregularity I_i (docs/method.md §6): how far each center's whole
//! trajectory stays from every other's. The refinement ranks centers by it
//! (`refine::irregular`); the reports plot its curve.

use crate::math::Real;
use crate::model::Trajectories;
use rayon::prelude::*;

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
