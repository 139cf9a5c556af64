//! PCAC, DFU and irregularity (docs/method.md §6, §8): hand-computed cases, both
//! eigen-decomposition routes of PCAC against a direct implementation of the
//! definition, irregularity against brute force, and the SVG curve.

mod common;
use nalgebra::{DMatrix, DVector, Rotation3, SymmetricEigen, Vector3};
use voltrack::math::{Point3, Real};
use voltrack::metrics::{dfu, irregularity, pcac};
use voltrack::model::Trajectories;

/// SplitMix64: a fixed-seed generator, independent of the crate's own.
struct Rng(u64);
impl Rng {
    fn u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [-1, 1).
    fn uniform(&mut self) -> Real {
        (self.u64() >> 11) as Real / (1u64 << 52) as Real - 1.0
    }
    fn point(&mut self) -> Point3 {
        Point3::new(self.uniform(), self.uniform(), self.uniform())
    }
}

/// Random-walk trajectories: smooth-ish, like tracked centers, not white noise.
fn random_trajectories(frames: usize, centers: usize, seed: u64) -> Trajectories {
    let mut rng = Rng(seed);
    let mut current: Vec<Point3> = (0..centers).map(|_| rng.point() * 2.0).collect();
    let mut out = Vec::new();
    for _ in 0..frames {
        out.push(current.clone());
        for p in &mut current {
            *p += rng.point().coords * 0.1;
        }
    }
    Trajectories::from_frames(out)
}

/// The 3F × N matrix M of the definition: column i is center i's trajectory
/// (x⁰ y⁰ z⁰ x¹ …), each row's mean over the centers subtracted.
fn centered_matrix(t: &Trajectories) -> DMatrix<Real> {
    let mut m = DMatrix::from_fn(3 * t.frames, t.centers, |r, i| t.get(r / 3, i)[r % 3]);
    for mut row in m.row_iter_mut() {
        let mean = row.mean();
        row.add_scalar_mut(-mean);
    }
    m
}

/// PCAC by the definition, always through the 3F × 3F matrix M Mᵀ: V its
/// eigenvectors by decreasing eigenvalue, C = Mᵀ V, S_k = Σ_j |C_jk|,
/// PCAC = Σ_k k S_k / Σ_k S_k. No cut-off of the null space: its columns of
/// C are rounding noise, far below the tolerances used here.
fn pcac_direct(t: &Trajectories) -> Real {
    let m = centered_matrix(t);
    let eig = SymmetricEigen::new(&m * m.transpose());
    let c = m.transpose() * &eig.eigenvectors;
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let s: Vec<Real> = order
        .iter()
        .map(|&k| c.column(k).iter().map(|x| x.abs()).sum())
        .collect();
    let total: Real = s.iter().sum();
    if total == 0.0 {
        return 0.0;
    }
    s.iter()
        .enumerate()
        .map(|(k, s)| k as Real * s)
        .sum::<Real>()
        / total
}

/// Trajectories whose centered matrix is exactly Σ_k σ_k u_k v_kᵀ (the v_k
/// must sum to zero so the row means vanish).
fn from_components(
    frames: usize,
    components: &[(Real, DVector<Real>, DVector<Real>)],
) -> Trajectories {
    let centers = components[0].2.len();
    let mut t = Trajectories::new(frames, centers);
    for f in 0..frames {
        for i in 0..centers {
            let mut p = Point3::origin();
            for (sigma, u, v) in components {
                for k in 0..3 {
                    p[k] += sigma * u[3 * f + k] * v[i];
                }
            }
            t.set(f, i, p);
        }
    }
    t
}

/// An orthonormal pair in R^n from fixed-seed random vectors (Gram-Schmidt).
fn orthonormal_pair(n: usize, seed: u64) -> (DVector<Real>, DVector<Real>) {
    let mut rng = Rng(seed);
    let a = DVector::from_fn(n, |_, _| rng.uniform()).normalize();
    let b = DVector::from_fn(n, |_, _| rng.uniform());
    let b = (&b - &a * a.dot(&b)).normalize();
    (a, b)
}

