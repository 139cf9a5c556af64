//! The stages strung together, as the commands use them: each function takes
//! its inputs and options and returns a result the CLI prints or writes.

use crate::deform::segments::{
    plan_segments, split_where_far, union_of_segments, FrameRange, Segment,
};
use crate::deform::{conform, deform_with};
use crate::error::{Error, Result, Saved};
use crate::metrics::{fit_outliers, fit_to_input, Coverage, FitOutliers, Quality, SequenceFit};
use crate::model::mesh::TriangleMesh;
use crate::model::metadata::GridRecord;
use crate::model::DynamicMesh;
use crate::model::FrameSource;
use crate::model::{GridSpec, Trajectories, TrajectoryMetadata};
use crate::params::{ConformParams, CoverageParams, DeformParams, RefineParams, TrackParams};
use crate::progress::{Progress, Stage};
use crate::refine::{
    global_affinity, refine_with_checkpoints, RefineResult, Refinement, SequenceCells,
};
use crate::track::{track_with_checkpoints, Checkpointing, FrameTiming, TrackResult};
use crate::voxel::{voxelize_sequence, VoxelParams, VoxelSequence};

pub mod guard;
pub use guard::OutputPlan;
use std::path::Path;
use std::time::Instant;

/// Measures trajectories against the voxelised sequence they track.
pub fn measure(traj: &Trajectories, seq: &VoxelSequence) -> Quality {
    let mut cells = SequenceCells::single_pass(seq);
    let counts: Vec<Vec<u32>> = crate::refine::cells::frame_blocks(0..traj.frames)
        .flat_map(|block| cells.update_frames(traj, 0, block, false))
        .map(|s| s.count)
        .collect();
    Quality::of(traj, &counts)
}

/// The metadata recording how trajectories were made, for their EXR file.
pub fn trajectory_metadata(
    seq: &VoxelSequence,
    traj: &Trajectories,
    voxel: &VoxelParams,
    track: &TrackParams,
    refine: Option<(&RefineParams, &[usize])>,
) -> TrajectoryMetadata {
    let mut meta = TrajectoryMetadata {
        resolution: Some(voxel.resolution),
        voxel_size: Some(seq.grid.voxel_size),
        grid: Some(GridRecord::from(&seq.grid)),
        frames: Some(seq.frames.len()),
        track: serde_json::to_value(track).ok(),
        first_input: Some(seq.names[0].clone()),
        reference: (traj.reference != 0).then_some(traj.reference),
        ..Default::default()
    };
    if let Some((r, removed)) = refine {
        record_refinement(&mut meta, r, removed);
    }
    meta
}

/// Records a refinement in `meta`: its parameters and the original indices
/// of the removed centers (replacing an earlier refinement's).
pub fn record_refinement(meta: &mut TrajectoryMetadata, params: &RefineParams, removed: &[usize]) {
    meta.refine = serde_json::to_value(params).ok();
    meta.removed = Some(removed.to_vec());
}

/// The resolution trajectories were tracked at, from their metadata.
pub fn resolution_of(meta: &TrajectoryMetadata, path: &Path) -> Result<usize> {
    meta.resolution
        .ok_or_else(|| Error::parse(path, None, "no voltrack.resolution attribute: not written by voltrack track; give the resolution it was tracked at"))
}

/// Checks that re-voxelised input lies on the grid the trajectories were made on.
pub fn check_grid(
    meta: &TrajectoryMetadata,
    grid: &GridSpec,
    traj: &Trajectories,
    seq: &VoxelSequence,
    path: &Path,
) -> Result<()> {
    if traj.frames != seq.frames.len() {
        return Err(Error::InvalidInput(format!(
            "{} has {} frames but the input has {}",
            path.display(),
            traj.frames,
            seq.frames.len()
        )));
    }
    if let Some(stored) = meta.voxel_size {
        if (stored - grid.voxel_size).abs() > 1e-9 * grid.voxel_size.max(stored.abs()) {
            return Err(Error::InvalidInput(format!(
                "{} was tracked on voxels of {stored}, the input gives {}: not the same input or resolution",
                path.display(),
                grid.voxel_size
            )));
        }
    }
    Ok(())
}

