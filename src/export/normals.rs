//! Vertex normals of an animated mesh, shared by every writer that stores
//! them (glTF's NORMAL and its morph deltas, the point cache's OBJ), so they
//! agree with each other.

use crate::math::{Point3, Vector3};

/// Area-weighted vertex normals with vertices welded by identical position
/// in the mesh as loaded, so a UV seam (duplicated vertices) shares one
/// normal instead of showing as a crease. (Not by their frame-0 positions:
/// a segmented mesh's hidden vertices all sit on one point there,
/// `deform::segments`.)
pub(crate) struct FrameNormals<'a> {
    triangles: &'a [[u32; 3]],
    /// Per vertex, the first vertex at the same frame-0 position.
    weld: Vec<u32>,
    /// Frame 0's normals; +Z where no triangle with area touches a vertex, as
    /// glTF requires unit normals.
    pub base: Vec<Vector3>,
}

impl<'a> FrameNormals<'a> {
    pub fn new(base: &'a crate::model::TriangleMesh, frame0: &[Point3]) -> Self {
        let weld = crate::model::mesh::weld_by_position(&base.positions);
        let mut n = FrameNormals {
            triangles: &base.triangles,
            weld,
            base: Vec::new(),
        };
        n.base = n
            .raw(frame0)
            .into_iter()
            .map(|v| {
                if v == Vector3::zeros() {
                    Vector3::z()
                } else {
                    v
                }
            })
            .collect();
        n
    }

    /// Unit normals of a frame; zero where undefined.
    fn raw(&self, positions: &[Point3]) -> Vec<Vector3> {
        let mut sum = vec![Vector3::zeros(); positions.len()];
        for t in self.triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let face = (b - a).cross(&(c - a));
            for &i in t {
                sum[self.weld[i as usize] as usize] += face;
            }
        }
        self.weld
            .iter()
            .map(|&w| {
                sum[w as usize]
                    .try_normalize(0.0)
                    .unwrap_or_else(Vector3::zeros)
            })
            .collect()
    }

    /// Normals of a frame, frame 0's where undefined (no change there).
    pub fn of(&self, positions: &[Point3]) -> Vec<Vector3> {
        self.raw(positions)
            .into_iter()
            .zip(&self.base)
            .map(|(n, b)| if n == Vector3::zeros() { *b } else { n })
            .collect()
    }
}