fn close(got: Real, want: Real, tol: Real) -> bool {
    (got - want).abs() <= tol * want.abs().max(1.0)
}

#[test]
fn pcac_of_centers_translating_together_is_that_of_one_frame() {
    // Offsets (±a, 0, 0), (0, ±b, 0), (0, 0, ±c) from a common point that moves
    // arbitrarily: after the mean over centers is subtracted every frame's rows
    // are the same, M = 1_F ⊗ D, so C = √F Dᵀ w_k and PCAC is that of D alone.
    // Components x, y, z with eigenvalues 2a², 2b², 2c² (a > b > c) and
    // S = 2a, 2b, 2c: PCAC = (0·2a + 1·2b + 2·2c) / (2a + 2b + 2c).
    let (a, b, c) = (3.0, 1.5, 0.5);
    let offsets = [
        Vector3::new(a, 0.0, 0.0),
        Vector3::new(-a, 0.0, 0.0),
        Vector3::new(0.0, b, 0.0),
        Vector3::new(0.0, -b, 0.0),
        Vector3::new(0.0, 0.0, c),
        Vector3::new(0.0, 0.0, -c),
    ];
    let want = (b + 2.0 * c) / (a + b + c);
    let one = Trajectories::from_frames(vec![offsets.iter().map(|o| Point3::from(*o)).collect()]);
    assert!(close(pcac(&one), want, 1e-12), "{} vs {want}", pcac(&one));
    // 1, 2 frames (3F ≤ N: the M Mᵀ route) and 3, 10 frames (3F > N: the Gram route).
    for frames in [1, 2, 3, 10] {
        let mut rng = Rng(frames as u64);
        let moving: Vec<Vec<Point3>> = (0..frames)
            .map(|_| {
                let common = rng.point() * 5.0;
                offsets.iter().map(|o| common + o).collect()
            })
            .collect();
        let t = Trajectories::from_frames(moving);
        // The rows after mean subtraction really are frame-constant.
        let m = centered_matrix(&t);
        for r in 3..m.nrows() {
            for i in 0..m.ncols() {
                assert!((m[(r, i)] - m[(r % 3, i)]).abs() < 1e-12);
            }
        }
        let got = pcac(&t);
        assert!(close(got, want, 1e-9), "F = {frames}: {got} vs {want}");
    }
}

#[test]
fn pcac_of_one_principal_component_is_zero() {
    // Center i in frame f at s_i · g(f): M = g (s − s̄)ᵀ has rank one.
    for (frames, centers) in [(2, 20), (4, 12), (5, 7), (30, 9)] {
        let mut rng = Rng(100 + frames as u64);
        let s: Vec<Real> = (0..centers).map(|_| rng.uniform()).collect();
        let g: Vec<Vector3<Real>> = (0..frames).map(|_| rng.point().coords).collect();
        let t = Trajectories::from_frames(
            (0..frames)
                .map(|f| s.iter().map(|&si| Point3::from(g[f] * si)).collect())
                .collect(),
        );
        let got = pcac(&t);
        assert!(got.abs() < 1e-9, "F = {frames}, N = {centers}: {got}");
        assert!(pcac_direct(&t).abs() < 1e-9);
    }
}

