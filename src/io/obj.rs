//! Wavefront OBJ, through tobj. tobj reports what went wrong but not where, and
//! takes faces of one or two corners for points and lines, so every vertex and
//! face line is checked first (naming its line), and on any other failure the
//! text is scanned once more for the offending line.

use super::triangulate_polygon;
use crate::error::{Error, Result};
use crate::math::Point3;
use crate::model::mesh::TriangleMesh;
use std::path::Path;

/// Material libraries larger than this are skipped (they are optional).
const MAX_MTL_BYTES: u64 = 64 << 20;

/// Decodes an OBJ file (`bytes`, read from `path`) into one mesh, polygons
/// triangulated: UVs and normals when every object has them, and the
/// texture (PNG or JPEG) of the first material used. Material libraries and
/// textures are found relative to `path`.
pub fn read_obj(path: &Path, bytes: &[u8]) -> Result<TriangleMesh> {
    // tobj splits lines at LF only, and takes a byte-order mark for part of
    // the first word (a first `v` line missed shifts every face by one).
    let bytes = &*super::lone_cr_to_lf(super::strip_bom(bytes));
    let bytes = &*normalise(path, bytes);
    check_lines(path, bytes)?;
    let options = tobj::LoadOptions {
        // One index per vertex, as glTF needs; polygons are triangulated
        // here (tobj fans them, which covers only convex ones).
        single_index: true,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut reader = std::io::BufReader::new(bytes);
    let (models, materials) = tobj::load_obj_buf(&mut reader, &options, |mtl| {
        // Only a regular file of sane size: `mtllib /dev/zero` must not hang.
        let file = dir.join(mtl);
        match std::fs::metadata(&file) {
            Ok(m) if m.is_file() && m.len() <= MAX_MTL_BYTES => tobj::load_mtl(file),
            _ => Err(tobj::LoadError::OpenFileFailed),
        }
    })
    .map_err(|e| Error::parse(path, locate_error(bytes, e), describe(e)))?;

    let mut mesh = TriangleMesh::default();
    let with_uvs = !models.is_empty() && models.iter().all(|m| !m.mesh.texcoords.is_empty());
    let with_normals = !models.is_empty() && models.iter().all(|m| !m.mesh.normals.is_empty());
    let mut uvs = Vec::new();
    let mut normals = Vec::new();
    // Read in f64 and kept to f32 (what glTF and PLY floats hold, so that one
    // capture gives the same result in every format) unless f32 would blur
    // a capture far from the origin.
    let mut bounds = crate::model::mesh::Aabb::empty();
    models
        .iter()
        .flat_map(|m| m.mesh.positions.chunks_exact(3))
        .for_each(|p| bounds.grow(&Point3::new(p[0], p[1], p[2])));
    let far = bounds.too_far_for_f32();
    let kept = |c: f64| if far { c } else { c as f32 as f64 };
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Point3::new(kept(p[0]), kept(p[1]), kept(p[2]))),
        );
        let indices: Vec<u32> = m.indices.iter().map(|&i| i + base).collect();
        if m.face_arities.is_empty() {
            // All triangles.
            mesh.triangles
                .extend(indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
        } else {
            let mut at = 0;
            for &arity in &m.face_arities {
                let face = &indices[at..at + arity as usize];
                triangulate_polygon(&mesh.positions, face, &mut mesh.triangles);
                at += arity as usize;
            }
        }
        if with_uvs {
            // OBJ's v points up, glTF's down.
            uvs.extend(
                m.texcoords
                    .chunks_exact(2)
                    .map(|t| [t[0] as f32, 1.0 - t[1] as f32]),
            );
        }
        if with_normals {
            normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| [n[0] as f32, n[1] as f32, n[2] as f32]),
            );
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
        if let Some(tex) = materials
            .get(first_used)
            .and_then(|m| m.diffuse_texture.as_ref())
        {
            let tex = path.parent().unwrap_or(Path::new("")).join(tex.trim());
            if !tex.is_file() {
                log::warn!(
                    "{}: texture {} not found; ignored",
                    path.display(),
                    tex.display()
                );
            } else if crate::model::mesh::embeddable_image(&tex).is_none() {
                // glTF carries PNG and JPEG; finding out at export would come
                // after the whole conversion.
                log::warn!(
                    "{}: texture {} is neither PNG nor JPEG; ignored",
                    path.display(),
                    tex.display()
                );
            } else {
                mesh.texture = Some(tex);
            }
        }
    }
    if let Err(Error::InvalidMesh { message, .. }) = mesh.validate(path) {
        return Err(Error::parse(path, None, message));
    }
    Ok(mesh)
}

