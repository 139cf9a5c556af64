//! Deforming the first-frame mesh by center trajectories. The conform tests
//! that measure distances to the input's surface with the surface index are
//! unit tests (`src/deform/conform_tests.rs`).

use voltrack::deform::{
    bind, conform, conform_frame, deform, smooth_bindings, Binding, DualQuaternion,
};
use voltrack::math::{Point3, Real, Rotation3, Vector3};
use voltrack::model::positions::PositionFrames;
use voltrack::model::{DynamicMesh, Rigid, Trajectories};
use voltrack::params::{Blending, ConformParams, DeformParams};
use voltrack::refine::SparseAffinity;
fn random_rigid(k: u32) -> Rigid {
    let a = k as Real;
    Rigid {
        rotation: *Rotation3::new(Vector3::new(0.3 * a.sin(), 0.7 * a.cos(), 0.2 + 0.1 * a))
            .matrix(),
        translation: Vector3::new(a, -0.5 * a, 0.25),
    }
}

#[test]
fn dual_quaternions_reproduce_rigid_motions() {
    for k in 0..10 {
        let m = random_rigid(k);
        let dq = DualQuaternion::from_rigid(&m);
        for p in [
            Point3::new(0.3, -1.0, 2.0),
            Point3::origin(),
            Point3::new(-4.0, 5.0, 0.5),
        ] {
            assert!((dq.apply(&p) - m.apply(&p)).norm() < 1e-12);
        }
        // Blending a motion with itself (either sign) gives the motion.
        let neg = DualQuaternion {
            real: -dq.real,
            dual: -dq.dual,
        };
        let b = DualQuaternion::blend([(dq, 0.3), (neg, 0.7)].into_iter());
        assert!(
            (b.apply(&Point3::new(1.0, 2.0, 3.0)) - m.apply(&Point3::new(1.0, 2.0, 3.0))).norm()
                < 1e-12
        );
    }
}

