//! Binary glTF (GLB) through gltf-json: one mesh, optionally animated by morph
//! targets whose weights are keyed per frame.
//!
//! [`write_dynamic_glb`] is the dynamic-mesh export: one mesh whose morph
//! targets (per frame, or a compact PCA basis, see [`super::basis`]) replay the
//! captured sequence in Blender, three.js and other glTF viewers.

pub use super::basis::BasisChoice;
use super::basis::{self, MorphBasis};
use super::normals::FrameNormals;
use crate::error::{Error, Result};
use crate::math::{Point3, Real, Vector3};
use crate::model::mesh::TriangleMesh;
use crate::model::DynamicMesh;
use crate::model::PositionFrames;
use crate::progress::{Counter, Progress, Stage};
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use rayon::prelude::*;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

/// How [`write_dynamic_glb`] encodes the animation.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfExportOptions {
    /// Capture rate in frames per second: frame f is keyed at f / fps seconds
    /// and shown until (f + 1) / fps. Default 30; in [0.001, 100000].
    pub fps: f32,
    /// Name of the node, the mesh and the animation: what Blender calls the
    /// object and its action, and three.js the object and its clip. Default
    /// [`DEFAULT_NAME`](crate::model::DEFAULT_NAME); not blank, no control characters.
    pub name: String,
    /// Morph basis: one target per frame, a fixed number of principal
    /// components, or chosen by length and error. Default [`BasisChoice::Auto`].
    pub basis: BasisChoice,
    /// Largest vertex error [`BasisChoice::Auto`] accepts from a compact basis,
    /// as a fraction of the bounding-box diagonal of the whole animation.
    /// Default 0.001; finite and ≥ 0 (0 means per-frame targets past 256 frames
    /// unless a basis reproduces the motion exactly).
    pub max_basis_error: Real,
    /// Write vertex normals (recomputed from the geometry of every frame) and
    /// their NORMAL morph deltas, so lighting follows the deformation. Without
    /// them the file has no normals and viewers derive them (three.js shades
    /// flat). Default true.
    pub normals: bool,
    /// Write a compressed file ([`SceneInfo::compress`]): positions, normals
    /// and their morph deltas quantised (KHR_mesh_quantization), vertex and
    /// index data encoded with meshoptimizer (EXT_meshopt_compression), both
    /// extensions required. The report's reconstruction error then includes
    /// the quantisation. Default false.
    pub compress: bool,
    /// The frames' names (the input files' stems), which per-frame targets
    /// are named after: frame `f`'s target is `frame_names[f]`. Default
    /// empty: `frame_0001`, `frame_0002`, … by index, as also where the
    /// names are not one per frame or not distinct.
    pub frame_names: Vec<String>,
    /// How players go from one capture to the next, the same for per-frame
    /// targets and a compact basis. [`Interpolation::Step`] (default) holds
    /// each capture for 1/fps: a player shows what was captured and nothing
    /// else. [`Interpolation::Linear`] blends consecutive captures, smoother
    /// where the display rate is above the capture rate; the poses between
    /// captures are then blends (a limb moving fast is drawn shorter
    /// between two captures), not captures.
    pub interpolation: Interpolation,
    /// Also measure the compact bases the choice tried (by error:
    /// [`BasisChoice::Auto`], [`BasisChoice::Bounded`]), each encoded as this
    /// file would be, for [`GltfExportReport::rate_distortion`]. Costs an
    /// encoding per basis tried. Default false.
    pub rate_distortion: bool,
}

impl Default for GltfExportOptions {
    fn default() -> Self {
        GltfExportOptions {
            fps: 30.0,
            name: crate::model::DEFAULT_NAME.into(),
            basis: BasisChoice::Auto,
            max_basis_error: 0.001,
            interpolation: Interpolation::Step,
            rate_distortion: false,
            normals: true,
            compress: false,
            frame_names: Vec::new(),
        }
    }
}

impl GltfExportOptions {
    /// Checks the options before any work is done.
    pub fn validate(&self) -> Result<()> {
        if self.basis == BasisChoice::Components(0) {
            return Err(Error::InvalidParameter(
                "a compact basis needs at least one component".into(),
            ));
        }
        crate::params::check(
            "the frame rate",
            self.fps as Real,
            crate::params::Span::closed(1e-3, 1e5),
        )?;
        crate::model::check_name(&self.name)?;
        if let BasisChoice::Components(k) = self.basis {
            crate::params::check_count(
                "the basis components",
                k,
                1..=crate::params::MAX_ITERATIONS,
            )?;
        }
        if let BasisChoice::Bounded { mean, max } = self.basis {
            if ![mean, max].iter().all(|b| b.is_finite() && *b >= 0.0) {
                return Err(Error::InvalidParameter(format!(
                    "the basis error bounds must be non-negative lengths, not {mean} (mean) and {max} (largest)"
                )));
            }
        }
        if !(self.max_basis_error.is_finite() && self.max_basis_error >= 0.0) {
            return Err(Error::InvalidParameter(format!(
                "the basis error bound must be a non-negative fraction, not {}",
                self.max_basis_error
            )));
        }
        Ok(())
    }
}

/// What [`write_dynamic_glb`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfExportReport {
    /// Morph targets in the file (0 for a single frame or no motion).
    pub targets: usize,
    /// Principal components of the compact basis, `None` for per-frame targets.
    pub basis: Option<usize>,
    /// Largest vertex error of the basis over all frames, as a fraction of the
    /// animation's bounding-box diagonal (0 for per-frame targets; f32
    /// rounding of the file, ~1e-7, not included). For a compressed file, the
    /// error of the positions the file decodes to (dequantised, at every
    /// frame's keyed weights) against the captured frames: basis and
    /// quantisation together.
    pub reconstruction_error_max: Real,
    /// Mean vertex error over all frames and vertices, same unit.
    pub reconstruction_error_mean: Real,
    /// Size of the file.
    pub bytes: u64,
    /// Whether the file is compressed ([`GltfExportOptions::compress`]).
    pub compressed: bool,
    /// Whether the targets are steps from frame to frame (a compressed file
    /// with one target per frame): target k holds the change from the frame
    /// of target k − 1 (frame 0 for the first) to its own, and each frame
    /// keys every step up to its own at weight 1, so a shape key alone shows
    /// a step, not a pose. Otherwise each frame keys its own target (or its
    /// basis weights).
    pub steps: bool,
    /// With [`GltfExportOptions::rate_distortion`], the compact bases the
    /// choice tried, by increasing size, each as this file would be with it.
    pub rate_distortion: Vec<RateRow>,
}

/// One basis of a rate-distortion table: its size and its error.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RateRow {
    /// Principal components (None: one target per frame).
    pub components: Option<usize>,
    /// Morph targets the basis takes.
    pub targets: usize,
    /// The file's size with this basis.
    pub bytes: u64,
    /// Reconstruction error, largest and mean, as fractions of the
    /// animation's diagonal ([`GltfExportReport::reconstruction_error_max`]:
    /// with the quantisation for a compressed file).
    pub error_max: Real,
    /// The mean error, same unit.
    pub error_mean: Real,
    /// Whether it is the basis written.
    pub chosen: bool,
}

impl RateRow {
    /// The row of `basis`: a file of `bytes` whose reconstruction error is
    /// (largest, mean) in scene units, of an animation of this `diagonal`.
    fn of(
        basis: &MorphBasis,
        bytes: u64,
        (max, mean): (Real, Real),
        diagonal: Real,
        chosen: bool,
    ) -> Self {
        let relative = |e: Real| if diagonal > 0.0 { e / diagonal } else { 0.0 };
        RateRow {
            components: basis.components,
            targets: basis.targets(),
            bytes,
            error_max: relative(max),
            error_mean: relative(mean),
            chosen,
        }
    }
}

