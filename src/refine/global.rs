//! The temporally global optimisation (docs/method.md §7): gradient steps on
//! Ê = Ês + β̂ Êu over all frames at once, with a halving line search.

use super::affinity::SparseAffinity;
use super::cells::{frame_blocks, SequenceCells};
use crate::error::Result;
use crate::math::{Point3, Real, Vector3};
use crate::model::{FrameStore, GridSpec, Trajectories};
use crate::params::RefineParams;
use rayon::prelude::*;

/// Ê at one set of trajectories, with what its gradient needs.
pub struct Evaluation {
    /// Ê = Ês + β̂ Êu.
    pub energy: Real,
    /// Ês: half the squared distances of the centers from their forward and
    /// backward predictions, summed.
    pub smooth: Real,
    /// Êu: half the squared distances of the centers from their cells'
    /// centroids, summed.
    pub data: Real,
    /// ∇Ês + β̂ ∇Êu with predictions and centroids held fixed, one frame of
    /// vectors per frame (in a temporary file past the memory allowed).
    pub gradient: FrameStore<Vector3>,
}

/// One accepted or final step of the optimisation.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Iteration {
    /// Ê = Ês + β̂ Êu after the step.
    pub energy: Real,
    /// Ês after the step: half the squared distances of the centers from
    /// their forward and backward predictions, summed.
    pub smooth: Real,
    /// Êu after the step: half the squared distances of the centers from
    /// their cells' centroids, summed.
    pub data: Real,
    /// Step accepted (0 for the starting point).
    pub lambda: Real,
}

/// Evaluates Ê at `traj`: Voronoi centroids x̄ of every frame, forward
/// predictions p^f = A^f(c^{f-1}) and backward q^f = (A^{f+1})⁻¹(c^{f+1}),
/// where A^f is each center's motion from f-1 to f fitted under `omega`.
/// Frames are visited in blocks of [`FRAME_BLOCK`](super::cells::FRAME_BLOCK); the result is the same
/// as over all at once. The gradient is kept in memory up to `memory` bytes
/// ([`RefineParams::memory`](crate::params::RefineParams::memory)), in a
/// temporary file past it; errors are that file's.
///
/// With `moved` = (step, λ), Ê at `traj` moved by −λ `step`, as if at the
/// trajectories `p − step · λ`, which are made a block of frames at a
/// time: the line search then holds no second copy of all trajectories.
/// None when `cells` were asked to stop ([`SequenceCells::cancelled`]).
fn evaluate_moved(
    traj: &Trajectories,
    moved: Option<(&FrameStore<Vector3>, Real)>,
    grid: &GridSpec,
    cells: &mut SequenceCells,
    omega: &SparseAffinity,
    beta_hat: Real,
    memory: usize,
) -> Result<Option<Evaluation>> {
    let (frames, n) = (traj.frames, traj.centers);
    let mut gradient = FrameStore::new(n, frames, memory)?;
    let mut per_frame: Vec<(Real, Real)> = Vec::with_capacity(frames);
    for block in frame_blocks(0..frames) {
        let (start, end) = (block.start, block.end);
        // The frames this block reads: its own and one on either side.
        let lo = start.saturating_sub(1);
        let hi = (end + 1).min(frames);
        let local;
        let (traj, offset) = match moved {
            None => (traj, 0),
            Some((step, lambda)) => {
                let mut positions = Vec::with_capacity((hi - lo) * n);
                for f in lo..hi {
                    let g = step.get(f)?;
                    positions.extend(
                        traj.frame(f)
                            .iter()
                            .zip(g.iter())
                            .map(|(p, g)| p - g * lambda),
                    );
                }
                local = Trajectories {
                    frames: hi - lo,
                    centers: n,
                    positions,
                    reference: 0,
                };
                (&local, lo)
            }
        };
        let stats = cells.update_frames(traj, offset, start..end, false);
        if cells.cancelled() {
            return Ok(None);
        }
        // The motions A^f this block's frames need (f - 1 to f, f from
        // `first`), of which only what they predict is kept: forward[k] is
        // A^f(c^{f-1}), backward[k] is (A^f)⁻¹(c^f), f = first + k.
        let first = start.max(1);
        let (forward, backward): (Vec<Vec<Point3>>, Vec<Vec<Point3>>) = (first
            ..(end + 1).min(frames))
            .into_par_iter()
            .map(|f| {
                let motions = omega.fit_frames(traj, f - 1 - offset, f - offset);
                let forward = motions
                    .iter()
                    .enumerate()
                    .map(|(i, a)| a.apply(&traj.get(f - 1 - offset, i)))
                    .collect();
                let backward = motions
                    .iter()
                    .enumerate()
                    .map(|(i, a)| a.inverse().apply(&traj.get(f - offset, i)))
                    .collect();
                (forward, backward)
            })
            .unzip();
        // Each frame's gradient and energy terms, in parallel; the terms are
        // summed after, in frame order.
        let terms: Vec<(Vec<Vector3>, Real, Real)> = block
            .into_par_iter()
            .map(|f| {
                let (mut smooth, mut data) = (0.0, 0.0);
                let grad = (0..n)
                    .map(|i| {
                        let mut g = Vector3::zeros();
                        let c = traj.get(f - offset, i);
                        if let Some(x) = stats[f - start].centroid(i, grid) {
                            let r = c - x;
                            data += 0.5 * r.norm_squared();
                            g += beta_hat * r;
                        }
                        if f >= 1 {
                            let r = c - forward[f - first][i];
                            smooth += 0.5 * r.norm_squared();
                            g += r;
                        }
                        if f + 1 < frames {
                            let r = c - backward[f + 1 - first][i];
                            smooth += 0.5 * r.norm_squared();
                            g += r;
                        }
                        g
                    })
                    .collect();
                (grad, smooth, data)
            })
            .collect();
        for (grad, smooth, data) in terms {
            gradient.push(grad)?;
            per_frame.push((smooth, data));
        }
    }
    let mut smooth = 0.0;
    let mut data = 0.0;
    for (s, d) in per_frame {
        smooth += s;
        data += d;
    }
    Ok(Some(Evaluation {
        energy: smooth + beta_hat * data,
        smooth,
        data,
        gradient,
    }))
}