#[test]
fn a_rigidly_moving_mesh_follows_exactly() {
    let mesh = voltrack::fixtures::torus(Point3::origin(), 1.0, 0.35, 24, 12);
    // Centers spread over the torus, carried by one rigid motion per frame.
    let centers0: Vec<Point3> = mesh.positions.iter().step_by(7).copied().collect();
    let motions: Vec<Rigid> = (0..5).map(random_rigid).collect();
    let frames: Vec<Vec<Point3>> = std::iter::once(centers0.clone())
        .chain(
            motions
                .iter()
                .skip(1)
                .map(|m| centers0.iter().map(|p| m.apply(p)).collect()),
        )
        .collect();
    let traj = Trajectories::from_frames(frames);
    let n = traj.centers;
    let omega = SparseAffinity {
        lists: (0..n)
            .map(|_| (0..n as u32).map(|j| (j, 1.0)).collect())
            .collect(),
    };
    for blending in [Blending::DualQuaternion, Blending::Linear] {
        let dm = deform(
            &mesh,
            &traj,
            &omega,
            &DeformParams {
                blending,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(dm.frames.len(), 5);
        assert_eq!(dm.frames.get(0).unwrap().as_ref(), &mesh.positions[..]);
        for (f, motion) in motions.iter().enumerate().take(5).skip(1) {
            for (v, p) in dm.frames.get(f).unwrap().iter().zip(&mesh.positions) {
                assert!(
                    (v - motion.apply(p)).norm() < 1e-9,
                    "{blending:?} frame {f}"
                );
            }
        }
    }
}

#[test]
fn vertices_bind_only_to_centers_affine_to_their_nearest() {
    // Two centers side by side that move apart: with ω = 0 between them, a
    // vertex next to the first follows it alone.
    let mesh = voltrack::fixtures::cube(Point3::new(0.0, 0.0, 0.0), 0.2);
    let traj = Trajectories::from_frames(vec![
        vec![Point3::new(0.0, 0.0, 0.0), Point3::new(0.5, 0.0, 0.0)],
        vec![Point3::new(0.0, 1.0, 0.0), Point3::new(0.5, -1.0, 0.0)],
    ]);
    let apart = SparseAffinity {
        lists: vec![vec![(0, 1.0)], vec![(1, 1.0)]],
    };
    let dm = deform(&mesh, &traj, &apart, &DeformParams::default()).unwrap();
    for (v, p) in dm.frames.get(1).unwrap().iter().zip(&mesh.positions) {
        assert!((v - (p + Vector3::new(0.0, 1.0, 0.0))).norm() < 1e-9);
    }
    let together = SparseAffinity {
        lists: vec![vec![(0, 1.0), (1, 1.0)], vec![(0, 1.0), (1, 1.0)]],
    };
    let dm = deform(&mesh, &traj, &together, &DeformParams::default()).unwrap();
    assert!(dm
        .frames
        .get(1)
        .unwrap()
        .iter()
        .zip(&mesh.positions)
        .any(|(v, p)| (v - (p + Vector3::new(0.0, 1.0, 0.0))).norm() > 1e-3));
}

/// A bar 3 long along x, with eight centers on its axis; ω links the centers
/// within `group` of each other's index range (`None`: all linked).
fn bar_with_centers(split: Option<u32>) -> (voltrack::TriangleMesh, Vec<Point3>, SparseAffinity) {
    let mesh = voltrack::fixtures::bending_bar(0);
    let centers: Vec<Point3> = (0..8)
        .map(|i| Point3::new(0.1875 + 0.375 * i as Real, 0.0, 0.0))
        .collect();
    let side = |i: u32| split.map_or(0, |s| u32::from(i >= s));
    let lists = (0..8u32)
        .map(|i| {
            (0..8u32)
                .filter(|&j| side(i) == side(j))
                .map(|j| (j, 1.0))
                .collect()
        })
        .collect();
    (mesh, centers, SparseAffinity { lists })
}

fn nearest_center(b: &Binding) -> u32 {
    b.centers[0].0
}

#[test]
fn smoothed_weights_stay_normalised_and_never_cross_a_cut() {
    let (mesh, centers, omega) = bar_with_centers(Some(4));
    let params = DeformParams::default();
    let bound = bind(&mesh, &centers, &omega, &params);
    assert_eq!(
        smooth_bindings(&mesh.triangles, bound.clone(), &omega, 0, 8),
        bound
    );
    let smoothed = smooth_bindings(&mesh.triangles, bound.clone(), &omega, 30, 8);
    for (b, s) in bound.iter().zip(&smoothed) {
        assert!(s.centers.len() <= 8 && !s.centers.is_empty());
        assert!((s.centers.iter().map(|c| c.1).sum::<Real>() - 1.0).abs() < 1e-12);
        assert!(s.centers.iter().all(|c| c.1 > 0.0));
        // The bar is one connected surface, but no weight leaks over the cut
        // between centers 0-3 and 4-7.
        let side = nearest_center(b) >= 4;
        assert!(
            s.centers.iter().all(|c| (c.0 >= 4) == side),
            "{b:?} became {s:?}"
        );
    }
}

#[test]
fn smoothing_makes_the_weights_change_gradually_along_the_surface() {
    let (mesh, centers, omega) = bar_with_centers(None);
    let params = DeformParams::default();
    let bound = bind(&mesh, &centers, &omega, &params);
    // Largest change of the weights across one edge, as an L1 distance.
    let jump = |b: &[Binding]| {
        let weight = |v: usize, c: u32| b[v].centers.iter().find(|e| e.0 == c).map_or(0.0, |e| e.1);
        mesh.triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| {
                (0..8)
                    .map(|c| (weight(a as usize, c) - weight(b as usize, c)).abs())
                    .sum::<Real>()
            })
            .fold(0.0, Real::max)
    };
    let before = jump(&bound);
    let after = jump(&smooth_bindings(
        &mesh.triangles,
        bound.clone(),
        &omega,
        params.smoothing,
        2 * params.neighbors,
    ));
    // Measured: 0.56 before, 0.35 after; without smoothing the two are equal.
    assert!(
        after < 0.7 * before,
        "largest jump {before} before, {after} after"
    );
}

/// The sphere the conform tests fit to, and a rigid motion of it.
fn conform_sphere() -> (voltrack::TriangleMesh, Rigid) {
    (
        voltrack::fixtures::sphere(Point3::origin(), 1.0, 32, 16),
        random_rigid(3),
    )
}

fn moved(points: &[Point3], m: &Rigid) -> Vec<Point3> {
    points.iter().map(|p| m.apply(p)).collect()
}

fn mean_distance(a: &[Point3], b: &[Point3]) -> Real {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).sum::<Real>() / a.len() as Real
}

