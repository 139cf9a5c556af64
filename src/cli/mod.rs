//! Command-line definitions and the glue from flags to library calls.

mod bars;
mod options;
mod plot;
mod preview;
mod report;
#[cfg(test)]
#[path = "../../tests/common/mod.rs"]
pub(crate) mod test_support;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use options::{BasisArg, ConvertArgs, InputArgs, OutputFormat, RefineArgs, TrackArgs};

/// The log as env_logger writes it (`RUST_LOG`, warnings by default), but
/// each warning only once: a frame is read by more than one pass, and its
/// warnings (a missing texture, a bare `usemtl`) would repeat with every
/// read.
struct WarnOnce {
    inner: env_logger::Logger,
    seen: std::sync::Mutex<std::collections::HashSet<String>>,
}

impl log::Log for WarnOnce {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        self.inner.enabled(metadata)
    }

    fn log(&self, record: &log::Record) {
        if !self.inner.matches(record) {
            return;
        }
        if record.level() <= log::Level::Warn {
            let mut seen = self.seen.lock().unwrap_or_else(|e| e.into_inner());
            if !seen.insert(record.args().to_string()) {
                return;
            }
        }
        self.inner.log(record);
    }

    fn flush(&self) {
        self.inner.flush();
    }
}

/// Installs [`WarnOnce`] as the logger.
pub fn init_logging() {
    let inner =
        env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).build();
    let max = inner.filter();
    let logger = Box::leak(Box::new(WarnOnce {
        inner,
        seen: Default::default(),
    }));
    if log::set_logger(logger).is_ok() {
        log::set_max_level(max);
    }
}
use std::path::{Path, PathBuf};
use voltrack::checkpoint::Checkpointing;
use voltrack::io::FrameFiles;
use voltrack::math::Real;
use voltrack::metrics::Quality;
use voltrack::params::CoverageParams;
use voltrack::pipeline;
use voltrack::Stage;

#[derive(Parser)]
#[command(
    name = "voltrack",
    version,
    about = "Time-varying meshes to dynamic meshes by volume tracking"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert a captured sequence into one animated mesh (voxelise, track, refine, deform, export)
    Convert(ConvertArgs),
    /// Voxelise every frame on one grid and write one .binvox per frame
    Voxelize {
        #[command(flatten)]
        input: InputArgs,
        /// Output directory
        #[arg(long, short = 'o')]
        output: PathBuf,
        /// Print a machine-readable summary on stdout
        #[arg(long)]
        json: bool,
    },
    /// Track volume elements through the sequence; write their trajectories as EXR
    Track {
        #[command(flatten)]
        input: InputArgs,
        /// Output EXR (width = centers, height = frames, RGB = xyz)
        #[arg(long, short = 'o')]
        output: PathBuf,
        #[command(flatten)]
        track: TrackArgs,
        /// Also remove irregular centers and optimise globally
        #[arg(long)]
        refine: bool,
        #[command(flatten)]
        refine_args: RefineArgs,
        /// Print a machine-readable summary on stdout
        #[arg(long)]
        json: bool,
    },
    /// Remove irregular centers from tracked trajectories and optimise globally
    Refine {
        /// Trajectories written by `voltrack track`
        centers: PathBuf,
        /// The sequence they were tracked on
        #[arg(long, required = true, num_args = 1..)]
        input: Vec<PathBuf>,
        #[arg(long, short = 'o')]
        output: PathBuf,
        #[command(flatten)]
        refine_args: RefineArgs,
        /// Save the refinement's state in this folder after every batch, once a minute within one, and on Ctrl-C, so an interrupted run can --resume
        #[arg(long, value_name = "DIR")]
        checkpoint: Option<PathBuf>,
        /// Continue from the refinement saved in --checkpoint DIR (same command, same trajectories and input); start over if there is none yet
        #[arg(long, requires = "checkpoint")]
        resume: bool,
        #[arg(long)]
        json: bool,
    },
    /// PCAC, DFU and irregularity of trajectories against their sequence
    Metrics {
        centers: PathBuf,
        #[arg(long, required = true, num_args = 1..)]
        input: Vec<PathBuf>,
        /// Print a machine-readable summary on stdout
        #[arg(long)]
        json: bool,
        /// Draw the irregularity curve (sorted I_i) as SVG
        #[arg(long)]
        plot: Option<PathBuf>,
    },
}

pub fn run() -> Result<()> {
    let matches = <Cli as clap::CommandFactory>::command().get_matches();
    let cli =
        <Cli as clap::FromArgMatches>::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    check_ignored(&cli, &matches)?;
    bars::handle_interrupts().context("installing the Ctrl-C handler")?;
    match cli.command {
        Command::Convert(args) => convert(args),
        Command::Voxelize {
            input,
            output,
            json,
        } => voxelize(input, output, json),
        Command::Track {
            input,
            output,
            track,
            refine,
            refine_args,
            json,
        } => track_command(input, output, track, refine.then_some(refine_args), json),
        Command::Refine {
            centers,
            input,
            output,
            refine_args,
            checkpoint,
            resume,
            json,
        } => {
            let checkpoint = checkpoint.map(|dir| Checkpointing {
                resume,
                ..Checkpointing::new(dir)
            });
            refine_command(centers, input, output, refine_args, checkpoint, json)
        }
        Command::Metrics {
            centers,
            input,
            json,
            plot,
        } => metrics(centers, input, json, plot),
    }
}

