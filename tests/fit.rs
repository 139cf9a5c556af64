//! The conversion report: the fit of a dynamic mesh to its input files, and
//! the HTML document built from a whole conversion of the bending bar.

use std::path::{Path, PathBuf};
use voltrack::fixtures::{bending_bar_motion, BENDING_BAR_FRAMES};
use voltrack::io::FrameFiles;
use voltrack::math::Real;
use voltrack::metrics::fit::FarDistances;
use voltrack::metrics::{fit_to_input, DistanceSummary};
use voltrack::model::DynamicMesh;
use voltrack::{Aabb, Error, Progress};

fn fixture_frames() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar");
    (0..BENDING_BAR_FRAMES)
        .map(|f| dir.join(format!("frame_{f}.obj")))
        .collect()
}

fn diagonal_of(paths: &[PathBuf]) -> Real {
    paths
        .iter()
        .map(|p| voltrack::io::read_mesh(p).unwrap().bounding_box())
        .fold(Aabb::empty(), |a, b| a.union(&b))
        .diagonal()
}

#[test]
fn fit_of_the_true_motion_is_zero_and_of_a_still_mesh_is_not() {
    let paths = fixture_frames();
    let diagonal = diagonal_of(&paths);
    let base = voltrack::io::read_mesh(&paths[0]).unwrap();
    // The bar's own motion applied to frame 0: every frame's surface to the
    // files' f32 precision, though each input frame is meshed differently,
    // except at the elbow: the motion leaves the ring at the pivot unrotated
    // and turns the next ring, so the strip between them depends on how far
    // apart the rings are (14, 16 or 18 quads along the bar; frames 3 and 6
    // have frame 0's 14).
    let truth = DynamicMesh {
        frames: (0..BENDING_BAR_FRAMES)
            .map(|f| {
                base.positions
                    .iter()
                    .map(|p| bending_bar_motion(f, p))
                    .collect()
            })
            .collect(),
        base: base.clone(),
        reference: 0,
    };
    let fit = fit_to_input(
        &truth,
        &FrameFiles::new(paths.clone()),
        diagonal,
        FarDistances::both(2.0),
        None,
        Progress::none(),
    )
    .unwrap();
    assert_eq!(fit.frames.len(), BENDING_BAR_FRAMES);
    assert_eq!(fit.diagonal, diagonal);
    for (f, x) in fit.frames.iter().enumerate() {
        let same_rings = f % 3 == 0;
        for s in [x.result_to_input, x.input_to_result] {
            assert!(s.p95 < 1e-5, "frame {f}: {x:?}");
            assert!(
                if same_rings {
                    s.max < 1e-5
                } else {
                    s.max < 1.0
                },
                "frame {f}: {x:?}"
            );
        }
        if !same_rings {
            assert!(
                x.two_sided.max > 1e-3,
                "frame {f}: the elbow strip should show: {x:?}"
            );
        }
    }
    // Frame 0 unmoved for every frame: the bent end is off by up to its
    // sagitta, most in the last frame.
    let still = DynamicMesh {
        frames: vec![base.positions.clone(); BENDING_BAR_FRAMES].into(),
        base,
        reference: 0,
    };
    let fit = fit_to_input(
        &still,
        &FrameFiles::new(paths.clone()),
        diagonal,
        FarDistances::both(2.0),
        None,
        Progress::none(),
    )
    .unwrap();
    assert_eq!(fit.frames[0].two_sided, DistanceSummary::default());
    let last = &fit.frames[BENDING_BAR_FRAMES - 1];
    assert!(
        last.result_to_input.max > 5.0 && last.input_to_result.max > 5.0,
        "{last:?}"
    );
    assert_eq!(fit.worst_frame(), BENDING_BAR_FRAMES - 1);
    assert!(
        fit.frames
            .windows(2)
            .all(|w| w[0].two_sided.mean < w[1].two_sided.mean),
        "{:?}",
        fit.frames
    );

    // A frame count that does not match, or a missing file, is an error.
    assert!(matches!(
        fit_to_input(
            &still,
            &FrameFiles::new(paths[1..].to_vec()),
            diagonal,
            FarDistances::both(2.0),
            None,
            Progress::none()
        ),
        Err(Error::InvalidInput(_))
    ));
    let mut missing = paths.clone();
    missing[3] = PathBuf::from("no_such_frame.obj");
    match fit_to_input(
        &still,
        &FrameFiles::new(missing),
        diagonal,
        FarDistances::both(2.0),
        None,
        Progress::none(),
    ) {
        Err(e) => assert!(e.to_string().contains("no_such_frame.obj"), "{e}"),
        Ok(_) => panic!("a missing frame was measured"),
    }
}
