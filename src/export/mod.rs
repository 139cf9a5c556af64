//! Stage 5: writing results (glTF, OBJ, PLY, binvox, EXR, vertex-animation
//! textures). Every writer of a path goes through
//! [`crate::files::write_atomic`] (or [`crate::files::write_atomic_all`] for
//! files that belong together), so a failure never leaves a half-written
//! file behind; [`gltf::write_dynamic_glb_to`] writes the same GLB into any
//! writer (a `Vec<u8>` for a web server or a test).

pub mod basis;
pub mod binvox;
pub mod exr;
pub mod gltf;
mod normals;
pub mod obj;
pub mod pc2;
pub mod ply;
pub mod vat;
