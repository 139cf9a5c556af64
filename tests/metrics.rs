//! PCAC, DFU and irregularity (method.md §6, §8): hand-computed cases, both
//! eigen-decomposition routes of PCAC against a direct implementation of the
//! definition, irregularity against brute force, and the SVG curve.

use nalgebra::{DMatrix, DVector, Rotation3, SymmetricEigen, Vector3};
use voltrack::math::{Point3, Real};
use voltrack::metrics::{dfu, irregularity, irregularity_curve_svg, irregularity_curves_svg, pcac};
use voltrack::track::Trajectories;

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
    let s: Vec<Real> = order.iter().map(|&k| c.column(k).iter().map(|x| x.abs()).sum()).collect();
    let total: Real = s.iter().sum();
    if total == 0.0 {
        return 0.0;
    }
    s.iter().enumerate().map(|(k, s)| k as Real * s).sum::<Real>() / total
}

/// Trajectories whose centered matrix is exactly Σ_k σ_k u_k v_kᵀ (the v_k
/// must sum to zero so the row means vanish).
fn from_components(frames: usize, components: &[(Real, DVector<Real>, DVector<Real>)]) -> Trajectories {
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
        let t = Trajectories::from_frames((0..frames).map(|f| s.iter().map(|&si| Point3::from(g[f] * si)).collect()).collect());
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
            let t = from_components(frames, &[(sigma1, u1, v1.clone()), (sigma2, u2, v2.clone())]);
            let got = pcac(&t);
            assert!(close(got, want, 1e-9), "σ = {sigma1}, {sigma2}, F = {frames}: {got} vs {want}");
        }
    }
}

#[test]
fn pcac_routes_agree_with_the_definition() {
    // N < 3F takes the N × N Gram route, N ≥ 3F the 3F × 3F one; the
    // reference here always takes the 3F × 3F one.
    for (frames, centers, seed) in [(10, 7, 1), (40, 25, 2), (8, 23, 3), (4, 12, 4), (3, 40, 5), (5, 14, 6), (5, 15, 7), (5, 16, 8)] {
        let t = random_trajectories(frames, centers, seed);
        let (got, want) = (pcac(&t), pcac_direct(&t));
        assert!(close(got, want, 1e-9), "F = {frames}, N = {centers}: {got} vs {want}");
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
            let repeated: Vec<Vec<Point3>> = (0..frames).flat_map(|f| std::iter::repeat(t.frame(f).to_vec()).take(r)).collect();
            let tr = Trajectories::from_frames(repeated);
            assert!(tr.centers < 3 * tr.frames);
            let twice = pcac(&tr);
            assert!(close(twice, once, 1e-9), "F = {frames}, N = {centers}, r = {r}: {twice} vs {once}");
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
    assert!(close(pcac(&moved), base, 1e-9), "{} vs {base}", pcac(&moved));
    let scaled = Trajectories { positions: t.positions.iter().map(|p| p * 1e3).collect(), ..t.clone() };
    assert!(close(pcac(&scaled), base, 1e-9));
    let reversed = Trajectories::from_frames((0..t.frames).map(|f| t.frame(f).iter().rev().copied().collect()).collect());
    assert!(close(pcac(&reversed), base, 1e-9));
    // Nothing moving apart (every center in one place), and empty input: 0.
    let still = Trajectories::from_frames(vec![vec![Point3::new(1.0, 2.0, 3.0); 5]; 4]);
    assert_eq!(pcac(&still), 0.0);
    assert_eq!(pcac(&Trajectories::new(0, 0)), 0.0);
    assert_eq!(pcac(&Trajectories::new(3, 0)), 0.0);
    let single = Trajectories::from_frames(vec![vec![Point3::new(1.0, 0.0, 0.0)], vec![Point3::new(2.0, 0.0, 0.0)]]);
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
    let (mean, per_frame) = dfu(&[vec![2, 2, 2, 2], vec![1, 3], vec![], vec![0, 0, 0], vec![3, 1]]);
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
    for (seed, frames, centers) in [(1, 9, 40), (2, 1, 25), (3, 30, 60), (4, 5, 2), (5, 17, 33), (6, 2, 90)] {
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
                t.set(f, 9, if f % 2 == 0 { q } else { q + Vector3::new(0.5, 0.0, 0.0) });
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
                .map(|j| (0..frames).map(|f| (t.get(f, i) - t.get(f, j)).norm_squared()).sum::<Real>())
                .fold(Real::INFINITY, Real::min);
            assert!((got[i] - other).abs() <= 1e-12 * other, "seed {seed}, center {i}: {} vs {other}", got[i]);
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
    let run = |threads| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| irregularity(&t));
    let one = run(1);
    assert_eq!(one, run(4));
    assert_eq!(one, irregularity_brute_force(&t));
}

/// Checks that `svg` is well-formed XML as far as these plots go: tags nest
/// and close, attributes are quoted, text holds no raw `<` or bare `&`.
fn assert_well_formed(svg: &str) {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = svg;
    while let Some(open) = rest.find('<') {
        let text = &rest[..open];
        for (i, _) in text.match_indices('&') {
            let entity = &text[i..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"].iter().any(|e| entity.starts_with(e)),
                "bare & in text: {text}"
            );
        }
        let close = rest[open..].find('>').expect("unclosed tag") + open;
        let tag = &rest[open + 1..close];
        assert!(!tag.contains('<'), "'<' inside a tag: {tag}");
        assert_eq!(tag.matches('"').count() % 2, 0, "unbalanced quotes in {tag}");
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(stack.pop().as_deref(), Some(name.trim()), "mismatched </{name}>");
        } else if !tag.ends_with('/') && !tag.starts_with('?') && !tag.starts_with('!') {
            stack.push(tag.split_whitespace().next().unwrap().to_string());
        } else {
            assert!(stack.first().is_some_and(|s| s == "svg") || tag.starts_with('?') || tag.starts_with('!'), "element outside <svg>");
        }
        rest = &rest[close + 1..];
    }
    assert!(rest.trim().is_empty(), "text after the root element: {rest}");
    assert!(stack.is_empty(), "unclosed elements: {stack:?}");
}

