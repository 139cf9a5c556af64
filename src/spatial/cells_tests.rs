//! The Voronoi assignment's fast paths (bounds and candidate lists, the
//! k-d tree, `nearest` with hints, carried and block assignments) against a
//! linear scan over the centers, written here independently of the module.

use super::*;
use crate::math::Vector3;

use crate::test_support::Lcg;

#[test]
fn voronoi_assignment_equals_a_linear_scan_while_centers_move() {
    // 60 centers: the candidate lists (16, extended to 48) hold most of
    // them; 400: lists and k-d tree both do real work.
    for n in [60, 400] {
        assignment_matches_linear_scan(n);
    }
}

/// Every voxel's owner, from the fast path (Hamerly bounds and candidate
/// lists on the carried index; at step 0, assigned afresh, each voxel from
/// the owner its scan neighbour got), from the k-d tree and from `nearest` with
/// good, bad and no hints, on the carried and on a fresh index, is exactly
/// the center [`linear_scan`] finds: the nearest, and on a tie the lowest
/// index. Random centers almost never tie by accident, so every tenth center
/// is an exact twin of the one before it (same position, same moves): each
/// voxel of a twin pair's cell has two nearest centers at equal distance, and
/// the lower index must win it.
fn assignment_matches_linear_scan(n: usize) {
    let grid = GridSpec {
        origin: Point3::new(-1.0, -2.0, 0.5),
        voxel_size: 0.1,
        dims: [30, 25, 20],
    };
    let mut g = Lcg(3);
    let voxels: Vec<u32> = (0..grid.len() as u32).filter(|_| g.next() < 0.4).collect();
    let mut centers: Vec<Point3> = (0..n)
        .map(|_| grid.voxel_center((g.next() * grid.len() as Real) as usize) + g.vec(0.05))
        .collect();
    let twin = |i: usize| i % 10 == 1;
    for i in (0..n).filter(|&i| twin(i)) {
        centers[i] = centers[i - 1];
    }
    let mut cells = Assignment::new(&grid, &voxels, vec![NO_OWNER; voxels.len()]);
    let mut moved = Vec::new();
    // The tracker's index follows the centers (keeping candidate lists); a
    // fresh one each step must agree with it and with the linear scan.
    let mut carried = CenterIndex::new(&centers);
    for step in 0..25 {
        // Voxels with two or more nearest centers at exactly equal distance.
        let mut ties = 0;
        if step > 0 {
            carried = carried.moved_to(&centers, &moved);
        }
        let stats = cells.update(&carried, &moved, false);
        let index = CenterIndex::new(&centers);
        let mut counts = vec![0u32; centers.len()];
        let mut sums = vec![[0i64; 3]; centers.len()];
        for (k, &v) in voxels.iter().enumerate() {
            let p = grid.voxel_center(v as usize);
            let q = [p.x, p.y, p.z];
            let (best, tied) = linear_scan(&centers, &p);
            ties += (tied > 1) as usize;
            let owner = cells.owners[k];
            let at =
                format!("{n} centers, step {step}, voxel {v} ({tied} nearest at equal distance)");
            assert_eq!(
                index.nearest_brute_force(&q),
                best,
                "{at}: the library's linear scan"
            );
            assert_eq!(
                owner, best,
                "{at}: fast path (bounds and candidate lists, carried index)"
            );
            assert_eq!(index.nearest_tree(&q), best, "{at}: k-d tree, fresh index");
            assert_eq!(
                carried.nearest_tree(&q),
                best,
                "{at}: k-d tree, carried index"
            );
            for hint in [owner, (owner + 7) % centers.len() as u32, NO_OWNER] {
                assert_eq!(
                    carried.nearest(&q, hint),
                    best,
                    "{at}, hint {hint}: carried index"
                );
                assert_eq!(
                    index.nearest(&q, hint),
                    best,
                    "{at}, hint {hint}: fresh index"
                );
            }
            counts[owner as usize] += 1;
            let c = grid.voxel_coords(v as usize);
            (0..3).for_each(|d| sums[owner as usize][d] += c[d] as i64);
        }
        // Not vacuous: the twins' cells hold 9 to 12 % of the voxels (seed 3).
        assert!(
            ties * 20 > voxels.len(),
            "{n} centers, step {step}: only {ties} of {} voxels tie",
            voxels.len()
        );
        // The cells' sums are kept up to date from the owner changes alone.
        assert_eq!(stats.count, counts, "step {step}");
        assert_eq!(stats.sum, sums, "step {step}");
        // Move: small steps mostly, a few jumps; some steps all tiny, so
        // that candidate lists survive several steps. Twins move together.
        moved.clear();
        let jumps = if step % 3 == 0 { 0.05 } else { 0.0 };
        let mut last = Vector3::zeros();
        for (i, c) in centers.iter_mut().enumerate() {
            let step = if g.next() < jumps {
                g.vec(1.0)
            } else {
                g.vec(0.02)
            };
            let step = if twin(i) { last } else { step };
            *c += step;
            moved.push(step.norm());
            last = step;
        }
    }
}

