//! Flags shared by several commands, each mapped onto a library parameter
//! struct; defaults come from the structs' `Default`, never repeated here.

use anyhow::Result;
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use voltrack::export::gltf::{BasisChoice, GltfExportOptions, Interpolation};
use voltrack::export::vat::VatOptions;
pub use voltrack::export::OutputFormat;
use voltrack::metrics::SequenceFit;
use voltrack::params::{
    AffinityKind, Blending, ConformParams, DeformParams, Reference, RefineParams, TrackParams,
};
use voltrack::track::Checkpointing;
use voltrack::voxel::VoxelParams;

#[derive(Args)]
pub struct InputArgs {
    /// Frames: a directory, a pattern such as 'seq/frame_*.obj', or files in order
    #[arg(required = true, value_name = "INPUT")]
    pub input: Vec<PathBuf>,
    /// Voxels along the longest side of the sequence's bounding box (range: 2..=1596)
    #[arg(long, short = 'r', default_value_t = VoxelParams::default().resolution)]
    pub resolution: usize,
    /// Memory the run may take, in GiB, beyond the frames read [default: what the system has available]; a resolution estimated to need more is refused before voxelising (range: 0 < GIB <= 1e9)
    #[arg(long, value_name = "GIB")]
    pub max_memory: Option<f64>,
}

impl InputArgs {
    /// An output plan that knows what this command reads.
    pub fn plan(&self) -> Result<voltrack::pipeline::OutputPlan> {
        super::plan_reading(&self.input)
    }