#[test]
fn pcac_of_two_components_with_known_coefficients() {
    // v₁ = (1, 1, 1, −1, −1, −1)/√6 (Σ|v₁| = √6), v₂ = (1, −1, 0, 1, −1, 0)/2
    // (Σ|v₂| = 2): orthonormal, both summing to zero. With orthonormal u₁, u₂
    // and σ₁ > σ₂, M = σ₁ u₁ v₁ᵀ + σ₂ u₂ v₂ᵀ, C's columns are σ_k v_k, so
    // S₀ = σ₁ √6, S₁ = 2 σ₂ and PCAC = S₁ / (S₀ + S₁).
    let v1 = DVector::from_vec(vec![1.0, 1.0, 1.0, -1.0, -1.0, -1.0]) / (6.0 as Real).sqrt();
    let v2 = DVector::from_vec(vec![1.0, -1.0, 0.0, 1.0, -1.0, 0.0]) / 2.0;
    for (sigma1, sigma2) in [(3.0, 1.0), (1.0, 0.999), (10.0, 0.01)] {
        let want = 2.0 * sigma2 / (sigma1 * (6.0 as Real).sqrt() + 2.0 * sigma2);
        // F = 1, 2: 3F ≤ 6 (M Mᵀ route); F = 3, 7: 3F > 6 (Gram route).
        for frames in [1, 2, 3, 7] {
            let (u1, u2) = orthonormal_pair(3 * frames, 7 * frames as u64);
            let t = from_components(
                frames,
                &[(sigma1, u1, v1.clone()), (sigma2, u2, v2.clone())],
            );
            let got = pcac(&t);
            assert!(
                close(got, want, 1e-9),
                "σ = {sigma1}, {sigma2}, F = {frames}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn pcac_routes_agree_with_the_definition() {
    // N < 3F takes the N × N Gram route, N ≥ 3F the 3F × 3F one; the
    // reference here always takes the 3F × 3F one.
    for (frames, centers, seed) in [
        (10, 7, 1),
        (40, 25, 2),
        (8, 23, 3),
        (4, 12, 4),
        (3, 40, 5),
        (5, 14, 6),
        (5, 15, 7),
        (5, 16, 8),
    ] {
        let t = random_trajectories(frames, centers, seed);
        let (got, want) = (pcac(&t), pcac_direct(&t));
        assert!(
            close(got, want, 1e-9),
            "F = {frames}, N = {centers}: {got} vs {want}"
        );
        assert!(got > 0.0 && got < (3 * frames).min(centers) as Real);
    }
}

#[test]
fn pcac_routes_agree_with_each_other_on_the_same_motion() {
    // Repeating every frame r times makes M r-fold taller (rows repeated), so
    // M Mᵀ's nonzero eigenvectors are the old ones spread over the copies and
    // C scales by √r: the same PCAC, computed once by the M Mᵀ route (N ≥ 3F)
    // and once by the Gram route (N < 3rF).
    for (frames, centers, seed) in [(3, 12, 11), (4, 12, 12), (2, 30, 13), (6, 18, 14)] {
        let t = random_trajectories(frames, centers, seed);
        assert!(centers >= 3 * frames);
        let once = pcac(&t);
        // Enough copies that 3 r F > N.
        let r0 = centers / (3 * frames) + 1;
        for r in [r0, r0 + 1, r0 + 3] {
            let repeated: Vec<Vec<Point3>> = (0..frames)
                .flat_map(|f| std::iter::repeat_n(t.frame(f).to_vec(), r))
                .collect();
            let tr = Trajectories::from_frames(repeated);
            assert!(tr.centers < 3 * tr.frames);
            let twice = pcac(&tr);
            assert!(
                close(twice, once, 1e-9),
                "F = {frames}, N = {centers}, r = {r}: {twice} vs {once}"
            );
        }
    }
}

#[test]
fn pcac_invariances() {
    let t = random_trajectories(12, 20, 21);
    let base = pcac(&t);
    // Per-frame rigid motions of the whole set (block-orthogonal M' = Q M),
    // scaling, and reordering the centers change nothing.
    let mut rng = Rng(22);
    let moved = Trajectories::from_frames(
        (0..t.frames)
            .map(|f| {
                let r = Rotation3::new(rng.point().coords * 2.0);
                let shift = rng.point().coords * 10.0;
                t.frame(f).iter().map(|p| r * p + shift).collect()
            })
            .collect(),
    );
    assert!(
        close(pcac(&moved), base, 1e-9),
        "{} vs {base}",
        pcac(&moved)
    );
    let scaled = Trajectories {
        positions: t.positions.iter().map(|p| p * 1e3).collect(),
        ..t.clone()
    };
    assert!(close(pcac(&scaled), base, 1e-9));
    let reversed = Trajectories::from_frames(
        (0..t.frames)
            .map(|f| t.frame(f).iter().rev().copied().collect())
            .collect(),
    );
    assert!(close(pcac(&reversed), base, 1e-9));
    // Nothing moving apart (every center in one place), and empty input: 0.
    let still = Trajectories::from_frames(vec![vec![Point3::new(1.0, 2.0, 3.0); 5]; 4]);
    assert_eq!(pcac(&still), 0.0);
    assert_eq!(pcac(&Trajectories::new(0, 0)), 0.0);
    assert_eq!(pcac(&Trajectories::new(3, 0)), 0.0);
    let single = Trajectories::from_frames(vec![
        vec![Point3::new(1.0, 0.0, 0.0)],
        vec![Point3::new(2.0, 0.0, 0.0)],
    ]);
    assert_eq!(pcac(&single), 0.0);
}

#[test]
fn dfu_hand_cases() {
    // Equal counts: 0.
    assert_eq!(dfu(&[vec![2, 2, 2, 2]]), (0.0, vec![0.0]));
    // [1, 3]: mean 2, population std 1 -> 0.5.
    assert_eq!(dfu(&[vec![1, 3]]), (0.5, vec![0.5]));
    // [0, 0, 0, 4]: mean 1, variance (1 + 1 + 1 + 9)/4 = 3 -> √3.
    let (mean, per_frame) = dfu(&[vec![0, 0, 0, 4]]);
    assert!((per_frame[0] - (3.0 as Real).sqrt()).abs() < 1e-15 && mean == per_frame[0]);
    // Mean over frames; empty and all-zero frames count 0.
    let (mean, per_frame) = dfu(&[
        vec![2, 2, 2, 2],
        vec![1, 3],
        vec![],
        vec![0, 0, 0],
        vec![3, 1],
    ]);
    assert_eq!(per_frame, vec![0.0, 0.5, 0.0, 0.0, 0.5]);
    assert!((mean - 1.0 / 5.0).abs() < 1e-15, "{mean}");
    // Scale invariance: counts ×10 give the same value.
    assert!((dfu(&[vec![10, 30]]).0 - 0.5).abs() < 1e-15);
    // No frames at all.
    assert_eq!(dfu(&[]), (0.0, vec![]));
}

/// I_i by brute force over all pairs, summing in the library's order
/// (frames in order, each ‖·‖² as x² + y² + z²), so equal bit for bit.
fn irregularity_brute_force(t: &Trajectories) -> Vec<Real> {
    (0..t.centers)
        .map(|i| {
            let mut best = Real::INFINITY;
            for j in (0..t.centers).filter(|&j| j != i) {
                let mut sum = 0.0;
                for f in 0..t.frames {
                    let (a, b) = (t.get(f, i), t.get(f, j));
                    sum += (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<Real>();
                }
                best = best.min(sum);
            }
            best
        })
        .collect()
}

#[test]
fn irregularity_matches_brute_force() {
    for (seed, frames, centers) in [
        (1, 9, 40),
        (2, 1, 25),
        (3, 30, 60),
        (4, 5, 2),
        (5, 17, 33),
        (6, 2, 90),
    ] {
        let mut t = random_trajectories(frames, centers, seed);
        let mut rng = Rng(seed + 1000);
        if centers > 12 {
            for f in 0..frames {
                // An exact duplicate, near duplicates, a trajectory that is near
                // only in some frames, and a far-off center.
                let p = t.get(f, 3);
                t.set(f, 5, p);
                t.set(f, 7, p + Vector3::new(1e-9, -1e-9, 0.0));
                t.set(f, 8, p + rng.point().coords * 1e-7);
                let q = t.get(f, 1);
                t.set(
                    f,
                    9,
                    if f % 2 == 0 {
                        q
                    } else {
                        q + Vector3::new(0.5, 0.0, 0.0)
                    },
                );
                t.set(f, 11, Point3::new(50.0 + f as Real, 0.0, 0.0));
            }
        }
        let got = irregularity(&t);
        let want = irregularity_brute_force(&t);
        assert_eq!(got.len(), centers);
        for i in 0..centers {
            assert_eq!(got[i], want[i], "seed {seed}, center {i}");
            // And against an independent evaluation (nalgebra's norm), relatively.
            let other = (0..centers)
                .filter(|&j| j != i)
                .map(|j| {
                    (0..frames)
                        .map(|f| (t.get(f, i) - t.get(f, j)).norm_squared())
                        .sum::<Real>()
                })
                .fold(Real::INFINITY, Real::min);
            assert!(
                (got[i] - other).abs() <= 1e-12 * other,
                "seed {seed}, center {i}: {} vs {other}",
                got[i]
            );
        }
        if centers > 12 {
            assert_eq!(got[3], 0.0);
            assert_eq!(got[5], 0.0);
            assert!(got[11] > 100.0);
        }
    }
}

#[test]
fn irregularity_edge_cases_and_threads() {
    // A lone center is infinitely irregular; none gives nothing.
    let lone = Trajectories::from_frames(vec![vec![Point3::new(1.0, 2.0, 3.0)]; 4]);
    assert_eq!(irregularity(&lone), vec![Real::INFINITY]);
    assert!(irregularity(&Trajectories::new(3, 0)).is_empty());
    // Two centers: each is the other's nearest, Σ_f ‖d_f‖² by hand.
    let two = Trajectories::from_frames(vec![
        vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0)],
        vec![Point3::new(0.0, 0.0, 0.0), Point3::new(0.0, 2.0, 0.0)],
        vec![Point3::new(1.0, 1.0, 1.0), Point3::new(1.0, 1.0, 4.0)],
    ]);
    assert_eq!(irregularity(&two), vec![14.0, 14.0]);
    // The result does not depend on the thread count.
    let t = random_trajectories(11, 150, 31);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| irregularity(&t))
    };
    let one = run(1);
    assert_eq!(one, run(4));
    assert_eq!(one, irregularity_brute_force(&t));
}

