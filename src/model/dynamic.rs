//! The result of the pipeline: one mesh, one connectivity, animated.

use super::{PositionFrames, TriangleMesh};

/// One connectivity, animated: `base` is the first frame as loaded (vertex
/// order, UVs, normals, texture), `frames.get(f)?[v]` vertex v's position in
/// frame f (frame 0 equals `base.positions`). A long sequence's frames are
/// kept in a temporary file (`DeformParams::memory`). Made
/// by the deform stage, read by the exporters and the metrics.
#[derive(Debug)]
pub struct DynamicMesh {
    pub base: TriangleMesh,
    pub frames: PositionFrames,
}
