//! Forward tracking, frame by frame (docs/method.md §3): extrapolate, presmooth
//! with rigid predictions, then alternate Voronoi centroids and rigid
//! predictions until no center moves more than the threshold.
//!
//! Beyond the paper, each frame is tracked from several guesses (see
//! [`TrackParams::damped_guess`] and [`TrackParams::accelerated_guess`]);
//! their runs are compared region by region and the best of each region
//! combined (see [`Tracker::track_frame`]).

use super::affinity::Affinity;
use super::checkpoint::{self, Checkpointing, Restored, Snapshot};
use super::lloyd::seed_centers_until;
use super::{FrameTiming, Guess};
use crate::error::{Error, Result, Saved};
use crate::math::{Point3, Real};
use crate::model::{GridSpec, Rigid, RigidFits, Trajectories};
use crate::params::TrackParams;
use crate::progress::{Progress, Stage};
use crate::spatial::cells::{
    assign, carry_owners, Assignment, CellMoments, CellStats, CenterIndex, NO_OWNER,
};
use crate::voxel::VoxelSequence;
use rayon::prelude::*;
use std::time::Instant;

impl FrameTiming {
    /// Adds the parts of a dropped run of the same frame.
    fn add_dropped(&mut self, dropped: &FrameTiming) {
        self.assign += dropped.assign;
        self.fit += dropped.fit;
        self.affinity += dropped.affinity;
        self.dropped_iterations += dropped.iterations;
    }
}

/// One frame tracked from one guess.
struct FrameResult {
    centers: Vec<Point3>,
    counts: Vec<u32>,
    timing: FrameTiming,
    /// E = Es + β Eu at the final positions (docs/method.md §3).
    energy: Real,
}

/// The tracker's result.
#[derive(Clone, Debug)]
pub struct TrackResult {
    /// Every center's position in every frame.
    pub trajectories: Trajectories,
    /// Occupied voxels per Voronoi cell at the final positions, per frame (for DFU).
    pub cell_counts: Vec<Vec<u32>>,
    /// Frame 0 is the Lloyd placement.
    pub timings: Vec<FrameTiming>,
    /// Lengths in the input's units: ρ_p, ρ_m, threshold after scaling.
    pub scale: Real,
    /// The frame the centers were placed in and why
    /// (`trajectories.reference` is its frame).
    pub reference: super::ReferenceChoice,
}

/// The state the tracker carries from one frame to the next.
struct Tracker<'a> {
    grid: &'a GridSpec,
    params: &'a TrackParams,
    threshold2: Real,
    affinity: Affinity,
    /// The previous frame's voxels.
    prev_voxels: std::sync::Arc<[u32]>,
    /// Their cells at the previous frame's centers: owners, and bounds
    /// unless that frame is frame 0 or the one a resumed run starts after.
    prev_cells: Assignment,
    /// The index over the previous frame's centers, which `prev_cells`'
    /// bounds were measured against.
    prev_index: CenterIndex,
    /// Each cell's frame-0 volume and reach, for starved cells' claims.
    capacity: Option<super::claims::Capacity>,
}

/// Tracks `params.centers` centers through every frame of `seq`.
pub fn track(seq: &VoxelSequence, params: &TrackParams, progress: Progress) -> Result<TrackResult> {
    track_with_checkpoints(seq, params, None, progress)
}

/// [`track`], saving its state to `checkpoint` every few frames, when
/// cancelled through `progress` (then returning [`Error::Interrupted`]) and at
/// the end; with `checkpoint.resume` it continues from the saved state. The
/// result is bit-identical to an uninterrupted [`track`].
///
/// The centers are placed in the reference frame `params.reference` chooses
/// ([`super::choose_reference`]) and tracked from it to the last frame, then
/// from it back to the first; with checkpoints the reference is frame 0.
pub fn track_with_checkpoints(
    seq: &VoxelSequence,
    params: &TrackParams,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
) -> Result<TrackResult> {
    params.validate()?;
    if checkpoint.is_some_and(|c| c.every == 0) {
        return Err(Error::InvalidParameter(
            "the checkpoint interval must be at least 1 frame".into(),
        ));
    }
    let choice = super::choose_reference(seq, params, checkpoint.is_some())?;
    let frames = seq.frames.len();
    let r = choice.frame;
    if r == 0 {
        let order: Vec<usize> = (0..frames).collect();
        let mut result = track_ordered(seq, &order, params, checkpoint, progress, 0, None)?;
        result.reference = choice;
        return Ok(result);
    }
    log::info!(
        "tracking from frame {r} ({}) forward, then back to frame 0",
        seq.names[r]
    );
    let forward: Vec<usize> = (r..frames).collect();
    let backward: Vec<usize> = (0..=r).rev().collect();
    // One placement for both ways.
    room_for_centers(seq, r, params)?;
    let scale = params.length_scale(&seq.bounds);
    let placed = first_frame(seq, &forward, params, scale, None, progress)?;
    let placed_back = placed.for_frames(backward.len());
    let ahead = track_ordered(seq, &forward, params, None, progress, 0, Some(placed))?;
    let behind = track_ordered(
        seq,
        &backward,
        params,
        None,
        progress,
        forward.len() - 1,
        Some(placed_back),
    )?;
    let n = params.centers;
    let mut trajectories = Trajectories::new(frames, n);
    trajectories.reference = r;
    let (mut cell_counts, mut timings) = (Vec::with_capacity(frames), Vec::with_capacity(frames));
    for (k, &f) in backward.iter().enumerate().rev().filter(|&(k, _)| k > 0) {
        trajectories
            .frame_mut(f)
            .copy_from_slice(behind.trajectories.frame(k));
        cell_counts.push(behind.cell_counts[k].clone());
        timings.push(behind.timings[k]);
    }
    for (k, &f) in forward.iter().enumerate() {
        trajectories
            .frame_mut(f)
            .copy_from_slice(ahead.trajectories.frame(k));
        cell_counts.push(ahead.cell_counts[k].clone());
        timings.push(ahead.timings[k]);
    }
    Ok(TrackResult {
        trajectories,
        cell_counts,
        timings,
        scale: ahead.scale,
        reference: choice,
    })
}

