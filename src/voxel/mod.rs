//! Stage 1: every frame on one common voxel grid (docs/method.md §1).

mod memory;
mod voxelize;
mod winding;

pub(crate) use memory::available_memory;
pub use memory::{FrameExtent, MemoryEstimate};
pub use voxelize::voxelize;
pub(crate) use voxelize::voxelize_detailed;
pub use winding::winding_number;
mod sequence;
mod topology;
pub use sequence::{voxelize_sequence, VoxelParams, VoxelSequence};
pub use topology::{frame_topology, FrameTopology};