/// Refuses options given on the command line that the rest of it makes
/// pointless: a user who sets one expects it to change something.
fn check_ignored(cli: &Cli, matches: &clap::ArgMatches) -> Result<()> {
    let Some((_, sub)) = matches.subcommand() else {
        return Ok(());
    };
    let given = |id: &str| {
        sub.ids().any(|i| i.as_str() == id)
            && sub.value_source(id) == Some(clap::parser::ValueSource::CommandLine)
    };
    let flag = |id: &str| format!("--{}", id.replace('_', "-"));
    let refuse = |m: String| -> Result<()> { Err(voltrack::Error::InvalidParameter(m).into()) };
    let track = match &cli.command {
        Command::Convert(args) => Some(&args.track),
        Command::Track { track, .. } => Some(track),
        _ => None,
    };
    if track.is_some_and(|t| !matches!(t.affinity, options::AffinityArg::Iir)) && given("alpha") {
        return refuse("--alpha weighs the IIR affinity's filter, which --affinity max does not use: drop it, or add --affinity iir".into());
    }
    if let Command::Track { refine: false, .. } = &cli.command {
        if let Some(id) = options::REFINE_IDS.iter().find(|id| given(id)) {
            return refuse(format!("{} shapes the refinement, which `track` runs only with --refine: add --refine, or drop it", flag(id)));
        }
    }
    if let Command::Convert(args) = &cli.command {
        if given("fps") {
            if let Ok(format) = args.format() {
                if !format.is_timed() {
                    return refuse(format!("--fps times an animation, but the output is {}, which has no frame rate: drop it", format.name()));
                }
            }
        }
        if given("interpolation") {
            if let Ok(format) = args.format() {
                if !format.is_gltf() {
                    return refuse(format!("--interpolation chooses the glTF animation's samplers, but the output is {}, which has none: drop it", format.name()));
                }
            }
        }
        if given("normals") {
            if let Ok(format) = args.format() {
                if !format.is_gltf() {
                    return refuse(format!("--normals chooses whether a glTF carries normals, but the output is {}: drop it", format.name()));
                }
            }
        }
        let conform = [
            "conform_stiffness",
            "conform_bend_strain",
            "conform_joint_strain",
        ];
        if args.conform_iterations == 0 {
            if let Some(id) = conform.iter().find(|id| given(id)) {
                return refuse(format!("{} shapes the conform stage, which --conform-iterations 0 turns off: drop one of them", flag(id)));
            }
        }
    }
    Ok(())
}

/// The frames `inputs` name, voxelised.
fn load(
    inputs: &[PathBuf],
    voxel: &voltrack::voxel::VoxelParams,
    bars: &bars::Bars,
) -> Result<(FrameFiles, voltrack::voxel::VoxelSequence)> {
    let files = FrameFiles::discover(inputs)?;
    let seq = voltrack::voxel::voxelize_sequence(&files, voxel, bars.progress())?;
    Ok((files, seq))
}

fn print_json(value: &serde_json::Value) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(value)?);
    Ok(())
}

fn voxelize(input: InputArgs, output: PathBuf, json: bool) -> Result<()> {
    let params = input.voxel_params();
    params.validate()?;
    input.plan()?.dir(&output, "the output folder").check()?;
    let bars = bars::Bars::new();
    let (_, seq) = load(&input.input, &params, &bars)?;
    let written = voltrack::export::binvox::write_binvox_frames(&seq, &output)?;
    bars.finish();
    let g = &seq.grid;
    if json {
        let frames: Vec<_> = seq
            .frames
            .iter()
            .zip(&seq.names)
            .zip(&written)
            .map(|((o, p), w)| serde_json::json!({"input": p, "output": w, "occupied": o.len()}))
            .collect();
        return print_json(&serde_json::json!({
            "frames": frames,
            "resolution": params.resolution,
            "grid": {"dims": g.dims, "origin": g.origin.coords.as_slice(), "voxel_size": g.voxel_size},
            "seconds": {"read": seq.read_seconds, "voxelize": seq.voxelize_seconds},
        }));
    }
    println!(
        "grid {} x {} x {} voxels of {:.6} (origin {:.4} {:.4} {:.4})",
        g.dims[0], g.dims[1], g.dims[2], g.voxel_size, g.origin.x, g.origin.y, g.origin.z
    );
    for (o, w) in seq.frames.iter().zip(&written) {
        println!("{:>10} occupied  {}", o.len(), w.display());
    }
    println!(
        "{} frames: read {:.2} s, voxelised {:.2} s ({:.1} ms/frame)",
        seq.frames.len(),
        seq.read_seconds,
        seq.voxelize_seconds,
        1000.0 * seq.voxelize_seconds / seq.frames.len() as f64
    );
    Ok(())
}