/// Writes `mesh` as a GLB holding one mesh: frame 0 as the base, morph targets
/// from the basis `options` selects, and one animation of the node's morph
/// weights with one keyframe per frame at f / fps and a closing key at
/// F / fps that holds the last frame, so the clip lasts F / fps and a player
/// that loops it (three.js' default) shows every frame for 1 / fps instead
/// of wrapping at the last one. Per-frame targets are keyed STEP with a
/// one-hot weight vector (all zero at frame 0); a compact basis is keyed
/// LINEAR. Node, mesh and animation are called `options.name`; the scene's
/// and the animation's `extras` hold the frame rate and the frame count
/// ([`Timing`]), which glTF has no field for. `mesh.extras.targetNames`
/// names the targets (Blender's shape keys, three.js'
/// `morphTargetDictionary`). UVs and
/// the first frame's texture are carried over; normals as `options.normals`
/// says (the base mesh's loaded normals are not used: they would not match
/// the recomputed ones of the other frames). Progress is reported under
/// [`Stage::Export`]; a stop request returns
/// [`Error::Interrupted`] and writes nothing.
pub fn write_dynamic_glb(
    path: &Path,
    mesh: &DynamicMesh,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<GltfExportReport> {
    dynamic_glb(mesh, options, progress, |glb, animation, failed| {
        crate::files::write_atomic(path, |w| glb.write(w, animation, progress, failed))
    })
}

/// [`write_dynamic_glb`] into any writer (a `Vec<u8>`, a socket): the same
/// bytes. What was written before an error stays written: the caller owns
/// the writer.
///
/// ```
/// # use voltrack::pipeline::{convert, ConvertOptions};
/// # use voltrack::{params::TrackParams, voxel::VoxelParams, TriangleMesh};
/// # use voltrack::math::{Point3, Real};
/// use voltrack::export::gltf::{write_dynamic_glb_to, GltfExportOptions};
/// # fn boxed(x: Real) -> TriangleMesh {
/// #     let positions = (0..8)
/// #         .map(|i| Point3::new(x + (i & 1) as Real, 0.6 * ((i >> 1) & 1) as Real, 0.4 * (i >> 2) as Real))
/// #         .collect();
/// #     let triangles = vec![
/// #         [0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
/// #         [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5],
/// #     ];
/// #     TriangleMesh { positions, triangles, ..Default::default() }
/// # }
/// // Three frames of a box moving along x, converted and encoded in memory.
/// let frames: Vec<TriangleMesh> = (0..3).map(|f| boxed(0.1 * f as Real)).collect();
/// let options = ConvertOptions {
///     voxel: VoxelParams { resolution: 24, ..Default::default() },
///     track: TrackParams { centers: 40, ..Default::default() },
///     ..Default::default()
/// };
/// let result = convert(&frames, &options, Default::default())?;
/// let mut glb = Vec::new();
/// let report = write_dynamic_glb_to(&mut glb, &result.mesh, &GltfExportOptions::default(), Default::default())?;
/// assert_eq!(&glb[..4], b"glTF");
/// assert_eq!(report.bytes, glb.len() as u64);
/// assert_eq!(report.targets, 2); // frames 1 and 2 against frame 0
/// # Ok::<(), voltrack::Error>(())
/// ```
pub fn write_dynamic_glb_to(
    w: &mut impl std::io::Write,
    mesh: &DynamicMesh,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<GltfExportReport> {
    dynamic_glb(mesh, options, progress, |glb, animation, failed| {
        glb.write(w, animation, progress, failed)
            .map_err(Error::WriteStream)
    })
}

/// [`write_dynamic_glb`] as a `.gltf` file: the same JSON with the binary
/// buffer embedded as a base64 `data:` URI, so the file stands alone (a
/// third larger than the GLB) and is written in one step like any other.
/// The report's `bytes` are the `.gltf` file's.
pub fn write_dynamic_gltf(
    path: &Path,
    mesh: &DynamicMesh,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<GltfExportReport> {
    let mut written = 0;
    let mut report = dynamic_glb(mesh, options, progress, |glb, animation, failed| {
        let mut bytes = Vec::with_capacity(glb.length()? as usize);
        glb.write(&mut bytes, animation, progress, failed)
            .map_err(Error::WriteStream)?;
        let text = embedded_gltf(&bytes)?;
        written = text.len() as u64;
        crate::files::write_atomic(path, |w| std::io::Write::write_all(w, text.as_bytes()))
    })?;
    report.bytes = written;
    Ok(report)
}

/// The `.gltf` text of a GLB of ours: its JSON chunk with the BIN chunk as
/// the first buffer's `data:` URI.
fn embedded_gltf(glb: &[u8]) -> Result<String> {
    let invalid = |e: &dyn std::fmt::Display| Error::InvalidInput(e.to_string());
    let glb = gltf::binary::Glb::from_slice(glb).map_err(|e| invalid(&e))?;
    let bin = glb.bin.as_deref().unwrap_or_default();
    let mut root: serde_json::Value = serde_json::from_slice(&glb.json).map_err(|e| invalid(&e))?;
    let buffer = root
        .get_mut("buffers")
        .and_then(|b| b.get_mut(0))
        .and_then(|b| b.as_object_mut())
        .ok_or_else(|| Error::InvalidInput("a GLB without a buffer".into()))?;
    let length = buffer
        .get("byteLength")
        .and_then(|l| l.as_u64())
        .unwrap_or(0) as usize;
    let data = bin
        .get(..length)
        .ok_or_else(|| Error::InvalidInput("the BIN chunk is shorter than its buffer".into()))?;
    buffer.insert(
        "uri".into(),
        format!("data:application/octet-stream;base64,{}", base64(data)).into(),
    );
    serde_json::to_string(&root).map_err(|e| invalid(&e))
}

/// Standard base64 with padding (RFC 4648 §4), as `data:` URIs take it.
fn base64(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for group in bytes.chunks(3) {
        let n = group
            .iter()
            .enumerate()
            .fold(0u32, |n, (k, &b)| n | (b as u32) << (16 - 8 * k));
        for k in 0..4 {
            out.push(if k <= group.len() {
                DIGITS[(n >> (18 - 6 * k) & 63) as usize] as char
            } else {
                '='
            });
        }
    }
    out
}

/// Encodes `mesh` as [`write_dynamic_glb`] says and hands the parts to
/// `emit`, which writes them and puts a failure other than its writer's in
/// `failed` (see `GlbParts::write`).
fn dynamic_glb(
    mesh: &DynamicMesh,
    options: &GltfExportOptions,
    progress: Progress,
    emit: impl FnOnce(&GlbParts, Option<&MorphAnimation>, &mut Option<Error>) -> Result<()>,
) -> Result<GltfExportReport> {
    options.validate()?;
    basis::check_frames(mesh)?;
    let frames = &mesh.frames;
    let diagonal = frames.bounds()?.diagonal();
    let (mut basis, error, trials) = basis::choose_with_trials(
        frames,
        options.basis,
        options.max_basis_error * diagonal,
        progress,
    )?;
    if basis.components.is_none() {
        name_targets_after_frames(&mut basis, &options.frame_names);
    }
    let (base, normals) = base_mesh(mesh, options.normals)?;
    // One target per frame, when a compressed file of them is smaller than
    // the basis chosen (below); declared here to outlive the animations.
    let per_frame_basis;
    let scene = SceneInfo {
        name: options.name.clone(),
        timing: Some(Timing {
            fps: options.fps,
            frames: frames.len(),
        }),
        compress: options.compress,
    };
    let (animation, quantizer, glb) = basis_encoded(
        frames,
        &basis,
        &base,
        normals.as_ref(),
        &scene,
        options,
        progress,
    )?;
    // Compressed, one target per frame as steps is exact and may take fewer
    // bytes than the basis the error bound chose (a take whose parts move
    // one after another): then it is the smaller file within the bound.
    // Tried up to AUTO_PER_FRAME_LIMIT frames, whose targets it holds.
    let automatic = matches!(
        options.basis,
        BasisChoice::Auto | BasisChoice::Bounded { .. }
    );
    // The bases measured as encoded here and not written: the rate table
    // takes their rows instead of encoding them again.
    let mut measured = Vec::new();
    let (basis, animation, quantizer, glb) = if options.compress
        && automatic
        && basis.components.is_some()
        && frames.len() <= basis::AUTO_PER_FRAME_LIMIT
    {
        let mut one_each = MorphBasis::per_frame(frames.len());
        name_targets_after_frames(&mut one_each, &options.frame_names);
        per_frame_basis = one_each;
        let steps = basis_encoded(
            frames,
            &per_frame_basis,
            &base,
            normals.as_ref(),
            &scene,
            options,
            progress,
        )?;
        let (steps_bytes, basis_bytes) = (steps.2.length()?, glb.length()?);
        if steps_bytes < basis_bytes {
            log::info!(
                "one target per frame as steps takes {steps_bytes} bytes, the basis of {:?} components {basis_bytes}: writing the steps",
                basis.components,
            );
            if options.rate_distortion {
                let error = quantised_error(frames, &base, animation.as_ref(), quantizer)?;
                measured.push(RateRow::of(&basis, basis_bytes, error, diagonal, false));
            }
            let (steps, q, steps_glb) = steps;
            (&per_frame_basis, steps, q, steps_glb)
        } else {
            (&basis, animation, quantizer, glb)
        }
    } else {
        (&basis, animation, quantizer, glb)
    };
    let steps = quantizer.is_some();
    let (error_max, error_mean) = if options.compress {
        quantised_error(frames, &base, animation.as_ref(), quantizer)?
    } else {
        (error.max, error.mean)
    };
    let bytes = glb.length()?;
    // An interruption or a frame that cannot be read while writing is
    // returned as itself, not as a failure to write the output.
    let mut failed = None;
    let written = emit(&glb, animation.as_ref(), &mut failed);
    if let Some(e) = failed {
        return Err(e);
    }
    written?;
    let written = RateRow::of(basis, bytes, (error_max, error_mean), diagonal, true);
    // As fractions of the diagonal, as the report gives them.
    let (relative_max, relative_mean) = (written.error_max, written.error_mean);
    let rate_distortion = if options.rate_distortion && !trials.is_empty() {
        measured.push(written);
        rate_distortion(
            frames,
            diagonal,
            &base,
            &trials,
            measured,
            normals.as_ref(),
            &scene,
            options,
            progress,
        )?
    } else {
        Vec::new()
    };
    Ok(GltfExportReport {
        targets: basis.targets(),
        basis: basis.components,
        reconstruction_error_max: relative_max,
        reconstruction_error_mean: relative_mean,
        bytes,
        compressed: options.compress,
        steps,
        rate_distortion,
    })
}

/// The file's base mesh: the first frame of `mesh` with its triangles, UVs
/// and texture, and the frames' normals when `with_normals` (the base's
/// stored in the mesh).
fn base_mesh(
    mesh: &DynamicMesh,
    with_normals: bool,
) -> Result<(TriangleMesh, Option<FrameNormals<'_>>)> {
    let first = mesh.frames.get(0)?.into_owned();
    let normals = with_normals.then(|| FrameNormals::new(&mesh.base, &first));
    let base = TriangleMesh {
        positions: first,
        triangles: mesh.base.triangles.clone(),
        uvs: mesh.base.uvs.clone(),
        normals: normals
            .as_ref()
            .map(|n| n.base.iter().map(to_f32).collect()),
        texture: mesh.base.texture.clone(),
    };
    Ok((base, normals))
}

/// The frames' morph targets in `basis`, and the file they make: the
/// animation, its quantiser (a compressed file's) and the parts. Per-frame
/// targets of a plain file are read from the frames as the file is
/// written, so a long sequence's are never all in memory; a compact basis's
/// few targets and a compressed file's quantised ones (one target per
/// frame: steps from frame to frame) are computed first.
fn basis_encoded<'a>(
    frames: &'a PositionFrames,
    basis: &'a MorphBasis,
    base: &TriangleMesh,
    normals: Option<&'a FrameNormals>,
    scene: &SceneInfo,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<(Option<MorphAnimation<'a>>, Option<Quantizer>, GlbParts)> {
    let deltas = if basis.components.is_none() && !options.compress {
        MorphDeltas::Computed(ComputedDeltas {
            frames,
            basis,
            first: base.positions.clone(),
            normals,
        })
    } else {
        stored_deltas(frames, basis, normals, progress)?
    };
    let animation = (basis.targets() > 0).then(|| {
        morph_animation(
            deltas,
            frames.len(),
            basis,
            options.fps,
            options.interpolation,
        )
    });
    encoded(animation, base, scene, basis.components.is_none(), progress)
}

/// The rate-distortion table: the rows of the bases `measured` already (the
/// one written among them), and every other basis of `trials` encoded as
/// the file would be with it (never written), their errors relative to
/// the animation's `diagonal`; by number of targets.
#[allow(clippy::too_many_arguments)]
fn rate_distortion(
    frames: &PositionFrames,
    diagonal: Real,
    base: &TriangleMesh,
    trials: &[basis::BasisTrial],
    mut measured: Vec<RateRow>,
    normals: Option<&FrameNormals>,
    scene: &SceneInfo,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<Vec<RateRow>> {
    let others: Vec<&basis::BasisTrial> = trials
        .iter()
        .filter(|t| measured.iter().all(|m| m.components != t.basis.components))
        .collect();
    let sizes = tried_sizes(frames, base, &others, normals, scene, options, progress)?;
    let mut rows: Vec<RateRow> = others
        .into_iter()
        .zip(sizes)
        .map(|(trial, Encoded { bytes, max, mean })| {
            RateRow::of(&trial.basis, bytes, (max, mean), diagonal, false)
        })
        .collect();
    rows.append(&mut measured);
    // By size, as the trials: the per-frame basis has the most targets.
    rows.sort_by_key(|r| r.targets);
    Ok(rows)
}

/// A basis encoded: the file's size, the largest and mean error (scene units).
struct Encoded {
    bytes: u64,
    max: Real,
    mean: Real,
}

/// Each of `trials` encoded as the file would be with it (never written):
/// its size and its error (with the quantisation when compressed). The
/// bases are nested (each one's targets begin the next's), so the largest's
/// targets are computed once and each takes its first ones.
fn tried_sizes(
    frames: &PositionFrames,
    base: &TriangleMesh,
    trials: &[&basis::BasisTrial],
    normals: Option<&FrameNormals>,
    scene: &SceneInfo,
    options: &GltfExportOptions,
    progress: Progress,
) -> Result<Vec<Encoded>> {
    let Some(largest) = trials.iter().max_by_key(|t| t.basis.targets()) else {
        return Ok(Vec::new());
    };
    let MorphDeltas::Stored { positions, normals } =
        stored_deltas(frames, &largest.basis, normals, progress)?
    else {
        unreachable!("stored deltas")
    };
    trials
        .iter()
        .map(|trial| {
            let t = trial.basis.targets();
            debug_assert_eq!(trial.basis.mix[..], largest.basis.mix[..t]);
            let deltas = MorphDeltas::Stored {
                positions: positions[..t].to_vec(),
                normals: normals.as_ref().map(|n| n[..t].to_vec()),
            };
            let animation = morph_animation(
                deltas,
                frames.len(),
                &trial.basis,
                options.fps,
                options.interpolation,
            );
            let (animation, quantizer, glb) = encoded(
                Some(animation),
                base,
                scene,
                trial.basis.components.is_none(),
                Progress::none(),
            )?;
            let (max, mean) = if options.compress {
                quantised_error(frames, base, animation.as_ref(), quantizer)?
            } else {
                (trial.error.max, trial.error.mean)
            };
            Ok(Encoded {
                bytes: glb.length()?,
                max,
                mean,
            })
        })
        .collect()
}

/// Max and mean distance between the captured frames and the positions a
/// compressed file decodes to at each frame's keyed weights.
fn quantised_error(
    frames: &PositionFrames,
    base: &TriangleMesh,
    animation: Option<&MorphAnimation>,
    quantizer: Option<Quantizer>,
) -> Result<(Real, Real)> {
    let q = match quantizer {
        Some(q) => q,
        None => Quantizer::new(&base.positions, animation)?,
    };
    let qbase: Vec<[i16; 3]> = base.positions.iter().map(|p| q.position(p)).collect();
    let qdeltas: Vec<Vec<[i16; 3]>> = match animation {
        Some(a) => (0..a.targets())
            .map(|k| Ok(a.positions(k)?.iter().map(|v| q.delta(v)).collect()))
            .collect::<Result<_>>()?,
        None => Vec::new(),
    };
    let (mut max, mut sum, mut n) = (0.0 as Real, 0.0 as Real, 0usize);
    for (f, frame) in frames.iter().enumerate() {
        let frame = frame?;
        let weights: &[f32] = animation.map_or(&[], |a| &a.weights[f]);
        for (v, p) in frame.iter().enumerate() {
            let mut acc = [0.0f64; 3];
            for k in 0..3 {
                acc[k] = qbase[v][k] as f64;
            }
            for (w, d) in weights.iter().zip(&qdeltas) {
                if *w != 0.0 {
                    for k in 0..3 {
                        acc[k] += *w as f64 * d[v][k] as f64;
                    }
                }
            }
            let decoded = q.dequantise(acc);
            let e = ((decoded[0] - p.x).powi(2)
                + (decoded[1] - p.y).powi(2)
                + (decoded[2] - p.z).powi(2))
            .sqrt() as Real;
            max = max.max(e);
            sum += e;
            n += 1;
        }
    }
    Ok((max, if n > 0 { sum / n as Real } else { 0.0 }))
}

/// `animation` packed as `scene` compresses it ([`packed`]; `per_frame`:
/// one target per frame), its quantisation, and the file it makes.
fn encoded<'a>(
    animation: Option<MorphAnimation<'a>>,
    base: &TriangleMesh,
    scene: &SceneInfo,
    per_frame: bool,
    progress: Progress,
) -> Result<(Option<MorphAnimation<'a>>, Option<Quantizer>, GlbParts)> {
    let (animation, quantizer) = packed(animation, base, scene.compress, per_frame)?;
    let glb = glb_with(
        base,
        animation.as_ref(),
        scene,
        GlbExtras {
            quantizer,
            ..Default::default()
        },
        progress,
    )?;
    Ok((animation, quantizer, glb))
}

/// The animation as a file with `compress` holds it, and the quantisation
/// that file needs when its targets' extent does not give it: a compressed
/// file's targets, computed beforehand, become steps when there is one
/// `per_frame` ([`into_steps`]); anything else is written as it is.
fn packed<'a>(
    animation: Option<MorphAnimation<'a>>,
    base: &TriangleMesh,
    compress: bool,
    per_frame: bool,
) -> Result<(Option<MorphAnimation<'a>>, Option<Quantizer>)> {
    match animation {
        Some(mut a) if compress && per_frame && a.targets() > 1 => {
            let q = Quantizer::new(&base.positions, Some(&a))?;
            let MorphDeltas::Stored { positions, normals } = &mut a.deltas else {
                return Ok((Some(a), None));
            };
            into_steps(positions, normals.as_deref_mut(), &q);
            for w in &mut a.weights {
                for t in (0..w.len().saturating_sub(1)).rev() {
                    w[t] += w[t + 1];
                }
            }
            Ok((Some(a), Some(q)))
        }
        other => Ok((other, None)),
    }
}

/// Per-frame targets made steps from frame to frame, in place: target k
/// then holds the change from target k − 1's frame to its own, quantised as
/// the difference of the two frames' quantised displacements (`q`'s, the
/// quantisation of the displacements themselves); the caller keys the
/// suffix sums of every keyframe's weights (a frame: its own step and every
/// one before at weight 1). The sums of the steps are the frames' quantised
/// displacements exactly, so the file decodes to the same positions, while a
/// body moves little from one frame to the next: the steps are small
/// numbers, which meshoptimizer's codec packs into fewer bytes than
/// displacements from frame 0. The normals' steps are bytes, each the
/// difference from the sum of the steps before it (so rounding does not
/// build up; a normal that turns further in one frame than a byte holds
/// catches up in the next).
fn into_steps(
    positions: &mut [Vec<[f32; 3]>],
    normals: Option<&mut [Vec<[f32; 3]>]>,
    q: &Quantizer,
) {
    // Last to first, so that each step is taken from its predecessor's
    // displacement before that one becomes a step too.
    for k in (0..positions.len()).rev() {
        let (before, from_k) = positions.split_at_mut(k);
        for (v, d) in from_k[0].iter_mut().enumerate() {
            let now = q.delta(d).map(i32::from);
            let was = before
                .last()
                .map_or([0; 3], |b| q.delta(&b[v]).map(i32::from));
            *d = q.delta_of([0, 1, 2].map(|c| now[c] - was[c]));
        }
    }
    let Some(normals) = normals else { return };
    let mut sum = vec![[0i32; 3]; normals.first().map_or(0, Vec::len)];
    for target in normals {
        for (n, s) in target.iter_mut().zip(&mut sum) {
            let b = byte4(n);
            *n = [0, 1, 2].map(|c| {
                let step = (b[c] as i32 - s[c]).clamp(-127, 127);
                s[c] += step;
                step as f32 / 127.0
            });
        }
    }
}

/// The order a compressed file holds its vertices and triangles in, as
/// gltfpack writes them: triangles ordered for the vertex cache
/// (meshoptimizer's), then vertices in the order those triangles first use
/// them (vertices no triangle uses last, as they were). meshoptimizer's
/// index codec encodes each triangle against the ones just before it and its
/// vertex codec each vertex against the one before, so both pay for
/// locality. The order is the file's own: the vertices are the same, and
/// the captures' positions, compared through it, unchanged.
struct CodecOrder {
    /// The original index of each vertex, in the file's order.
    vertices: Vec<u32>,
    /// The triangles in the file's order, in the file's vertex indices.
    triangles: Vec<[u32; 3]>,
}

impl CodecOrder {
    fn new(mesh: &TriangleMesh) -> Self {
        let n = mesh.positions.len();
        let flat: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let cached = meshopt::optimize_vertex_cache(&flat, n);
        let mut new_index = vec![u32::MAX; n];
        let mut vertices = Vec::with_capacity(n);
        for &v in &cached {
            if new_index[v as usize] == u32::MAX {
                new_index[v as usize] = vertices.len() as u32;
                vertices.push(v);
            }
        }
        for (v, index) in new_index.iter_mut().enumerate() {
            if *index == u32::MAX {
                *index = vertices.len() as u32;
                vertices.push(v as u32);
            }
        }
        let triangles = cached
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]].map(|v| new_index[v as usize]))
            .collect();
        CodecOrder {
            vertices,
            triangles,
        }
    }

    /// Per-vertex `data` in the file's order.
    fn apply<T: Copy>(&self, data: &[T]) -> Vec<T> {
        self.vertices.iter().map(|&v| data[v as usize]).collect()
    }
}

