//! The temporally global optimisation (method.md §7): gradient steps on
//! Ê = Ês + β̂ Êu over all frames at once, with a halving line search.

use super::affinity::SparseAffinity;
use super::cells::SequenceCells;
use crate::math::{Point3, Real, Vector3};
use crate::model::Trajectories;
use crate::model::GridSpec;
use rayon::prelude::*;

/// Ê at one set of trajectories, with what its gradient needs.
pub struct Evaluation {
    pub energy: Real,
    pub smooth: Real,
    pub data: Real,
    /// ∇Ês + β̂ ∇Êu with predictions and centroids held fixed, frame-major.
    pub gradient: Vec<Vector3>,
}

/// One accepted or final step of the optimisation.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Iteration {
    pub energy: Real,
    pub smooth: Real,
    pub data: Real,
    /// Step accepted (0 for the starting point).
    pub lambda: Real,
}

/// Evaluates Ê at `traj`: Voronoi centroids x̄ of every frame, forward
/// predictions p^f = A^f(c^{f-1}) and backward q^f = (A^{f+1})⁻¹(c^{f+1}),
/// where A^f is each center's motion from f-1 to f fitted under `omega`.
pub fn evaluate(traj: &Trajectories, grid: &GridSpec, cells: &mut SequenceCells, omega: &SparseAffinity, beta_hat: Real) -> Evaluation {
    let (frames, n) = (traj.frames, traj.centers);
    let stats = cells.update(traj, false);
    // The motion A^f carries frame f-1 to f; only what it predicts is kept,
    // 48 bytes per center and frame instead of the motion's 96: forward[f-1]
    // is A^f(c^{f-1}), backward[f-1] is (A^f)⁻¹(c^f).
    let (forward, backward): (Vec<Vec<Point3>>, Vec<Vec<Point3>>) = (1..frames)
        .into_par_iter()
        .map(|f| {
            let motions = omega.fit_frames(traj, f - 1, f);
            let forward = motions.iter().enumerate().map(|(i, a)| a.apply(&traj.get(f - 1, i))).collect();
            let backward = motions.iter().enumerate().map(|(i, a)| a.inverse().apply(&traj.get(f, i))).collect();
            (forward, backward)
        })
        .unzip();
    let mut gradient = vec![Vector3::zeros(); frames * n];
    // Each frame's gradient written in place; its energy terms summed after, in frame order.
    let per_frame: Vec<(Real, Real)> = gradient
        .par_chunks_mut(n.max(1))
        .enumerate()
        .map(|(f, grad)| {
            let (mut smooth, mut data) = (0.0, 0.0);
            for (i, g) in grad.iter_mut().enumerate() {
                let c = traj.get(f, i);
                if let Some(x) = stats[f].centroid(i, grid) {
                    let r = c - x;
                    data += 0.5 * r.norm_squared();
                    *g += beta_hat * r;
                }
                if f >= 1 {
                    let r = c - forward[f - 1][i];
                    smooth += 0.5 * r.norm_squared();
                    *g += r;
                }
                if f + 1 < frames {
                    let r = c - backward[f][i];
                    smooth += 0.5 * r.norm_squared();
                    *g += r;
                }
            }
            (smooth, data)
        })
        .collect();
    let mut smooth = 0.0;
    let mut data = 0.0;
    for (s, d) in per_frame {
        smooth += s;
        data += d;
    }
    Evaluation { energy: smooth + beta_hat * data, smooth, data, gradient }
}

/// Gradient descent with λ halved until the energy drops; stops after
/// `max_iterations`, when no halving helps, or when `on_iteration` (called
/// with the iterations done, the trajectories and the history so far, to
/// report or save them) returns false. Returns the energy before and after
/// every accepted step.
pub fn optimise(
    traj: &mut Trajectories,
    grid: &GridSpec,
    cells: &mut SequenceCells,
    omega: &SparseAffinity,
    beta_hat: Real,
    lambda0: Real,
    max_iterations: usize,
    max_halvings: usize,
    mut on_iteration: impl FnMut(usize, &Trajectories, &[Iteration]) -> bool,
) -> Vec<Iteration> {
    let mut current = evaluate(traj, grid, cells, omega, beta_hat);
    let mut history = vec![Iteration { energy: current.energy, smooth: current.smooth, data: current.data, lambda: 0.0 }];
    for it in 0..max_iterations {
        let mut lambda = lambda0;
        let mut accepted = None;
        for _ in 0..=max_halvings {
            let mut trial = traj.clone();
            for (p, g) in trial.positions.iter_mut().zip(&current.gradient) {
                *p -= g * lambda;
            }
            let e = evaluate(&trial, grid, cells, omega, beta_hat);
            if e.energy < current.energy {
                accepted = Some((trial, e));
                break;
            }
            lambda *= 0.5;
        }
        let Some((trial, e)) = accepted else {
            on_iteration(it + 1, traj, &history);
            log::debug!("global optimisation: no step lowers the energy after {it} iterations");
            break;
        };
        *traj = trial;
        history.push(Iteration { energy: e.energy, smooth: e.smooth, data: e.data, lambda });
        current = e;
        if !on_iteration(it + 1, traj, &history) {
            break;
        }
    }
    history
}