/// Whether frame `placed` of `seq` has an occupied voxel for every center.
fn room_for_centers(seq: &VoxelSequence, placed: usize, params: &TrackParams) -> Result<()> {
    let n0 = seq.frames[placed].len();
    if params.centers > n0 {
        return Err(Error::InvalidParameter(format!(
            "{}: only {n0} occupied voxels for {} centers; lower the number of centers or raise the resolution",
            seq.names[placed],
            params.centers
        )));
    }
    Ok(())
}

/// Tracks through the frames `order` (indices into `seq`, each next to the
/// one before): the centers are placed in `order[0]`, unless `placed_already`
/// holds that placement. Progress counts on from `done_before` frames of
/// `seq.frames.len()`.
fn track_ordered(
    seq: &VoxelSequence,
    order: &[usize],
    params: &TrackParams,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
    done_before: usize,
    placed_already: Option<Restored>,
) -> Result<TrackResult> {
    let (frames, total) = (order.len(), seq.frames.len());
    let placed = order[0];
    room_for_centers(seq, placed, params)?;
    debug_assert!(checkpoint.is_none() || order.iter().enumerate().all(|(k, &f)| k == f));
    // The checkpoint with the fingerprint its files carry.
    let fingerprinted = checkpoint.map(|c| (c, checkpoint::fingerprint(seq, params)));
    let scale = params.length_scale(&seq.bounds);
    let grid = &seq.grid;
    progress.report(Stage::Track, done_before, total);

    let (started, resume) = starting_state(
        seq,
        order,
        params,
        scale,
        fingerprinted,
        progress,
        placed_already,
    )?;
    let Restored {
        frames_done: first,
        trajectories: mut traj,
        mut cell_counts,
        mut timings,
        affinity,
        owners,
    } = started;
    progress.report(Stage::Track, done_before + first, total);

    let prev_voxels: std::sync::Arc<[u32]> = seq.frames[order[first - 1]].indices().into();
    let capacity = params
        .reclaim
        .then(|| super::claims::Capacity::of_first_frame(seq, placed, traj.frame(0)));
    let mut tracker = Tracker {
        capacity,
        grid,
        params,
        threshold2: (params.threshold * scale).powi(2),
        affinity,
        prev_cells: Assignment::new(grid, &prev_voxels, owners),
        prev_index: CenterIndex::new(traj.frame(first - 1)),
        prev_voxels,
    };
    // Frames held by the checkpoint file.
    let mut saved = if resume { first } else { 0 };
    let save = |tracker: &Tracker,
                traj: &Trajectories,
                cell_counts: &[Vec<u32>],
                timings: &[FrameTiming]|
     -> Result<()> {
        match fingerprinted {
            Some((c, fp)) => save_tracking(c, fp, tracker, traj, cell_counts, timings),
            None => Ok(()),
        }
    };
    for (f, &at) in order.iter().enumerate().skip(first) {
        let start = Instant::now();
        let voxels: std::sync::Arc<[u32]> = seq.frames[at].indices().into();
        let (prev, voxels) = (traj.frame(f - 1), &voxels);
        let fits = tracker.fits(prev);
        let kept = tracker.track_frame(prev, guesses(&traj, f, params), &fits, voxels, progress);
        let Some(FrameResult {
            centers,
            counts,
            mut timing,
            energy,
        }) = kept
        else {
            // Frame f was abandoned; the state is still that after frame f - 1.
            if saved < f {
                save(&tracker, &traj, &cell_counts, &timings)?;
            }
            return Err(Error::Interrupted {
                saved: checkpoint.map(|c| Saved {
                    path: c.path(),
                    frames: f,
                    refine: None,
                }),
            });
        };
        timing.total = start.elapsed().as_secs_f64();
        traj.frame_mut(f).copy_from_slice(&centers);
        cell_counts.push(counts);
        log::debug!(
            "frame {at}: {:?} guess kept, {} iterations, energy {energy:.4e}, {:.3} s",
            timing.kept_guess,
            timing.iterations,
            timing.total
        );
        timings.push(timing);
        progress.report(Stage::Track, done_before + f + 1, total);
        if checkpoint.is_some_and(|c| (f + 1) % c.every == 0 || f + 1 == frames) {
            save(&tracker, &traj, &cell_counts, &timings)?;
            saved = f + 1;
        }
    }
    Ok(TrackResult {
        trajectories: traj,
        cell_counts,
        timings,
        scale,
        reference: Default::default(),
    })
}