/// Where a mesh far from the origin for its size (a capture in map
/// coordinates, [`Aabb::too_far_for_f32`](crate::model::mesh::Aabb::too_far_for_f32))
/// is written from: the centre of its bounds, as f32 (what the node's
/// translation holds), so that positions relative to it keep f32's
/// precision; None for most captures, written as they are.
fn far_origin(positions: &[Point3]) -> Option<[f32; 3]> {
    let bounds = crate::model::mesh::Aabb::from_points(positions);
    bounds
        .too_far_for_f32()
        .then(|| [0, 1, 2].map(|k| ((bounds.min[k] + bounds.max[k]) / 2.0) as f32))
}

/// The quantisation of a compressed file (KHR_mesh_quantization): positions
/// and position deltas as normalized SHORT in one common uniform scale (the
/// node's, which glTF applies to both; uniform so that normals keep their
/// directions), positions relative to the centre of the base mesh's bounds
/// (the node's translation). The scale covers both the base positions' offsets
/// from the centre and every delta, so nothing is clamped, in
/// [`POSITION_BITS`] of precision.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Quantizer {
    center: [f32; 3],
    scale: f32,
}

const SHORT: f64 = 32767.0;

/// Precision of the quantised positions and deltas: normalized SHORT values
/// confined to ±(2^(bits−1) − 1) (the node's scale is larger by as much), so
/// that their high bytes vary little and meshoptimizer's codec packs them
/// tighter. 14 bits (gltfpack's default) keep the error about 1e-4 of the
/// diagonal; 16 would be the full range.
const POSITION_BITS: i32 = 14;

