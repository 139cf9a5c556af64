//! Issue 21: a thin part that swings fast past another part loses its
//! centers, and the converted mesh is mangled there. The fixture
//! ([`voltrack::fixtures::swinging`]) is a body with two thin legs side by
//! side, one swinging past the other by about four of its widths per frame.
//! These tests hold the detector that warns of such frames
//! ([`voltrack::metrics::coverage`], [`voltrack::metrics::fit_outliers`]),
//! and (ignored until the tracker is fixed) the tracker itself.

use std::path::{Path, PathBuf};
use voltrack::fixtures::{swinging, swinging_leg, SWINGING_LEG_FRAMES};
use voltrack::math::Real;
use voltrack::model::Trajectories;
use voltrack::params::{CoverageParams, DeformParams, Reference, RefineParams, TrackParams};
use voltrack::pipeline::Conversion;
use voltrack::voxel::{VoxelParams, VoxelSequence};
use voltrack::Progress;

mod common;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// The README's kind of run at low resolution, everything else at defaults.
fn convert(name: &str, resolution: usize, centers: usize) -> Conversion {
    convert_with(
        name,
        resolution,
        TrackParams {
            centers,
            ..Default::default()
        },
    )
}

/// The paper's guess alone, which still loses the swinging leg.
/// The paper's tracking: one guess, and no reclaiming of starved cells'
/// volume (which would keep the leg in most frames).
fn single_guess(centers: usize) -> TrackParams {
    TrackParams {
        centers,
        damped_guess: None,
        accelerated_guess: false,
        reclaim: false,
        ..Default::default()
    }
}

/// One conversion (`attempts: 1`): the tests of the detector need the
/// placement that loses the leg, not the attempt that keeps it.
fn convert_with(name: &str, resolution: usize, track: TrackParams) -> Conversion {
    convert_attempts(name, resolution, track, 1)
}

fn convert_attempts(
    name: &str,
    resolution: usize,
    track: TrackParams,
    attempts: usize,
) -> Conversion {
    let files = voltrack::io::FrameFiles::discover(&[fixture(name)]).unwrap();
    let voxel = VoxelParams {
        resolution,
        ..Default::default()
    };
    voltrack::pipeline::convert(
        &files,
        &voltrack::pipeline::ConvertOptions {
            voxel: voxel.clone(),
            track: track.clone(),
            refine: Some(RefineParams::default()),
            deform: DeformParams::default(),
            conform: Default::default(),
            checkpoint: None,
            attempts,
            ..Default::default()
        },
        Progress::none(),
    )
    .unwrap()
}

/// Per frame, the mean and largest distance (in voxels) of the centers that
/// start in the swinging leg from where the leg's rigid motion takes them.
fn leg_errors(traj: &Trajectories, voxel_size: Real) -> Vec<(Real, Real)> {
    let legs: Vec<usize> = (0..traj.centers)
        .filter(|&i| swinging::in_swinging_leg(&traj.get(0, i)))
        .collect();
    assert!(
        legs.len() >= 3,
        "only {} centers start in the leg",
        legs.len()
    );
    (0..traj.frames)
        .map(|f| {
            let e: Vec<Real> = legs
                .iter()
                .map(|&i| {
                    (traj.get(f, i) - swinging::motion(f, &traj.get(0, i))).norm() / voxel_size
                })
                .collect();
            (
                e.iter().sum::<Real>() / e.len() as Real,
                e.iter().copied().fold(0.0, Real::max),
            )
        })
        .collect()
}

/// The swinging-leg frames voxelised in memory, and centers placed in frame
/// 0 by the tracker: tracked through frame 0 alone, they are its Lloyd
/// placement (seed 0, 1000 steps over-relaxed by 1.8, until no center moves
/// 1e-6).
fn swinging_sequence(
    resolution: usize,
    centers: usize,
) -> (VoxelSequence, Vec<voltrack::math::Point3>) {
    let meshes: Vec<_> = (0..SWINGING_LEG_FRAMES).map(swinging_leg).collect();
    let seq = common::voxel_sequence(&meshes, resolution);
    let first = VoxelSequence {
        frames: seq.frames[..1].to_vec(),
        names: seq.names[..1].to_vec(),
        ..seq.clone()
    };
    let placed = voltrack::track::track(
        &first,
        &TrackParams {
            centers,
            seed: 0,
            lloyd_iterations: 1000,
            over_relaxation: 1.8,
            // The threshold in the input's units.
            threshold: 1e-6,
            absolute_units: true,
            reference: Reference::First,
            ..Default::default()
        },
        Progress::none(),
    )
    .expect("placing the centers")
    .trajectories
    .frame(0)
    .to_vec();
    (seq, placed)
}