/// Where tracking starts: `placed_already`, else the checkpoint when asked
/// to resume from one that exists (which must match the fingerprint beside
/// it), else a fresh start ([`first_frame`]); and whether it resumed.
fn starting_state(
    seq: &VoxelSequence,
    order: &[usize],
    params: &TrackParams,
    scale: Real,
    fingerprinted: Option<(&Checkpointing, u64)>,
    progress: Progress,
    placed_already: Option<Restored>,
) -> Result<(Restored, bool)> {
    let checkpoint = fingerprinted.map(|(c, _)| c);
    let resume = match fingerprinted {
        Some((c, fp)) if c.resume && c.path().exists() => Some((c, fp)),
        Some((c, _)) if c.resume => {
            // So that one command line can be rerun until it completes.
            log::warn!(
                "no checkpoint in {} yet: tracking starts from the first frame",
                c.dir.display()
            );
            None
        }
        _ => None,
    };
    let started = match (placed_already, resume) {
        (Some(placed), _) => placed,
        (None, Some((c, fingerprint))) => {
            let r = checkpoint::load(c, fingerprint, seq, params)?;
            log::info!(
                "resuming from {} after {} of {} frames",
                c.path().display(),
                r.frames_done,
                order.len()
            );
            r
        }
        (None, None) => first_frame(seq, order, params, scale, checkpoint, progress)?,
    };
    Ok((started, resume.is_some()))
}

/// Saves the tracking after its first `cell_counts.len()` frames into
/// checkpoint `c`, fingerprinted `fingerprint`.
fn save_tracking(
    c: &Checkpointing,
    fingerprint: u64,
    tracker: &Tracker,
    traj: &Trajectories,
    cell_counts: &[Vec<u32>],
    timings: &[FrameTiming],
) -> Result<()> {
    let frames_done = cell_counts.len();
    let snapshot = Snapshot {
        frames_done,
        trajectories: traj,
        cell_counts,
        timings,
        affinity: &tracker.affinity,
        owners: &tracker.prev_cells.owners,
    };
    checkpoint::save(c, fingerprint, &snapshot)?;
    log::debug!(
        "checkpoint: {frames_done} frames saved in {}",
        c.path().display()
    );
    Ok(())
}

/// A fresh start: the centers placed in frame `order[0]` (Lloyd), their
/// cells, the first affinity; a refinement checkpoint of an earlier run is
/// removed, since it refined tracking this run starts over.
fn first_frame(
    seq: &VoxelSequence,
    order: &[usize],
    params: &TrackParams,
    scale: Real,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
) -> Result<Restored> {
    let (grid, frames) = (&seq.grid, order.len());
    if let Some(stale) = checkpoint.map(|c| c.refine_path()).filter(|p| p.exists()) {
        // It refined the tracking this run starts over, not this run's.
        log::info!("tracking starts over: removing {}", stale.display());
        std::fs::remove_file(&stale).map_err(|e| Error::io(&stale, e))?;
    }
    let start = Instant::now();
    let voxels0 = &seq.frames[order[0]].indices();
    let placed = seed_centers_until(
        grid,
        voxels0,
        params.centers,
        params.seed,
        params.lloyd_iterations,
        params.over_relaxation,
        params.threshold * scale,
        &|| progress.cancelled(),
    );
    // Nothing to save yet.
    let (centers0, lloyd_steps) = placed.ok_or(Error::Interrupted { saved: None })?;
    let mut traj = Trajectories::new(frames, params.centers);
    traj.frame_mut(0).copy_from_slice(&centers0);
    let mut owners = vec![NO_OWNER; voxels0.len()];
    let stats0 = assign(
        grid,
        voxels0,
        &CenterIndex::new(&centers0),
        &mut owners,
        false,
    );
    let reach = super::rho_p(params, seq, order[0], scale);
    let affinity = Affinity::initial(
        &centers0,
        params.affinity,
        reach,
        params.rho_m * scale,
        params.alpha,
        params.mu,
    );
    let timing = FrameTiming {
        total: start.elapsed().as_secs_f64(),
        iterations: lloyd_steps,
        ..Default::default()
    };
    log::info!(
        "frame {}: {} centers placed; ρ_p {reach:.4}, {:.1} neighbours each",
        order[0],
        params.centers,
        affinity.mean_neighbors()
    );
    Ok(Restored {
        frames_done: 1,
        trajectories: traj,
        cell_counts: vec![stats0.count],
        timings: vec![timing],
        affinity,
        owners,
    })
}

