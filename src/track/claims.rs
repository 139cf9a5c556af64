//! Starved parts turn about their joint to the volume no other cell carries.
//!
//! A thin part that moves several of its widths in a frame leaves its
//! centers behind: their Voronoi cells in the new frame are empty or nearly
//! (no voxel is nearest to them), while the cells of the centers nearest to
//! where the part went stretch across it. The centroid term, which only
//! sees a center's own cell, has nothing to pull the stranded centers with.
//!
//! Each volume element keeps about its volume from frame to frame (the
//! subject's volume is nearly conserved), so a cell far below its frame-0
//! share is starved. The volume the starved part should hold is the part
//! of the new frame that the other cells' motions do not carry there:
//! each kept cell of the frame before, moved by its center's rigid motion,
//! covers where its volume went, and what is left uncovered is where the
//! lost part went. The starved centers tied by strong links are one part,
//! which hangs from the kept centers it is linked to (a limb from the body,
//! however weakly the affinity now ties them); it is turned as one rigid
//! body about that joint to the turn that brings its centers nearest to the
//! uncovered volume. Turned whole, its centers keep their order along the
//! limb, which moving each center to its own nearest volume would not.

use crate::math::{Point3, Real, Rotation3, Vector3};
use crate::model::GridSpec;
use crate::spatial::cells::CellStats;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// A cell is starved below this share of its frame-0 voxels (scaled by the
/// frame's volume).
pub(crate) const STARVED: Real = 0.3;

/// Links at least this strong tie starved centers into one part.
const PART_LINK: Real = 0.5;

/// Axes and angles of the turns tried about a starved part's joint.
const TURN_AXES: usize = 64;
const TURN_STEPS: usize = 18;

/// Each center's volume in the frame it was placed in: what it should keep.
#[derive(Clone, Debug)]
pub(crate) struct Capacity {
    /// Voxels of each cell in frame 0.
    count: Vec<Real>,
    /// Each cell's reach in frame 0: its farthest voxel from its center.
    reach: Vec<Real>,
    /// Occupied voxels of frame 0.
    total: Real,
}

impl Capacity {
    /// Of the centers `centers0` placed in `seq`'s frame `placed`, their
    /// cells assigned afresh.
    pub(crate) fn of_first_frame(
        seq: &crate::voxel::VoxelSequence,
        placed: usize,
        centers0: &[Point3],
    ) -> Self {
        use crate::spatial::cells::{assign, CenterIndex, NO_OWNER};
        let voxels0 = seq.frames[placed].indices();
        let mut owners = vec![NO_OWNER; voxels0.len()];
        assign(
            &seq.grid,
            &voxels0,
            &CenterIndex::new(centers0),
            &mut owners,
            false,
        );
        Capacity::new(&seq.grid, &voxels0, &owners, centers0)
    }

    /// From frame 0's voxels, their owners and the centers.
    pub(crate) fn new(grid: &GridSpec, voxels: &[u32], owners: &[u32], centers: &[Point3]) -> Self {
        let n = centers.len();
        let mut count = vec![0.0; n];
        let mut reach: Vec<Real> = vec![0.0; n];
        for (&v, &o) in voxels.iter().zip(owners) {
            let o = o as usize;
            count[o] += 1.0;
            reach[o] = reach[o].max((grid.voxel_center(v as usize) - centers[o]).norm());
        }
        // A one-voxel cell still reaches half a voxel.
        let floor = 0.5 * grid.voxel_size;
        reach.iter_mut().for_each(|r| *r = r.max(floor));
        Capacity {
            count,
            reach,
            total: voxels.len() as Real,
        }
    }

    /// Which centers are starved, of cells `stats` in a frame of
    /// `occupied` voxels.
    pub(crate) fn starved(&self, stats: &CellStats, occupied: usize) -> Vec<bool> {
        let scale = occupied as Real / self.total;
        (0..stats.count.len())
            .map(|i| (stats.count[i] as Real) < STARVED * self.count[i] * scale)
            .collect()
    }

