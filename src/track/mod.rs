//! Stages 2-3: seeding centers in the first frame and tracking them forward
//! (method.md §2-§5). One file per algorithm: `lloyd` (frame 0), `assign`
//! (Voronoi cells), `rigid` (weighted Kabsch), `affinity` (who moves with
//! whom), `forward` (the frame loop).

pub mod affinity;
pub mod assign;
pub mod checkpoint;
mod forward;
pub mod lloyd;
pub mod rigid;
pub(crate) mod rng;
mod trajectories;

pub use checkpoint::Checkpointing;
pub use forward::{cell_moments, predict, track, track_with_checkpoints, FrameTiming, TrackResult};
pub use rigid::{fit_rigid, rotation_from_covariance, Rigid, RigidFits};
pub use trajectories::Trajectories;
