//! The data every stage shares: triangle meshes, the common voxel grid and a
//! frame's occupancy, center trajectories and rigid motions, and the frames
//! of a sequence as a [`FrameSource`]. Nothing here reads or writes a file.

pub mod grid;
pub mod mesh;
pub mod rigid;
pub(crate) mod rng;
pub mod trajectories;

pub use grid::{GridSpec, Occupancy, GRID_MARGIN, MAX_RESOLUTION};
pub use mesh::{Aabb, TriangleMesh};
pub use rigid::{fit_rigid, rotation_from_covariance, Rigid, RigidFits};
pub use trajectories::Trajectories;
