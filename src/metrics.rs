//! Quality measures of a tracking result (docs/method.md §6, §8), computed as the
//! reference computes them, and of the dynamic mesh against its input
//! ([`fit`]).

pub mod coverage;
pub mod fit;
mod irregularity;
pub mod lost;

pub use coverage::{coverage, fit_outliers, Coverage, FitOutliers, FrameCoverage};

pub use fit::{
    fit_to_input, surface_fit, DistanceSummary, FarRegion, FrameFit, SequenceFit, Surface,
};
pub use irregularity::irregularity;
pub use lost::{frame_runs, lost_parts, FrameLoss, LostPartWarning, LostParts};

use crate::math::Real;
use crate::model::Trajectories;
use nalgebra::{DMatrix, SymmetricEigen};

/// A share (a fraction) written in percent, as every share and distance in
/// the JSON the commands print.
fn as_percent<S: serde::Serializer>(share: &Real, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(100.0 * share)
}

/// PCAC, DFU and irregularity of one set of trajectories (docs/method.md §6, §8).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Quality {
    /// PCA compactness of the trajectories ([`pcac`]; lower is simpler).
    pub pcac: Real,
    /// Deviation from uniformity of the cells' volumes, mean over the frames
    /// ([`dfu`]; 0 when all cells hold the same number of voxels).
    pub dfu: Real,
    /// Deviation from uniformity per frame.
    pub dfu_per_frame: Vec<Real>,
    /// I_i per center, in the trajectories' order.
    pub irregularity: Vec<Real>,
}

impl Quality {
    /// The qualities of `traj`, whose cells held `counts` occupied voxels
    /// per frame (the tracker returns them for its final positions;
    /// `pipeline::measure` assigns them).
    pub fn of(traj: &Trajectories, counts: &[Vec<u32>]) -> Quality {
        let (dfu, dfu_per_frame) = dfu(counts);
        Quality {
            pcac: pcac(traj),
            dfu,
            dfu_per_frame,
            irregularity: irregularity(traj),
        }
    }

    /// The `k` largest I_i, largest first.
    pub fn largest_irregularity(&self, k: usize) -> Vec<Real> {
        let mut v = self.irregularity.clone();
        v.sort_by(|a, b| b.total_cmp(a));
        v.truncate(k);
        v
    }
}

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
        let c = DMatrix::from_fn(n, n, |j, k| {
            eig.eigenvalues[k].max(0.0).sqrt() * eig.eigenvectors[(j, k)]
        });
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
        .map(|&k| {
            if eigenvalues[k] > NULL_EIGENVALUE * largest {
                coefficients.column(k).iter().map(|c| c.abs()).sum()
            } else {
                0.0
            }
        })
        .collect();
    let total: Real = s.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    s.iter()
        .enumerate()
        .map(|(k, s)| k as Real * s)
        .sum::<Real>()
        / total
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
    let mean = if per_frame.is_empty() {
        0.0
    } else {
        per_frame.iter().sum::<Real>() / per_frame.len() as Real
    };
    (mean, per_frame)
}
