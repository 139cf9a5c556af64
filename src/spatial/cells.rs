//! Voronoi assignment of occupied voxels to their nearest center, and the
//! per-cell sums the tracker needs.
//!
//! Centers move little between iterations, which these exact shortcuts exploit:
//! - Hamerly's bounds: each voxel keeps an upper bound on the distance to its
//!   center and a lower bound on the distance to any other; moving centers
//!   loosen them by how far they moved, and while upper < lower the owner
//!   cannot have changed, so the voxel is skipped.
//! - Candidate lists: a voxel that must be searched tries its previous center
//!   o and o's K nearest centers. The best of those is provably the nearest
//!   when d_b < r_K(o) - |v - o| (r_K(o): distance from o to its K-th nearest
//!   center; any center outside the list is at least that far from v by the
//!   triangle inequality). Otherwise the list's extension to the 48 nearest
//!   tries the same with r_48(o), and only then does a k-d tree answer.
//!   The lists outlive an iteration ([`CenterIndex::moved_to`]): a center
//!   outside o's list was at least r_K(o) from o when the list was built,
//!   and since then the two have moved at most o's own travel plus, per
//!   iteration, the largest move among all centers but the FAST fastest, so
//!   r_K shrinks by that much. The fastest few (centers thrown out of the
//!   volume move far) are measured against every list instead, and a list
//!   they enter is dropped. (Counting the largest move of all in the shrink
//!   instead would let those few centers shrink every list's reach, so lists
//!   would be rebuilt, and voxels searched, far more often.)
//! - Local decay of the lower bound: Hamerly lowers every voxel's lower
//!   bound by the largest move of any center, so one fast center makes every
//!   voxel look again. With o's list in hand, a voxel of o needs only two
//!   terms: the centers in the list moved at most their own largest move, and
//!   every center outside it is at least r_K(o) - |v - o| away anyway.
//!
//! Ties are broken by the lower center index, so the result does not depend
//! on the number of threads. The shortcuts are tested against a linear scan.
//!
//! [`Assignment::blocks`] assigns cubes of voxels instead, each whole by its
//! voxels' centroid (the tracker's screening of its guesses, when asked).

use crate::math::{Point3, Real};
use crate::model::GridSpec;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::iter::Either;
use rayon::prelude::*;
use std::num::NonZeroUsize;
use std::sync::OnceLock;

/// No hint for this voxel.
pub const NO_OWNER: u32 = u32::MAX;

/// Candidate-list length K.
const CANDIDATES: usize = 16;

/// Length of the extended list tried when the first K do not certify.
const CANDIDATES_FAR: usize = 48;

/// Voxels per parallel work unit.
const CHUNK: usize = 8192;

/// Nearest-center queries over one set of center positions.
pub struct CenterIndex {
    /// Built on first use: once the centers have settled, the candidate
    /// lists answer nearly every query.
    tree: OnceLock<ImmutableKdTree<Real, 3>>,
    points: Vec<[Real; 3]>,
    /// Each center's candidate list, built on first use: most voxels never
    /// need one once the centers have settled.
    knn: Vec<OnceLock<Candidates>>,
    k: usize,
    k_far: usize,
    /// How far each center has moved, summed over [`CenterIndex::moved_to`] calls.
    travel: Vec<Real>,
    /// Per call, the largest move of any center but its FAST fastest,
    /// summed: no center moved farther, except while checked one by one.
    travel_cap: Real,
    /// Set by [`CenterIndex::moved_to`], per center: how its voxels' bounds
    /// loosen after that move; None for a fresh index, whose voxels' lower
    /// bounds fall by the largest move.
    local: Option<Vec<Loosening>>,
}

impl Clone for CenterIndex {
    /// Without the k-d tree, rebuilt on first use (as after every move).
    fn clone(&self) -> Self {
        CenterIndex {
            tree: OnceLock::new(),
            points: self.points.clone(),
            knn: self.knn.clone(),
            k: self.k,
            k_far: self.k_far,
            travel: self.travel.clone(),
            travel_cap: self.travel_cap,
            local: self.local.clone(),
        }
    }
}

/// How the bounds of a voxel of center o loosen after a move.
#[derive(Clone, Copy, Debug)]
struct Loosening {
    /// o's own move: the upper bound grows by it.
    moved: Real,
    /// The largest move among o's candidates (the largest of all when o had
    /// no list, or its list was dropped).
    decay: Real,
    /// r_K(o) now; infinite when o had no list (decay then covers everyone).
    reach: Real,
    /// The largest move of any center.
    max_move: Real,
}

impl Loosening {
    /// Hamerly's bound alone: no center moved farther than `max_move`.
    fn everyone(moved: Real, max_move: Real) -> Self {
        Loosening {
            moved,
            decay: max_move,
            reach: Real::INFINITY,
            max_move,
        }
    }

    /// The lower bound `lower` after the move, for a voxel whose distance
    /// to o is now at most `upper`.
    #[inline]
    fn lowered(&self, lower: Real, upper: Real) -> Real {
        // Both bounds hold; far from o, where the list proves little,
        // Hamerly's may be the better. Comparisons rather than min and max,
        // whose NaN handling costs instructions on every voxel measured;
        // no operand is NaN (the bounds are finite or infinite, the terms
        // finite but an infinite reach).
        let (a, b, c) = (
            lower - self.decay,
            self.reach - upper,
            lower - self.max_move,
        );
        let m = if a < b { a } else { b };
        if m > c {
            m
        } else {
            c
        }
    }
}

/// [`Loosening`] in f32, rounded so that the bounds stay valid, for the
/// pass over every voxel: the bounds are stored in f32, and the same pass in
/// f64 spends its time converting them and branching, a cost paid for every
/// voxel in every iteration.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Loosening32 {
    moved: f32,
    decay: f32,
    reach: f32,
    max_move: f32,
}

/// Factors that cover the f32 rounding of [`Loosening32::loosen`]: each of
/// its few operations errs by at most 2^-24 relative, and the bounds it
/// compares are positive.
const GROW: f32 = 1.0 + 1.0 / (1u32 << 20) as f32;
const SHRINK: f32 = 1.0 - 1.0 / (1u32 << 20) as f32;

fn round_up(x: Real) -> f32 {
    let f = x as f32;
    if (f as Real) < x {
        f.next_up()
    } else {
        f
    }
}

fn round_down(x: Real) -> f32 {
    let f = x as f32;
    if (f as Real) > x {
        f.next_down()
    } else {
        f
    }
}

impl From<&Loosening> for Loosening32 {
    fn from(b: &Loosening) -> Self {
        Loosening32 {
            moved: round_up(b.moved),
            decay: round_up(b.decay),
            reach: round_down(b.reach),
            max_move: round_up(b.max_move),
        }
    }
}

impl Loosening32 {
    /// The bounds (`upper`, `lower`) after the move. The owner still holds
    /// when upper < lower; otherwise the loosened bounds may be NaN or
    /// meaningless, and the voxel must be measured.
    ///
    /// Valid because the move terms are rounded outwards, the upper bound is
    /// raised by 2^-20 relative after its one addition, and the lower bound,
    /// positive whenever it proves anything, is lowered by as much after its
    /// subtractions (whose relative errors the min and max keep).
    #[inline(always)]
    fn loosen(&self, upper: f32, lower: f32) -> (f32, f32) {
        // Comparisons rather than f32::min/max, whose NaN handling costs
        // instructions here; a NaN (from an infinite upper bound) only fails
        // the test u < l.
        let u = (upper + self.moved) * GROW;
        (u, self.lowered(lower, u))
    }

