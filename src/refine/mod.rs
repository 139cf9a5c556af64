//! Stage 3: removing irregular centers in batches, each followed by the
//! temporally global optimisation (docs/method.md §6-§7). The API is
//! [`refine`] and [`refine_with_checkpoints`], what they give, and
//! [`SparseAffinity`], the global affinity ω the deformation binds a mesh
//! with (`pipeline::sequence_affinity` makes it); the algorithm's parts
//! (`affinity`, `cells`, `global`, `irregular`) are internal.

mod affinity;
pub(crate) mod cells;
mod checkpoint;
mod global;
mod irregular;

pub(crate) use affinity::global_affinity;
pub use affinity::SparseAffinity;
pub(crate) use cells::SequenceCells;
use checkpoint::{Restored, Snapshot};
use global::optimise;
pub use global::Iteration;
use irregular::most_irregular;

use crate::checkpoint::Checkpointing;
use crate::error::{Error, Result, Saved};
use crate::model::Trajectories;
use crate::params::RefineParams;
use crate::progress::{Progress, Stage};
use crate::voxel::VoxelSequence;
use std::time::Instant;

/// What refinement gives: the remaining centers' trajectories and what it did.
#[derive(Clone, Debug)]
pub struct RefineResult {
    /// The remaining centers' trajectories, in their original order.
    pub trajectories: Trajectories,
    /// What refinement did.
    pub refinement: Refinement,
}

/// What refinement did.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Original indices of the removed centers, in removal order.
    pub removed: Vec<usize>,
    /// Original index of each remaining center.
    pub kept: Vec<usize>,
    /// Energy history of each batch's optimisation (empty without it).
    pub batches: Vec<Vec<Iteration>>,
    /// Seconds the refinement took, a resumed run's earlier ones included.
    pub seconds: f64,
}

/// Removes `params.total_removed(N)` irregular centers in `params.batches`
/// batches, optimising globally after each. The trajectories are moved in
/// and refined in place: a long sequence's are not held twice.
pub fn refine(
    traj: Trajectories,
    seq: &VoxelSequence,
    params: &RefineParams,
    progress: Progress,
) -> Result<RefineResult> {
    refine_with_checkpoints(traj, seq, params, None, progress)
}

/// Removes the `n_rem` most irregular centers of `current` (relative to
/// their spacing when `params` says so) from it and from `cells`; `kept`
/// maps the centers left to the tracked ones, `removed` gains theirs.
fn remove_irregular(
    current: &mut Trajectories,
    cells: &mut SequenceCells,
    kept: &mut Vec<usize>,
    removed: &mut Vec<usize>,
    n_rem: usize,
    params: &RefineParams,
) {
    let mut irregularity = crate::metrics::irregularity(current);
    if params.relative_irregularity {
        irregularity = irregular::relative_irregularity(current, &irregularity);
    }
    let worst = most_irregular(&irregularity, n_rem);
    removed.extend(worst.iter().map(|&i| kept[i]));
    let survivors = current.remove_centers(&worst);
    cells.keep_centers(&survivors);
    *kept = survivors.into_iter().map(|i| kept[i]).collect();
}

