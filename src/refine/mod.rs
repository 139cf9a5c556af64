//! Stage 4: removing irregular centers in batches, each followed by the
//! temporally global optimisation (method.md §6-§7).

pub mod affinity;
pub mod cells;
pub mod global;
pub mod irregular;

pub use affinity::{global_affinity, SparseAffinity};
pub use cells::SequenceCells;
pub use global::{evaluate, optimise, Iteration};
pub use irregular::most_irregular;

use crate::error::{Error, Result};
use crate::params::RefineParams;
use crate::progress::{Progress, Stage};
use crate::model::Trajectories;
use crate::voxel::VoxelSequence;
use std::time::Instant;

/// What refinement did.
#[derive(Clone, Debug)]
pub struct RefineResult {
    /// The remaining centers' trajectories, in their original order.
    pub trajectories: Trajectories,
    /// Original indices of the removed centers, in removal order.
    pub removed: Vec<usize>,
    /// Original index of each remaining center.
    pub kept: Vec<usize>,
    /// Energy history of each batch's optimisation (empty without it).
    pub batches: Vec<Vec<Iteration>>,
    pub seconds: f64,
}

/// Removes `params.total_removed(N)` irregular centers in `params.batches`
/// batches, optimising globally after each.
pub fn refine(traj: &Trajectories, seq: &VoxelSequence, params: &RefineParams, progress: Progress) -> Result<RefineResult> {
    params.validate(traj.centers)?;
    let start = Instant::now();
    let scale = params.length_scale(&seq.bounds);
    let total = params.total_removed(traj.centers);
    let mut current = traj.clone();
    let mut kept: Vec<usize> = (0..traj.centers).collect();
    let mut removed = Vec::new();
    let mut batches = Vec::new();
    let mut cells = SequenceCells::new(seq);
    let steps = params.batches * params.max_iterations.max(1);
    progress.report(Stage::Refine, 0, steps);
    for b in 0..params.batches {
        // Spread the remainder over the first batches.
        let n_rem = total / params.batches + usize::from(b < total % params.batches);
        let irregularity = irregular::irregularity(&current);
        let worst = most_irregular(&irregularity, n_rem);
        removed.extend(worst.iter().map(|&i| kept[i]));
        current = current.without(&worst);
        kept = (0..kept.len()).filter(|i| !worst.contains(i)).map(|i| kept[i]).collect();
        if !params.optimise {
            continue;
        }
        let omega = global_affinity(&current, seq, &mut cells, params.rho_gp * scale, params.rho_gm * scale, params.mu);
        log::info!("batch {}: removed {n_rem}, ω keeps {:.1} neighbours per center", b + 1, omega.mean_neighbors());
        let done = b * params.max_iterations.max(1);
        let history = optimise(
            &mut current,
            &seq.grid,
            &mut cells,
            &omega,
            params.beta_hat,
            params.lambda,
            params.max_iterations,
            params.max_halvings,
            |it| {
                progress.report(Stage::Refine, done + it, steps);
                !progress.cancelled()
            },
        );
        batches.push(history);
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
    }
    progress.report(Stage::Refine, steps, steps);
    Ok(RefineResult { trajectories: current, removed, kept, batches, seconds: start.elapsed().as_secs_f64() })
}
