//! Irregular-center removal through the public stage. The removal's and
//! the global optimisation's parts are unit tests (`src/refine/tests.rs`).

use voltrack::math::{Point3, Real, Rotation3, Vector3};
use voltrack::model::{Rigid, Trajectories};
use voltrack::params::{RefineParams, TrackParams};
use voltrack::refine::refine;
use voltrack::track::track;
use voltrack::voxel::VoxelSequence;

mod common;

/// Two boxes, one still and one sliding away, voxelised on one grid.
fn two_bodies(frames: usize, resolution: usize) -> VoxelSequence {
    let a = voltrack::fixtures::cube(Point3::new(0.0, 0.0, 0.0), 1.0);
    let b = voltrack::fixtures::cube(Point3::new(1.6, 0.0, 0.0), 1.0);
    let meshes: Vec<voltrack::TriangleMesh> = (0..frames)
        .map(|f| {
            let m = Rigid {
                rotation: *Rotation3::new(Vector3::new(0.0, 0.0, 0.05 * f as Real)).matrix(),
                translation: Vector3::new(0.08 * f as Real, 0.0, 0.0),
            };
            let mut moved = b.clone();
            moved.positions.iter_mut().for_each(|p| *p = m.apply(p));
            voltrack::fixtures::merge(&[a.clone(), moved])
        })
        .collect();
    common::voxel_sequence(&meshes, resolution)
}

/// `centers` centers tracked through `seq` at the defaults otherwise.
fn tracked(seq: &VoxelSequence, centers: usize) -> Trajectories {
    track(
        seq,
        &TrackParams {
            centers,
            ..Default::default()
        },
        Default::default(),
    )
    .unwrap()
    .trajectories
}

#[test]
fn removal_spreads_over_batches() {
    let seq = two_bodies(4, 32);
    let tracked = tracked(&seq, 30);
    let res = refine(
        tracked.clone(),
        &seq,
        &RefineParams {
            remove: Some(7),
            batches: 3,
            optimise: false,
            ..Default::default()
        },
        Default::default(),
    )
    .unwrap();
    let (refined, res) = (res.trajectories, res.refinement);
    assert_eq!(res.removed.len(), 7);
    let mut sorted = res.removed.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), 7, "each removed once");
    assert_eq!(res.kept.len(), 23);
    // Removal alone leaves the remaining trajectories untouched.
    for (k, &orig) in res.kept.iter().enumerate() {
        for f in 0..refined.frames {
            assert_eq!(refined.get(f, k), tracked.get(f, orig));
        }
    }
}
