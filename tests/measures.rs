//! PCAC, DFU and irregularity (method.md §6, §8) on hand-computed cases and
//! against direct evaluation of their definitions.

use nalgebra::{DMatrix, SymmetricEigen};
use voltrack::math::{Point3, Real};
use voltrack::metrics::{dfu, irregularity, irregularity_curve_svg, pcac};
use voltrack::track::Trajectories;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> Real {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as Real / (1u64 << 53) as Real
    }
}

fn random_trajectories(frames: usize, centers: usize, seed: u64) -> Trajectories {
    let mut rng = Rng(seed);
    Trajectories::from_frames(
        (0..frames).map(|_| (0..centers).map(|_| Point3::new(rng.next(), rng.next(), rng.next())).collect()).collect(),
    )
}

/// PCAC straight from the definition: eigenvectors of M Mᵀ, C = Mᵀ V.
fn pcac_by_definition(t: &Trajectories) -> Real {
    let m = DMatrix::from_fn(3 * t.frames, t.centers, |r, i| {
        let mean = (0..t.centers).map(|j| t.get(r / 3, j)[r % 3]).sum::<Real>() / t.centers as Real;
        t.get(r / 3, i)[r % 3] - mean
    });
    let eig = SymmetricEigen::new(&m * m.transpose());
    let c = m.transpose() * &eig.eigenvectors;
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    // The null space's coefficients are 0 exactly; here they are rounding noise.
    let largest = eig.eigenvalues[order[0]];
    let s: Vec<Real> =
        order.iter().map(|&k| if eig.eigenvalues[k] > 1e-12 * largest { c.column(k).iter().map(|x| x.abs()).sum() } else { 0.0 }).collect();
    s.iter().enumerate().map(|(k, s)| k as Real * s).sum::<Real>() / s.iter().sum::<Real>()
}

#[test]
fn pcac_of_one_component_is_zero() {
    // Every center's trajectory is a multiple of one direction: M has rank 1.
    let frames: Vec<Vec<Point3>> =
        (0..5).map(|f| (0..7).map(|i| Point3::new(i as Real * (1.0 + f as Real), 0.0, 0.0)).collect()).collect();
    assert!(pcac(&Trajectories::from_frames(frames)).abs() < 1e-9);
}

#[test]
fn pcac_of_two_known_components() {
    // Four centers, one frame: offsets (±a, 0, 0) and (0, ±b, 0) from the mean.
    // Components x (eigenvalue 2a²) and y (2b²), S_x = 2a, S_y = 2b; with a > b
    // PCAC = (0·2a + 1·2b) / (2a + 2b).
    let (a, b) = (3.0, 1.0);
    let frame = vec![Point3::new(a, 0.0, 0.0), Point3::new(-a, 0.0, 0.0), Point3::new(0.0, b, 0.0), Point3::new(0.0, -b, 0.0)];
    let got = pcac(&Trajectories::from_frames(vec![frame]));
    assert!((got - b / (a + b)).abs() < 1e-12, "{got}");
}

#[test]
fn pcac_both_routes_match_the_definition() {
    // 3F > N (Gram route) and 3F < N (M Mᵀ route).
    for (frames, centers, seed) in [(10, 7, 1), (4, 30, 2), (6, 18, 3), (20, 50, 4)] {
        let t = random_trajectories(frames, centers, seed);
        let (got, want) = (pcac(&t), pcac_by_definition(&t));
        assert!((got - want).abs() < 1e-9 * want.max(1.0), "F={frames} N={centers}: {got} vs {want}");
    }
}

#[test]
fn dfu_hand_cases() {
    assert_eq!(dfu(&[vec![2, 2, 2, 2]]).0, 0.0);
    let (mean, per_frame) = dfu(&[vec![1, 3], vec![5, 5], vec![0, 4]]);
    assert_eq!(per_frame, vec![0.5, 0.0, 1.0]);
    assert!((mean - 0.5).abs() < 1e-15);
}

#[test]
fn irregularity_matches_brute_force() {
    for seed in 0..6 {
        let mut t = random_trajectories(9, 40, seed);
        // Exact and near duplicates, and one far-off center.
        for f in 0..t.frames {
            let p = t.get(f, 3);
            t.set(f, 5, p);
            t.set(f, 7, p + nalgebra::Vector3::new(1e-9, 0.0, 0.0));
            t.set(f, 11, Point3::new(50.0, 0.0, f as Real));
        }
        let got = irregularity(&t);
        for i in 0..t.centers {
            let want = (0..t.centers)
                .filter(|&j| j != i)
                .map(|j| (0..t.frames).map(|f| (t.get(f, i) - t.get(f, j)).norm_squared()).sum::<Real>())
                .fold(Real::INFINITY, Real::min);
            assert!((got[i] - want).abs() <= 1e-12 * want.max(1e-300), "seed {seed} center {i}: {} vs {want}", got[i]);
        }
        assert_eq!(got[5], 0.0);
    }
}

#[test]
fn irregularity_curve_is_an_svg_without_nan() {
    let svg = irregularity_curve_svg(&[3.0, 0.0, Real::INFINITY, 1e-3, 0.5, 2.0]);
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("<polyline"));
    assert!(!svg.contains("NaN") && !svg.contains("inf"), "{svg}");
    // Nothing to draw is still a valid, empty plot.
    let empty = irregularity_curve_svg(&[]);
    assert!(empty.starts_with("<svg") && !empty.contains("NaN"));
}
