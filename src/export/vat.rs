//! Vertex-animation textures (VAT) laid out as game engines read them
//! (SideFX's VAT, the Unity and Unreal shaders built on it): every frame's
//! vertex positions in one float texture, vertices wrapped into rows of at
//! most [`VatOptions::max_width`] texels and frames stacked below each other;
//! a static mesh beside it whose second UV set (TEXCOORD_1) addresses each
//! vertex's texel; and a JSON sidecar ([`VatInfo`]) saying how to decode it.
//!
//! For `anim.exr` the files are `anim.exr` (the texture), `anim.glb` (the
//! mesh) and `anim.json` (the sidecar), written all or none.

use super::basis::check_frames;
use super::exr::PointImage;
use super::gltf::{glb_bytes_with, GlbExtras, SceneInfo, Timing};
use super::normals::FrameNormals;
use crate::error::{Error, Result};
use crate::files::write_atomic_all;
use crate::math::{Point3, Real};
use crate::model::mesh::TriangleMesh;
use crate::model::DynamicMesh;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What every VAT sidecar holds near its start (its `software` field), by
/// which a rerun knows it may replace the file.
pub const SIDECAR_MARK: &str = "\"software\": \"voltrack ";

/// What the mesh beside a VAT holds near the start of its JSON chunk (its
/// asset's `extras`), by which a rerun knows it may replace the file. Not
/// the generator alone: a morph-target GLB voltrack wrote under that name
/// is the user's output, not a VAT's mesh.
pub const MESH_MARK: &str = "\"voltrack\":\"vertex-animation mesh\"";

/// Largest texture side [`VatOptions`] accept: beyond every GPU's limit.
pub const MAX_TEXTURE_SIDE: usize = 65_536;

/// How [`write_vat`] lays out the texture.
#[derive(Clone, Debug, PartialEq)]
pub struct VatOptions {
    /// Capture rate, recorded in the sidecar and the mesh's scene `extras`.
    /// Default 30; in [0.001, 100000].
    pub fps: f32,
    /// Name of the mesh's node and mesh. Default
    /// [`DEFAULT_NAME`](crate::model::DEFAULT_NAME); not blank, no control characters.
    pub name: String,
    /// Most vertices per texture row: the texture's width is the vertex count
    /// up to this, and a frame takes as many rows as its vertices need.
    /// Default 8192, within the texture size GPUs commonly accept;
    /// 1 ..= [`MAX_TEXTURE_SIDE`].
    pub max_width: usize,
    /// Largest texture height (frames × rows per frame, rounded up to a power
    /// of two with `power_of_two`): a longer animation is refused, not
    /// written as a texture no GPU loads. Default 16384; 1 ..=
    /// [`MAX_TEXTURE_SIDE`].
    pub max_height: usize,
    /// Both sides powers of two, for engines and compressors that need them:
    /// rows of the power of two at or above the vertex count (at most the
    /// largest one within `max_width`), the height padded with zero texels.
    /// Default false.
    pub power_of_two: bool,
}

impl Default for VatOptions {
    fn default() -> Self {
        VatOptions {
            fps: 30.0,
            name: crate::model::DEFAULT_NAME.into(),
            max_width: 8192,
            max_height: 16384,
            power_of_two: false,
        }
    }
}

impl VatOptions {
    /// Checks the options before any work is done.
    pub fn validate(&self) -> Result<()> {
        crate::params::check(
            "the frame rate",
            self.fps as Real,
            crate::params::Span::closed(1e-3, 1e5),
        )?;
        crate::model::check_name(&self.name)?;
        crate::params::check_count(
            "the texture's largest width",
            self.max_width,
            1..=MAX_TEXTURE_SIDE,
        )?;
        crate::params::check_count(
            "the texture's largest height",
            self.max_height,
            1..=MAX_TEXTURE_SIDE,
        )?;
        Ok(())
    }

