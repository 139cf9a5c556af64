//! Affinity weights between centers (docs/method.md §5): who moves with whom.
//!
//! Kept sparse: each center lists the centers whose weight is at least μ. The
//! maximum-distance weights only ever decrease, so lists only shrink. The IIR
//! weights can grow again, so that variant keeps its filter state for every
//! pair (N² floats, updated once per frame, never in the iteration loop) and
//! rebuilds the lists from it.

use crate::math::{Matrix3, Point3, Real};
use crate::model::Rigid;
use crate::params::{sigma_for, AffinityKind};
use crate::spatial::cells::CellMoments;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// One directed neighbour entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbor {
    /// The neighbour's center index.
    pub j: u32,
    /// Current weight w(i, j).
    pub w: Real,
    /// max over frames of ||c_i - c_j||² (max affinity only).
    pub max_d2: Real,
    /// max over frames of the motion dissimilarity d² (max affinity only).
    pub max_m2: Real,
}

/// Mean squared difference of two rigid motions over a cell:
/// d_i(A_i, A_j)² = mean_{v in V_i} ||A_i(v) - A_j(v)||², in closed form
/// tr(Dᵀ D Σ) + ||D m + e||² with D = R_i - R_j, e = t_i - t_j and the cell's
/// mean m and covariance Σ.
pub fn motion_dissimilarity2(cell: &CellMoments, a: &Rigid, b: &Rigid) -> Real {
    let d = a.rotation - b.rotation;
    let e = a.translation - b.translation;
    let spread = (d.transpose() * d * cell.covariance).trace();
    let offset = d * cell.mean.coords + e;
    (spread + offset.norm_squared()).max(0.0)
}

/// [`motion_dissimilarity2`] of one cell under its own motion A_i against
/// many other motions A_j, with what depends on the cell and A_i taken
/// once: the refinement measures every center against hundreds of
/// neighbours in every frame. With rotations R_i and R_j, DᵀD = 2I − R_iᵀR_j
/// − R_jᵀR_i, so tr(DᵀDΣ) = 2 tr Σ − 2 ⟨R_j, R_i Σ⟩ (Frobenius, Σ symmetric),
/// and D m + e = A_i(m) − A_j(m): one matrix product per pair instead of three.
pub struct CellMotion {
    trace: Real,
    turned: Matrix3,
    mean: Point3,
    moved_mean: Point3,
}

impl CellMotion {
    /// The cell `cell` under its own motion `own`.
    pub fn new(cell: &CellMoments, own: &Rigid) -> Self {
        CellMotion {
            trace: cell.covariance.trace(),
            turned: own.rotation * cell.covariance,
            mean: cell.mean,
            moved_mean: own.apply(&cell.mean),
        }
    }

    /// d_i(A_i, `other`)², as [`motion_dissimilarity2`] gives it up to rounding.
    pub fn dissimilarity2(&self, other: &Rigid) -> Real {
        let spread = 2.0 * (self.trace - other.rotation.dot(&self.turned));
        (spread + (self.moved_mean - other.apply(&self.mean)).norm_squared()).max(0.0)
    }
}

/// The affinity state carried from frame to frame.
#[derive(Clone, Debug)]
pub struct Affinity {
    kind: AffinityKind,
    sigma_p: Real,
    sigma_m: Real,
    alpha: Real,
    mu: Real,
    pub(super) lists: Vec<Vec<Neighbor>>,
    /// IIR only: a_IIR for every ordered pair, row-major.
    pub(super) iir: Vec<f32>,
}

impl Affinity {
    /// Frame 0: positional weights only. `rho_p`, `rho_m` in the input's units.
    pub fn initial(
        centers: &[Point3],
        kind: AffinityKind,
        rho_p: Real,
        rho_m: Real,
        alpha: Real,
        mu: Real,
    ) -> Self {
        let iir = if kind == AffinityKind::Iir {
            vec![1.0; centers.len() * centers.len()]
        } else {
            Vec::new()
        };
        let mut a = Affinity::restore(kind, rho_p, rho_m, alpha, mu, Vec::new(), iir);
        a.lists = a.positional_lists(centers, |_, _| 1.0);
        a
    }

