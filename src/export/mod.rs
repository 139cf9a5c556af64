//! Stage 5: writing results (glTF, OBJ, PLY, binvox, EXR, vertex-animation
//! textures). Every writer of a path goes through
//! [`crate::files::write_atomic`] (or [`crate::files::write_atomic_all`] for
//! files that belong together), so a failure never leaves a half-written
//! file behind. Each has a twin that writes the same bytes into writers of
//! the caller's (a `Vec<u8>` for a web server or a test):
//! [`gltf::write_dynamic_glb_to`], [`exr::write_trajectories_exr_to`],
//! [`vat::write_vat_to`], [`pc2::write_pc2_to`] and [`obj::ObjFrames`].
//! [`OutputFormat`] names the formats and the files each writes for one
//! output path, for the command line and its output plan.

pub mod basis;
pub mod binvox;
pub mod exr;
pub mod format;
pub mod gltf;
mod normals;
pub mod obj;
pub mod pc2;
pub mod ply;
pub mod vat;

pub use format::OutputFormat;