    /// Checks what can be known before the mesh exists: that `frames`
    /// frames fit the height at one row each.
    pub fn check_frames(&self, frames: usize) -> Result<()> {
        self.validate()?;
        match self.layout(1, frames) {
            Ok(_) => Ok(()),
            Err(_) => Err(Error::InvalidParameter(format!(
                "{frames} frames need a vertex-animation texture at least {frames} rows high, more than the largest height allowed, {} \
                 (--vat-max-height); convert fewer frames",
                self.max_height
            ))),
        }
    }

    /// Where `vertices` vertices of `frames` frames go; an error if the
    /// texture would be higher than [`max_height`](Self::max_height).
    pub fn layout(&self, vertices: usize, frames: usize) -> Result<VatLayout> {
        self.validate()?;
        if vertices == 0 || frames == 0 {
            return Err(Error::InvalidInput(format!(
                "a vertex-animation texture of {vertices} vertices and {frames} frames is empty"
            )));
        }
        let width = if self.power_of_two {
            let widest = 1usize << self.max_width.ilog2();
            vertices.next_power_of_two().min(widest)
        } else {
            vertices.min(self.max_width)
        };
        let rows_per_frame = vertices.div_ceil(width);
        let rows = frames.saturating_mul(rows_per_frame);
        let height = if self.power_of_two {
            rows.checked_next_power_of_two().unwrap_or(usize::MAX)
        } else {
            rows
        };
        if height > self.max_height {
            let padded = if self.power_of_two && height != rows {
                format!(", {height} as a power of two")
            } else {
                String::new()
            };
            return Err(Error::InvalidParameter(format!(
                "{vertices} vertices in rows of {width} take {rows_per_frame} rows per frame, {rows} rows for {frames} frames{padded}: \
                 more than the largest vertex-animation texture height allowed, {}; allow wider rows (--vat-max-width) or a higher \
                 texture (--vat-max-height), or convert fewer frames",
                self.max_height
            )));
        }
        Ok(VatLayout {
            vertices,
            frames,
            width,
            height,
            rows_per_frame,
        })
    }
}

/// Where each vertex of each frame lies in the texture: vertex v of frame f
/// at column v mod `width`, row f × `rows_per_frame` + v div `width`, row 0
/// being the image's first (top) row. Texels no vertex uses are zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VatLayout {
    /// Vertices per frame.
    pub vertices: usize,
    /// Frames in the texture.
    pub frames: usize,
    /// Texture width: vertices per row.
    pub width: usize,
    /// Texture height: at least frames × rows per frame.
    pub height: usize,
    /// Texture rows one frame takes: vertices divided by `width`, rounded up.
    pub rows_per_frame: usize,
}

impl VatLayout {
    /// (column, row) of vertex `v` in frame `f`.
    pub fn texel(&self, v: usize, f: usize) -> (usize, usize) {
        (v % self.width, f * self.rows_per_frame + v / self.width)
    }

    /// The vertex and frame a texel holds, if any.
    pub fn vertex_at(&self, column: usize, row: usize) -> Option<(usize, usize)> {
        let (f, v) = (
            row / self.rows_per_frame,
            (row % self.rows_per_frame) * self.width + column,
        );
        (column < self.width && f < self.frames && v < self.vertices).then_some((v, f))
    }

    /// TEXCOORD_1 of vertex `v`: the center of its frame-0 texel, with (0, 0)
    /// at the image's top-left corner, as glTF's UVs.
    pub fn uv(&self, v: usize) -> [f32; 2] {
        let (column, row) = self.texel(v, 0);
        [
            ((column as f64 + 0.5) / self.width as f64) as f32,
            ((row as f64 + 0.5) / self.height as f64) as f32,
        ]
    }

    /// How far UV v moves from one frame to the next.
    pub fn frame_v_step(&self) -> f64 {
        self.rows_per_frame as f64 / self.height as f64
    }
}

