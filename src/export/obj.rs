//! Wavefront OBJ writing.

use crate::math::Point3;
use crate::mesh::TriangleMesh;
use std::io::Write;

/// Writes `positions` with the connectivity (and UVs) of `mesh`.
pub fn write_obj(out: &mut impl Write, mesh: &TriangleMesh, positions: &[Point3]) -> std::io::Result<()> {
    writeln!(out, "# voltrack {}", env!("CARGO_PKG_VERSION"))?;
    for p in positions {
        writeln!(out, "v {} {} {}", p.x as f32, p.y as f32, p.z as f32)?;
    }
    if let Some(uv) = &mesh.uvs {
        for t in uv {
            writeln!(out, "vt {} {}", t[0], 1.0 - t[1])?;
        }
    }
    let uv = mesh.uvs.is_some();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        if uv {
            writeln!(out, "f {a}/{a} {b}/{b} {c}/{c}")?;
        } else {
            writeln!(out, "f {a} {b} {c}")?;
        }
    }
    Ok(())
}