    /// A lower bound after the move (`lower`, or another one of the same
    /// voxel) given the voxel's upper bound after it, `upper`
    /// ([`Loosening32::loosen`]'s first).
    #[inline(always)]
    fn lowered(&self, lower: f32, upper: f32) -> f32 {
        let (a, b) = (lower - self.decay, self.reach - upper);
        let m = if a < b { a } else { b };
        let c = lower - self.max_move;
        (if m > c { m } else { c }) * SHRINK
    }
}

/// The `k` nearest centers of a center (itself first), the distance to the
/// k-th (infinite when the list holds every center) and the travel counters
/// when the list was built.
///
/// The list is extended to the `CANDIDATES_FAR` nearest: the first K serve
/// nearly every search, and the rest, with their own reach, settle most of
/// those the first K cannot without the k-d tree, whose query costs many
/// list searches.
#[derive(Clone)]
struct Candidates {
    list: Box<[u32]>,
    /// The first `near` of `list` are the K nearest, with reach `reach`;
    /// `reach_far` is the whole list's.
    near: usize,
    reach: Real,
    reach_far: Real,
    travel: Real,
    travel_cap: Real,
}

#[inline]
fn squared_distance(a: &[Real; 3], b: &[Real; 3]) -> Real {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Centers checked one by one when lists are carried over a move.
const FAST: usize = 32;

impl Candidates {
    /// How the bounds of this list's center's voxels loosen after the
    /// centers moved by `moved` (its own by `own_move`), with `reach` the
    /// list's r_K now.
    fn loosening(&self, own_move: Real, moved: &[Real], reach: Real, max_move: Real) -> Loosening {
        Loosening {
            moved: own_move,
            decay: self.list[..self.near]
                .iter()
                .map(|&j| moved[j as usize])
                .fold(0.0, Real::max),
            reach,
            max_move,
        }
    }

    /// Whether center j, unless in the list of center o, is beyond both
    /// reaches shrunk by `shrink`.
    fn keeps_out(&self, j: u32, o: usize, points: &[[Real; 3]], shrink: Real) -> bool {
        let d2 = squared_distance(&points[j as usize], &points[o]);
        let beyond = |reach: Real| reach - shrink <= 0.0 || d2 >= (reach - shrink).powi(2);
        (beyond(self.reach) || self.list[..self.near].contains(&j))
            && (beyond(self.reach_far) || self.list.contains(&j))
    }

    /// How much the reaches have shrunk since the list was built: the
    /// center's own travel and the most any other center can have travelled
    /// (but the fastest, checked one by one).
    #[inline]
    fn shrink(&self, travel: Real, travel_cap: Real) -> Real {
        (travel - self.travel) + (travel_cap - self.travel_cap)
    }
}

impl CenterIndex {
    /// The index over `centers`; its k-d tree and candidate lists are built
    /// when first needed.
    pub fn new(centers: &[Point3]) -> Self {
        let points: Vec<[Real; 3]> = centers.iter().map(|p| [p.x, p.y, p.z]).collect();
        let n = points.len();
        CenterIndex {
            tree: OnceLock::new(),
            points,
            knn: (0..n).map(|_| OnceLock::new()).collect(),
            k: CANDIDATES.min(n),
            k_far: CANDIDATES_FAR.min(n),
            travel: vec![0.0; n],
            travel_cap: 0.0,
            local: None,
        }
    }

    /// The index over `centers`, which are this index's centers moved by
    /// `moved[i]` each: candidate lists that still certify most queries are
    /// kept, with their reach shrunk by how far their centers may have moved.
    pub fn moved_to(mut self, centers: &[Point3], moved: &[Real]) -> Self {
        assert_eq!(centers.len(), self.points.len());
        assert_eq!(moved.len(), self.points.len());
        for (p, c) in self.points.iter_mut().zip(centers) {
            *p = [c.x, c.y, c.z];
        }
        for (t, m) in self.travel.iter_mut().zip(moved) {
            *t += m;
        }
        let max_move = moved.iter().copied().fold(0.0, Real::max);
        // The FAST centers that moved most (often thrown out of the volume,
        // moving far) are checked one by one against every list below; every
        // other center moved at most the next largest move, which is all the
        // reaches lose to them.
        let fast = FAST.min(moved.len().saturating_sub(1));
        let mut order: Vec<u32> = (0..moved.len() as u32).collect();
        if !order.is_empty() {
            order.select_nth_unstable_by(fast, |a, b| {
                moved[*b as usize].total_cmp(&moved[*a as usize])
            });
            self.travel_cap += moved[order[fast] as usize];
        }
        let fast = &order[..fast];
        self.tree = OnceLock::new();
        let (points, travel_cap) = (&self.points, self.travel_cap);
        let local = self
            .knn
            .par_iter_mut()
            .zip(&self.travel)
            .zip(moved)
            .enumerate()
            .map(|(o, ((slot, &travel), &own_move))| {
                // Rebuilt (on demand) once a tenth of its reach is used up: a
                // shrunk reach certifies fewer voxels and sends them to the
                // slow k-d tree path, which costs more than an early rebuild.
                let kept = slot
                    .get()
                    .map(|c| (c, c.shrink(travel, travel_cap)))
                    .filter(|(c, shrink)| {
                        c.reach - shrink >= 0.9 * c.reach
                            && fast.iter().all(|&j| c.keeps_out(j, o, points, *shrink))
                    })
                    .map(|(c, shrink)| (c, c.reach - shrink));
                match kept.map(|(c, reach)| c.loosening(own_move, moved, reach, max_move)) {
                    Some(loosening) => Ok(loosening),
                    // Its members bound the new list's search.
                    None => Err(slot.take().map(|c| c.list)),
                }
            })
            .collect::<Vec<_>>();
        // The lists dropped are rebuilt around the new positions at once:
        // their K nearest bound the loosening (a voxel's other centers are
        // in the list, each moved at most the list's largest move, or beyond
        // its reach), where Hamerly's largest move of all would send every
        // voxel of the cell to a search.
        let this = &self;
        let local = local
            .into_par_iter()
            .enumerate()
            .map(|(o, kept)| {
                kept.unwrap_or_else(|old| {
                    let c = this.candidates_around(o as u32, old.as_deref());
                    c.loosening(moved[o], moved, c.reach, max_move)
                })
            })
            .collect();
        self.local = Some(local);
        self
    }

    /// Per center, how its voxels' bounds loosen after the move `moved`
    /// (one distance per center; for an index from [`CenterIndex::moved_to`],
    /// the move it was given).
    fn loosening(&self, moved: &[Real]) -> std::borrow::Cow<'_, [Loosening]> {
        match &self.local {
            Some(local) => local.into(),
            None => {
                let max_move = moved.iter().copied().fold(0.0, Real::max);
                moved
                    .iter()
                    .map(|&m| Loosening::everyone(m, max_move))
                    .collect::<Vec<_>>()
                    .into()
            }
        }
    }

    fn tree(&self) -> &ImmutableKdTree<Real, 3> {
        self.tree.get_or_init(|| {
            ImmutableKdTree::new_from_slice(&self.points)
                .expect("building a k-d tree over finite centers")
        })
    }

    fn candidates(&self, i: u32) -> &Candidates {
        self.candidates_around(i, None)
    }

    /// [`CenterIndex::candidates`], the search bounded by `old` (any
    /// centers, such as i's list before a move) when there are enough of
    /// them: the nearest are no farther than the farthest of those, and the
    /// k-d tree then skips what lies beyond instead of sorting it in.
    fn candidates_around(&self, i: u32, old: Option<&[u32]>) -> &Candidates {
        self.knn[i as usize].get_or_init(|| {
            let (p, k) = (
                &self.points[i as usize],
                NonZeroUsize::new(self.k_far).unwrap(),
            );
            let query = self.tree().query(p).nearest_n::<SquaredEuclidean<Real>>(k);
            let bounded = old.filter(|old| old.len() >= self.k_far).map(|old| {
                // Widened by a hair for the rounding of the distances.
                let reach2 = old.iter().map(|&j| self.dist2(j, p)).fold(0.0, Real::max)
                    * (1.0 + 1e-9)
                    + Real::MIN_POSITIVE;
                query
                    .within(reach2)
                    .execute()
                    .into_iter()
                    .map(|r| (r.distance, r.item))
                    .collect::<Vec<(Real, u32)>>()
            });
            let mut found = match bounded {
                Some(found) if found.len() == self.k_far => found,
                _ => query
                    .execute()
                    .into_iter()
                    .map(|r| (r.distance, r.item))
                    .collect(),
            };
            found.sort_by(|a, b| {
                a.0.total_cmp(&b.0)
                    .then((a.1 != i).cmp(&(b.1 != i)))
                    .then(a.1.cmp(&b.1))
            });
            // Any center outside the first m is at least as far as the m-th.
            let reach = |m: usize| {
                if m == self.points.len() {
                    Real::INFINITY
                } else {
                    found[m - 1].0.sqrt()
                }
            };
            let (reach, reach_far) = (reach(self.k), reach(self.k_far));
            Candidates {
                near: self.k,
                reach,
                reach_far,
                list: found.into_iter().map(|r| r.1).collect(),
                travel: self.travel[i as usize],
                travel_cap: self.travel_cap,
            }
        })
    }

    #[inline]
    fn dist2(&self, i: u32, v: &[Real; 3]) -> Real {
        squared_distance(&self.points[i as usize], v)
    }

    /// Nearest center by linear scan: the reference the fast paths are tested against.
    #[cfg(test)]
    pub fn nearest_brute_force(&self, v: &[Real; 3]) -> u32 {
        let mut best = (Real::INFINITY, 0u32);
        for i in 0..self.points.len() as u32 {
            let d = self.dist2(i, v);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// Nearest center from the k-d tree, ties to the lower index.
    pub fn nearest_tree(&self, v: &[Real; 3]) -> u32 {
        let r = self
            .tree()
            .query(v)
            .nearest_one::<SquaredEuclidean<Real>>()
            .execute();
        // The tree may return any of several equidistant centers (common while
        // centers sit on voxel centers); settle ties over all of them.
        let d = self.dist2(r.item, v);
        let reach = d * (1.0 + 1e-9) + Real::MIN_POSITIVE;
        let mut best = (d, r.item);
        for c in self
            .tree()
            .query(v)
            .within::<SquaredEuclidean<Real>>(reach)
            .execute()
        {
            let d = self.dist2(c.item, v);
            if d < best.0 || (d == best.0 && c.item < best.1) {
                best = (d, c.item);
            }
        }
        best.1
    }

    /// Nearest center and bounds on the others' distances, starting from the
    /// hint `o` (a center index, or NO_OWNER).
    #[inline]
    fn nearest2(&self, v: &[Real; 3], hint: u32) -> Found {
        if hint != NO_OWNER && (hint as usize) < self.points.len() {
            match self.nearest_among_candidates(v, hint) {
                Ok(found) => return found,
                // The hint was stale: the best of its list is nearer to v,
                // and so likely to certify with its own list.
                Err(best) if best != hint => {
                    if let Ok(found) = self.nearest_among_candidates(v, best) {
                        return found;
                    }
                }
                Err(_) => {}
            }
        }
        if self.points.len() == 1 {
            return Found {
                owner: 0,
                distance: self.dist2(0, v).sqrt(),
                second: Real::INFINITY,
                runner_up: NO_OWNER,
                third: Real::INFINITY,
            };
        }
        let found = self
            .tree()
            .query(v)
            .nearest_n::<SquaredEuclidean<Real>>(NonZeroUsize::new(2).unwrap())
            .execute();
        let (a, b) = (found[0].item, found[1].item);
        let (da, db) = (self.dist2(a, v), self.dist2(b, v));
        // Clearly nearer than the runner-up: no tie to settle.
        let owner = if db > da * (1.0 + 1e-9) + Real::MIN_POSITIVE {
            a
        } else {
            self.nearest_tree(v)
        };
        // The second distance bounds every center but the owner from below.
        let second = if owner == a { db } else { da.min(db) };
        Found {
            owner,
            distance: self.dist2(owner, v).sqrt(),
            second: second.sqrt(),
            runner_up: NO_OWNER,
            third: Real::INFINITY,
        }
    }

    /// The nearest center among `hint`'s candidates with a lower bound on
    /// every other center's distance, when the list's reach proves it the
    /// nearest of all; otherwise Err with the best candidate.
    #[inline]
    fn nearest_among_candidates(&self, v: &[Real; 3], hint: u32) -> Result<Found, u32> {
        let (mut best, mut second, mut third) = (
            (Real::INFINITY, 0u32),
            (Real::INFINITY, NO_OWNER),
            Real::INFINITY,
        );
        let cand = self.candidates(hint);
        let shrink =
            cand.shrink(self.travel[hint as usize], self.travel_cap) + self.dist2(hint, v).sqrt();
        for (part, reach) in [
            (&cand.list[..cand.near], cand.reach),
            (&cand.list[cand.near..], cand.reach_far),
        ] {
            for &c in part {
                let d = self.dist2(c, v);
                // Branch-free (selects rather than jumps: which candidate
                // wins is unpredictable): d displaces the best, the
                // runner-up or the third, and whichever it displaces moves
                // down one place.
                let wins = d < best.0 || (d == best.0 && c < best.1);
                // The loser of d and the best, then of that and the runner-up.
                let (lose, lose_c) = if wins { best } else { (d, c) };
                let seconds = lose < second.0;
                let drop = if seconds { second.0 } else { lose };
                third = if drop < third { drop } else { third };
                second = (
                    if seconds { lose } else { second.0 },
                    if seconds { lose_c } else { second.1 },
                );
                best = (if wins { d } else { best.0 }, if wins { c } else { best.1 });
            }
            let bound = reach - shrink;
            let d_best = best.0.sqrt();
            // Strict: a center at exactly the bound could tie and win on index.
            if d_best < bound {
                // Every center outside the list is at least `bound` away.
                return Ok(Found {
                    owner: best.1,
                    distance: d_best,
                    second: second.0.sqrt().min(bound),
                    runner_up: second.1,
                    third: third.sqrt().min(bound),
                });
            }
        }
        Err(best.1)
    }

    /// Nearest center (ties to the lower index), from a hint or none.
    #[cfg(test)]
    pub fn nearest(&self, v: &[Real; 3], hint: u32) -> u32 {
        self.nearest2(v, hint).owner
    }

    /// Number of centers.
    pub fn len(&self) -> usize {
        self.points.len()
    }
}

/// A nearest-center search's answer.
#[derive(Clone, Copy, Debug)]
struct Found {
    owner: u32,
    /// The distance to the owner.
    distance: Real,
    /// A lower bound on the distance to every other center.
    second: Real,
    /// A center other than the owner (the nearest of the others when the
    /// search knew it), or NO_OWNER.
    runner_up: u32,
    /// With a runner-up, a lower bound on the distance to every center but
    /// the owner and the runner-up.
    third: Real,
}

/// Per-cell sums over occupied voxels, in integer voxel coordinates so that
/// they are exact and independent of summation order.
#[derive(Clone, Debug, Default)]
pub struct CellStats {
    /// Per cell, the number of its voxels.
    pub count: Vec<u32>,
    /// Per cell, the sum of its voxels' grid coordinates (i, j, k).
    pub sum: Vec<[i64; 3]>,
    /// Σ v vᵀ as (xx, yy, zz, xy, xz, yz), when requested.
    pub second: Option<Vec<[i64; 6]>>,
}

/// Mean and covariance of a cell's voxel centers, in world units.
#[derive(Clone, Copy, Debug)]
pub struct CellMoments {
    /// Voxels in the cell. Nothing in the crate reads it (the tests build
    /// cells with it).
    #[allow(dead_code)]
    pub count: u32,
    /// Centroid of the voxel centers.
    pub mean: Point3,
    /// Covariance of the voxel centers, in squared world units.
    pub covariance: nalgebra::Matrix3<Real>,
}

impl CellStats {
    /// Adds (`sign` 1) or takes away (`sign` -1) the voxels of `block` in
    /// cell `cell` (their count and coordinate sums only).
    fn tally_block(&mut self, cell: usize, block: &Block, sign: i64) {
        self.count[cell] = (self.count[cell] as i64 + sign * block.count as i64) as u32;
        let s = &mut self.sum[cell];
        for (s, b) in s.iter_mut().zip(block.sum) {
            *s += sign * b;
        }
    }

    /// Adds (`sign` 1) or takes away (`sign` -1) the voxel at grid
    /// coordinates `c` in cell `cell`.
    fn tally(&mut self, cell: usize, c: [u16; 3], sign: i64) {
        let [x, y, z] = c.map(|c| c as i64);
        self.tally_block(
            cell,
            &Block {
                count: 1,
                sum: [x, y, z],
            },
            sign,
        );
        if let Some(second) = &mut self.second {
            let q = &mut second[cell];
            q[0] += sign * x * x;
            q[1] += sign * y * y;
            q[2] += sign * z * z;
            q[3] += sign * x * y;
            q[4] += sign * x * z;
            q[5] += sign * y * z;
        }
    }

    /// World centroid of cell i, None when it holds no voxel.
    pub fn centroid(&self, i: usize, grid: &GridSpec) -> Option<Point3> {
        let n = self.count[i];
        (n > 0).then(|| {
            let s = self.sum[i];
            let m = [0, 1, 2].map(|k| s[k] as Real / n as Real + 0.5);
            grid.origin + nalgebra::Vector3::new(m[0], m[1], m[2]) * grid.voxel_size
        })
    }

    /// Mean and covariance of cell i (needs `second`).
    pub fn moments(&self, i: usize, grid: &GridSpec) -> Option<CellMoments> {
        let second = self.second.as_ref()?;
        let mean = self.centroid(i, grid)?;
        let n = self.count[i] as Real;
        let s = self.sum[i].map(|x| x as Real / n);
        let q = second[i].map(|x| x as Real / n);
        // Covariance is shift-invariant: compute it in voxel units, then scale.
        let (xx, yy, zz) = (q[0] - s[0] * s[0], q[1] - s[1] * s[1], q[2] - s[2] * s[2]);
        let (xy, xz, yz) = (q[3] - s[0] * s[1], q[4] - s[0] * s[2], q[5] - s[1] * s[2]);
        let a2 = grid.voxel_size * grid.voxel_size;
        let covariance = nalgebra::Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz) * a2;
        Some(CellMoments {
            count: self.count[i],
            mean,
            covariance,
        })
    }
}

/// A block of a frame's voxels assigned as one: how many, and the sum of
/// their grid coordinates, so that a cell's centroid is exactly that of the
/// voxels of its blocks.
#[derive(Clone, Copy, Debug)]
struct Block {
    count: u32,
    sum: [i64; 3],
}

/// A frame's voxels grouped into cubic blocks, each assigned by its voxels'
/// centroid (see [`Assignment::blocks`]).
#[derive(Clone)]
struct Blocks {
    blocks: Vec<Block>,
    /// Each block's centroid, in world units.
    positions: Vec<[Real; 3]>,
}

/// One frame's voxels with their owners and Hamerly bounds, updated as the
/// centers move.
///
/// 26 bytes per voxel (coordinates, owner, runner-up, three f32 bounds), 18
/// [`without_runner_ups`](Self::without_runner_ups).
#[derive(Clone)]
pub struct Assignment {
    origin: [Real; 3],
    voxel_size: Real,
    /// Grid coordinates of each voxel (of each block's first voxel when the
    /// elements are `blocks`).
    coords: Vec<[u16; 3]>,
    /// Elements that each stand for a block of voxels, when assigned as such.
    blocks: Option<Blocks>,
    /// Per element (voxel, or block when assigned as blocks), the index of
    /// its center as last assigned, or the hint given ([`NO_OWNER`] for none).
    pub owners: Vec<u32>,
    upper: Vec<f32>,
    lower: Vec<f32>,
    /// Per element, the center that was nearest after its owner when it
    /// was last measured (NO_OWNER if not known): an element between two
    /// cells, the common case among those whose bounds fail, is settled by
    /// measuring both instead of searching the owner's candidates.
    runner_up: Vec<u32>,
    /// Per element with a runner-up, a lower bound on the distance to every
    /// center but the owner and the runner-up, loosened as `lower` is.
    third: Vec<f32>,
    /// Slack for the f64 arithmetic on the bounds, in world units (the f32
    /// bounds themselves are rounded outwards).
    eps: Real,
    /// Counts and sums of the cells as last returned, kept up to date from
    /// the voxels that change owner (a tiny share per iteration once the
    /// centers settle) instead of summed afresh.
    sums: Option<CellStats>,
}

impl Assignment {
    /// `hints`: one center index (or NO_OWNER) per voxel.
    pub fn new(grid: &GridSpec, voxels: &[u32], hints: Vec<u32>) -> Self {
        assert_eq!(voxels.len(), hints.len());
        let coords = voxels
            .iter()
            .map(|&v| grid.voxel_coords(v as usize).map(|c| c as u16))
            .collect();
        let n = voxels.len();
        Assignment {
            origin: grid.origin.coords.into(),
            voxel_size: grid.voxel_size,
            coords,
            blocks: None,
            owners: hints,
            upper: vec![f32::INFINITY; n],
            lower: vec![f32::NEG_INFINITY; n],
            runner_up: vec![NO_OWNER; n],
            third: vec![f32::NEG_INFINITY; n],
            eps: grid.voxel_size * 1e-9,
            sums: None,
        }
    }

    /// Each voxel's grid coordinates, in the order of `owners`; None when
    /// the elements are blocks of voxels.
    pub fn voxel_coords(&self) -> Option<&[[u16; 3]]> {
        self.blocks.is_none().then_some(&self.coords[..])
    }

    /// The same assignment without runner-ups and third bounds, for one
    /// kept long whose updates follow small moves (the refinement's): few
    /// of its voxels then need measuring, and a third of its memory would
    /// go to the pair test that spares some of them a search.
    pub fn without_runner_ups(mut self) -> Self {
        self.runner_up = Vec::new();
        self.third = Vec::new();
        self
    }

    /// `voxels` with the owners and bounds that `prev` (an assignment of
    /// `prev_voxels`, both sorted) has for those of its voxels they share;
    /// the others take the owner of the voxel before them in `prev_voxels`
    /// as a hint, without bounds. The bounds hold for the centers `prev`
    /// was last updated to, so the first [`Assignment::update`] must be
    /// given an index moved from those (a voxel that stays occupied
    /// needs no search unless the centers moved past its bounds).
    pub fn carried(
        grid: &GridSpec,
        voxels: &[u32],
        prev_voxels: &[u32],
        prev: &Assignment,
    ) -> Self {
        assert!(prev.blocks.is_none(), "bounds are carried between voxels");
        assert_eq!(prev_voxels.len(), prev.owners.len());
        let mut a = Assignment::new(grid, voxels, vec![NO_OWNER; voxels.len()]);
        match_voxels(prev_voxels, voxels, |k, found| match found {
            Ok(j) => {
                (a.owners[k], a.upper[k], a.lower[k]) =
                    (prev.owners[j], prev.upper[j], prev.lower[j]);
                if !prev.runner_up.is_empty() {
                    (a.runner_up[k], a.third[k]) = (prev.runner_up[j], prev.third[j]);
                }
            }
            Err(before) => a.owners[k] = before.map_or(NO_OWNER, |j| prev.owners[j]),
        });
        a
    }

    /// Drops every center of `old_count` but those in `keep` (ascending),
    /// which take their position in `keep` as their new index. A dropped
    /// center's voxels lose their owner and are measured at the next
    /// [`Assignment::update`]; the others keep their bounds, since fewer
    /// centers leave every distance to the nearest other at least as long.
    /// That update must be given an index over the kept centers and their
    /// moves since the last.
    pub fn keep_centers(&mut self, keep: &[usize], old_count: usize) {
        let mut renumbered = vec![NO_OWNER; old_count];
        for (new, &old) in keep.iter().enumerate() {
            renumbered[old] = new as u32;
        }
        for (o, up) in self.owners.iter_mut().zip(&mut self.upper) {
            if *o != NO_OWNER {
                *o = renumbered[*o as usize];
                if *o == NO_OWNER {
                    *up = f32::INFINITY;
                }
            }
        }
        // The third bound still holds for the others when the runner-up goes.
        for r in self.runner_up.iter_mut().filter(|r| **r != NO_OWNER) {
            *r = renumbered[*r as usize];
        }
        self.sums = None;
    }

    /// The voxels grouped into blocks of `edge`³ grid cells, each assigned
    /// as a whole by its voxels' centroid: about `edge`³ times fewer
    /// elements, and cells whose counts and centroids are exactly those of
    /// their blocks' voxels. `hints`: one center index (or NO_OWNER) per
    /// voxel; a block takes the first hint among its voxels. No moments
    /// ([`Assignment::update`] with `with_moments` panics).
    pub fn blocks(grid: &GridSpec, voxels: &[u32], hints: &[u32], edge: usize) -> Self {
        assert_eq!(voxels.len(), hints.len());
        assert!(edge >= 1);
        let block_dims = grid.dims.map(|d| d.div_ceil(edge));
        // Sorted by block, then by voxel: the blocks come in grid order, as
        // voxels do, which the scan's neighbour hint relies on.
        let mut order: Vec<(usize, [usize; 3], u32)> = voxels
            .iter()
            .zip(hints)
            .map(|(&v, &h)| {
                let c = grid.voxel_coords(v as usize);
                let b = c.map(|c| c / edge);
                ((b[2] * block_dims[1] + b[1]) * block_dims[0] + b[0], c, h)
            })
            .collect();
        order.sort_unstable_by_key(|&(key, c, _)| (key, c[2], c[1], c[0]));
        let (mut blocks, mut positions, mut owners, mut coords) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let a = grid.voxel_size;
        for group in order.chunk_by(|x, y| x.0 == y.0) {
            let mut block = Block {
                count: group.len() as u32,
                sum: [0; 3],
            };
            for (_, c, _) in group {
                for (sum, &x) in block.sum.iter_mut().zip(c.iter()) {
                    *sum += x as i64;
                }
            }
            let n = block.count as Real;
            positions
                .push([0, 1, 2].map(|d| grid.origin[d] + (block.sum[d] as Real / n + 0.5) * a));
            blocks.push(block);
            coords.push(group[0].1.map(|c| c as u16));
            owners.push(
                group
                    .iter()
                    .map(|g| g.2)
                    .find(|&h| h != NO_OWNER)
                    .unwrap_or(NO_OWNER),
            );
        }
        let n = blocks.len();
        Assignment {
            origin: grid.origin.coords.into(),
            voxel_size: a,
            coords,
            blocks: Some(Blocks { blocks, positions }),
            owners,
            upper: vec![f32::INFINITY; n],
            lower: vec![f32::NEG_INFINITY; n],
            runner_up: vec![NO_OWNER; n],
            third: vec![f32::NEG_INFINITY; n],
            eps: a * 1e-9,
            sums: None,
        }
    }

    /// Re-assigns after the centers moved: `index` over the new positions,
    /// `moved[i]` how far center i moved since the last call (ignored on the
    /// first call). Returns the cells' sums.
    ///
    /// Two passes per chunk of voxels: a branch-free one loosens every
    /// voxel's bounds in f32 and lists those whose bounds no longer prove
    /// the owner (a minority once the centers settle), then those are
    /// measured.
    pub fn update(&mut self, index: &CenterIndex, moved: &[Real], with_moments: bool) -> CellStats {
        assert!(
            !(with_moments && self.blocks.is_some()),
            "blocks keep no second moments"
        );
        let loosening = index.loosening(moved);
        let (eps, origin, a) = (self.eps, self.origin, self.voxel_size);
        let bounds = Bounds {
            owners: &mut self.owners,
            upper: &mut self.upper,
            lower: &mut self.lower,
            runner_up: &mut self.runner_up,
            third: &mut self.third,
        };
        let coords = &self.coords;
        // One copy of the pass for each kind of element, each with its own
        // position lookup compiled in.
        let changes = match &self.blocks {
            Some(b) => reassign(bounds, coords, eps, index, &loosening, |at, _| {
                b.positions[at]
            }),
            None => reassign(bounds, coords, eps, index, &loosening, |_, c| {
                [0, 1, 2].map(|d| origin[d] + (c[d] as Real + 0.5) * a)
            }),
        };
        match &mut self.sums {
            Some(sums) if !with_moments && sums.count.len() == index.len() => {
                // Every voxel had an owner when the sums were taken.
                for &(k, old) in changes.iter().flatten() {
                    let (k, new) = (k as usize, self.owners[k as usize] as usize);
                    match &self.blocks {
                        Some(b) => {
                            sums.tally_block(old as usize, &b.blocks[k], -1);
                            sums.tally_block(new, &b.blocks[k], 1);
                        }
                        None => {
                            sums.tally(old as usize, self.coords[k], -1);
                            sums.tally(new, self.coords[k], 1);
                        }
                    }
                }
                sums.clone()
            }
            _ => {
                let stats = match &self.blocks {
                    Some(b) => block_stats(&b.blocks, &self.owners, index.len()),
                    None => cell_stats(&self.coords, &self.owners, index.len(), with_moments),
                };
                self.sums = Some(CellStats {
                    second: None,
                    ..stats.clone()
                });
                stats
            }
        }
    }
}

/// The first pass of [`reassign`] over a chunk: loosens every element's
/// bounds by its owner's [`Loosening32`] and lists in `pending` (element,
/// lower bound before) those whose bounds no longer prove the owner, and
/// those without one. Returns how many. `third` is empty when the
/// assignment keeps no runner-ups.
fn loosen_all(
    owners: &[u32],
    upper: &mut [f32],
    lower: &mut [f32],
    third: &mut [f32],
    loosening: &[Loosening32],
    pending: &mut [Pending],
) -> usize {
    let pairs = !third.is_empty();
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && !loosening.is_empty() {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe {
            match pairs {
                true => loosen_all_avx2::<true>(owners, upper, lower, third, loosening, pending),
                false => loosen_all_avx2::<false>(owners, upper, lower, third, loosening, pending),
            }
        };
    }
    match pairs {
        true => loosen_all_portable::<true>(owners, upper, lower, third, loosening, pending, 0),
        false => loosen_all_portable::<false>(owners, upper, lower, third, loosening, pending, 0),
    }
}

/// [`loosen_all`] from element `from` on, one element at a time; `PAIRS`:
/// whether there is a third bound to loosen.
#[inline(always)]
fn loosen_all_portable<const PAIRS: bool>(
    owners: &[u32],
    upper: &mut [f32],
    lower: &mut [f32],
    third: &mut [f32],
    loosening: &[Loosening32],
    pending: &mut [Pending],
    from: usize,
) -> usize {
    let mut n = 0;
    for k in from..owners.len() {
        let lo = lower[k];
        let skip = match loosening.get(owners[k] as usize) {
            Some(b) => {
                let (u, l) = b.loosen(upper[k], lo);
                upper[k] = u;
                lower[k] = l;
                if PAIRS {
                    third[k] = b.lowered(third[k], u);
                }
                u < l
            }
            None => false,
        };
        pending[n] = Pending {
            element: k as u32,
            lower: lo,
        };
        n += !skip as usize;
    }
    n
}

/// [`loosen_all`] eight elements at a time, each owner's loosening loaded
/// whole and the eight transposed into vectors. The same f32 operations in
/// the same order as [`Loosening32::loosen`] (`_mm256_min_ps(a, b)` is `if a < b { a } else
/// { b }`, NaN included), so the bounds come out bit-identical.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn loosen_all_avx2<const PAIRS: bool>(
    owners: &[u32],
    upper: &mut [f32],
    lower: &mut [f32],
    third: &mut [f32],
    loosening: &[Loosening32],
    pending: &mut [Pending],
) -> usize {
    use std::arch::x86_64::*;
    let len = owners.len();
    assert!(
        upper.len() == len
            && lower.len() == len
            && (!PAIRS || third.len() == len)
            && pending.len() >= len
    );
    let table = loosening.as_ptr() as *const f32;
    let top = loosening.len() as u32 - 1;
    let last = _mm256_set1_epi32(top as i32);
    let (grow, shrink) = (_mm256_set1_ps(GROW), _mm256_set1_ps(SHRINK));
    // The same for every center (the largest move of all): not transposed.
    let max_move = _mm256_set1_ps(loosening[0].max_move);
    debug_assert!(loosening
        .iter()
        .all(|l| l.max_move == loosening[0].max_move));
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mut n = 0;
    let mut k = 0;
    while k + 8 <= len {
        let own = _mm256_loadu_si256(owners.as_ptr().add(k) as *const __m256i);
        // Owners past the table (NO_OWNER) read its last entry, then are
        // left as they were and listed.
        let clamped = _mm256_min_epu32(own, last);
        let valid = _mm256_cmpeq_epi32(clamped, own);
        // Each owner's loosening as one 16-byte load, transposed into
        // vectors of moves, decays and reaches: cheaper than three gathers.
        let row = |j: usize| {
            _mm_loadu_ps(table.add(4 * (*owners.get_unchecked(k + j)).min(top) as usize))
        };
        let (r0, r1) = (
            _mm256_set_m128(row(4), row(0)),
            _mm256_set_m128(row(5), row(1)),
        );
        let (r2, r3) = (
            _mm256_set_m128(row(6), row(2)),
            _mm256_set_m128(row(7), row(3)),
        );
        // Lanes 0-3 hold elements 0-3 and 4-7 in the two halves: moved,
        // decay, reach, max_move of rows 0..3, then of 4..7.
        let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpacklo_ps(r2, r3));
        let (t2, t3) = (_mm256_unpackhi_ps(r0, r1), _mm256_unpackhi_ps(r2, r3));
        let moved = _mm256_castpd_ps(_mm256_unpacklo_pd(
            _mm256_castps_pd(t0),
            _mm256_castps_pd(t1),
        ));
        let decay = _mm256_castpd_ps(_mm256_unpackhi_pd(
            _mm256_castps_pd(t0),
            _mm256_castps_pd(t1),
        ));
        let reach = _mm256_castpd_ps(_mm256_unpacklo_pd(
            _mm256_castps_pd(t2),
            _mm256_castps_pd(t3),
        ));
        let up0 = _mm256_loadu_ps(upper.as_ptr().add(k));
        let lo0 = _mm256_loadu_ps(lower.as_ptr().add(k));
        let u = _mm256_mul_ps(_mm256_add_ps(up0, moved), grow);
        let lowered = |l: __m256| {
            let m = _mm256_min_ps(_mm256_sub_ps(l, decay), _mm256_sub_ps(reach, u));
            _mm256_mul_ps(_mm256_max_ps(m, _mm256_sub_ps(l, max_move)), shrink)
        };
        let l = lowered(lo0);
        let valid = _mm256_castsi256_ps(valid);
        _mm256_storeu_ps(upper.as_mut_ptr().add(k), _mm256_blendv_ps(up0, u, valid));
        _mm256_storeu_ps(lower.as_mut_ptr().add(k), _mm256_blendv_ps(lo0, l, valid));
        if PAIRS {
            let th0 = _mm256_loadu_ps(third.as_ptr().add(k));
            _mm256_storeu_ps(
                third.as_mut_ptr().add(k),
                _mm256_blendv_ps(th0, lowered(th0), valid),
            );
        }
        let skip = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(u, l), valid);
        let listed = !_mm256_movemask_ps(skip) & 0xff;
        // The listed elements' (index, lower bound before) packed to the
        // front, then written as eight pairs at once: the slots past the
        // listed ones are overwritten later or never read, and the eight
        // fit since n <= k and k + 8 <= len.
        let order = _mm256_cvtepu8_epi32(_mm_loadl_epi64(
            LEFT_PACK[listed as usize].as_ptr() as *const __m128i
        ));
        let elements = _mm256_permutevar8x32_epi32(
            _mm256_add_epi32(_mm256_set1_epi32(k as i32), lanes),
            order,
        );
        let lows = _mm256_castps_si256(_mm256_permutevar8x32_ps(lo0, order));
        let (a, b) = (
            _mm256_unpacklo_epi32(elements, lows),
            _mm256_unpackhi_epi32(elements, lows),
        );
        let out = pending.as_mut_ptr().add(n) as *mut __m256i;
        _mm256_storeu_si256(out, _mm256_permute2x128_si256::<0x20>(a, b));
        _mm256_storeu_si256(out.add(1), _mm256_permute2x128_si256::<0x31>(a, b));
        n += listed.count_ones() as usize;
        k += 8;
    }
    n + loosen_all_portable::<PAIRS>(owners, upper, lower, third, loosening, &mut pending[n..], k)
}