// ---------------------------------------------------------------------------
// Surface fit (its exact point-to-triangle distances through the hierarchy
// are tested in src/spatial/surface_tests.rs).

use voltrack::fixtures;
use voltrack::metrics::{surface_fit, DistanceSummary, Surface};
use voltrack::TriangleMesh;

#[test]
fn weighted_summary_by_hand() {
    let s = DistanceSummary::of_weighted(&[(1.0, 1.0), (3.0, 2.0), (2.0, 1.0)]);
    assert_eq!(
        s,
        DistanceSummary {
            mean: 2.25,
            p95: 3.0,
            max: 3.0
        }
    );
    // 95 % of the weight on the smallest value: it is the 95th percentile.
    let s = DistanceSummary::of_weighted(&[(10.0, 1.0), (0.0, 99.0)]);
    assert_eq!((s.p95, s.max), (0.0, 10.0));
    assert!(close(s.mean, 0.1, 1e-15));
    let values: Vec<(Real, Real)> = (1..=100).rev().map(|v| (v as Real, 1.0)).collect();
    assert_eq!(
        DistanceSummary::of_weighted(&values),
        DistanceSummary {
            mean: 50.5,
            p95: 95.0,
            max: 100.0
        }
    );
    // Weights that sum to zero count equally; no samples give zeros.
    assert_eq!(
        DistanceSummary::of_weighted(&[(1.0, 0.0), (3.0, 0.0)]).mean,
        2.0
    );
    assert_eq!(
        DistanceSummary::of_weighted(&[]),
        DistanceSummary::default()
    );
}

