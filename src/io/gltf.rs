//! glTF 2.0 (.gltf with external or embedded buffers, and .glb): every triangle
//! primitive of the default scene, with node transforms applied.

use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::mesh::TriangleMesh;
use nalgebra::Matrix4;
use std::path::Path;

pub fn read_gltf(path: &Path, bytes: &[u8]) -> Result<TriangleMesh> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| Error::parse(path, None, format!("invalid glTF: {e}")))?;
    let doc = &gltf.document;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in doc.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| Error::parse(path, None, "the GLB has no binary chunk but a buffer refers to it"))?,
            gltf::buffer::Source::Uri(uri) => load_uri(path, uri)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::parse(
                path,
                None,
                format!("buffer {} holds {} bytes, declares {}", buffer.index(), data.len(), buffer.length()),
            ));
        }
        buffers.push(data);
    }
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| Error::mesh(path, "the file has no scene"))?;
    let mut mesh = TriangleMesh::default();
    let mut stack: Vec<(gltf::Node, Matrix4<Real>)> = scene.nodes().map(|n| (n, Matrix4::identity())).collect();
    let mut visited = 0usize;
    while let Some((node, parent)) = stack.pop() {
        visited += 1;
        if visited > 1_000_000 {
            return Err(Error::parse(path, None, "the node hierarchy is cyclic"));
        }
        let local = Matrix4::from_fn(|r, c| node.transform().matrix()[c][r] as Real);
        let world = parent * local;
        if let Some(m) = node.mesh() {
            for prim in m.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    log::warn!("{}: skipping a primitive of mode {:?}", path.display(), prim.mode());
                    continue;
                }
                append_primitive(path, &prim, &buffers, &world, &mut mesh)?;
            }
        }
        stack.extend(node.children().map(|c| (c, world)));
    }
    mesh.validate(path)?;
    Ok(mesh)
}

fn append_primitive(
    path: &Path,
    prim: &gltf::Primitive,
    buffers: &[Vec<u8>],
    world: &Matrix4<Real>,
    mesh: &mut TriangleMesh,
) -> Result<()> {
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let base = mesh.positions.len() as u32;
    let positions: Vec<[f32; 3]> = reader
        .read_positions()
        .ok_or_else(|| Error::mesh(path, "a triangle primitive has no POSITION"))?
        .collect();
    let n = positions.len() as u32;
    mesh.positions.extend(positions.iter().map(|p| {
        world.transform_point(&Point3::new(p[0] as Real, p[1] as Real, p[2] as Real))
    }));
    let indices: Vec<u32> = match reader.read_indices() {
        Some(ix) => ix.into_u32().collect(),
        None => (0..n).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i >= n) {
        return Err(Error::mesh(path, format!("index {bad} is beyond the primitive's {n} vertices")));
    }
    // A mirroring node transform flips the winding.
    let flip = world.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
    mesh.triangles.extend(indices.chunks_exact(3).map(|t| {
        if flip {
            [t[0] + base, t[2] + base, t[1] + base]
        } else {
            [t[0] + base, t[1] + base, t[2] + base]
        }
    }));
    Ok(())
}

fn load_uri(path: &Path, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or_else(|| Error::parse(path, None, "only base64 data URIs are supported"))?;
        return decode_base64(payload).ok_or_else(|| Error::parse(path, None, "invalid base64 in a data URI"));
    }
    let file = path.parent().unwrap_or(Path::new("")).join(uri);
    std::fs::read(&file).map_err(|e| Error::io(&file, e))
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
