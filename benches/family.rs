//! Converts every take of the generated family
//! (`voltrack::fixtures::family`) at the defaults and prints, per take, the
//! correspondence error against the ground truth (mean, 95th percentile and
//! maximum, in percent of the diagonal), its drift (the last tenth's mean
//! over the first tenth's), the frames where a part is truly lost (a part's
//! mean error above 5 %), the frames `convert` warns of, and the seconds;
//! then how many takes are within the bounds.
//!
//! `cargo bench --bench family`. Environment:
//! - `VOLTRACK_FAMILY`: `all` (default), `dev` (the takes tuning may look
//!   at), `held-out` (the others), or names (prefixes), comma-separated;
//! - `VOLTRACK_SEED`: the conversion's seed (`--seed`), default 0;
//!   `VOLTRACK_ATTEMPTS`: `--attempts`, default 2 (a row ends with the seeds
//!   tried when there were more than one);
//! - `VOLTRACK_RESOLUTION`, `VOLTRACK_CENTERS`, `VOLTRACK_CONFORM_ITERATIONS`:
//!   other than the defaults; `VOLTRACK_FRAMES`: each take cut to its first
//!   frames; `VOLTRACK_RECLAIM=0` (`--reclaim off`),
//!   `VOLTRACK_ABSOLUTE_IRREGULARITY=1` (`--absolute-irregularity`);
//!   `VOLTRACK_THRESHOLD`, `VOLTRACK_CONVERGENCE_WINDOW` (`--threshold`,
//!   `--convergence-window`);
//!   `VOLTRACK_REFERENCE`: `first`, `middle` (each take's middle frame),
//!   `auto-middle` (of the frames `auto` would choose among, the one
//!   nearest the middle) or a frame number (`--reference`; default `auto`);
//! - `VOLTRACK_FAMILY_JSON=FILE`: also write every take's figures as JSON
//!   lines (per-frame errors included), for tables before and after a change.

use std::io::Write;
use std::time::Instant;
use voltrack::deform::segments::most_separate_near_middle;
use voltrack::fixtures::family::{build, family, score_stretches, stretches, TakeSpec};
use voltrack::metrics::coverage::runs;
use voltrack::params::Reference;
use voltrack::pipeline::{convert, ConvertOptions};

/// A take is within bounds when its correspondence maximum is at most this.
const MAX_BOUND: f64 = 8.0;
/// A take of at least this many frames must drift at most [`DRIFT_BOUND`].
const LONG_TAKE: usize = 100;
const DRIFT_BOUND: f64 = 2.0;
/// Distances (percent of the diagonal) the JSON's far regions are measured at.
const FAR_PROFILE: [f64; 5] = [1.0, 1.5, 2.0, 3.0, 5.0];

fn chosen(spec: &TakeSpec, which: &str) -> bool {
    match which {
        "all" => true,
        "dev" => !spec.held_out,
        "held-out" => spec.held_out,
        names => names
            .split(',')
            .any(|n| !n.is_empty() && spec.name.starts_with(n.trim())),
    }
}

fn frames_text(frames: &[usize]) -> String {
    if frames.is_empty() {
        return "-".into();
    }
    runs(frames)
        .iter()
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}-{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(",")
}

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().map(|v| {
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v} is not a number"))
    })
}