/// What a [`Conversion`] does not hold yet: the quality of its forward-tracked
/// and refined trajectories (what `--report` shows beside the conversion's
/// own fit to the input).
#[derive(Clone, Debug)]
pub struct Measurements {
    /// PCAC, DFU and irregularity of the forward-tracked trajectories
    /// ([`Tracked::quality`]).
    pub tracked: Quality,
    /// The same after refinement (None when refinement was skipped).
    pub refined: Option<Quality>,
}

impl Measurements {
    /// Measures `conv`, made with [`ConvertOptions::measure_tracked`] (the
    /// forward-tracked trajectories were measured when tracked): the refined
    /// trajectories by assigning cells in every frame again.
    pub fn of(conv: &Conversion) -> Result<Self> {
        let tracked = conv.tracked.quality.clone().ok_or_else(|| {
            Error::InvalidParameter("the conversion did not measure its forward-tracked trajectories: set ConvertOptions::measure_tracked".into())
        })?;
        let refined = conv
            .refined
            .as_ref()
            .map(|_| measure(&conv.trajectories, &conv.sequence));
        Ok(Measurements { tracked, refined })
    }
}

/// What forward tracking gave besides the trajectories, which refinement
/// takes on: the tracked trajectories are not kept beside the refined ones.
#[derive(Clone, Debug)]
pub struct Tracked {
    /// Centers tracked (before refinement removes any).
    pub centers: usize,
    /// PCAC, DFU and irregularity of the forward-tracked trajectories, when
    /// [`ConvertOptions::measure_tracked`] asked for them.
    pub quality: Option<Quality>,
    /// Per frame; the reference frame's is the Lloyd placement.
    pub timings: Vec<FrameTiming>,
    /// The frame the centers were placed in and tracked from, and why.
    pub reference: crate::track::ReferenceChoice,
}

impl Tracked {
    /// Splits `result`'s trajectories off, measuring them first if `measure`;
    /// its cell counts are not kept.
    pub fn split(result: TrackResult, measure: bool) -> (Self, Trajectories) {
        let quality = measure.then(|| Quality::of(&result.trajectories, &result.cell_counts));
        (
            Tracked {
                centers: result.trajectories.centers,
                quality,
                timings: result.timings,
                reference: result.reference,
            },
            result.trajectories,
        )
    }
}

/// Everything `convert` produces, with its timings.
pub struct Conversion {
    /// Every frame on the common voxel grid (stage 1).
    pub sequence: VoxelSequence,
    /// The final trajectories: refined, or as tracked when refinement was
    /// skipped.
    pub trajectories: Trajectories,
    /// What forward tracking gave besides the trajectories.
    pub tracked: Tracked,
    /// What refinement did (None when skipped).
    pub refined: Option<Refinement>,
    /// The result: the reference frame's mesh (each segment's, in a take cut
    /// into segments) animated over every frame, conformed to the input
    /// unless conforming was skipped.
    pub mesh: DynamicMesh,
    /// The stretches of the take with a mesh of their own
    /// ([`crate::deform::segments`]): one, the whole take, unless the
    /// input's parts merge or part.
    pub segments: Vec<Segment>,
    /// Input volume the final centers' cells do not reach, per frame, at
    /// [`ConvertOptions::coverage`]: frames where a part was lost.
    pub coverage: Coverage,
    /// The mesh's fit to every input frame, read again from the source.
    pub fit: SequenceFit,
    /// The frames fitted far worse than the rest.
    pub fit_outliers: FitOutliers,
    /// Every attempt made ([`ConvertOptions::attempts`]), in order: this
    /// result is `attempts[kept]`'s.
    pub attempts: Vec<Attempt>,
    /// Which of `attempts` this result is.
    pub kept: usize,
    /// Seconds each stage took in this run, summed over the attempts (a
    /// resumed run's, not the interrupted one's before it).
    pub seconds: Vec<(Stage, f64)>,
}

