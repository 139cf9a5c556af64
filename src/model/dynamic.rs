//! The result of the pipeline: one mesh, one connectivity, animated.

use super::{PositionFrames, TriangleMesh};

/// One connectivity, animated: `base` is the reference frame as loaded
/// (vertex order, UVs, normals, texture), `frames.get(f)?[v]` vertex v's
/// position in frame f (frame `reference` equals `base.positions`). A long sequence's frames are
/// kept in a temporary file (`DeformParams::memory`). Made
/// by the deform stage, read by the exporters and the metrics.
#[derive(Debug)]
pub struct DynamicMesh {
    pub base: TriangleMesh,
    pub frames: PositionFrames,
    /// The frame whose mesh `base` is ([`super::Trajectories::reference`]).
    pub reference: usize,
}
