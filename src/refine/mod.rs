//! Stage 3: removing irregular centers in batches, each followed by the
//! temporally global optimisation (docs/method.md §6-§7).

pub mod affinity;
pub mod cells;
mod checkpoint;
pub mod global;
pub mod irregular;

pub use affinity::{global_affinity, SparseAffinity};
pub use cells::SequenceCells;
use checkpoint::{Restored, Snapshot};
pub use global::{evaluate, optimise, Iteration};
pub use irregular::most_irregular;

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
    let restored = match saving {
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
    };
    let Restored {
        batches_done: first,
        mut kept,
        trajectories: mut current,
        mut removed,
        finished: mut batches,
        current: mut in_progress,
        seconds: earlier,
    } = restored;
    let seconds = |start: &Instant| earlier + start.elapsed().as_secs_f64();
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
                    &mut kept,
                    &mut removed,
                    n_rem,
                    params,
                );
                if !params.optimise {
                    save(
                        saving,
                        Snapshot {
                            batches_done: b + 1,
                            trajectories: &current,
                            kept: &kept,
                            removed: &removed,
                            finished: &batches,
                            current: None,
                            seconds: seconds(&start),
                        },
                    )?;
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
        // A resumed batch goes on with the iterations it had left; its start
        // is the saved history's last entry.
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
        let done = b * per_batch + done_before;
        let history = optimise(
            &mut current,
            &seq.grid,
            &mut cells,
            &omega,
            &RefineParams {
                max_iterations: params.max_iterations.saturating_sub(done_before),
                ..params.clone()
            },
            |it, now, history| {
                progress.report(Stage::Refine, done + it, steps);
                if progress.cancelled() {
                    return false;
                }
                if saving.is_some_and(|(c, _)| {
                    last_save.elapsed().as_secs_f64() >= c.refine_save_seconds
                }) {
                    let history = joined(history);
                    let snapshot = Snapshot {
                        batches_done: b,
                        trajectories: now,
                        kept: &kept,
                        removed: &removed,
                        finished: &batches,
                        current: Some((&omega, &history)),
                        seconds: seconds(&start),
                    };
                    if let Err(e) = save(saving, snapshot) {
                        save_error = Some(e);
                        return false;
                    }
                    last_save = Instant::now();
                }
                true
            },
        )?;
        if let Some(e) = save_error {
            return Err(e);
        }
        let history = joined(&history);
        if progress.cancelled() {
            // The batch may have ended too; resumed, it finds no iteration
            // left or no step that lowers the energy, as it would have.
            save(
                saving,
                Snapshot {
                    batches_done: b,
                    trajectories: &current,
                    kept: &kept,
                    removed: &removed,
                    finished: &batches,
                    current: Some((&omega, &history)),
                    seconds: seconds(&start),
                },
            )?;
            return Err(interrupted(b));
        }
        batches.push(history);
        save(
            saving,
            Snapshot {
                batches_done: b + 1,
                trajectories: &current,
                kept: &kept,
                removed: &removed,
                finished: &batches,
                current: None,
                seconds: seconds(&start),
            },
        )?;
    }
    progress.report(Stage::Refine, steps, steps);
    Ok(RefineResult {
        trajectories: current,
        refinement: Refinement {
            removed,
            kept,
            batches,
            seconds: seconds(&start),
        },
    })
}

/// Saves `snapshot` where `saving` says, if anywhere.
fn save(saving: Option<(&Checkpointing, u64)>, snapshot: Snapshot) -> Result<()> {
    saving.map_or(Ok(()), |(c, fp)| checkpoint::save(c, fp, &snapshot))
}