/// The tracker's next frame: `Assignment::carried` takes the owners and
/// bounds of the voxels two frames share (and hints for the new ones), and
/// its first update, on the last frame's index moved to the new centers,
/// gives every voxel the center a linear scan finds nearest. Centers move a
/// little or jump (so that candidate lists are kept or rebuilt), twins tie.
#[test]
fn carried_assignment_matches_linear_scan() {
    let grid = GridSpec {
        origin: Point3::new(-1.0, -2.0, 0.5),
        voxel_size: 0.1,
        dims: [30, 25, 20],
    };
    for (seed, n) in [(6, 1), (7, 40), (8, 300)] {
        let mut g = Lcg(seed);
        let mut before: Vec<u32> = (0..grid.len() as u32).filter(|_| g.next() < 0.4).collect();
        let mut centers: Vec<Point3> = (0..n)
            .map(|_| grid.voxel_center((g.next() * grid.len() as Real) as usize) + g.vec(0.05))
            .collect();
        for i in (0..n).filter(|i| i % 10 == 1) {
            centers[i] = centers[i - 1];
        }
        let mut index = CenterIndex::new(&centers);
        let mut cells = Assignment::new(&grid, &before, vec![NO_OWNER; before.len()]);
        cells.update(&index, &[], false);
        for frame in 0..6 {
            // The next frame keeps most voxels, loses some and gains others.
            let kept: std::collections::HashSet<u32> =
                before.iter().copied().filter(|_| g.next() < 0.8).collect();
            let after: Vec<u32> = (0..grid.len() as u32)
                .filter(|v| kept.contains(v) || g.next() < 0.1)
                .collect();
            let jumps = if frame % 2 == 0 { 0.1 } else { 0.0 };
            let mut moved = Vec::new();
            let mut last = Vector3::zeros();
            for (i, c) in centers.iter_mut().enumerate() {
                let step = if i % 10 == 1 {
                    last
                } else if g.next() < jumps {
                    g.vec(1.0)
                } else {
                    g.vec(0.03)
                };
                *c += step;
                moved.push(step.norm());
                last = step;
            }
            let mut next = Assignment::carried(&grid, &after, &before, &cells);
            index = index.moved_to(&centers, &moved);
            let stats = next.update(&index, &moved, false);
            let mut counts = vec![0u32; n];
            for (k, &v) in after.iter().enumerate() {
                let (best, tied) = linear_scan(&centers, &grid.voxel_center(v as usize));
                assert_eq!(
                    next.owners[k], best,
                    "{n} centers, frame {frame}, voxel {v} ({tied} nearest at equal distance)"
                );
                counts[best as usize] += 1;
            }
            assert_eq!(stats.count, counts, "{n} centers, frame {frame}");
            // Bounds and owners for the frame after, as the tracker keeps them.
            (before, cells) = (after, next);
        }
    }
}

/// Blocks of 2³ and 3³ voxels (`Assignment::blocks`), grouped here
/// independently in the order the library documents (by block, z slowest):
/// each block's owner is the center a linear scan finds nearest its voxels'
/// centroid, from no hints and from every voxel's hint, while the centers
/// move; the cells' counts and sums are exactly those of the voxels of their
/// blocks; and edge 1 is the voxels themselves.
#[test]
fn block_assignment_equals_a_linear_scan_over_block_centroids() {
    let grid = GridSpec {
        origin: Point3::new(-1.0, -2.0, 0.5),
        voxel_size: 0.1,
        dims: [30, 25, 20],
    };
    let mut g = Lcg(5);
    let voxels: Vec<u32> = (0..grid.len() as u32).filter(|_| g.next() < 0.4).collect();
    for edge in [1usize, 2, 3] {
        let mut groups: std::collections::BTreeMap<[usize; 3], Vec<u32>> = Default::default();
        for &v in &voxels {
            let c = grid.voxel_coords(v as usize).map(|c| c / edge);
            groups.entry([c[2], c[1], c[0]]).or_default().push(v);
        }
        let groups: Vec<Vec<u32>> = groups.into_values().collect();
        let centroid = |vs: &[u32]| {
            vs.iter()
                .map(|&v| grid.voxel_center(v as usize).coords)
                .sum::<Vector3>()
                / vs.len() as Real
        };
        let mut centers: Vec<Point3> = (0..150)
            .map(|_| grid.voxel_center((g.next() * grid.len() as Real) as usize) + g.vec(0.05))
            .collect();
        let hints: Vec<u32> = (0..voxels.len())
            .map(|k| {
                if k % 3 == 0 {
                    NO_OWNER
                } else {
                    (k % 150) as u32
                }
            })
            .collect();
        for mut cells in [
            Assignment::blocks(&grid, &voxels, &vec![NO_OWNER; voxels.len()], edge),
            Assignment::blocks(&grid, &voxels, &hints, edge),
        ] {
            let mut index = CenterIndex::new(&centers);
            let mut moved = Vec::new();
            for step in 0..10 {
                if step > 0 {
                    index = index.moved_to(&centers, &moved);
                }
                let stats = cells.update(&index, &moved, false);
                assert_eq!(cells.owners.len(), groups.len(), "edge {edge}");
                let mut counts = vec![0u32; centers.len()];
                let mut sums = vec![[0i64; 3]; centers.len()];
                for (b, vs) in groups.iter().enumerate() {
                    let owner = cells.owners[b];
                    // Centroids are computed in another order here: compare
                    // distances, so that a near-tie may go either way.
                    let x = Point3::from(centroid(vs));
                    let (best, _) = linear_scan(&centers, &x);
                    let (d_owner, d_best) = (
                        (centers[owner as usize] - x).norm(),
                        (centers[best as usize] - x).norm(),
                    );
                    assert!(d_owner <= d_best + 1e-12, "edge {edge}, step {step}, block {b}: center {owner} at {d_owner}, {best} at {d_best}");
                    for &v in vs {
                        counts[owner as usize] += 1;
                        let c = grid.voxel_coords(v as usize);
                        (0..3).for_each(|d| sums[owner as usize][d] += c[d] as i64);
                    }
                }
                assert_eq!(stats.count, counts, "edge {edge}, step {step}");
                assert_eq!(stats.sum, sums, "edge {edge}, step {step}");
                moved.clear();
                for c in centers.iter_mut() {
                    let step = if g.next() < 0.05 {
                        g.vec(1.0)
                    } else {
                        g.vec(0.02)
                    };
                    *c += step;
                    moved.push(step.norm());
                }
            }
        }
    }
}