/// The numbers of every `points` attribute of the polylines.
fn polylines(svg: &str) -> Vec<Vec<(Real, Real)>> {
    svg.lines()
        .filter(|l| l.trim_start().starts_with("<polyline"))
        .map(|l| {
            let start = l.find("points=\"").unwrap() + 8;
            let end = start + l[start..].find('"').unwrap();
            l[start..end]
                .split_whitespace()
                .map(|xy| {
                    let (x, y) = xy.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}

#[test]
fn irregularity_curve_is_well_formed_svg() {
    let values = [3.0, 0.0, Real::INFINITY, 1e-3, 0.5, 2.0, Real::NAN, 1e-300, 7e5];
    let svg = irregularity_curve_svg(&values);
    assert!(svg.starts_with("<svg"), "{svg}");
    assert!(svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("<polyline"));
    assert_well_formed(&svg);
    for bad in ["NaN", "nan", "inf", "Infinity"] {
        assert!(!svg.contains(bad), "{bad} in {svg}");
    }
    // One point per finite positive value (0 has no place on a log axis),
    // inside the picture, falling from left to right (most irregular first).
    let lines = polylines(&svg);
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0].len(), 6);
    for w in lines[0].windows(2) {
        assert!(w[0].0 < w[1].0 && w[0].1 <= w[1].1, "{:?}", lines[0]);
    }
    assert!(lines[0].iter().all(|&(x, y)| (0.0..=720.0).contains(&x) && (0.0..=420.0).contains(&y)));

    // Degenerate inputs still give a valid picture without NaN: nothing,
    // only zeros and infinities, one value, all equal.
    for values in [vec![], vec![0.0, Real::INFINITY, 0.0], vec![Real::INFINITY], vec![0.25], vec![2.0; 50]] {
        let svg = irregularity_curve_svg(&values);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{values:?}");
        assert_well_formed(&svg);
        assert!(!svg.contains("NaN") && !svg.contains("inf"), "{values:?}: {svg}");
        for line in polylines(&svg) {
            assert!(line.iter().all(|&(x, y)| x.is_finite() && y.is_finite()));
        }
    }

    // Several curves, with labels that need escaping.
    let svg = irregularity_curves_svg(&[("before <refine> & after", &[1.0, 2.0, 3.0][..]), ("\"quoted\"", &[0.5, 0.25][..])]);
    assert_well_formed(&svg);
    assert_eq!(polylines(&svg).len(), 2);
    assert!(svg.contains("before &lt;refine&gt; &amp; after"));
}