/// Gradient descent with λ (`params.lambda`) halved until the energy drops
/// (at most `params.max_halvings` times); stops after
/// `params.max_iterations`, when no halving helps, or when `on_iteration`
/// (called with the iterations done, the trajectories and the history so
/// far, to report or save them) returns false, or at once when `cells` are
/// asked to stop ([`SequenceCells::stopping_with`]; the trajectories are
/// then those of the last accepted step). Returns the energy before
/// and after every accepted step (none when stopped before the first
/// evaluation ended). The energy weighs the centroid term by
/// `params.beta_hat`; the gradients are kept as [`evaluate_moved`] says
/// (`params.memory`); errors are their temporary files'.
pub fn optimise(
    traj: &mut Trajectories,
    grid: &GridSpec,
    cells: &mut SequenceCells,
    omega: &SparseAffinity,
    params: &RefineParams,
    mut on_iteration: impl FnMut(usize, &Trajectories, &[Iteration]) -> bool,
) -> Result<Vec<Iteration>> {
    let RefineParams {
        beta_hat,
        lambda: lambda0,
        max_iterations,
        max_halvings,
        memory,
        ..
    } = *params;
    // Cells asked to stop end the optimisation where it is: the
    // trajectories change only by accepted steps.
    let Some(mut current) = evaluate_moved(traj, None, grid, cells, omega, beta_hat, memory)?
    else {
        return Ok(Vec::new());
    };
    let mut history = vec![Iteration {
        energy: current.energy,
        smooth: current.smooth,
        data: current.data,
        lambda: 0.0,
    }];
    for it in 0..max_iterations {
        let mut lambda = lambda0;
        let mut accepted = None;
        for _ in 0..=max_halvings {
            let Some(e) = evaluate_moved(
                traj,
                Some((&current.gradient, lambda)),
                grid,
                cells,
                omega,
                beta_hat,
                memory,
            )?
            else {
                return Ok(history);
            };
            if e.energy < current.energy {
                accepted = Some(e);
                break;
            }
            lambda *= 0.5;
        }
        let Some(e) = accepted else {
            on_iteration(it + 1, traj, &history);
            log::debug!("global optimisation: no step lowers the energy after {it} iterations");
            break;
        };
        // The step evaluated, taken in place (the same values the trial had).
        for f in 0..traj.frames {
            let step = current.gradient.get(f)?;
            for (p, g) in traj.frame_mut(f).iter_mut().zip(step.iter()) {
                *p -= g * lambda;
            }
        }
        history.push(Iteration {
            energy: e.energy,
            smooth: e.smooth,
            data: e.data,
            lambda,
        });
        current = e;
        if !on_iteration(it + 1, traj, &history) {
            break;
        }
    }
    Ok(history)
}
