//! Scalar and geometry type aliases used throughout the crate (as in parry),
//! so precision is chosen in one place.

/// The scalar used for all geometry and tracking arithmetic.
///
/// f64: tracking accumulates rigid fits over hundreds of frames and the global
/// optimisation compares energies that differ in the 6th digit.
pub type Real = f64;
pub type Point3 = nalgebra::Point3<Real>;
pub type Vector3 = nalgebra::Vector3<Real>;
pub type Matrix3 = nalgebra::Matrix3<Real>;
pub type Rotation3 = nalgebra::Rotation3<Real>;
pub type UnitQuaternion = nalgebra::UnitQuaternion<Real>;
/// A rigid motion x -> R x + t.
pub type Isometry3 = nalgebra::Isometry3<Real>;
