//! What the unit tests share: a small deterministic generator (the tests
//! need no rand crate). The integration tests under `tests/` have their own.

use crate::math::{Real, Rotation3, Vector3};
use crate::model::Rigid;

/// A linear congruential generator: the same numbers for the same seed.
pub(crate) struct Lcg(pub u64);

impl Lcg {
    /// Uniform in [0, 1).
    pub fn next(&mut self) -> Real {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as Real / (1u64 << 53) as Real
    }

    /// Each coordinate uniform in [-scale/2, scale/2).
    pub fn vec(&mut self, scale: Real) -> Vector3 {
        Vector3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * scale
    }

    /// A rotation by up to 3 radians about a random axis, and a translation
    /// within a box of 4.
    pub fn rigid(&mut self) -> Rigid {
        let rot = Rotation3::new(self.vec(1.0).normalize() * (self.next() * 3.0));
        Rigid {
            rotation: *rot.matrix(),
            translation: self.vec(4.0),
        }
    }
}
