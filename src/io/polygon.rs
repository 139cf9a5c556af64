//! Triangulating the polygon faces OBJ and PLY files may hold. A fan from the
//! first corner covers only convex polygons: for a concave one (a star-shaped
//! cap) some of its triangles fall outside the face and overlap others. Ear
//! clipping on the polygon's own plane covers the face exactly.

use crate::math::{Point3, Real, Vector3};

/// Most steps (mostly point-in-triangle tests) spent on one polygon before
/// the rest of it is fanned: ear clipping is quadratic in the worst case, and
/// a file may declare a face of a million corners.
const MAX_TESTS: u64 = 1 << 26;

/// Appends triangles covering the polygon `corners` (indices into
/// `positions`, in order, each in range) to `out`, with the polygon's
/// winding. The corners are projected onto the plane of the polygon's Newell
/// normal and ear-clipped there; a degenerate polygon (no area: all corners
/// on one line or one point) is fanned, its triangles being degenerate
/// whatever the choice. A polygon that is not simple gets triangles anyway,
/// from the corners left when no ear remains.
pub(crate) fn triangulate_polygon(positions: &[Point3], corners: &[u32], out: &mut Vec<[u32; 3]>) {
    let n = corners.len();
    if n < 3 {
        return;
    }
    let fan = |out: &mut Vec<[u32; 3]>| {
        out.extend((1..n - 1).map(|i| [corners[0], corners[i], corners[i + 1]]))
    };
    if n == 3 {
        return fan(out);
    }
    // About the first corner, so coordinates far from the origin keep their digits.
    let origin = positions[corners[0] as usize];
    let local: Vec<Vector3> = corners
        .iter()
        .map(|&c| positions[c as usize] - origin)
        .collect();
    let normal: Vector3 = (0..n).map(|i| local[i].cross(&local[(i + 1) % n])).sum();
    let size = local.iter().map(|p| p.norm()).fold(0.0, Real::max);
    // Twice the area against the size squared: zero up to rounding.
    let tiny = 1e-12 * size * size;
    if !(normal.norm() > tiny) {
        return fan(out);
    }
    let z = normal.normalize();
    // Any unit vector in the plane; (u, v, z) is right-handed, so the polygon
    // turns counter-clockwise in (u, v).
    let axis = if z.x.abs() <= z.y.abs() && z.x.abs() <= z.z.abs() {
        Vector3::x()
    } else if z.y.abs() <= z.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let u = (axis - z * z.dot(&axis)).normalize();
    let v = z.cross(&u);
    let q: Vec<[Real; 2]> = local.iter().map(|p| [p.dot(&u), p.dot(&v)]).collect();
    clip_ears(&q, tiny, &mut |[a, b, c]| {
        out.push([corners[a], corners[b], corners[c]])
    });
}

