//! Exact point-to-triangle distances, and the hierarchy's nearest points
//! against a brute-force scan of every triangle.

use super::*;
use crate::model::TriangleMesh;
use nalgebra::{Rotation3, Vector3};

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

fn close(got: Real, want: Real, tol: Real) -> bool {
    (got - want).abs() <= tol * want.abs().max(1.0)
}

/// Distance to every triangle, smallest taken: what the index must equal.
fn brute_force_distance(p: &Point3, mesh: &TriangleMesh) -> Real {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            point_triangle_distance_squared(p, &a, &b, &c)
        })
        .fold(Real::INFINITY, Real::min)
        .sqrt()
}

#[test]
fn point_triangle_distance_in_each_region() {
    let (a, b, c) = (
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
    );
    // (query, closest point on the triangle): vertex, edge and face regions.
    let cases = [
        (Point3::new(-1.0, -1.0, 0.5), a),
        (Point3::new(2.0, -0.5, 0.0), b),
        (Point3::new(-0.5, 2.0, 1.0), c),
        (Point3::new(0.5, -1.0, 1.0), Point3::new(0.5, 0.0, 0.0)),
        (Point3::new(-2.0, 0.3, 0.0), Point3::new(0.0, 0.3, 0.0)),
        (Point3::new(1.0, 1.0, 0.5), Point3::new(0.5, 0.5, 0.0)),
        (Point3::new(0.2, 0.3, -0.7), Point3::new(0.2, 0.3, 0.0)),
        (Point3::new(0.25, 0.25, 0.0), Point3::new(0.25, 0.25, 0.0)),
    ];
    // The same cases after a rigid motion, and with the corners relabelled.
    let motion =
        nalgebra::Isometry3::new(Vector3::new(0.3, -2.0, 5.0), Vector3::new(0.4, -1.1, 0.7));
    for (p, closest) in cases {
        let want = (p - closest).norm_squared();
        for (q, x, y, z) in [(p, a, b, c), (p, c, a, b), (p, b, a, c)] {
            assert!(
                close(point_triangle_distance_squared(&q, &x, &y, &z), want, 1e-14),
                "{p:?}"
            );
            let m = |v: &Point3| motion * v;
            assert!(
                close(
                    point_triangle_distance_squared(&m(&q), &m(&x), &m(&y), &m(&z)),
                    want,
                    1e-12
                ),
                "{p:?} moved"
            );
        }
        let got = closest_point_on_triangle(&p, &a, &b, &c);
        assert!(
            (got - closest).norm() < 1e-14,
            "{p:?}: closest {got:?}, want {closest:?}"
        );
    }
    // Degenerate triangles are their edges: collinear corners, and one point.
    let (x0, x1, x2) = (
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(3.0, 0.0, 0.0),
    );
    assert_eq!(
        point_triangle_distance_squared(&Point3::new(2.0, 1.0, 0.0), &x0, &x1, &x2),
        1.0
    );
    assert_eq!(
        point_triangle_distance_squared(&Point3::new(5.0, 0.0, 0.0), &x0, &x2, &x1),
        4.0
    );
    assert_eq!(
        point_triangle_distance_squared(&Point3::new(0.0, 3.0, 4.0), &x1, &x1, &x1),
        26.0
    );
}

/// A triangle soup: many small random triangles and a few huge ones, which a
/// search that does not bound each triangle individually would get wrong or slow.
fn random_soup(rng: &mut Rng, small: usize) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for k in 0..small + 3 {
        let size = if k < small { 0.05 } else { 4.0 };
        let center = rng.point();
        for _ in 0..3 {
            m.positions.push(center + rng.point().coords * size);
        }
        let i = 3 * k as u32;
        m.triangles.push([i, i + 1, i + 2]);
    }
    m
}