/// A square sheet of `n` × `n` cells in the plane z = `z`, side 1.
fn sheet(n: u32, z: Real) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            m.positions
                .push(Point3::new(i as Real / n as Real, j as Real / n as Real, z));
        }
    }
    let v = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            m.triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            m.triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    m
}

#[test]
fn surface_fit_known_cases() {
    let fit = |result: &TriangleMesh, input: &TriangleMesh, diagonal: Real| {
        surface_fit(
            Surface::from(result),
            Surface::from(input),
            diagonal,
            voltrack::metrics::fit::FarDistances::both(2.0),
            None,
        )
    };
    // Identical surfaces: nothing anywhere.
    let sphere = fixtures::sphere(Point3::origin(), 1.0, 24, 12);
    let same = fit(&sphere, &sphere, 2.0);
    for s in [same.result_to_input, same.input_to_result, same.two_sided] {
        assert_eq!(s, DistanceSummary::default());
    }
    // A sheet lifted by 0.01 against a differently meshed sheet: 0.01
    // everywhere, which is 0.5 % of a diagonal of 2.
    let lifted = fit(&sheet(7, 0.01), &sheet(5, 0.0), 2.0);
    for s in [
        lifted.result_to_input,
        lifted.input_to_result,
        lifted.two_sided,
    ] {
        for v in [s.mean, s.p95, s.max] {
            assert!(close(v, 0.5, 1e-12), "{lifted:?}");
        }
    }
    // The same sphere scaled by 1.1 as the result: each of its vertices lies
    // radially outside a vertex of the inscribed input, which is its nearest
    // point, so result -> input is 0.1 (up to the fixture's f32 rounding of
    // the vertices); the input's vertices are inside the larger polyhedron,
    // nearer than 0.1 to its faces.
    let mut larger = sphere.clone();
    larger.positions.iter_mut().for_each(|p| *p *= 1.1);
    let shell = fit(&larger, &sphere, 1.0);
    for v in [
        shell.result_to_input.mean,
        shell.result_to_input.p95,
        shell.result_to_input.max,
    ] {
        assert!(close(v, 10.0, 1e-6), "{shell:?}");
    }
    assert!(
        shell.input_to_result.max < 10.0 && shell.input_to_result.mean > 5.0,
        "{shell:?}"
    );
    // Part of the input missing from the result shows only input -> result,
    // and the two-sided mean weighs both directions alike.
    let cube = fixtures::cube(Point3::new(4.0, 0.0, 0.0), 1.0);
    let both = fixtures::merge(&[sphere.clone(), cube]);
    let part = fit(&sphere, &both, 1.0);
    assert_eq!(part.result_to_input, DistanceSummary::default());
    assert!(part.input_to_result.max > 250.0, "{part:?}");
    assert!(
        close(part.two_sided.mean, part.input_to_result.mean / 2.0, 1e-12),
        "{part:?}"
    );
    assert_eq!(part.two_sided.max, part.input_to_result.max);
}