fn quality_json(q: &Quality) -> serde_json::Value {
    serde_json::json!({"pcac": q.pcac, "dfu": q.dfu, "dfu_per_frame": q.dfu_per_frame, "largest_irregularity": q.largest_irregularity(20)})
}

fn track_command(
    input: InputArgs,
    output: PathBuf,
    track: TrackArgs,
    refine: Option<RefineArgs>,
    json: bool,
) -> Result<()> {
    let voxel = input.voxel_params();
    let params = track.params();
    voxel.validate()?;
    params.validate()?;
    if let Some(r) = &refine {
        r.params(track.absolute_units).validate(params.centers)?;
    }
    let checkpoint = track.checkpointing()?;
    let frames = voltrack::io::discover_frames(&input.input)?.len();
    voltrack::track::check_reference(params.reference, frames, checkpoint.is_some())?;
    let mut plan = input.plan()?.file(&output, "the output");
    if let Some(c) = &checkpoint {
        plan = plan.checkpoints(c);
    }
    plan.check()?;
    let bars = bars::Bars::new();
    let (_, seq) = load(&input.input, &voxel, &bars)?;
    let tracked = voltrack::track::track_with_checkpoints(
        &seq,
        &params,
        checkpoint.as_ref(),
        bars.progress(),
    )?;
    let (
        pipeline::Tracked {
            quality,
            timings,
            reference,
            ..
        },
        trajectories,
    ) = pipeline::Tracked::split(tracked, true);
    let before = quality.expect("measured");
    let (traj, refined, refine_params) = match refine {
        Some(r) => {
            let rp = r.params(track.absolute_units).within(voxel.max_memory);
            let res = pipeline::refine_tracked(
                trajectories,
                &seq,
                &rp,
                checkpoint.as_ref(),
                bars.progress(),
            )?;
            (res.trajectories, Some(res.refinement), Some(rp))
        }
        None => (trajectories, None, None),
    };
    let meta = pipeline::trajectory_metadata(
        &seq,
        &traj,
        &voxel,
        &params,
        refine_params
            .as_ref()
            .zip(refined.as_ref())
            .map(|(p, r)| (p, r.removed.as_slice())),
    );
    voltrack::export::exr::write_trajectories_exr(&output, &traj, &meta)?;
    bars.finish();
    let after = refined.as_ref().map(|_| pipeline::measure(&traj, &seq));
    let coverage = pipeline::check_coverage(&traj, &seq, &CoverageParams::default())?;
    let timing_json: Vec<_> = timings.iter().map(|t| serde_json::json!({"seconds": t.total, "iterations": t.iterations, "assign": t.assign, "fit": t.fit, "affinity": t.affinity, "dropped_iterations": t.dropped_iterations, "kept_guess": t.kept_guess})).collect();
    if json {
        return print_json(&serde_json::json!({
            "output": output,
            "frames": seq.frames.len(),
            "centers": params.centers,
            "resolution": voxel.resolution,
            "affinity": params.affinity,
            "reference": {"frame": reference.frame, "input": seq.names[reference.frame], "asked": reference.asked, "why": reference.why},
            "pcac": before.pcac,
            "dfu": before.dfu,
            "seconds": {"read": seq.read_seconds, "voxelize": seq.voxelize_seconds, "voxelize_per_frame": seq.voxelize_seconds / seq.frames.len() as f64, "track_per_frame": timing_json},
            "refined": refined.as_ref().zip(after.as_ref()).map(|(r, q)| serde_json::json!({"removed": r.removed, "after": quality_json(q), "energy": r.batches, "seconds": r.seconds})),
            "coverage": coverage,
        }));
    }
    let r = reference.frame;
    let tracking: f64 = timings.iter().map(|t| t.total).sum::<f64>() - timings[r].total;
    println!(
        "{} frames, {} centers, resolution {}, affinity {:?}",
        seq.frames.len(),
        params.centers,
        voxel.resolution,
        params.affinity
    );
    println!("reference: frame {r} ({}), {}", seq.names[r], reference.why);
    println!(
        "voxelised in {:.2} s; frame {r} placed in {:.2} s; tracked in {:.2} s ({:.3} s/frame)",
        seq.voxelize_seconds,
        timings[r].total,
        tracking,
        tracking / (seq.frames.len() - 1).max(1) as f64
    );
    println!("PCAC {:.4}  DFU {:.4}", before.pcac, before.dfu);
    if let (Some(r), Some(q)) = (&refined, &after) {
        println!(
            "refined: removed {} centers in {:.1} s; PCAC {:.4}  DFU {:.4}",
            r.removed.len(),
            r.seconds,
            q.pcac,
            q.dfu
        );
    }
    println!("wrote {}", output.display());
    for w in voltrack::metrics::lost_parts(&coverage, None)
        .warnings()
        .into_iter()
        .map(|w| w.message)
    {
        println!("{w}");
    }
    Ok(())
}