#[test]
fn surface_index_matches_brute_force() {
    let mut rng = Rng(2024);
    let mut meshes: Vec<(String, TriangleMesh)> = crate::fixtures::shapes()
        .into_iter()
        .map(|(n, m)| (n.to_string(), m))
        .collect();
    meshes.push(("soup".into(), random_soup(&mut rng, 400)));
    meshes.push(("bending bar".into(), crate::fixtures::bending_bar(5)));
    meshes.push((
        "one triangle".into(),
        TriangleMesh {
            positions: vec![
                Point3::origin(),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        },
    ));
    for (name, mesh) in &meshes {
        let index = SurfaceIndex::new(&mesh.positions, &mesh.triangles);
        let scale = mesh.bounding_box().diagonal();
        // Points near the surface (vertices jittered), inside, and far away.
        let mut queries: Vec<Point3> = mesh
            .positions
            .iter()
            .step_by(7)
            .map(|v| v + rng.point().coords * 0.02 * scale)
            .collect();
        queries.extend((0..200).map(|_| Point3::from(rng.point().coords * scale)));
        queries.extend((0..50).map(|_| Point3::from(rng.point().coords * 20.0 * scale)));
        for p in &queries {
            let (got, want) = (index.distance(p), brute_force_distance(p, mesh));
            assert!(
                (got - want).abs() <= 1e-12 * want.max(scale),
                "{name}: {p:?}: {got} vs brute force {want}"
            );
            // The closest point is that far and on the surface, with a unit
            // normal.
            let (c, n) = index.closest_point(p).expect("triangles");
            assert!(
                ((c - p).norm() - want).abs() <= 1e-12 * want.max(scale),
                "{name}: {p:?}"
            );
            assert!(
                brute_force_distance(&c, mesh) <= 1e-12 * scale && (n.norm() - 1.0).abs() < 1e-9,
                "{name}: {p:?}"
            );
            // Told the surface is within twice the distance, the search finds
            // the same point; told it is within half, it finds none.
            assert_eq!(
                index.closest_point_within(p, 2.0 * want + 1e-9 * scale),
                Some((c, n)),
                "{name}: {p:?}"
            );
            if want > 1e-6 * scale {
                assert_eq!(
                    index.closest_point_within(p, 0.5 * want),
                    None,
                    "{name}: {p:?}"
                );
            }
        }
        // A vertex is on the surface.
        assert_eq!(
            index.distance(&mesh.positions[mesh.triangles[0][1] as usize]),
            0.0,
            "{name}"
        );
        // Refitted to moved vertices (twisted, jittered), the index answers
        // as a brute-force scan of the moved mesh, and names the triangle.
        let moved: Vec<Point3> = mesh
            .positions
            .iter()
            .map(|p| {
                Rotation3::new(Vector3::z() * (p.z / scale)) * p + rng.point().coords * 0.01 * scale
            })
            .collect();
        let moved_mesh = TriangleMesh {
            positions: moved,
            ..mesh.clone()
        };
        let mut refitted = index;
        refitted.refit(&moved_mesh.positions, &moved_mesh.triangles);
        for p in &queries {
            let want = brute_force_distance(p, &moved_mesh);
            let (got, _) = refitted.closest_point(p).expect("triangles");
            assert!(
                ((got - p).norm() - want).abs() <= 1e-12 * want.max(scale),
                "{name} refitted: {p:?}"
            );
            let (t, c) = refitted
                .closest_triangle_within(p, Real::INFINITY)
                .expect("triangles");
            let [a, b, d] =
                moved_mesh.triangles[t as usize].map(|i| moved_mesh.positions[i as usize]);
            assert!(
                (point_triangle_distance_squared(p, &a, &b, &d).sqrt() - want).abs()
                    <= 1e-12 * want.max(scale),
                "{name} refitted: triangle {t}"
            );
            assert_eq!(c, got, "{name} refitted: {p:?}");
            // Searched upwards from any triangle's leaf (the conform stage's
            // last match), with or without the bound that triangle gives:
            // the same triangle, ties included.
            for near in [t, (rng.u64() % moved_mesh.triangles.len() as u64) as u32] {
                let [a, b, d] =
                    moved_mesh.triangles[near as usize].map(|i| moved_mesh.positions[i as usize]);
                let bound = point_triangle_distance_squared(p, &a, &b, &d).sqrt();
                assert_eq!(
                    refitted.closest_triangle_near(p, bound, near),
                    Some((t, c)),
                    "{name} from triangle {near}: {p:?}"
                );
                assert_eq!(
                    refitted.closest_triangle_near(p, Real::INFINITY, near),
                    Some((t, c)),
                    "{name} from triangle {near}: {p:?}"
                );
            }
        }
    }
    assert_eq!(
        SurfaceIndex::new(&[], &[]).distance(&Point3::origin()),
        Real::INFINITY
    );
}