#[test]
fn coverage_is_quiet_when_the_centers_follow_the_true_motion() {
    let (seq, placed) = swinging_sequence(64, 200);
    let truth = Trajectories::from_frames(
        (0..SWINGING_LEG_FRAMES)
            .map(|f| placed.iter().map(|c| swinging::motion(f, c)).collect())
            .collect(),
    );
    let c = voltrack::metrics::coverage(&truth, &seq, &CoverageParams::default()).unwrap();
    assert!(c.flagged.is_empty(), "{:?}", c.frames);
    assert!(c.frames.iter().all(|x| x.lost == 0), "{:?}", c.frames);
}

#[test]
fn coverage_flags_a_leg_whose_centers_stayed_behind() {
    let (seq, placed) = swinging_sequence(64, 200);
    // Every center follows the truth but the leg's, which stay where they
    // were in frame 0: the captured leg swings away empty.
    let lost = Trajectories::from_frames(
        (0..SWINGING_LEG_FRAMES)
            .map(|f| {
                placed
                    .iter()
                    .map(|c| {
                        if swinging::in_swinging_leg(c) {
                            *c
                        } else {
                            swinging::motion(f, c)
                        }
                    })
                    .collect()
            })
            .collect(),
    );
    let c = voltrack::metrics::coverage(&lost, &seq, &CoverageParams::default()).unwrap();
    for (f, x) in c.frames.iter().enumerate() {
        eprintln!(
            "frame {f}: angle {:.0}°, lost {:.2} %, largest region {:.1} cells",
            swinging::angle(f).to_degrees(),
            100.0 * x.lost_share,
            x.largest_region as Real / c.cell_voxels
        );
    }
    // In front, the leg is far from every center; in frame 8 it is back
    // where it started, around its own centers.
    for f in [3, 4, 5] {
        assert!(
            c.flagged.contains(&f),
            "frame {f} not flagged: {:?}",
            c.flagged
        );
    }
    for f in [0, 8] {
        assert!(
            !c.flagged.contains(&f),
            "frame {f} flagged: {:?}",
            c.flagged
        );
    }
    assert_eq!(
        c.flagged_runs().first().map(|r| r.0),
        c.flagged.first().copied()
    );
}

/// The paper's single guess loses the swinging leg at `-r 48 -n 150`; the
/// detector must flag every frame where it does.
#[test]
fn the_detector_flags_the_frames_where_the_tracker_loses_the_leg() {
    let conv = convert_with("swinging_leg", 48, single_guess(150));
    let errors = leg_errors(&conv.trajectories, conv.sequence.grid.voxel_size);
    let flagged = conv.lost_parts().flagged;
    for (f, (mean, max)) in errors.iter().enumerate() {
        eprintln!(
            "frame {f}: leg centers off by {mean:.1} (max {max:.1}) voxels; lost volume {:.2} %, fit p95 {:.2} %",
            100.0 * conv.coverage.frames[f].lost_share,
            conv.fit_outliers.p95[f]
        );
    }
    eprintln!(
        "flagged: {flagged:?} (volume {:?}, fit {:?}, fit limit {:.2} %)",
        conv.coverage.flagged, conv.fit_outliers.flagged, conv.fit_outliers.limit
    );
    // Lost: the leg's centers are on average more than a third of its length
    // (23 voxels here) from where the leg is.
    let lost: Vec<usize> = (0..SWINGING_LEG_FRAMES)
        .filter(|&f| errors[f].0 > 8.0)
        .collect();
    assert!(
        !lost.is_empty(),
        "the paper's single guess kept the leg: give this test a fixture it still loses"
    );
    for f in &lost {
        assert!(
            flagged.contains(f),
            "frame {f}: the leg is lost ({:?} voxels) but not flagged",
            errors[*f]
        );
    }
    // While the leg is tracked, nothing is flagged.
    for f in (0..SWINGING_LEG_FRAMES).filter(|&f| errors[f].1 < 3.0) {
        assert!(
            !flagged.contains(&f),
            "frame {f} flagged with the leg tracked ({:?} voxels)",
            errors[f]
        );
    }
}

/// The leg is no longer lost: in every frame its centers are on average
/// within a third of its length (23 voxels) of where its motion takes them,
/// the bound past which the detector test calls it lost. Before the
/// accelerated guess and the region-by-region combination of the guesses'
/// runs (issue 21) they were up to 17.7 voxels off on average, taken by the
/// still leg and the body from frame 6 on; now at most about 6.
#[test]
fn the_tracker_no_longer_loses_the_swinging_leg() {
    let conv = convert("swinging_leg", 48, 150);
    let errors = leg_errors(&conv.trajectories, conv.sequence.grid.voxel_size);
    for (f, (mean, max)) in errors.iter().enumerate() {
        eprintln!("frame {f}: leg centers off by {mean:.1} (max {max:.1}) voxels");
    }
    for (f, (mean, _)) in errors.iter().enumerate() {
        assert!(
            *mean <= 8.0,
            "frame {f}: the leg's centers are {mean:.1} voxels off on average: lost"
        );
    }
    assert!(
        conv.coverage.flagged.is_empty(),
        "{:?}",
        conv.coverage.frames
    );
}