type Tracked = (
    voltrack::model::Trajectories,
    voltrack::model::TrajectoryMetadata,
);

/// Reads trajectories written by `voltrack track`.
fn read_tracked(centers: &Path) -> Result<Tracked> {
    Ok(voltrack::io::exr::read_trajectories_exr(centers)?)
}

/// Re-voxelises the input of trajectories at their stored resolution.
fn load_tracked_input(
    centers: &Path,
    tracked: &Tracked,
    input: &[PathBuf],
    bars: &bars::Bars,
) -> Result<voltrack::voxel::VoxelSequence> {
    let (traj, meta) = tracked;
    let resolution = pipeline::resolution_of(meta, centers)?;
    let voxel = voltrack::voxel::VoxelParams {
        resolution,
        ..Default::default()
    };
    let (_, seq) = load(input, &voxel, bars)?;
    pipeline::check_grid(meta, &seq.grid, traj, &seq, centers)?;
    Ok(seq)
}

/// What a command reads: the frames its inputs name, for [`voltrack::pipeline::OutputPlan`].
fn plan_reading(inputs: &[PathBuf]) -> Result<voltrack::pipeline::OutputPlan> {
    let frames = voltrack::io::discover_frames(inputs)?;
    Ok(voltrack::pipeline::OutputPlan::new().reading(inputs, &frames))
}

fn refine_command(
    centers: PathBuf,
    input: Vec<PathBuf>,
    output: PathBuf,
    args: RefineArgs,
    checkpoint: Option<Checkpointing>,
    json: bool,
) -> Result<()> {
    let tracked = read_tracked(&centers)?;
    let params = args.params(tracked.1.absolute_units());
    params.validate(tracked.0.centers)?;
    let mut plan = plan_reading(&input)?
        .reading_file(&centers)
        .file(&output, "the output");
    if let Some(c) = &checkpoint {
        plan = plan.checkpoints(c);
    }
    plan.check()?;
    let bars = bars::Bars::new();
    let seq = load_tracked_input(&centers, &tracked, &input, &bars)?;
    let (traj, meta) = tracked;
    let before = pipeline::measure(&traj, &seq);
    let voltrack::refine::RefineResult {
        trajectories,
        refinement: res,
    } = voltrack::refine::refine_with_checkpoints(
        traj,
        &seq,
        &params,
        checkpoint.as_ref(),
        bars.progress(),
    )?;
    let after = pipeline::measure(&trajectories, &seq);
    let mut meta = meta;
    pipeline::record_refinement(&mut meta, &params, &res.removed);
    voltrack::export::exr::write_trajectories_exr(&output, &trajectories, &meta)?;
    bars.finish();
    if json {
        return print_json(&serde_json::json!({
            "output": output, "removed": res.removed, "before": quality_json(&before), "after": quality_json(&after),
            "energy": res.batches, "seconds": res.seconds,
        }));
    }
    println!(
        "removed {} irregular centers: {:?}",
        res.removed.len(),
        res.removed
    );
    println!(
        "PCAC {:.4} -> {:.4}   DFU {:.4} -> {:.4}",
        before.pcac, after.pcac, before.dfu, after.dfu
    );
    for (b, h) in res.batches.iter().enumerate() {
        if let (Some(first), Some(last)) = (h.first(), h.last()) {
            println!(
                "batch {}: energy {:.6e} -> {:.6e} in {} steps",
                b + 1,
                first.energy,
                last.energy,
                h.len() - 1
            );
        }
    }
    println!("wrote {} ({:.1} s)", output.display(), res.seconds);
    Ok(())
}