/// The JSON sidecar of a VAT (and the texture's `vat` header attribute):
/// what a shader or importer needs to decode it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VatInfo {
    /// "voltrack VERSION"; first, so [`SIDECAR_MARK`] is near the start.
    pub software: String,
    /// File name of the texture, beside the sidecar.
    pub texture: String,
    /// File name of the mesh, beside the sidecar.
    pub mesh: String,
    /// Capture rate, frames per second ([`VatOptions::fps`]).
    pub fps: f32,
    /// Frames in the texture.
    pub frames: usize,
    /// Vertices per frame, as in the mesh.
    pub vertices: usize,
    /// Texture width in texels.
    pub width: usize,
    /// Texture height in texels.
    pub height: usize,
    /// Texture rows per frame: frame f starts at row f × rows_per_frame.
    pub rows_per_frame: usize,
    /// Whether both sides are powers of two ([`VatOptions::power_of_two`]).
    pub power_of_two: bool,
    /// How the texels are laid out, in words.
    pub layout: String,
    /// Which way rows run.
    pub row_order: String,
    /// The mesh attribute addressing each vertex's texel.
    pub uv_set: String,
    /// How that UV addresses the texel, in words.
    pub uv: String,
    /// rows_per_frame / height: add f × this to the UV's v for frame f.
    pub frame_v_step: f64,
    /// Lowest corner of the box around every position of every frame, for
    /// shaders that take normalised textures.
    pub bounds_min: [Real; 3],
    /// Highest corner of that box.
    pub bounds_max: [Real; 3],
}

/// What [`write_vat`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct VatReport {
    /// Where each vertex of each frame went in the texture.
    pub layout: VatLayout,
    /// Sizes of the texture, the mesh and the sidecar.
    pub bytes: [u64; 3],
}

/// The mesh and the JSON sidecar written beside a texture at `path`.
pub fn files_beside(path: &Path) -> (PathBuf, PathBuf) {
    (path.with_extension("glb"), path.with_extension("json"))
}

/// Writes the frames of `mesh` as a vertex-animation texture at `path` (an
/// RGB float32 OpenEXR, ZIP-compressed, RGB = absolute x, y, z in the
/// input's units, laid out as [`VatLayout`] says), frame 0 as a static GLB
/// at `path.with_extension("glb")` (normals, the UVs and texture it has as
/// TEXCOORD_0, TEXCOORD_1 = [`VatLayout::uv`], repeated as TEXCOORD_0 when
/// the mesh has no UVs), and [`VatInfo`] as
/// `path.with_extension("json")` ([`files_beside`]); all three or none.
pub fn write_vat(path: &Path, mesh: &DynamicMesh, options: &VatOptions) -> Result<VatReport> {
    let (mesh_path, sidecar) = files_beside(path);
    if sidecar == path || mesh_path == path {
        return Err(Error::write(
            path,
            "the texture would overwrite its JSON sidecar or its mesh; name it .exr",
        ));
    }
    let file_name = |p: &Path| {
        p.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let names = VatNames {
        texture: &file_name(path),
        mesh: &file_name(&mesh_path),
        sidecar: &file_name(&sidecar),
    };
    let vat = PreparedVat::new(mesh, options, &names, &sidecar)?;
    let mut texture_bytes = 0;
    let mut failed = None;
    // All or none: the texture cannot be decoded without the other two.
    let written = write_atomic_all(vec![
        (
            path,
            Box::new(|w: &mut _| {
                vat.texture(w, path)
                    .map(|n| texture_bytes = n)
                    .map_err(|e| {
                        let io = std::io::Error::other(e.to_string());
                        failed = Some(e);
                        io
                    })
            }),
        ),
        (&mesh_path, Box::new(|w: &mut _| w.write_all(&vat.glb))),
        (
            &sidecar,
            Box::new(|w: &mut _| w.write_all(vat.text.as_bytes())),
        ),
    ]);
    // A frame that could not be read is that error, not a failure to write.
    if let Some(e) = failed {
        return Err(e);
    }
    written?;
    Ok(vat.report(texture_bytes))
}

/// The file names a VAT's three files go by: each names the others inside
/// (the sidecar its texture and mesh, the mesh its sidecar).
#[derive(Clone, Copy, Debug)]
pub struct VatNames<'a> {
    /// The texture's file name.
    pub texture: &'a str,
    /// The mesh's file name.
    pub mesh: &'a str,
    /// The JSON sidecar's file name.
    pub sidecar: &'a str,
}