    pub fn voxel_params(&self) -> VoxelParams {
        VoxelParams {
            resolution: self.resolution,
            max_memory: self.max_memory.map(|g| g * (1u64 << 30) as f64),
            ..Default::default()
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
pub enum AffinityArg {
    Max,
    Iir,
}

#[derive(Args)]
pub struct TrackArgs {
    /// Number of tracked volume elements (range: 1..=1000000)
    #[arg(long, short = 'n', default_value_t = TrackParams::default().centers)]
    pub centers: usize,
    /// Affinity weighting the rigid fits
    #[arg(long, value_enum, default_value = "max")]
    pub affinity: AffinityArg,
    /// Seed of the initial center placement
    #[arg(long, default_value_t = TrackParams::default().seed)]
    pub seed: u64,
    /// The frame whose mesh is deformed, where the centers are placed and tracked from, forward and back: auto (the first frame whose parts are most separate), first, or a frame number from 0
    #[arg(long, value_name = "auto|first|FRAME", default_value = "auto", value_parser = parse_reference)]
    pub reference: Reference,
    /// ρ_p: distance at which the positional affinity is 0.5 [default: 1.5 typical center spacings in frame 0; the paper's is 0.07] (range: 1e-12..=1e12)
    #[arg(long)]
    pub rho_p: Option<f64>,
    /// ρ_m: motion dissimilarity at which the motion affinity is 0.5 (range: 1e-12..=1e12)
    #[arg(long, default_value_t = TrackParams::default().rho_m)]
    pub rho_m: f64,
    /// α: IIR filter weight (--affinity iir) (range: 0 < α <= 1)
    #[arg(long, default_value_t = TrackParams::default().alpha)]
    pub alpha: f64,
    /// β: weight of the centroid term (range: 0 < β <= 1e6)
    #[arg(long, default_value_t = TrackParams::default().beta)]
    pub beta: f64,
    /// μ: smallest affinity kept (range: 0 < μ < 1)
    #[arg(long, default_value_t = TrackParams::default().mu)]
    pub mu: f64,
    /// Rigid-prediction steps before the centroid term enters (range: 0..=1000)
    #[arg(long, default_value_t = TrackParams::default().presmooth_steps)]
    pub presmooth: usize,
    /// Convergence threshold on the largest move per iteration (range: 1e-12..=1e12)
    #[arg(long, default_value_t = TrackParams::default().threshold)]
    pub threshold: f64,
    /// Iteration limit per frame (range: 1..=100000)
    #[arg(long, default_value_t = TrackParams::default().max_iterations)]
    pub max_iterations: usize,
    /// Also converged when no center moved W × --threshold over the last W iterations (the state of those with the shortest largest update is kept); 1 is the paper's per-iteration test alone (range: 1..=1000)
    #[arg(long, value_name = "W", default_value_t = TrackParams::default().convergence_window)]
    pub convergence_window: usize,
    /// Also track every frame from the previous velocity scaled by K; the runs from the guesses are compared region by region by their energy (range: 0 <= K < 1)
    #[arg(long, value_name = "K", default_value_t = TrackParams::default().damped_guess.expect("on by default"))]
    pub damped_guess: f64,
    /// Track every frame from the paper's constant-velocity guess alone (no damped or accelerated guess): a third of the tracking work, but fast limbs that turn back get lost
    #[arg(long, conflicts_with_all = ["damped_guess", "no_accelerated_guess", "guess_screening", "screening_unsettled", "screening_block"])]
    pub single_guess: bool,
    /// No start at constant acceleration (the guess that follows a limb turning back, as a galloping animal's legs do)
    #[arg(long)]
    pub no_accelerated_guess: bool,
    /// The runs from the several guesses are compared, region by region, once their updates fall below this many times --threshold; only the kept one runs on to --threshold. 1 runs them all to --threshold (range: 1..=1e6)
    #[arg(long, value_name = "FACTOR", default_value_t = TrackParams::default().guess_screening)]
    pub guess_screening: f64,
    /// The screening compares the runs once no more than this share of the centers still move more than --guess-screening × --threshold; 0 waits for every center (range: 0 <= SHARE < 1)
    #[arg(long, value_name = "SHARE", default_value_t = TrackParams::default().screening_unsettled)]
    pub screening_unsettled: f64,
    /// The guesses' runs up to the screening assign blocks of N³ voxels, each by its voxels' centroid; the kept run goes on on voxels. 2 tracks in a little over half the time, with a little worse correspondence; 1 screens on voxels (range: 1..=8)
    #[arg(long, value_name = "N", default_value_t = TrackParams::default().screening_block)]
    pub screening_block: usize,
    /// Once a frame has converged, turn the centers a fast limb left without volume, as one part about its joint, toward the volume no other cell's motion carries there: on keeps fast thin parts; off is the paper's tracking
    #[arg(long, value_name = "WHEN", default_value = "on")]
    pub reclaim: Switch,
    /// Over-relaxation of the tracking iterations: each step goes ω times the way to the paper's update; 1 is the paper's (range: 0 < ω < 2)
    #[arg(long, value_name = "ω", default_value_t = TrackParams::default().tracking_over_relaxation)]
    pub tracking_over_relaxation: f64,
    /// Lloyd iterations placing the centers in frame 0 (range: 1..=100000)
    #[arg(long, default_value_t = TrackParams::default().lloyd_iterations)]
    pub lloyd_iterations: usize,
    /// Over-relaxation of those Lloyd iterations (range: 0 < ω < 2)
    #[arg(long, default_value_t = TrackParams::default().over_relaxation)]
    pub over_relaxation: f64,
    /// Take lengths (ρ, thresholds) in the input's units, not as fractions of the bounding box's longest side
    #[arg(long)]
    pub absolute_units: bool,
    /// Save the tracking state in this folder every few frames, and the refinement's after every batch and once a minute, on Ctrl-C and at the end, so an interrupted run can --resume
    #[arg(long, value_name = "DIR")]
    pub checkpoint: Option<PathBuf>,
    /// Frames between checkpoints (range: 1..=1000000)
    #[arg(long, value_name = "FRAMES", default_value_t = Checkpointing::new("").every, requires = "checkpoint")]
    pub checkpoint_every: usize,
    /// Continue from the checkpoints in --checkpoint DIR (same command, same input), in tracking or in refinement; start over if there is none yet
    #[arg(long, requires = "checkpoint")]
    pub resume: bool,
}

impl TrackArgs {
    /// The checkpoint settings (None without --checkpoint); the interval must be in range.
    pub fn checkpointing(&self) -> Result<Option<Checkpointing>> {
        let Some(dir) = self.checkpoint.clone() else {
            return Ok(None);
        };
        if !(1..=1_000_000).contains(&self.checkpoint_every) {
            return Err(voltrack::Error::InvalidParameter(format!(
                "--checkpoint-every is {}, outside 1..=1000000",
                self.checkpoint_every
            ))
            .into());
        }
        Ok(Some(Checkpointing {
            every: self.checkpoint_every,
            resume: self.resume,
            ..Checkpointing::new(dir)
        }))
    }

    pub fn params(&self) -> TrackParams {
        TrackParams {
            centers: self.centers,
            seed: self.seed,
            affinity: match self.affinity {
                AffinityArg::Max => AffinityKind::Max,
                AffinityArg::Iir => AffinityKind::Iir,
            },
            rho_p: self.rho_p,
            rho_m: self.rho_m,
            alpha: self.alpha,
            beta: self.beta,
            mu: self.mu,
            presmooth_steps: self.presmooth,
            threshold: self.threshold,
            max_iterations: self.max_iterations,
            convergence_window: self.convergence_window,
            damped_guess: (!self.single_guess).then_some(self.damped_guess),
            accelerated_guess: !self.single_guess && !self.no_accelerated_guess,
            guess_screening: self.guess_screening,
            screening_unsettled: self.screening_unsettled,
            screening_block: self.screening_block,
            tracking_over_relaxation: self.tracking_over_relaxation,
            reclaim: self.reclaim == Switch::On,
            lloyd_iterations: self.lloyd_iterations,
            over_relaxation: self.over_relaxation,
            absolute_units: self.absolute_units,
            reference: self.reference,
        }
    }
}

fn parse_reference(s: &str) -> std::result::Result<Reference, String> {
    match s {
        "auto" => Ok(Reference::Auto),
        "first" => Ok(Reference::First),
        _ => s
            .parse()
            .map(Reference::Frame)
            .map_err(|_| format!("'{s}' is not auto, first or a frame number")),
    }
}

/// The ids of [`RefineArgs`]' options.
pub const REFINE_IDS: [&str; 9] = [
    "remove",
    "batches",
    "no_optimise",
    "absolute_irregularity",
    "beta_hat",
    "rho_gp",
    "rho_gm",
    "global_iterations",
    "cell_memory",
];

#[derive(Args)]
pub struct RefineArgs {
    /// Irregular centers to remove in all [default: 1 % of the centers, at least 1] (range: 0..=centers - 2)
    #[arg(long)]
    pub remove: Option<usize>,
    /// n_go: batches the removal is split into, each followed by a global optimisation (range: 1..=100)
    #[arg(long, default_value_t = RefineParams::default().batches)]
    pub batches: usize,
    /// Remove irregular centers without the global optimisation
    #[arg(long)]
    pub no_optimise: bool,
    /// Rank irregular centers by the paper's absolute I_i, which removes sparsely covered thin parts first, instead of relative to each center's spacing
    #[arg(long)]
    pub absolute_irregularity: bool,
    /// β̂: weight of the centroid term in the global energy (range: 0 < β̂ <= 1e6)
    #[arg(long, default_value_t = RefineParams::default().beta_hat)]
    pub beta_hat: f64,
    /// ρ_gp: largest distance at which ω_max is 0.5 (range: 1e-12..=1e12)
    #[arg(long, default_value_t = RefineParams::default().rho_gp)]
    pub rho_gp: f64,
    /// ρ_gm: largest motion dissimilarity at which ω is 0.5 (range: 1e-12..=1e12)
    #[arg(long, default_value_t = RefineParams::default().rho_gm)]
    pub rho_gm: f64,
    /// Global iterations per batch (range: 0..=100000)
    #[arg(long, default_value_t = RefineParams::default().max_iterations)]
    pub global_iterations: usize,
    /// Memory for the cell assignments the global optimisation keeps between its steps, in GiB; frames past it are assigned afresh at every step (the same result, more slowly) [default: half of --max-memory, or of what the system has available] (range: 0 < GIB <= 1e9)
    #[arg(long, value_name = "GIB")]
    pub cell_memory: Option<f64>,
}

impl RefineArgs {
    /// The refinement's parameters; `absolute_units` comes from the tracking
    /// (its flag, or the attributes of the trajectories being refined), so
    /// every caller must say it.
    pub fn params(&self, absolute_units: bool) -> RefineParams {
        RefineParams {
            absolute_units,
            remove: self.remove,
            batches: self.batches,
            optimise: !self.no_optimise,
            relative_irregularity: !self.absolute_irregularity,
            beta_hat: self.beta_hat,
            rho_gp: self.rho_gp,
            rho_gm: self.rho_gm,
            max_iterations: self.global_iterations,
            cell_memory: self.cell_memory.map(|g| g * (1u64 << 30) as f64),
            ..Default::default()
        }
    }
}

/// `--basis`: a number of components, or chosen by the result's fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BasisArg {
    /// The fewest components within the result's own fit to the input
    /// ([`BasisChoice::Bounded`]).
    Auto,
    /// One target per frame (exact), also with `--compress`.
    PerFrame,
    Components(usize),
}

fn parse_basis(text: &str) -> Result<BasisArg, String> {
    if text.eq_ignore_ascii_case("auto") {
        return Ok(BasisArg::Auto);
    }
    if text.eq_ignore_ascii_case("per-frame") {
        return Ok(BasisArg::PerFrame);
    }
    text.parse::<usize>()
        .map(BasisArg::Components)
        .map_err(|_| {
            format!("'{text}' is neither a whole number of components, 'auto' nor 'per-frame'")
        })
}

/// glTF's samplers for the morph weights (see `GltfExportOptions::interpolation`).
#[derive(Clone, Copy, ValueEnum)]
pub enum InterpolationArg {
    /// Each capture held for 1/fps: a player shows the captures and nothing else
    Step,
    /// Consecutive captures blended: smoother at display rates above the capture rate, but the poses between captures are blends
    Linear,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum BlendArg {
    Dq,
    Linear,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    On,
    Off,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SegmentsArg {
    /// Cut where the input's parts merge or part, a mesh of its own for each stretch
    Auto,
    /// One mesh for the whole take
    Off,
}

#[derive(Args)]
pub struct ConvertArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Output file (.glb, .exr, .pc2) or directory (OBJ sequence)
    #[arg(long, short = 'o')]
    pub output: PathBuf,
    /// Output format [default: from the extension; a directory means an OBJ sequence]
    #[arg(long, value_enum)]
    pub format: Option<OutputFormat>,
    /// Frames per second of the animation (range: 0.001..=100000)
    #[arg(long, default_value_t = GltfExportOptions::default().fps)]
    pub fps: f32,
    /// How players go from one capture to the next in a .glb, per-frame targets and --basis alike
    #[arg(long, value_enum, default_value = "step")]
    pub interpolation: InterpolationArg,
    /// Compact glTF: K principal components as morph targets; 'auto': the fewest components whose error, mean and largest, stays within the result's own fit to the input (the default with --compress); 'per-frame': one target per frame, exact [default: one target per frame up to 256 frames; beyond, the fewest components (at most 128) that keep every vertex within 0.1 % of the diagonal, else one target per frame] (range: 1..=100000, auto or per-frame)
    #[arg(long, value_parser = parse_basis)]
    pub basis: Option<BasisArg>,
    /// Compressed glTF for the web: quantised positions, normals and morph deltas (KHR_mesh_quantization) encoded by meshoptimizer (EXT_meshopt_compression); viewers need a meshopt decoder (three.js: MeshoptDecoder). Prints the positions' error
    #[arg(long)]
    pub compress: bool,
    /// Vertex normals and their morph deltas in a glTF, recomputed from every frame's geometry; 'off' leaves them out, and players derive them from each frame's geometry (three.js shades flat), for a compressed file 35-45 % smaller
    #[arg(long, value_enum, default_value = "on")]
    pub normals: Switch,
    /// Also write a self-contained HTML report: fit to the input per frame, PCAC/DFU, irregularity, time per stage
    #[arg(long, value_name = "HTML")]
    pub report: Option<PathBuf>,
    /// Name of the animated object: the glTF node, mesh and animation, the OBJ's object [default: the input directory's name, or the frames' common file-name prefix]
    #[arg(long)]
    pub name: Option<String>,
    /// Print a machine-readable summary on stdout, and nothing else there
    #[arg(long)]
    pub json: bool,
    /// Per-vertex animation as an EXR vertex-animation texture, with its mesh (.glb, TEXCOORD_1 addressing the texels) and a JSON sidecar beside it (same as --format vat)
    #[arg(
        long,
        conflicts_with = "format",
        help_heading = "Vertex-animation texture"
    )]
    pub vat: bool,
    /// Most vertices per row of the vertex-animation texture: its width; a frame takes as many rows as its vertices need (range: 1..=65536)
    #[arg(long, value_name = "TEXELS", default_value_t = VatOptions::default().max_width, help_heading = "Vertex-animation texture")]
    pub vat_max_width: usize,
    /// Largest height of the vertex-animation texture (frames × rows per frame); a longer animation is refused (range: 1..=65536)
    #[arg(long, value_name = "TEXELS", default_value_t = VatOptions::default().max_height, help_heading = "Vertex-animation texture")]
    pub vat_max_height: usize,
    /// Vertex-animation texture with power-of-two sides (unused texels zero)
    #[arg(long, help_heading = "Vertex-animation texture")]
    pub vat_power_of_two: bool,
    #[command(flatten, next_help_heading = "Tracking")]
    pub track: TrackArgs,
    /// Conversions at most, each with the next seed, while the result warns of a lost part; the one warned of the fewest frames is kept (1: convert once) (range: 1..=100)
    #[arg(long, default_value_t = voltrack::pipeline::ConvertOptions::default().attempts, help_heading = "Tracking")]
    pub attempts: usize,
    /// Skip irregular-center removal and the global optimisation
    #[arg(long, conflicts_with_all = ["remove", "batches", "no_optimise", "beta_hat", "rho_gp", "rho_gm", "global_iterations"], help_heading = "Refinement")]
    pub no_refine: bool,
    #[command(flatten, next_help_heading = "Refinement")]
    pub refine: RefineArgs,
    /// Centers each vertex follows (range: 1..=64)
    #[arg(long, default_value_t = DeformParams::default().neighbors, help_heading = "Mesh")]
    pub bind_neighbors: usize,
    /// Rounds of spreading each vertex's center weights to its mesh neighbours (0: off) (range: 0..=1000)
    #[arg(long, default_value_t = DeformParams::default().smoothing, help_heading = "Mesh")]
    pub bind_smoothing: usize,
    /// Blending of the centers' motions
    #[arg(long, value_enum, default_value = "dq", help_heading = "Mesh")]
    pub blend: BlendArg,
    /// Where the input's parts merge or part (a ball thrown, caught), cut the take and deform a mesh of each stretch's own, all in one mesh (the others' triangles shrunk to a point while one is shown); off keeps one mesh
    #[arg(long, value_enum, default_value = "auto", help_heading = "Mesh")]
    pub segments: SegmentsArg,
    /// Rounds of fitting every frame's mesh onto its input surface, keeping its frame-0 edges as far as it can (0: off, the mesh stays as blended) (range: 0..=1000)
    #[arg(long, default_value_t = ConformParams::default().iterations, help_heading = "Mesh")]
    pub conform_iterations: usize,
    /// Stiffness of that fit: weight of keeping the frame-0 edges against lying on the input surface (range: 0 < s <= 1e6)
    #[arg(long, default_value_t = ConformParams::default().stiffness, help_heading = "Mesh")]
    pub conform_stiffness: f64,
    /// Strain at which an edge's rigidity weighs half in that fit, so joints bend where they are instead of bending the parts beside them (0: every edge alike) (range: 0 <= s <= 1e6)
    #[arg(long, default_value_t = ConformParams::default().bend_strain, help_heading = "Mesh")]
    pub conform_bend_strain: f64,
    /// Mean strain, over a first fit of up to 16 frames spread over the take, at which an edge's rigidity weighs half in every frame's fit: joints are where the take bends (0: no first fit, each frame finds its own) (range: 0 <= s <= 1e6)
    #[arg(long, default_value_t = ConformParams::default().joint_strain, help_heading = "Mesh")]
    pub conform_joint_strain: f64,
}

impl ConvertArgs {
    /// The output format: as given (`--format`, `--vat`), which must agree
    /// with the output's extension when that names a format, or from the
    /// extension.
    pub fn format(&self) -> Result<OutputFormat> {
        let bad = |m: String| Err(voltrack::Error::InvalidParameter(m).into());
        let ext = self
            .output
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let implied = OutputFormat::from_extension(&ext);
        let given = if self.vat {
            Some(OutputFormat::Vat)
        } else {
            self.format
        };
        let format = match (given, implied) {
            (Some(f), None) | (None, Some(f)) => f,
            (Some(OutputFormat::Vat), Some(OutputFormat::Exr)) => OutputFormat::Vat,
            (Some(f), Some(i)) if f == i => f,
            (Some(f), Some(i)) => {
                return bad(format!(
                "{}: the extension says {} but {} was asked for; name the output after its format",
                self.output.display(),
                i.name(),
                f.name()
            ))
            }
            (None, None) if ext.is_empty() => OutputFormat::ObjSequence,
            (None, None) => {
                return bad(format!(
                    "{}: cannot tell the output format from '.{ext}'; use --format",
                    self.output.display()
                ))
            }
        };
        if self.basis.is_some() && !format.is_gltf() {
            return bad(format!(
                "--basis shapes glTF morph targets, but the output is {}",
                format.name()
            ));
        }
        let d = VatOptions::default();
        if (self.vat_power_of_two
            || self.vat_max_width != d.max_width
            || self.vat_max_height != d.max_height)
            && format != OutputFormat::Vat
        {
            return bad(format!("--vat-max-width, --vat-max-height and --vat-power-of-two shape a vertex-animation texture, but the output is {}", format.name()));
        }
        if self.compress && !format.is_gltf() {
            return bad(format!(
                "--compress compresses a GLB, but the output is {}",
                format.name()
            ));
        }
        Ok(format)
    }

