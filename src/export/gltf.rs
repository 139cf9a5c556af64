//! Binary glTF (GLB) through gltf-json: one mesh, optionally animated by morph
//! targets whose weights are keyed per frame.

use crate::error::{Error, Result};
use crate::mesh::TriangleMesh;
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use std::collections::BTreeMap;

/// How morph weights are interpolated between keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
}

/// Morph-target animation of a mesh: frame k's positions are
/// `base + Σ_t weights[k][t] · position_deltas[t]`.
#[derive(Clone, Debug)]
pub struct MorphAnimation {
    pub position_deltas: Vec<Vec<[f32; 3]>>,
    /// NORMAL deltas per target, same length as `position_deltas` when given.
    pub normal_deltas: Option<Vec<Vec<[f32; 3]>>>,
    /// One weight vector (one entry per target) per keyframe.
    pub weights: Vec<Vec<f32>>,
    /// Keyframe times in seconds.
    pub times: Vec<f32>,
    pub interpolation: Interpolation,
    pub target_names: Vec<String>,
}

/// Accumulates binary data and the views/accessors describing it.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8], target: Option<json::buffer::Target>) -> json::Index<json::buffer::View> {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
        let view = self.view(bytes, target);
        let (min, max) = match bounds {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    fn vec3(&mut self, data: &[[f32; 3]], with_bounds: bool, target: Option<json::buffer::Target>) -> json::Index<json::Accessor> {
        let bounds = with_bounds.then(|| bounds_of(data));
        self.accessor(
            &f32_bytes(data.iter().flatten().copied()),
            data.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            bounds,
            target,
        )
    }
}

fn f32_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// Exact per-component min and max, as glTF requires for POSITION.
fn bounds_of(data: &[[f32; 3]]) -> (Vec<f32>, Vec<f32>) {
    let mut lo = vec![f32::INFINITY; 3];
    let mut hi = vec![f32::NEG_INFINITY; 3];
    for p in data {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if data.is_empty() {
        (lo, hi) = (vec![0.0; 3], vec![0.0; 3]);
    }
    (lo, hi)
}

/// Encodes `mesh` (and its animation) as a GLB file.
pub fn glb_bytes(mesh: &TriangleMesh, animation: Option<&MorphAnimation>) -> Result<Vec<u8>> {
    let mut b = Builder { root: json::Root::default(), bin: Vec::new() };
    b.root.asset.generator = Some(format!("voltrack {}", env!("CARGO_PKG_VERSION")));
    let array = Some(json::buffer::Target::ArrayBuffer);
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| [p.x as f32, p.y as f32, p.z as f32]).collect();
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), b.vec3(&positions, true, array));
    let normals: Option<Vec<[f32; 3]>> = match (&mesh.normals, animation.is_some_and(|a| a.normal_deltas.is_some())) {
        (Some(n), _) => Some(n.clone()),
        (None, true) => Some(mesh.vertex_normals().iter().map(|n| [n.x as f32, n.y as f32, n.z as f32]).collect()),
        _ => None,
    };
    if let Some(n) = &normals {
        attributes.insert(Valid(json::mesh::Semantic::Normals), b.vec3(n, false, array));
    }
    if let Some(uv) = &mesh.uvs {
        let acc = b.accessor(
            &f32_bytes(uv.iter().flatten().copied()),
            uv.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec2,
            None,
            array,
        );
        attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), acc);
    }
    let idx: Vec<u8> = mesh.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
    let indices = b.accessor(
        &idx,
        mesh.triangles.len() * 3,
        json::accessor::ComponentType::U32,
        json::accessor::Type::Scalar,
        None,
        Some(json::buffer::Target::ElementArrayBuffer),
    );
    let material = match (&mesh.texture, &mesh.uvs) {
        (Some(tex), Some(_)) => Some(texture_material(&mut b, tex)?),
        _ => None,
    };
    let mut targets = None;
    let mut extras = None;
    let mut weights = None;
    if let Some(anim) = animation {
        let mut t = Vec::with_capacity(anim.position_deltas.len());
        for (k, d) in anim.position_deltas.iter().enumerate() {
            let normals = anim.normal_deltas.as_ref().map(|n| b.vec3(&n[k], false, array));
            t.push(json::mesh::MorphTarget { positions: Some(b.vec3(d, true, array)), normals, tangents: None });
        }
        targets = Some(t);
        weights = Some(vec![0.0; anim.position_deltas.len()]);
        let names = serde_json::json!({ "targetNames": anim.target_names });
        extras = Some(serde_json::value::to_raw_value(&names).map_err(|e| Error::InvalidInput(e.to_string()))?);
    }
    let primitive = json::mesh::Primitive {
        attributes,
        extensions: None,
        extras: Default::default(),
        indices: Some(indices),
        material,
        mode: Valid(json::mesh::Mode::Triangles),
        targets,
    };
    let mesh_index = b.root.push(json::Mesh {
        extensions: None,
        extras,
        name: Some("voltrack".into()),
        primitives: vec![primitive],
        weights,
    });
    let node = b.root.push(json::Node { mesh: Some(mesh_index), name: Some("voltrack".into()), ..Default::default() });
    let scene = b.root.push(json::Scene { extensions: None, extras: Default::default(), name: None, nodes: vec![node] });
    b.root.scene = Some(scene);
    if let Some(anim) = animation {
        add_weight_animation(&mut b, anim, node);
    }
    while b.bin.len() % 4 != 0 {
        b.bin.push(0);
    }
    b.root.push(json::Buffer { byte_length: USize64::from(b.bin.len()), name: None, uri: None, extensions: None, extras: Default::default() });
    let mut json_bytes = b.root.to_vec().map_err(|e| Error::InvalidInput(e.to_string()))?;
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
        json: json_bytes.into(),
        bin: Some(b.bin.into()),
    };
    glb.to_vec().map_err(|e| Error::InvalidInput(e.to_string()))
}

