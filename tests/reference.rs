//! Issue 47: the reference frame. A ball that parts from a slab
//! ([`voltrack::fixtures::parting`]): deforming frame 0, where the two are
//! merged, keeps them joined for the rest of the take; `Reference::Auto`
//! deforms the first frame where they are apart instead, tracking from it
//! forward and back.

use voltrack::fixtures::{
    ball_takes, parting, thrown, PARTING_APART, PARTING_FRAMES, THROWN_CAUGHT, THROWN_FRAMES,
    THROWN_RELEASE,
};
use voltrack::math::Real;
use voltrack::params::{DeformParams, Reference, TrackParams};
use voltrack::pipeline::{convert, Conversion, ConvertOptions};
use voltrack::voxel::{voxelize_sequence, VoxelParams};
use voltrack::{Error, Progress, TriangleMesh};

fn frames() -> Vec<TriangleMesh> {
    (0..PARTING_FRAMES).map(parting).collect()
}

fn options(reference: Reference) -> ConvertOptions {
    with_segments(reference, false)
}

fn with_segments(reference: Reference, segments: bool) -> ConvertOptions {
    ConvertOptions {
        deform: DeformParams {
            segments,
            ..Default::default()
        },
        voxel: VoxelParams {
            resolution: 48,
            ..Default::default()
        },
        track: TrackParams {
            centers: 150,
            reference,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Connected pieces of `mesh` through shared vertices.
fn pieces(mesh: &TriangleMesh) -> usize {
    let mut parent: Vec<usize> = (0..mesh.positions.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (
                root(&mut parent, t[0] as usize),
                root(&mut parent, t[k] as usize),
            );
            parent[a] = b;
        }
    }
    let used: std::collections::BTreeSet<usize> = mesh
        .triangles
        .iter()
        .map(|t| root(&mut parent, t[0] as usize))
        .collect();
    used.len()
}

/// The largest distance from the result to the input in each frame, % of
/// the diagonal.
fn worst_fit(conv: &Conversion) -> Vec<Real> {
    conv.fit.frames.iter().map(|f| f.two_sided.max).collect()
}

#[test]
fn auto_deforms_the_first_frame_where_the_parts_are_apart() {
    let input = frames();
    let auto = convert(&input, &options(Reference::Auto), Progress::none()).unwrap();
    let r = auto.tracked.reference.frame;
    assert_eq!(r, PARTING_APART, "{}", auto.tracked.reference.why);
    assert_eq!(auto.trajectories.reference, r);
    assert_eq!(auto.mesh.reference, r);
    let t = &auto.tracked.reference.topology;
    assert_eq!((t[0].parts, t[r].parts), (1, 2));
    // The mesh is that frame's, as loaded, in that frame.
    assert_eq!(auto.mesh.base.triangles, input[r].triangles);
    assert_eq!(
        auto.mesh.frames.get(r).unwrap().into_owned(),
        input[r].positions
    );
    assert_eq!(pieces(&auto.mesh.base), 2);

    let first = convert(&input, &options(Reference::First), Progress::none()).unwrap();
    assert_eq!(first.tracked.reference.frame, 0);
    assert_eq!(pieces(&first.mesh.base), 1);
    let (auto_fit, first_fit) = (worst_fit(&auto), worst_fit(&first));
    let last = PARTING_FRAMES - 1;
    eprintln!("largest distance to the input per frame, % of the diagonal:\n  from frame 0: {first_fit:.3?}\n  from frame {r}: {auto_fit:.3?}");
    // Frame 0's mesh stretches a membrane from the slab to the ball once they
    // part; the reference's has none, and fits as closely where they touch.
    assert!(
        first_fit[last] > 3.0 * auto_fit[last],
        "last frame: {} % from frame 0, {} % from frame {r}",
        first_fit[last],
        auto_fit[last]
    );
    // Apart, the result fits as closely as the input's meshing allows.
    let apart = auto_fit[PARTING_APART..]
        .iter()
        .copied()
        .fold(0.0, Real::max);
    assert!(apart < 1.0, "{auto_fit:?} against {first_fit:?}");
}

#[test]
fn segments_give_the_merged_frames_a_mesh_of_their_own() {
    let input = frames();
    let conv = convert(
        &input,
        &with_segments(Reference::Auto, true),
        Progress::none(),
    )
    .unwrap();
    let segments: Vec<_> = conv
        .segments
        .iter()
        .map(|s| (s.frames.clone(), s.reference, s.parts))
        .collect();
    // Merged, then apart; each deforms the frame in its middle.
    let (a, b) = (
        (PARTING_APART - 1) / 2,
        PARTING_APART + (PARTING_FRAMES - PARTING_APART - 1) / 2,
    );
    assert_eq!(
        segments,
        vec![
            (0..PARTING_APART, a, 1),
            (PARTING_APART..PARTING_FRAMES, b, 2)
        ]
    );
    // One mesh: frame a's and frame b's side by side; in each frame the other
    // shrunk onto one point, its triangles without area, the same point in
    // every frame it is hidden.
    let (na, nb) = (input[a].positions.len(), input[b].positions.len());
    assert_eq!(conv.mesh.base.positions.len(), na + nb);
    assert_eq!(
        conv.mesh.base.triangles.len(),
        input[a].triangles.len() + input[b].triangles.len()
    );
    for f in 0..PARTING_FRAMES {
        let p = conv.mesh.frames.get(f).unwrap();
        let hidden = if f < PARTING_APART {
            na..na + nb
        } else {
            0..na
        };
        assert!(
            p[hidden.clone()].iter().all(|q| *q == p[hidden.start]),
            "frame {f}"
        );
        let first_hidden = if f < PARTING_APART { 0 } else { PARTING_APART };
        assert_eq!(
            p[hidden.start],
            conv.mesh.frames.get(first_hidden).unwrap()[hidden.start],
            "frame {f}"
        );
    }
    assert_eq!(
        &conv.mesh.frames.get(a).unwrap()[..na],
        &input[a].positions[..]
    );
    assert_eq!(
        &conv.mesh.frames.get(b).unwrap()[na..],
        &input[b].positions[..]
    );
    let fit = worst_fit(&conv);
    let one = convert(
        &input,
        &with_segments(Reference::Auto, false),
        Progress::none(),
    )
    .unwrap();
    let one_fit = worst_fit(&one);
    eprintln!("largest distance per frame, segments: {fit:.3?}\n  one mesh: {one_fit:.3?}");
    // The merged frames no longer keep the ball's and the slab's surfaces
    // inside the merged volume; the others are as before.
    for f in 0..PARTING_APART {
        assert!(
            fit[f] < 0.3 * one_fit[f],
            "frame {f}: {fit:?} against {one_fit:?}"
        );
    }
    assert!(fit.iter().all(|&d| d < 2.0), "{fit:?}");

    // The same through the GLB writer: every frame's positions as written.
    let mut glb = Vec::new();
    voltrack::export::gltf::write_dynamic_glb_to(
        &mut glb,
        &conv.mesh,
        &Default::default(),
        Progress::none(),
    )
    .unwrap();
    assert!(glb.len() > 1000);
}

#[test]
fn a_ball_held_thrown_and_caught_is_three_segments_cut_where_it_leaves_and_lands() {
    let input: Vec<TriangleMesh> = (0..THROWN_FRAMES).map(thrown).collect();
    let conv = convert(
        &input,
        &with_segments(Reference::Auto, true),
        Progress::none(),
    )
    .unwrap();
    let cuts: Vec<(usize, usize)> = conv
        .segments
        .iter()
        .map(|s| (s.frames.start, s.parts))
        .collect();
    assert_eq!(cuts.len(), 3, "{:?}", conv.segments);
    assert_eq!((cuts[0], cuts[1].1, cuts[2].1), ((0, 1), 2, 1));
    // Cut where the ball leaves the slab and where it lands, within 2 frames.
    assert!(cuts[1].0.abs_diff(THROWN_RELEASE) <= 2, "{cuts:?}");
    assert!(cuts[2].0.abs_diff(THROWN_CAUGHT) <= 2, "{cuts:?}");
    // Tracked from the first frame where the ball is in the air.
    assert_eq!(conv.trajectories.reference, cuts[1].0);
    let fit = worst_fit(&conv);
    eprintln!(
        "thrown: segments {:?}, largest distance per frame: {fit:.3?}",
        conv.segments
    );
    assert!(fit.iter().all(|&d| d < 3.0), "{fit:?}");
}

#[test]
fn tracking_back_from_the_last_frame_is_tracking_the_reversed_take_forward() {
    let input = frames();
    let reversed: Vec<TriangleMesh> = input.iter().rev().cloned().collect();
    let voxel = VoxelParams {
        resolution: 40,
        ..Default::default()
    };
    let params = |reference| TrackParams {
        centers: 80,
        reference,
        ..Default::default()
    };
    let seq = voxelize_sequence(&input, &voxel, Progress::none()).unwrap();
    let back = voltrack::track::track(
        &seq,
        &params(Reference::Frame(PARTING_FRAMES - 1)),
        Progress::none(),
    )
    .unwrap();
    let seq = voxelize_sequence(&reversed, &voxel, Progress::none()).unwrap();
    let forward =
        voltrack::track::track(&seq, &params(Reference::First), Progress::none()).unwrap();
    assert_eq!(back.trajectories.reference, PARTING_FRAMES - 1);
    for f in 0..PARTING_FRAMES {
        assert_eq!(
            back.trajectories.frame(f),
            forward.trajectories.frame(PARTING_FRAMES - 1 - f),
            "frame {f}"
        );
        assert_eq!(
            back.cell_counts[f],
            forward.cell_counts[PARTING_FRAMES - 1 - f]
        );
    }
}

#[test]
fn a_reference_in_the_middle_tracks_both_ways_from_it() {
    let input = frames();
    let voxel = VoxelParams {
        resolution: 40,
        ..Default::default()
    };
    let seq = voxelize_sequence(&input, &voxel, Progress::none()).unwrap();
    let middle = |reference| {
        voltrack::track::track(
            &seq,
            &TrackParams {
                centers: 80,
                reference,
                ..Default::default()
            },
            Progress::none(),
        )
    };
    let r = 5;
    let both = middle(Reference::Frame(r)).unwrap();
    assert_eq!(both.trajectories.reference, r);
    assert_eq!(both.cell_counts.len(), PARTING_FRAMES);
    assert_eq!(both.timings.len(), PARTING_FRAMES);
    // Placed in frame r: every cell there is a Lloyd cell, none empty.
    assert!(both.cell_counts[r].iter().all(|&c| c > 0));
    assert_eq!(
        middle(Reference::Frame(r)).unwrap().trajectories,
        both.trajectories
    );

    // Frames past the end, and a reference with checkpoints, are refused
    // before any tracking.
    let past = middle(Reference::Frame(PARTING_FRAMES));
    assert!(matches!(past, Err(Error::InvalidParameter(m)) if m.contains("past the last frame")));
    let checkpoint = voltrack::track::Checkpointing::new(
        std::env::temp_dir().join("voltrack-reference-never-written"),
    );
    let refused = voltrack::track::track_with_checkpoints(
        &seq,
        &TrackParams {
            centers: 80,
            reference: Reference::Frame(2),
            ..Default::default()
        },
        Some(&checkpoint),
        Progress::none(),
    );
    assert!(matches!(refused, Err(Error::InvalidParameter(m)) if m.contains("checkpoint")));
    assert!(!checkpoint.dir.exists());
}

/// Issue 47's generated takes (bodies apart that merge, merged that part,
/// a ball held, thrown and caught): every vertex stays on its own body
/// within issue 47's bounds (correspondence mean 0.5 %, max 5 %) at a low
/// resolution. At 48 voxels the thrown ball, 6 across, moving 5 a frame,
/// is lost for two frames before it lands at one seed of four.
#[test]
fn on_the_takes_that_merge_and_part_every_vertex_keeps_to_its_body() {
    let mut options = with_segments(Reference::Auto, true);
    options.voxel.resolution = 64;
    options.track.centers = 200;
    for take in ball_takes() {
        let input = take.meshes();
        let conv = convert(&input, &options, Progress::none()).unwrap();
        let result = conv.mesh.frames.to_vec().unwrap();
        let s = take.score(&input, &conv.segments, &result);
        eprintln!(
            "{}: correspondence mean {:.3} p95 {:.3} max {:.3} %, worst part per frame {:.2?}, segments {:?}",
            take.name,
            s.mean,
            s.p95,
            s.max,
            s.worst_part.iter().map(|w| w.1).collect::<Vec<_>>(),
            conv.segments
        );
        assert!(s.mean <= 0.5 && s.max <= 5.0, "{}: {s:?}", take.name);
        assert!(s.lost.is_empty(), "{}: lost in {:?}", take.name, s.lost);
    }
}
