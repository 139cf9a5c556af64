//! Weighted Kabsch: the rigid motion that best carries one set of weighted
//! points onto another (docs/method.md §4).

use crate::math::{Matrix3, Point3, Real, UnitQuaternion, Vector3};
use rayon::prelude::*;

/// x -> rotation · x + translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    /// A proper rotation (orthonormal, determinant 1).
    pub rotation: Matrix3,
    /// Applied after the rotation, in the input's units.
    pub translation: Vector3,
}

impl Rigid {
    /// The motion that moves nothing.
    pub fn identity() -> Self {
        Rigid {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// The image of `p`: rotated, then translated.
    #[inline]
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.rotation * p.coords + self.translation)
    }

    /// The motion undoing this one.
    pub fn inverse(&self) -> Rigid {
        let rt = self.rotation.transpose();
        Rigid {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Rigid) -> Rigid {
        Rigid {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }
}

/// argmin over rigid (R, t) of Σ w_j ||dst_j - (R src_j + t)||², over the
/// weighted index list `pairs` (closed form from the weighted
/// cross-covariance: Horn's quaternion, or the covariance's SVD where that
/// loses its digits; the best proper rotation, never a reflection).
///
/// With too few or collinear points the rotation is under-determined; a small
/// pull towards the identity then picks the smallest rotation.
pub fn fit_rigid(
    src: &[Point3],
    dst: &[Point3],
    pairs: impl Iterator<Item = (usize, Real)> + Clone,
) -> Rigid {
    // One pass over the pairs (this is the tracker's inner loop): weighted
    // sums of p, q and p qᵀ, taken relative to the first pair so that the
    // covariance H = Σ w p qᵀ - W p̄ q̄ᵀ does not cancel digits away.
    let Some((j0, _)) = pairs.clone().next() else {
        return Rigid::identity();
    };
    let (p0, q0) = (src[j0].coords, dst[j0].coords);
    let mut wsum = 0.0;
    let mut ps = Vector3::zeros();
    let mut qs = Vector3::zeros();
    let mut pq = Matrix3::zeros();
    for (j, w) in pairs {
        let (p, q) = (src[j].coords - p0, dst[j].coords - q0);
        let wp = w * p;
        wsum += w;
        ps += wp;
        qs += w * q;
        pq += wp * q.transpose();
    }
    if !(wsum > 0.0) {
        return Rigid::identity();
    }
    let h = pq - ps * (qs / wsum).transpose();
    rigid_from_covariance(&h, &(p0 + ps / wsum), &(q0 + qs / wsum))
}

/// The rigid motion carrying the weighted mean `pm` to `qm` whose rotation
/// best aligns the weighted cross-covariance H = Σ w (p - pm)(q - qm)ᵀ.
fn rigid_from_covariance(h: &Matrix3, pm: &Vector3, qm: &Vector3) -> Rigid {
    let rotation = rotation_from_covariance(h);
    Rigid {
        rotation,
        translation: qm - rotation * pm,
    }
}

/// The proper rotation R that best carries the p's onto the q's, given their
/// cross-covariance H = Σ w (p - pm)(q - qm)ᵀ: maximises trace(R H).
///
/// Horn's unit quaternion, the eigenvector of the largest eigenvalue of a
/// symmetric 4 × 4 matrix built from H, with that eigenvalue found as the
/// largest root of its characteristic polynomial by Newton's method
/// (Theobald's QCP) and the eigenvector read off the adjugate of N - λI.
/// Why: the tracker fits every center in every iteration, and this takes a
/// fraction of a 3 × 3 SVD's time. Where the largest eigenvalue is close to
/// double (few or collinear points, or a fit that barely prefers one
/// rotation), the adjugate loses its digits and the SVD decides instead.
pub fn rotation_from_covariance(h: &Matrix3) -> Matrix3 {
    quaternion_rotation(h).unwrap_or_else(|| svd_rotation(h))
}

/// Horn's rotation when the largest eigenvalue stands clear of the next;
/// None otherwise.
fn quaternion_rotation(h: &Matrix3) -> Option<Matrix3> {
    let (sxx, sxy, sxz) = (h[(0, 0)], h[(0, 1)], h[(0, 2)]);
    let (syx, syy, syz) = (h[(1, 0)], h[(1, 1)], h[(1, 2)]);
    let (szx, szy, szz) = (h[(2, 0)], h[(2, 1)], h[(2, 2)]);
    let n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let frobenius2 = h.norm_squared();
    if !(frobenius2 > 0.0) || !frobenius2.is_finite() {
        return None;
    }
    // N is traceless: its characteristic polynomial is
    // λ⁴ + c2 λ² + c1 λ + c0 with c2 = -2 |H|², c1 = -8 det H, c0 = det N.
    let (c2, c1, c0) = (-2.0 * frobenius2, -8.0 * h.determinant(), det4(&n));
    // The eigenvalues are ±σ1 ± σ2 ± σ3 (H's singular values, the smallest
    // signed as det H; an even number of minus signs), so none exceeds
    // σ1 + σ2 + σ3 <= √3 |H|: from there Newton's steps fall monotonically
    // onto the largest, the polynomial being increasing and convex above it.
    let mut lambda = (3.0 * frobenius2).sqrt();
    for _ in 0..60 {
        let l2 = lambda * lambda;
        let p = (l2 + c2) * l2 + c1 * lambda + c0;
        let dp = (4.0 * l2 + 2.0 * c2) * lambda + c1;
        if !(dp > 0.0) {
            break;
        }
        let step = p / dp;
        lambda -= step;
        if step.abs() <= 1e-15 * lambda.abs() {
            break;
        }
    }
    let mut a = n;
    for (i, row) in a.iter_mut().enumerate() {
        row[i] -= lambda;
    }
    // adj(N - λI) = Π (λ_k - λ) q qᵀ for a simple λ: column j is q_j times
    // the product of λ's gaps to the other eigenvalues, and the longest
    // (|q_j| >= 1/2) is the best conditioned; a short one means a near-double λ.
    let (best, length2) = (0..4)
        .map(|j| {
            let c: [Real; 4] = std::array::from_fn(|i| cofactor(&a, j, i));
            (c, c.iter().map(|x| x * x).sum::<Real>())
        })
        .fold(([0.0; 4], -1.0), |b, c| if c.1 > b.1 { c } else { b });
    let scale3 = frobenius2 * frobenius2.sqrt();
    if !(length2.sqrt() > 1e-4 * scale3) {
        return None;
    }
    let q = nalgebra::Quaternion::new(best[0], best[1], best[2], best[3]);
    Some(
        *UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .matrix(),
    )
}

/// The determinant of the 3 × 3 matrix `a` without row `r` and column `c`,
/// signed as the cofactor (r, c).
fn cofactor(a: &[[Real; 4]; 4], r: usize, c: usize) -> Real {
    let rows: [usize; 3] = std::array::from_fn(|k| k + usize::from(k >= r));
    let cols: [usize; 3] = std::array::from_fn(|k| k + usize::from(k >= c));
    let m = |i: usize, j: usize| a[rows[i]][cols[j]];
    let det = m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1))
        - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
        + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0));
    if (r + c).is_multiple_of(2) {
        det
    } else {
        -det
    }
}