/// The starts of frame `f` (from 1): the paper's constant-velocity guess
/// c^{f-1} + v with v = c^{f-1} − c^{f-2} (c^0 itself in frame 1), the damped
/// guess c^{f-1} + k v from frame 2, and the accelerated guess
/// c^{f-1} + v + (v − v') with v' = c^{f-2} − c^{f-3} from frame 3, as
/// `params` asks for them.
fn guesses(traj: &Trajectories, f: usize, params: &TrackParams) -> Vec<(Guess, Vec<Point3>)> {
    let prev = traj.frame(f - 1);
    if f == 1 {
        return vec![(Guess::ConstantVelocity, prev.to_vec())];
    }
    let before = traj.frame(f - 2);
    let extrapolate = |k: Real| -> Vec<Point3> {
        prev.iter()
            .zip(before)
            .map(|(a, b)| a + (a - b) * k)
            .collect()
    };
    let mut starts = vec![(Guess::ConstantVelocity, extrapolate(1.0))];
    if let Some(k) = params.damped_guess {
        starts.push((Guess::Damped, extrapolate(k)));
    }
    if params.accelerated_guess && f >= 3 {
        let accelerated = prev
            .iter()
            .zip(before)
            .zip(traj.frame(f - 3))
            .map(|((a, b), c)| a + (a - b) * 2.0 - (b - c))
            .collect();
        starts.push((Guess::Accelerated, accelerated));
    }
    starts
}

/// Most rounds of turning starved parts toward the volume they lost, per frame.
const MAX_RECLAIMS: usize = 3;

/// A round of reclaiming is kept when it leaves less than this share of the
/// volume no kept cell carries.
const RECLAIM_GAIN: Real = 0.8;

/// One run of a frame's iterations from one guess.
#[derive(Clone)]
struct Run {
    cur: Vec<Point3>,
    cells: Assignment,
    /// How far each center moved in the last iteration (empty before the first).
    moved: Vec<Real>,
    index: CenterIndex,
    timing: FrameTiming,
    converged: bool,
    /// Whether `cells` are blocks of voxels ([`TrackParams::screening_block`]).
    blocks: bool,
}

impl<'a> Tracker<'a> {
    /// The rigid fits from frame f-1: its centers and the weights are fixed for the whole frame.
    fn fits(&self, prev: &[Point3]) -> RigidFits {
        RigidFits::new(prev, prev.len(), |i| self.affinity.pairs(i))
    }

    /// `presmooth_steps` of presmoothing from the guess `cur`, and the cells
    /// carried over from frame f-1: of blocks of `block`³ voxels when
    /// `block` > 1.
    fn start(
        &self,
        prev: &[Point3],
        mut cur: Vec<Point3>,
        fits: &RigidFits,
        voxels: &[u32],
        presmooth_steps: usize,
        block: usize,
    ) -> Run {
        let mut timing = FrameTiming::default();
        let clock = Instant::now();
        for _ in 0..presmooth_steps {
            cur = predict(&fits.fit(&cur), prev);
        }
        timing.fit += clock.elapsed().as_secs_f64();
        let (cells, index, moved) = if block > 1 {
            (
                Assignment::blocks(self.grid, voxels, &self.carried_owners(voxels), block),
                CenterIndex::new(&cur),
                Vec::new(),
            )
        } else {
            // Frame f-1's bounds, loosened in the first iteration by how far
            // each center is from where they were measured: a voxel that
            // stays occupied and whose centers moved little needs no search.
            let moved = cur.iter().zip(prev).map(|(c, p)| (c - p).norm()).collect();
            (
                Assignment::carried(self.grid, voxels, &self.prev_voxels, &self.prev_cells),
                self.prev_index.clone(),
                moved,
            )
        };
        Run {
            cur,
            cells,
            moved,
            index,
            timing,
            converged: false,
            blocks: block > 1,
        }
    }

    /// Frame f-1's owners carried over to `voxels` as hints.
    fn carried_owners(&self, voxels: &[u32]) -> Vec<u32> {
        carry_owners(&self.prev_voxels, &self.prev_cells.owners, voxels)
    }