/// An element whose bounds no longer prove its owner, with its lower bound
/// before the pass loosened it (C layout: the vector pass writes pairs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
struct Pending {
    element: u32,
    lower: f32,
}

/// A measured element whose distance to its owner settles it: the new
/// bounds, before rounding outwards.
#[derive(Clone, Copy, Debug, Default)]
struct Settled {
    element: u32,
    upper: f32,
    lower: f32,
}

/// A measured element that its owner's distance does not settle, with that
/// squared distance (NaN when it has no owner with a loosening).
#[derive(Clone, Copy, Debug, Default)]
struct Unsettled {
    element: u32,
    own2: Real,
}

/// Per 8-bit mask, the positions of its set bits in order (the rest 0):
/// the permutation that packs the lanes a mask selects to the front.
#[cfg(target_arch = "x86_64")]
static LEFT_PACK: [[u8; 8]; 256] = {
    let mut table = [[0u8; 8]; 256];
    let mut mask = 0;
    while mask < 256 {
        let (mut lane, mut n) = (0, 0);
        while lane < 8 {
            if mask >> lane & 1 == 1 {
                table[mask][n] = lane as u8;
                n += 1;
            }
            lane += 1;
        }
        mask += 1;
    }
    table
};

/// An assignment's per-element state, borrowed for [`reassign`].
struct Bounds<'a> {
    owners: &'a mut [u32],
    upper: &'a mut [f32],
    lower: &'a mut [f32],
    runner_up: &'a mut [u32],
    third: &'a mut [f32],
}