/// The determinant of `a`, by its first row's cofactors.
fn det4(a: &[[Real; 4]; 4]) -> Real {
    (0..4).map(|c| a[0][c] * cofactor(a, 0, c)).sum()
}

/// [`rotation_from_covariance`] by the SVD of H, which copes with every H.
fn svd_rotation(h: &Matrix3) -> Matrix3 {
    let mut svd = h.svd(true, true);
    if svd.singular_values[1] <= 1e-10 * svd.singular_values[0] {
        // Rank <= 1 (collinear or too few points): the rotation about the line
        // is free; a small pull towards the identity picks the smallest one.
        let pull = 1e-6 * svd.singular_values[0] + Real::MIN_POSITIVE;
        svd = (h + Matrix3::identity() * pull).svd(true, true);
    }
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose()
}

/// Many weighted rigid fits from one source set, each over its own weighted
/// list of points, repeated for destinations that change: the tracker fits
/// every center from frame f-1 to f in every iteration, with the sources
/// and the weights fixed for the frame.
///
/// What depends only on the sources and weights (Σ w, Σ w p) is summed once;
/// each [`RigidFits::fit`] sums Σ w q and Σ w p qᵀ from one per-point table
/// of q and p qᵀ, which is a third of [`fit_rigid`]'s arithmetic per pair
/// and reads one contiguous row per neighbour. Coordinates are taken
/// relative to the sets' means so that H = Σ w p qᵀ - Σ w p (Σ w q)ᵀ / Σ w
/// keeps its digits; tested against [`fit_rigid`].
pub struct RigidFits {
    /// Fit i's points are `points[start[i]..start[i + 1]]`, with `weights` alongside.
    start: Vec<usize>,
    points: Vec<u32>,
    weights: Vec<Real>,
    /// Sources relative to `src_shift`.
    src: Vec<Vector3>,
    src_shift: Vector3,
    /// Per fit: Σ w and Σ w p (relative).
    wsum: Vec<Real>,
    psum: Vec<Vector3>,
}

