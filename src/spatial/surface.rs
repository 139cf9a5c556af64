//! Closest points on a triangle surface: exact point-triangle distances and a
//! bounding-volume hierarchy that finds a query's nearest triangle.

#[cfg(test)]
use crate::math::Vector3;
use crate::math::{Point3, Real};

/// The point of triangle `abc` closest to `p` (Ericson, Real-Time Collision
/// Detection §5.1.5: which vertex, edge or face region `p` projects into).
/// A degenerate triangle (zero area) is treated as its three edges.
pub fn closest_point_on_triangle(p: &Point3, a: &Point3, b: &Point3, c: &Point3) -> Point3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    // Zero area: the region tests below would divide 0 by 0.
    if ab.cross(&ac).norm_squared() == 0.0 {
        return [
            closest_point_on_segment(p, a, b),
            closest_point_on_segment(p, b, c),
            closest_point_on_segment(p, c, a),
        ]
        .into_iter()
        .min_by(|x, y| (p - x).norm_squared().total_cmp(&(p - y).norm_squared()))
        .expect("three candidates");
    }
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    a + ab * (vb / denom) + ac * (vc / denom)
}

fn closest_point_on_segment(p: &Point3, a: &Point3, b: &Point3) -> Point3 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 == 0.0 {
        return *a;
    }
    a + ab * ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
}

/// Squared distance from `p` to triangle `abc`.
pub fn point_triangle_distance_squared(p: &Point3, a: &Point3, b: &Point3, c: &Point3) -> Real {
    (p - closest_point_on_triangle(p, a, b, c)).norm_squared()
}

/// Triangles per leaf of the hierarchy.
const LEAF_SIZE: usize = 4;

/// One box of the hierarchy: a leaf holds `count` triangles from `first`;
/// an inner node (count 0) has its first child right after it and its
/// second at `first`.
#[derive(Clone, Copy, Debug)]
struct Node {
    min: [Real; 3],
    max: [Real; 3],
    first: u32,
    count: u32,
}

impl Node {
    /// Squared distance from `p` to the box (0 inside): never more than to
    /// anything in it, so a box at least as far as the best triangle found
    /// cannot hold a closer one.
    fn distance_squared(&self, p: &Point3) -> Real {
        (0..3)
            .map(|k| {
                (self.min[k] - p[k])
                    .max(p[k] - self.max[k])
                    .max(0.0)
                    .powi(2)
            })
            .sum()
    }
}

/// Nearest-point queries against one triangle surface: a bounding-volume
/// hierarchy (median splits on the longest axis of the triangles' centroids),
/// searched nearest box first.
///
/// Why boxes rather than a k-d tree of centroids: the centroid search must
/// widen its radius by the largest triangle's size, so one large triangle
/// (a floor, a hole-filling patch) would make every query scan most of the
/// mesh; a box bounds each subtree's own triangles.
pub struct SurfaceIndex {
    nodes: Vec<Node>,
    /// Corners of every triangle, in leaf order.
    triangles: Vec<[Point3; 3]>,
    /// Every leaf-order triangle's index in the mesh given.
    ids: Vec<u32>,
    /// Per mesh triangle, its place in leaf order.
    places: Vec<u32>,
    /// Per leaf-order triangle, the leaf that holds it.
    leaves: Vec<u32>,
    /// Per node, its parent (the root's is itself).
    parents: Vec<u32>,
}

