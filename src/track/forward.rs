//! Forward tracking, frame by frame (method.md §3): extrapolate, presmooth
//! with rigid predictions, then alternate Voronoi centroids and rigid
//! predictions until no center moves more than the threshold.
//!
//! Beyond the paper, each frame is also tracked from a damped guess and the
//! result with the lower energy is kept (see [`TrackParams::damped_guess`]).

use super::affinity::Affinity;
use super::checkpoint::{self, Checkpointing, Snapshot};
use crate::spatial::cells::{assign, carry_owners, Assignment, CellMoments, CellStats, CenterIndex, NO_OWNER};
use super::lloyd::seed_centers;
use crate::model::{GridSpec, Rigid, RigidFits, Trajectories};
use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::params::TrackParams;
use crate::progress::{Progress, Stage};
use crate::voxel::VoxelSequence;
use super::FrameTiming;
use std::time::Instant;


impl FrameTiming {
    /// Adds the parts of the dropped run of the same frame.
    fn add_dropped(&mut self, dropped: &FrameTiming) {
        self.assign += dropped.assign;
        self.fit += dropped.fit;
        self.affinity += dropped.affinity;
        self.dropped_iterations = dropped.iterations;
    }
}

/// One frame tracked from one guess.
struct FrameResult {
    centers: Vec<Point3>,
    counts: Vec<u32>,
    timing: FrameTiming,
    /// E = Es + β Eu at the final positions (method.md §3).
    energy: Real,
}

/// The tracker's result.
#[derive(Clone, Debug)]
pub struct TrackResult {
    pub trajectories: Trajectories,
    /// Occupied voxels per Voronoi cell at the final positions, per frame (for DFU).
    pub cell_counts: Vec<Vec<u32>>,
    /// Frame 0 is the Lloyd placement.
    pub timings: Vec<FrameTiming>,
    /// Lengths in the input's units: ρ_p, ρ_m, threshold after scaling.
    pub scale: Real,
}

/// The state the tracker carries from one frame to the next.
#[derive(Clone)]
struct Tracker<'a> {
    grid: &'a GridSpec,
    params: &'a TrackParams,
    threshold2: Real,
    affinity: Affinity,
    owners: Vec<u32>,
    /// The previous frame's voxels.
    prev_voxels: std::sync::Arc<[u32]>,
}

/// Tracks `params.centers` centers through every frame of `seq`.
pub fn track(seq: &VoxelSequence, params: &TrackParams, progress: Progress) -> Result<TrackResult> {
    track_with_checkpoints(seq, params, None, progress)
}

