//! Dual quaternions for blending rigid motions (Kavan et al. 2008).

use crate::math::{Point3, Real, UnitQuaternion};
use crate::model::Rigid;
use nalgebra::{Quaternion, Rotation3, Vector3};

/// real + ε dual; a unit dual quaternion is a rigid motion.
#[derive(Clone, Copy, Debug)]
pub struct DualQuaternion {
    /// The rotation, a unit quaternion for a rigid motion.
    pub real: Quaternion<Real>,
    /// Half the translation times the rotation, `t · real / 2`.
    pub dual: Quaternion<Real>,
}

impl DualQuaternion {
    /// The unit dual quaternion of a rigid motion.
    pub fn from_rigid(m: &Rigid) -> Self {
        let rot = Rotation3::from_matrix_unchecked(m.rotation);
        let real = *UnitQuaternion::from_rotation_matrix(&rot).quaternion();
        let t = Quaternion::from_imag(m.translation);
        DualQuaternion {
            real,
            dual: t * real * 0.5,
        }
    }

    /// Weighted sum with every term on the real part's hemisphere of the
    /// heaviest one (q and -q are the same rotation), normalised.
    pub fn blend(terms: impl Iterator<Item = (DualQuaternion, Real)> + Clone) -> DualQuaternion {
        let pivot = terms
            .clone()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|t| t.0.real)
            .unwrap_or(Quaternion::identity());
        let mut real = Quaternion::new(0.0, 0.0, 0.0, 0.0);
        let mut dual = Quaternion::new(0.0, 0.0, 0.0, 0.0);
        for (q, w) in terms {
            let s = if q.real.dot(&pivot) < 0.0 { -w } else { w };
            real += q.real * s;
            dual += q.dual * s;
        }
        let norm = real.norm();
        if norm <= Real::MIN_POSITIVE {
            return DualQuaternion {
                real: Quaternion::identity(),
                dual: Quaternion::new(0.0, 0.0, 0.0, 0.0),
            };
        }
        DualQuaternion {
            real: real / norm,
            dual: dual / norm,
        }
    }

    /// Applies the (normalised) motion to a point.
    pub fn apply(&self, p: &Point3) -> Point3 {
        let r = UnitQuaternion::new_unchecked(self.real);
        // Translation: the vector part of 2 dual · conj(real).
        let t: Vector3<Real> = (self.dual * self.real.conjugate() * 2.0).imag();
        Point3::from(r * p.coords + t)
    }
}