/// One conversion of the input with one seed, and what it warned of.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Attempt {
    /// The center placement's seed ([`TrackParams::seed`]).
    pub seed: u64,
    /// The frames where it may have lost a part ([`Conversion::lost_parts`]).
    pub warned: Vec<usize>,
    /// Those of `warned` carried on from a neighbour by weaker evidence
    /// ([`crate::metrics::LostParts::continued`]).
    pub continued: Vec<usize>,
}

impl Attempt {
    /// What [`convert`] keeps the least of: the frames warned of on
    /// evidence of their own first, since the frames carried on by weaker
    /// evidence are there to report a lost part, not to judge between
    /// attempts; then all of them.
    fn warnings(&self) -> (usize, usize) {
        (self.warned.len() - self.continued.len(), self.warned.len())
    }
}

impl Conversion {
    /// The seed this result was tracked with: the kept attempt's.
    pub fn seed(&self) -> u64 {
        self.attempts[self.kept].seed
    }

    /// The frames where this result may have lost a part, from its
    /// unreached volume and its fit to the input.
    pub fn lost_parts(&self) -> crate::metrics::LostParts {
        crate::metrics::lost_parts(&self.coverage, Some((&self.fit, &self.fit_outliers)))
    }
}

/// The options of every stage of [`convert`].
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    /// Voxelisation (stage 1). Default: its defaults.
    pub voxel: VoxelParams,
    /// Tracking (stage 2). Default: its defaults.
    pub track: TrackParams,
    /// Refinement (docs/method.md §6-§7); None skips it. Default: its defaults.
    pub refine: Option<RefineParams>,
    /// Deforming the reference frame's mesh by the centers. Default: its
    /// defaults.
    pub deform: DeformParams,
    /// Fitting every frame to its input; `iterations: 0` skips it.
    pub conform: ConformParams,
    /// What counts as a lost part in [`Conversion::coverage`].
    pub coverage: CoverageParams,
    /// Saving tracking's state as it goes, and resuming from it. Default None.
    pub checkpoint: Option<Checkpointing>,
    /// Measure the forward-tracked trajectories (PCAC, DFU, irregularity:
    /// [`Tracked::quality`]) before refinement moves them, for
    /// [`Measurements::of`] and the report. PCAC takes a dense
    /// 3F × N matrix and its eigen-decomposition, which a conversion does
    /// not otherwise need. Default false.
    pub measure_tracked: bool,
    /// How many conversions to make at most, each with the next seed
    /// ([`TrackParams::seed`] + 0, 1, ...), while every one so far warns of a
    /// lost part; the one that warns of the fewest frames is kept (counting
    /// first those warned of on evidence of their own, not carried on from a
    /// neighbour: [`Attempt::continued`]; the first on a tie). Where a thin
    /// part is lost, whether it is turns on
    /// where the centers were placed, and the warnings, which need no
    /// ground truth, tell the draws apart. A take that warns of nothing is
    /// converted once. Default 2; at least 1. Only the first attempt saves
    /// to and resumes from `checkpoint`.
    pub attempts: usize,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            voxel: VoxelParams::default(),
            track: TrackParams::default(),
            refine: Some(RefineParams::default()),
            deform: DeformParams::default(),
            conform: ConformParams::default(),
            coverage: CoverageParams::default(),
            checkpoint: None,
            measure_tracked: false,
            attempts: 2,
        }
    }
}

