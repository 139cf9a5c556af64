//! Forward tracking speed on crane_tvm, where the time goes per frame.
//!
//! `cargo bench --bench track` runs the two configurations:
//! R = 256, N = 1000 and the authors' R = 512, N = 2000.
//! `VOLTRACK_BENCH_FRAMES=K` tracks only the first K frames;
//! `VOLTRACK_BENCH_DATA=DIR` tracks another sequence;
//! `VOLTRACK_BENCH_RESOLUTION=256` runs only the configuration at that R;
//! `VOLTRACK_BENCH_SINGLE_GUESS=1` tracks from the paper's constant-velocity
//! guess alone (`--single-guess`), without the damped second run.

use std::time::Instant;
use voltrack::params::TrackParams;
use voltrack::voxel::{voxelize_sequence, VoxelParams};

fn main() {
    let dir = std::env::var("VOLTRACK_BENCH_DATA").unwrap_or_else(|_| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/crane_tvm").into()
    });
    let frames: usize = std::env::var("VOLTRACK_BENCH_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(usize::MAX);
    let mut paths = match voltrack::io::discover_frames(&[dir.clone().into()]) {
        Ok(p) => p,
        Err(e) => {
            println!("track bench skipped: {e}");
            return;
        }
    };
    paths.truncate(frames);
    let only: Option<usize> = std::env::var("VOLTRACK_BENCH_RESOLUTION")
        .ok()
        .and_then(|s| s.parse().ok());
    let single = std::env::var_os("VOLTRACK_BENCH_SINGLE_GUESS").is_some();
    let params = TrackParams {
        damped_guess: if single {
            None
        } else {
            TrackParams::default().damped_guess
        },
        ..Default::default()
    };
    println!(
        "threads: {}; {}",
        rayon::current_num_threads(),
        if single {
            "single guess"
        } else {
            "constant-velocity and damped guesses (default)"
        }
    );
    for (r, n) in [(256, 1000), (512, 2000)]
        .into_iter()
        .filter(|&(r, _)| only.is_none_or(|o| o == r))
    {
        let clock = Instant::now();
        let seq = voxelize_sequence(
            &voltrack::io::FrameFiles::new(paths.to_vec()),
            &VoxelParams {
                resolution: r,
                ..Default::default()
            },
            Default::default(),
        )
        .expect("voxelising");
        let read_voxelize = clock.elapsed().as_secs_f64();
        let occupied: usize = seq.frames.iter().map(|f| f.len()).sum::<usize>() / seq.frames.len();
        let res = voltrack::track::track(
            &seq,
            &TrackParams {
                centers: n,
                ..params.clone()
            },
            Default::default(),
        )
        .expect("tracking");
        let tracked = &res.timings[1..];
        let k = tracked.len() as f64;
        let mean =
            |f: fn(&voltrack::track::FrameTiming) -> f64| tracked.iter().map(f).sum::<f64>() / k;
        println!(
            "crane_tvm R={r} N={n}: {} frames, {occupied} occupied voxels/frame; read+voxelise {:.2} s ({:.1} ms/frame); frame 0 (Lloyd) {:.2} s",
            seq.frames.len(),
            read_voxelize,
            1000.0 * seq.voxelize_seconds / seq.frames.len() as f64,
            res.timings[0].total
        );
        // With several guesses the parts add up all runs, which overlap in time.
        println!(
            "  tracking {:.3} s/frame: assign {:.3}, fit {:.3}, affinity {:.3}{}; {:.1} iterations/frame ({:.1} more dropped); a guess other than the paper's kept in {} of {} frames",
            mean(|t| t.total),
            mean(|t| t.assign),
            mean(|t| t.fit),
            mean(|t| t.affinity),
            if single { format!(", other {:.3}", mean(|t| t.total - t.assign - t.fit - t.affinity)) } else { " (all runs)".into() },
            mean(|t| t.iterations as f64),
            mean(|t| t.dropped_iterations as f64),
            tracked.iter().filter(|t| t.kept_guess != voltrack::track::Guess::ConstantVelocity).count(),
            tracked.len()
        );
    }
}
