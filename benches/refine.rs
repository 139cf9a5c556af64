//! Speed of the refinement stage on crane_tvm at R = 256, N = 1000, through
//! the public stage functions: the global affinity ω of the tracked
//! trajectories (`pipeline::sequence_affinity`), and the temporally global
//! optimisation as `refine::refine` runs it with no center removed, in one
//! batch (ω again, then the global iterations at the defaults, each with its
//! line search): seconds per accepted global iteration; and the peak memory
//! of the whole run.
//!
//! `cargo bench --bench refine`; `VOLTRACK_BENCH_DATA=DIR` for another
//! sequence, `VOLTRACK_BENCH_FRAMES=K` for its first K frames.

use std::time::Instant;
use voltrack::params::{RefineParams, TrackParams};
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
    let traj = tracked.trajectories;
    let params = RefineParams::default();
    let clock = Instant::now();
    let omega =
        voltrack::pipeline::sequence_affinity(&traj, &seq, Some(&params), Default::default())
            .expect("the global affinity");
    let affinity_seconds = clock.elapsed().as_secs_f64();
    let centers = traj.centers;
    let clock = Instant::now();
    let refined = voltrack::refine::refine(
        traj,
        &seq,
        &RefineParams {
            remove: Some(0),
            batches: 1,
            ..params
        },
        Default::default(),
    )
    .expect("refining");
    let optimise_seconds = clock.elapsed().as_secs_f64();
    let history = &refined.refinement.batches[0];
    let accepted = history.len().saturating_sub(1);
    println!(
        "{}: {} frames, {} centers, R = 256, threads {}",
        dir,
        seq.frames.len(),
        centers,
        rayon::current_num_threads()
    );
    println!(
        "global affinity ω: {affinity_seconds:.2} s ({:.1} neighbours per center)",
        omega.mean_neighbors()
    );
    println!(
        "optimisation (refine, no removal, one batch): {optimise_seconds:.2} s, ω included; {accepted} accepted iterations = {:.2} s per global iteration (line search included, ω's {affinity_seconds:.2} s taken out); energy {:.6e} -> {:.6e}",
        (optimise_seconds - affinity_seconds).max(0.0) / accepted.max(1) as f64,
        history.first().map_or(0.0, |h| h.energy),
        history.last().map_or(0.0, |h| h.energy)
    );
    if let Some(m) = peak_rss_mib() {
        let voxels: usize = seq.frames.iter().map(|f| f.len()).sum();
        println!("peak memory {m:.0} MiB for {voxels} occupied voxels over all frames ({:.1} bytes per voxel overall)", m * 1048576.0 / voxels as f64);
    }
}