/// [`track`], saving its state to `checkpoint` every few frames, when
/// cancelled through `progress` (then returning [`Error::Interrupted`]) and at
/// the end; with `checkpoint.resume` it continues from the saved state. The
/// result is bit-identical to an uninterrupted [`track`].
pub fn track_with_checkpoints(seq: &VoxelSequence, params: &TrackParams, checkpoint: Option<&Checkpointing>, progress: Progress) -> Result<TrackResult> {
    params.validate()?;
    let frames = seq.frames.len();
    let n0 = seq.frames[0].len();
    if params.centers > n0 {
        return Err(Error::InvalidParameter(format!(
            "{}: only {n0} occupied voxels for {} centers; lower the number of centers or raise the resolution",
            seq.names[0],
            params.centers
        )));
    }
    if checkpoint.is_some_and(|c| c.every == 0) {
        return Err(Error::InvalidParameter("the checkpoint interval must be at least 1 frame".into()));
    }
    let fingerprint = checkpoint.map(|_| checkpoint::fingerprint(seq, params));
    let scale = params.length_scale(&seq.bounds);
    let grid = &seq.grid;
    progress.report(Stage::Track, 0, frames);

    let resume = match checkpoint {
        Some(c) if c.resume && c.path().exists() => Some(c),
        Some(c) if c.resume => {
            // So that one command line can be rerun until it completes.
            log::warn!("no checkpoint in {} yet: tracking starts from the first frame", c.dir.display());
            None
        }
        _ => None,
    };
    let (mut traj, mut cell_counts, mut timings, affinity, owners, first) = match resume {
        Some(c) => {
            let r = checkpoint::load(c, fingerprint.expect("fingerprinted"), seq, params)?;
            log::info!("resuming from {} after {} of {frames} frames", c.path().display(), r.frames_done);
            (r.trajectories, r.cell_counts, r.timings, r.affinity, r.owners, r.frames_done)
        }
        None => {
            let start = Instant::now();
            let voxels0 = &seq.frames[0].indices();
            let (centers0, lloyd_steps) =
                seed_centers(grid, voxels0, params.centers, params.seed, params.lloyd_iterations, params.over_relaxation, params.threshold * scale);
            let mut traj = Trajectories::new(frames, params.centers);
            traj.frame_mut(0).copy_from_slice(&centers0);
            let mut owners = vec![NO_OWNER; voxels0.len()];
            let stats0 = assign(grid, voxels0, &CenterIndex::new(&centers0), &mut owners, false);
            let reach = super::rho_p(params, seq, scale);
            let affinity = Affinity::initial(&centers0, params.affinity, reach, params.rho_m * scale, params.alpha, params.mu);
            let timing = FrameTiming { total: start.elapsed().as_secs_f64(), iterations: lloyd_steps, ..Default::default() };
            log::info!("frame 0: {} centers placed; ρ_p {reach:.4}, {:.1} neighbours each", params.centers, affinity.mean_neighbors());
            (traj, vec![stats0.count], vec![timing], affinity, owners, 1)
        }
    };
    progress.report(Stage::Track, first, frames);

    let mut tracker = Tracker {
        grid,
        params,
        threshold2: (params.threshold * scale).powi(2),
        affinity,
        owners,
        prev_voxels: seq.frames[first - 1].indices().into(),
    };
    // Frames held by the checkpoint file.
    let mut saved = if resume.is_some() { first } else { 0 };
    let save = |tracker: &Tracker, traj: &Trajectories, cell_counts: &[Vec<u32>], timings: &[FrameTiming]| -> Result<()> {
        let (Some(c), Some(fp)) = (checkpoint, fingerprint) else { return Ok(()) };
        let frames_done = cell_counts.len();
        let snapshot = Snapshot { frames_done, trajectories: traj, cell_counts, timings, affinity: &tracker.affinity, owners: &tracker.owners };
        checkpoint::save(c, fp, &snapshot)?;
        log::debug!("checkpoint: {frames_done} frames saved in {}", c.path().display());
        Ok(())
    };
    for f in first..frames {
        let start = Instant::now();
        let voxels: std::sync::Arc<[u32]> = seq.frames[f].indices().into();
        let (prev, voxels) = (traj.frame(f - 1), &voxels);
        let extrapolate = |k: Real| -> Vec<Point3> { prev.iter().zip(traj.frame(f - 2)).map(|(a, b)| a + (a - b) * k).collect() };
        let fits = tracker.fits(prev);
        let kept = match params.damped_guess.filter(|_| f >= 2) {
            None => {
                let guess = if f == 1 { prev.to_vec() } else { extrapolate(1.0) };
                tracker.track_frame(prev, guess, &fits, voxels, progress)
            }
            Some(k) => tracker.track_frame_from_two_guesses(prev, [extrapolate(1.0), extrapolate(k)], &fits, voxels, progress).map(|(kept, damped_kept)| {
                log::debug!("frame {f}: {} guess kept", if damped_kept { "damped" } else { "constant-velocity" });
                kept
            }),
        };
        let Some(FrameResult { centers, counts, mut timing, energy }) = kept else {
            // Frame f was abandoned; the state is still that after frame f - 1.
            if saved < f {
                save(&tracker, &traj, &cell_counts, &timings)?;
            }
            return Err(Error::Interrupted { saved: checkpoint.map(|c| (c.path(), f)) });
        };
        timing.total = start.elapsed().as_secs_f64();
        traj.frame_mut(f).copy_from_slice(&centers);
        cell_counts.push(counts);
        log::debug!("frame {f}: {} iterations, energy {energy:.4e}, {:.3} s", timing.iterations, timing.total);
        timings.push(timing);
        progress.report(Stage::Track, f + 1, frames);
        if checkpoint.is_some_and(|c| (f + 1) % c.every == 0 || f + 1 == frames) {
            save(&tracker, &traj, &cell_counts, &timings)?;
            saved = f + 1;
        }
    }
    Ok(TrackResult { trajectories: traj, cell_counts, timings, scale })
}

