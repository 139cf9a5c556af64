//! voltrack: time-varying meshes to dynamic meshes by as-rigid-as-possible
//! volume tracking with temporally global optimisation.
//!
//! The pipeline, one module per stage: [`io`] reads a sequence, [`voxel`]
//! puts every frame on one grid.

pub mod deform;
pub mod error;
pub mod export;
pub mod files;
pub mod fixtures;
pub mod io;
pub mod math;
pub mod model;
pub mod params;
pub mod pipeline;
pub mod metrics;
pub mod progress;
pub mod refine;
pub mod spatial;
pub mod track;
pub mod voxel;

pub use error::{Error, Result};
pub use model::{Aabb, TriangleMesh};
pub use progress::{Progress, Stage};