/// [`refine`], saving its state to `checkpoint` ([`Checkpointing::refine_path`])
/// after every batch, every `refine_save_seconds` within one, and when
/// cancelled through `progress` (then returning [`Error::Interrupted`]); with
/// `checkpoint.resume` it continues from the saved state. The result is
/// bit-identical to an uninterrupted [`refine`].
pub fn refine_with_checkpoints(
    traj: Trajectories,
    seq: &VoxelSequence,
    params: &RefineParams,
    checkpoint: Option<&Checkpointing>,
    progress: Progress,
) -> Result<RefineResult> {
    params.validate(traj.centers)?;
    let start = Instant::now();
    let scale = params.length_scale(&seq.bounds);
    let (frames, total) = (traj.frames, params.total_removed(traj.centers));
    // Where to save, and the fingerprint the file carries.
    let saving = checkpoint.map(|c| (c, checkpoint::fingerprint(&traj, seq, params)));
    let Restored {
        batches_done: first,
        kept,
        trajectories: mut current,
        removed,
        finished,
        current: mut in_progress,
        seconds: earlier,
    } = restore(traj, params, saving)?;
    let mut record = Record {
        kept,
        removed,
        finished,
        earlier,
        start,
    };
    let interrupted = |batches_done: usize| Error::Interrupted {
        saved: checkpoint.map(|c| Saved {
            path: c.path(),
            frames,
            refine: Some((batches_done, params.batches)),
        }),
    };
    // A share of the memory available now, 1 GiB where that is unknown.
    let budget = params.cell_memory.unwrap_or_else(|| {
        crate::voxel::available_memory().map_or((1u64 << 30) as f64, crate::params::kept_cell_share)
    });
    let mut cells = SequenceCells::new(seq, budget as usize).stopping_with(progress);
    log::info!(
        "the cells of {} of {frames} frames kept between evaluations (budget {:.0} MiB)",
        cells.cached_frames(),
        budget / (1u64 << 20) as f64
    );
    let per_batch = params.max_iterations.max(1);
    let steps = params.batches * per_batch;
    progress.report(Stage::Refine, first * per_batch, steps);
    for b in first..params.batches {
        let (omega, before) = match in_progress.take() {
            Some(resumed) => resumed,
            None => {
                // Spread the remainder over the first batches.
                let n_rem = total / params.batches + usize::from(b < total % params.batches);
                remove_irregular(
                    &mut current,
                    &mut cells,
                    &mut record.kept,
                    &mut record.removed,
                    n_rem,
                    params,
                );
                if !params.optimise {
                    save(saving, record.snapshot(b + 1, &current, None))?;
                    continue;
                }
                let omega = global_affinity(
                    &current,
                    seq,
                    &mut cells,
                    params.rho_gp * scale,
                    params.rho_gm * scale,
                    params.mu,
                );
                if cells.cancelled() {
                    // ω is not whole; the state before this batch's removal
                    // is what the last save holds, and a resumed run starts
                    // the batch again from it.
                    return Err(interrupted(b));
                }
                log::info!(
                    "batch {}: removed {n_rem}, ω keeps {:.1} neighbours per center",
                    b + 1,
                    omega.mean_neighbors()
                );
                (omega, Vec::new())
            }
        };
        let batch = Batch {
            index: b,
            omega: &omega,
            before: &before,
            done: b * per_batch,
            steps,
        };
        let history = optimise_batch(
            &mut current,
            seq,
            &mut cells,
            &record,
            &batch,
            params,
            saving,
            progress,
        )?;
        if progress.cancelled() {
            // The batch may have ended too; resumed, it finds no iteration
            // left or no step that lowers the energy, as it would have.
            save(
                saving,
                record.snapshot(b, &current, Some((&omega, &history))),
            )?;
            return Err(interrupted(b));
        }
        record.finished.push(history);
        save(saving, record.snapshot(b + 1, &current, None))?;
    }
    progress.report(Stage::Refine, steps, steps);
    Ok(RefineResult {
        trajectories: current,
        refinement: Refinement {
            seconds: record.seconds(),
            removed: record.removed,
            kept: record.kept,
            batches: record.finished,
        },
    })
}

/// The saved state to resume from where `saving` says to resume and a file
/// is there, else the start of a refinement of `traj`.
fn restore(
    traj: Trajectories,
    params: &RefineParams,
    saving: Option<(&Checkpointing, u64)>,
) -> Result<Restored> {
    Ok(match saving {
        Some((c, fp)) if c.resume && c.refine_path().exists() => {
            let r = checkpoint::load(c, fp, &traj, params.batches)?;
            log::info!(
                "resuming refinement from {} after {} of {} batches",
                c.refine_path().display(),
                r.batches_done,
                params.batches
            );
            r
        }
        _ => Restored::fresh(traj),
    })
}