/// Voxelise, track (saving and resuming through `options.checkpoint` when
/// given), refine, deform and conform to the input surfaces: the whole
/// pipeline up to export, reading the frames of `source` as each stage
/// needs them.
///
/// Converts again with the next seed while the result warns of a lost part,
/// up to [`ConvertOptions::attempts`] times, and keeps the result that
/// warns of the fewest frames; the input is voxelised once.
pub fn convert(
    source: &dyn FrameSource,
    options: &ConvertOptions,
    progress: Progress,
) -> Result<Conversion> {
    if options.attempts == 0 {
        return Err(Error::InvalidParameter(
            "attempts must be at least 1".into(),
        ));
    }
    crate::model::PositionFrames::check_temporary_folder()?;
    let sequence = voxelize_sequence(source, &options.voxel, progress)?;
    if sequence.first_mesh.is_none() {
        return Err(Error::InvalidInput(format!(
            "{}: voxel input has no mesh to deform; convert needs meshes",
            sequence.names[0]
        )));
    }
    let mut seconds = vec![
        (Stage::Read, sequence.read_seconds),
        (Stage::Voxelize, sequence.voxelize_seconds),
    ];
    let mut attempts: Vec<Attempt> = Vec::new();
    let mut kept: Option<Conversion> = None;
    let mut sequence = Some(sequence);
    for k in 0..options.attempts {
        // Voxelised once: the last attempt takes the sequence, the others a copy.
        let voxels = if k + 1 < options.attempts {
            sequence.clone()
        } else {
            sequence.take()
        }
        .expect("the attempts stop after the last");
        let mut track = options.track.clone();
        track.seed = options.track.seed.wrapping_add(k as u64);
        let checkpoint = if k == 0 {
            options.checkpoint.as_ref()
        } else {
            None
        };
        let conv = convert_voxelized(source, voxels, options, &track, checkpoint, progress)?;
        add_seconds(&mut seconds, &conv.seconds);
        // The attempt as `convert_voxelized` recorded it, warnings and all.
        attempts.push(conv.attempts[0].clone());
        let fewest = kept
            .as_ref()
            .map_or((usize::MAX, usize::MAX), |c| attempts[c.kept].warnings());
        let warned = attempts[k].warned.len();
        if attempts[k].warnings() < fewest {
            kept = Some(Conversion { kept: k, ..conv });
        }
        if warned == 0 {
            break;
        }
        if k + 1 < options.attempts {
            log::warn!(
                "seed {}: {warned} frames may have lost a part; converting again with seed {}",
                track.seed,
                track.seed.wrapping_add(1)
            );
        }
    }
    let mut conv = kept.expect("at least one attempt");
    if attempts.len() > 1 {
        log::info!(
            "kept seed {}'s result ({} frames warned of)",
            attempts[conv.kept].seed,
            attempts[conv.kept].warned.len()
        );
    }
    conv.attempts = attempts;
    conv.seconds = seconds;
    Ok(conv)
}

/// Adds each stage's seconds in `more` to its entry in `seconds`, in the
/// order stages first appear.
fn add_seconds(seconds: &mut Vec<(Stage, f64)>, more: &[(Stage, f64)]) {
    for &(stage, s) in more {
        match seconds.iter_mut().find(|(t, _)| *t == stage) {
            Some((_, total)) => *total += s,
            None => seconds.push((stage, s)),
        }
    }
}

