//! The removal's and the global optimisation's parts: accepted steps lower
//! the energy, the most irregular center is the one removed, the kept cells
//! fill their byte budget, kept and fresh cells and gradients in memory or
//! in a file give the same optimisation, and a stop request ends it.

use super::*;
use crate::math::{Point3, Real, Rotation3, Vector3};
use crate::model::Rigid;
use crate::params::TrackParams;
use crate::track::track;

/// The global optimisation's affinity Ω at `p`'s distances, as `refine`
/// computes it.
fn omega_of(
    traj: &Trajectories,
    seq: &VoxelSequence,
    cells: &mut SequenceCells,
    p: &RefineParams,
) -> SparseAffinity {
    let scale = p.length_scale(&seq.bounds);
    global_affinity(traj, seq, cells, p.rho_gp * scale, p.rho_gm * scale, p.mu)
}

/// Two boxes, one still and one sliding away, voxelised on one grid.
fn two_bodies(frames: usize, resolution: usize) -> VoxelSequence {
    let a = crate::fixtures::cube(Point3::new(0.0, 0.0, 0.0), 1.0);
    let b = crate::fixtures::cube(Point3::new(1.6, 0.0, 0.0), 1.0);
    let meshes: Vec<crate::TriangleMesh> = (0..frames)
        .map(|f| {
            let m = Rigid {
                rotation: *Rotation3::new(Vector3::new(0.0, 0.0, 0.05 * f as Real)).matrix(),
                translation: Vector3::new(0.08 * f as Real, 0.0, 0.0),
            };
            let mut moved = b.clone();
            moved.positions.iter_mut().for_each(|p| *p = m.apply(p));
            crate::fixtures::merge(&[a.clone(), moved])
        })
        .collect();
    voxel_sequence(&meshes, resolution)
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

/// A sequence voxelised in memory from one mesh per frame, on the common grid
/// of their bounding box (frame f named `frame{f}.obj`).
fn voxel_sequence(
    meshes: &[crate::TriangleMesh],
    resolution: usize,
) -> crate::voxel::VoxelSequence {
    let bounds = meshes
        .iter()
        .map(|m| m.bounding_box())
        .reduce(|a, b| a.union(&b))
        .unwrap();
    let grid = crate::model::GridSpec::for_bounds(&bounds, resolution).unwrap();
    crate::voxel::VoxelSequence {
        frames: meshes
            .iter()
            .map(|m| crate::voxel::voxelize(m, &grid).into())
            .collect(),
        grid,
        names: (0..meshes.len()).map(|f| format!("frame{f}.obj")).collect(),
        bounds,
        first_mesh: Some(meshes[0].clone()),
        read_seconds: 0.0,
        voxelize_seconds: 0.0,
    }
}

/// Counts its polls and asks to stop from the `after`-th on.
struct StopAfterPolls {
    polls: std::sync::atomic::AtomicUsize,
    after: usize,
}

impl StopAfterPolls {
    fn new(after: usize) -> Self {
        StopAfterPolls {
            polls: 0.into(),
            after,
        }
    }
    fn polls(&self) -> usize {
        self.polls.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl crate::progress::ProgressSink for StopAfterPolls {
    fn report(&self, _: crate::Stage, _: usize, _: usize) {}
    fn cancelled(&self) -> bool {
        self.polls
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            >= self.after
    }
}

#[test]
fn accepted_iterations_lower_the_energy_monotonically() {
    let seq = two_bodies(6, 40);
    let tracked = tracked(&seq, 40);
    let mut traj = tracked.clone();
    let p = RefineParams::default();
    let mut cells = SequenceCells::new(&seq, usize::MAX);
    let omega = omega_of(&traj, &seq, &mut cells, &p);
    let history = optimise(
        &mut traj,
        &seq.grid,
        &mut cells,
        &omega,
        &RefineParams {
            max_iterations: 10,
            ..p.clone()
        },
        |_, _, _| true,
    )
    .unwrap();
    assert!(history.len() >= 2, "at least one step was accepted");
    for w in history.windows(2) {
        assert!(
            w[1].energy < w[0].energy,
            "energy rose: {} -> {}",
            w[0].energy,
            w[1].energy
        );
        assert!((w[1].energy - (w[1].smooth + p.beta_hat * w[1].data)).abs() <= 1e-9 * w[1].energy);
    }
    assert_ne!(traj, tracked);
}

#[test]
fn a_center_jumping_between_bodies_is_removed_first() {
    let seq = two_bodies(6, 40);
    let tracked = tracked(&seq, 40);
    let mut traj: Trajectories = tracked.clone();
    // Center 7 alternates between a center of each body.
    let (on_a, on_b) = {
        let f0 = traj.frame(0);
        let a = (0..traj.centers)
            .min_by(|&i, &j| f0[i].x.total_cmp(&f0[j].x))
            .unwrap();
        let b = (0..traj.centers)
            .max_by(|&i, &j| f0[i].x.total_cmp(&f0[j].x))
            .unwrap();
        (a, b)
    };
    let jumper = (0..traj.centers).find(|&i| i != on_a && i != on_b).unwrap();
    for f in 0..traj.frames {
        let src = if f % 2 == 0 { on_a } else { on_b };
        let p = traj.get(f, src) + Vector3::new(0.0, 0.05, 0.0);
        traj.set(f, jumper, p);
    }
    let irregularity = crate::metrics::irregularity(&traj);
    assert_eq!(most_irregular(&irregularity, 1), vec![jumper]);
    let res = refine(
        traj.clone(),
        &seq,
        &RefineParams {
            remove: Some(1),
            batches: 1,
            ..Default::default()
        },
        Default::default(),
    )
    .unwrap();
    assert_eq!(res.trajectories.centers, traj.centers - 1);
    let res = res.refinement;
    assert_eq!(res.removed, vec![jumper]);
    assert!(!res.kept.contains(&jumper));
    assert!(res.batches[0].len() >= 2);
}

/// The kept assignments fill the byte budget from the first frame on, at
/// most [`KEPT_CELL_FRAMES`] frames: none under one frame's bytes, as many
/// frames as fit, every frame of a short sequence for an unbounded budget.
#[test]
fn kept_assignments_fill_the_byte_budget() {
    use crate::params::{KEPT_CELL_BYTES_PER_VOXEL, KEPT_CELL_FRAMES};
    let seq = two_bodies(7, 40);
    let bytes: Vec<usize> = seq
        .frames
        .iter()
        .map(|f| f.len() * KEPT_CELL_BYTES_PER_VOXEL)
        .collect();
    let first_three: usize = bytes[..3].iter().sum();
    for (budget, kept) in [
        (0, 0),
        (bytes[0] - 1, 0),
        (bytes[0], 1),
        (first_three, 3),
        (first_three + bytes[3] - 1, 3),
        (usize::MAX, 7.min(KEPT_CELL_FRAMES)),
    ] {
        assert_eq!(
            SequenceCells::new(&seq, budget).cached_frames(),
            kept,
            "budget {budget} bytes (frames of {bytes:?} bytes)"
        );
    }
}

/// The global optimisation keeps the assignments of only some frames between
/// updates, and its gradients in memory only up to a size, so that memory
/// does not grow with the sequence; the other frames are assigned afresh and
/// the gradients go to a temporary file. Every way must give the same cells
/// at every step, and so the same optimised trajectories, bit for bit.
#[test]
fn kept_and_fresh_assignments_and_gradients_in_a_file_give_the_same_optimisation() {
    let seq = two_bodies(7, 40);
    let tracked = tracked(&seq, 40);
    let p = RefineParams::default();
    let run = |kept: usize, memory: usize| {
        let mut traj = tracked.clone();
        let mut cells = SequenceCells::with_cache(&seq, kept);
        assert_eq!(cells.cached_frames(), kept.min(7));
        let mut energies = Vec::new();
        let mut omega = None;
        // Two batches, with centers removed between them as the refinement
        // does: the kept assignments drop them and keep their bounds for the rest.
        for batch in 0..2 {
            if batch > 0 {
                let survivors = traj.remove_centers(&[3, 17, 30]);
                cells.keep_centers(&survivors);
            }
            let w = omega_of(&traj, &seq, &mut cells, &p);
            let history = optimise(
                &mut traj,
                &seq.grid,
                &mut cells,
                &w,
                &RefineParams {
                    max_iterations: 8,
                    memory,
                    ..p.clone()
                },
                |_, _, _| true,
            )
            .unwrap();
            energies.extend(history.iter().map(|h| h.energy.to_bits()));
            omega.get_or_insert(w);
        }
        (traj, omega.expect("two batches"), energies)
    };
    let all = run(usize::MAX, usize::MAX);
    assert!(
        all.2.len() >= 6,
        "some steps were accepted in both batches: {:?}",
        all.2
    );
    for (kept, memory) in [
        (0, usize::MAX),
        (1, usize::MAX),
        (4, usize::MAX),
        (usize::MAX, 0),
        (1, 0),
    ] {
        let some = run(kept, memory);
        assert_eq!(some.1, all.1, "affinity with {kept} frames kept");
        assert_eq!(
            some.2, all.2,
            "energies with {kept} frames kept, gradients in memory up to {memory} bytes"
        );
        assert_eq!(
            some.0, all.0,
            "trajectories with {kept} frames kept, gradients in memory up to {memory} bytes"
        );
    }
}

#[test]
fn a_stop_request_ends_the_optimisation_within_an_evaluation_and_keeps_accepted_steps() {
    let seq = two_bodies(6, 40);
    let tracked = tracked(&seq, 40);
    let p = RefineParams {
        max_iterations: 10,
        ..Default::default()
    };
    let run = |after: usize| {
        let sink = StopAfterPolls::new(after);
        let mut traj = tracked.clone();
        let mut cells =
            SequenceCells::new(&seq, usize::MAX).stopping_with(crate::Progress(Some(&sink)));
        let omega = omega_of(&traj, &seq, &mut cells, &p);
        let mut accepted = Vec::new();
        let history = optimise(&mut traj, &seq.grid, &mut cells, &omega, &p, |_, now, _| {
            accepted = now.positions.clone();
            true
        })
        .unwrap();
        (traj, history, accepted, sink.polls())
    };
    // Stopped at once: nothing evaluated, the trajectories untouched.
    let (traj, history, _, _) = run(0);
    assert!(history.is_empty());
    assert_eq!(traj.positions, tracked.positions);
    // Stopped part way: the trajectories are those of the last accepted step.
    let (full, full_history, _, asked) = run(usize::MAX);
    let (traj, history, accepted, _) = run(asked / 2);
    assert!(
        history.len() < full_history.len(),
        "{} steps of {}",
        history.len(),
        full_history.len()
    );
    if history.len() > 1 {
        assert_eq!(traj.positions, accepted);
    } else {
        assert_eq!(traj.positions, tracked.positions);
    }
    assert_ne!(full.positions, tracked.positions);
}