/// The pass of [`Assignment::update`] over every element: loosens the
/// bounds, measures the elements they no longer prove, and returns (element,
/// old owner) for every element whose owner changed. `position(k, coords[k])`
/// is element k's position.
fn reassign(
    bounds: Bounds,
    coords: &[[u16; 3]],
    eps: Real,
    index: &CenterIndex,
    loosening: &[Loosening],
    position: impl Fn(usize, [u16; 3]) -> [Real; 3] + Sync,
) -> Vec<Vec<(u32, u32)>> {
    let loosening32: Vec<Loosening32> = loosening.iter().map(Loosening32::from).collect();
    let Bounds {
        owners,
        upper,
        lower,
        runner_up,
        third,
    } = bounds;
    // Without runner-ups ([`Assignment::without_runner_ups`]) every chunk
    // gets empty slices for them.
    let pairs = !runner_up.is_empty();
    let chunks = owners.len().div_ceil(CHUNK);
    let (runner_up, third) = if pairs {
        (
            Either::Left(runner_up.par_chunks_mut(CHUNK)),
            Either::Left(third.par_chunks_mut(CHUNK)),
        )
    } else {
        (
            Either::Right((0..chunks).into_par_iter().map(|_| <&mut [u32]>::default())),
            Either::Right((0..chunks).into_par_iter().map(|_| <&mut [f32]>::default())),
        )
    };
    // (voxel, old owner) for every voxel whose owner changed.
    owners
        .par_chunks_mut(CHUNK)
        .zip(upper.par_chunks_mut(CHUNK))
        .zip(lower.par_chunks_mut(CHUNK))
        .zip(runner_up)
        .zip(third)
        .zip(coords.par_chunks(CHUNK))
        .enumerate()
        // Voxels to measure, with their lower bound before the first
        // pass, then split into those their owner's distance settles and
        // the others: buffers per rayon job rather than zeroed ones per chunk.
        .map_init(
            || {
                (
                    vec![Pending::default(); CHUNK],
                    vec![Settled::default(); CHUNK],
                    vec![Unsettled::default(); CHUNK],
                )
            },
            |(pending, settled, unsettled),
             (chunk, (((((own, up), low), runner), third), coords))| {
                let n = loosen_all(own, up, low, third, &loosening32, pending);
                let pass = ChunkPass {
                    base: chunk * CHUNK,
                    coords,
                    eps,
                    index,
                    loosening,
                    position: &position,
                };
                let (n_settled, n_unsettled) =
                    pass.measure_owners(own, &pending[..n], settled, unsettled);
                for &Settled {
                    element: k,
                    upper,
                    lower,
                } in &settled[..n_settled]
                {
                    up[k as usize] = upper.next_up();
                    low[k as usize] = lower.next_down();
                }
                let mut chunk_bounds = Bounds {
                    owners: own,
                    upper: up,
                    lower: low,
                    runner_up: runner,
                    third,
                };
                pass.settle(&mut chunk_bounds, pairs, &unsettled[..n_unsettled])
            },
        )
        .collect()
}

