//! Time of the compact morph basis (issue 22): `Auto` and `Components(16)` on
//! a synthetic deforming torus of 5,000 vertices at 250 to 2,000 frames,
//! seconds per frame count. The cost should grow about linearly in F; so
//! should `Components(F)`'s, a K far above the motion's rank.
//! Then `Auto` on the same motion with noise no small basis fits (it falls
//! back to per-frame targets): seconds, and the peak memory the call adds
//! (Linux), which should not grow with F.
//!
//! `cargo bench --bench basis`; `VOLTRACK_BENCH_FRAMES=250,500` picks the
//! frame counts, `VOLTRACK_BENCH_IN_FILE=1` keeps the frames in a temporary
//! file (as a long sequence's are).

#[path = "common/peak.rs"]
mod peak;

use std::time::Instant;
use voltrack::export::basis::{choose, BasisChoice};
use voltrack::fixtures;
use voltrack::math::{Point3, Real, Rotation3, Vector3};
use voltrack::model::PositionFrames;

/// A turn, two travelling waves, a bend and a slowly chirping ripple: smooth
/// motion of moderate rank whose spectrum decays, like a tracked capture's.
fn motion(f: usize, p: &Point3) -> Point3 {
    let t = f as Real;
    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.6 * (0.013 * t).sin());
    let wave = 0.05 * (3.0 * p.x - 0.11 * t).sin() + 0.03 * (5.0 * p.y + 0.07 * t).cos();
    let bend = 0.1 * (0.021 * t).sin() * p.x * p.x;
    let ripple = 0.004 * (p.y * (1.0 + 0.002 * t) * 4.0 + 0.05 * t).sin();
    turn * p + Vector3::new(ripple, 0.0, wave + bend)
}

fn main() {
    let counts: Vec<usize> = std::env::var("VOLTRACK_BENCH_FRAMES")
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![250, 500, 1000, 2000]);
    // VOLTRACK_BENCH_IN_FILE=1 keeps the frames in a temporary file, as a
    // long sequence's are (`DeformParams::memory`).
    let in_file = std::env::var("VOLTRACK_BENCH_IN_FILE").is_ok_and(|v| v == "1");
    let base = fixtures::torus(Point3::origin(), 1.0, 0.3, 100, 50);
    println!(
        "{} vertices, threads {}, frames {}",
        base.positions.len(),
        rayon::current_num_threads(),
        if in_file { "in a file" } else { "in memory" }
    );
    println!(
        "| frames | Auto s | Auto components | Components(16) s | s per 1000 frames (Auto, 16) | Components(F) s | its components |"
    );
    println!("|---|---|---|---|---|---|---|");
    let positions = |f: usize, noise: Real| {
        let mut frames = PositionFrames::new(
            base.positions.len(),
            f,
            if in_file { 0 } else { usize::MAX },
        )
        .expect("a temporary file");
        let mut state = 0x5eed_u64;
        for g in 0..f {
            let mut jitter = || {
                // A linear congruential step: noise of no structure, reproducible.
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                noise * ((state >> 11) as Real / (1u64 << 53) as Real - 0.5)
            };
            frames
                .push(
                    base.positions
                        .iter()
                        .map(|p| motion(g, p) + Vector3::new(jitter(), jitter(), jitter()))
                        .collect(),
                )
                .expect("written");
        }
        frames
    };
    for &f in &counts {
        let frames = positions(f, 0.0);
        let tolerance = 0.001 * frames.bounds().expect("read").diagonal();
        let clock = Instant::now();
        let (auto, _) =
            choose(&frames, BasisChoice::Auto, tolerance, Default::default()).expect("Auto basis");
        let auto_s = clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        choose(
            &frames,
            BasisChoice::Components(16),
            tolerance,
            Default::default(),
        )
        .expect("16 components");
        let k16_s = clock.elapsed().as_secs_f64();
        // `--basis F`: a K far above the motion's rank (issue 49, item 13).
        let clock = Instant::now();
        let (all, _) = choose(
            &frames,
            BasisChoice::Components(f),
            tolerance,
            Default::default(),
        )
        .expect("F components");
        let all_s = clock.elapsed().as_secs_f64();
        println!(
            "| {f} | {auto_s:.2} | {} | {k16_s:.2} | {:.2}, {:.2} | {all_s:.2} | {} |",
            auto.components
                .map_or("per frame".into(), |k| k.to_string()),
            1000.0 * auto_s / f as f64,
            1000.0 * k16_s / f as f64,
            all.components.map_or("per frame".into(), |k| k.to_string()),
        );
    }
    println!();
    println!(
        "With noise of 1 % of the torus' radius on every coordinate, which no small basis fits:"
    );
    println!("| frames | Auto s | Auto components | peak memory added, MB |");
    println!("|---|---|---|---|");
    for &f in &counts {
        let frames = positions(f, 0.01);
        let tolerance = 0.001 * frames.bounds().expect("read").diagonal();
        let before = peak::reset();
        let clock = Instant::now();
        let (auto, _) =
            choose(&frames, BasisChoice::Auto, tolerance, Default::default()).expect("Auto basis");
        let auto_s = clock.elapsed().as_secs_f64();
        let added = before
            .zip(peak::high_water())
            .map_or("n/a".into(), |(a, b)| format!("{:.1}", (b - a) / 1e3));
        println!(
            "| {f} | {auto_s:.2} | {} | {added} |",
            auto.components
                .map_or("per frame".into(), |k| k.to_string())
        );
    }
}
