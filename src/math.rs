//! Scalar and geometry type aliases used throughout the crate (as in parry),
//! so precision is chosen in one place.

/// The scalar used for all geometry and tracking arithmetic.
///
/// f64: tracking accumulates rigid fits over hundreds of frames and the global
/// optimisation compares energies that differ in the 6th digit.
pub type Real = f64;
/// A position in space.
pub type Point3 = nalgebra::Point3<Real>;
/// A displacement or direction.
pub type Vector3 = nalgebra::Vector3<Real>;
/// A 3 × 3 matrix (rotations, covariances).
pub type Matrix3 = nalgebra::Matrix3<Real>;
/// A rotation as an orthonormal matrix.
pub type Rotation3 = nalgebra::Rotation3<Real>;
/// A rotation as a unit quaternion.
pub type UnitQuaternion = nalgebra::UnitQuaternion<Real>;
/// A rigid motion x -> R x + t.
pub type Isometry3 = nalgebra::Isometry3<Real>;