impl Quantizer {
    fn new(positions: &[Point3], animation: Option<&MorphAnimation>) -> Result<Self> {
        let (lo, hi) = bounds_of(
            &positions
                .iter()
                .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                .collect::<Vec<_>>(),
        );
        let center = [0, 1, 2].map(|k| ((lo[k] as f64 + hi[k] as f64) / 2.0) as f32);
        let mut extent = 0.0f64;
        for p in positions {
            for (k, c) in [p.x, p.y, p.z].into_iter().enumerate() {
                extent = extent.max((c - center[k] as f64).abs());
            }
        }
        if let Some(a) = animation {
            for k in 0..a.targets() {
                for c in a.positions(k)?.iter().flatten() {
                    extent = extent.max(c.abs() as f64);
                }
            }
        }
        // Rounded up to f32 (what the node holds) and a hair more, so that
        // no value falls outside [-1, 1] after the f32 rounding.
        let steps = (1i32 << (POSITION_BITS - 1)) as f64 - 1.0;
        let scale = if extent > 0.0 && extent.is_finite() {
            (extent * (1.0 + 1e-6) * SHORT / steps) as f32
        } else {
            1.0
        };
        Ok(Quantizer { center, scale })
    }

    fn short(&self, x: f64) -> i16 {
        (x / self.scale as f64 * SHORT).round().clamp(-SHORT, SHORT) as i16
    }

    fn position(&self, p: &Point3) -> [i16; 3] {
        let c = [p.x, p.y, p.z];
        [0, 1, 2].map(|k| self.short(c[k] - self.center[k] as f64))
    }

    fn delta(&self, d: &[f32; 3]) -> [i16; 3] {
        d.map(|c| self.short(c as f64))
    }

    /// The delta whose quantised value is `s` (exactly: [`Quantizer::delta`]
    /// gives `s` back).
    fn delta_of(&self, s: [i32; 3]) -> [f32; 3] {
        s.map(|c| (c as f64 / SHORT * self.scale as f64) as f32)
    }

    /// Dequantised point from (possibly weighted sums of) SHORT values.
    fn dequantise(&self, q: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|k| q[k] / SHORT * self.scale as f64 + self.center[k] as f64)
    }
}

/// A unit vector or a normal delta as normalized BYTE (clamped to [-1, 1];
/// a normal delta is larger only where a normal turns by more than 90°, and
/// affects the shading only), padded to 4 bytes.
fn byte4(v: &[f32; 3]) -> [i8; 4] {
    let b = |x: f32| (x.clamp(-1.0, 1.0) * 127.0).round() as i8;
    [b(v[0]), b(v[1]), b(v[2]), 0]
}

/// Per-frame targets named after their frames (`names`, one per frame,
/// distinct, not blank, no control characters), else left as they are.
fn name_targets_after_frames(basis: &mut MorphBasis, names: &[String]) {
    let usable = |n: &String| !n.trim().is_empty() && !n.chars().any(char::is_control);
    if names.len() != basis.targets() + 1 || !names.iter().all(usable) {
        return;
    }
    let mut sorted: Vec<&String> = names.iter().collect();
    sorted.sort();
    sorted.dedup();
    if sorted.len() == names.len() {
        basis.names = names[1..].to_vec();
    }
}