/// Twice the signed area of the triangle a b c: positive if counter-clockwise.
fn orient(a: [Real; 2], b: [Real; 2], c: [Real; 2]) -> Real {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Ear clipping of the counter-clockwise polygon `q`, emitting triangles of
/// corner numbers. `tiny` is the orientation below which three corners count
/// as collinear.
fn clip_ears(q: &[[Real; 2]], tiny: Real, emit: &mut impl FnMut([usize; 3])) {
    let n = q.len();
    let mut next: Vec<usize> = (1..=n).map(|i| i % n).collect();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut alive = vec![true; n];
    let convex_at =
        |prev: &[usize], next: &[usize], i: usize| orient(q[prev[i]], q[i], q[next[i]]) > tiny;
    let mut convex: Vec<bool> = (0..n).map(|i| convex_at(&prev, &next, i)).collect();
    // Only a corner that is not convex can lie inside an ear of a simple polygon.
    let mut reflex: Vec<usize> = (0..n).filter(|&i| !convex[i]).collect();
    let mut tests: u64 = 0;
    // Starting at corner 1 and moving on to the next corner after each clip
    // gives a convex polygon the fan from corner 0 that readers made before.
    let (mut i, mut remaining, mut misses) = (1, n, 0);
    while remaining > 3 {
        let (a, c) = (prev[i], next[i]);
        tests += 1;
        let is_ear = convex[i] && {
            tests += reflex.len() as u64;
            let (pa, pb, pc) = (q[a], q[i], q[c]);
            reflex.iter().all(|&r| {
                let p = q[r];
                r == a
                    || r == c
                    || p == pa
                    || p == pb
                    || p == pc
                    || orient(pa, pb, p) < -tiny
                    || orient(pb, pc, p) < -tiny
                    || orient(pc, pa, p) < -tiny
            })
        };
        let clip = if is_ear {
            Some(i)
        } else {
            misses += 1;
            if misses <= remaining {
                None
            } else {
                // A whole round without an ear: the polygon is not simple.
                // Any convex corner goes; with none left the rest has no area.
                tests += remaining as u64;
                let mut j = i;
                (0..remaining).find_map(|_| {
                    j = next[j];
                    convex[j].then_some(j)
                })
            }
        };
        if tests > MAX_TESTS {
            log::warn!("a polygon of {n} corners is too large to clip: fanning its last {remaining} corners");
            break;
        }
        if misses > remaining && clip.is_none() {
            break;
        }
        match clip {
            Some(k) => {
                let (a, c) = (prev[k], next[k]);
                emit([a, k, c]);
                alive[k] = false;
                next[a] = c;
                prev[c] = a;
                remaining -= 1;
                misses = 0;
                convex[a] = convex_at(&prev, &next, a);
                convex[c] = convex_at(&prev, &next, c);
                reflex.retain(|&r| alive[r] && !convex[r]);
                i = c;
            }
            None => i = next[i],
        }
    }
    // Three corners left, or a fan of what is left, from its first corner.
    let mut start = i;
    let mut j = next[i];
    while j != i {
        start = start.min(j);
        j = next[j];
    }
    let mut j = next[start];
    while next[j] != start {
        emit([start, j, next[j]]);
        j = next[j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift, fixed seed.
    struct Rng(u64);
    impl Rng {
        fn unit(&mut self) -> Real {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as Real / (1u64 << 53) as Real
        }
    }

    fn shoelace(p: &[[Real; 2]]) -> Real {
        (0..p.len())
            .map(|i| orient([0.0, 0.0], p[i], p[(i + 1) % p.len()]))
            .sum::<Real>()
            / 2.0
    }

    /// Crossing number: strictly inside the polygon.
    fn inside(p: [Real; 2], poly: &[[Real; 2]]) -> bool {
        let mut odd = false;
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            if (a[1] > p[1]) != (b[1] > p[1])
                && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
            {
                odd = !odd;
            }
        }
        odd
    }

    /// A random star-shaped (so simple) polygon: corners at increasing
    /// angles, each at its own radius.
    fn random_polygon(rng: &mut Rng, n: usize) -> Vec<[Real; 2]> {
        let mut angles: Vec<Real> = (0..n).map(|_| rng.unit() * std::f64::consts::TAU).collect();
        angles.sort_by(Real::total_cmp);
        angles
            .iter()
            .map(|&t| {
                let r = 0.1 + rng.unit();
                [r * t.cos(), r * t.sin()]
            })
            .collect()
    }

    #[test]
    fn random_simple_polygons_are_covered_exactly() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for case in 0..200 {
            let n = 4 + case % 40;
            let poly = random_polygon(&mut rng, n);
            let area = shoelace(&poly);
            // Placed in space on a tilted plane far from the origin.
            let rot = crate::math::Rotation3::new(Vector3::new(
                rng.unit() * 3.0,
                rng.unit() * 3.0,
                rng.unit() * 3.0,
            ));
            let offset = Vector3::new(100.0, -50.0, 7.0);
            let positions: Vec<Point3> = poly
                .iter()
                .map(|p| rot * Point3::new(p[0], p[1], 0.0) + offset)
                .collect();
            let normal = rot * Vector3::z();
            // Both windings, and not starting at corner 0.
            for reversed in [false, true] {
                let mut corners: Vec<u32> = (0..n as u32).map(|i| (i + 3) % n as u32).collect();
                if reversed {
                    corners.reverse();
                }
                let mut triangles = Vec::new();
                triangulate_polygon(&positions, &corners, &mut triangles);
                assert_eq!(triangles.len(), n - 2, "case {case}");
                let mut sum = 0.0;
                for t in &triangles {
                    let [a, b, c] = t.map(|k| positions[k as usize]);
                    let cross = (b - a).cross(&(c - a));
                    let facing = if reversed { -normal } else { normal };
                    assert!(
                        cross.dot(&facing) > 0.0,
                        "case {case}: triangle {t:?} inverted or flat"
                    );
                    sum += cross.norm() / 2.0;
                    let centroid = [t[0], t[1], t[2]].map(|k| poly[k as usize]);
                    let centroid = [
                        (centroid[0][0] + centroid[1][0] + centroid[2][0]) / 3.0,
                        (centroid[0][1] + centroid[1][1] + centroid[2][1]) / 3.0,
                    ];
                    assert!(
                        inside(centroid, &poly),
                        "case {case}: triangle {t:?} outside the polygon"
                    );
                }
                assert!(
                    (sum - area).abs() < 1e-9 * area,
                    "case {case}: {sum} vs {area}"
                );
            }
        }
    }

    #[test]
    fn huge_tangled_polygons_still_end() {
        // Corners at random: not simple, nearly half of them reflex.
        let mut rng = Rng(7);
        let n = 300_000;
        let positions: Vec<Point3> = (0..n)
            .map(|_| Point3::new(rng.unit(), rng.unit(), 0.01 * rng.unit()))
            .collect();
        let mut triangles = Vec::new();
        triangulate_polygon(
            &positions,
            &(0..n as u32).collect::<Vec<u32>>(),
            &mut triangles,
        );
        assert_eq!(triangles.len(), n - 2);
    }

    #[test]
    fn collinear_corners_and_degenerate_polygons() {
        // A square with a corner halfway along each side.
        let square = [
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [2.0, 2.0],
            [1.0, 2.0],
            [0.0, 2.0],
            [0.0, 1.0],
        ];
        let positions: Vec<Point3> = square
            .iter()
            .map(|p| Point3::new(p[0], p[1], 0.0))
            .collect();
        let mut triangles = Vec::new();
        triangulate_polygon(&positions, &(0..8).collect::<Vec<u32>>(), &mut triangles);
        assert_eq!(triangles.len(), 6);
        let area: Real = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| positions[k as usize]);
                (b - a).cross(&(c - a)).z / 2.0
            })
            .sum();
        assert!((area - 4.0).abs() < 1e-12, "{area}");
        assert!(triangles.iter().all(|t| {
            let [a, b, c] = t.map(|k| positions[k as usize]);
            (b - a).cross(&(c - a)).z >= 0.0
        }));
        // All corners on one line: a fan, still n - 2 triangles.
        let line: Vec<Point3> = (0..5)
            .map(|i| Point3::new(i as Real, 2.0 * i as Real, 0.0))
            .collect();
        let mut triangles = Vec::new();
        triangulate_polygon(&line, &[0, 1, 2, 3, 4], &mut triangles);
        assert_eq!(triangles, [[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }
}