    /// Iterates `run` until no center's update is as long as the square
    /// root of `threshold2`, or the iteration limit. None when `progress`
    /// asks to stop.
    ///
    /// Toward the tracker's own threshold (not the guesses' screening, unless
    /// on blocks), the run also stops by [`TrackParams::convergence_window`]: once no center
    /// has moved `window` × the threshold over the last `window` iterations,
    /// it takes the state among those whose largest update was the shortest.
    /// In the screening it stops once no more than
    /// [`TrackParams::screening_unsettled`] of the centers' updates are that long.
    fn iterate(
        &self,
        run: &mut Run,
        prev: &[Point3],
        fits: &RigidFits,
        threshold2: Real,
        progress: Progress,
    ) -> Option<()> {
        let limit = self.params.max_iterations;
        let (beta, omega) = (self.params.beta, self.params.tracking_over_relaxation);
        // Blocks jitter more than voxels (one changing owner moves a
        // centroid several times as far), so they need the window too.
        let screening = threshold2 > self.threshold2;
        let window = if screening && !run.blocks {
            1
        } else {
            self.params.convergence_window
        };
        // The screening compares regions: a few centers still creeping along
        // need not hold it up ([`TrackParams::screening_unsettled`]).
        let unsettled = if screening {
            (self.params.screening_unsettled * run.cur.len() as Real) as usize
        } else {
            0
        };
        let mut recent = Recent::new(window);
        let Run {
            cur,
            cells,
            moved,
            index,
            timing: t,
            converged,
            ..
        } = run;
        while !*converged && t.iterations < limit {
            if progress.cancelled() {
                return None;
            }
            t.iterations += 1;
            let clock = Instant::now();
            if !moved.is_empty() {
                *index = std::mem::replace(index, CenterIndex::new(&[])).moved_to(cur, moved);
            }
            let stats = cells.update(index, moved, false);
            t.assign += clock.elapsed().as_secs_f64();
            let clock = Instant::now();
            let motions = fits.fit(cur);
            t.fit += clock.elapsed().as_secs_f64();
            moved.clear();
            recent.push(cur);
            // The residual G(c) − c of the paper's update G(c) = (p + β x̄) / (1 + β)
            // decides convergence whatever the step taken along it.
            let (mut residual_most, mut unsettled_now): (Real, usize) = (0.0, 0);
            for (i, c) in cur.iter_mut().enumerate() {
                let p = motions[i].apply(&prev[i]);
                let x = stats.centroid(i, self.grid).unwrap_or(p);
                let residual = Point3::from((p.coords + x.coords * beta) / (1.0 + beta)) - *c;
                residual_most = residual_most.max(residual.norm());
                unsettled_now += (residual.norm_squared() >= threshold2) as usize;
                let step = residual * omega;
                moved.push(step.norm());
                *c += step;
            }
            if t.iterations % 100 == 0 {
                let over = moved.iter().filter(|&&m| m * m >= threshold2).count();
                log::debug!("iteration {}: {over} centers move more than the threshold, largest residual {residual_most:.2e}", t.iterations);
            }
            recent.set_largest_update(residual_most);
            *converged = residual_most * residual_most < threshold2
                || (unsettled > 0 && unsettled_now <= unsettled);
            if !*converged && recent.settled(cur, threshold2) {
                recent.take_steadiest(cur, moved);
                *converged = true;
            }
        }
        Some(())
    }

    /// The frame's cells and motions at the final positions; they feed the
    /// affinity, which is updated, and the tracker moves on to this frame.
    fn finish(
        &mut self,
        run: Run,
        prev: &[Point3],
        fits: &RigidFits,
        voxels: &std::sync::Arc<[u32]>,
    ) -> FrameResult {
        let Run {
            cur,
            mut cells,
            moved,
            index,
            mut timing,
            ..
        } = run;
        let clock = Instant::now();
        let index = index.moved_to(&cur, &moved);
        let stats = cells.update(&index, &moved, true);
        timing.assign += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        let motions = fits.fit(&cur);
        let energy = energy(
            &cur,
            &predict(&motions, prev),
            &stats,
            self.grid,
            self.params.beta,
        );
        self.affinity
            .update(&cur, &motions, &cell_moments(&stats, self.grid));
        timing.affinity += clock.elapsed().as_secs_f64();
        self.prev_cells = cells;
        self.prev_index = index;
        self.prev_voxels = voxels.clone();
        FrameResult {
            centers: cur,
            counts: stats.count,
            timing,
            energy,
        }
    }

    /// Turns the starved parts of a converged run toward the volume no kept
    /// cell carries (see `track::claims`) and iterates again, as long as
    /// that leaves clearly less of that volume.
    fn reclaim(
        &self,
        mut run: Run,
        prev: &[Point3],
        fits: &RigidFits,
        progress: Progress,
    ) -> Option<Run> {
        let Some(capacity) = &self.capacity else {
            return Some(run);
        };
        // The starved centers and the volume no kept cell carries, of the
        // run kept so far: a kept round's are those its check measured.
        let stats = self.refresh(&mut run);
        let mut starved = capacity.starved(&stats, run.cells.owners.len());
        if !starved.contains(&true) {
            return Some(run);
        }
        let mut uncarried = self.uncarried(&run.cur, &starved, fits, &run.cells);
        for _ in 0..MAX_RECLAIMS {
            if !starved.contains(&true) {
                break;
            }
            let claims =
                capacity.claims(&run.cur, &starved, &uncarried, |i| self.affinity.pairs(i));
            if claims.is_empty() {
                break;
            }
            let mut trial = run.clone();
            for &(i, x) in &claims {
                trial.cur[i] = x;
            }
            trial.moved = trial
                .cur
                .iter()
                .zip(&run.cur)
                .map(|(a, b)| (a - b).norm())
                .collect();
            trial.converged = false;
            self.iterate(&mut trial, prev, fits, self.threshold2, progress)?;
            let stats = self.refresh(&mut trial);
            let starved_after = capacity.starved(&stats, trial.cells.owners.len());
            let after = self.uncarried(&trial.cur, &starved_after, fits, &trial.cells);
            log::debug!(
                "reclaim: {} starved centers turned, uncarried voxels {} -> {}",
                claims.len(),
                uncarried.len(),
                after.len()
            );
            run.timing.add_dropped(&FrameTiming {
                iterations: trial.timing.iterations - run.timing.iterations,
                ..Default::default()
            });
            if (after.len() as Real) < RECLAIM_GAIN * uncarried.len() as Real {
                (run, starved, uncarried) = (trial, starved_after, after);
            } else {
                break;
            }
        }
        Some(run)
    }