/// The morph animation of `basis` with its targets' `deltas`: weights keyed
/// at f / fps with `interpolation`, and the last frame's weights again at
/// F / fps: without that key the clip ends where the last frame begins, and
/// a looping player never shows it.
fn morph_animation<'a>(
    deltas: MorphDeltas<'a>,
    frames: usize,
    basis: &MorphBasis,
    fps: f32,
    interpolation: Interpolation,
) -> MorphAnimation<'a> {
    MorphAnimation {
        deltas,
        weights: basis
            .weights
            .iter()
            .chain(basis.weights.last())
            .map(|w| w.iter().map(|&x| x as f32).collect())
            .collect(),
        times: (0..=frames)
            .map(|f| (f as f64 / fps as f64) as f32)
            .collect(),
        interpolation,
        target_names: basis.names.clone(),
    }
}

/// Every target of `basis` computed at once, one pass over the frames:
/// position targets from the displacements, normal targets from the
/// normals' change since frame 0.
fn stored_deltas(
    frames: &PositionFrames,
    basis: &MorphBasis,
    normals: Option<&FrameNormals>,
    progress: Progress,
) -> Result<MorphDeltas<'static>> {
    let first = frames.get(0)?;
    let vertices = first.len();
    let positions = basis.combine(
        frames.len(),
        vertices,
        |g| position_deltas(frames, &first, g),
        progress,
    )?;
    let normals = normals
        .map(|n| {
            basis.combine(
                frames.len(),
                vertices,
                |g| normal_deltas(n, frames, g),
                progress,
            )
        })
        .transpose()?;
    Ok(MorphDeltas::Stored { positions, normals })
}

/// Frame `g`'s moves from frame 0 (`first`), per vertex.
fn position_deltas(frames: &PositionFrames, first: &[Point3], g: usize) -> Result<Vec<Vector3>> {
    Ok(frames
        .get(g)?
        .iter()
        .zip(first)
        .map(|(p, p0)| p - p0)
        .collect())
}

/// Frame `g`'s normals less the mesh's own, per vertex.
fn normal_deltas(
    normals: &FrameNormals,
    frames: &PositionFrames,
    g: usize,
) -> Result<Vec<Vector3>> {
    Ok(normals
        .of(&frames.get(g)?)
        .iter()
        .zip(&normals.base)
        .map(|(a, b)| a - b)
        .collect())
}

/// Morph targets computed from the frames one at a time, when asked for.
pub struct ComputedDeltas<'a> {
    frames: &'a PositionFrames,
    basis: &'a MorphBasis,
    first: Vec<Point3>,
    normals: Option<&'a FrameNormals<'a>>,
}

/// The deltas of a [`MorphAnimation`]'s targets.
pub enum MorphDeltas<'a> {
    /// In memory: POSITION deltas, one per vertex, per target (at least one
    /// target); NORMAL deltas per target, relative to the mesh's normals
    /// (which must then be present), as many as `positions` when given.
    Stored {
        /// Per target, one POSITION delta per vertex.
        positions: Vec<Vec<[f32; 3]>>,
        /// Per target, one NORMAL delta per vertex, if normals are animated.
        normals: Option<Vec<Vec<[f32; 3]>>>,
    },
    /// Computed from a dynamic mesh's frames as they are written.
    Computed(ComputedDeltas<'a>),
}

fn to_f32(v: &Vector3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// How morph weights are interpolated between keyframes (glTF's STEP and
/// LINEAR samplers; see [`GltfExportOptions::interpolation`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    /// Each keyframe held until the next.
    #[default]
    Step,
    /// Consecutive keyframes blended.
    Linear,
}

/// Morph-target animation of a mesh: at keyframe k the positions are
/// `base + Σ_t weights[k][t] · positions(t)`, likewise the normals.
pub struct MorphAnimation<'a> {
    /// The targets' deltas, stored or computed.
    pub deltas: MorphDeltas<'a>,
    /// One weight vector (one entry per target) per keyframe; the first is
    /// also the mesh's default weights, what viewers show unanimated.
    pub weights: Vec<Vec<f32>>,
    /// Keyframe times in seconds, increasing, one per weight vector.
    pub times: Vec<f32>,
    /// How the weights change between keyframes.
    pub interpolation: Interpolation,
    /// One name per target, written as the mesh's `extras.targetNames`.
    pub target_names: Vec<String>,
}

impl MorphAnimation<'_> {
    /// Number of targets.
    pub fn targets(&self) -> usize {
        match &self.deltas {
            MorphDeltas::Stored { positions, .. } => positions.len(),
            MorphDeltas::Computed(c) => c.basis.targets(),
        }
    }

    /// Whether the targets have NORMAL deltas.
    pub fn has_normals(&self) -> bool {
        match &self.deltas {
            MorphDeltas::Stored { normals, .. } => normals.is_some(),
            MorphDeltas::Computed(c) => c.normals.is_some(),
        }
    }

    /// Target k's POSITION deltas.
    pub fn positions(&self, k: usize) -> Result<Cow<'_, [[f32; 3]]>> {
        match &self.deltas {
            MorphDeltas::Stored { positions, .. } => Ok(Cow::Borrowed(&positions[k])),
            MorphDeltas::Computed(c) => {
                let target = c
                    .basis
                    .target(k, c.first.len(), |g| position_deltas(c.frames, &c.first, g))?;
                Ok(Cow::Owned(target))
            }
        }
    }

    /// Target k's NORMAL deltas (an error when it has none).
    pub fn normals(&self, k: usize) -> Result<Cow<'_, [[f32; 3]]>> {
        match &self.deltas {
            MorphDeltas::Stored {
                normals: Some(n), ..
            } => Ok(Cow::Borrowed(&n[k])),
            MorphDeltas::Computed(ComputedDeltas {
                frames,
                basis,
                first,
                normals: Some(n),
            }) => {
                let target = basis.target(k, first.len(), |g| normal_deltas(n, frames, g))?;
                Ok(Cow::Owned(target))
            }
            _ => Err(Error::InvalidInput(
                "morph animation: no normal deltas".into(),
            )),
        }
    }

    /// Checks the sizes against `mesh` and each other, and the times.
    fn check(&self, mesh: &TriangleMesh) -> Result<()> {
        let (targets, vertices) = (self.targets(), mesh.positions.len());
        let bad = |what: &str| Err(Error::InvalidInput(format!("morph animation: {what}")));
        if targets == 0 {
            return bad("no targets");
        }
        if self.has_normals() && mesh.normals.is_none() {
            return bad("normal deltas without base normals");
        }
        match &self.deltas {
            MorphDeltas::Stored { positions, normals } => {
                let sized = |d: &[Vec<[f32; 3]>]| {
                    d.len() == targets && d.iter().all(|t| t.len() == vertices)
                };
                if !sized(positions) || normals.as_ref().is_some_and(|n| !sized(n)) {
                    return bad("a target does not have one delta per vertex");
                }
            }
            MorphDeltas::Computed(c) => {
                if c.first.len() != vertices {
                    return bad("the frames do not have one position per vertex");
                }
            }
        }
        if self.weights.is_empty()
            || self.weights.len() != self.times.len()
            || self.weights.iter().any(|w| w.len() != targets)
        {
            return bad("not one weight per target for every keyframe time");
        }
        if self.target_names.len() != targets {
            return bad("not one name per target");
        }
        if !self.times.iter().all(|t| t.is_finite()) || self.times.windows(2).any(|w| w[0] >= w[1])
        {
            return bad("keyframe times are not finite and increasing");
        }
        Ok(())
    }
}

/// Accumulates binary data and the views/accessors describing it.
struct Builder {
    root: json::Root,
    bin: Bin,
    /// Store the vertex, index and weight data meshopt-encoded
    /// ([`SceneInfo::compress`]).
    compress: bool,
    /// Length of the EXT_meshopt_compression fallback buffer (buffer 1, no
    /// data) that the compressed views describe; 0 when nothing is compressed.
    fallback_len: usize,
    /// The EXT_meshopt_compression object of each compressed view, by index.
    meshopt: Vec<(usize, serde_json::Value)>,
}

/// How meshoptimizer encodes a compressed view.
#[derive(Clone, Copy, PartialEq, Eq)]
enum MeshoptMode {
    Attributes,
    Triangles,
}

