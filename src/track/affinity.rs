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
    #[cfg(test)]
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Rotation3, Vector3};
    use crate::test_support::Lcg;

    #[test]
    fn motion_dissimilarity_matches_its_definition() {
        let mut g = Lcg(4);
        let pts: Vec<Point3> = (0..40)
            .map(|_| Point3::from(g.vec(2.0) + Vector3::new(5.0, 0.0, 0.0)))
            .collect();
        let n = pts.len() as Real;
        let mean = Point3::from(pts.iter().map(|p| p.coords).sum::<Vector3>() / n);
        let covariance = pts
            .iter()
            .map(|p| (p - mean) * (p - mean).transpose())
            .sum::<Matrix3>()
            / n;
        let cell = CellMoments {
            count: 40,
            mean,
            covariance,
        };
        for k in 0..40 {
            let a = g.rigid();
            // Half of them nearly alike, where the refinement's form subtracts
            // nearly equal terms.
            let b = if k % 2 == 0 {
                g.rigid()
            } else {
                Rigid {
                    rotation: Rotation3::new(g.vec(1e-4)).matrix() * a.rotation,
                    translation: a.translation + g.vec(1e-4),
                }
            };
            let direct: Real = pts
                .iter()
                .map(|p| (a.apply(p) - b.apply(p)).norm_squared())
                .sum::<Real>()
                / n;
            let closed = motion_dissimilarity2(&cell, &a, &b);
            assert!(
                (direct - closed).abs() < 1e-9 * direct.max(1.0),
                "{direct} vs {closed}"
            );
            let once = CellMotion::new(&cell, &a).dissimilarity2(&b);
            assert!(
                (direct - once).abs() < 1e-9 * direct.max(1.0),
                "{direct} vs {once}"
            );
        }
    }

    /// Weights after a few frames, from the formulas of docs/method.md §5 evaluated
    /// directly over the whole history.
    #[test]
    fn both_affinities_match_their_formulas() {
        let mut g = Lcg(5);
        let n = 8;
        let (rho_p, rho_m, alpha, mu) = (1.5, 0.4, 0.3, 1e-6);
        let (sp, sm) = (sigma_for(rho_p), sigma_for(rho_m));
        let frames: Vec<Vec<Point3>> = (0..4)
            .map(|_| (0..n).map(|_| Point3::from(g.vec(2.0))).collect())
            .collect();
        let motions: Vec<Vec<Rigid>> = (0..4)
            .map(|_| (0..n).map(|_| g.rigid()).collect())
            .collect();
        let cells: Vec<Vec<Option<CellMoments>>> = (0..4)
            .map(|_| {
                (0..n)
                    .map(|_| {
                        let a = g.vec(0.3);
                        Some(CellMoments {
                            count: 5,
                            mean: Point3::from(g.vec(2.0)),
                            covariance: a * a.transpose() + Matrix3::identity() * 0.01,
                        })
                    })
                    .collect()
            })
            .collect();
        for kind in [AffinityKind::Max, AffinityKind::Iir] {
            let mut aff = Affinity::initial(&frames[0], kind, rho_p, rho_m, alpha, mu);
            for f in 1..4 {
                aff.update(&frames[f], &motions[f], &cells[f]);
            }
            for i in 0..n {
                for j in 0..n {
                    let d2 = |f: usize| (frames[f][i] - frames[f][j]).norm_squared();
                    let m2 = |f: usize| {
                        motion_dissimilarity2(
                            cells[f][i].as_ref().unwrap(),
                            &motions[f][i],
                            &motions[f][j],
                        )
                    };
                    let expected = match kind {
                        AffinityKind::Max => {
                            let maxd = (0..4).map(d2).fold(0.0, Real::max);
                            let maxm = (1..4).map(m2).fold(0.0, Real::max);
                            (-sp * maxd).exp() * (-sm * maxm).exp()
                        }
                        AffinityKind::Iir => {
                            let mut a = 1.0;
                            for f in 1..4 {
                                a = alpha * (-sm * m2(f)).exp() + (1.0 - alpha) * a;
                            }
                            (-sp * d2(3)).exp() * a
                        }
                    };
                    let got = aff
                        .neighbors(i)
                        .iter()
                        .find(|nb| nb.j as usize == j)
                        .map_or(0.0, |nb| nb.w);
                    let tol = if kind == AffinityKind::Iir {
                        1e-6
                    } else {
                        1e-12
                    };
                    if expected >= mu * 1.01 {
                        assert!(
                            (got - expected).abs() < tol,
                            "{kind:?} w({i},{j}) = {got}, expected {expected}"
                        );
                    } else {
                        assert!(
                            got < mu * 1.01 + tol,
                            "{kind:?} w({i},{j}) = {got} should be pruned"
                        );
                    }
                }
            }
        }
    }
}
