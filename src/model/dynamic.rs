//! The result of the pipeline: one mesh, one connectivity, animated.

use super::{PositionFrames, TriangleMesh};

/// One connectivity, animated: `base` is the reference frame as loaded
/// (vertex order, UVs, normals, texture), `frames.get(f)?[v]` vertex v's
/// position in frame f (frame `reference` equals `base.positions`). A take
/// cut into segments (`deform::segments`) has as `base` the union of each
/// segment's reference mesh as loaded, each segment's vertices where its
/// mesh has them in that segment's frames and on one point elsewhere. A long sequence's frames are
/// kept in a temporary file (`DeformParams::memory`). Made
/// by the deform stage, read by the exporters and the metrics.
#[derive(Debug)]
pub struct DynamicMesh {
    /// The mesh every frame shares: connectivity, UVs, normals, texture, and
    /// the reference frame's positions.
    pub base: TriangleMesh,
    /// Every vertex's position in every frame, in the input's units.
    pub frames: PositionFrames,
    /// The frame whose mesh `base` is ([`super::Trajectories::reference`]).
    pub reference: usize,
}