/// What [`reassign`] knows of one chunk of elements: the first's index,
/// their coordinates, and the centers' index and moves.
struct ChunkPass<'a, P> {
    base: usize,
    coords: &'a [[u16; 3]],
    eps: Real,
    index: &'a CenterIndex,
    loosening: &'a [Loosening],
    position: &'a P,
}

impl<P: Fn(usize, [u16; 3]) -> [Real; 3]> ChunkPass<'_, P> {
    /// The distance of each `pending` element (with its lower bound before
    /// the pass) to its owner in `own`, whose new bounds settle about half of
    /// them: those are listed in `settled`, the others in `unsettled` (with
    /// the squared distance), in their order, so the scan's hint in
    /// [`Self::settle`] sees the same elements. Without a branch on that
    /// outcome, which no predictor guesses, each element is written on both
    /// sides and counted on one. Returns how many of each.
    #[inline(always)]
    fn measure_owners(
        &self,
        own: &[u32],
        pending: &[Pending],
        settled: &mut [Settled],
        unsettled: &mut [Unsettled],
    ) -> (usize, usize) {
        let (mut n_settled, mut n_unsettled) = (0, 0);
        for &Pending {
            element: k,
            lower: lo,
        } in pending
        {
            let o = own[k as usize];
            let (own2, done) = match self.loosening.get(o as usize) {
                Some(b) => {
                    let pos = (self.position)(self.base + k as usize, self.coords[k as usize]);
                    let u2 = self.index.dist2(o, &pos);
                    let u = u2.sqrt();
                    let l = b.lowered(lo as Real, u);
                    let done = u + self.eps < l;
                    settled[n_settled] = Settled {
                        element: k,
                        upper: u as f32,
                        lower: l as f32,
                    };
                    n_settled += done as usize;
                    (u2, done)
                }
                None => (Real::NAN, false),
            };
            unsettled[n_unsettled] = Unsettled { element: k, own2 };
            n_unsettled += !done as usize;
        }
        (n_settled, n_unsettled)
    }

    /// Finds the owner of each `unsettled` element and its bounds in `b`
    /// (this chunk's slices; runner-ups kept where `pairs`); returns
    /// (element, old owner) for every element whose owner changed.
    #[inline(always)]
    fn settle(&self, b: &mut Bounds, pairs: bool, unsettled: &[Unsettled]) -> Vec<(u32, u32)> {
        let (index, eps) = (self.index, self.eps);
        let Bounds {
            owners: own,
            upper: up,
            lower: low,
            runner_up: runner,
            third,
        } = b;
        let mut changed = Vec::new();
        // The owner last found in this chunk: a voxel without
        // one (assigned afresh) starts from its neighbour's in
        // the scan, which is nearly always its own or close, so
        // that the candidate lists settle it instead of the k-d
        // tree. The owner found is the same either way.
        let mut last = NO_OWNER;
        for &Unsettled { element: k, own2 } in unsettled {
            let k = k as usize;
            let o = own[k];
            let at = self.base + k;
            let pos = (self.position)(at, self.coords[k]);
            // The squared distance to the voxel's last owner, or to
            // its hint when assigned afresh (another frame's owner,
            // say); infinite without either.
            let own2 = match self.loosening.get(o as usize) {
                Some(_) => {
                    let (u2, u) = (own2, own2.sqrt());
                    // Between the owner and the runner-up, when every
                    // other center is farther than both.
                    let (r, others) = if pairs {
                        (runner[k], third[k] as Real)
                    } else {
                        (NO_OWNER, Real::NEG_INFINITY)
                    };
                    if r != NO_OWNER && u + eps < others {
                        let r2 = index.dist2(r, &pos);
                        let takes = r2 < u2 || (r2 == u2 && r < o);
                        let (near, far) = if takes {
                            (r2.sqrt(), u)
                        } else {
                            (u, r2.sqrt())
                        };
                        if near + eps < others {
                            if takes {
                                own[k] = r;
                                runner[k] = o;
                                changed.push((at as u32, o));
                            }
                            up[k] = (near as f32).next_up();
                            low[k] = (far.min(others) as f32).next_down();
                            last = own[k];
                            continue;
                        }
                    }
                    u2
                }
                None if (o as usize) < index.len() => index.dist2(o, &pos),
                None => Real::INFINITY,
            };
            // Where the centers moved far (a frame's first
            // iterations, or another frame's owners as hints), the
            // owner the scan just found is often nearer than the
            // voxel's own, and its candidate list the one that
            // settles the voxel.
            let hint = if last != NO_OWNER && last != o && index.dist2(last, &pos) < own2 {
                last
            } else {
                o
            };
            let found = index.nearest2(&pos, hint);
            last = found.owner;
            if found.owner != o {
                changed.push((at as u32, o));
            }
            own[k] = found.owner;
            up[k] = (found.distance as f32).next_up();
            low[k] = (found.second as f32).next_down();
            if pairs {
                runner[k] = found.runner_up;
                third[k] = (found.third as f32).next_down();
            }
        }
        changed
    }
}