    /// Where the `starved` centers of `cur` go: each starved part that
    /// hangs from kept centers (`links(i)`: center i's affinity links)
    /// turned about its joint toward `uncarried`, the frame's voxel
    /// centers no kept cell carries. Largest parts first, each taking the
    /// volume within two reaches of where it lands, so that two parts do not
    /// claim one limb. A part moves only where the turn brings its centers
    /// on average within one frame-0 reach of that volume and halves their
    /// squared distances to it (each counted to at most two reaches).
    pub(crate) fn claims<I>(
        &self,
        cur: &[Point3],
        starved: &[bool],
        uncarried: &[Point3],
        links: impl Fn(usize) -> I,
    ) -> Vec<(usize, Point3)>
    where
        I: Iterator<Item = (usize, Real)>,
    {
        let turns = joint_turns();
        let mut taken = vec![false; uncarried.len()];
        let mut claims = Vec::new();
        for StarvedPart { members, anchors } in starved_parts(starved, links) {
            let free: Vec<[Real; 3]> = uncarried
                .iter()
                .zip(&taken)
                .filter(|(_, &t)| !t)
                .map(|(p, _)| [p.x, p.y, p.z])
                .collect();
            if free.is_empty() {
                break;
            }
            let tree =
                ImmutableKdTree::<Real, 3>::new_from_slice(&free).expect("finite voxel positions");
            let weight: Real = anchors.iter().map(|a| a.1).sum();
            let joint = Point3::from(
                anchors
                    .iter()
                    .map(|&(j, w)| cur[j].coords * w)
                    .sum::<Vector3>()
                    / weight,
            );
            let reach =
                members.iter().map(|&i| self.reach[i]).sum::<Real>() / members.len() as Real;
            let cap2 = (2.0 * reach).powi(2);
            let cost = |turn: &Rotation3| -> Real {
                members
                    .iter()
                    .map(|&i| {
                        let p = joint + turn * (cur[i] - joint);
                        let nearest = tree
                            .query(&[p.x, p.y, p.z])
                            .nearest_one::<SquaredEuclidean<Real>>()
                            .execute();
                        nearest.distance.min(cap2)
                    })
                    .sum()
            };
            let here = cost(&Rotation3::identity());
            // The least cost, the smallest turn of equal ones.
            let (best, k) = turns
                .par_iter()
                .enumerate()
                .map(|(k, t)| (cost(t), k))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                .expect("turns to try");
            let turn = &turns[k];
            log::debug!(
                "starved part of {} centers: {:.2} reaches from the uncarried volume, {:.2} turned by {:.0}°",
                members.len(),
                (here / members.len() as Real).sqrt() / reach,
                (best / members.len() as Real).sqrt() / reach,
                turn.angle().to_degrees()
            );
            if best >= 0.5 * here || best / members.len() as Real >= reach * reach {
                continue;
            }
            let moved: Vec<Point3> = members
                .iter()
                .map(|&i| joint + turn * (cur[i] - joint))
                .collect();
            for (t, p) in taken.iter_mut().zip(uncarried) {
                *t = *t || moved.iter().any(|c| (c - p).norm_squared() < cap2);
            }
            claims.extend(members.iter().copied().zip(moved));
        }
        claims
    }
}

/// A starved part: its centers, and the kept centers it is linked to with
/// the links' weights.
struct StarvedPart {
    members: Vec<usize>,
    anchors: Vec<(usize, Real)>,
}

/// The starved centers tied by links of at least [`PART_LINK`] (`links(i)`:
/// center i's affinity links), as parts with the kept centers each is
/// linked to and how strongly (its joint: however weak, a limb's links to
/// the body it turns on are the ones the affinity weakens); largest parts
/// first, those linked to no kept center left out.
fn starved_parts<I>(starved: &[bool], links: impl Fn(usize) -> I) -> Vec<StarvedPart>
where
    I: Iterator<Item = (usize, Real)>,
{
    let mut seen = vec![false; starved.len()];
    let mut parts = Vec::new();
    for s in (0..starved.len()).filter(|&s| starved[s]) {
        if seen[s] {
            continue;
        }
        seen[s] = true;
        let (mut members, mut anchors) = (vec![s], Vec::new());
        let mut k = 0;
        while k < members.len() {
            let i = members[k];
            k += 1;
            for (j, w) in links(i).filter(|&(j, w)| j != i && w > 0.0) {
                if !starved[j] {
                    anchors.push((j, w));
                } else if w >= PART_LINK && !seen[j] {
                    seen[j] = true;
                    members.push(j);
                }
            }
        }
        if !anchors.is_empty() {
            parts.push(StarvedPart { members, anchors });
        }
    }
    parts.sort_by_key(|p| std::cmp::Reverse(p.members.len()));
    parts
}