fn main() {
    let which = std::env::var("VOLTRACK_FAMILY").unwrap_or_else(|_| "all".into());
    let mut options = ConvertOptions::default();
    let defaults = options.track.clone();
    options.track.seed = env("VOLTRACK_SEED").unwrap_or(0);
    if let Some(a) = env("VOLTRACK_ATTEMPTS") {
        options.attempts = a;
    }
    if let Some(r) = env("VOLTRACK_RESOLUTION") {
        options.voxel.resolution = r;
    }
    if let Some(n) = env("VOLTRACK_CENTERS") {
        options.track.centers = n;
    }
    if let Some(n) = env("VOLTRACK_CONFORM_ITERATIONS") {
        options.conform.iterations = n;
    }
    if env::<u8>("VOLTRACK_RECLAIM") == Some(0) {
        options.track.reclaim = false;
    }
    if let Some(t) = env("VOLTRACK_THRESHOLD") {
        options.track.threshold = t;
    }
    if let Some(w) = env("VOLTRACK_CONVERGENCE_WINDOW") {
        options.track.convergence_window = w;
    }
    if env::<u8>("VOLTRACK_ABSOLUTE_IRREGULARITY") == Some(1) {
        options
            .refine
            .as_mut()
            .expect("refinement at the defaults")
            .relative_irregularity = false;
    }
    let mut json = std::env::var("VOLTRACK_FAMILY_JSON")
        .ok()
        .map(|p| std::fs::File::create(p).expect("creating the JSON file"));
    println!(
        "family at resolution {}, {} centers, seed {}, attempts {}, threads {}{}{}{}",
        options.voxel.resolution,
        options.track.centers,
        options.track.seed,
        options.attempts,
        rayon::current_num_threads(),
        if options.track.reclaim {
            ""
        } else {
            ", no reclaiming"
        },
        if options
            .refine
            .as_ref()
            .is_some_and(|r| !r.relative_irregularity)
        {
            ", absolute irregularity"
        } else {
            ""
        },
        if (options.track.threshold, options.track.convergence_window)
            == (defaults.threshold, defaults.convergence_window)
        {
            String::new()
        } else {
            format!(
                ", threshold {:e}, convergence window {}",
                options.track.threshold, options.track.convergence_window
            )
        }
    );
    println!(
        "{:<18} {:>4} {:>5} {:>5} {:>6} {:>6} {:>6} {:>6}  {:<18} {:<18} {:>7}",
        "take", "fr", "limb", "fast%", "mean", "p95", "max", "drift", "lost", "warned", "s"
    );
    let mut rows = Vec::new();
    let cut: Option<usize> = env("VOLTRACK_FRAMES");
    for spec in family().into_iter().filter(|s| chosen(s, &which)) {
        let spec = TakeSpec {
            frames: cut.map_or(spec.frames, |c| c.min(spec.frames)),
            ..spec
        };
        let take = build(&spec);
        let mut options = options.clone();
        options.track.reference = match std::env::var("VOLTRACK_REFERENCE").as_deref() {
            Ok("first") => Reference::First,
            Ok("middle") => Reference::Frame(spec.frames / 2),
            // The most separate frame nearest the middle (a candidate rule).
            Ok("auto-middle") => {
                let seq = voltrack::voxel::voxelize_sequence(
                    &take.meshes,
                    &options.voxel,
                    Default::default(),
                )
                .expect("voxelising");
                let topology = voltrack::track::frame_topologies(&seq, options.track.centers);
                Reference::Frame(most_separate_near_middle(&topology, 0..topology.len()))
            }
            Ok(k) => Reference::Frame(
                k.parse()
                    .expect("VOLTRACK_REFERENCE: first, middle or a frame"),
            ),
            Err(_) => Reference::Auto,
        };
        let clock = Instant::now();
        let conv = convert(&take.meshes, &options, Default::default()).expect("converting");
        let seconds = clock.elapsed().as_secs_f64();
        let warned = conv.lost_parts().flagged;
        let result = conv.mesh.frames.to_vec().expect("reading the result");
        let s = score_stretches(
            &stretches(&conv.segments, &take.meshes, |r| take.truth_from(r)),
            take.diagonal,
            &result,
        );
        let missed: Vec<usize> = s
            .lost
            .iter()
            .copied()
            .filter(|f| !warned.contains(f))
            .collect();
        println!(
            "{:<18} {:>4} {:>5.1} {:>5.1} {:>6.3} {:>6.3} {:>6.2} {:>6.2}  {:<18} {:<18} {:>7.1}{}",
            spec.name,
            spec.frames,
            take.limb_voxels,
            take.fastest_percent,
            s.mean,
            s.p95,
            s.max,
            s.drift,
            frames_text(&s.lost),
            frames_text(&warned),
            seconds,
            if missed.is_empty() {
                String::new()
            } else {
                format!("  missed {}", frames_text(&missed))
            } + &match conv.mesh.reference {
                0 => String::new(),
                r => format!("  reference {r}"),
            } + &if conv.attempts.len() > 1 {
                let tried: Vec<String> = conv
                    .attempts
                    .iter()
                    .map(|a| format!("{} ({} warned)", a.seed, a.warned.len()))
                    .collect();
                format!(
                    "  seeds {}, kept {}",
                    tried.join(", "),
                    conv.attempts[conv.kept].seed
                )
            } else {
                String::new()
            }
        );
        std::io::stdout().flush().ok();
        if let Some(out) = json.as_mut() {
            // Far regions at several distances, both ways, per frame: for
            // choosing the warning's threshold.
            let profile: Vec<Vec<[f64; 4]>> = result
                .iter()
                .zip(&take.meshes)
                .enumerate()
                .map(|(f, (positions, input))| {
                    let surface = voltrack::metrics::Surface {
                        positions,
                        triangles: &conv.mesh.base.triangles,
                    };
                    let inside = voltrack::metrics::fit::inside_volume(&conv.sequence, f);
                    voltrack::metrics::fit::far_profile(
                        surface,
                        input.into(),
                        conv.sequence.bounds.diagonal(),
                        &FAR_PROFILE,
                        Some(&inside),
                    )
                    .iter()
                    .map(|(i, r)| [i.share, i.farthest, r.share, r.farthest])
                    .collect()
                })
                .collect();
            let line = serde_json::json!({
                "take": spec.name, "held_out": spec.held_out, "frames": spec.frames, "limb_voxels": take.limb_voxels,
                "fastest_percent": take.fastest_percent, "seed": options.track.seed, "resolution": options.voxel.resolution,
                "centers": options.track.centers, "mean": s.mean, "p95": s.p95, "max": s.max, "drift": s.drift,
                "lost": s.lost, "warned": warned, "missed": missed, "seconds": seconds, "reference": conv.mesh.reference,
                "per_frame_mean": s.per_frame_mean, "worst_part": s.worst_part,
                "far_thresholds": FAR_PROFILE, "far_profile": profile,
                "coverage": conv.coverage.frames.iter().map(|c| c.lost_share).collect::<Vec<_>>(),
                "fit_p95": conv.fit_outliers.p95, "attempts": conv.attempts, "kept": conv.kept,
            });
            writeln!(out, "{line}").expect("writing the JSON file");
        }
        rows.push((spec, s, missed, seconds));
    }
    if rows.is_empty() {
        println!("no take matches VOLTRACK_FAMILY={which}");
        return;
    }
    let within = rows.iter().filter(|r| r.1.max <= MAX_BOUND).count();
    let mut means: Vec<f64> = rows.iter().map(|r| r.1.mean).collect();
    means.sort_by(f64::total_cmp);
    let median = if means.len() % 2 == 1 {
        means[means.len() / 2]
    } else {
        0.5 * (means[means.len() / 2 - 1] + means[means.len() / 2])
    };
    let long: Vec<_> = rows.iter().filter(|r| r.0.frames >= LONG_TAKE).collect();
    let drifting: Vec<&str> = long
        .iter()
        .filter(|r| r.1.drift > DRIFT_BOUND)
        .map(|r| r.0.name)
        .collect();
    let lost: usize = rows.iter().map(|r| r.1.lost.len()).sum();
    let missed: usize = rows.iter().map(|r| r.2.len()).sum();
    let seconds: f64 = rows.iter().map(|r| r.3).sum();
    println!(
        "{} takes: {within} with max <= {MAX_BOUND} %; median mean {median:.3} %; {} of {} takes of {LONG_TAKE}+ frames drift <= {DRIFT_BOUND}{}; \
         {lost} frames lost, {} warned of ({missed} missed); {seconds:.0} s",
        rows.len(),
        long.len() - drifting.len(),
        long.len(),
        if drifting.is_empty() { String::new() } else { format!(" (not {})", drifting.join(", ")) },
        lost - missed,
    );
}