impl Builder {
    /// A view of `raw` (elements of `stride` bytes) stored encoded by
    /// meshoptimizer in the GLB buffer, and described uncompressed in the
    /// fallback buffer as EXT_meshopt_compression says.
    fn meshopt_view(
        &mut self,
        raw: &[u8],
        stride: usize,
        mode: MeshoptMode,
        target: Option<json::buffer::Target>,
    ) -> Result<json::Index<json::buffer::View>> {
        let count = raw.len() / stride;
        let encoded = match mode {
            // Version 0 of the vertex codec: EXT_meshopt_compression's (the
            // later version 1 is KHR_meshopt_compression's).
            MeshoptMode::Attributes => match stride {
                4 => meshopt::encode_vertex_buffer_level(&chunks::<4>(raw), 2, Some(0)),
                8 => meshopt::encode_vertex_buffer_level(&chunks::<8>(raw), 2, Some(0)),
                _ => unreachable!("meshopt attribute stride {stride}"),
            },
            MeshoptMode::Triangles => {
                let idx: Vec<u32> = raw
                    .chunks_exact(4)
                    .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                let vertices = idx.iter().max().map_or(0, |&m| m as usize + 1);
                meshopt::encode_index_buffer(&idx, vertices)
            }
        }
        .map_err(|e| Error::InvalidInput(format!("meshoptimizer: {e:?}")))?;
        let offset = self.append(&encoded);
        self.fallback_len = self.fallback_len.next_multiple_of(4);
        let fallback_offset = self.fallback_len;
        self.fallback_len += raw.len();
        let index = self.root.push(json::buffer::View {
            buffer: json::Index::new(1),
            byte_length: USize64::from(raw.len()),
            byte_offset: Some(USize64::from(fallback_offset)),
            // glTF's byteStride is for vertex attributes only.
            byte_stride: (target == Some(json::buffer::Target::ArrayBuffer))
                .then_some(json::buffer::Stride(stride)),
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        });
        self.meshopt.push((
            index.value(),
            serde_json::json!({
                "buffer": 0,
                "byteOffset": offset,
                "byteLength": encoded.len(),
                "byteStride": stride,
                "count": count,
                "mode": if mode == MeshoptMode::Attributes { "ATTRIBUTES" } else { "TRIANGLES" },
            }),
        ));
        Ok(index)
    }

    /// An accessor of `count` elements in `view`.
    #[allow(clippy::too_many_arguments)]
    fn accessor_in(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        component: json::accessor::ComponentType,
        type_: json::accessor::Type,
        normalized: bool,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
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
            normalized,
            sparse: None,
        })
    }

    /// A quantised VEC3 attribute: normalized SHORT padded to 8 bytes, with
    /// exact bounds (in the stored integers) when asked.
    fn short3(
        &mut self,
        data: &[[i16; 3]],
        with_bounds: bool,
    ) -> Result<json::Index<json::Accessor>> {
        let raw: Vec<u8> = data
            .iter()
            .flat_map(|v| [v[0], v[1], v[2], 0])
            .flat_map(i16::to_le_bytes)
            .collect();
        let view = self.meshopt_view(
            &raw,
            8,
            MeshoptMode::Attributes,
            Some(json::buffer::Target::ArrayBuffer),
        )?;
        let bounds = with_bounds
            .then(|| bounds_of(&data.iter().map(|v| v.map(|c| c as f32)).collect::<Vec<_>>()));
        Ok(self.accessor_in(
            view,
            data.len(),
            json::accessor::ComponentType::I16,
            json::accessor::Type::Vec3,
            true,
            bounds,
        ))
    }

    /// A quantised VEC3 direction or direction delta: normalized BYTE padded to 4 bytes.
    fn byte3(&mut self, data: &[[f32; 3]]) -> Result<json::Index<json::Accessor>> {
        let raw: Vec<u8> = data.iter().flat_map(byte4).map(|b| b as u8).collect();
        let view = self.meshopt_view(
            &raw,
            4,
            MeshoptMode::Attributes,
            Some(json::buffer::Target::ArrayBuffer),
        )?;
        Ok(self.accessor_in(
            view,
            data.len(),
            json::accessor::ComponentType::I8,
            json::accessor::Type::Vec3,
            true,
            None,
        ))
    }

    /// Appends `bytes` to the binary chunk at the next 4-byte boundary;
    /// returns where they start.
    fn append(&mut self, bytes: &[u8]) -> usize {
        self.bin.append(bytes)
    }

    /// A VEC3 float accessor of target `target`'s NORMAL (or POSITION)
    /// deltas, `count` of them, whose bytes are computed when the file is written.
    fn deferred_vec3(
        &mut self,
        target: usize,
        normals: bool,
        count: usize,
        bounds: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let len = 12 * count;
        let offset = self.bin.defer(target, normals, len);
        let view = self.view_at(offset, len, Some(json::buffer::Target::ArrayBuffer));
        self.accessor_in(
            view,
            count,
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec3,
            false,
            bounds,
        )
    }

    /// A view of data stored as the file is: meshopt-encoded (elements of
    /// `stride` bytes, in `mode`) when compressing, plain otherwise.
    fn data_view(
        &mut self,
        bytes: &[u8],
        stride: usize,
        mode: MeshoptMode,
        target: Option<json::buffer::Target>,
    ) -> Result<json::Index<json::buffer::View>> {
        if self.compress {
            self.meshopt_view(bytes, stride, mode, target)
        } else {
            Ok(self.view(bytes, target))
        }
    }

    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        let offset = self.append(bytes);
        self.view_at(offset, bytes.len(), target)
    }

    /// A view of `len` bytes of the binary chunk at `offset`.
    fn view_at(
        &mut self,
        offset: usize,
        len: usize,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(len),
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
        self.accessor_in(view, count, component, type_, false, bounds)
    }

    fn vec3(
        &mut self,
        data: &[[f32; 3]],
        with_bounds: bool,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
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

fn chunks<const N: usize>(raw: &[u8]) -> Vec<[u8; N]> {
    raw.chunks_exact(N)
        .map(|c| c.try_into().expect("chunk of N bytes"))
        .collect()
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

/// The capture's time base, which glTF has no field for: written to the
/// scene's and the animation's `extras` as `{"fps": …, "frames": …}`, where
/// importers and scripts can read the frame rate and range to set.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Timing {
    /// Captured frames per second.
    pub fps: f32,
    /// Captured frames (the animation has one key more, closing the last).
    pub frames: usize,
}

/// What names and describes the scene [`glb_bytes`] writes.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneInfo {
    /// Name of the node, the mesh and the animation. Default
    /// [`DEFAULT_NAME`](crate::model::DEFAULT_NAME); not blank, no control characters.
    pub name: String,
    /// Frame rate and count for the `extras`; default None (no `extras`).
    pub timing: Option<Timing>,
    /// Compress the file: positions and their morph deltas as normalized
    /// SHORT and normals and theirs as normalized BYTE (KHR_mesh_quantization;
    /// the node's translation and uniform scale dequantise the positions),
    /// then vertex and index data encoded by meshoptimizer
    /// (EXT_meshopt_compression, with a fallback buffer that has no data).
    /// Both extensions are required: viewers need a meshopt decoder (three.js'
    /// `MeshoptDecoder`). UVs stay float (encoded by meshoptimizer too), the animation's
    /// weights are encoded, its times and the texture are stored as they are.
    /// Default false.
    pub compress: bool,
}

impl Default for SceneInfo {
    fn default() -> Self {
        SceneInfo {
            name: crate::model::DEFAULT_NAME.into(),
            timing: None,
            compress: false,
        }
    }
}

fn raw_json(value: &impl serde::Serialize) -> Result<Box<serde_json::value::RawValue>> {
    serde_json::value::to_raw_value(value).map_err(|e| Error::InvalidInput(e.to_string()))
}

/// Encodes `mesh` (and its animation) as a GLB file: positions, and the
/// mesh's normals, UVs and texture when present, named and described as
/// `scene` says. Without an animation the output is a plain static mesh (the
/// committed fixtures are built this way, with the default `scene`, byte for
/// byte).
pub fn glb_bytes(
    mesh: &TriangleMesh,
    animation: Option<&MorphAnimation>,
    scene: &SceneInfo,
) -> Result<Vec<u8>> {
    glb_bytes_with(mesh, animation, scene, GlbExtras::default())
}

/// What a GLB may hold beyond [`glb_bytes`]'s.
#[derive(Default)]
pub(crate) struct GlbExtras<'a> {
    /// TEXCOORD_1, one per vertex; the mesh must have UVs (TEXCOORD_0).
    pub uv1: Option<&'a [[f32; 2]]>,
    /// The asset's `extras`.
    pub asset: Option<Box<serde_json::value::RawValue>>,
    /// A compressed file's quantisation, when the targets' own extent does
    /// not give it (targets that are steps, [`packed`]).
    pub quantizer: Option<Quantizer>,
}

/// [`glb_bytes`] with `extras` added.
pub(crate) fn glb_bytes_with(
    mesh: &TriangleMesh,
    animation: Option<&MorphAnimation>,
    scene: &SceneInfo,
    extras: GlbExtras,
) -> Result<Vec<u8>> {
    let glb = glb_with(mesh, animation, scene, extras, Progress::none())?;
    let mut out = Vec::with_capacity(glb.length()? as usize);
    let mut failed = None;
    let written = glb.write(&mut out, animation, Progress::none(), &mut failed);
    match failed {
        Some(e) => Err(e),
        None => written
            .map(|()| out)
            .map_err(|e| Error::InvalidInput(e.to_string())),
    }
}