/// [`write_vat`] into three writers of the caller's, whose files go by
/// `names`: the texture into `texture`, the mesh into `glb`, the sidecar
/// into `sidecar`. What was written before an error stays written.
pub fn write_vat_to(
    texture: &mut (impl std::io::Write + std::io::Seek),
    glb: &mut impl std::io::Write,
    sidecar: &mut impl std::io::Write,
    names: &VatNames,
    mesh: &DynamicMesh,
    options: &VatOptions,
) -> Result<VatReport> {
    let vat = PreparedVat::new(mesh, options, names, Path::new(names.sidecar))?;
    let texture_bytes = vat.texture(texture, Path::new(names.texture))?;
    glb.write_all(&vat.glb).map_err(Error::WriteStream)?;
    sidecar
        .write_all(vat.text.as_bytes())
        .map_err(Error::WriteStream)?;
    Ok(vat.report(texture_bytes))
}

/// A VAT ready to write: its layout, the texture's metadata, the mesh and
/// the sidecar; the texture itself is encoded as it is written.
struct PreparedVat<'a> {
    mesh: &'a DynamicMesh,
    layout: VatLayout,
    attrs: serde_json::Map<String, serde_json::Value>,
    glb: Vec<u8>,
    text: String,
}

impl<'a> PreparedVat<'a> {
    /// `sidecar` names the sidecar in errors.
    fn new(
        mesh: &'a DynamicMesh,
        options: &VatOptions,
        names: &VatNames,
        sidecar: &Path,
    ) -> Result<Self> {
        options.validate()?;
        check_frames(mesh)?;
        let layout = options.layout(mesh.base.positions.len(), mesh.frames.len())?;
        let bounds = mesh.frames.bounds()?;
        let info = VatInfo {
            software: concat!("voltrack ", env!("CARGO_PKG_VERSION")).into(),
            texture: names.texture.into(),
            mesh: names.mesh.into(),
            fps: options.fps,
            frames: layout.frames,
            vertices: layout.vertices,
            width: layout.width,
            height: layout.height,
            rows_per_frame: layout.rows_per_frame,
            power_of_two: options.power_of_two,
            layout: "vertex v (the mesh's order) of frame f at column v mod width, row f × rows_per_frame + v div width; \
                     RGB = its absolute x, y, z (float32); texels no vertex uses are 0"
                .into(),
            row_order: "top to bottom: row 0 is the image's first (top) row, frame 0's first vertices; frames follow downward".into(),
            uv_set: "TEXCOORD_1".into(),
            uv: "TEXCOORD_1 of vertex v is the center of its frame-0 texel, ((column + 0.5) / width, (row + 0.5) / height), \
                 origin at the image's top-left corner as in glTF; frame f is at (u, v + f × frame_v_step) \
                 (a mesh without UVs of its own has the same in TEXCOORD_0). \
                 Where v = 0 is the bottom row (OpenGL, Unity, Unreal after a glTF import flips v to 1 − v), frame f is at 1 − v − f × frame_v_step"
                .into(),
            frame_v_step: layout.frame_v_step(),
            bounds_min: [bounds.min.x, bounds.min.y, bounds.min.z],
            bounds_max: [bounds.max.x, bounds.max.y, bounds.max.z],
        };
        let mut attrs = serde_json::Map::new();
        attrs.insert(
            "vat".into(),
            serde_json::to_value(&info).map_err(|e| Error::write(sidecar, e))?,
        );
        let glb = mesh_bytes(mesh, &layout, options, &info.texture, names.sidecar)?;
        let text = serde_json::to_string_pretty(&info).map_err(|e| Error::write(sidecar, e))?;
        Ok(PreparedVat {
            mesh,
            layout,
            attrs,
            glb,
            text,
        })
    }