#[test]
fn conforming_undoes_a_twist_that_blending_left_on_the_surface() {
    let (base, _) = conform_sphere();
    // Each latitude turned about the axis by 0.3 z radians: still on the
    // sphere, but sheared, which the frame-0 edges rule out.
    let twisted: Vec<Point3> = base
        .positions
        .iter()
        .map(|p| Rotation3::new(Vector3::z() * 0.3 * p.z) * p)
        .collect();
    let fitted = conform_frame(
        &base,
        &twisted,
        &base,
        &base.bounding_box(),
        &ConformParams::default(),
    )
    .unwrap();
    let (before, after) = (
        mean_distance(&twisted, &base.positions),
        mean_distance(&fitted, &base.positions),
    );
    assert!(after < 0.05 * before, "mean error {before} -> {after}");
    // Off: the blended positions stay.
    let off = conform_frame(
        &base,
        &twisted,
        &base,
        &base.bounding_box(),
        &ConformParams {
            iterations: 0,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(off, twisted);
}

#[test]
fn conforming_to_an_inside_out_input_gives_the_same_mesh() {
    let (base, m) = conform_sphere();
    let input = voltrack::TriangleMesh {
        positions: moved(&base.positions, &m),
        ..base.clone()
    };
    let inside_out = voltrack::TriangleMesh {
        triangles: input.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(),
        ..input.clone()
    };
    let centre = m.apply(&Point3::origin());
    let offset: Vec<Point3> = input
        .positions
        .iter()
        .map(|p| centre + (p - centre) * 1.02)
        .collect();
    let params = ConformParams::default();
    let a = conform_frame(&base, &offset, &input, &base.bounding_box(), &params).unwrap();
    let b = conform_frame(&base, &offset, &inside_out, &base.bounding_box(), &params).unwrap();
    assert!(mean_distance(&a, &b) < 1e-9, "{}", mean_distance(&a, &b));
}

/// [`conform_sphere`]'s mesh with a UV-style seam along one meridian: the
/// triangles on one side of it use copies of its vertices, as an OBJ with
/// texture coordinates loads. Returns the mesh and (copy, original) pairs.
fn sphere_with_a_seam() -> (voltrack::TriangleMesh, Vec<(usize, usize)>) {
    let (segments, rings) = (32u32, 16u32);
    let mut mesh = voltrack::fixtures::sphere(Point3::origin(), 1.0, segments, rings);
    let on_seam =
        |v: u32| v >= 1 && v < 1 + (rings - 1) * segments && (v - 1).is_multiple_of(segments);
    let last_segment =
        |v: u32| v >= 1 && v < 1 + (rings - 1) * segments && (v - 1) % segments == segments - 1;
    let mut copies = std::collections::HashMap::new();
    for t in 0..mesh.triangles.len() {
        if !mesh.triangles[t].iter().any(|&v| last_segment(v)) {
            continue;
        }
        for k in 0..3 {
            let v = mesh.triangles[t][k];
            if on_seam(v) {
                let copy = *copies.entry(v).or_insert_with(|| {
                    mesh.positions.push(mesh.positions[v as usize]);
                    mesh.positions.len() as u32 - 1
                });
                mesh.triangles[t][k] = copy;
            }
        }
    }
    let pairs = copies
        .into_iter()
        .map(|(v, c)| (c as usize, v as usize))
        .collect();
    (mesh, pairs)
}

#[test]
fn conforming_keeps_a_seam_closed() {
    let (base, seam) = sphere_with_a_seam();
    assert_eq!(seam.len(), 15);
    let twisted: Vec<Point3> = base
        .positions
        .iter()
        .map(|p| Rotation3::new(Vector3::z() * 0.3 * p.z) * p)
        .collect();
    let fitted = conform_frame(
        &base,
        &twisted,
        &base,
        &base.bounding_box(),
        &ConformParams::default(),
    )
    .unwrap();
    let gap = seam
        .iter()
        .map(|&(c, v)| (fitted[c] - fitted[v]).norm())
        .fold(0.0, Real::max);
    assert!(gap == 0.0, "the seam opened by {gap}");
    // And the twist is undone as on the welded sphere.
    let (before, after) = (
        mean_distance(&twisted, &base.positions),
        mean_distance(&fitted, &base.positions),
    );
    assert!(after < 0.05 * before, "mean error {before} -> {after}");
}

#[test]
fn blending_keeps_a_seam_closed() {
    let (mesh, seam) = sphere_with_a_seam();
    // Centers on the axis and around it, each latitude turned its own way.
    let centers0: Vec<Point3> = (0..12)
        .map(|i| {
            Rotation3::new(Vector3::z() * i as Real)
                * Point3::new(0.5, 0.0, -0.8 + 0.15 * i as Real)
        })
        .collect();
    let frames: Vec<Vec<Point3>> = (0..3)
        .map(|f| {
            centers0
                .iter()
                .map(|p| Rotation3::new(Vector3::z() * (0.2 * f as Real * p.z)) * p)
                .collect()
        })
        .collect();
    let traj = Trajectories::from_frames(frames);
    let n = traj.centers;
    let omega = SparseAffinity {
        lists: (0..n)
            .map(|_| (0..n as u32).map(|j| (j, 1.0)).collect())
            .collect(),
    };
    let dm = deform(&mesh, &traj, &omega, &DeformParams::default()).unwrap();
    // Asked to stop, it stops between frames.
    struct Stop;
    impl voltrack::progress::ProgressSink for Stop {
        fn report(&self, _: voltrack::Stage, _: usize, _: usize) {}
        fn cancelled(&self) -> bool {
            true
        }
    }
    let stopped = voltrack::deform::deform_with(
        &mesh,
        &traj,
        &omega,
        &DeformParams::default(),
        voltrack::Progress(Some(&Stop)),
    );
    assert!(matches!(stopped, Err(voltrack::Error::Interrupted { .. })));
    for frame in &dm.frames.to_vec().unwrap() {
        let gap = seam
            .iter()
            .map(|&(c, v)| (frame[c] - frame[v]).norm())
            .fold(0.0, Real::max);
        assert!(gap == 0.0, "the seam opened by {gap}");
    }
}

/// The bundled bar (two rigid halves and an elbow at x = 1.5) in frame f,
/// as `bending_bar_motion` makes it, and as blending would deform it: the
/// elbow's bend spread over the bar's middle third, as centers on both
/// sides of a joint give.
fn bar_bent_and_blended(
    base: &voltrack::TriangleMesh,
    f: usize,
) -> (voltrack::TriangleMesh, Vec<Point3>) {
    let input = voltrack::TriangleMesh {
        positions: base
            .positions
            .iter()
            .map(|p| voltrack::fixtures::bending_bar_motion(f, p))
            .collect(),
        ..base.clone()
    };
    let pivot = Point3::new(1.5, 0.0, 0.0);
    // The elbow's turn and the whole bar's motion, as bending_bar_motion makes them.
    let (bend, turn, shift) = (
        0.12 * f as Real,
        0.04 * f as Real,
        Vector3::new(0.02 * f as Real, 0.0, 0.0),
    );
    let whole = |q: Point3| Rotation3::new(Vector3::y() * turn) * q + shift;
    // Blending's bend: each point takes a share of the elbow's turn, 0 to 1 over x in 1 ..= 2.
    let share = |p: &Point3| (p.x - 1.0).clamp(0.0, 1.0);
    let blended: Vec<Point3> = base
        .positions
        .iter()
        .map(|p| whole(pivot + Rotation3::new(Vector3::z() * bend * share(p)) * (p - pivot)))
        .collect();
    // Outside the middle third it is the truth.
    assert!(base
        .positions
        .iter()
        .zip(blended.iter().zip(&input.positions))
        .all(|(p, (b, q))| (share(p) > 0.0 && share(p) < 1.0) || (b - q).norm() < 1e-9));
    (input, blended)
}

/// Mean distance of the bar's vertices away from its elbow to where they
/// belong.
fn bar_rigid_parts_off(base: &voltrack::TriangleMesh, fitted: &[Point3], truth: &[Point3]) -> Real {
    let far: Vec<usize> = (0..fitted.len())
        .filter(|&v| (base.positions[v].x - 1.5).abs() > 0.3)
        .collect();
    far.iter()
        .map(|&v| (fitted[v] - truth[v]).norm())
        .sum::<Real>()
        / far.len() as Real
}

#[test]
fn conforming_keeps_a_joint_s_bend_at_the_joint() {
    // The bar bent as in its last frame; the input pulls the spread bend back.
    let base = voltrack::fixtures::bending_bar(0);
    let (input, blended) = bar_bent_and_blended(&base, voltrack::fixtures::BENDING_BAR_FRAMES - 1);
    let rigid_parts = |fitted: &[Point3]| bar_rigid_parts_off(&base, fitted, &input.positions);
    let even = conform_frame(
        &base,
        &blended,
        &input,
        &base.bounding_box(),
        &ConformParams {
            bend_strain: 0.0,
            ..Default::default()
        },
    )
    .unwrap();
    let jointed = conform_frame(
        &base,
        &blended,
        &input,
        &base.bounding_box(),
        &ConformParams::default(),
    )
    .unwrap();
    let (before, even, jointed) = (
        rigid_parts(&blended),
        rigid_parts(&even),
        rigid_parts(&jointed),
    );
    // Even the truth is no rest for the fit (its elbow's inner corner is
    // squeezed, which the frame-0 edges resist, and the bar slides along
    // itself to ease it), so both fits move the rigid parts; weighing the
    // elbow's strained edges less moves them less.
    assert!(jointed < 0.92 * even, "rigid parts off by {before} blended, {even} with every edge alike, {jointed} with strained edges weighing less");
}

#[test]
fn conforming_a_take_finds_its_joint_from_every_frame() {
    // The bar through its whole take, each frame blended with the bend
    // spread: the edges that bend through the take (the elbow's) weigh less
    // in every frame, on top of each frame's own strains.
    let base = voltrack::fixtures::bending_bar(0);
    let (inputs, blended): (Vec<voltrack::TriangleMesh>, Vec<Vec<Point3>>) = (0
        ..voltrack::fixtures::BENDING_BAR_FRAMES)
        .map(|f| bar_bent_and_blended(&base, f))
        .unzip();
    let bounds = base.bounding_box();
    let fit = |params: &ConformParams| -> Real {
        let mesh = DynamicMesh {
            base: base.clone(),
            frames: PositionFrames::from(blended.clone()),
            reference: 0,
        };
        let fitted = conform(mesh, &inputs, &bounds, params, Default::default())
            .unwrap()
            .frames
            .to_vec()
            .unwrap();
        assert_eq!(fitted[0], blended[0], "frame 0 stays");
        fitted
            .iter()
            .zip(&inputs)
            .skip(1)
            .map(|(fitted, input)| bar_rigid_parts_off(&base, fitted, &input.positions))
            .sum::<Real>()
            / (fitted.len() - 1) as Real
    };
    let alone = fit(&ConformParams {
        joint_strain: 0.0,
        ..Default::default()
    });
    let pooled = fit(&ConformParams::default());
    assert!(
        pooled < 0.85 * alone,
        "rigid parts off by {alone} with each frame's own strains, {pooled} with the take's too"
    );
}