    /// The voxels of this frame (`cells`') that no kept center carries
    /// there: frame f-1's cells of the centers not `starved`, each voxel
    /// moved by its center's rigid motion to `cur` (and grown by a voxel
    /// each way, which a turned cell leaves between its voxels).
    fn uncarried(
        &self,
        cur: &[Point3],
        starved: &[bool],
        fits: &RigidFits,
        cells: &Assignment,
    ) -> Vec<Point3> {
        let Some(coords) = cells.voxel_coords() else {
            return Vec::new();
        };
        let motions = fits.fit(cur);
        let grid = self.grid;
        let mut carried = vec![0u64; grid.len().div_ceil(64)];
        let dims = grid.dims;
        for (&v, &o) in self.prev_voxels.iter().zip(&self.prev_cells.owners) {
            if o == NO_OWNER || starved[o as usize] {
                continue;
            }
            let p = motions[o as usize].apply(&grid.voxel_center(v as usize));
            let Some(q) = grid.voxel_at(&p) else {
                continue;
            };
            let [x, y, z] = grid.voxel_coords(q);
            for (dx, dy, dz) in [
                (0i64, 0i64, 0i64),
                (1, 0, 0),
                (-1, 0, 0),
                (0, 1, 0),
                (0, -1, 0),
                (0, 0, 1),
                (0, 0, -1),
            ] {
                let c = [x as i64 + dx, y as i64 + dy, z as i64 + dz];
                if c.iter().zip(dims).all(|(&a, d)| a >= 0 && a < d as i64) {
                    let q = grid.linear_index(c.map(|a| a as usize));
                    carried[q / 64] |= 1 << (q % 64);
                }
            }
        }
        coords
            .iter()
            .map(|c| c.map(usize::from))
            .filter(|&c| {
                let q = grid.linear_index(c);
                carried[q / 64] & (1 << (q % 64)) == 0
            })
            .map(|c| grid.center_at(c))
            .collect()
    }

    /// Brings a run's cells up to its positions and returns their sums.
    fn refresh(&self, run: &mut Run) -> CellStats {
        let Run {
            cur,
            cells,
            moved,
            index,
            ..
        } = run;
        if !moved.is_empty() {
            *index = std::mem::replace(index, CenterIndex::new(&[])).moved_to(cur, moved);
        }
        let stats = cells.update(index, moved, false);
        moved.clear();
        moved.resize(cur.len(), 0.0);
        stats
    }

    /// Each center's term of E at `run`'s positions ([`center_energies`]).
    /// Brings the run's cells up to those positions.
    fn local_energies(&self, run: &mut Run, prev: &[Point3], fits: &RigidFits) -> Vec<Real> {
        let Run {
            cur,
            cells,
            moved,
            index,
            timing,
            ..
        } = run;
        let clock = Instant::now();
        if !moved.is_empty() {
            *index = std::mem::replace(index, CenterIndex::new(&[])).moved_to(cur, moved);
        }
        let stats = cells.update(index, moved, false);
        timing.assign += clock.elapsed().as_secs_f64();
        // The cells and the index are now those of `cur`.
        moved.clear();
        moved.resize(cur.len(), 0.0);
        let clock = Instant::now();
        let predictions = predict(&fits.fit(cur), prev);
        timing.fit += clock.elapsed().as_secs_f64();
        center_energies(cur, &predictions, &stats, self.grid, self.params.beta)
    }