/// A GLB's JSON chunk and what its binary chunk holds: written straight to a
/// file, with the morph targets' deltas filled in as they are written.
struct GlbParts {
    json: Vec<u8>,
    bin: Bin,
}

impl GlbParts {
    /// The file's length in bytes; an error past the 4 GiB the format's
    /// 32-bit length field can say.
    fn length(&self) -> Result<u64> {
        let length = 12
            + 8
            + self.json.len().next_multiple_of(4) as u64
            + 8
            + (self.bin.len as u64).next_multiple_of(4);
        if length > u32::MAX as u64 {
            return Err(Error::InvalidInput(format!(
                "the GLB would take {:.1} GiB, beyond the 4 GiB a GLB can hold: choose a compact basis (--basis K), --compress or another format",
                length as f64 / (1u64 << 30) as f64
            )));
        }
        Ok(length)
    }

    /// Writes the file as glTF's binary container lays it out (the same bytes
    /// as `gltf::binary::Glb::to_writer`); the targets' deltas come from
    /// `animation`, which must be the one the parts were made with. What
    /// stops it other than the writer's own error (a stop request, a frame
    /// that cannot be read) is put in `failed`.
    fn write(
        &self,
        w: &mut impl std::io::Write,
        animation: Option<&MorphAnimation>,
        progress: Progress,
        failed: &mut Option<Error>,
    ) -> std::io::Result<()> {
        self.write_or_fail(w, animation, progress)
            .map_err(|e| match e {
                Failure::Write(e) => e,
                Failure::Other(e) => {
                    let io = std::io::Error::other(e.to_string());
                    *failed = Some(e);
                    io
                }
            })
    }

    fn write_or_fail(
        &self,
        w: &mut impl std::io::Write,
        animation: Option<&MorphAnimation>,
        progress: Progress,
    ) -> std::result::Result<(), Failure> {
        let length = self.length()? as u32;
        let io = Failure::Write;
        let json_len = self.json.len().next_multiple_of(4);
        let bin_len = self.bin.len.next_multiple_of(4);
        let mut head = Vec::with_capacity(20);
        head.extend_from_slice(b"glTF");
        head.extend_from_slice(&2u32.to_le_bytes());
        head.extend_from_slice(&length.to_le_bytes());
        head.extend_from_slice(&(json_len as u32).to_le_bytes());
        head.extend_from_slice(b"JSON");
        w.write_all(&head).map_err(io)?;
        w.write_all(&self.json).map_err(io)?;
        w.write_all(&vec![b' '; json_len - self.json.len()])
            .map_err(io)?;
        w.write_all(&(bin_len as u32).to_le_bytes()).map_err(io)?;
        w.write_all(b"BIN\0").map_err(io)?;
        let deferred = self
            .bin
            .parts
            .iter()
            .filter(|p| matches!(p, Part::Deferred { .. }))
            .count();
        let mut done = 0;
        for part in &self.bin.parts {
            match part {
                Part::Bytes(bytes) => w.write_all(bytes).map_err(io)?,
                Part::Deferred {
                    target,
                    normals,
                    len,
                } => {
                    if progress.cancelled() {
                        return Err(Error::Interrupted { saved: None }.into());
                    }
                    let anim = animation.ok_or_else(|| {
                        Error::InvalidInput("morph deltas without their animation".into())
                    })?;
                    let deltas = if *normals {
                        anim.normals(*target)?
                    } else {
                        anim.positions(*target)?
                    };
                    let bytes = f32_bytes(deltas.iter().flatten().copied());
                    if bytes.len() != *len {
                        return Err(Error::InvalidInput(format!(
                            "morph target {target} changed size while it was written"
                        ))
                        .into());
                    }
                    w.write_all(&bytes).map_err(io)?;
                    done += 1;
                    progress.report(Stage::Export, done, deferred);
                }
            }
        }
        w.write_all(&vec![0; bin_len - self.bin.len]).map_err(io)
    }
}

/// Why [`GlbParts::write`] stopped: its writer failed, or something else did.
enum Failure {
    Write(std::io::Error),
    Other(Error),
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Failure::Other(e)
    }
}

/// The binary chunk: bytes held, and morph deltas left to compute when the
/// file is written (their place and length are known before).
#[derive(Default)]
struct Bin {
    parts: Vec<Part>,
    len: usize,
}

enum Part {
    Bytes(Vec<u8>),
    /// Target `target`'s NORMAL (or POSITION) deltas as f32, `len` bytes.
    Deferred {
        target: usize,
        normals: bool,
        len: usize,
    },
}

impl Bin {
    /// Appends `bytes` at the next 4-byte boundary; returns where they start.
    fn append(&mut self, bytes: &[u8]) -> usize {
        self.pad();
        let offset = self.len;
        self.append_unpadded(bytes);
        offset
    }

    /// Reserves `len` bytes for deltas written later; returns where they start.
    fn defer(&mut self, target: usize, normals: bool, len: usize) -> usize {
        self.pad();
        let offset = self.len;
        self.parts.push(Part::Deferred {
            target,
            normals,
            len,
        });
        self.len += len;
        offset
    }

    fn pad(&mut self) {
        let padding = self.len.next_multiple_of(4) - self.len;
        if padding > 0 {
            self.append_unpadded(&[0; 3][..padding]);
        }
    }

    fn append_unpadded(&mut self, bytes: &[u8]) {
        match self.parts.last_mut() {
            Some(Part::Bytes(b)) => b.extend_from_slice(bytes),
            _ => self.parts.push(Part::Bytes(bytes.to_vec())),
        }
        self.len += bytes.len();
    }
}

/// The JSON and binary parts of [`glb_bytes_with`]'s file.
/// Computing the targets' bounds is reported to `progress` (one step a
/// target) and stops when it asks.
fn glb_with(
    mesh: &TriangleMesh,
    animation: Option<&MorphAnimation>,
    scene: &SceneInfo,
    extras: GlbExtras,
    progress: Progress,
) -> Result<GlbParts> {
    crate::model::check_name(&scene.name)?;
    if let Some(anim) = animation {
        anim.check(mesh)?;
    }
    if extras
        .uv1
        .is_some_and(|uv| uv.len() != mesh.positions.len() || mesh.uvs.is_none())
    {
        // glTF numbers UV sets from 0, without gaps.
        return Err(Error::InvalidInput(
            "a second UV set needs a first, and one UV per vertex".into(),
        ));
    }
    let timing = scene.timing.as_ref().map(raw_json).transpose()?;
    let mut b = Builder {
        root: json::Root::default(),
        bin: Bin::default(),
        compress: scene.compress,
        fallback_len: 0,
        meshopt: Vec::new(),
    };
    b.root.asset.generator = Some(format!("voltrack {}", env!("CARGO_PKG_VERSION")));
    b.root.asset.extras = extras.asset;
    // A compressed file's quantisation and the order of its vertices: every
    // per-vertex array goes through both.
    let packing = scene
        .compress
        .then(|| {
            Ok((
                match extras.quantizer {
                    Some(q) => q,
                    None => Quantizer::new(&mesh.positions, animation)?,
                },
                CodecOrder::new(mesh),
            ))
        })
        .transpose()?;
    let origin = if scene.compress {
        None
    } else {
        far_origin(&mesh.positions)
    };
    let attributes = vertex_attributes(&mut b, mesh, packing.as_ref(), origin, extras.uv1)?;
    let triangles = packing
        .as_ref()
        .map_or(&mesh.triangles, |(_, o)| &o.triangles);
    let idx: Vec<u8> = triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let view = b.data_view(
        &idx,
        4,
        MeshoptMode::Triangles,
        Some(json::buffer::Target::ElementArrayBuffer),
    )?;
    let indices = b.accessor_in(
        view,
        mesh.triangles.len() * 3,
        json::accessor::ComponentType::U32,
        json::accessor::Type::Scalar,
        false,
        None,
    );
    let material = match (&mesh.texture, &mesh.uvs) {
        (Some(tex), Some(_)) => Some(texture_material(&mut b, tex)?),
        _ => None,
    };
    let mut targets = None;
    let mut extras = None;
    let mut weights = None;
    if let Some(anim) = animation {
        let t = morph_targets(&mut b, mesh, anim, packing.as_ref(), progress)?;
        targets = Some(t);
        weights = Some(anim.weights[0].clone());
        let names = serde_json::json!({ "targetNames": anim.target_names });
        extras = Some(raw_json(&names)?);
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
        name: Some(scene.name.clone()),
        primitives: vec![primitive],
        weights,
    });
    let node = b.root.push(json::Node {
        mesh: Some(mesh_index),
        name: Some(scene.name.clone()),
        translation: packing.as_ref().map(|(q, _)| q.center).or(origin),
        scale: packing.as_ref().map(|(q, _)| [q.scale; 3]),
        ..Default::default()
    });
    let scene_index = b.root.push(json::Scene {
        extensions: None,
        extras: timing.clone(),
        name: None,
        nodes: vec![node],
    });
    b.root.scene = Some(scene_index);
    if let Some(anim) = animation {
        add_weight_animation(&mut b, anim, node, &scene.name, timing)?;
    }
    b.finish()
}

