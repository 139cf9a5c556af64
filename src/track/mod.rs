//! Stages 2-3: seeding centers in the first frame and tracking them forward
//! (method.md §2-§5). One file per algorithm: `lloyd` (frame 0), `assign`
//! (Voronoi cells), `rigid` (weighted Kabsch), `affinity` (who moves with
//! whom), `forward` (the frame loop).

pub mod affinity;
pub mod checkpoint;
mod forward;
pub mod lloyd;

pub use checkpoint::Checkpointing;
pub use forward::{cell_moments, predict, track, track_with_checkpoints, FrameTiming, TrackResult};
