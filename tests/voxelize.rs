//! Voxelisation over the committed fixture suite: formats agree, volumes are
//! right, and the fast classifier matches a brute-force winding number.

use std::path::{Path, PathBuf};
use voltrack::io::read_mesh;
use voltrack::model::GridSpec;
use voltrack::voxel::{voxelize, winding_number};
use voltrack::{fixtures, Aabb};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

fn grid_for(mesh: &voltrack::TriangleMesh, r: usize) -> GridSpec {
    GridSpec::for_bounds(&mesh.bounding_box(), r).unwrap()
}

#[test]
fn committed_fixtures_match_their_generator() {
    for (path, bytes) in fixtures::files().unwrap() {
        let committed = std::fs::read(fixture(&path))
            .unwrap_or_else(|e| panic!("{path}: {e}; regenerate them: cargo run --release -p voltrack-tools --bin make_fixtures"));
        assert!(
            committed == bytes,
            "{path} differs from what fixtures::files() generates"
        );
    }
}

#[test]
fn every_format_gives_the_identical_grid() {
    for (name, _) in fixtures::shapes() {
        let reference = read_mesh(&fixture(&format!("shapes/{name}.obj"))).unwrap();
        let grid = grid_for(&reference, 64);
        let expected = voxelize(&reference, &grid);
        assert!(!expected.is_empty(), "{name}");
        for ext in ["_le.ply", "_be.ply", ".ply", ".glb"] {
            let m = read_mesh(&fixture(&format!("shapes/{name}{ext}"))).unwrap();
            // tobj numbers OBJ vertices by first use, so compare as sets.
            let sorted = |m: &voltrack::TriangleMesh| {
                let mut v: Vec<[u64; 3]> = m
                    .positions
                    .iter()
                    .map(|p| [p.x, p.y, p.z].map(f64::to_bits))
                    .collect();
                v.sort();
                v
            };
            assert_eq!(sorted(&m), sorted(&reference), "{name}{ext}: positions");
            assert_eq!(
                m.triangles.len(),
                reference.triangles.len(),
                "{name}{ext}: triangles"
            );
            assert_eq!(voxelize(&m, &grid), expected, "{name}{ext}: occupancy");
        }
    }
}

#[test]
fn closed_fixtures_have_their_volume_within_one_percent_at_128() {
    for (name, m) in fixtures::shapes() {
        if !fixtures::is_closed(name) {
            continue;
        }
        let grid = grid_for(&m, 128);
        let occ = voxelize(&m, &grid);
        let (vox, exact) = (occ.volume(&grid), m.signed_volume());
        let rel = (vox - exact).abs() / exact;
        assert!(
            rel < 0.01,
            "{name}: voxel volume {vox:.5} vs mesh volume {exact:.5} ({:.3} %)",
            100.0 * rel
        );
    }
}

/// Occupied-set disagreement with the generalised winding number (>= 0.5),
/// evaluated by brute force at every voxel of the mesh's bounding box (outside
/// it the winding number is at most 0.5, so nothing is missed there).
fn gwn_mismatches(m: &voltrack::TriangleMesh, r: usize) -> (usize, usize) {
    let grid = grid_for(m, r);
    let occ = voxelize(m, &grid);
    let mut mismatches = 0;
    for idx in 0..grid.len() {
        let inside = winding_number(m, &grid.voxel_center(idx)) >= 0.5;
        if inside != occ.contains(idx as u32) {
            mismatches += 1;
        }
    }
    (mismatches, occ.len())
}

#[test]
fn closed_fixtures_agree_exactly_with_the_winding_number() {
    for (name, m) in fixtures::shapes() {
        if fixtures::is_closed(name) {
            let (bad, n) = gwn_mismatches(&m, 24);
            assert_eq!(bad, 0, "{name}: {bad} of {n} voxels disagree");
        }
    }
}

#[test]
fn open_cup_is_filled_without_leaks() {
    let (_, cup) = fixtures::shapes()
        .into_iter()
        .find(|(n, _)| *n == "open_cup")
        .unwrap();
    let (bad, n) = gwn_mismatches(&cup, 24);
    assert!(n > 0);
    // Only the rim, where the winding number passes 0.5, may differ.
    assert!(
        (bad as f64) < 0.03 * n as f64,
        "{bad} of {n} voxels disagree"
    );
}

#[test]
fn a_box_is_voxelised_exactly_when_its_faces_lie_on_voxel_boundaries() {
    // A 1×1×1 cube on a grid of voxel 1/8: exactly 8³ voxels.
    let m = fixtures::cube(voltrack::math::Point3::origin(), 1.0);
    let grid = grid_for(&m, 8);
    assert_eq!(voxelize(&m, &grid).len(), 512);
}