/// Issue 21's goal: the centers of the fast thin part follow it closely.
/// Fails today: where the leg turns back (frames 7-8) they follow with a
/// lag (docs/measurements.md says how much).
#[test]
#[ignore = "issue 21: the tracker lags a fast thin part where it turns back"]
fn the_tracker_keeps_the_swinging_leg() {
    let conv = convert("swinging_leg", 48, 150);
    let errors = leg_errors(&conv.trajectories, conv.sequence.grid.voxel_size);
    for (f, (mean, max)) in errors.iter().enumerate() {
        eprintln!("frame {f}: leg centers off by {mean:.1} (max {max:.1}) voxels");
    }
    let worst = errors.iter().map(|e| e.1).fold(0.0, Real::max);
    assert!(
        worst < 4.0,
        "a center of the leg strays {worst:.1} voxels from the leg's motion"
    );
    assert!(conv.coverage.flagged.is_empty());
}

/// Each attempt is the conversion its seed gives alone; the result kept is
/// the one warned of the fewest frames (those warned of on evidence of their
/// own first; the first on a tie), and the
/// attempts stop at the first that warns of none.
#[test]
fn the_attempt_warned_of_the_fewest_frames_is_kept() {
    let track = |seed| TrackParams {
        seed,
        ..single_guess(150)
    };
    let conv = convert_attempts("swinging_leg", 48, track(0), 3);
    let seeds: Vec<u64> = conv.attempts.iter().map(|a| a.seed).collect();
    eprintln!("attempts {:?}, kept {}", conv.attempts, conv.kept);
    assert_eq!(seeds, (0..seeds.len() as u64).collect::<Vec<_>>());
    assert!(
        !conv.attempts[0].warned.is_empty(),
        "the paper's single guess kept the leg at seed 0: give this test a placement that loses it"
    );
    for (k, attempt) in conv.attempts.iter().enumerate() {
        let alone = convert_with("swinging_leg", 48, track(attempt.seed));
        assert_eq!(attempt.warned, alone.lost_parts().flagged, "attempt {k}");
        assert_eq!(
            attempt.continued,
            alone.lost_parts().continued,
            "attempt {k}"
        );
        let last = k + 1 == conv.attempts.len();
        assert!(
            last || !attempt.warned.is_empty(),
            "attempt {k} warned of none yet was not the last"
        );
    }
    assert!(conv.attempts.len() == 3 || conv.attempts.last().unwrap().warned.is_empty());
    // Frames warned of on evidence of their own first, then all.
    let key =
        |a: &voltrack::pipeline::Attempt| (a.warned.len() - a.continued.len(), a.warned.len());
    let fewest = conv.attempts.iter().map(key).min().unwrap();
    let first_fewest = conv.attempts.iter().position(|a| key(a) == fewest).unwrap();
    assert_eq!(conv.kept, first_fewest);
    assert_eq!(conv.lost_parts().flagged, conv.attempts[conv.kept].warned);
    assert_eq!(conv.seed(), conv.attempts[conv.kept].seed);
}

/// The bending bar tracks well: no frame is flagged.
#[test]
fn the_detector_is_quiet_on_the_bending_bar() {
    let conv = convert("bending_bar", 64, 200);
    eprintln!(
        "coverage {:?}\nfit p95 {:?}, limit {:.2}",
        conv.coverage.frames, conv.fit_outliers.p95, conv.fit_outliers.limit
    );
    assert!(
        conv.coverage.flagged.is_empty(),
        "{:?}",
        conv.coverage.frames
    );
    assert!(
        conv.coverage
            .frames
            .iter()
            .all(|x| x.lost == 0 && x.farthest < 1.9),
        "{:?}",
        conv.coverage.frames
    );
    assert!(
        conv.fit_outliers.flagged.is_empty(),
        "{:?}",
        conv.fit_outliers
    );
}

