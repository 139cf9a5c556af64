//! Stage 5: the first-frame mesh deformed by the center trajectories into one
//! mesh with one connectivity for all frames (method.md §10).

use crate::math::Point3;
use crate::mesh::TriangleMesh;

/// One connectivity, animated: `base` is the first frame as loaded (vertex
/// order, UVs, normals, texture), `frames[f][v]` vertex v's position in frame f
/// (`frames[0]` equals `base.positions`).
#[derive(Clone, Debug)]
pub struct DynamicMesh {
    pub base: TriangleMesh,
    pub frames: Vec<Vec<Point3>>,
}