/// What the refinement has done so far besides the trajectories: what a
/// checkpoint saves with them.
struct Record {
    kept: Vec<usize>,
    removed: Vec<usize>,
    /// The finished batches' energy histories.
    finished: Vec<Vec<Iteration>>,
    /// Seconds of a resumed run's earlier sessions.
    earlier: f64,
    start: Instant,
}

impl Record {
    /// Seconds spent refining so far, earlier sessions included.
    fn seconds(&self) -> f64 {
        self.earlier + self.start.elapsed().as_secs_f64()
    }

    /// The state to save after `batches_done` batches, with `trajectories`
    /// and the batch in progress, if any.
    fn snapshot<'a>(
        &'a self,
        batches_done: usize,
        trajectories: &'a Trajectories,
        current: Option<(&'a SparseAffinity, &'a [Iteration])>,
    ) -> Snapshot<'a> {
        Snapshot {
            batches_done,
            trajectories,
            kept: &self.kept,
            removed: &self.removed,
            finished: &self.finished,
            current,
            seconds: self.seconds(),
        }
    }
}

/// A batch's global optimisation, as far as the progress bar and a resumed
/// run see it.
struct Batch<'a> {
    /// Which batch (from 0).
    index: usize,
    omega: &'a SparseAffinity,
    /// A resumed batch's history so far (empty when the batch starts now);
    /// its last entry is where the iterations go on from.
    before: &'a [Iteration],
    /// The progress steps of the batches before.
    done: usize,
    steps: usize,
}

/// Optimises `current` over the batch's iterations left, saving the state
/// every `refine_save_seconds`; returns the batch's whole energy history
/// (a resumed batch's earlier part included). Stops early when `progress`
/// asks to or a save fails (that error returned).
#[allow(clippy::too_many_arguments)]
fn optimise_batch(
    current: &mut Trajectories,
    seq: &VoxelSequence,
    cells: &mut SequenceCells,
    record: &Record,
    batch: &Batch,
    params: &RefineParams,
    saving: Option<(&Checkpointing, u64)>,
    progress: Progress,
) -> Result<Vec<Iteration>> {
    let before = batch.before;
    let done_before = before.len().saturating_sub(1);
    let joined = |history: &[Iteration]| -> Vec<Iteration> {
        if before.is_empty() {
            history.to_vec()
        } else {
            before
                .iter()
                .chain(history.iter().skip(1))
                .copied()
                .collect()
        }
    };
    let mut last_save = Instant::now();
    let mut save_error = None;
    let done = batch.done + done_before;
    let history = optimise(
        current,
        &seq.grid,
        cells,
        batch.omega,
        &RefineParams {
            max_iterations: params.max_iterations.saturating_sub(done_before),
            ..params.clone()
        },
        |it, now, history| {
            progress.report(Stage::Refine, done + it, batch.steps);
            if progress.cancelled() {
                return false;
            }
            if saving
                .is_some_and(|(c, _)| last_save.elapsed().as_secs_f64() >= c.refine_save_seconds)
            {
                let history = joined(history);
                let snapshot = record.snapshot(batch.index, now, Some((batch.omega, &history)));
                if let Err(e) = save(saving, snapshot) {
                    save_error = Some(e);
                    return false;
                }
                last_save = Instant::now();
            }
            true
        },
    )?;
    match save_error {
        Some(e) => Err(e),
        None => Ok(joined(&history)),
    }
}

/// Saves `snapshot` where `saving` says, if anywhere.
fn save(saving: Option<(&Checkpointing, u64)>, snapshot: Snapshot) -> Result<()> {
    saving.map_or(Ok(()), |(c, fp)| checkpoint::save(c, fp, &snapshot))
}

#[cfg(test)]
mod tests;
