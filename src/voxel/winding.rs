//! Generalised winding number (Jacobson et al. 2013) by brute force: the
//! reference our voxeliser is measured against, never used in the pipeline.

use crate::math::{Point3, Real};
use crate::model::mesh::TriangleMesh;

/// Σ over triangles of the signed solid angle at `p`, divided by 4π: 1 inside
/// a closed outward-oriented mesh, 0 outside, in between near holes.
pub fn winding_number(mesh: &TriangleMesh, p: &Point3) -> Real {
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize] - p);
        let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
        let det = a.dot(&b.cross(&c));
        let div = la * lb * lc + a.dot(&b) * lc + b.dot(&c) * la + c.dot(&a) * lb;
        total += 2.0 * det.atan2(div);
    }
    total / (4.0 * std::f64::consts::PI)
}
