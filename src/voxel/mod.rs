//! Stage 1: every frame on one common voxel grid (method.md §1).

mod memory;
mod voxelize;
mod winding;

pub use voxelize::{voxelize, voxelize_detailed, Voxelization};
pub use memory::{available_memory, MemoryEstimate};
pub use winding::winding_number;
mod sequence;
pub use sequence::{voxelize_sequence, VoxelParams, VoxelSequence};