/// Assigns every occupied voxel to its nearest center in one go. `owners`
/// holds one hint per voxel on entry (NO_OWNER for none), the owner on return.
pub fn assign(
    grid: &GridSpec,
    voxels: &[u32],
    index: &CenterIndex,
    owners: &mut [u32],
    with_moments: bool,
) -> CellStats {
    let mut a = Assignment::new(grid, voxels, owners.to_vec());
    let stats = a.update(index, &[], with_moments);
    owners.copy_from_slice(&a.owners);
    stats
}

/// Sums over each cell's voxels given their owners (sequential: integer
/// sums, a small share of the time).
fn cell_stats(coords: &[[u16; 3]], owners: &[u32], n: usize, with_moments: bool) -> CellStats {
    let mut stats = CellStats {
        count: vec![0; n],
        sum: vec![[0; 3]; n],
        second: with_moments.then(|| vec![[0; 6]; n]),
    };
    for (&o, &c) in owners.iter().zip(coords) {
        stats.tally(o as usize, c, 1);
    }
    stats
}

/// [`cell_stats`] over blocks (counts and sums only).
fn block_stats(blocks: &[Block], owners: &[u32], n: usize) -> CellStats {
    let mut stats = CellStats {
        count: vec![0; n],
        sum: vec![[0; 3]; n],
        second: None,
    };
    for (&o, b) in owners.iter().zip(blocks) {
        stats.tally_block(o as usize, b, 1);
    }
    stats
}