#[test]
fn the_fixture_is_closed_and_its_leg_moves_fast() {
    let w = 2.0 * swinging::LEG_RADIUS;
    let steps: Vec<Real> = (1..SWINGING_LEG_FRAMES)
        .map(|f| (swinging::foot(f) - swinging::foot(f - 1)).norm() / w)
        .collect();
    assert!(
        steps.iter().copied().fold(0.0, Real::max) > 4.0,
        "{steps:?}"
    );
    for f in 0..SWINGING_LEG_FRAMES {
        let m = swinging_leg(f);
        // Closed: every edge in exactly two triangles, once each way.
        let mut edges = std::collections::HashMap::new();
        for t in &m.triangles {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        assert!(
            edges
                .iter()
                .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1)),
            "frame {f} is not closed"
        );
    }
    // Re-tessellated: frames differ in their vertex counts.
    assert_ne!(
        swinging_leg(0).positions.len(),
        swinging_leg(1).positions.len()
    );
}

/// The binary on `fixture` in a fresh folder; stdout.
fn voltrack(test: &str, args: &[&str]) -> String {
    let dir = common::Scratch::new("thin-parts", test);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_voltrack"))
        .args(args)
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "voltrack {args:?}:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn convert_warns_after_its_summary_and_the_report_marks_the_frames() {
    let input = fixture("swinging_leg");
    let dir = common::Scratch::new("thin-parts", "report");
    let report = dir.join("report.html");
    // The paper's tracking, which still loses the leg (with the starved
    // leg turned about its hip, even one guess keeps it).
    let args = [
        input.to_str().unwrap(),
        "-r",
        "48",
        "-n",
        "150",
        "--single-guess",
        "--reclaim",
        "off",
        "--attempts",
        "1",
        "-o",
        "out.glb",
        "--report",
        report.to_str().unwrap(),
    ];
    let stdout = voltrack("convert", &[&["convert"][..], &args].concat());
    let wrote = stdout.find("wrote ").expect("summary");
    // The leg is lost from frame 6 on (its centers 10-21 voxels off on
    // average); in frame 5 it is going (3.6 on average, 8 at most), and the
    // input's leg there is far from the result's too.
    let warning = stdout
        .find("warning: frames 5-9: a part of the input's surface lies far from the result")
        .unwrap_or_else(|| panic!("no warning:\n{stdout}"));
    assert!(
        warning > wrote,
        "the warning comes after the summary:\n{stdout}"
    );
    let html = std::fs::read_to_string(&report).unwrap();
    common::assert_well_formed(&html);
    assert!(
        html.contains("Warning: a part may have been lost") && html.contains("Frames 5-9"),
        "no warning in the report"
    );
    assert_eq!(html.matches("<tr class=\"flagged\">").count(), 5);
    // Without a report too: the fit is measured for every mesh output.
    let plain = voltrack(
        "plain",
        &[
            "convert",
            input.to_str().unwrap(),
            "-r",
            "48",
            "-n",
            "150",
            "--single-guess",
            "--reclaim",
            "off",
            "--attempts",
            "1",
            "-o",
            "plain.glb",
        ],
    );
    assert!(
        plain.contains(
            "warning: frames 5-9: a part of the input's surface lies far from the result"
        ),
        "no warning without --report:\n{plain}"
    );
    // The bar is not flagged.
    let bar = fixture("bending_bar");
    let stdout = voltrack(
        "bar",
        &[
            "convert",
            bar.to_str().unwrap(),
            "-r",
            "48",
            "-n",
            "120",
            "-o",
            "bar.glb",
        ],
    );
    assert!(!stdout.contains("warning"), "{stdout}");
}

#[test]
fn track_json_carries_the_coverage_per_frame() {
    let input = fixture("swinging_leg");
    let stdout = voltrack(
        "json",
        &[
            "track",
            input.to_str().unwrap(),
            "-r",
            "48",
            "-n",
            "150",
            "-o",
            "c.exr",
            "--json",
        ],
    );
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let coverage = &v["coverage"];
    assert_eq!(
        coverage["frames"].as_array().map(Vec::len),
        Some(SWINGING_LEG_FRAMES)
    );
    assert!(
        coverage["flagged"].is_array() && coverage["cell_voxels"].as_f64().unwrap() > 0.0,
        "{coverage}"
    );
    for key in [
        "occupied",
        "unreached",
        "lost",
        "lost_percent",
        "largest_region",
        "farthest",
    ] {
        assert!(
            !coverage["frames"][0][key].is_null(),
            "{key} missing: {coverage}"
        );
    }
    assert_eq!(coverage["params"]["reach"], 2.0);
    // Shares in percent, as the far regions' and the fit's.
    let lost = coverage["frames"].as_array().unwrap().iter().map(|f| {
        (
            f["lost"].as_f64().unwrap(),
            f["occupied"].as_f64().unwrap(),
            f["lost_percent"].as_f64().unwrap(),
        )
    });
    for (lost, occupied, percent) in lost {
        assert!(
            (percent - 100.0 * lost / occupied).abs() < 1e-9,
            "{coverage}"
        );
    }
}
