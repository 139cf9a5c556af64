//! glTF 2.0 (.gltf with external or embedded buffers, and .glb): every triangle
//! primitive (list, strip or fan) of the default scene, with node transforms
//! applied.
//!
//! The gltf crate's validation and readers take parts of the document on
//! trust (they index, subtract and multiply unchecked, and assert on element
//! types), so what they rely on is checked here first.

use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::model::mesh::TriangleMesh;
use gltf::mesh::Mode;
use nalgebra::Matrix4;
use std::path::Path;

/// Largest external buffer file read.
const MAX_BUFFER_BYTES: u64 = 1 << 32;

/// Decodes a glTF or GLB file (`bytes`, read from `path`) into one mesh:
/// every triangle primitive of the default scene, node transforms applied.
/// External buffers are read from files named relative to `path`.
pub fn read_gltf(path: &Path, bytes: &[u8]) -> Result<TriangleMesh> {
    // serde_json refuses a byte-order mark before the JSON; the crate reads
    // the binary header after one too.
    let bytes = super::strip_bom(bytes);
    let (doc, blob) = document(path, bytes)?;
    let buffers = load_buffers(path, &doc, blob)?;
    // One vertex per byte of input is already far more than any capture
    // needs: the bound on what instancing one mesh in many nodes may make.
    let budget = (bytes.len() + buffers.iter().map(Vec::len).sum::<usize>()).max(1 << 20);
    let mesh = scene_mesh(path, &doc, &buffers, budget)?;
    mesh.validate(path)?;
    Ok(mesh)
}

/// The error for a file the gltf crate or our checks refuse.
fn invalid(path: &Path, e: &dyn std::fmt::Display) -> Error {
    let text = e.to_string();
    Error::parse(
        path,
        None,
        if text.starts_with("invalid glTF") {
            text
        } else {
            format!("invalid glTF: {text}")
        },
    )
}