impl RigidFits {
    /// `lists(i)`: the weighted points of fit i, for i in 0..`fits`.
    pub fn new<I: Iterator<Item = (usize, Real)>>(
        src: &[Point3],
        fits: usize,
        lists: impl Fn(usize) -> I,
    ) -> Self {
        let src_shift = mean(src);
        let src: Vec<Vector3> = src.iter().map(|p| p.coords - src_shift).collect();
        let mut start = Vec::with_capacity(fits + 1);
        let (mut points, mut weights) = (Vec::new(), Vec::new());
        let (mut wsum, mut psum) = (Vec::with_capacity(fits), Vec::with_capacity(fits));
        start.push(0);
        for i in 0..fits {
            let (mut w_i, mut p_i) = (0.0, Vector3::zeros());
            for (j, w) in lists(i) {
                points.push(j as u32);
                weights.push(w);
                w_i += w;
                p_i += w * src[j];
            }
            start.push(points.len());
            wsum.push(w_i);
            psum.push(p_i);
        }
        RigidFits {
            start,
            points,
            weights,
            src,
            src_shift,
            wsum,
            psum,
        }
    }

    /// Every fit's rigid motion from the sources to `dst`.
    pub fn fit(&self, dst: &[Point3]) -> Vec<Rigid> {
        assert_eq!(dst.len(), self.src.len());
        let dst_shift = mean(dst);
        // Per point: q, then p qᵀ column-major (nalgebra's order).
        let table: Vec<[Real; 12]> = self
            .src
            .iter()
            .zip(dst)
            .map(|(p, q)| {
                let q = q.coords - dst_shift;
                let pq = p * q.transpose();
                let mut row = [0.0; 12];
                row[..3].copy_from_slice(q.as_slice());
                row[3..].copy_from_slice(pq.as_slice());
                row
            })
            .collect();
        // Fits are summed two at a time: each sum is a chain of dependent
        // additions, and two independent chains keep the adder busy.
        let mut motions = vec![Rigid::identity(); self.wsum.len()];
        motions
            .par_chunks_mut(2)
            .enumerate()
            .for_each(|(pair, out)| {
                let i = 2 * pair;
                let list = |i: usize| {
                    let range = self.start[i]..self.start[i + 1];
                    (&self.points[range.clone()], &self.weights[range])
                };
                // The last fit of an odd count is paired with an empty list.
                let second = if out.len() == 2 {
                    list(i + 1)
                } else {
                    (&[][..], &[][..])
                };
                let sums = weighted_sums(list(i), second, &table);
                for (k, motion) in out.iter_mut().enumerate() {
                    *motion = self.motion(i + k, &sums[k], &dst_shift);
                }
            });
        motions
    }

    /// Fit i's motion from its sums Σ w q and Σ w p qᵀ (`acc`, as in the table).
    fn motion(&self, i: usize, acc: &[Real; 12], dst_shift: &Vector3) -> Rigid {
        let wsum = self.wsum[i];
        // Also an empty list, whose weights sum to 0.
        if !(wsum > 0.0) {
            return Rigid::identity();
        }
        let qs = Vector3::new(acc[0], acc[1], acc[2]);
        let pq = Matrix3::from_column_slice(&acc[3..]);
        let ps = self.psum[i];
        let h = pq - ps * (qs / wsum).transpose();
        rigid_from_covariance(&h, &(self.src_shift + ps / wsum), &(dst_shift + qs / wsum))
    }
}