impl SurfaceIndex {
    /// Indexes the triangles of `positions`. Indices must be in range (as
    /// [`crate::model::TriangleMesh::validate`] checks).
    pub fn new(positions: &[Point3], triangles: &[[u32; 3]]) -> Self {
        let corners: Vec<[Point3; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| positions[i as usize]))
            .collect();
        let centroids: Vec<Point3> = corners
            .iter()
            .map(|[a, b, c]| Point3::from((a.coords + b.coords + c.coords) / 3.0))
            .collect();
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * corners.len() / LEAF_SIZE + 1);
        if !order.is_empty() {
            build(&mut nodes, &mut order, 0, &corners, &centroids);
        }
        let mut places = vec![0u32; order.len()];
        for (k, &t) in order.iter().enumerate() {
            places[t as usize] = k as u32;
        }
        let (mut leaves, mut parents) = (vec![0u32; order.len()], vec![0u32; nodes.len()]);
        for (n, node) in nodes.iter().enumerate() {
            if node.count > 0 {
                leaves[node.first as usize..(node.first + node.count) as usize].fill(n as u32);
            } else {
                parents[n + 1] = n as u32;
                parents[node.first as usize] = n as u32;
            }
        }
        SurfaceIndex {
            nodes,
            triangles: order.iter().map(|&t| corners[t as usize]).collect(),
            ids: order,
            places,
            leaves,
            parents,
        }
    }

    /// Squared distance from `p` to the surface (infinite without triangles).
    pub(crate) fn distance_squared(&self, p: &Point3) -> Real {
        self.nearest_triangle(p, Real::INFINITY)
            .map_or(Real::INFINITY, |(_, d)| d)
    }

    /// The point of the surface nearest to `p` and the unit normal of the
    /// triangle it lies on (zero for a degenerate triangle); None without
    /// triangles.
    #[cfg(test)]
    pub fn closest_point(&self, p: &Point3) -> Option<(Point3, Vector3)> {
        self.closest_point_within(p, Real::INFINITY)
    }

    /// [`SurfaceIndex::closest_point`], knowing that the surface comes within
    /// `bound` of `p` (a point found before): boxes farther away are skipped.
    /// None also when nothing is nearer than `bound`.
    #[cfg(test)]
    pub fn closest_point_within(&self, p: &Point3, bound: Real) -> Option<(Point3, Vector3)> {
        let (t, _) = self.nearest_triangle(p, bound * bound)?;
        let [a, b, c] = &self.triangles[t];
        let normal = (b - a)
            .cross(&(c - a))
            .try_normalize(0.0)
            .unwrap_or_else(Vector3::zeros);
        Some((closest_point_on_triangle(p, a, b, c), normal))
    }

    /// The same index over moved vertices: `positions` of the mesh indexed,
    /// same `triangles`. The boxes are recomputed over the tree as it was
    /// split, in time linear in the triangles; a mesh that moves smoothly
    /// keeps a tree nearly as tight as a new one.
    pub fn refit(&mut self, positions: &[Point3], triangles: &[[u32; 3]]) {
        for (corners, &t) in self.triangles.iter_mut().zip(&self.ids) {
            *corners = triangles[t as usize].map(|i| positions[i as usize]);
        }
        // Children come after their parent, so a reverse sweep sees them first.
        for n in (0..self.nodes.len()).rev() {
            let node = self.nodes[n];
            let (mut min, mut max) = ([Real::INFINITY; 3], [Real::NEG_INFINITY; 3]);
            let mut grow = |lo: &[Real; 3], hi: &[Real; 3]| {
                for k in 0..3 {
                    min[k] = min[k].min(lo[k]);
                    max[k] = max[k].max(hi[k]);
                }
            };
            if node.count > 0 {
                for p in self.triangles[node.first as usize..(node.first + node.count) as usize]
                    .iter()
                    .flatten()
                {
                    let c = [p.x, p.y, p.z];
                    grow(&c, &c);
                }
            } else {
                for child in [n + 1, node.first as usize] {
                    let c = self.nodes[child];
                    grow(&c.min, &c.max);
                }
            }
            self.nodes[n].min = min;
            self.nodes[n].max = max;
        }
    }

    /// The triangle nearest to `p` (its index in the mesh given) and the
    /// point of it nearest to `p`, if one is at most `bound` away. Of
    /// triangles equally near, the first in the hierarchy's order.
    pub fn closest_triangle_within(&self, p: &Point3, bound: Real) -> Option<(u32, Point3)> {
        let (t, _) = self.nearest_triangle(p, bound * bound)?;
        let [a, b, c] = &self.triangles[t];
        Some((self.ids[t], closest_point_on_triangle(p, a, b, c)))
    }

    /// [`SurfaceIndex::closest_triangle_within`], searched from the leaf of
    /// triangle `near` (an index in the mesh given) upwards: when `p` lies
    /// close to that triangle (the last match of a point on a mesh that has
    /// moved a little), its leaf tightens the bound at once and the walk up
    /// visits only the siblings that could hold a nearer triangle, instead
    /// of descending from the root. The answer is the same.
    pub fn closest_triangle_near(
        &self,
        p: &Point3,
        bound: Real,
        near: u32,
    ) -> Option<(u32, Point3)> {
        let mut best = (usize::MAX, bound * bound * (1.0 + 1e-9));
        let mut stack = Vec::with_capacity(64);
        let mut node = self.leaves[self.places[near as usize] as usize];
        self.descend(node, p, &mut best, &mut stack);
        while node != 0 {
            let parent = self.parents[node as usize];
            let sibling = if node == parent + 1 {
                self.nodes[parent as usize].first
            } else {
                parent + 1
            };
            self.descend(sibling, p, &mut best, &mut stack);
            node = parent;
        }
        (best.0 != usize::MAX).then(|| {
            let [a, b, c] = &self.triangles[best.0];
            (self.ids[best.0], closest_point_on_triangle(p, a, b, c))
        })
    }

    /// The triangle (in leaf order) nearest to `p` and its squared distance,
    /// if one is at most `bound_squared` away.
    fn nearest_triangle(&self, p: &Point3, bound_squared: Real) -> Option<(usize, Real)> {
        // The bound is widened by a hair so that the triangle it was measured
        // to, at exactly that distance, is still found despite rounding.
        let mut best = (usize::MAX, bound_squared * (1.0 + 1e-9));
        if self.nodes.is_empty() {
            return None;
        }
        self.descend(0, p, &mut best, &mut Vec::with_capacity(64));
        (best.0 != usize::MAX).then_some(best)
    }

    /// Tightens `best` (a leaf-order triangle and its squared distance from
    /// `p`) with the triangles under node `root`, nearest box first. Of
    /// triangles equally near, the first in leaf order wins, whatever order
    /// they are visited in, so that a search from anywhere in the tree finds
    /// the same one. `stack` is scratch space.
    fn descend(
        &self,
        root: u32,
        p: &Point3,
        best: &mut (usize, Real),
        stack: &mut Vec<(u32, Real)>,
    ) {
        // Depth is at most log2 of the triangle count (median splits), and the
        // stack holds at most one pending sibling per level.
        stack.clear();
        stack.push((root, self.nodes[root as usize].distance_squared(p)));
        while let Some((n, d)) = stack.pop() {
            // A box as far as the best may still hold a tie that comes first.
            if d > best.1 {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.count > 0 {
                let (first, count) = (node.first as usize, node.count as usize);
                for (t, [a, b, c]) in self.triangles[first..first + count].iter().enumerate() {
                    let d = point_triangle_distance_squared(p, a, b, c);
                    if d < best.1 || (d == best.1 && first + t < best.0) {
                        *best = (first + t, d);
                    }
                }
                continue;
            }
            let (l, r) = (n + 1, node.first);
            let (dl, dr) = (
                self.nodes[l as usize].distance_squared(p),
                self.nodes[r as usize].distance_squared(p),
            );
            // The nearer child is popped first, so its triangles tighten `best`
            // before the farther one is considered.
            let (near, far) = if dl <= dr {
                ((l, dl), (r, dr))
            } else {
                ((r, dr), (l, dl))
            };
            if far.1 <= best.1 {
                stack.push(far);
            }
            if near.1 <= best.1 {
                stack.push(near);
            }
        }
    }

    /// Distance from `p` to the surface.
    pub fn distance(&self, p: &Point3) -> Real {
        self.distance_squared(p).sqrt()
    }
}