    pub fn deform_params(&self) -> DeformParams {
        DeformParams {
            neighbors: self.bind_neighbors,
            smoothing: self.bind_smoothing,
            blending: match self.blend {
                BlendArg::Dq => Blending::DualQuaternion,
                BlendArg::Linear => Blending::Linear,
            },
            segments: self.segments == SegmentsArg::Auto,
            ..Default::default()
        }
    }

    pub fn conform_params(&self) -> ConformParams {
        ConformParams {
            iterations: self.conform_iterations,
            stiffness: self.conform_stiffness,
            bend_strain: self.conform_bend_strain,
            joint_strain: self.conform_joint_strain,
            absolute_units: self.track.absolute_units,
            ..Default::default()
        }
    }

    /// The vertex-animation texture's options, the mesh called `name`.
    pub fn vat_options(&self, name: String) -> VatOptions {
        VatOptions {
            fps: self.fps,
            name,
            max_width: self.vat_max_width,
            max_height: self.vat_max_height,
            power_of_two: self.vat_power_of_two,
        }
    }

    /// Whether the compact basis is chosen by the result's fit to the input:
    /// `--basis auto`, or `--compress` without `--basis`.
    pub fn basis_by_fit(&self) -> bool {
        match self.basis {
            Some(BasisArg::Auto) => true,
            None => self.compress,
            Some(_) => false,
        }
    }