/// Many weighted rigid fits between the same two point sets, each over its
/// own weighted list of their points, when both sets change from call to
/// call: the refinement fits every center from frame f-1 to f once per
/// evaluation, and every step moves both frames.
///
/// One row per point holds 1, p, q and p qᵀ (relative to the sets' means,
/// so that H = Σ w p qᵀ - Σ w p (Σ w q)ᵀ / Σ w keeps its digits): a fit sums
/// whole rows, one multiply and add per entry, where [`fit_rigid`] takes
/// each pair's differences and products anew. Tested against [`fit_rigid`].
pub struct PairTable {
    rows: Vec<[Real; 16]>,
    src_shift: Vector3,
    dst_shift: Vector3,
}

impl PairTable {
    /// The table of `src` and `dst`, point j of one paired with point j of the other.
    pub fn new(src: &[Point3], dst: &[Point3]) -> Self {
        assert_eq!(src.len(), dst.len());
        let (src_shift, dst_shift) = (mean(src), mean(dst));
        let rows = src
            .iter()
            .zip(dst)
            .map(|(p, q)| {
                let (p, q) = (p.coords - src_shift, q.coords - dst_shift);
                let mut row = [0.0; 16];
                row[0] = 1.0;
                row[1..4].copy_from_slice(p.as_slice());
                row[4..7].copy_from_slice(q.as_slice());
                row[7..].copy_from_slice((p * q.transpose()).as_slice());
                row
            })
            .collect();
        PairTable {
            rows,
            src_shift,
            dst_shift,
        }
    }

    /// The rigid motion over `pairs` (point index, weight), as
    /// [`fit_rigid`] gives it up to rounding.
    pub fn fit(&self, pairs: &[(u32, Real)]) -> Rigid {
        let acc = row_sums(pairs, &self.rows);
        let wsum = acc[0];
        if !(wsum > 0.0) {
            return Rigid::identity();
        }
        let ps = Vector3::new(acc[1], acc[2], acc[3]);
        let qs = Vector3::new(acc[4], acc[5], acc[6]);
        let h = Matrix3::from_column_slice(&acc[7..]) - ps * (qs / wsum).transpose();
        rigid_from_covariance(
            &h,
            &(self.src_shift + ps / wsum),
            &(self.dst_shift + qs / wsum),
        )
    }
}

/// Σ w · rows[j] over `pairs` (j, w), in list order whatever the path: on
/// x86-64 CPUs with AVX a copy compiled for AVX runs, four lanes at a time.
fn row_sums(pairs: &[(u32, Real)], rows: &[[Real; 16]]) -> [Real; 16] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        return unsafe { row_sums_avx(pairs, rows) };
    }
    row_sums_portable(pairs, rows)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn row_sums_avx(pairs: &[(u32, Real)], rows: &[[Real; 16]]) -> [Real; 16] {
    row_sums_portable(pairs, rows)
}

#[inline(always)]
fn row_sums_portable(pairs: &[(u32, Real)], rows: &[[Real; 16]]) -> [Real; 16] {
    let mut acc = [0.0; 16];
    for &(j, w) in pairs {
        let row = &rows[j as usize];
        for (s, r) in acc.iter_mut().zip(row) {
            *s += w * r;
        }
    }
    acc
}

/// One fit's weighted list: point indices and their weights.
type WeightedList<'a> = (&'a [u32], &'a [Real]);

/// Σ w_k · table[points[k]] over two lists: most of the rigid fits' time,
/// which is a large share of the tracking time.
///
/// Each of the 24 sums adds its terms one by one in list order, whatever the
/// path, so results are bit-identical: the lists are interleaved, not split
/// (which would reorder additions), and Rust never fuses a multiply and an
/// add. On x86-64 CPUs with AVX a copy compiled for AVX runs, with four
/// lanes instead of SSE2's two.
fn weighted_sums(a: WeightedList, b: WeightedList, table: &[[Real; 12]]) -> [[Real; 12]; 2] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        return unsafe { weighted_sums_avx(a, b, table) };
    }
    weighted_sums_portable(a, b, table)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn weighted_sums_avx(
    a: WeightedList,
    b: WeightedList,
    table: &[[Real; 12]],
) -> [[Real; 12]; 2] {
    weighted_sums_portable(a, b, table)
}

