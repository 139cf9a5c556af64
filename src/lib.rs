//! voltrack: time-varying meshes to dynamic meshes by as-rigid-as-possible
//! volume tracking with temporally global optimisation (Dvořák et al., ICCS
//! 2023).
//!
//! A time-varying mesh is one unrelated triangle mesh per frame; voltrack
//! turns it into one mesh with one connectivity animated over all frames.
//! The stages, each one function taking its input and an options struct
//! (fields documented with their defaults and ranges):
//!
//! 1. [`voxel::voxelize_sequence`]: every frame of a [`FrameSource`] on one
//!    common voxel grid;
//! 2. [`track::track`]: N volume elements (centers) tracked through all
//!    frames;
//! 3. [`refine::refine`]: irregular centers removed, the temporally global
//!    optimisation run;
//! 4. [`deform::deform`] and [`deform::conform`]: the first frame's mesh
//!    moved by the centers, then fitted to every frame's input;
//! 5. [`export`]: glTF with morph targets, OpenEXR trajectories,
//!    vertex-animation textures, PC2, OBJ sequences
//!    ([`export::OutputFormat`]), each to a path or into writers.
//!
//! [`pipeline::convert`] runs stages 1-4 with [`pipeline::ConvertOptions`].
//! Frames come from a [`FrameSource`]: [`io::FrameFiles`] reads files (OBJ,
//! PLY, glTF/GLB, binvox) one frame at a time; a `Vec<TriangleMesh>` serves
//! frames already in memory. The shared data types are in [`model`]; the
//! library never prints, it logs (`log`) and reports progress through
//! [`Progress`].
//!
//! A closed box moving along x for three frames, converted in memory:
//!
//! ```
//! use voltrack::pipeline::{convert, ConvertOptions};
//! use voltrack::{params::TrackParams, voxel::VoxelParams, TriangleMesh};
//! use voltrack::math::{Point3, Real};
//!
//! // A closed box of 1 × 0.6 × 0.4 with its corner at (x, 0, 0).
//! fn boxed(x: Real) -> TriangleMesh {
//!     let (a, b, c) = (1.0, 0.6, 0.4);
//!     let positions = (0..8)
//!         .map(|i| Point3::new(x + a * (i & 1) as Real, b * ((i >> 1) & 1) as Real, c * (i >> 2) as Real))
//!         .collect();
//!     let triangles = vec![
//!         [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
//!         [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
//!     ];
//!     TriangleMesh { positions, triangles, ..Default::default() }
//! }
//!
//! let frames: Vec<TriangleMesh> = (0..3).map(|f| boxed(0.1 * f as Real)).collect();
//! let options = ConvertOptions {
//!     voxel: VoxelParams { resolution: 24, ..Default::default() },
//!     track: TrackParams { centers: 40, ..Default::default() },
//!     ..Default::default()
//! };
//! let result = convert(&frames, &options, Default::default())?;
//!
//! // One connectivity, three frames; every corner follows the box.
//! assert_eq!(result.mesh.frames.len(), 3);
//! assert_eq!(result.mesh.base.triangles, frames[0].triangles);
//! for (f, frame) in result.mesh.frames.iter().enumerate() {
//!     for (v, p) in frame?.iter().enumerate() {
//!         let truth = frames[f].positions[v];
//!         assert!((p - truth).norm() < 0.05, "frame {f}, corner {v}: {p} against {truth}");
//!     }
//! }
//! # Ok::<(), voltrack::Error>(())
//! ```

// `!(x > 0.0)` is how a NaN is refused along with the out-of-range values;
// `x <= 0.0` would let it through.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![warn(missing_docs)]

pub mod checkpoint;
pub mod deform;
pub mod error;
pub mod export;
pub mod files;
/// Generators of the test fixtures (`fixtures/`) and benchmark inputs; not
/// part of the API.
#[doc(hidden)]
pub mod fixtures;
pub mod io;
pub mod math;
pub mod metrics;
pub mod model;
pub mod params;
pub mod pipeline;
pub mod progress;
pub mod refine;
pub(crate) mod spatial;
pub mod track;
pub mod voxel;

#[cfg(test)]
mod test_support;

pub use error::{Error, Result};
pub use model::{Aabb, DynamicMesh, TriangleMesh};
pub use model::{Frame, FrameSource};
pub use progress::{Progress, Stage};