/// The mesh's vertex attributes (POSITION, NORMAL, TEXCOORD_0 and _1), as
/// `packing` quantises and orders them or as floats moved by `origin`.
fn vertex_attributes(
    b: &mut Builder,
    mesh: &TriangleMesh,
    packing: Option<&(Quantizer, CodecOrder)>,
    origin: Option<[f32; 3]>,
    uv1: Option<&[[f32; 2]]>,
) -> Result<BTreeMap<json::validation::Checked<json::mesh::Semantic>, json::Index<json::Accessor>>>
{
    let array = Some(json::buffer::Target::ArrayBuffer);
    let at = origin.map_or([0.0; 3], |o| o.map(f64::from));
    let positions: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| {
            [
                (p.x - at[0]) as f32,
                (p.y - at[1]) as f32,
                (p.z - at[2]) as f32,
            ]
        })
        .collect();
    let mut attributes = BTreeMap::new();
    let position_accessor = match packing {
        Some((q, o)) => b.short3(
            &o.apply(
                &mesh
                    .positions
                    .iter()
                    .map(|p| q.position(p))
                    .collect::<Vec<_>>(),
            ),
            true,
        )?,
        None => b.vec3(&positions, true, array),
    };
    attributes.insert(Valid(json::mesh::Semantic::Positions), position_accessor);
    if let Some(n) = &mesh.normals {
        let acc = match packing {
            Some((_, o)) => b.byte3(&o.apply(n))?,
            None => b.vec3(n, false, array),
        };
        attributes.insert(Valid(json::mesh::Semantic::Normals), acc);
    }
    for (set, uv) in [(0, mesh.uvs.as_deref()), (1, uv1)] {
        let Some(uv) = uv else { continue };
        let uv = match packing {
            Some((_, o)) => std::borrow::Cow::Owned(o.apply(uv)),
            None => std::borrow::Cow::Borrowed(uv),
        };
        let bytes = f32_bytes(uv.iter().flatten().copied());
        let view = b.data_view(&bytes, 8, MeshoptMode::Attributes, array)?;
        let acc = b.accessor_in(
            view,
            uv.len(),
            json::accessor::ComponentType::F32,
            json::accessor::Type::Vec2,
            false,
            None,
        );
        attributes.insert(Valid(json::mesh::Semantic::TexCoords(set)), acc);
    }
    Ok(attributes)
}

/// One morph target per target of `anim`: quantised deltas as `packing`
/// says, or float deltas deferred to the writing of the binary chunk (with
/// their bounds, which POSITION needs in the JSON first).
fn morph_targets(
    b: &mut Builder,
    mesh: &TriangleMesh,
    anim: &MorphAnimation,
    packing: Option<&(Quantizer, CodecOrder)>,
    progress: Progress,
) -> Result<Vec<json::mesh::MorphTarget>> {
    let mut t = Vec::with_capacity(anim.targets());
    // POSITION needs its bounds in the JSON, before the deltas are written.
    let bounds: Vec<_> = match packing {
        Some(_) => Vec::new(),
        None => {
            let counter = Counter::new(progress, Stage::Export, anim.targets());
            (0..anim.targets())
                .into_par_iter()
                .map(|k| {
                    if progress.cancelled() {
                        return Err(Error::Interrupted { saved: None });
                    }
                    let bounds = bounds_of(&anim.positions(k)?);
                    counter.tick();
                    Ok(bounds)
                })
                .collect::<Result<_>>()?
        }
    };
    for k in 0..anim.targets() {
        let target = match packing {
            Some((q, o)) => {
                let normals = if anim.has_normals() {
                    Some(b.byte3(&o.apply(&anim.normals(k)?))?)
                } else {
                    None
                };
                let deltas: Vec<[i16; 3]> = anim.positions(k)?.iter().map(|v| q.delta(v)).collect();
                let positions = b.short3(&o.apply(&deltas), true)?;
                json::mesh::MorphTarget {
                    positions: Some(positions),
                    normals,
                    tangents: None,
                }
            }
            None => {
                let vertices = mesh.positions.len();
                let normals = anim
                    .has_normals()
                    .then(|| b.deferred_vec3(k, true, vertices, None));
                let positions = b.deferred_vec3(k, false, vertices, bounds.get(k).cloned());
                json::mesh::MorphTarget {
                    positions: Some(positions),
                    normals,
                    tangents: None,
                }
            }
        };
        t.push(target);
    }
    Ok(t)
}

impl Builder {
    /// The buffers (and a compressed file's fallback buffer and extensions)
    /// added, the JSON serialised and padded: the file's two parts.
    fn finish(mut self) -> Result<GlbParts> {
        self.bin.pad();
        self.root.push(json::Buffer {
            byte_length: USize64::from(self.bin.len),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let mut json_bytes = if self.compress {
            let used = ["EXT_meshopt_compression", "KHR_mesh_quantization"]
                .map(String::from)
                .to_vec();
            self.root.extensions_used = used.clone();
            self.root.extensions_required = used;
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.fallback_len.next_multiple_of(4)),
                name: None,
                uri: None,
                extensions: None,
                extras: Default::default(),
            });
            // gltf-json has no types for EXT_meshopt_compression: added to the JSON.
            let mut value =
                serde_json::to_value(&self.root).map_err(|e| Error::InvalidInput(e.to_string()))?;
            for (view, ext) in self.meshopt.drain(..) {
                value["bufferViews"][view]["extensions"] =
                    serde_json::json!({ "EXT_meshopt_compression": ext });
            }
            value["buffers"][1]["extensions"] =
                serde_json::json!({ "EXT_meshopt_compression": { "fallback": true } });
            serde_json::to_vec(&value).map_err(|e| Error::InvalidInput(e.to_string()))?
        } else {
            self.root
                .to_vec()
                .map_err(|e| Error::InvalidInput(e.to_string()))?
        };
        while json_bytes.len() % 4 != 0 {
            json_bytes.push(b' ');
        }
        Ok(GlbParts {
            json: json_bytes,
            bin: self.bin,
        })
    }
}

fn add_weight_animation(
    b: &mut Builder,
    anim: &MorphAnimation,
    node: json::Index<json::Node>,
    name: &str,
    extras: Option<Box<serde_json::value::RawValue>>,
) -> Result<()> {
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
    // The weights (F + 1 keys of T each: for per-frame targets a one-hot
    // matrix, the larger part of a small mesh's file) compressed with the
    // vertex data; the few times are not.
    let view = b.data_view(
        &f32_bytes(flat.iter().copied()),
        4,
        MeshoptMode::Attributes,
        None,
    )?;
    let output = b.accessor_in(
        view,
        flat.len(),
        json::accessor::ComponentType::F32,
        json::accessor::Type::Scalar,
        false,
        None,
    );
    let interpolation = match anim.interpolation {
        Interpolation::Step => json::animation::Interpolation::Step,
        Interpolation::Linear => json::animation::Interpolation::Linear,
    };
    let sampler = json::animation::Sampler {
        extensions: None,
        extras: Default::default(),
        input,
        interpolation: Valid(interpolation),
        output,
    };
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
        extras,
        channels: vec![channel],
        name: Some(name.into()),
        samplers: vec![sampler],
    });
    Ok(())
}

/// Embeds the first frame's texture image as-is (PNG or JPEG) in the GLB.
fn texture_material(
    b: &mut Builder,
    path: &std::path::Path,
) -> Result<json::Index<json::Material>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let Some(mime) = crate::model::mesh::image_mime(&bytes) else {
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
    let texture = b.root.push(json::Texture {
        name: None,
        sampler: None,
        source: image,
        extensions: None,
        extras: Default::default(),
    });
    Ok(b.root.push(json::Material {
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_texture: Some(json::texture::Info {
                index: texture,
                tex_coord: 0,
                extensions: None,
                extras: Default::default(),
            }),
            metallic_factor: json::material::StrengthFactor(0.0),
            ..Default::default()
        },
        double_sided: true,
        ..Default::default()
    }))
}

#[cfg(test)]
mod tests {
    /// RFC 4648 §10's test vectors.
    #[test]
    fn base64_as_the_rfc_gives_it() {
        for (text, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(text.as_bytes()), coded, "{text:?}");
        }
        assert_eq!(super::base64(&[0xff, 0xfe, 0x00]), "//4A");
    }
}