    /// The glTF options, the object called `name`; a basis chosen by the fit
    /// is bounded by `fit` (by zero without it: per-frame targets).
    pub fn gltf_options(&self, name: String, fit: Option<&SequenceFit>) -> GltfExportOptions {
        GltfExportOptions {
            fps: self.fps,
            name,
            basis: match self.basis {
                Some(BasisArg::Components(k)) => BasisChoice::Components(k),
                Some(BasisArg::PerFrame) => BasisChoice::PerFrame,
                _ if self.basis_by_fit() => {
                    let length = |percent: voltrack::math::Real, f: &SequenceFit| {
                        percent / 100.0 * f.diagonal
                    };
                    let (mean, max) = fit.map_or((0.0, 0.0), |f| {
                        let s = f.summary();
                        (length(s.mean, f), length(s.max, f))
                    });
                    BasisChoice::Bounded { mean, max }
                }
                _ => BasisChoice::Auto,
            },
            compress: self.compress,
            normals: self.normals == Switch::On,
            interpolation: match self.interpolation {
                InterpolationArg::Step => Interpolation::Step,
                InterpolationArg::Linear => Interpolation::Linear,
            },
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `track` refuses these without --refine: the list must be the options.
    #[test]
    fn refine_ids_are_the_refine_options() {
        let command = RefineArgs::augment_args(clap::Command::new("refine"));
        let ids: Vec<&str> = command
            .get_arguments()
            .map(|a| a.get_id().as_str())
            .collect();
        assert_eq!(ids, REFINE_IDS);
    }
}
