//! Quality measures of a tracking result (method.md §6, §8), computed as the
//! reference computes them, and of the dynamic mesh against its input
//! ([`surface`]).

pub mod coverage;
pub mod fit;

pub use coverage::{coverage, fit_outliers, Coverage, FitOutliers, FrameCoverage};

pub use fit::{fit_to_input, surface_fit, DistanceSummary, FrameFit, SequenceFit, Surface};

use crate::math::Real;
use crate::model::Trajectories;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;

/// Eigenvalues below this fraction of the largest belong to M's null space.
const NULL_EIGENVALUE: Real = 1e-12;

/// PCA compactness (lower = simpler trajectories). M is the 3F × N matrix
/// with one column per center trajectory (rows x⁰ y⁰ z⁰ x¹ …), each row's
/// mean over the centers subtracted; with V the eigenvectors of M Mᵀ by
/// decreasing eigenvalue (k = 0 the largest) and C = Mᵀ V,
/// S_k = Σ_j |C_jk| and PCAC = Σ_k k S_k / Σ_k S_k.
///
/// When there are fewer centers than rows the N × N Gram matrix Mᵀ M = U Λ Uᵀ
/// is diagonalised instead: Mᵀ v_k = √λ_k u_k, the same coefficients up to
/// each column's sign, which |·| discards. 0 when nothing moves apart.
pub fn pcac(traj: &Trajectories) -> Real {
    let (rows, n) = (3 * traj.frames, traj.centers);
    if rows == 0 || n == 0 {
        return 0.0;
    }
    let mut m = DMatrix::<Real>::zeros(rows, n);
    for f in 0..traj.frames {
        for axis in 0..3 {
            let r = 3 * f + axis;
            let mean = (0..n).map(|i| traj.get(f, i)[axis]).sum::<Real>() / n as Real;
            for i in 0..n {
                m[(r, i)] = traj.get(f, i)[axis] - mean;
            }
        }
    }
    // Columns of `coefficients` are C's columns (one per component), in
    // decreasing order of eigenvalue.
    let (eigenvalues, coefficients) = if n < rows {
        let eig = SymmetricEigen::new(m.tr_mul(&m));
        let c = DMatrix::from_fn(n, n, |j, k| eig.eigenvalues[k].max(0.0).sqrt() * eig.eigenvectors[(j, k)]);
        (eig.eigenvalues, c)
    } else {
        let eig = SymmetricEigen::new(&m * m.transpose());
        (eig.eigenvalues.clone(), m.tr_mul(&eig.eigenvectors))
    };
    let mut order: Vec<usize> = (0..eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eigenvalues[b].total_cmp(&eigenvalues[a]));
    // Components of the null space have C = 0 exactly; computed, they carry
    // rounding noise (amplified by √λ on the Gram route), which the weights k
    // would count. Below 1e-12 of the largest eigenvalue is that noise.
    let largest = order.first().map_or(0.0, |&k| eigenvalues[k]);
    let s: Vec<Real> = order
        .iter()
        .map(|&k| if eigenvalues[k] > NULL_EIGENVALUE * largest { coefficients.column(k).iter().map(|c| c.abs()).sum() } else { 0.0 })
        .collect();
    let total: Real = s.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    s.iter().enumerate().map(|(k, s)| k as Real * s).sum::<Real>() / total
}

/// Deviation from uniformity: per frame, the population standard deviation
/// of the cells' occupied-voxel counts over their mean; returns the mean over
/// frames and the per-frame values. A frame with no voxels counts 0.
pub fn dfu(counts: &[Vec<u32>]) -> (Real, Vec<Real>) {
    let per_frame: Vec<Real> = counts
        .iter()
        .map(|n| {
            if n.is_empty() {
                return 0.0;
            }
            let len = n.len() as Real;
            let mean = n.iter().map(|&c| c as Real).sum::<Real>() / len;
            if mean == 0.0 {
                return 0.0;
            }
            let var = n.iter().map(|&c| (c as Real - mean).powi(2)).sum::<Real>() / len;
            var.sqrt() / mean
        })
        .collect();
    let mean = if per_frame.is_empty() { 0.0 } else { per_frame.iter().sum::<Real>() / per_frame.len() as Real };
    (mean, per_frame)
}

/// Irregularity I_i = min over j ≠ i of Σ_f ‖c_i^f − c_j^f‖² (method.md §6):
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
    // Center-major copy, so each trajectory is contiguous.
    let paths: Vec<Vec<[Real; 3]>> =
        (0..n).map(|i| traj.trajectory(i).map(|p| [p.x, p.y, p.z]).collect()).collect();
    let means: Vec<[Real; 3]> = paths
        .iter()
        .map(|p| {
            let s = p.iter().fold([0.0; 3], |s, q| [s[0] + q[0], s[1] + q[1], s[2] + q[2]]);
            s.map(|c| c / frames.max(1) as Real)
        })
        .collect();
    let squared = |a: &[Real; 3], b: &[Real; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<Real>();
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut order: Vec<(Real, usize)> =
                (0..n).filter(|&j| j != i).map(|j| (frames as Real * squared(&means[i], &means[j]), j)).collect();
            order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let mut best = Real::INFINITY;
            for (bound, j) in order {
                if bound >= best {
                    break;
                }
                let mut sum = 0.0;
                for (a, b) in paths[i].iter().zip(&paths[j]) {
                    sum += squared(a, b);
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

