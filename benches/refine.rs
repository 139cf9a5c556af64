//! Speed of the temporally global optimisation on crane_tvm at R = 256,
//! N = 1000: seconds per energy evaluation (all frames' Voronoi cells, rigid
//! fits and predictions) and per accepted global iteration (its line search
//! included), and the peak memory of the whole run.
//!
//! `cargo bench --bench refine`; `VOLTRACK_BENCH_DATA=DIR` for another
//! sequence, `VOLTRACK_BENCH_FRAMES=K` for its first K frames.

use std::time::Instant;
use voltrack::params::{RefineParams, TrackParams};
use voltrack::refine::{evaluate, global_affinity, optimise, SequenceCells};
use voltrack::voxel::{voxelize_sequence, VoxelParams};

#[path = "common/peak.rs"]
mod peak;

fn peak_rss_mib() -> Option<f64> {
    peak::high_water().map(|kb| kb / 1024.0)
}

fn main() {
    let dir = std::env::var("VOLTRACK_BENCH_DATA").unwrap_or_else(|_| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/crane_tvm").into()
    });
    let frames: usize = std::env::var("VOLTRACK_BENCH_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(usize::MAX);
    let Ok(mut paths) = voltrack::io::discover_frames(&[dir.clone().into()]) else {
        println!("refine bench: {dir} not found, skipped");
        return;
    };
    paths.truncate(frames);
    let seq = voxelize_sequence(
        &voltrack::io::FrameFiles::new(paths.to_vec()),
        &VoxelParams {
            resolution: 256,
            ..Default::default()
        },
        Default::default(),
    )
    .expect("voxelising");
    let tracked = voltrack::track::track(
        &seq,
        &TrackParams {
            centers: 1000,
            ..Default::default()
        },
        Default::default(),
    )
    .expect("tracking");
    let traj = tracked.trajectories.clone();
    let params = RefineParams::default();
    let scale = params.length_scale(&seq.bounds);
    let mut cells = SequenceCells::new(&seq, usize::MAX);
    let clock = Instant::now();
    let omega = global_affinity(
        &traj,
        &seq,
        &mut cells,
        params.rho_gp * scale,
        params.rho_gm * scale,
        params.mu,
    );
    let affinity_seconds = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let runs = 3;
    for _ in 0..runs {
        std::hint::black_box(
            evaluate(
                &traj,
                &seq.grid,
                &mut cells,
                &omega,
                params.beta_hat,
                params.memory,
            )
            .expect("gradient in memory"),
        );
    }
    let evaluation = clock.elapsed().as_secs_f64() / runs as f64;
    let mut current = traj.clone();
    let clock = Instant::now();
    let history = optimise(
        &mut current,
        &seq.grid,
        &mut cells,
        &omega,
        &params,
        |_, _, _| true,
    )
    .expect("gradient in memory");
    let optimise_seconds = clock.elapsed().as_secs_f64();
    let accepted = history.len().saturating_sub(1);
    println!(
        "{}: {} frames, {} centers, R = 256, threads {}",
        dir,
        seq.frames.len(),
        traj.centers,
        rayon::current_num_threads()
    );
    println!(
        "global affinity ω: {affinity_seconds:.2} s ({:.1} neighbours per center)",
        omega.mean_neighbors()
    );
    println!(
        "energy evaluation: {evaluation:.3} s ({:.1} ms per frame)",
        1000.0 * evaluation / seq.frames.len() as f64
    );
    println!(
        "optimisation: {accepted} accepted iterations in {optimise_seconds:.2} s = {:.2} s per global iteration (line search included); energy {:.6e} -> {:.6e}",
        optimise_seconds / accepted.max(1) as f64,
        history.first().map_or(0.0, |h| h.energy),
        history.last().map_or(0.0, |h| h.energy)
    );
    if let Some(m) = peak_rss_mib() {
        let voxels: usize = seq.frames.iter().map(|f| f.len()).sum();
        println!("peak memory {m:.0} MiB for {voxels} occupied voxels over all frames ({:.1} bytes per voxel overall)", m * 1048576.0 / voxels as f64);
    }
}