/// Carries owners from one frame's voxels to the next's: voxels present in
/// both keep their owner as a hint (both lists are sorted).
pub(crate) fn carry_owners(prev_voxels: &[u32], prev_owners: &[u32], voxels: &[u32]) -> Vec<u32> {
    let mut out = vec![NO_OWNER; voxels.len()];
    match_voxels(prev_voxels, voxels, |k, found| {
        // Else the owner of the voxel before it, nearly always a neighbour.
        if let Ok(j) | Err(Some(j)) = found {
            out[k] = prev_owners[j];
        }
    });
    out
}

/// For each of `voxels` (index k), where it is in `prev_voxels` (both
/// sorted): Ok(j) when there, else Err with the last index before it, if any.
fn match_voxels(
    prev_voxels: &[u32],
    voxels: &[u32],
    mut each: impl FnMut(usize, Result<usize, Option<usize>>),
) {
    let mut j = 0;
    for (k, &v) in voxels.iter().enumerate() {
        while j < prev_voxels.len() && prev_voxels[j] < v {
            j += 1;
        }
        each(
            k,
            if j < prev_voxels.len() && prev_voxels[j] == v {
                Ok(j)
            } else {
                Err(j.checked_sub(1))
            },
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::rng::SplitMix64;

    /// The pass over a chunk eight elements at a time gives the bounds and
    /// the list of elements to measure of the one at a time, bit for bit,
    /// with owners past the table, infinite and NaN-making bounds, and
    /// lengths that leave a tail.
    #[test]
    fn the_vector_pass_matches_the_scalar_one() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut rng = SplitMix64::new(5);
            for case in 0..300 {
                let centers = 1 + case % 40;
                let len = case * 7 % 200;
                let mut unit = || rng.unit();
                let loosening: Vec<Loosening32> = (0..centers)
                    .map(|i| {
                        let reach = if i % 7 == 0 {
                            Real::INFINITY
                        } else {
                            1.0 + unit()
                        };
                        Loosening32::from(&Loosening {
                            moved: 0.1 * unit(),
                            decay: 0.1 * unit(),
                            reach,
                            max_move: 0.2,
                        })
                    })
                    .collect();
                let owners: Vec<u32> = (0..len)
                    .map(|_| {
                        if unit() < 0.1 {
                            NO_OWNER
                        } else {
                            (unit() * centers as Real) as u32
                        }
                    })
                    .collect();
                let mut bound = |inf: f32| if unit() < 0.05 { inf } else { unit() as f32 };
                let upper: Vec<f32> = (0..len).map(|_| bound(f32::INFINITY)).collect();
                let lower: Vec<f32> = (0..len).map(|_| bound(f32::NEG_INFINITY)).collect();
                let third: Vec<f32> = (0..len).map(|_| bound(f32::NEG_INFINITY)).collect();
                let run = |vector: bool| {
                    let (mut up, mut lo, mut th) = (upper.clone(), lower.clone(), third.clone());
                    let mut pending = vec![Pending::default(); len];
                    // Without a third bound on odd cases.
                    let pairs = case % 2 == 0;
                    if !pairs {
                        th.clear();
                    }
                    // SAFETY: the CPU has AVX2, checked above.
                    let n = match (vector, pairs) {
                        (true, true) => unsafe {
                            loosen_all_avx2::<true>(
                                &owners,
                                &mut up,
                                &mut lo,
                                &mut th,
                                &loosening,
                                &mut pending,
                            )
                        },
                        (true, false) => unsafe {
                            loosen_all_avx2::<false>(
                                &owners,
                                &mut up,
                                &mut lo,
                                &mut th,
                                &loosening,
                                &mut pending,
                            )
                        },
                        (false, true) => loosen_all_portable::<true>(
                            &owners,
                            &mut up,
                            &mut lo,
                            &mut th,
                            &loosening,
                            &mut pending,
                            0,
                        ),
                        (false, false) => loosen_all_portable::<false>(
                            &owners,
                            &mut up,
                            &mut lo,
                            &mut th,
                            &loosening,
                            &mut pending,
                            0,
                        ),
                    };
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    let listed: Vec<(u32, u32)> = pending[..n]
                        .iter()
                        .map(|p| (p.element, p.lower.to_bits()))
                        .collect();
                    (bits(&up), bits(&lo), bits(&th), listed)
                };
                let (vector, scalar) = (run(true), run(false));
                assert_eq!(
                    vector, scalar,
                    "case {case}: {centers} centers, {len} elements"
                );
            }
        }
    }

    /// The f32 loosening never tightens a bound the f64 arithmetic allows,
    /// at any scale, on bounds built to fall within an f32 rounding of a tie.
    #[test]
    fn f32_loosening_keeps_the_bounds_valid() {
        let mut rng = SplitMix64::new(11);
        let mut unit = || rng.unit();
        let (mut skipped, mut measured) = (0, 0);
        for case in 0..200_000 {
            let scale = (10.0 as Real).powf(-3.0 + 7.0 * unit());
            let moved = scale * 1e-3 * unit();
            let max_move = scale * 1e-3 * unit();
            let decay = max_move * unit();
            let reach = if case % 5 == 0 {
                Real::INFINITY
            } else {
                scale * (1.0 + 2.0 * unit())
            };
            let b = Loosening {
                moved,
                decay,
                reach,
                max_move,
            };
            let upper = (scale * unit()) as f32;
            // Within a few f32 roundings of the loosened bounds meeting.
            let tie = upper as Real + moved + max_move.max(decay);
            let lower = (tie * (1.0 + 1e-6 * (2.0 * unit() - 1.0))) as f32;
            let (u, l) = Loosening32::from(&b).loosen(upper, lower);
            let u_exact = upper as Real + moved;
            assert!(
                u as Real >= u_exact,
                "case {case}: upper {u} below {u_exact}"
            );
            if u < l {
                skipped += 1;
                let l_exact = b.lowered(lower as Real, u_exact);
                assert!(
                    l as Real <= l_exact,
                    "case {case}: lower {l} above {l_exact}"
                );
            } else {
                measured += 1;
            }
        }
        assert!(
            skipped > 10_000 && measured > 10_000,
            "{skipped} skipped, {measured} measured: the cases miss the boundary"
        );
    }
}

#[cfg(test)]
#[path = "cells_tests.rs"]
mod scan_tests;