    /// The texture into `w` (`path` names it in errors); its length in bytes.
    /// It is encoded as the rows are asked for, frame after frame, each read
    /// once: no frame but the current one is held. A frame that cannot be
    /// read is that error.
    fn texture(&self, w: &mut (impl std::io::Write + std::io::Seek), path: &Path) -> Result<u64> {
        let (mesh, layout) = (self.mesh, &self.layout);
        let current = Mutex::new(Frame {
            index: usize::MAX,
            positions: Vec::new(),
            failed: None,
        });
        let pixel = |x: usize, y: usize| match layout.vertex_at(x, y) {
            Some((v, f)) => current
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .position(mesh, f, v),
            None => Point3::origin(),
        };
        let image = PointImage {
            path,
            name: "vertex animation",
            width: layout.width,
            height: layout.height,
            pixel,
            meta: self.attrs.clone(),
        };
        let streamed = image.stream(w);
        let unread = current
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .failed
            .take();
        match unread {
            Some(e) => Err(e),
            None => streamed,
        }
    }

    fn report(&self, texture_bytes: u64) -> VatReport {
        VatReport {
            layout: self.layout,
            bytes: [texture_bytes, self.glb.len() as u64, self.text.len() as u64],
        }
    }
}

/// The frame whose texels are being written, read when its first is asked for.
struct Frame {
    index: usize,
    positions: Vec<Point3>,
    /// The first frame that could not be read; its texels are written as 0
    /// and the file discarded.
    failed: Option<Error>,
}

impl Frame {
    /// Vertex `v`'s position in frame `f`.
    fn position(&mut self, mesh: &DynamicMesh, f: usize, v: usize) -> Point3 {
        if self.index != f {
            match mesh.frames.get(f) {
                Ok(frame) => self.positions = frame.into_owned(),
                Err(e) => {
                    self.failed.get_or_insert(e);
                    self.positions.clear();
                }
            }
            self.index = f;
        }
        self.positions
            .get(v)
            .copied()
            .unwrap_or_else(Point3::origin)
    }
}

/// The static GLB beside the texture: frame 0 with its normals, UVs and
/// texture, TEXCOORD_1 addressing the texels, and [`MESH_MARK`] with the
/// companion files' names in the asset's `extras`.
fn mesh_bytes(
    mesh: &DynamicMesh,
    layout: &VatLayout,
    options: &VatOptions,
    texture: &str,
    sidecar: &str,
) -> Result<Vec<u8>> {
    let frame0 = mesh.frames.get(0)?;
    let normals = FrameNormals::new(&mesh.base, &frame0).base;
    let uv1: Vec<[f32; 2]> = (0..layout.vertices).map(|v| layout.uv(v)).collect();
    // glTF numbers UV sets from 0: a mesh without UVs of its own repeats the
    // texel addresses there.
    let uvs = mesh.base.uvs.clone().unwrap_or_else(|| uv1.clone());
    let base = TriangleMesh {
        positions: frame0.into_owned(),
        triangles: mesh.base.triangles.clone(),
        normals: Some(
            normals
                .iter()
                .map(|n| [n.x as f32, n.y as f32, n.z as f32])
                .collect(),
        ),
        texture: mesh.base.uvs.as_ref().and(mesh.base.texture.clone()),
        uvs: Some(uvs),
    };
    // Written by hand, not through serde_json, so its text is MESH_MARK's.
    let asset = format!(
        "{{{MESH_MARK},\"texture\":{},\"sidecar\":{}}}",
        serde_json::Value::from(texture),
        serde_json::Value::from(sidecar)
    );
    let asset = serde_json::value::RawValue::from_string(asset)
        .map_err(|e| Error::InvalidInput(e.to_string()))?;
    let scene = SceneInfo {
        name: options.name.clone(),
        timing: Some(Timing {
            fps: options.fps,
            frames: layout.frames,
        }),
        compress: false,
    };
    glb_bytes_with(
        &base,
        None,
        &scene,
        GlbExtras {
            uv1: Some(&uv1),
            asset: Some(asset),
            ..Default::default()
        },
    )
}
