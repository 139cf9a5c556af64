//! Wavefront OBJ, through tobj. tobj reports what went wrong but not where, so
//! on failure we scan the text once more to name the offending line.

use crate::error::{Error, Result};
use crate::math::Point3;
use crate::mesh::TriangleMesh;
use std::path::Path;

pub fn read_obj(path: &Path, bytes: &[u8]) -> Result<TriangleMesh> {
    let options = tobj::LoadOptions {
        // One index per vertex, as glTF needs; polygons fanned into triangles.
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut reader = std::io::BufReader::new(bytes);
    let (models, materials) = tobj::load_obj_buf(&mut reader, &options, |mtl| {
        tobj::load_mtl(dir.join(mtl))
    })
    .map_err(|e| Error::parse(path, locate_error(bytes, e), e.to_string()))?;

    let mut mesh = TriangleMesh::default();
    let with_uvs = !models.is_empty() && models.iter().all(|m| !m.mesh.texcoords.is_empty());
    let with_normals = !models.is_empty() && models.iter().all(|m| !m.mesh.normals.is_empty());
    let mut uvs = Vec::new();
    let mut normals = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(
            m.positions.chunks_exact(3).map(|p| Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)),
        );
        mesh.triangles.extend(m.indices.chunks_exact(3).map(|t| [t[0] + base, t[1] + base, t[2] + base]));
        if with_uvs {
            // OBJ's v points up, glTF's down.
            uvs.extend(m.texcoords.chunks_exact(2).map(|t| [t[0], 1.0 - t[1]]));
        }
        if with_normals {
            normals.extend(m.normals.chunks_exact(3).map(|n| [n[0], n[1], n[2]]));
        }
    }
    if with_uvs && uvs.len() == mesh.positions.len() {
        mesh.uvs = Some(uvs);
    }
    if with_normals && normals.len() == mesh.positions.len() {
        mesh.normals = Some(normals);
    }
    if let Ok(materials) = materials {
        let first_used = models.iter().find_map(|m| m.mesh.material_id).unwrap_or(0);
        if let Some(tex) = materials.get(first_used).and_then(|m| m.diffuse_texture.as_ref()) {
            let tex = path.parent().unwrap_or(Path::new("")).join(tex.trim());
            if tex.is_file() {
                mesh.texture = Some(tex);
            } else {
                log::warn!("{}: texture {} not found; exporting without it", path.display(), tex.display());
            }
        }
    }
    if let Err(Error::InvalidMesh { message, .. }) = mesh.validate(path) {
        // tobj renumbers vertices in the order faces use them, so the mesh's
        // vertex number is not the file's: find the file's own `v` line.
        if let Some((line, k)) = first_non_finite_vertex(bytes) {
            return Err(Error::parse(path, Some(line), format!("vertex {k} has a non-finite coordinate")));
        }
        return Err(Error::parse(path, None, message));
    }
    Ok(mesh)
}

/// Line number and 1-based index among the `v` lines of the first vertex
/// with a coordinate that is not a finite number.
fn first_non_finite_vertex(bytes: &[u8]) -> Option<(usize, usize)> {
    lines(bytes)
        .filter(|(_, l)| first_word(l) == "v")
        .enumerate()
        .find(|(_, (_, l))| l.split_whitespace().skip(1).take(3).any(|c| !c.parse::<f64>().is_ok_and(f64::is_finite)))
        .map(|(k, (line, _))| (line, k + 1))
}

fn lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &str)> {
    bytes.split(|&b| b == b'\n').enumerate().map(|(i, l)| (i + 1, std::str::from_utf8(l).unwrap_or("\u{fffd}")))
}

fn first_word(line: &str) -> &str {
    line.split_whitespace().next().unwrap_or("")
}

/// Best-effort line of a tobj error: the first line that fails the same check.
fn locate_error(bytes: &[u8], err: tobj::LoadError) -> Option<usize> {
    use tobj::LoadError as E;
    let floats_ok = |l: &str, min: usize| {
        let v: Vec<&str> = l.split_whitespace().skip(1).collect();
        v.len() >= min && v.iter().all(|t| t.parse::<f32>().is_ok())
    };
    let mut counts = [0i64; 3]; // v, vt, vn seen so far (OBJ indices refer backwards)
    for (n, l) in lines(bytes) {
        let l = l.trim();
        match (first_word(l), err) {
            ("v", E::PositionParseError) if !floats_ok(l, 3) => return Some(n),
            ("vn", E::NormalParseError) if !floats_ok(l, 3) => return Some(n),
            ("vt", E::TexcoordParseError) if !floats_ok(l, 1) => return Some(n),
            ("v", _) => counts[0] += 1,
            ("vt", _) => counts[1] += 1,
            ("vn", _) => counts[2] += 1,
            ("f", _) => {
                let corners: Vec<&str> = l.split_whitespace().skip(1).collect();
                if corners.len() < 3 {
                    if matches!(err, E::FaceParseError | E::InvalidPolygon) {
                        return Some(n);
                    }
                    continue;
                }
                for c in corners {
                    for (slot, field) in c.split('/').enumerate().take(3) {
                        if field.is_empty() && slot > 0 {
                            continue;
                        }
                        let Ok(i) = field.parse::<i64>() else {
                            return Some(n);
                        };
                        let count = counts[[0, 1, 2][slot]];
                        if i == 0 || i > count || -i > count {
                            return Some(n);
                        }
                    }
                }
            }
            _ => {}
        }
    }
    None
}
