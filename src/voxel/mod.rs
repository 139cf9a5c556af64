//! Stage 1: every frame on one common voxel grid (method.md §1).

mod grid;
mod memory;
mod voxelize;
mod winding;

pub use grid::{GridSpec, Occupancy, GRID_MARGIN, MAX_RESOLUTION};
pub use voxelize::{voxelize, voxelize_detailed, Voxelization};
pub use memory::{available_memory, MemoryEstimate};
pub use winding::winding_number;
mod sequence;
pub use sequence::{voxelize_sequence, VoxelParams, VoxelSequence};