/// One attempt of [`convert`]: everything after voxelising, with `track`'s
/// seed, measured against the input.
fn convert_voxelized(
    source: &dyn FrameSource,
    sequence: VoxelSequence,
    options: &ConvertOptions,
    track: &TrackParams,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
) -> Result<Conversion> {
    let mut seconds = Vec::new();
    let clock = Instant::now();
    let (tracked, trajectories) = Tracked::split(
        track_with_checkpoints(&sequence, track, checkpoint, progress)?,
        options.measure_tracked,
    );
    seconds.push((Stage::Track, clock.elapsed().as_secs_f64()));
    let (trajectories, refined) = match &options.refine {
        Some(p) => {
            let p = &p.clone().within(options.voxel.max_memory);
            let clock = Instant::now();
            let r = refine_tracked(trajectories, &sequence, p, checkpoint, progress)?;
            // This run's seconds, as every stage's: a resumed refinement's
            // earlier ones are in `r.refinement.seconds`.
            seconds.push((Stage::Refine, clock.elapsed().as_secs_f64()));
            (r.trajectories, Some(r.refinement))
        }
        None => (trajectories, None),
    };
    let coverage = check_coverage(&trajectories, &sequence, &options.coverage)?;
    let segments = plan_segments_of(&trajectories, &sequence, &tracked, options);
    let saved = |e| finished_saved(e, checkpoint, &sequence, options.refine.as_ref());
    let clock = Instant::now();
    progress.report(Stage::Deform, 0, 1);
    let omega = sequence_affinity(&trajectories, &sequence, options.refine.as_ref(), progress)
        .map_err(saved)?;
    seconds.push((Stage::Deform, clock.elapsed().as_secs_f64()));
    let stages = MeshStages {
        source,
        sequence: &sequence,
        trajectories: &trajectories,
        omega: &omega,
        options,
        progress,
        saved: &saved,
    };
    let fit_of = |mesh: &DynamicMesh, segments: &[Segment]| {
        fit_with_outliers(
            mesh,
            segments,
            &sequence,
            &coverage.params,
            source,
            progress,
        )
    };
    let (mut segments, mut mesh) = stages.run(segments, &mut seconds)?;
    let (mut fit, mut fit_outliers) = fit_of(&mesh, &segments)?;
    // Where the parts merge or part, a stretch's mesh may not serve the
    // frames nearest the change (a ball half sunk into a slab that the
    // stretch's mesh shows whole): those frames get meshes of their own,
    // and again, at most SPLIT_ROUNDS times, where theirs do not serve
    // all of them either.
    for _ in 0..SPLIT_ROUNDS {
        if segments.len() < 2 {
            break;
        }
        let far = crate::metrics::lost_parts(&coverage, Some((&fit, &fit_outliers))).far;
        let split = split_where_far(&segments, &far);
        if split.len() == segments.len() {
            break;
        }
        log::info!(
            "frames {} lie far from their stretch's mesh: {} segments instead of {}",
            crate::metrics::frame_runs(&far),
            split.len(),
            segments.len()
        );
        let fitted = fit.seconds;
        (segments, mesh) = stages.run(split, &mut seconds)?;
        (fit, fit_outliers) = fit_of(&mesh, &segments)?;
        fit.seconds += fitted;
    }
    seconds.push((Stage::Fit, fit.seconds));
    let lost = crate::metrics::lost_parts(&coverage, Some((&fit, &fit_outliers)));
    Ok(Conversion {
        sequence,
        trajectories,
        tracked,
        refined,
        mesh,
        segments,
        coverage,
        fit,
        fit_outliers,
        attempts: vec![Attempt {
            seed: track.seed,
            warned: lost.flagged,
            continued: lost.continued,
        }],
        kept: 0,
        seconds,
    })
}

/// Most rounds of cutting a take's segments again where their meshes do not
/// serve some frames ([`split_where_far`]); each round runs the mesh stages
/// and the fit again.
const SPLIT_ROUNDS: usize = 2;

/// The mesh stages of a conversion, run on a plan of segments: each
/// segment's reference mesh deformed by the trajectories over its frames and
/// conformed to the input, the segments' meshes joined into one.
struct MeshStages<'a> {
    source: &'a dyn FrameSource,
    sequence: &'a VoxelSequence,
    trajectories: &'a Trajectories,
    /// The binding affinity of the trajectories ([`sequence_affinity`]).
    omega: &'a crate::refine::SparseAffinity,
    options: &'a ConvertOptions,
    progress: Progress<'a>,
    /// What an error becomes (an interruption names the checkpoint).
    saved: &'a dyn Fn(Error) -> Error,
}