/// Checks every vertex and face line, naming the line, where tobj names none
/// or reads on:
/// - a vertex is `x y z`, `x y z w` or `x y z r g b`, with `w` finite and not
///   0, and finite coordinates once divided by `w` (as tobj does, in f64);
///   tobj reports `w = 0` and a wrong count without a line, divides by a NaN
///   `w`, and renumbers vertices, so a non-finite coordinate could not be
///   traced back to its line afterwards;
/// - a face (a line, a point) has at least three (two, one) corners, each
///   `v`, `v/vt`, `v//vn` or
///   `v/vt/vn` with indices that refer to an element defined above the line
///   (1-based, or negative counting back from the last one). tobj would take a
///   face of one or two corners (a file cut short in a face line) for a point
///   or a line and drop it, and checks some indices only with arithmetic that
///   can overflow.
fn check_lines(path: &Path, bytes: &[u8]) -> Result<()> {
    const KINDS: [(&str, &str); 3] = [
        ("vertex", "vertices"),
        ("texture coordinate", "texture coordinates"),
        ("normal", "normals"),
    ];
    let mut counts = [0u64; 3]; // v, vt, vn so far
    for (n, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let err = |m: String| Error::parse(path, Some(n + 1), m);
        let line = std::str::from_utf8(raw).map_err(|_| err("not UTF-8 text".into()))?;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                counts[0] += 1;
                let values: Vec<&str> = words.collect();
                let number = |t: &str| {
                    t.parse::<f64>()
                        .map_err(|_| err(format!("vertex {}: '{t}' is not a number", counts[0])))
                };
                match values.len() {
                    0..=2 => return Err(err("a vertex ('v') needs three numbers".into())),
                    3 | 4 | 6 => {}
                    n => {
                        return Err(err(format!(
                            "vertex {} has {n} numbers: a vertex is x y z, x y z w or x y z r g b",
                            counts[0]
                        )))
                    }
                }
                let numbers = values
                    .iter()
                    .map(|t| number(t))
                    .collect::<Result<Vec<f64>>>()?;
                let w = if values.len() == 4 { numbers[3] } else { 1.0 };
                if !w.is_finite() || w == 0.0 {
                    return Err(err(format!(
                        "vertex {}: its weight w = {w} is not a finite number other than 0",
                        counts[0]
                    )));
                }
                if numbers[..3].iter().any(|&c| !(c / w).is_finite()) {
                    return Err(err(format!(
                        "vertex {} has a non-finite coordinate",
                        counts[0]
                    )));
                }
                if let Some(c) = numbers[..3]
                    .iter()
                    .map(|&c| c / w)
                    .find(|c| c.abs() > f32::MAX as f64)
                {
                    return Err(err(format!(
                        "vertex {}: coordinate {c:e} is beyond ±3.4e38, the largest a 32-bit float (glTF's, most PLY files') holds",
                        counts[0]
                    )));
                }
            }
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some(kind @ ("f" | "l" | "p")) => {
                // Lines and points are dropped, but tobj still resolves
                // their indices, with the same overflowing arithmetic.
                let corners: Vec<&str> = words.collect();
                let (least, what) = match kind {
                    "f" => (3, "a face"),
                    "l" => (2, "a line ('l')"),
                    _ => (1, "a point ('p')"),
                };
                if corners.len() < least {
                    return Err(err(format!(
                        "{what} needs at least {least} corners, this one has {}",
                        corners.len()
                    )));
                }
                for corner in corners {
                    let fields: Vec<&str> = corner.split('/').collect();
                    if fields.len() > 3 || fields[0].is_empty() {
                        return Err(err(format!(
                            "'{corner}' is not a face corner (v, v/vt, v//vn or v/vt/vn)"
                        )));
                    }
                    for (slot, field) in fields.iter().enumerate().filter(|(_, f)| !f.is_empty()) {
                        let ((one, many), count) = (KINDS[slot], counts[slot]);
                        let index = field.parse::<i64>().map_err(|e| {
                            let why = match e.kind() {
                                std::num::IntErrorKind::PosOverflow
                                | std::num::IntErrorKind::NegOverflow => {
                                    "is too large for an index"
                                }
                                _ => "is not a whole number",
                            };
                            err(format!("{one} index '{field}' {why}"))
                        })?;
                        let problem = match index {
                            0 => Some("OBJ indices start at 1".to_string()),
                            i if i > 0 && i.unsigned_abs() > count => Some(format!("only {count} {many} are defined above this line")),
                            i if i < 0 && i.unsigned_abs() > count => {
                                Some(format!("it counts back past the first of the {count} {many} defined above this line"))
                            }
                            _ => None,
                        };
                        if let Some(problem) = problem {
                            return Err(err(format!(
                                "{one} index {index} in '{corner}': {problem}"
                            )));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// OBJ text as tobj and [`check_lines`] read it, with each line at its own
/// number still: a line ending in `\` is joined with the next (the line
/// after a joined one is left empty), a comment that starts a word is
/// removed (`v 1 2 3 # note`: tobj would read the comment as numbers), and a
/// `usemtl` naming no material, which tobj refuses without saying where, is
/// dropped with a warning (its faces take the default material, which
/// voltrack ignores anyway). Borrowed when no line changes.
fn normalise<'a>(path: &Path, bytes: &'a [u8]) -> std::borrow::Cow<'a, [u8]> {
    let lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    let mut out: Option<Vec<u8>> = None;
    let mut joined = 0; // lines joined into the one being written
    for (n, &raw) in lines.iter().enumerate() {
        let mut line = raw.strip_suffix(b"\r").unwrap_or(raw);
        if let Some(hash) =
            (1..line.len()).find(|&i| line[i] == b'#' && line[i - 1].is_ascii_whitespace())
        {
            line = &line[..hash];
        }
        let words = || {
            line.split(|b| b.is_ascii_whitespace())
                .filter(|w| !w.is_empty())
        };
        let bare_usemtl = words().next() == Some(b"usemtl") && words().nth(1).is_none();
        if bare_usemtl {
            log::warn!(
                "{}:{}: 'usemtl' names no material; ignored",
                path.display(),
                n + 1
            );
            line = b"";
        }
        let trimmed = line.trim_ascii_end();
        let continues = trimmed.ends_with(b"\\") && n + 1 < lines.len();
        if continues {
            line = &trimmed[..trimmed.len() - 1];
        }
        let last = n + 1 == lines.len();
        if out.is_none() && (line.len() != raw.len() || continues || joined > 0) {
            // The first change: copy the lines before it as they were.
            let start = raw.as_ptr() as usize - bytes.as_ptr() as usize;
            out = Some(bytes[..start].to_vec());
        }
        let Some(out) = out.as_mut() else { continue };
        out.extend_from_slice(line);
        if continues {
            out.push(b' ');
            joined += 1;
        } else {
            // This line's end, and one empty line for each joined into it.
            if !last {
                out.extend(std::iter::repeat_n(b'\n', joined + 1));
            }
            joined = 0;
        }
    }
    match out {
        Some(out) => std::borrow::Cow::Owned(out),
        None => std::borrow::Cow::Borrowed(bytes),
    }
}

/// tobj's error in words.
fn describe(err: tobj::LoadError) -> String {
    use tobj::LoadError as E;
    match err {
        E::PositionParseError => "a vertex ('v') needs three numbers".into(),
        E::NormalParseError => "a normal ('vn') needs three numbers".into(),
        E::TexcoordParseError => "a texture coordinate ('vt') needs two numbers".into(),
        E::FaceColorOutOfBounds => {
            "vertex colors ('v x y z r g b') are given for some vertices but not for all".into()
        }
        other => other.to_string(),
    }
}

fn lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &str)> {
    bytes
        .split(|&b| b == b'\n')
        .enumerate()
        .map(|(i, l)| (i + 1, std::str::from_utf8(l).unwrap_or("\u{fffd}")))
}

fn first_word(line: &str) -> &str {
    line.split_whitespace().next().unwrap_or("")
}

/// Best-effort line of a tobj error: the first line that fails the same
/// check (face lines were checked before tobj saw them).
fn locate_error(bytes: &[u8], err: tobj::LoadError) -> Option<usize> {
    use tobj::LoadError as E;
    let floats_ok = |l: &str, min: usize| {
        let v: Vec<&str> = l.split_whitespace().skip(1).take(min).collect();
        v.len() >= min && v.iter().all(|t| t.parse::<f32>().is_ok())
    };
    lines(bytes).find_map(|(n, l)| {
        let bad = match (first_word(l), err) {
            ("v", E::PositionParseError) | ("vn", E::NormalParseError) => !floats_ok(l, 3),
            ("vt", E::TexcoordParseError) => !floats_ok(l, 2),
            ("v", E::FaceColorOutOfBounds) => l.split_whitespace().count() < 7,
            _ => false,
        };
        bad.then_some(n)
    })
}