    /// One frame from `guesses` (at least one). None when `progress` asks to
    /// stop; the state is then left as it was. The caller times the whole
    /// frame.
    ///
    /// One guess runs to convergence. Several run side by side until their
    /// updates are below `guess_screening` times the threshold; then each
    /// center takes the run whose energy summed over its neighbourhood
    /// (weighted by affinity) is lowest, and where that mixes runs, the
    /// combination runs as well. The run with the lowest energy goes on to
    /// the threshold. Why region by region: a galloping animal's front legs
    /// may turn back while its hind legs keep their speed, so no one guess
    /// suits the whole frame, and the frame's energy would hand one leg's
    /// failure to the run that got the other leg right. Why screen early:
    /// the last stretch to the threshold, a slow creep, takes most of a
    /// run's iterations (docs/measurements.md), and only the kept run needs
    /// it.
    fn track_frame(
        &mut self,
        prev: &[Point3],
        guesses: Vec<(Guess, Vec<Point3>)>,
        fits: &RigidFits,
        voxels: &std::sync::Arc<[u32]>,
        progress: Progress,
    ) -> Option<FrameResult> {
        let this = &*self;
        let presmooth = self.params.presmooth_steps;
        let fine = self.threshold2;
        if guesses.len() == 1 {
            let (guess, start) = guesses.into_iter().next().expect("one guess");
            let mut run = self.start(prev, start, fits, voxels, presmooth, 1);
            self.iterate(&mut run, prev, fits, fine, progress)?;
            let run = self.reclaim(run, prev, fits, progress)?;
            let mut result = self.finish(run, prev, fits, voxels);
            result.timing.kept_guess = guess;
            return Some(result);
        }
        let coarse = fine * self.params.guess_screening.powi(2);
        let block = self.params.screening_block;
        // Each run is parallel inside, but not evenly: running them at once fills the cores.
        let mut runs: Vec<(Guess, Run, Vec<Real>)> = guesses
            .into_par_iter()
            .map(|(guess, start)| {
                let mut run = this.start(prev, start, fits, voxels, presmooth, block);
                this.iterate(&mut run, prev, fits, coarse, progress)?;
                let energies = this.local_energies(&mut run, prev, fits);
                Some((guess, run, energies))
            })
            .collect::<Option<_>>()?;
        let choice: Vec<usize> = (0..prev.len())
            .into_par_iter()
            .map(|i| {
                let around = |r: usize| {
                    this.affinity
                        .pairs(i)
                        .map(|(j, w)| w * runs[r].2[j])
                        .sum::<Real>()
                };
                lowest((0..runs.len()).map(around))
            })
            .collect();
        if choice.iter().any(|&r| r != choice[0]) {
            // Already through presmoothing: it would blur the seams' choice.
            let mixed: Vec<Point3> = choice
                .iter()
                .enumerate()
                .map(|(i, &r)| runs[r].1.cur[i])
                .collect();
            // From the cells of the run most centers chose, which hold for
            // its positions: only the centers taken from other runs have
            // moved, so few voxels need a search.
            let mut chosen = vec![0usize; runs.len()];
            choice.iter().for_each(|&r| chosen[r] += 1);
            let majority = (0..runs.len())
                .max_by_key(|&r| (chosen[r], std::cmp::Reverse(r)))
                .expect("several runs");
            let base = &runs[majority].1;
            let moved = mixed
                .iter()
                .zip(&base.cur)
                .map(|(a, b)| (a - b).norm())
                .collect();
            let mut run = Run {
                cur: mixed,
                cells: base.cells.clone(),
                moved,
                index: base.index.clone(),
                timing: FrameTiming::default(),
                converged: false,
                blocks: base.blocks,
            };
            this.iterate(&mut run, prev, fits, coarse, progress)?;
            let energies = this.local_energies(&mut run, prev, fits);
            runs.push((Guess::Mixed, run, energies));
        }
        let best = lowest(runs.iter().map(|r| r.2.iter().sum::<Real>()));
        let (guess, mut kept, _) = runs.remove(best);
        if kept.blocks {
            // Without bounds: the index and `moved` stay those of the run's
            // positions.
            kept.cells = Assignment::new(this.grid, voxels, this.carried_owners(voxels));
            kept.blocks = false;
        }
        if coarse > fine || block > 1 {
            kept.converged = false;
            self.iterate(&mut kept, prev, fits, fine, progress)?;
        }
        let kept = self.reclaim(kept, prev, fits, progress)?;
        let mut result = self.finish(kept, prev, fits, voxels);
        for (_, dropped, _) in &runs {
            result.timing.add_dropped(&dropped.timing);
        }
        result.timing.kept_guess = guess;
        Some(result)
    }
}

/// The last iterations' states of a run, for the windowed convergence test
/// ([`TrackParams::convergence_window`]).
struct Recent {
    window: usize,
    /// The positions each of the last `window` iterations started from,
    /// oldest first, with the largest update found there.
    states: std::collections::VecDeque<(Vec<Point3>, Real)>,
    /// Iterations so far in this phase.
    iterations: usize,
}

impl Recent {
    fn new(window: usize) -> Self {
        Recent {
            window,
            states: std::collections::VecDeque::with_capacity(window),
            iterations: 0,
        }
    }

    /// Records the positions an iteration starts from.
    fn push(&mut self, start: &[Point3]) {
        self.iterations += 1;
        if self.window <= 1 {
            return;
        }
        let slot = if self.states.len() == self.window {
            self.states.pop_front().map(|(mut v, _)| {
                v.copy_from_slice(start);
                v
            })
        } else {
            None
        };
        self.states
            .push_back((slot.unwrap_or_else(|| start.to_vec()), Real::INFINITY));
    }

    /// The largest update found from the positions pushed last.
    fn set_largest_update(&mut self, largest: Real) {
        if let Some(last) = self.states.back_mut() {
            last.1 = largest;
        }
    }

