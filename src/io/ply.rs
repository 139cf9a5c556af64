//! Stanford PLY, ASCII and binary of either byte order. Our own reader rather
//! than a crate: the maintained ones report neither line nor element on bad
//! input, and we only need positions, optional normals/UVs and faces.

use super::triangulate_polygon;
use crate::error::{Error, Result};
use crate::math::Point3;
use crate::model::mesh::TriangleMesh;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLe,
    BinaryBe,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<Scalar>,
    scalar: Scalar,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
    /// Header line declaring it.
    line: usize,
}

impl Element {
    /// Fails where the rest of the file (`left` bytes) cannot hold the
    /// count declared: before a loop of billions.
    fn check_fits(&self, path: &Path, left: usize, encoding: Encoding) -> Result<()> {
        let fits = self
            .count
            .checked_mul(self.min_bytes(encoding))
            .is_some_and(|need| need <= left + 1);
        if fits {
            return Ok(());
        }
        Err(Error::parse(
            path,
            Some(self.line),
            format!(
                "the header declares {} {} elements of at least {} bytes each, more than the {left} bytes left in the file",
                self.count,
                self.name,
                self.min_bytes(encoding)
            ),
        ))
    }

    /// Fewest bytes one element takes in the body: its scalars and list
    /// counts in binary, a value and a line break in ASCII.
    fn min_bytes(&self, encoding: Encoding) -> usize {
        match encoding {
            Encoding::Ascii => 2,
            _ => self
                .properties
                .iter()
                .map(|p| p.list.unwrap_or(p.scalar).size())
                .sum(),
        }
    }
}

/// Where an element's properties of interest are (indices into its
/// properties).
struct Layout {
    is_vertex: bool,
    is_face: bool,
    xyz: [Option<usize>; 3],
    nxyz: [Option<usize>; 3],
    uv: [Option<usize>; 2],
    /// The face's list of vertex indices.
    face_list: Option<usize>,
}

impl Layout {
    /// Of `el`, failing where a vertex element lacks a coordinate or a face
    /// element its index list.
    fn of(el: &Element, path: &Path) -> Result<Self> {
        let is_vertex = el.name == "vertex";
        let is_face = el.name == "face";
        let find = |names: &[&str]| {
            el.properties
                .iter()
                .position(|p| names.contains(&p.name.as_str()) && p.list.is_none())
        };
        let xyz = [find(&["x"]), find(&["y"]), find(&["z"])];
        if is_vertex && xyz.iter().any(Option::is_none) {
            return Err(Error::parse(
                path,
                Some(el.line),
                "the vertex element lacks one of the properties x, y, z",
            ));
        }
        let face_list = el.properties.iter().position(|p| {
            p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
        });
        if is_face && face_list.is_none() {
            return Err(Error::parse(
                path,
                Some(el.line),
                "the face element has no vertex_indices list",
            ));
        }
        Ok(Layout {
            is_vertex,
            is_face,
            xyz,
            nxyz: [find(&["nx"]), find(&["ny"]), find(&["nz"])],
            uv: [
                find(&["u", "s", "texture_u", "texture_s"]),
                find(&["v", "t", "texture_v", "texture_t"]),
            ],
            face_list,
        })
    }
}

/// Reads values one at a time from the body, whatever the encoding, and knows
/// where it is for error messages.
struct Body<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
    encoding: Encoding,
    line: usize,
    tokens: std::vec::IntoIter<&'a str>,
    /// The element being read: name, 1-based number, count declared.
    element: (&'a str, usize, usize),
}

impl<'a> Body<'a> {
    /// Reads a list of `n` values of type `scalar`; where `keep` (a face's
    /// vertex indices), checks them as indices (against the `vertices` read
    /// where the vertex element came first) into `corners`, at least three.
    fn corners(
        &mut self,
        n: usize,
        scalar: Scalar,
        keep: bool,
        vertices: Option<usize>,
        corners: &mut Vec<u32>,
    ) -> Result<()> {
        corners.clear();
        for _ in 0..n {
            let v = self.value(scalar)?;
            if keep {
                if v < 0.0 || v.fract() != 0.0 || v >= u32::MAX as f64 {
                    return Err(self.err(format!("vertex index {v} is not valid")));
                }
                if let Some(n) = vertices.filter(|&n| v >= n as f64) {
                    return Err(self.err(format!("vertex index {v} is beyond the {n} vertices")));
                }
                corners.push(v as u32);
            }
        }
        if keep && corners.len() < 3 {
            return Err(self.err(format!(
                "a face needs at least 3 corners, this one has {}",
                corners.len()
            )));
        }
        Ok(())
    }

