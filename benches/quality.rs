//! Quality tables on the shared captures (issues 3 and 4): PCAC and DFU of
//! forward tracking with the max against the IIR affinity (cf. the paper's
//! Table 1), then irregular-center removal with and without the global
//! optimisation (cf. Table 2).
//!
//! `cargo bench --bench quality` runs walker, crane_tvm and collision at
//! R = 256, N = 1000, seed 0. `VOLTRACK_BENCH_SEQUENCES=walker,crane_tvm`
//! picks sequences, `VOLTRACK_BENCH_CENTERS`, `VOLTRACK_BENCH_R` and
//! `VOLTRACK_BENCH_FRAMES` change the configuration.

use std::time::Instant;
use voltrack::metrics::Quality;
use voltrack::params::{AffinityKind, RefineParams, TrackParams};
use voltrack::pipeline::measure;
use voltrack::voxel::{voxelize_sequence, VoxelParams};

fn env(key: &str, default: usize) -> usize {
    std::env::var(key)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn top(q: &Quality, k: usize) -> String {
    q.largest_irregularity(k)
        .iter()
        .map(|x| format!("{x:.3e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn main() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data");
    let names = std::env::var("VOLTRACK_BENCH_SEQUENCES")
        .unwrap_or_else(|_| "walker,crane_tvm,collision".into());
    let (r, n, frames) = (
        env("VOLTRACK_BENCH_R", 256),
        env("VOLTRACK_BENCH_CENTERS", 1000),
        env("VOLTRACK_BENCH_FRAMES", usize::MAX),
    );
    println!(
        "R = {r}, N = {n}, seed 0, threads {}",
        rayon::current_num_threads()
    );
    let mut table1 = vec![
        "| sequence | frames | PCAC max | PCAC iir | DFU max | DFU iir | track s/frame max | iir |"
            .to_string(),
        "|---|---|---|---|---|---|---|---|".into(),
    ];
    let mut table2 = vec!["| sequence | variant | centers | PCAC | DFU | largest I_i (top 5 of 20) | refine s | global iterations |".to_string(), "|---|---|---|---|---|---|---|---|".into()];
    let mut irregular = Vec::new();
    for name in names.split(',') {
        let Ok(mut paths) = voltrack::io::discover_frames(&[format!("{data}/{name}").into()])
        else {
            println!("{name}: not found, skipped");
            continue;
        };
        paths.truncate(frames);
        let seq = voxelize_sequence(
            &voltrack::io::FrameFiles::new(paths.to_vec()),
            &VoxelParams {
                resolution: r,
                ..Default::default()
            },
            Default::default(),
        )
        .expect("voxelising");
        let mut results = Vec::new();
        for affinity in [AffinityKind::Max, AffinityKind::Iir] {
            let params = TrackParams {
                centers: n,
                affinity,
                ..Default::default()
            };
            let clock = Instant::now();
            let tracked =
                voltrack::track::track(&seq, &params, Default::default()).expect("tracking");
            let per_frame = clock.elapsed().as_secs_f64() / seq.frames.len() as f64;
            results.push((tracked, per_frame));
        }
        let forward =
            |r: &voltrack::track::TrackResult| Quality::of(&r.trajectories, &r.cell_counts);
        let (qm, qi) = (forward(&results[0].0), forward(&results[1].0));
        table1.push(format!(
            "| {name} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {:.2} |",
            seq.frames.len(),
            qm.pcac,
            qi.pcac,
            qm.dfu,
            qi.dfu,
            results[0].1,
            results[1].1
        ));
        println!("{}", table1.last().unwrap());

        let forward = &results[0].0.trajectories;
        let row = |variant: &str, q: &Quality, centers: usize, seconds: f64, iterations: String| {
            format!("| {name} | {variant} | {centers} | {:.3} | {:.4} | {} | {seconds:.1} | {iterations} |", q.pcac, q.dfu, top(q, 5))
        };
        table2.push(row("forward only", &qm, forward.centers, 0.0, "-".into()));
        irregular.push(format!("{name} forward only: {}", top(&qm, 20)));
        println!("{}", table2.last().unwrap());
        let variants = [
            ("removal only (20)", 20, 1, false),
            ("n_rem 20, n_go 1", 20, 1, true),
            ("n_rem 4, n_go 5", 20, 5, true),
            ("n_rem 1, n_go 20", 20, 20, true),
        ];
        for (variant, remove, batches, optimise) in variants {
            let params = RefineParams {
                remove: Some(remove),
                batches,
                optimise,
                ..Default::default()
            };
            let refined =
                voltrack::refine::refine(forward.clone(), &seq, &params, Default::default())
                    .expect("refining");
            let q = measure(&refined.trajectories, &seq);
            let iterations: Vec<String> = refined
                .refinement
                .batches
                .iter()
                .map(|b| (b.len().saturating_sub(1)).to_string())
                .collect();
            let iterations = if iterations.is_empty() {
                "-".into()
            } else {
                iterations.join("+")
            };
            table2.push(row(
                variant,
                &q,
                refined.trajectories.centers,
                refined.refinement.seconds,
                iterations,
            ));
            irregular.push(format!("{name} {variant}: {}", top(&q, 20)));
            println!("{}", table2.last().unwrap());
        }
    }
    println!(
        "\nForward tracking, max against IIR affinity:\n{}",
        table1.join("\n")
    );
    println!(
        "\nIrregular-center removal and global optimisation:\n{}",
        table2.join("\n")
    );
    println!("\nLargest 20 I_i:\n{}", irregular.join("\n"));
}