fn metrics(centers: PathBuf, input: Vec<PathBuf>, json: bool, plot: Option<PathBuf>) -> Result<()> {
    let tracked = read_tracked(&centers)?;
    let mut plan = plan_reading(&input)?.reading_file(&centers);
    if let Some(p) = &plot {
        plan = plan.file(p, "the plot");
    }
    plan.check()?;
    let bars = bars::Bars::new();
    let seq = load_tracked_input(&centers, &tracked, &input, &bars)?;
    let traj = tracked.0;
    let q = pipeline::measure(&traj, &seq);
    bars.finish();
    if let Some(p) = &plot {
        let svg = plot::irregularity_curve_svg(&q.irregularity);
        voltrack::files::write_atomic(p, |w| std::io::Write::write_all(w, svg.as_bytes()))
            .with_context(|| "writing the plot")?;
    }
    if json {
        return print_json(&serde_json::json!({
            "frames": traj.frames, "centers": traj.centers, "pcac": q.pcac, "dfu": q.dfu,
            "dfu_per_frame": q.dfu_per_frame, "irregularity": q.irregularity,
        }));
    }
    println!("{} frames, {} centers", traj.frames, traj.centers);
    println!("PCAC {:.4}", q.pcac);
    println!(
        "DFU  {:.4} (mean over frames; worst frame {:.4})",
        q.dfu,
        q.dfu_per_frame.iter().copied().fold(0.0, f64::max)
    );
    let top = q.largest_irregularity(10);
    println!(
        "largest irregularity: {}",
        top.iter()
            .map(|v| format!("{v:.4e}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    if let Some(p) = plot {
        println!("irregularity curve: {}", p.display());
    }
    Ok(())
}

fn convert(args: ConvertArgs) -> Result<()> {
    let plan = convert_plan(&args)?;
    let bars = bars::Bars::new();
    let source = &plan.source;
    let options = pipeline::ConvertOptions {
        voxel: plan.voxel.clone(),
        track: plan.track.clone(),
        refine: plan.refine.clone(),
        deform: plan.deform.clone(),
        conform: plan.conform.clone(),
        coverage: CoverageParams::default(),
        checkpoint: plan.checkpoint.clone(),
        measure_tracked: args.report.is_some(),
        attempts: args.attempts,
    };
    let conv = pipeline::convert(source, &options, bars.progress())?;
    let measured = match &args.report {
        Some(_) => Some(pipeline::Measurements::of(&conv)?),
        None => None,
    };
    let clock = std::time::Instant::now();
    bars.progress().report(Stage::Export, 0, 1);
    let out = &args.output;
    let mut written = write_output(&args, &plan, &conv, &conv.fit, bars.progress())?;
    bars.progress().report(Stage::Export, 1, 1);
    let mut seconds = conv.seconds.clone();
    seconds.push((Stage::Export, clock.elapsed().as_secs_f64()));
    if let (Some(path), Some(measured)) = (&args.report, measured) {
        // Arguments need not be UTF-8 (file names): shown as well as they can be.
        let command = std::env::args_os()
            .map(|a| a.to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join(" ");
        let report = report::ReportInput {
            seconds: &seconds,
            output: Some(out),
            output_bytes: Some(output_size(out)),
            gltf: written.gltf.as_ref(),
            command: Some(&command),
            ..report::ReportInput::new(
                &conv,
                &measured,
                source.paths(),
                &plan.voxel,
                &plan.track,
                plan.refine.as_ref(),
                &plan.deform,
                &plan.conform,
            )
        };
        report::write_report(path, &report)?;
        written.notes.push(format!("report: {}", path.display()));
    }
    bars.finish();
    print_conversion(&args, &plan, &conv, &seconds, written)
}

/// What `convert` checked before reading a frame, and what it will run with.
struct ConvertPlan {
    voxel: voltrack::voxel::VoxelParams,
    track: voltrack::params::TrackParams,
    refine: Option<voltrack::params::RefineParams>,
    deform: voltrack::params::DeformParams,
    conform: voltrack::params::ConformParams,
    format: OutputFormat,
    checkpoint: Option<Checkpointing>,
    /// The input's frames, listed once.
    source: FrameFiles,
    /// The object's name in the outputs.
    name: String,
}

/// Checks every parameter and every output location of `args`, before a
/// frame is read, not after the whole pipeline has run.
fn convert_plan(args: &ConvertArgs) -> Result<ConvertPlan> {
    let voxel = args.input.voxel_params();
    let track = args.track.params();
    let refine = (!args.no_refine).then(|| args.refine.params(args.track.absolute_units));
    let deform = args.deform_params();
    let format = args.format()?;
    let mut conform = args.conform_params();
    voxel.validate()?;
    track.validate()?;
    if let Some(r) = &refine {
        r.validate(track.centers)?;
    }
    deform.validate()?;
    conform.validate()?;
    if !(1..=100).contains(&args.attempts) {
        return Err(voltrack::Error::InvalidParameter(format!(
            "--attempts must be in 1..=100, got {}",
            args.attempts
        ))
        .into());
    }
    if let Some(name) = &args.name {
        voltrack::model::check_name(name)?;
    }
    args.gltf_options(voltrack::model::DEFAULT_NAME.into(), None)
        .validate()?;
    let vat = args.vat_options(voltrack::model::DEFAULT_NAME.into());
    vat.validate()?;
    if format == OutputFormat::Exr && args.report.is_none() {
        // Only the trajectories are written: the fitted mesh would go unused.
        conform.iterations = 0;
    }
    let checkpoint = args.track.checkpointing()?;
    // The frames are listed once, for the output checks, the VAT's height
    // and the default name.
    let found = voltrack::io::discover_frames(&args.input.input)?;
    voltrack::track::check_reference(track.reference, found.len(), checkpoint.is_some())?;
    let reading = voltrack::pipeline::OutputPlan::new().reading(&args.input.input, &found);
    let mut plan = reading.output(format, &args.output);
    if let Some(report) = &args.report {
        plan = plan.file(report, "the report");
    }
    if let Some(c) = &checkpoint {
        plan = plan.checkpoints(c);
    }
    plan.check()?;
    if format == OutputFormat::Vat {
        // The rows a frame takes are known only once the mesh is; one each must fit now.
        vat.check_frames(found.len())?;
    }
    let name = match &args.name {
        Some(name) => name.clone(),
        None => voltrack::io::sequence_name(&args.input.input, &found),
    };
    Ok(ConvertPlan {
        voxel,
        track,
        refine,
        deform,
        conform,
        format,
        checkpoint,
        source: FrameFiles::new(found),
        name,
    })
}

/// What `write_output` wrote: the files, notes for the summary, and what
/// the glTF or VAT writer reports.
struct Written {
    files: Vec<PathBuf>,
    notes: Vec<String>,
    gltf: Option<voltrack::export::gltf::GltfExportReport>,
    vat: Option<voltrack::export::vat::VatLayout>,
}

/// Writes the conversion in `plan.format` to `args.output`; `fit` is the
/// result's fit to the input, which bounds `--basis auto`.
fn write_output(
    args: &ConvertArgs,
    plan: &ConvertPlan,
    conv: &pipeline::Conversion,
    fit: &voltrack::metrics::SequenceFit,
    progress: voltrack::Progress,
) -> Result<Written> {
    let (out, name, format) = (&args.output, &plan.name, plan.format);
    let (voxel, track, refine) = (&plan.voxel, &plan.track, &plan.refine);
    let mut notes = Vec::new();
    let mut glb_report = None;
    let mut vat_layout = None;
    let listed =
        || -> Vec<std::path::PathBuf> { format.files(out).into_iter().map(|f| f.path).collect() };
    let files = match format {
        OutputFormat::Glb | OutputFormat::Gltf => {
            let (report, gltf_notes) =
                write_gltf(args, format, conv, &plan.source, fit, name, progress)?;
            notes.extend(gltf_notes);
            glb_report = Some(report);
            listed()
        }
        OutputFormat::Exr => {
            let removed = conv
                .refined
                .as_ref()
                .map(|r| r.removed.clone())
                .unwrap_or_default();
            // The seed the kept attempt was tracked with.
            let track = voltrack::params::TrackParams {
                seed: conv.seed(),
                ..track.clone()
            };
            let meta = pipeline::trajectory_metadata(
                &conv.sequence,
                &conv.trajectories,
                voxel,
                &track,
                refine.as_ref().map(|r| (r, removed.as_slice())),
            );
            voltrack::export::exr::write_trajectories_exr(out, &conv.trajectories, &meta)?;
            listed()
        }
        OutputFormat::Vat => {
            let report =
                voltrack::export::vat::write_vat(out, &conv.mesh, &args.vat_options(name.clone()))?;
            let l = report.layout;
            notes.push(format!(
                "texture {} x {} texels, {} row(s) per frame; mesh {}",
                l.width,
                l.height,
                l.rows_per_frame,
                voltrack::export::vat::files_beside(out).0.display()
            ));
            vat_layout = Some(l);
            listed()
        }
        OutputFormat::Pc2 => {
            voltrack::export::pc2::write_pc2(out, &conv.mesh, args.fps, name)?;
            listed()
        }
        OutputFormat::ObjSequence => {
            voltrack::export::obj::write_obj_sequence(out, &conv.mesh, name)?
        }
    };
    Ok(Written {
        files,
        notes,
        gltf: glb_report,
        vat: vat_layout,
    })
}

/// Writes the glTF output and says what the basis chose and cost.
fn write_gltf(
    args: &ConvertArgs,
    format: OutputFormat,
    conv: &pipeline::Conversion,
    source: &FrameFiles,
    fit: &voltrack::metrics::SequenceFit,
    name: &str,
    progress: voltrack::Progress,
) -> Result<(voltrack::export::gltf::GltfExportReport, Vec<String>)> {
    let out = &args.output;
    let mut notes = Vec::new();
    // Targets named after the input files, not frame indices.
    let frame_names = source
        .paths()
        .iter()
        .map(|p| {
            p.file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let gltf = voltrack::export::gltf::GltfExportOptions {
        frame_names,
        // The sizes and errors of the bases tried, for --json and the report.
        rate_distortion: args.json || args.report.is_some(),
        ..args.gltf_options(name.to_string(), Some(fit))
    };
    let s = fit.summary();
    let bounded = args.basis_by_fit();
    let write = if format == OutputFormat::Gltf {
        voltrack::export::gltf::write_dynamic_gltf
    } else {
        voltrack::export::gltf::write_dynamic_glb
    };
    let report = write(out, &conv.mesh, &gltf, progress)?;
    // The basis' error in percent of the fit's diagonal, as the fit.
    let animation = conv.mesh.frames.bounds()?.diagonal();
    let as_fit = |e: Real| 100.0 * e * animation / fit.diagonal.max(Real::MIN_POSITIVE);
    if let Some(k) = report.basis {
        let (mean, max) = (
            as_fit(report.reconstruction_error_mean),
            as_fit(report.reconstruction_error_max),
        );
        if bounded {
            notes.push(format!(
                        "--basis auto: {k} components, the fewest whose error (mean {mean:.4} %, max {max:.4} %) stays within the result's own fit to the input (mean {:.4} %, max {:.4} %)",
                        s.mean, s.max
                    ));
        } else if mean > s.mean || max > s.max {
            notes.push(format!(
                        "warning: the compact basis of {k} components adds more error (mean {mean:.4} %, max {max:.4} %) than the result has against the input (mean {:.4} %, max {:.4} %); --basis auto picks the fewest components within it",
                        s.mean, s.max
                    ));
        }
    }
    if bounded && report.basis.is_none() {
        notes.push(
                    "--basis auto: no compact basis within the result's own fit to the input needs fewer morph targets than one per frame; wrote one per frame".into(),
                );
    }
    if let Some(k) = report.basis {
        if args.basis.is_none() && !bounded {
            notes.push(format!(
                        "{} frames is past {} (where three.js and mobile GPUs fail with one morph target per frame): \
                         wrote a compact basis instead; --basis K chooses it yourself",
                        conv.mesh.frames.len(),
                        voltrack::export::basis::AUTO_PER_FRAME_LIMIT
                    ));
        }
        if !report.compressed && !bounded {
            notes.push(format!(
                        "compact basis of {k} components ({} morph targets): reconstruction error max {:.4} %, mean {:.4} % of the diagonal",
                        report.targets,
                        100.0 * report.reconstruction_error_max,
                        100.0 * report.reconstruction_error_mean
                    ));
        }
    }
    if let (Some(BasisArg::Components(k)), None) = (args.basis, report.basis) {
        notes.push(format!(
                    "--basis {k}: that many components need no fewer morph targets than one per frame ({}); wrote one per frame, which is exact",
                    conv.mesh.frames.len().saturating_sub(1)
                ));
    }
    if report.compressed {
        let basis = match report.basis {
            Some(k) => format!(
                ", compact basis of {k} components ({} morph targets)",
                report.targets
            ),
            None if report.steps => format!(
                ", {} morph targets as steps from frame to frame",
                report.targets
            ),
            None => String::new(),
        };
        notes.push(format!(
                    "compressed (KHR_mesh_quantization + EXT_meshopt_compression{basis}): reconstruction error max {:.4} %, mean {:.4} % of the diagonal",
                    100.0 * report.reconstruction_error_max,
                    100.0 * report.reconstruction_error_mean
                ));
    }
    Ok((report, notes))
}

/// Prints what `convert` did: `--json`'s document, or the summary and the
/// warnings.
fn print_conversion(
    args: &ConvertArgs,
    plan: &ConvertPlan,
    conv: &pipeline::Conversion,
    seconds: &[(Stage, f64)],
    written: Written,
) -> Result<()> {
    let (out, name, format, voxel) = (&args.output, &plan.name, plan.format, &plan.voxel);
    let Written {
        files,
        notes,
        gltf: glb_report,
        vat: vat_layout,
    } = written;
    let size = output_size(out);
    let traj = &conv.trajectories;
    let total: f64 = seconds.iter().map(|s| s.1).sum();
    // What carries the name and the frame rate, and where they are written.
    let (named, timed) = (format.has_mesh(), format.is_timed());
    let lost = conv.lost_parts();
    let warnings = lost.warnings();
    if args.json {
        let mut stages: serde_json::Map<String, serde_json::Value> = seconds
            .iter()
            .map(|(stage, s)| (stage.name().to_string(), (*s).into()))
            .collect();
        stages.insert("total".into(), total.into());
        return print_json(&serde_json::json!({
            "output": out,
            "files": files,
            "format": format.name(),
            "name": named.then_some(&name),
            "fps": timed.then_some(args.fps),
            "interpolation": format.is_gltf().then(|| {
                clap::ValueEnum::to_possible_value(&args.interpolation).map(|v| v.get_name().to_string())
            }),
            "frames": conv.mesh.frames.len(),
            "vertices": conv.mesh.base.positions.len(),
            "triangles": conv.mesh.base.triangles.len(),
            "resolution": voxel.resolution,
            "centers": traj.centers,
            "reference": reference_json(conv),
            "segments": conv.segments.iter().map(|s| serde_json::json!({
                "first": s.frames.start,
                "last": s.frames.end - 1,
                "reference": s.reference,
                "input": conv.sequence.names[s.reference],
                "parts": s.parts,
            })).collect::<Vec<_>>(),
            "removed": conv.refined.as_ref().map(|r| &r.removed),
            "seconds": stages,
            // In percent of the input's bounding-box diagonal, as printed.
            "fit_percent": conv.fit.summary(),
            "fit_outliers": &conv.fit_outliers,
            "seed": conv.seed(),
            "attempts": &conv.attempts,
            "coverage": &conv.coverage,
            "lost_parts": &lost,
            "warnings": warnings.iter().map(|w| &w.message).collect::<Vec<_>>(),
            "basis": glb_report.as_ref().map(|r| basis_json(args, r)),
            "vat": vat_layout.map(|l| serde_json::json!({"width": l.width, "height": l.height, "rows_per_frame": l.rows_per_frame})),
            "report": args.report,
            "bytes": size,
        }));
    }
    print_summary(conv, seconds, total, &notes);
    let called = if named {
        format!(", object \"{name}\"")
    } else {
        String::new()
    };
    println!("wrote {} ({}{called})", out.display(), human_size(size));
    for w in warnings {
        println!("{}", w.message);
    }
    Ok(())
}

/// `--json`'s `basis`: the morph targets written and how they were chosen.
fn basis_json(
    args: &ConvertArgs,
    r: &voltrack::export::gltf::GltfExportReport,
) -> serde_json::Value {
    serde_json::json!({
        "targets": r.targets,
        "components": r.basis,
        "compressed": r.compressed,
        // Frame-to-frame steps, each frame keying every step up to its own
        // (a compressed file with one target per frame).
        "steps": r.steps,
        "normals": args.normals == options::Switch::On,
        "chosen_by": match args.basis {
            Some(BasisArg::Components(_)) => "components",
            Some(BasisArg::PerFrame) => "per-frame",
            _ if args.basis_by_fit() => "fit",
            _ => "length",
        },
        // Percent of the diagonal, as `fit_percent`.
        "reconstruction_error_percent": {
            "max": 100.0 * r.reconstruction_error_max,
            "mean": 100.0 * r.reconstruction_error_mean,
        },
        // The bases the choice by error tried, each as this file would be
        // with it: bytes against error.
        "rate_distortion": r.rate_distortion.iter().map(|row| serde_json::json!({
            "components": row.components,
            "targets": row.targets,
            "bytes": row.bytes,
            "error_percent": {"max": 100.0 * row.error_max, "mean": 100.0 * row.error_mean},
            "chosen": row.chosen,
        })).collect::<Vec<_>>(),
    })
}

/// The summary `convert` prints before the file it wrote: sizes, the
/// reference, the segments, each stage's seconds, the attempts, the fit
/// and the exporter's `notes`.
fn print_summary(
    conv: &pipeline::Conversion,
    seconds: &[(Stage, f64)],
    total: f64,
    notes: &[String],
) {
    let traj = &conv.trajectories;
    println!(
        "{} frames, {} vertices, {} triangles, {} centers{}",
        conv.mesh.frames.len(),
        conv.mesh.base.positions.len(),
        conv.mesh.base.triangles.len(),
        traj.centers,
        conv.refined.as_ref().map_or(String::new(), |r| format!(
            " ({} irregular removed)",
            r.removed.len()
        ))
    );
    let reference = &conv.tracked.reference;
    println!(
        "reference: frame {} ({}), {}",
        reference.frame, conv.sequence.names[reference.frame], reference.why
    );
    if conv.segments.len() > 1 {
        println!(
            "segments (the input's parts merge or part): {}",
            segments_text(&conv.segments)
        );
    }
    for (stage, s) in seconds {
        println!(
            "  {:>9} {:>8.2} s  {:>5.1} %",
            stage.name(),
            s,
            100.0 * s / total.max(1e-9)
        );
    }
    println!("  {:>9} {:>8.2} s", "total", total);
    if conv.attempts.len() > 1 {
        println!("{}", attempts_text(conv));
    }
    let s = conv.fit.summary();
    println!(
        "fit to the input: mean {:.3} %, p95 {:.3} %, max {:.3} % of the diagonal",
        s.mean, s.p95, s.max
    );
    for n in notes {
        println!("{n}");
    }
}

/// The attempts in a line: `seeds tried: 0 (12 frames warned of), 1 (3); kept seed 1`.
pub(crate) fn attempts_text(conv: &pipeline::Conversion) -> String {
    let each = conv
        .attempts
        .iter()
        .map(|a| format!("{} ({} frames warned of)", a.seed, a.warned.len()))
        .collect::<Vec<_>>()
        .join(", ");
    format!(
        "seeds tried: {each}; kept seed {}, warned of the fewest (on evidence of their own first; the first on a tie)",
        conv.seed()
    )
}

/// The segments in a line: `frames 0-17 from 0 (2 parts), …`.
pub(crate) fn segments_text(segments: &[voltrack::deform::segments::Segment]) -> String {
    segments
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The reference frame for `--json`: which, the input it is, what was
/// asked for and why; with `auto`, each frame's parts and tunnels.
fn reference_json(conv: &pipeline::Conversion) -> serde_json::Value {
    let r = &conv.tracked.reference;
    serde_json::json!({
        "frame": r.frame,
        "input": conv.sequence.names[r.frame],
        "asked": r.asked,
        "why": r.why,
        "parts": r.topology.iter().map(|t| t.parts).collect::<Vec<_>>(),
        "tunnels": r.topology.iter().map(|t| t.tunnels).collect::<Vec<_>>(),
    })
}

/// Bytes under `path` (a file, or a directory of files).
fn output_size(path: &Path) -> u64 {
    if path.is_dir() {
        std::fs::read_dir(path)
            .map(|d| {
                d.flatten()
                    .filter_map(|e| e.metadata().ok())
                    .map(|m| m.len())
                    .sum()
            })
            .unwrap_or(0)
    } else {
        std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
    }
}

fn human_size(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 => format!("{:.2} GiB", b as f64 / (1u64 << 30) as f64),
        b if b >= 1 << 20 => format!("{:.1} MiB", b as f64 / (1u64 << 20) as f64),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}