fn add_weight_animation(b: &mut Builder, anim: &MorphAnimation, node: json::Index<json::Node>) {
    let tmin = anim.times.iter().copied().fold(f32::INFINITY, f32::min);
    let tmax = anim.times.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let input = b.accessor(
        &f32_bytes(anim.times.iter().copied()),
        anim.times.len(),
        json::accessor::ComponentType::F32,
        json::accessor::Type::Scalar,
        Some((vec![tmin], vec![tmax])),
        None,
    );
    let flat: Vec<f32> = anim.weights.iter().flatten().copied().collect();
    let output = b.accessor(
        &f32_bytes(flat.iter().copied()),
        flat.len(),
        json::accessor::ComponentType::F32,
        json::accessor::Type::Scalar,
        None,
        None,
    );
    let interpolation = match anim.interpolation {
        Interpolation::Step => json::animation::Interpolation::Step,
        Interpolation::Linear => json::animation::Interpolation::Linear,
    };
    let sampler = json::animation::Sampler { extensions: None, extras: Default::default(), input, interpolation: Valid(interpolation), output };
    let channel = json::animation::Channel {
        sampler: json::Index::new(0),
        target: json::animation::Target {
            extensions: None,
            extras: Default::default(),
            node,
            path: Valid(json::animation::Property::MorphTargetWeights),
        },
        extensions: None,
        extras: Default::default(),
    };
    b.root.push(json::Animation {
        extensions: None,
        extras: Default::default(),
        channels: vec![channel],
        name: Some("capture".into()),
        samplers: vec![sampler],
    });
}

/// Embeds the first frame's texture image as-is (PNG or JPEG) in the GLB.
fn texture_material(b: &mut Builder, path: &std::path::Path) -> Result<json::Index<json::Material>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let mime = if bytes.starts_with(b"\x89PNG") {
        "image/png"
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        "image/jpeg"
    } else {
        return Err(Error::parse(path, None, "texture is neither PNG nor JPEG"));
    };
    let view = b.view(&bytes, None);
    let image = b.root.push(json::Image {
        buffer_view: Some(view),
        mime_type: Some(json::image::MimeType(mime.into())),
        name: path.file_name().map(|n| n.to_string_lossy().into_owned()),
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let texture = b.root.push(json::Texture { name: None, sampler: None, source: image, extensions: None, extras: Default::default() });
    Ok(b.root.push(json::Material {
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: Some(json::texture::Info { index: texture, tex_coord: 0, extensions: None, extras: Default::default() }),
            metallic_factor: json::material::StrengthFactor(0.0),
            ..Default::default()
        },
        double_sided: true,
        ..Default::default()
    }))
}
