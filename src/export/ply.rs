//! Stanford PLY writing (used for fixtures and tests of the reader).

use crate::model::mesh::TriangleMesh;
use std::io::Write;

/// How [`write_ply`] encodes the vertices and faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyEncoding {
    /// Text, one vertex or face per line.
    Ascii,
    /// Binary, least significant byte first.
    BinaryLittleEndian,
    /// Binary, most significant byte first.
    BinaryBigEndian,
}

/// Writes the positions (as doubles) and triangles of `mesh` as a PLY file
/// to `out`; UVs, normals and texture are left out.
pub fn write_ply(
    out: &mut impl Write,
    mesh: &TriangleMesh,
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    let format = match encoding {
        PlyEncoding::Ascii => "ascii",
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
    };
    write!(
        out,
        "ply\nformat {format} 1.0\ncomment voltrack\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    let be = encoding == PlyEncoding::BinaryBigEndian;
    for p in &mesh.positions {
        match encoding {
            PlyEncoding::Ascii => writeln!(out, "{} {} {}", p.x, p.y, p.z)?,
            _ => {
                for c in [p.x, p.y, p.z] {
                    out.write_all(&if be { c.to_be_bytes() } else { c.to_le_bytes() })?;
                }
            }
        }
    }
    for t in &mesh.triangles {
        match encoding {
            PlyEncoding::Ascii => writeln!(out, "3 {} {} {}", t[0], t[1], t[2])?,
            _ => {
                out.write_all(&[3])?;
                for i in t {
                    out.write_all(&if be { i.to_be_bytes() } else { i.to_le_bytes() })?;
                }
            }
        }
    }
    Ok(())
}