/// The document of `bytes` and its GLB binary chunk, with what the gltf
/// crate takes on trust checked first.
fn document(path: &Path, bytes: &[u8]) -> Result<(gltf::Document, Option<Vec<u8>>)> {
    // A .glb that does not start with the binary header would be taken for
    // JSON and fail as "expected value at line 1 column 1".
    let named_glb = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    if named_glb && !bytes.starts_with(b"glTF") {
        let head: String = bytes
            .iter()
            .take(4)
            .map(|&b| if b.is_ascii_graphic() { b as char } else { '.' })
            .collect();
        return Err(Error::parse(
            path,
            None,
            format!("not a binary glTF: a .glb starts with 'glTF', this file with '{head}'"),
        ));
    }
    // The crate subtracts the header's size from the declared length unchecked.
    if let Some(declared) = bytes.strip_prefix(b"glTF").and_then(|b| b.get(4..8)) {
        let declared = u32::from_le_bytes(declared.try_into().expect("4 bytes"));
        if declared < 12 {
            return Err(invalid(
                path,
                &format!(
                "the GLB header declares a length of {declared} bytes, less than the header itself"
            ),
            ));
        }
    }
    let gltf = gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(path, &e))?;
    let blob = gltf.blob;
    let json = gltf.document.into_json();
    // gltf-json's validation indexes the accessors by POSITION unchecked.
    for (m, mesh) in json.meshes.iter().enumerate() {
        for prim in &mesh.primitives {
            for (semantic, index) in &prim.attributes {
                if index.value() >= json.accessors.len() {
                    return Err(invalid(
                        path,
                        &format!(
                            "mesh {m}: its {} refers to accessor {}, but there are {}",
                            semantic.to_string(),
                            index.value(),
                            json.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    let doc = gltf::Document::from_json(json).map_err(|e| invalid(path, &e))?;
    Ok((doc, blob))
}

/// The data of every buffer of `doc`: the GLB's binary chunk `blob`, or
/// files and data URIs named relative to `path`.
fn load_buffers(path: &Path, doc: &gltf::Document, blob: Option<Vec<u8>>) -> Result<Vec<Vec<u8>>> {
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in doc.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.clone().ok_or_else(|| {
                Error::parse(
                    path,
                    None,
                    "the GLB has no binary chunk but a buffer refers to it",
                )
            })?,
            gltf::buffer::Source::Uri(uri) => load_uri(path, uri)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::parse(
                path,
                None,
                format!(
                    "buffer {} holds {} bytes, declares {}",
                    buffer.index(),
                    data.len(),
                    buffer.length()
                ),
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// Every triangle primitive of `doc`'s default scene (else its first) in
/// world coordinates, as one mesh of at most `budget` vertices.
fn scene_mesh(
    path: &Path,
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    budget: usize,
) -> Result<TriangleMesh> {
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| Error::mesh(path, "the file has no scene"))?;
    let mut mesh = TriangleMesh::default();
    let mut stack: Vec<(gltf::Node, Matrix4<Real>)> =
        scene.nodes().map(|n| (n, Matrix4::identity())).collect();
    // glTF node hierarchies are trees: a node reached twice has two parents
    // or is in a cycle, and would be drawn again (2^k times down k layers).
    let mut seen = vec![false; doc.nodes().len()];
    // Modes of the primitives skipped, for the error if nothing else is left.
    let mut skipped: Vec<Mode> = Vec::new();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(Error::parse(
                path,
                None,
                format!("node {} is reached twice from the scene (it has more than one parent, or is in a cycle): glTF node hierarchies must be trees", node.index()),
            ));
        }
        let local = Matrix4::from_fn(|r, c| node.transform().matrix()[c][r] as Real);
        let world = parent * local;
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                if !matches!(
                    prim.mode(),
                    Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
                ) {
                    log::warn!(
                        "{}: skipping a primitive of mode {:?}",
                        path.display(),
                        prim.mode()
                    );
                    skipped.push(prim.mode());
                    continue;
                }
                append_primitive(path, &prim, buffers, &world, &mut mesh)?;
                if mesh.positions.len() > budget {
                    return Err(Error::parse(
                        path,
                        None,
                        format!("the scene instances its meshes into more than {budget} vertices, one per byte of input"),
                    ));
                }
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    if mesh.triangles.is_empty() && !skipped.is_empty() {
        skipped.dedup();
        return Err(Error::mesh(
            path,
            format!("the scene has only points or lines (primitive modes {skipped:?}), no triangles: voltrack reads surfaces"),
        ));
    }
    Ok(mesh)
}

fn append_primitive(
    path: &Path,
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: &Matrix4<Real>,
    mesh: &mut TriangleMesh,
) -> Result<()> {
    use gltf::accessor::{DataType, Dimensions};
    let position = prim
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| Error::mesh(path, "a triangle primitive has no POSITION"))?;
    check_accessor(path, &position, "POSITION", buffers)?;
    if (position.dimensions(), position.data_type()) != (Dimensions::Vec3, DataType::F32) {
        return Err(accessor_error(
            path,
            &position,
            "POSITION",
            "not VEC3 of float",
        ));
    }
    if let Some(indices) = prim.indices() {
        check_accessor(path, &indices, "indices", buffers)?;
        if indices.dimensions() != Dimensions::Scalar
            || !matches!(
                indices.data_type(),
                DataType::U8 | DataType::U16 | DataType::U32
            )
        {
            return Err(accessor_error(
                path,
                &indices,
                "indices",
                "not SCALAR of unsigned byte, short or int",
            ));
        }
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let base = mesh.positions.len() as u32;
    let positions: Vec<[f32; 3]> = reader
        .read_positions()
        .ok_or_else(|| {
            accessor_error(
                path,
                &position,
                "POSITION",
                "its data lies outside its buffer",
            )
        })?
        .collect();
    if mesh.positions.len() + positions.len() > u32::MAX as usize {
        return Err(Error::mesh(path, "more than 2^32 vertices"));
    }
    let n = positions.len() as u32;
    mesh.positions.extend(
        positions
            .iter()
            .map(|p| world.transform_point(&Point3::new(p[0] as Real, p[1] as Real, p[2] as Real))),
    );
    let indices: Vec<u32> = match (prim.indices(), reader.read_indices()) {
        (None, _) => (0..n).collect(),
        (Some(_), Some(ix)) => ix.into_u32().collect(),
        (Some(a), None) => {
            return Err(accessor_error(
                path,
                &a,
                "indices",
                "its data lies outside its buffer",
            ))
        }
    };
    if let Some(&bad) = indices.iter().find(|&&i| i >= n) {
        return Err(Error::mesh(
            path,
            format!("index {bad} is beyond the primitive's {n} vertices"),
        ));
    }
    let triangles: Vec<[u32; 3]> = match prim.mode() {
        // Every other triangle of a strip is wound the other way round, so
        // its corners are swapped back; triangles that repeat a corner only
        // join strips together and are left out.
        Mode::TriangleStrip => (2..indices.len())
            .map(|k| {
                if k % 2 == 0 {
                    [indices[k - 2], indices[k - 1], indices[k]]
                } else {
                    [indices[k - 1], indices[k - 2], indices[k]]
                }
            })
            .filter(|[a, b, c]| a != b && b != c && a != c)
            .collect(),
        Mode::TriangleFan => (2..indices.len())
            .map(|k| [indices[0], indices[k - 1], indices[k]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    };
    // A mirroring node transform flips the winding.
    let flip = world.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
    mesh.triangles
        .extend(triangles.into_iter().map(|[a, b, c]| {
            if flip {
                [a + base, c + base, b + base]
            } else {
                [a + base, b + base, c + base]
            }
        }));
    Ok(())
}

fn accessor_error(
    path: &Path,
    accessor: &gltf::Accessor,
    what: &str,
    problem: impl std::fmt::Display,
) -> Error {
    Error::parse(
        path,
        None,
        format!("accessor {} ({what}): {problem}", accessor.index()),
    )
}

/// What the gltf crate's accessor iterators assume: 1 ..= 2^32 - 1 elements,
/// strides no smaller than an element, and every element inside its buffer
/// view and every view inside its buffer; a sparse accessor without a view
/// (zeros, then the sparse values) no longer than the buffers are in bytes.
fn check_accessor(
    path: &Path,
    accessor: &gltf::Accessor,
    what: &str,
    buffers: &[Vec<u8>],
) -> Result<()> {
    let bad = |problem: String| accessor_error(path, accessor, what, problem);
    let count = accessor.count();
    if count == 0 || count > u32::MAX as usize {
        return Err(bad(format!("{count} elements")));
    }
    let fits = |view: gltf::buffer::View, offset: usize, count: usize, size: usize| -> Result<()> {
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(bad(format!(
                "buffer view {} has a stride of {stride} bytes, less than an element's {size}",
                view.index()
            )));
        }
        let end = stride
            .checked_mul(count - 1)
            .and_then(|b| b.checked_add(size))
            .and_then(|b| b.checked_add(offset));
        if end.is_none_or(|end| end > view.length()) {
            return Err(bad(format!(
                "{count} elements from byte {offset} do not fit in buffer view {} of {} bytes",
                view.index(),
                view.length()
            )));
        }
        let held = buffers.get(view.buffer().index()).map_or(0, Vec::len);
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|end| end > held)
        {
            return Err(bad(format!(
                "buffer view {} reaches beyond its buffer of {held} bytes",
                view.index()
            )));
        }
        Ok(())
    };
    if let Some(view) = accessor.view() {
        fits(view, accessor.offset(), count, accessor.size())?;
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(bad(format!("{n} sparse elements of {count}")));
        }
        fits(
            sparse.indices().view(),
            sparse.indices().offset(),
            n,
            sparse.indices().index_type().size(),
        )?;
        fits(
            sparse.values().view(),
            sparse.values().offset(),
            n,
            accessor.size(),
        )?;
        let held: usize = buffers.iter().map(Vec::len).sum();
        if accessor.view().is_none() && count > held {
            return Err(bad(format!(
                "{count} elements, more than the {held} bytes of the file's buffers"
            )));
        }
    }
    Ok(())
}

fn load_uri(path: &Path, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| Error::parse(path, None, "only base64 data URIs are supported"))?;
        return decode_base64(payload)
            .ok_or_else(|| Error::parse(path, None, "invalid base64 in a data URI"));
    }
    let bad = |why: String| Error::parse(path, None, format!("buffer URI '{uri}': {why}"));
    // A scheme (`http:`, `file:`) has a letter first and a colon before any
    // slash; a relative reference's first segment has no colon.
    let scheme = uri
        .split_once(':')
        .filter(|(s, _)| s.starts_with(|c: char| c.is_ascii_alphabetic()) && !s.contains('/'));
    if let Some((scheme, _)) = scheme {
        return Err(bad(format!(
            "a '{scheme}:' URI; voltrack reads buffers from files named relative to the glTF file, or from data: URIs"
        )));
    }
    let relative = percent_decode(uri).ok_or_else(|| bad("invalid percent-encoding".into()))?;
    if relative.starts_with('/') || relative.starts_with('\\') {
        return Err(bad(
            "an absolute path; glTF names its buffers relative to the glTF file".into(),
        ));
    }
    let file = path.parent().unwrap_or(Path::new("")).join(&relative);
    let meta = std::fs::metadata(&file).map_err(|e| bad(format!("{}: {e}", file.display())))?;
    let canonical = |p: &Path| std::fs::canonicalize(p).ok();
    if canonical(&file).is_some_and(|f| Some(f) == canonical(path)) {
        return Err(bad("names the glTF file itself".into()));
    }
    // Only a regular file: a URI naming /dev/zero or a FIFO must not hang.
    if !meta.is_file() || meta.len() > MAX_BUFFER_BYTES {
        return Err(bad(format!(
            "{} is not a regular file of at most {MAX_BUFFER_BYTES} bytes",
            file.display()
        )));
    }
    std::fs::read(&file).map_err(|e| bad(format!("{}: {e}", file.display())))
}

/// `uri` with its `%XX` escapes decoded (glTF URIs are percent-encoded:
/// `my%20buffer.bin`); None when an escape is malformed or the result is
/// not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

fn decode_base64(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' | b'\n' | b'\r' | b' ' => continue,
            _ => return None,
        } as u32;
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}