    /// The state saved by a checkpoint, put back (see `super::checkpoint`).
    pub(super) fn restore(
        kind: AffinityKind,
        rho_p: Real,
        rho_m: Real,
        alpha: Real,
        mu: Real,
        lists: Vec<Vec<Neighbor>>,
        iir: Vec<f32>,
    ) -> Self {
        Affinity {
            kind,
            sigma_p: sigma_for(rho_p),
            sigma_m: sigma_for(rho_m),
            alpha,
            mu,
            lists,
            iir,
        }
    }

    /// Lists of every j with exp(-σ_p d²) · extra(i, j) >= μ.
    fn positional_lists(
        &self,
        centers: &[Point3],
        extra: impl Fn(usize, usize) -> Real + Sync,
    ) -> Vec<Vec<Neighbor>> {
        within_reach(centers, self.sigma_p, self.mu)
            .into_par_iter()
            .enumerate()
            .map(|(i, found)| {
                found
                    .into_iter()
                    .filter_map(|j| {
                        let d2 = (centers[i] - centers[j as usize]).norm_squared();
                        let w = (-self.sigma_p * d2).exp() * extra(i, j as usize);
                        (w >= self.mu).then_some(Neighbor {
                            j,
                            w,
                            max_d2: d2,
                            max_m2: 0.0,
                        })
                    })
                    .collect()
            })
            .collect()
    }

    /// Center i's neighbours (itself included), ordered by index.
    pub fn neighbors(&self, i: usize) -> &[Neighbor] {
        &self.lists[i]
    }

    /// Weighted index pairs for the rigid fits ([`crate::model::RigidFits`]).
    pub fn pairs(&self, i: usize) -> impl Iterator<Item = (usize, Real)> + Clone + '_ {
        self.lists[i].iter().map(|n| (n.j as usize, n.w))
    }

    /// Average list length, for diagnostics.
    pub fn mean_neighbors(&self) -> Real {
        self.lists.iter().map(Vec::len).sum::<usize>() as Real / self.lists.len().max(1) as Real
    }

    /// Folds in frame f's result: center positions, each center's rigid
    /// motion from f-1 to f, and each cell's moments in frame f.
    pub fn update(&mut self, centers: &[Point3], motions: &[Rigid], cells: &[Option<CellMoments>]) {
        match self.kind {
            AffinityKind::Max => {
                let (sp, sm, mu) = (self.sigma_p, self.sigma_m, self.mu);
                self.lists.par_iter_mut().enumerate().for_each(|(i, list)| {
                    for n in list.iter_mut() {
                        let j = n.j as usize;
                        n.max_d2 = n.max_d2.max((centers[i] - centers[j]).norm_squared());
                        if let Some(cell) = &cells[i] {
                            n.max_m2 =
                                n.max_m2
                                    .max(motion_dissimilarity2(cell, &motions[i], &motions[j]));
                        }
                        n.w = (-sp * n.max_d2).exp() * (-sm * n.max_m2).exp();
                    }
                    list.retain(|n| n.w >= mu);
                });
            }
            AffinityKind::Iir => {
                let n = centers.len();
                let (sm, alpha) = (self.sigma_m, self.alpha);
                self.iir.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
                    let Some(cell) = &cells[i] else { return };
                    for (j, a) in row.iter_mut().enumerate() {
                        let am =
                            (-sm * motion_dissimilarity2(cell, &motions[i], &motions[j])).exp();
                        *a = (alpha * am + (1.0 - alpha) * *a as Real) as f32;
                    }
                });
                let iir = std::mem::take(&mut self.iir);
                self.lists = self.positional_lists(centers, |i, j| iir[i * n + j] as Real);
                self.iir = iir;
            }
        }
    }
}

/// For each center, every center (itself included, ascending) whose Gaussian
/// weight exp(-σ d²) at their distance in `centers` is at least μ: the only
/// candidates of a weight that is that Gaussian times factors <= 1.
pub(crate) fn within_reach(centers: &[Point3], sigma: Real, mu: Real) -> Vec<Vec<u32>> {
    let radius2 = -mu.ln() / sigma;
    let points: Vec<[Real; 3]> = centers.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree = ImmutableKdTree::<Real, 3>::new_from_slice(&points).expect("finite centers");
    points
        .par_iter()
        .map(|p| {
            let mut found: Vec<u32> = tree
                .query(p)
                .within::<SquaredEuclidean<Real>>(radius2)
                .execute()
                .into_iter()
                .map(|r| r.item)
                .collect();
            found.sort_unstable();
            found
        })
        .collect()
}
