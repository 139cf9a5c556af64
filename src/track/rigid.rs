//! Weighted Kabsch: the rigid motion that best carries one set of weighted
//! points onto another (method.md §4).

use crate::math::{Matrix3, Point3, Real, Vector3};
use rayon::prelude::*;

/// x -> rotation · x + translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    pub rotation: Matrix3,
    pub translation: Vector3,
}

impl Rigid {
    pub fn identity() -> Self {
        Rigid { rotation: Matrix3::identity(), translation: Vector3::zeros() }
    }

    #[inline]
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.rotation * p.coords + self.translation)
    }

    pub fn inverse(&self) -> Rigid {
        let rt = self.rotation.transpose();
        Rigid { rotation: rt, translation: -(rt * self.translation) }
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Rigid) -> Rigid {
        Rigid { rotation: self.rotation * other.rotation, translation: self.rotation * other.translation + self.translation }
    }
}

/// argmin over rigid (R, t) of Σ w_j ||dst_j - (R src_j + t)||², over the
/// weighted index list `pairs` (closed form by SVD of the weighted
/// cross-covariance; a reflection is turned into the nearest rotation).
///
/// With too few or collinear points the rotation is under-determined; a small
/// pull towards the identity then picks the smallest rotation.
pub fn fit_rigid(src: &[Point3], dst: &[Point3], pairs: impl Iterator<Item = (usize, Real)> + Clone) -> Rigid {
    // One pass over the pairs (this is the tracker's inner loop): weighted
    // sums of p, q and p qᵀ, taken relative to the first pair so that the
    // covariance H = Σ w p qᵀ - W p̄ q̄ᵀ does not cancel digits away.
    let Some((j0, _)) = pairs.clone().next() else { return Rigid::identity() };
    let (p0, q0) = (src[j0].coords, dst[j0].coords);
    let mut wsum = 0.0;
    let mut ps = Vector3::zeros();
    let mut qs = Vector3::zeros();
    let mut pq = Matrix3::zeros();
    for (j, w) in pairs {
        let (p, q) = (src[j].coords - p0, dst[j].coords - q0);
        let wp = w * p;
        wsum += w;
        ps += wp;
        qs += w * q;
        pq += wp * q.transpose();
    }
    if !(wsum > 0.0) {
        return Rigid::identity();
    }
    let h = pq - ps * (qs / wsum).transpose();
    rigid_from_covariance(&h, &(p0 + ps / wsum), &(q0 + qs / wsum))
}

/// The rigid motion carrying the weighted mean `pm` to `qm` whose rotation
/// best aligns the weighted cross-covariance H = Σ w (p - pm)(q - qm)ᵀ.
fn rigid_from_covariance(h: &Matrix3, pm: &Vector3, qm: &Vector3) -> Rigid {
    let mut svd = h.svd(true, true);
    if svd.singular_values[1] <= 1e-10 * svd.singular_values[0] {
        // Rank <= 1 (collinear or too few points): the rotation about the line
        // is free; a small pull towards the identity picks the smallest one.
        let pull = 1e-6 * svd.singular_values[0] + Real::MIN_POSITIVE;
        svd = (h + Matrix3::identity() * pull).svd(true, true);
    }
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let rotation = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    Rigid { rotation, translation: qm - rotation * pm }
}

/// Many weighted rigid fits from one source set, each over its own weighted
/// list of points, repeated for destinations that change: the tracker fits
/// every center from frame f-1 to f in every iteration, with the sources
/// and the weights fixed for the frame.
///
/// What depends only on the sources and weights (Σ w, Σ w p) is summed once;
/// each [`RigidFits::fit`] sums Σ w q and Σ w p qᵀ from one per-point table
/// of q and p qᵀ, which is a third of [`fit_rigid`]'s arithmetic per pair
/// and reads one contiguous row per neighbour. Coordinates are taken
/// relative to the sets' means so that H = Σ w p qᵀ - Σ w p (Σ w q)ᵀ / Σ w
/// keeps its digits; tested against [`fit_rigid`].
pub struct RigidFits {
    /// Fit i's points are `points[start[i]..start[i + 1]]`, with `weights` alongside.
    start: Vec<usize>,
    points: Vec<u32>,
    weights: Vec<Real>,
    /// Sources relative to `src_shift`.
    src: Vec<Vector3>,
    src_shift: Vector3,
    /// Per fit: Σ w and Σ w p (relative).
    wsum: Vec<Real>,
    psum: Vec<Vector3>,
}

impl RigidFits {
    /// `lists(i)`: the weighted points of fit i, for i in 0..`fits`.
    pub fn new<I: Iterator<Item = (usize, Real)>>(src: &[Point3], fits: usize, lists: impl Fn(usize) -> I) -> Self {
        let src_shift = mean(src);
        let src: Vec<Vector3> = src.iter().map(|p| p.coords - src_shift).collect();
        let mut start = Vec::with_capacity(fits + 1);
        let (mut points, mut weights) = (Vec::new(), Vec::new());
        let (mut wsum, mut psum) = (Vec::with_capacity(fits), Vec::with_capacity(fits));
        start.push(0);
        for i in 0..fits {
            let (mut w_i, mut p_i) = (0.0, Vector3::zeros());
            for (j, w) in lists(i) {
                points.push(j as u32);
                weights.push(w);
                w_i += w;
                p_i += w * src[j];
            }
            start.push(points.len());
            wsum.push(w_i);
            psum.push(p_i);
        }
        RigidFits { start, points, weights, src, src_shift, wsum, psum }
    }

    /// Every fit's rigid motion from the sources to `dst`.
    pub fn fit(&self, dst: &[Point3]) -> Vec<Rigid> {
        assert_eq!(dst.len(), self.src.len());
        let dst_shift = mean(dst);
        // Per point: q, then p qᵀ column-major (nalgebra's order).
        let table: Vec<[Real; 12]> = self
            .src
            .iter()
            .zip(dst)
            .map(|(p, q)| {
                let q = q.coords - dst_shift;
                let pq = p * q.transpose();
                let mut row = [0.0; 12];
                row[..3].copy_from_slice(q.as_slice());
                row[3..].copy_from_slice(pq.as_slice());
                row
            })
            .collect();
        (0..self.wsum.len())
            .into_par_iter()
            .map(|i| {
                let (wsum, range) = (self.wsum[i], self.start[i]..self.start[i + 1]);
                // Also an empty list, whose weights sum to 0.
                if !(wsum > 0.0) {
                    return Rigid::identity();
                }
                let mut acc = [0.0; 12];
                for (&j, &w) in self.points[range.clone()].iter().zip(&self.weights[range]) {
                    let row = &table[j as usize];
                    for (a, r) in acc.iter_mut().zip(row) {
                        *a += w * r;
                    }
                }
                let qs = Vector3::new(acc[0], acc[1], acc[2]);
                let pq = Matrix3::from_column_slice(&acc[3..]);
                let ps = self.psum[i];
                let h = pq - ps * (qs / wsum).transpose();
                rigid_from_covariance(&h, &(self.src_shift + ps / wsum), &(dst_shift + qs / wsum))
            })
            .collect()
    }
}

fn mean(points: &[Point3]) -> Vector3 {
    points.iter().map(|p| p.coords).sum::<Vector3>() / points.len().max(1) as Real
}
