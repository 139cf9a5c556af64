//! Weighted Kabsch: the rigid motion that best carries one set of weighted
//! points onto another (method.md §4).

use crate::math::{Matrix3, Point3, Real, Vector3};

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
    let (pm, qm) = (p0 + ps / wsum, q0 + qs / wsum);
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