impl MeshStages<'_> {
    /// The segments deformed and the dynamic mesh; the seconds of the
    /// deform and conform stages added to `seconds`. One segment (the whole
    /// take) when the reference meshes carry texture coordinates, which
    /// one mesh for several stretches cannot.
    fn run(
        &self,
        segments: Vec<Segment>,
        seconds: &mut Vec<(Stage, f64)>,
    ) -> Result<(Vec<Segment>, DynamicMesh)> {
        let (sequence, trajectories, options, progress) = (
            self.sequence,
            self.trajectories,
            self.options,
            self.progress,
        );
        // The meshes the result deforms: each segment's reference frame's,
        // read again unless it is the first, which voxelising kept.
        let mesh_of = |r: usize| match r {
            0 => Ok(sequence.first_mesh.clone().expect("checked above")),
            r => self.source.mesh(r),
        };
        let mut references = segments
            .iter()
            .map(|s| mesh_of(s.reference))
            .collect::<Result<Vec<_>>>()?;
        let (segments, references) = if segments.len() > 1
            && references
                .iter()
                .any(|m| m.uvs.is_some() || m.texture.is_some())
        {
            log::warn!(
                "the input's parts merge or part ({} stretches), but its meshes carry texture coordinates, which one mesh for all stretches cannot: one mesh deforms the whole take",
                segments.len()
            );
            let whole = Segment {
                frames: 0..sequence.frames.len(),
                reference: trajectories.reference,
                parts: segments[0].parts,
            };
            let reference = mesh_of(whole.reference)?;
            (vec![whole], vec![reference])
        } else {
            let one = std::mem::take(&mut references);
            (segments, one)
        };
        let clock = Instant::now();
        progress.report(Stage::Deform, 0, 1);
        let whole = segments.len() == 1;
        let meshes = segments
            .iter()
            .zip(&references)
            .map(|(segment, mesh)| {
                if whole {
                    return deform_with(mesh, trajectories, self.omega, &options.deform, progress);
                }
                let window = trajectories.window(
                    segment.frames.clone(),
                    segment.reference - segment.frames.start,
                );
                deform_with(mesh, &window, self.omega, &options.deform, progress)
            })
            .collect::<Result<Vec<_>>>()
            .map_err(self.saved)?;
        progress.report(Stage::Deform, 1, 1);
        add_seconds(seconds, &[(Stage::Deform, clock.elapsed().as_secs_f64())]);
        let clock = Instant::now();
        let mut meshes = segments
            .iter()
            .zip(meshes)
            .map(|(segment, mesh)| {
                if whole {
                    return conform(
                        mesh,
                        self.source,
                        &sequence.bounds,
                        &options.conform,
                        progress,
                    );
                }
                let frames = FrameRange {
                    source: self.source,
                    range: segment.frames.clone(),
                };
                conform(mesh, &frames, &sequence.bounds, &options.conform, progress)
            })
            .collect::<Result<Vec<_>>>()
            .map_err(self.saved)?;
        let mesh = if whole {
            meshes.pop().expect("one segment")
        } else {
            union_of_segments(
                &segments,
                meshes,
                trajectories.reference,
                options.deform.memory,
            )?
        };
        if options.conform.iterations > 0 {
            add_seconds(seconds, &[(Stage::Conform, clock.elapsed().as_secs_f64())]);
        }
        Ok((segments, mesh))
    }
}

/// The fit of `mesh` to every frame of `source` and the frames fitted far
/// worse than the rest (exact in `segments`' reference frames).
fn fit_with_outliers(
    mesh: &DynamicMesh,
    segments: &[Segment],
    sequence: &VoxelSequence,
    params: &CoverageParams,
    source: &dyn FrameSource,
    progress: Progress,
) -> Result<(SequenceFit, FitOutliers)> {
    let diagonal = sequence.bounds.diagonal();
    let far = params.far_distances(diagonal, sequence.grid.voxel_size);
    let fit = fit_to_input(mesh, source, diagonal, far, Some(sequence), progress)?;
    let exact: Vec<usize> = segments.iter().map(|s| s.reference).collect();
    let outliers = fit_outliers(&fit, &exact, params)?;
    Ok((fit, outliers))
}

