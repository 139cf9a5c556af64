//! The affinity of the global optimisation, from the whole sequence at once
//! (docs/method.md §7): ω_max from the largest distance over all frames, rigid
//! motions fitted with it, then ω from the largest motion dissimilarity.

use super::cells::{frame_blocks, SequenceCells};
use crate::math::Real;
use crate::model::{PairTable, Rigid, Trajectories};
use crate::params::sigma_for;
use crate::track::affinity::{within_reach, CellMotion};
use crate::track::cell_moments;
use crate::voxel::VoxelSequence;
use rayon::prelude::*;

/// Sparse symmetric-in-spirit, directed-in-fact weights: `lists[i]` holds
/// (j, weight) for every j with weight >= μ, ordered by j, i itself included.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SparseAffinity {
    /// Per center i, (j, ω(i, j)) for the centers j it is tied to.
    pub lists: Vec<Vec<(u32, Real)>>,
}

impl SparseAffinity {
    /// Center i's list as (j, weight).
    pub fn pairs(&self, i: usize) -> impl Iterator<Item = (usize, Real)> + Clone + '_ {
        self.lists[i].iter().map(|&(j, w)| (j as usize, w))
    }

    /// ω(i, j); 0 when j is not in i's list.
    pub fn weight(&self, i: usize, j: usize) -> Real {
        self.lists[i]
            .binary_search_by_key(&(j as u32), |e| e.0)
            .map_or(0.0, |k| self.lists[i][k].1)
    }

    /// Mean length of the lists (i itself included).
    pub fn mean_neighbors(&self) -> Real {
        self.lists.iter().map(Vec::len).sum::<usize>() as Real / self.lists.len().max(1) as Real
    }

    /// Rigid motions of every center from frame `from` to frame `to`.
    pub(crate) fn fit_frames(&self, traj: &Trajectories, from: usize, to: usize) -> Vec<Rigid> {
        debug_assert_eq!(self.lists.len(), traj.centers);
        let table = PairTable::new(traj.frame(from), traj.frame(to));
        self.lists.par_iter().map(|list| table.fit(list)).collect()
    }
}

/// ω_max(i, j) = exp(-σ_gp max_f ||c_i^f - c_j^f||²), pruned at μ. The
/// maximum is at least the frame-0 distance, so a radius query in frame 0
/// finds every candidate.
pub(crate) fn max_distance_affinity(traj: &Trajectories, rho_gp: Real, mu: Real) -> SparseAffinity {
    let sigma = sigma_for(rho_gp);
    let lists = within_reach(traj.frame(0), sigma, mu)
        .into_par_iter()
        .enumerate()
        .map(|(i, js)| {
            js.into_iter()
                .filter_map(|j| {
                    let d2 = (0..traj.frames)
                        .map(|f| (traj.get(f, i) - traj.get(f, j as usize)).norm_squared())
                        .fold(0.0, Real::max);
                    let w = (-sigma * d2).exp();
                    (w >= mu).then_some((j, w))
                })
                .collect()
        })
        .collect();
    SparseAffinity { lists }
}

/// ω(i, j) = exp(-σ_gm max_f d_i^f(A_i, A_j)²) over the pairs ω_max keeps,
/// with A the motions from f-1 to f fitted under ω_max and d_i over cell
/// V_i^f. Restricting to ω_max's pairs keeps it sparse: centers never within
/// reach of each other do not steer each other's fits.
pub fn global_affinity(
    traj: &Trajectories,
    seq: &VoxelSequence,
    cells: &mut SequenceCells,
    rho_gp: Real,
    rho_gm: Real,
    mu: Real,
) -> SparseAffinity {
    let omega_max = max_distance_affinity(traj, rho_gp, mu);
    let sigma = sigma_for(rho_gm);
    let mut worst: Vec<Vec<Real>> = omega_max.lists.iter().map(|l| vec![0.0; l.len()]).collect();
    // A block of frames' cell moments at a time, not the whole sequence's.
    for block in frame_blocks(1..traj.frames) {
        let stats = cells.update_frames(traj, 0, block.clone(), true);
        for f in block.clone() {
            let motions = omega_max.fit_frames(traj, f - 1, f);
            let moments = cell_moments(&stats[f - block.start], &seq.grid);
            worst.par_iter_mut().enumerate().for_each(|(i, row)| {
                let Some(cell) = &moments[i] else { return };
                let cell = CellMotion::new(cell, &motions[i]);
                for (k, &(j, _)) in omega_max.lists[i].iter().enumerate() {
                    row[k] = row[k].max(cell.dissimilarity2(&motions[j as usize]));
                }
            });
        }
    }
    let lists = omega_max
        .lists
        .iter()
        .zip(&worst)
        .map(|(l, row)| {
            l.iter()
                .zip(row)
                .filter_map(|(&(j, _), &m2)| {
                    let w = (-sigma * m2).exp();
                    (w >= mu).then_some((j, w))
                })
                .collect()
        })
        .collect();
    SparseAffinity { lists }
}