#[test]
fn voxelisation_matches_point_in_mesh_for_random_rotations() {
    // Rotated shapes put vertices, edges and faces at arbitrary positions
    // relative to the voxel centers: still exact on closed meshes.
    let mut state = 12345u64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for (name, m) in fixtures::shapes() {
        if !fixtures::is_closed(name) {
            continue;
        }
        let axis = voltrack::math::Vector3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
        let rot = voltrack::math::Rotation3::new(axis.normalize() * (rnd() * 6.0));
        let mut r = m.clone();
        for p in &mut r.positions {
            *p = rot * *p;
        }
        let (bad, n) = gwn_mismatches(&r, 20);
        assert_eq!(bad, 0, "{name} rotated: {bad} of {n}");
    }
}

#[test]
fn binvox_round_trips() {
    let m = read_mesh(&fixture("shapes/torus.obj")).unwrap();
    let grid = grid_for(&m, 40);
    let occ = voxelize(&m, &grid);
    let mut bytes = Vec::new();
    voltrack::export::binvox::write_binvox(&mut bytes, &grid, &occ).unwrap();
    let (g2, o2) = voltrack::io::read_binvox(Path::new("mem.binvox"), &bytes).unwrap();
    assert_eq!(g2.dims, [grid.dims.iter().copied().max().unwrap(); 3]);
    assert!((g2.voxel_size - grid.voxel_size).abs() < 1e-12);
    assert_eq!(g2.origin, grid.origin);
    // Same voxels, re-indexed on the cubic grid.
    let back: Vec<[usize; 3]> = o2
        .indices
        .iter()
        .map(|&i| g2.voxel_coords(i as usize))
        .collect();
    let orig: Vec<[usize; 3]> = occ
        .indices
        .iter()
        .map(|&i| grid.voxel_coords(i as usize))
        .collect();
    let mut a = back.clone();
    let mut b = orig.clone();
    a.sort();
    b.sort();
    assert_eq!(a, b);
}

#[test]
fn sequence_grid_spans_all_frames_with_a_margin() {
    let a = fixtures::cube(voltrack::math::Point3::origin(), 1.0);
    let b = fixtures::cube(voltrack::math::Point3::new(3.0, 0.0, 0.0), 1.0);
    let bounds: Aabb = a.bounding_box().union(&b.bounding_box());
    let g = GridSpec::for_bounds(&bounds, 64).unwrap();
    assert_eq!(g.dims[0], 64 + 2 * voltrack::model::GRID_MARGIN);
    assert!((g.voxel_size - 4.0 / 64.0).abs() < 1e-12);
    assert!(voxelize(&a, &g).len() == voxelize(&b, &g).len());
}

/// A sequence keeps each frame as runs of consecutive voxels: expanding them
/// gives back exactly the voxels voxelisation found, for solid, hollow and
/// scattered frames alike.
#[test]
fn occupancy_runs_give_back_the_voxels() {
    use voltrack::math::Point3;
    use voltrack::model::{Occupancy, OccupancyRuns};
    let grid = GridSpec::for_bounds(
        &voltrack::Aabb {
            min: Point3::new(-1.0, -1.0, -1.0),
            max: Point3::new(1.0, 1.0, 1.0),
        },
        32,
    )
    .unwrap();
    let torus = voltrack::fixtures::torus(Point3::origin(), 0.6, 0.25, 32, 16);
    let mut state = 0x9e37_79b9_u64;
    let scattered: Vec<u32> = (0..grid.len() as u32)
        .filter(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state.is_multiple_of(3)
        })
        .collect();
    // The last case's gaps need every byte of the encoding.
    let cases = [
        voxelize(&torus, &grid),
        Occupancy { indices: scattered },
        Occupancy::default(),
        Occupancy {
            indices: vec![0, 1, 2, grid.len() as u32 - 1],
        },
        Occupancy {
            indices: vec![127, 128, 16_511, 2_113_663, u32::MAX - 2, u32::MAX - 1],
        },
    ];
    for occ in cases {
        let runs = OccupancyRuns::from(&occ);
        assert_eq!(runs.len(), occ.len());
        assert_eq!(runs.indices(), occ.indices);
        assert_eq!(runs.expand(), occ);
        assert!(runs.runs() <= occ.len());
    }
    // A solid's rows are long: far fewer runs than voxels.
    let solid = OccupancyRuns::from(voxelize(
        &voltrack::fixtures::cube(Point3::origin(), 1.0),
        &grid,
    ));
    assert!(
        solid.runs() * 8 <= solid.len(),
        "{} runs for {} voxels",
        solid.runs(),
        solid.len()
    );
    // Gaps and lengths of a few hundred voxels take a byte or two each.
    assert!(
        solid.bytes() <= 3 * solid.runs(),
        "{} bytes for {} runs",
        solid.bytes(),
        solid.runs()
    );
}