#[test]
fn surface_fit_does_not_depend_on_the_thread_count() {
    let input = fixtures::torus(Point3::origin(), 1.0, 0.35, 40, 20);
    let mut rng = Rng(77);
    let mut result = fixtures::torus(Point3::origin(), 1.0, 0.3, 31, 17);
    result
        .positions
        .iter_mut()
        .for_each(|p| *p += rng.point().coords * 0.05);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                surface_fit(
                    Surface::from(&result),
                    Surface::from(&input),
                    2.7,
                    voltrack::metrics::fit::FarDistances::both(2.0),
                    None,
                )
            })
    };
    let one = run(1);
    assert_eq!(one, run(3));
    assert!(
        one.two_sided.mean > 0.0 && one.two_sided.max < 10.0,
        "{one:?}"
    );
}

/// The largest far regions: a part of the input the result lacks is one
/// region of the input's surface (its share of the area, its farthest
/// point); a part the result carries where the input has none is one of
/// the result's, unless it lies inside the input's volume (a surface the
/// input hides where two parts touch); each direction has its own distance.
#[test]
fn far_regions_find_a_missing_part_and_skip_hidden_surfaces() {
    use voltrack::metrics::fit::FarDistances;
    let body = fixtures::sphere(Point3::origin(), 1.0, 24, 12);
    let limb = fixtures::cube(Point3::new(4.0, 0.0, 0.0), 1.0);
    let whole = fixtures::merge(&[body.clone(), limb.clone()]);
    let diagonal = 10.0;
    let fit = |result: &TriangleMesh,
               input: &TriangleMesh,
               far: FarDistances,
               inside: Option<voltrack::metrics::fit::InsideInput>| {
        surface_fit(
            Surface::from(result),
            Surface::from(input),
            diagonal,
            far,
            inside,
        )
    };
    // The result lacks the limb: the input's cube is one far region of its
    // share of the area; its far corners are about 3.6 from the sphere (36 %
    // of a diagonal of 10), its near ones 2.6.
    let lost = fit(&body, &whole, FarDistances::both(2.0), None);
    let area = |m: &TriangleMesh| {
        m.triangles
            .iter()
            .map(|t| {
                (m.positions[t[1] as usize] - m.positions[t[0] as usize])
                    .cross(&(m.positions[t[2] as usize] - m.positions[t[0] as usize]))
                    .norm()
                    / 2.0
            })
            .sum::<Real>()
    };
    let cube_share = 100.0 * area(&limb) / area(&whole);
    assert_eq!(lost.far_input.vertices, 8, "{lost:?}");
    assert!(
        (lost.far_input.share - cube_share).abs() < 0.2 * cube_share,
        "{lost:?} against {cube_share}"
    );
    assert!(
        lost.far_input.farthest > 30.0 && lost.far_input.farthest < 50.0,
        "{lost:?}"
    );
    assert_eq!(lost.far_result.vertices, 0);
    // Past the farthest distance, nothing is far.
    assert_eq!(
        fit(&body, &whole, FarDistances::of(50.0, 2.0), None)
            .far_input
            .vertices,
        0
    );
    // ... but past a weaker distance below it, the region is weakly far.
    let weakly = fit(
        &body,
        &whole,
        FarDistances {
            weak_input: 2.0,
            ..FarDistances::of(50.0, 2.0)
        },
        None,
    );
    assert_eq!(weakly.far_input.vertices, 0);
    assert_eq!(weakly.weak_input, lost.far_input, "{weakly:?}");
    // The result carries the limb where the input has none: far one way
    // only, at the result's own distance...
    let carried = fit(&whole, &body, FarDistances::of(2.0, 20.0), None);
    assert_eq!(carried.far_input.vertices, 0);
    assert_eq!(carried.far_result.vertices, 8, "{carried:?}");
    assert_eq!(
        fit(&whole, &body, FarDistances::of(2.0, 50.0), None)
            .far_result
            .vertices,
        0
    );
    // ... and not at all when the input's volume holds it.
    let inside = |p: &Point3| p.x > 2.0;
    let hidden = fit(&whole, &body, FarDistances::both(2.0), Some(&inside));
    assert_eq!(hidden.far_result.vertices, 0, "{hidden:?}");
}

/// The far distances never fall under `far_voxels` voxels: at a coarse
/// grid a rebuilt surface is that far off without any part being lost.
#[test]
fn far_distances_keep_to_a_few_voxels() {
    let params = voltrack::params::CoverageParams::default();
    let fine = params.far_distances(100.0, 0.25);
    assert_eq!((fine.input, fine.result), (params.far, params.far_result));
    // Voxels of 2 % of the diagonal: 3 of them are 6 %.
    let coarse = params.far_distances(100.0, 2.0);
    assert!(
        (coarse.input - 6.0).abs() < 1e-12 && (coarse.result - 6.0).abs() < 1e-12,
        "{coarse:?}"
    );
}