/// Appends the subtree over `order` (a slice of triangle ids starting at
/// `offset` in the final leaf order) and returns its node index.
fn build(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    offset: usize,
    corners: &[[Point3; 3]],
    centroids: &[Point3],
) -> usize {
    let (mut min, mut max) = ([Real::INFINITY; 3], [Real::NEG_INFINITY; 3]);
    let (mut cmin, mut cmax) = ([Real::INFINITY; 3], [Real::NEG_INFINITY; 3]);
    for &t in order.iter() {
        for p in &corners[t as usize] {
            for k in 0..3 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        let c = &centroids[t as usize];
        for k in 0..3 {
            cmin[k] = cmin[k].min(c[k]);
            cmax[k] = cmax[k].max(c[k]);
        }
    }
    let index = nodes.len();
    nodes.push(Node {
        min,
        max,
        first: offset as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF_SIZE {
        return index;
    }
    let axis = (0..3)
        .max_by(|&a, &b| (cmax[a] - cmin[a]).total_cmp(&(cmax[b] - cmin[b])))
        .unwrap_or(0);
    let mid = order.len() / 2;
    // Ties broken by id so the tree does not depend on the sort's internals.
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis]
            .total_cmp(&centroids[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (left, right) = order.split_at_mut(mid);
    build(nodes, left, offset, corners, centroids);
    let second = build(nodes, right, offset + mid, corners, centroids);
    nodes[index].first = second as u32;
    nodes[index].count = 0;
    index
}

#[cfg(test)]
#[path = "surface_tests.rs"]
mod tests;
