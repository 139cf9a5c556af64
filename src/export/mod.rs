//! Stage 5: writing results (glTF, OBJ, PLY, binvox, EXR, vertex-animation
//! textures). Every writer goes through [`crate::files::write_atomic`] (or
//! [`crate::files::write_atomic_all`] for files that belong together), so a
//! failure never leaves a half-written file behind.

pub mod basis;
pub mod binvox;
pub mod exr;
pub mod gltf;
mod normals;
pub mod obj;
pub mod pc2;
pub mod ply;
pub mod vat;