    /// An error at the current position, saying which element it is in (a
    /// count in the header that disagrees with the body shows up as an
    /// element that does not fit).
    fn err(&self, msg: impl Into<String>) -> Error {
        let (name, k, count) = self.element;
        let msg = format!("{name} {k} of {count}: {}", msg.into());
        match self.encoding {
            Encoding::Ascii => Error::parse(self.path, Some(self.line), msg),
            _ => Error::parse(self.path, None, format!("{msg} (at byte {})", self.pos)),
        }
    }

    /// Fails unless only white space follows the last element.
    fn check_end(&self) -> Result<()> {
        let rest = &self.bytes[self.pos.min(self.bytes.len())..];
        let Some(at) = rest.iter().position(|b| !b.is_ascii_whitespace()) else {
            return Ok(());
        };
        let msg = "data after the last element the header declares: are its element counts right?";
        Err(match self.encoding {
            Encoding::Ascii => {
                let line = self.line + rest[..at].iter().filter(|&&b| b == b'\n').count() + 1;
                Error::parse(self.path, Some(line), msg)
            }
            _ => Error::parse(
                self.path,
                None,
                format!("{} more bytes: {msg} (at byte {})", rest.len(), self.pos),
            ),
        })
    }

    /// Starts a new ASCII element line.
    fn next_line(&mut self) -> Result<()> {
        if self.encoding != Encoding::Ascii {
            return Ok(());
        }
        loop {
            if self.pos >= self.bytes.len() {
                return Err(self.err("file ends before all elements were read"));
            }
            let end = self.bytes[self.pos..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(self.bytes.len(), |e| self.pos + e);
            let text = std::str::from_utf8(&self.bytes[self.pos..end])
                .map_err(|_| self.err("not UTF-8 text"))?;
            self.pos = end + 1;
            self.line += 1;
            let tokens: Vec<&'a str> = text.split_whitespace().collect();
            if !tokens.is_empty() {
                self.tokens = tokens.into_iter();
                return Ok(());
            }
        }
    }

    fn end_line(&mut self) -> Result<()> {
        if self.encoding == Encoding::Ascii && self.tokens.len() > 0 {
            return Err(self.err("more values on the line than the header declares"));
        }
        Ok(())
    }

    fn value(&mut self, s: Scalar) -> Result<f64> {
        match self.encoding {
            Encoding::Ascii => {
                let t = self.tokens.next().ok_or_else(|| {
                    self.err(if self.pos >= self.bytes.len() {
                        "the file ends in the middle of this element"
                    } else {
                        "fewer values on the line than the header declares"
                    })
                })?;
                let v = if matches!(s, Scalar::F32 | Scalar::F64) {
                    t.parse::<f64>().ok()
                } else {
                    t.parse::<i64>().ok().map(|i| i as f64)
                };
                v.ok_or_else(|| self.err(format!("'{t}' is not a number of type {s:?}")))
            }
            enc => {
                let n = s.size();
                let b = self
                    .bytes
                    .get(self.pos..self.pos + n)
                    .ok_or_else(|| self.err("file ends before all elements were read"))?;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                if enc == Encoding::BinaryBe {
                    a[..n].reverse();
                }
                self.pos += n;
                Ok(match s {
                    Scalar::I8 => a[0] as i8 as f64,
                    Scalar::U8 => a[0] as f64,
                    Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
                    Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
                    Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
                    Scalar::F64 => f64::from_le_bytes(a),
                })
            }
        }
    }
}

/// Decodes a PLY file (ASCII or binary; `bytes`, read from `path`) into
/// one mesh, with its normals and UVs when present.
pub fn read_ply(path: &Path, bytes: &[u8]) -> Result<TriangleMesh> {
    let raw = super::strip_bom(bytes);
    // Lines may end in a lone CR; a binary body is read from the bytes as
    // they are (the conversion keeps offsets).
    let text = super::lone_cr_to_lf(raw);
    let (encoding, elements, body_start, header_lines) = read_header(path, &text)?;
    let bytes = if encoding == Encoding::Ascii {
        &*text
    } else {
        raw
    };
    let mut body = Body {
        path,
        bytes,
        pos: body_start,
        encoding,
        line: header_lines,
        tokens: Vec::new().into_iter(),
        element: ("header", 0, 0),
    };
    let mut mesh = TriangleMesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut saw_vertices = false;
    // Faces before the vertex element.
    let mut polygons: Vec<Vec<u32>> = Vec::new();
    // Vertices read once the vertex element is complete: face indices are checked against it.
    let mut vertices: Option<usize> = None;
    for el in &elements {
        if el.properties.is_empty() {
            continue; // holds nothing, however many there are
        }
        el.check_fits(path, bytes.len().saturating_sub(body.pos), encoding)?;
        let Layout {
            is_vertex,
            is_face,
            xyz,
            nxyz,
            uv,
            face_list,
        } = Layout::of(el, path)?;
        saw_vertices |= is_vertex;
        let has_normals = nxyz.iter().all(Option::is_some);
        let has_uvs = uv.iter().all(Option::is_some);
        let mut values = vec![0.0f64; el.properties.len()];
        let mut corners: Vec<u32> = Vec::new();
        for number in 1..=el.count {
            body.element = (&el.name, number, el.count);
            body.next_line()?;
            for (k, p) in el.properties.iter().enumerate() {
                if let Some(count_type) = p.list {
                    let n = body.value(count_type)?;
                    if !(0.0..=1e6).contains(&n) || n.fract() != 0.0 {
                        return Err(body.err(format!(
                            "list length {n} of property '{}' is not a valid count",
                            p.name
                        )));
                    }
                    let keep = is_face && Some(k) == face_list;
                    body.corners(n as usize, p.scalar, keep, vertices, &mut corners)?;
                    if keep && vertices.is_some() {
                        triangulate_polygon(&mesh.positions, &corners, &mut mesh.triangles);
                    } else if keep {
                        // Triangulated once the vertex element, which comes later, is read.
                        polygons.push(corners.clone());
                    }
                } else {
                    values[k] = body.value(p.scalar)?;
                }
            }
            body.end_line()?;
            if is_vertex {
                let [x, y, z] = xyz.map(|i| values[i.unwrap()]);
                if ![x, y, z].iter().all(|c| c.is_finite()) {
                    return Err(body.err(format!("non-finite coordinate ({x}, {y}, {z})")));
                }
                mesh.positions.push(Point3::new(x, y, z));
                if has_normals {
                    normals.push(nxyz.map(|i| values[i.unwrap()] as f32));
                }
                if has_uvs {
                    // PLY follows OBJ: v up.
                    uvs.push([
                        values[uv[0].unwrap()] as f32,
                        1.0 - values[uv[1].unwrap()] as f32,
                    ]);
                }
            }
        }
        if is_vertex {
            vertices = Some(mesh.positions.len());
        }
    }
    body.check_end()?;
    if !saw_vertices {
        return Err(Error::parse(path, None, "no vertex element in the header"));
    }
    let n = mesh.positions.len();
    for corners in &polygons {
        if let Some(&bad) = corners.iter().find(|&&c| c as usize >= n) {
            return Err(Error::parse(
                path,
                None,
                format!("a face's vertex index {bad} is beyond the {n} vertices"),
            ));
        }
        triangulate_polygon(&mesh.positions, corners, &mut mesh.triangles);
    }
    if !normals.is_empty() {
        mesh.normals = Some(normals);
    }
    if !uvs.is_empty() {
        mesh.uvs = Some(uvs);
    }
    mesh.validate(path)?;
    Ok(mesh)
}

/// Returns encoding, elements, byte offset of the body and the number of header lines.
fn read_header(path: &Path, bytes: &[u8]) -> Result<(Encoding, Vec<Element>, usize, usize)> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|e| pos + e)
            .ok_or_else(|| {
                Error::parse(
                    path,
                    Some(line_no + 1),
                    "the header does not end with 'end_header'",
                )
            })?;
        line_no += 1;
        let line = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| Error::parse(path, Some(line_no), "header is not text"))?;
        pos = end + 1;
        let err = |m: String| Error::parse(path, Some(line_no), m);
        let words: Vec<&str> = line.split_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err(err("not a PLY file (first line is not 'ply')".into()));
            }
            continue;
        }
        match words.as_slice() {
            [] => {}
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => {
                encoding = Some(match *f {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLe,
                    "binary_big_endian" => Encoding::BinaryBe,
                    other => return Err(err(format!("unknown format '{other}'"))),
                })
            }
            ["element", name, count] => {
                let count = count
                    .parse::<usize>()
                    .map_err(|_| err(format!("element count '{count}' is not a number")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: line_no,
                });
            }
            ["property", "list", ct, it, name] => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".into()))?;
                let ct = Scalar::parse(ct).filter(|s| !matches!(s, Scalar::F32 | Scalar::F64));
                let it = Scalar::parse(it);
                match (ct, it) {
                    (Some(ct), Some(it)) => el.properties.push(Property {
                        name: name.to_string(),
                        list: Some(ct),
                        scalar: it,
                    }),
                    _ => return Err(err("unknown type in list property".into())),
                }
            }
            ["property", ty, name] => {
                let el = elements
                    .last_mut()
                    .ok_or_else(|| err("property before any element".into()))?;
                let scalar = Scalar::parse(ty)
                    .ok_or_else(|| err(format!("unknown property type '{ty}'")))?;
                el.properties.push(Property {
                    name: name.to_string(),
                    list: None,
                    scalar,
                });
            }
            ["end_header"] => break,
            _ => return Err(err(format!("unexpected header line '{}'", line.trim()))),
        }
    }
    let encoding =
        encoding.ok_or_else(|| Error::parse(path, None, "the header has no 'format' line"))?;
    Ok((encoding, elements, pos, line_no))
}
