//! The same input and seed give byte-identical GLB and EXR output whatever
//! the number of threads (the whole pipeline, on the bending-bar fixture,
//! with the guesses screened on voxels and on blocks), and so does the check
//! for lost parts; a take with broken frames fails naming the first of them.

mod common;
use common::Scratch;
use std::path::Path;
use voltrack::params::{DeformParams, RefineParams, TrackParams};
use voltrack::voxel::VoxelParams;

fn convert_bytes(
    threads: usize,
    screening_block: usize,
    dir: &Scratch,
) -> (Vec<u8>, Vec<u8>, voltrack::metrics::Coverage) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar");
        let voxel = VoxelParams {
            resolution: 48,
            ..Default::default()
        };
        let track = TrackParams {
            centers: 120,
            seed: 7,
            screening_block,
            ..Default::default()
        };
        let conv = voltrack::pipeline::convert(
            &voltrack::io::FrameFiles::discover(&[input]).unwrap(),
            &voltrack::pipeline::ConvertOptions {
                voxel: voxel.clone(),
                track: track.clone(),
                refine: Some(RefineParams::default()),
                deform: DeformParams::default(),
                conform: Default::default(),
                checkpoint: None,
                ..Default::default()
            },
            Default::default(),
        )
        .unwrap();
        let glb = dir.join(&format!("bar{threads}.glb"));
        let exr = dir.join(&format!("bar{threads}.exr"));
        voltrack::export::gltf::write_dynamic_glb(
            &glb,
            &conv.mesh,
            &Default::default(),
            Default::default(),
        )
        .unwrap();
        let refined = conv.refined.as_ref().unwrap();
        let meta = voltrack::pipeline::trajectory_metadata(
            &conv.sequence,
            &conv.trajectories,
            &voxel,
            &track,
            Some((&RefineParams::default(), &refined.removed)),
        );
        voltrack::export::exr::write_trajectories_exr(&exr, &conv.trajectories, &meta).unwrap();
        (
            std::fs::read(glb).unwrap(),
            std::fs::read(exr).unwrap(),
            conv.coverage,
        )
    })
}

#[test]
fn outputs_do_not_depend_on_the_thread_count() {
    let dir = Scratch::new("determinism", "threads");
    for block in [1, 2] {
        let one = convert_bytes(1, block, &dir);
        let many = convert_bytes(3, block, &dir);
        assert!(
            one.0 == many.0,
            "screening block {block}: GLB differs between 1 and 3 threads"
        );
        assert!(
            one.1 == many.1,
            "screening block {block}: EXR differs between 1 and 3 threads"
        );
        assert_eq!(
            one.2, many.2,
            "screening block {block}: the coverage check differs between 1 and 3 threads"
        );
    }
}

/// Frames are read in parallel; where several are broken, the error names
/// the first of them whatever the number of threads and whichever thread
/// fails first.
#[test]
fn the_first_broken_frame_is_the_one_named() {
    let dir = Scratch::new("determinism", "broken-frames");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar");
    let take = dir.join("take");
    std::fs::create_dir_all(&take).unwrap();
    for f in 0..8 {
        let name = format!("frame_{f}.obj");
        let text = match f {
            // Broken two ways: a vertex of two coordinates, a face past the vertices.
            2 => "v 0 0\n".to_string(),
            5 | 6 => "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n".to_string(),
            _ => std::fs::read_to_string(input.join(&name)).unwrap(),
        };
        std::fs::write(take.join(&name), text).unwrap();
    }
    let files = voltrack::io::FrameFiles::discover(&[take]).unwrap();
    let voxel = VoxelParams {
        resolution: 24,
        ..Default::default()
    };
    for threads in [1, 2, 3, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for _ in 0..5 {
            let error = pool
                .install(|| {
                    voltrack::voxel::voxelize_sequence(&files, &voxel, voltrack::Progress::none())
                })
                .expect_err("broken frames")
                .to_string();
            assert!(error.contains("frame_2.obj"), "{threads} threads: {error}");
        }
    }
}