/// The turns tried about a joint: [`TURN_AXES`] axes spread evenly over the
/// sphere (a Fibonacci lattice), by [`TURN_STEPS`] angles up to a half turn.
fn joint_turns() -> Vec<Rotation3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let axes: Vec<nalgebra::Unit<Vector3>> = (0..TURN_AXES)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / TURN_AXES as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * k as f64;
            nalgebra::Unit::new_normalize(Vector3::new(r * t.cos(), r * t.sin(), z))
        })
        .collect();
    (1..=TURN_STEPS)
        .flat_map(|s| {
            let angle = std::f64::consts::PI * s as f64 / TURN_STEPS as f64;
            axes.iter()
                .map(move |a| Rotation3::from_axis_angle(a, angle))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each center's affinity links.
    type Links = Vec<Vec<(usize, Real)>>;

    /// A body center at the joint (1, 0, 0) and a leg of four starved
    /// centers along x from it, linked to each other and weakly to the
    /// body; each of reach 0.3.
    fn leg() -> (Capacity, Vec<Point3>, Vec<bool>, Links) {
        let cur = vec![
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.5, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(2.5, 0.0, 0.0),
            Point3::new(3.0, 0.0, 0.0),
        ];
        let capacity = Capacity {
            count: vec![10.0; 5],
            reach: vec![0.3; 5],
            total: 50.0,
        };
        let mut links = vec![vec![(1, 0.05)], vec![(0, 0.05), (2, 1.0)]];
        links.extend((2..5).map(|i| {
            let mut l = vec![(i - 1, 1.0)];
            if i < 4 {
                l.push((i + 1, 1.0));
            }
            l
        }));
        (capacity, cur, vec![false, true, true, true, true], links)
    }

    /// Voxel centers filling a bar of half-width 0.15 from `a` to `b`.
    fn bar(a: Point3, b: Point3) -> Vec<Point3> {
        let steps = 40;
        let mut out = Vec::new();
        for k in 0..=steps {
            let c = a + (b - a) * (k as Real / steps as Real);
            for (dx, dz) in [(0.0, 0.0), (0.1, 0.0), (-0.1, 0.0), (0.0, 0.1), (0.0, -0.1)] {
                out.push(c + Vector3::new(dx, 0.0, dz));
            }
        }
        out
    }

    #[test]
    fn a_leg_left_behind_turns_about_its_joint_to_where_the_volume_went() {
        let (capacity, cur, starved, links) = leg();
        // The leg went up: turned 90° about z through the joint.
        let went = bar(Point3::new(1.0, 0.3, 0.0), Point3::new(1.0, 2.2, 0.0));
        let claims = capacity.claims(&cur, &starved, &went, |i| links[i].iter().copied());
        assert_eq!(
            claims.iter().map(|c| c.0).collect::<Vec<_>>(),
            vec![1, 2, 3, 4]
        );
        for &(i, p) in &claims {
            let want = Point3::new(1.0, cur[i].x - 1.0, 0.0);
            assert!((p - want).norm() < 0.3, "center {i} at {p}, not {want}");
        }
    }

    #[test]
    fn a_part_stays_where_no_turn_brings_it_near_the_volume_or_nothing_holds_it() {
        let (capacity, cur, starved, links) = leg();
        // Far from anything the leg can reach by turning.
        let far = bar(Point3::new(9.0, 9.0, 0.0), Point3::new(9.0, 11.0, 0.0));
        assert!(capacity
            .claims(&cur, &starved, &far, |i| links[i].iter().copied())
            .is_empty());
        // Linked to no kept center: nothing to turn about.
        let went = bar(Point3::new(1.0, 0.3, 0.0), Point3::new(1.0, 2.2, 0.0));
        let loose = |i: usize| {
            links[i]
                .iter()
                .copied()
                .filter(move |&(j, _)| j != 0 && i != 0)
        };
        assert!(capacity.claims(&cur, &starved, &went, loose).is_empty());
        // No starved center.
        assert!(capacity
            .claims(&cur, &[false; 5], &went, |i| links[i].iter().copied())
            .is_empty());
    }
}