/// One run of a frame's iterations from one guess.
struct Run {
    cur: Vec<Point3>,
    cells: Assignment,
    /// How far each center moved in the last iteration (empty before the first).
    moved: Vec<Real>,
    index: CenterIndex,
    timing: FrameTiming,
    /// E at the positions before the last iteration (infinite before the first).
    energy: Real,
    converged: bool,
}

impl<'a> Tracker<'a> {
    /// The rigid fits from frame f-1: its centers and the weights are fixed for the whole frame.
    fn fits(&self, prev: &[Point3]) -> RigidFits {
        RigidFits::new(prev, prev.len(), |i| self.affinity.pairs(i))
    }

    /// Presmoothing from the guess `cur`, and the cells carried over from frame f-1.
    fn start(&self, prev: &[Point3], mut cur: Vec<Point3>, fits: &RigidFits, voxels: &[u32]) -> Run {
        let mut timing = FrameTiming::default();
        let cells = Assignment::new(self.grid, voxels, carry_owners(&self.prev_voxels, &self.owners, voxels));
        let clock = Instant::now();
        for _ in 0..self.params.presmooth_steps {
            cur = predict(&fits.fit(&cur), prev);
        }
        timing.fit += clock.elapsed().as_secs_f64();
        let index = CenterIndex::new(&cur);
        Run { cur, cells, moved: Vec::new(), index, timing, energy: Real::INFINITY, converged: false }
    }

