//! Voxelisation speed: one dancer frame (~40 k triangles, open, 16 loose
//! pieces) on the sequence's grid at R = 256, on one core, and the synthetic
//! fixtures at R = 128. Criterion prints the time per frame.
//!
//! `cargo bench --bench voxelize`; `VOLTRACK_BENCH_DATA=DIR` uses another
//! sequence's first frame.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use voltrack::model::GridSpec;
use voltrack::voxel::{voxelize, VoxelParams};

fn dancer(c: &mut Criterion) {
    let dir = std::env::var("VOLTRACK_BENCH_DATA")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/dancer").into());
    let Ok(paths) = voltrack::io::discover_frames(&[dir.clone().into()]) else {
        eprintln!("voxelize bench: {dir} not found, skipped");
        return;
    };
    let seq = voltrack::voxel::voxelize_sequence(
        &voltrack::io::FrameFiles::new(paths.to_vec()),
        &VoxelParams {
            resolution: 256,
            ..Default::default()
        },
        Default::default(),
    )
    .expect("voxelising the sequence");
    let mesh = voltrack::io::read_mesh(&paths[0]).expect("reading frame 0");
    let one_core = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool");
    let name = format!(
        "dancer frame 0 ({} triangles) R=256, 1 thread",
        mesh.triangles.len()
    );
    c.bench_function(&name, |b| {
        b.iter(|| one_core.install(|| voxelize(black_box(&mesh), &seq.grid)))
    });
}

fn fixtures(c: &mut Criterion) {
    let mut group = c.benchmark_group("fixtures R=128");
    for (name, mesh) in voltrack::fixtures::shapes() {
        let grid = GridSpec::for_bounds(&mesh.bounding_box(), 128).expect("grid");
        group.bench_function(name, |b| b.iter(|| voxelize(black_box(&mesh), &grid)));
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = dancer, fixtures
}
criterion_main!(benches);