#[inline(always)]
fn weighted_sums_portable(
    a: WeightedList,
    b: WeightedList,
    table: &[[Real; 12]],
) -> [[Real; 12]; 2] {
    #[inline(always)]
    fn add(acc: &mut [Real; 12], w: Real, row: &[Real; 12]) {
        for (s, r) in acc.iter_mut().zip(row) {
            *s += w * r;
        }
    }
    let (mut sa, mut sb) = ([0.0; 12], [0.0; 12]);
    let m = a.0.len().min(b.0.len());
    for k in 0..m {
        add(&mut sa, a.1[k], &table[a.0[k] as usize]);
        add(&mut sb, b.1[k], &table[b.0[k] as usize]);
    }
    for k in m..a.0.len() {
        add(&mut sa, a.1[k], &table[a.0[k] as usize]);
    }
    for k in m..b.0.len() {
        add(&mut sb, b.1[k], &table[b.0[k] as usize]);
    }
    [sa, sb]
}

fn mean(points: &[Point3]) -> Vector3 {
    points.iter().map(|p| p.coords).sum::<Vector3>() / points.len().max(1) as Real
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::rng::SplitMix64;
    use crate::test_support::Lcg;

    /// Horn's quaternion gives the SVD's rotation wherever it answers, and
    /// answers for well-spread points; reflections and near-degenerate
    /// covariances included.
    #[test]
    fn quaternion_rotation_matches_the_svd() {
        let mut rng = SplitMix64::new(21);
        let mut answered = 0;
        for case in 0..20_000 {
            let mut value = || rng.unit() * 2.0 - 1.0;
            let mut h = Matrix3::from_fn(|_, _| value());
            match case % 5 {
                // A rotation's covariance with noise: the tracker's case.
                0 | 1 => {
                    let r = *crate::math::Rotation3::from_scaled_axis(
                        Vector3::new(value(), value(), value()) * 3.0,
                    )
                    .matrix();
                    let spread = Matrix3::from_diagonal(&Vector3::new(
                        1.0 + value().abs(),
                        1.0 + value().abs(),
                        0.2 + value().abs(),
                    ));
                    h = spread * r.transpose() + h * 0.05;
                }
                // Rank one or two, or nearly.
                2 => {
                    let (u, v) = (
                        Vector3::new(value(), value(), value()),
                        Vector3::new(value(), value(), value()),
                    );
                    h = u * v.transpose() + h * 1e-9 * (case % 3) as Real;
                }
                _ => {}
            }
            h *= (10.0 as Real).powf(6.0 * value());
            let svd = svd_rotation(&h);
            if let Some(q) = quaternion_rotation(&h) {
                answered += 1;
                assert!(
                    (q - svd).norm() < 1e-8,
                    "case {case}: {q} against {svd} for {h}"
                );
                assert!((q.determinant() - 1.0).abs() < 1e-12);
            }
            assert!(
                (rotation_from_covariance(&h) - svd).norm() < 1e-8,
                "case {case}"
            );
        }
        assert!(
            answered > 15_000,
            "only {answered} answered by the quaternion"
        );
    }

    /// The AVX copy of the inner loop (taken on CPUs that have AVX) gives
    /// the same bits as the portable one, and two lists summed together the
    /// same as each alone, so results depend neither on the CPU nor on the pairing.
    #[test]
    fn weighted_sums_are_bit_identical_on_every_path() {
        let mut rng = SplitMix64::new(7);
        let mut value = || (rng.unit() - 0.5) * 1e3;
        let table: Vec<[Real; 12]> = (0..500).map(|_| [(); 12].map(|_| value())).collect();
        let mut rng = SplitMix64::new(8);
        let lists: Vec<(Vec<u32>, Vec<Real>)> = [0, 1, 3, 17, 427, 430]
            .iter()
            .map(|&len| {
                (
                    (0..len).map(|_| rng.below(table.len()) as u32).collect(),
                    (0..len).map(|_| rng.unit()).collect(),
                )
            })
            .collect();
        let bits = |s: [[Real; 12]; 2]| s.map(|s| s.map(Real::to_bits));
        for a in &lists {
            let alone = weighted_sums_portable((&a.0, &a.1), (&[], &[]), &table)[0];
            for b in &lists {
                let pair = ((&a.0[..], &a.1[..]), (&b.0[..], &b.1[..]));
                let (dispatched, portable) = (
                    weighted_sums(pair.0, pair.1, &table),
                    weighted_sums_portable(pair.0, pair.1, &table),
                );
                assert_eq!(
                    bits(dispatched),
                    bits(portable),
                    "{} and {} terms",
                    a.0.len(),
                    b.0.len()
                );
                assert_eq!(
                    alone.map(Real::to_bits),
                    dispatched[0].map(Real::to_bits),
                    "{} terms paired with {}",
                    a.0.len(),
                    b.0.len()
                );
            }
        }
    }

    /// The tracker's batched fits ([`RigidFits`]) and the refinement's
    /// ([`PairTable`]) against one [`fit_rigid`] each: neighbour lists of every
    /// size (empty, one point, collinear, many), points far from the origin,
    /// nearly rigid motions and zero weights.
    #[test]
    fn batched_rigid_fits_equal_single_fits() {
        let mut g = Lcg(5);
        let offset = Vector3::new(250.0, -40.0, 1000.0);
        let n = 120;
        let src: Vec<Point3> = (0..n).map(|_| Point3::from(g.vec(10.0) + offset)).collect();
        let lists: Vec<Vec<(usize, Real)>> = (0..n)
            .map(|i| match i % 6 {
                0 => Vec::new(),
                1 => vec![(i, 1.0)],
                2 => vec![(i, 1.0), ((i + 1) % n, 0.5)],
                3 => (0..n)
                    .step_by(7)
                    .map(|j| (j, if j % 2 == 0 { 0.0 } else { g.next() }))
                    .collect(),
                _ => (0..n)
                    .filter(|j| (j * 31 + i) % 5 == 0)
                    .map(|j| (j, 0.001 + g.next()))
                    .collect(),
            })
            .collect();
        let fits = RigidFits::new(&src, n, |i| lists[i].iter().copied());
        for _ in 0..5 {
            let truth = g.rigid();
            // Rigid plus per-point noise, so that the fits differ from each other.
            let dst: Vec<Point3> = src.iter().map(|p| truth.apply(p) + g.vec(0.3)).collect();
            let batched = fits.fit(&dst);
            let table = PairTable::new(&src, &dst);
            for (i, list) in lists.iter().enumerate() {
                let single = fit_rigid(&src, &dst, list.iter().copied());
                let paired =
                    table.fit(&list.iter().map(|&(j, w)| (j as u32, w)).collect::<Vec<_>>());
                for (a, b) in [(&batched[i], &single), (&paired, &single)] {
                    let energy = |r: &Rigid| -> Real {
                        list.iter()
                            .map(|&(j, w)| w * (dst[j] - r.apply(&src[j])).norm_squared())
                            .sum()
                    };
                    assert!(
                        (energy(a) - energy(b)).abs() <= 1e-9 * (1.0 + energy(b)),
                        "fit {i}: energy {} vs {}",
                        energy(a),
                        energy(b)
                    );
                    if list.len() == 2 {
                        // Two points leave the spin about their line to a 1e-6 pull
                        // towards the identity, which the 3x3 SVD resolves only to
                        // about 1e-5: the line is carried alike, the spin nearly so.
                        assert!(
                            (a.rotation - b.rotation).abs().max() < 1e-3,
                            "fit {i}: {:?} vs {:?}",
                            a.rotation,
                            b.rotation
                        );
                        continue;
                    }
                    assert!(
                        (a.rotation - b.rotation).abs().max() < 1e-9,
                        "fit {i} ({} points): {:?} vs {:?}",
                        list.len(),
                        a.rotation,
                        b.rotation
                    );
                    // Translations carry the offset (about 1000): compare where they take the points.
                    let worst = list
                        .iter()
                        .map(|&(j, _)| (a.apply(&src[j]) - b.apply(&src[j])).norm())
                        .fold(0.0, Real::max);
                    assert!(worst < 1e-8, "fit {i}: points land {worst} apart");
                }
            }
        }
    }
}