    /// Iterates `run` until it converges or reaches the iteration limit.
    /// None when `progress` asks to stop.
    fn iterate(&self, run: &mut Run, prev: &[Point3], fits: &RigidFits, progress: Progress) -> Option<()> {
        let limit = self.params.max_iterations;
        let (beta, omega) = (self.params.beta, self.params.tracking_over_relaxation);
        let Run { cur, cells, moved, index, timing: t, energy, converged } = run;
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
            // The residual G(c) − c of the paper's update G(c) = (p + β x̄) / (1 + β)
            // decides convergence whatever the step taken along it.
            let (mut residual_most, mut smooth, mut data): (Real, Real, Real) = (0.0, 0.0, 0.0);
            for (i, c) in cur.iter_mut().enumerate() {
                let p = motions[i].apply(&prev[i]);
                let x = stats.centroid(i, self.grid);
                smooth += (*c - p).norm_squared();
                data += x.map_or(0.0, |x| (*c - x).norm_squared());
                let x = x.unwrap_or(p);
                let residual = Point3::from((p.coords + x.coords * beta) / (1.0 + beta)) - *c;
                residual_most = residual_most.max(residual.norm());
                let step = residual * omega;
                moved.push(step.norm());
                *c += step;
            }
            *energy = 0.5 * (smooth + beta * data);
            if t.iterations % 100 == 0 {
                let over = moved.iter().filter(|&&m| m * m >= self.threshold2).count();
                log::debug!("iteration {}: {over} centers move more than the threshold, largest residual {residual_most:.2e}", t.iterations);
            }
            *converged = residual_most * residual_most < self.threshold2;
        }
        Some(())
    }

    /// The frame's cells and motions at the final positions; they feed the
    /// affinity, which is updated, and the tracker moves on to this frame.
    fn finish(&mut self, run: Run, prev: &[Point3], fits: &RigidFits, voxels: &std::sync::Arc<[u32]>) -> FrameResult {
        let Run { cur, mut cells, moved, index, mut timing, .. } = run;
        let clock = Instant::now();
        let stats = cells.update(&index.moved_to(&cur, &moved), &moved, true);
        timing.assign += clock.elapsed().as_secs_f64();
        let clock = Instant::now();
        let motions = fits.fit(&cur);
        let energy = energy(&cur, &predict(&motions, prev), &stats, self.grid, self.params.beta);
        self.affinity.update(&cur, &motions, &cell_moments(&stats, self.grid));
        timing.affinity += clock.elapsed().as_secs_f64();
        self.owners = cells.owners;
        self.prev_voxels = voxels.clone();
        FrameResult { centers: cur, counts: stats.count, timing, energy }
    }

    /// One frame from the guess `guess`. None when `progress` asks to stop;
    /// the state is then left as it was. The caller times the whole frame.
    fn track_frame(&mut self, prev: &[Point3], guess: Vec<Point3>, fits: &RigidFits, voxels: &std::sync::Arc<[u32]>, progress: Progress) -> Option<FrameResult> {
        let mut run = self.start(prev, guess, fits, voxels);
        self.iterate(&mut run, prev, fits, progress)?;
        Some(self.finish(run, prev, fits, voxels))
    }

    /// One frame from two guesses, run side by side to convergence; the one
    /// with the higher energy is dropped. Returns the result and whether the
    /// second guess was kept.
    ///
    /// Why not decide earlier: on crane_tvm the order of the two runs'
    /// energies after 5 to 40 iterations matched the final order in about
    /// half the frames, no better than chance (docs/measurements.md).
    fn track_frame_from_two_guesses(
        &mut self,
        prev: &[Point3],
        [first, second]: [Vec<Point3>; 2],
        fits: &RigidFits,
        voxels: &std::sync::Arc<[u32]>,
        progress: Progress,
    ) -> Option<(FrameResult, bool)> {
        let this = &*self;
        let run = |guess: Vec<Point3>| {
            let mut run = this.start(prev, guess, fits, voxels);
            this.iterate(&mut run, prev, fits, progress).map(|_| run)
        };
        // Each run is parallel inside, but not evenly: running both at once fills the cores.
        let (a, b) = rayon::join(|| run(first), || run(second));
        let (a, b) = (a?, b?);
        let second_kept = b.energy < a.energy;
        let (kept, dropped) = if second_kept { (b, a) } else { (a, b) };
        let mut result = self.finish(kept, prev, fits, voxels);
        result.timing.add_dropped(&dropped.timing);
        result.timing.damped_guess_kept = second_kept;
        Some((result, second_kept))
    }
}

/// E = Es + β Eu = ½ Σ ‖c_i − p_i‖² + β ½ Σ ‖c_i − x̄_i‖² (method.md §3);
/// an empty cell adds nothing to Eu.
fn energy(centers: &[Point3], predictions: &[Point3], stats: &CellStats, grid: &GridSpec, beta: Real) -> Real {
    let smooth: Real = centers.iter().zip(predictions).map(|(c, p)| (c - p).norm_squared()).sum();
    let data: Real = centers.iter().enumerate().filter_map(|(i, c)| Some((c - stats.centroid(i, grid)?).norm_squared())).sum();
    0.5 * (smooth + beta * data)
}

/// Rigid predictions p_i = A_i(c_i^{f-1}).
pub fn predict(motions: &[Rigid], prev: &[Point3]) -> Vec<Point3> {
    motions.iter().zip(prev).map(|(m, p)| m.apply(p)).collect()
}

/// Every cell's moments (None for empty cells).
pub(crate) fn cell_moments(stats: &CellStats, grid: &GridSpec) -> Vec<Option<CellMoments>> {
    (0..stats.count.len()).map(|i| stats.moments(i, grid)).collect()
}
