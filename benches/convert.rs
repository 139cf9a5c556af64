//! End-to-end `convert` at default settings on crane_tvm, time per stage:
//! read, voxelise, track, refine, deform, export (GLB). The target:
//! deform + export at most 10 % of the total.
//!
//! `cargo bench --bench convert`; `VOLTRACK_BENCH_DATA=DIR` for another
//! sequence.

use std::time::Instant;
use voltrack::export::gltf::{write_dynamic_glb, GltfExportOptions};
use voltrack::params::{DeformParams, RefineParams, TrackParams};
use voltrack::voxel::VoxelParams;

fn main() {
    let dir = std::env::var("VOLTRACK_BENCH_DATA").unwrap_or_else(|_| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/crane_tvm").into()
    });
    if !std::path::Path::new(&dir).is_dir() {
        println!("convert bench: {dir} not found, skipped");
        return;
    }
    let clock = Instant::now();
    let conv = voltrack::pipeline::convert(
        &voltrack::io::FrameFiles::discover(&[dir.clone().into()]).unwrap(),
        &voltrack::pipeline::ConvertOptions {
            voxel: VoxelParams::default(),
            track: TrackParams::default(),
            refine: Some(RefineParams::default()),
            deform: DeformParams::default(),
            conform: Default::default(),
            checkpoint: None,
            ..Default::default()
        },
        Default::default(),
    )
    .expect("converting");
    let export = Instant::now();
    let out = std::env::temp_dir().join(format!("voltrack-bench-{}.glb", std::process::id()));
    let report = write_dynamic_glb(
        &out,
        &conv.mesh,
        &GltfExportOptions::default(),
        Default::default(),
    )
    .expect("exporting");
    let export_seconds = export.elapsed().as_secs_f64();
    let wall = clock.elapsed().as_secs_f64();
    let _ = std::fs::remove_file(&out);
    let mut stages = conv.seconds.clone();
    stages.push((voltrack::Stage::Export, export_seconds));
    let total: f64 = stages.iter().map(|s| s.1).sum();
    println!(
        "{dir}: {} frames, {} vertices, {} centers, threads {}",
        conv.mesh.frames.len(),
        conv.mesh.base.positions.len(),
        conv.trajectories.centers,
        rayon::current_num_threads()
    );
    for (stage, s) in &stages {
        println!(
            "{:>10} {s:>8.2} s {:>6.1} %",
            stage.name(),
            100.0 * s / total
        );
    }
    let share = |of: &[voltrack::Stage]| {
        100.0
            * stages
                .iter()
                .filter(|(s, _)| of.contains(s))
                .map(|s| s.1)
                .sum::<f64>()
            / total
    };
    use voltrack::Stage::{Conform, Deform, Export};
    println!(
        "{:>10} {total:>8.2} s (wall {wall:.2} s); deform + export {:.1} % of the total, with conform {:.1} %; GLB {:.1} MiB, {} targets",
        "total",
        share(&[Deform, Export]),
        share(&[Deform, Conform, Export]),
        report.bytes as f64 / 1048576.0,
        report.targets
    );
}