    /// Whether, `window` iterations or more into the phase, no center of
    /// `cur` is `window` × the threshold from where it was `window`
    /// iterations ago.
    fn settled(&self, cur: &[Point3], threshold2: Real) -> bool {
        if self.window <= 1 || self.iterations <= self.window {
            return false;
        }
        let reach2 = threshold2 * (self.window * self.window) as Real;
        cur.iter()
            .zip(&self.states[0].0)
            .all(|(a, b)| (a - b).norm_squared() < reach2)
    }

    /// Moves `cur` to the recorded state with the shortest largest update
    /// (the first of equal ones) and sets `moved` to each center's distance
    /// from the positions of the last iteration's start, where the cells
    /// were last assigned.
    fn take_steadiest(&self, cur: &mut [Point3], moved: &mut Vec<Real>) {
        let k = (0..self.states.len())
            .min_by(|&a, &b| self.states[a].1.total_cmp(&self.states[b].1))
            .expect("settled after a full window");
        let (chosen, last) = (&self.states[k].0, &self.states[self.states.len() - 1].0);
        moved.clear();
        moved.extend(chosen.iter().zip(last).map(|(a, b)| (a - b).norm()));
        cur.copy_from_slice(chosen);
    }
}

/// E = Es + β Eu = ½ Σ ‖c_i − p_i‖² + β ½ Σ ‖c_i − x̄_i‖² (docs/method.md §3);
/// an empty cell adds nothing to Eu.
fn energy(
    centers: &[Point3],
    predictions: &[Point3],
    stats: &CellStats,
    grid: &GridSpec,
    beta: Real,
) -> Real {
    center_energies(centers, predictions, stats, grid, beta)
        .iter()
        .sum()
}

/// Each center's term of [`energy`].
fn center_energies(
    centers: &[Point3],
    predictions: &[Point3],
    stats: &CellStats,
    grid: &GridSpec,
    beta: Real,
) -> Vec<Real> {
    centers
        .iter()
        .zip(predictions)
        .enumerate()
        .map(|(i, (c, p))| {
            0.5 * ((c - p).norm_squared()
                + beta
                    * stats
                        .centroid(i, grid)
                        .map_or(0.0, |x| (c - x).norm_squared()))
        })
        .collect()
}

/// The position of the smallest of `values`, the first of equal ones.
fn lowest(values: impl Iterator<Item = Real>) -> usize {
    values
        .enumerate()
        .fold(
            (0, Real::INFINITY),
            |(b, e), (r, v)| if v < e { (r, v) } else { (b, e) },
        )
        .0
}

/// Rigid predictions p_i = A_i(c_i^{f-1}).
pub fn predict(motions: &[Rigid], prev: &[Point3]) -> Vec<Point3> {
    motions.iter().zip(prev).map(|(m, p)| m.apply(p)).collect()
}

/// Every cell's moments (None for empty cells).
pub(crate) fn cell_moments(stats: &CellStats, grid: &GridSpec) -> Vec<Option<CellMoments>> {
    (0..stats.count.len())
        .map(|i| stats.moments(i, grid))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: Real) -> Vec<Point3> {
        vec![Point3::new(x, 0.0, 0.0), Point3::new(0.0, x, 0.0)]
    }

    /// Settled only once a full window lies behind, only when no center
    /// drifted W × threshold over it; the state kept is the one whose
    /// largest update was the shortest, with the moves from the last start.
    #[test]
    fn the_window_stops_jitter_not_drift_and_keeps_the_steadiest_state() {
        let threshold2 = 1.0;
        // Jitter: back and forth by 2 thresholds, updates 2, 0.5, 2, ...
        let mut recent = Recent::new(3);
        let mut cur = at(0.0);
        for k in 0..4 {
            recent.push(&cur);
            recent.set_largest_update(if k % 2 == 0 { 2.0 } else { 0.5 });
            cur = at(if k % 2 == 0 { 2.0 } else { 0.0 });
            assert_eq!(
                recent.settled(&cur, threshold2),
                k == 3,
                "iteration {}",
                k + 1
            );
        }
        let mut moved = Vec::new();
        recent.take_steadiest(&mut cur, &mut moved);
        // Starts of iterations 2, 3, 4: at 2 (update 0.5), 0 (2), 2 (0.5).
        assert_eq!(cur, at(2.0));
        assert_eq!(moved, vec![0.0, 0.0]);

        // Drift: 1.2 thresholds per iteration never passes the per-iteration
        // test, and moves 3.6 > 3 thresholds over the window.
        let mut recent = Recent::new(3);
        let mut cur = at(0.0);
        for k in 0..10 {
            recent.push(&cur);
            recent.set_largest_update(1.2);
            cur = at(1.2 * (k + 1) as Real);
            assert!(!recent.settled(&cur, threshold2), "iteration {}", k + 1);
        }

        // Window 1 is the paper's test alone.
        let mut recent = Recent::new(1);
        for _ in 0..5 {
            recent.push(&cur);
            assert!(!recent.settled(&cur, threshold2));
        }
    }
}
