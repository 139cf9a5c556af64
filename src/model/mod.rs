//! The data every stage shares: triangle meshes, the common voxel grid and a
//! frame's occupancy, center trajectories and rigid motions ([`Rigid`],
//! [`fit_rigid`]; the batched fits the tracker and the refinement run are
//! internal), and the frames of a sequence as a [`FrameSource`]. Nothing
//! here reads an input or writes an output: [`positions`] may keep a long
//! sequence's frames in a temporary file of its own, and [`mesh`] looks at a
//! texture's first bytes to tell whether glTF can carry it.

pub mod dynamic;
pub mod frames;
pub mod grid;
pub mod mesh;
pub mod metadata;
pub mod positions;
mod rigid;
pub(crate) mod rng;
pub mod trajectories;

pub use dynamic::DynamicMesh;
pub use frames::{Frame, FrameSource};
pub use grid::{GridSpec, Occupancy, OccupancyRuns, GRID_MARGIN, MAX_RESOLUTION};
pub use mesh::{Aabb, TriangleMesh};
pub use metadata::{TrajectoryMetadata, METADATA_ATTRIBUTE};
pub use positions::{FrameStore, PositionFrames};
pub use rigid::{fit_rigid, Rigid};
pub(crate) use rigid::{rotation_from_covariance, PairTable, RigidFits};
pub use trajectories::Trajectories;

use crate::error::{Error, Result};

/// What the writers call the animated object (glTF node, mesh and animation,
/// OBJ object) when no name is given.
pub const DEFAULT_NAME: &str = "voltrack";

/// Checks a name for the animated object: something besides white space,
/// and no control characters (a line break would end an OBJ's `o` line and
/// start another).
pub fn check_name(name: &str) -> Result<()> {
    if name.trim().is_empty() {
        return Err(Error::InvalidParameter("the name must not be empty".into()));
    }
    if name.chars().any(char::is_control) {
        return Err(Error::InvalidParameter(format!(
            "the name {name:?} holds a control character"
        )));
    }
    Ok(())
}