/// The nearest center to `p` by a linear scan written here, independent of
/// the library: the lowest index among the centers at the least squared
/// distance (summed as the library sums it, so that equal means equal), and
/// how many centers share that distance.
fn linear_scan(centers: &[Point3], p: &Point3) -> (u32, usize) {
    let d: Vec<Real> = centers
        .iter()
        .map(|c| (c.x - p.x).powi(2) + (c.y - p.y).powi(2) + (c.z - p.z).powi(2))
        .collect();
    let least = d.iter().copied().fold(Real::INFINITY, Real::min);
    let best = d
        .iter()
        .position(|&x| x == least)
        .expect("at least one center");
    (best as u32, d.iter().filter(|&&x| x == least).count())
}

/// Centers on voxel centers put many voxels at exactly equal distance from
/// two or more centers (Lloyd's start; the grid's coordinates are exact in
/// binary, so equal means equal): the lower index, as [`linear_scan`] finds
/// it, must win everywhere, in the assignment, the k-d tree and `nearest`
/// with any hint, on the fresh and on the carried index.
#[test]
fn voronoi_ties_go_to_the_lower_index() {
    let grid = GridSpec {
        origin: Point3::new(0.0, 0.0, 0.0),
        voxel_size: 0.5,
        dims: [24, 20, 16],
    };
    let mut g = Lcg(11);
    let voxels: Vec<u32> = (0..grid.len() as u32).filter(|_| g.next() < 0.6).collect();
    let mut centers: Vec<Point3> = (0..40)
        .map(|_| grid.voxel_center(voxels[(g.next() * voxels.len() as Real) as usize] as usize))
        .collect();
    let mut cells = Assignment::new(&grid, &voxels, vec![NO_OWNER; voxels.len()]);
    let mut carried = CenterIndex::new(&centers);
    let mut moved: Vec<Real> = Vec::new();
    for step in 0..12 {
        if step > 0 {
            carried = carried.moved_to(&centers, &moved);
        }
        cells.update(&carried, &moved, false);
        let index = CenterIndex::new(&centers);
        let mut ties = 0;
        for (k, &v) in voxels.iter().enumerate() {
            let p = grid.voxel_center(v as usize);
            let q = [p.x, p.y, p.z];
            let (best, tied) = linear_scan(&centers, &p);
            ties += (tied > 1) as usize;
            let at = format!("step {step}, voxel {v} ({tied} nearest at equal distance)");
            assert_eq!(
                index.nearest_brute_force(&q),
                best,
                "{at}: the library's linear scan"
            );
            assert_eq!(cells.owners[k], best, "{at}: assignment");
            assert_eq!(index.nearest_tree(&q), best, "{at}: tree");
            for hint in [best, (best + 1) % centers.len() as u32, NO_OWNER] {
                assert_eq!(
                    carried.nearest(&q, hint),
                    best,
                    "{at}, hint {hint}: carried index"
                );
                assert_eq!(
                    index.nearest(&q, hint),
                    best,
                    "{at}, hint {hint}: fresh index"
                );
            }
        }
        // Not vacuous: ties to settle in every step (4 to 7 % of the voxels
        // with seed 11).
        assert!(
            ties * 50 > voxels.len(),
            "step {step}: only {ties} of {} voxels tie",
            voxels.len()
        );
        // Whole-voxel moves keep the ties coming.
        moved.clear();
        for c in centers.iter_mut() {
            let d = nalgebra::Vector3::new(
                (g.next() * 3.0).floor() - 1.0,
                (g.next() * 3.0).floor() - 1.0,
                0.0,
            ) * grid.voxel_size;
            *c += d;
            moved.push(d.norm());
        }
    }
}