/// The segments of the conversion ([`crate::deform::segments`]): one,
/// the whole take, unless [`DeformParams::segments`] asks for them; the
/// frames' parts as the reference's choice measured them, or measured now.
fn plan_segments_of(
    traj: &Trajectories,
    seq: &VoxelSequence,
    tracked: &Tracked,
    options: &ConvertOptions,
) -> Vec<Segment> {
    let frames = seq.frames.len();
    if !options.deform.segments {
        return vec![Segment {
            frames: 0..frames,
            reference: traj.reference,
            parts: tracked
                .reference
                .topology
                .get(traj.reference)
                .map_or(0, |t| t.parts),
        }];
    }
    let measured;
    let topology = if tracked.reference.topology.len() == frames {
        &tracked.reference.topology
    } else {
        measured = crate::track::frame_topologies(seq, options.track.centers);
        &measured
    };
    let segments = plan_segments(topology, traj.reference);
    if segments.len() > 1 {
        log::info!(
            "{} segments where the parts merge or part: {}",
            segments.len(),
            segments
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    segments
}

/// [`crate::metrics::coverage()`] of the final trajectories, logging the
/// frames it flags.
pub fn check_coverage(
    traj: &Trajectories,
    seq: &VoxelSequence,
    params: &CoverageParams,
) -> Result<Coverage> {
    let coverage = crate::metrics::coverage(traj, seq, params)?;
    for (a, b) in coverage.flagged_runs() {
        log::info!(
            "frames {a}-{b}: input volume no tracked cell reaches (a part may have been lost)"
        );
    }
    Ok(coverage)
}

/// [`refine_with_checkpoints`] after [`track_with_checkpoints`], saving and
/// resuming through the same checkpoint folder.
pub fn refine_tracked(
    traj: Trajectories,
    seq: &VoxelSequence,
    params: &RefineParams,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
) -> Result<RefineResult> {
    refine_with_checkpoints(traj, seq, params, checkpoint, progress)
}

/// An interruption after tracking (and refinement, when `refine` gives its
/// parameters) names the checkpoint folder, which holds them finished.
fn finished_saved(
    e: Error,
    checkpoint: Option<&Checkpointing>,
    seq: &VoxelSequence,
    refine: Option<&RefineParams>,
) -> Error {
    match e {
        Error::Interrupted { saved: None } => Error::Interrupted {
            saved: checkpoint.map(|c| Saved {
                path: c.path(),
                frames: seq.frames.len(),
                refine: refine.map(|p| (p.batches, p.batches)),
            }),
        },
        e => e,
    }
}

/// Deforms `first` (the trajectories' reference frame as loaded) by
/// trajectories tracked on `seq`, with the global affinity ω of the final
/// trajectories ([`sequence_affinity`]).
/// Returns [`Error::Interrupted`] soon after `progress` asks to stop.
pub fn deform_sequence(
    first: &TriangleMesh,
    traj: &Trajectories,
    seq: &VoxelSequence,
    refine_params: Option<&RefineParams>,
    deform_params: &DeformParams,
    progress: Progress,
) -> Result<DynamicMesh> {
    let omega = sequence_affinity(traj, seq, refine_params, progress)?;
    deform_with(first, traj, &omega, deform_params, progress)
}

/// The global affinity ω of trajectories tracked on `seq` (its ρ_gp, ρ_gm
/// and μ from `refine_params`, or their defaults when refinement was
/// skipped), which binds a mesh to the centers.
pub fn sequence_affinity(
    traj: &Trajectories,
    seq: &VoxelSequence,
    refine_params: Option<&RefineParams>,
    progress: Progress,
) -> Result<crate::refine::SparseAffinity> {
    let rp = refine_params.cloned().unwrap_or_default();
    let scale = rp.length_scale(&seq.bounds);
    let mut cells = SequenceCells::single_pass(seq).stopping_with(progress);
    let omega = global_affinity(
        traj,
        seq,
        &mut cells,
        rp.rho_gp * scale,
        rp.rho_gm * scale,
        rp.mu,
    );
    if cells.cancelled() {
        return Err(Error::Interrupted { saved: None });
    }
    Ok(omega)
}
