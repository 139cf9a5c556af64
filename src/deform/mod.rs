//! Stage 4: the first-frame mesh deformed by the center trajectories into one
//! mesh with one connectivity for all frames (docs/method.md §10).
//!
//! Every frame-0 vertex binds to its nearest centers, but only to those
//! affine (ω) to its nearest one, so a hand resting on a hip in frame 0 is not
//! glued to the hip. Each center's rigid motion from frame 0 to frame f is
//! fitted over its own affine neighbours, and a vertex follows the blend of
//! its centers' motions. The weights are spread a little over the mesh, so
//! the set of centers changes gradually from vertex to vertex.

mod blend;
mod conform;
pub mod segments;

pub use blend::DualQuaternion;
pub use conform::{conform, conform_frame};

use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::model::mesh::TriangleMesh;
use crate::model::{DynamicMesh, PositionFrames, Rigid, Trajectories};
use crate::params::{Blending, DeformParams};
use crate::progress::Progress;
use crate::refine::SparseAffinity;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::num::NonZeroUsize;

/// A vertex's centers and their normalised weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Binding {
    /// (center index, weight), nearest first; the weights sum to 1.
    pub centers: Vec<(u32, Real)>,
}

/// Binds every vertex of `mesh` to up to `params.neighbors` centers of frame 0.
pub fn bind(
    mesh: &TriangleMesh,
    centers: &[Point3],
    omega: &SparseAffinity,
    params: &DeformParams,
) -> Vec<Binding> {
    let points: Vec<[Real; 3]> = centers.iter().map(|p| [p.x, p.y, p.z]).collect();
    let tree = ImmutableKdTree::<Real, 3>::new_from_slice(&points).expect("finite centers");
    // Weight falloff: a center one typical spacing away counts half.
    let spacing = typical_spacing(&tree, &points);
    let sigma = std::f64::consts::LN_2 / (spacing * spacing);
    let candidates = NonZeroUsize::new((params.neighbors * 4).min(points.len())).unwrap();
    mesh.positions
        .par_iter()
        .map(|v| {
            let found = tree
                .query(&[v.x, v.y, v.z])
                .nearest_n::<SquaredEuclidean<Real>>(candidates)
                .execute();
            let nearest = found[0].item as usize;
            let mut centers: Vec<(u32, Real)> = found
                .iter()
                .filter(|r| {
                    r.item as usize == nearest
                        || omega.weight(nearest, r.item as usize) >= params.min_affinity
                })
                .take(params.neighbors)
                .map(|r| (r.item, (-sigma * r.distance).exp().max(1e-12)))
                .collect();
            let total: Real = centers.iter().map(|c| c.1).sum();
            centers.iter_mut().for_each(|c| c.1 /= total);
            Binding { centers }
        })
        .collect()
}

/// Median distance from a center to its nearest other center.
fn typical_spacing(tree: &ImmutableKdTree<Real, 3>, points: &[[Real; 3]]) -> Real {
    if points.len() < 2 {
        return 1.0;
    }
    let mut d: Vec<Real> = points
        .iter()
        .map(|p| {
            tree.query(p)
                .nearest_n::<SquaredEuclidean<Real>>(NonZeroUsize::new(2).unwrap())
                .execute()[1]
                .distance
                .sqrt()
        })
        .collect();
    d.sort_by(Real::total_cmp);
    d[d.len() / 2].max(Real::MIN_POSITIVE)
}

/// Each center's rigid motion from the reference frame to frame `f`: the rotation
/// fitted over its affine neighbours, the translation chosen so that the
/// center itself lands exactly on its tracked position.
///
/// Why anchor: the plain fit carries the neighbours' weighted centroid, not
/// the center, so wherever a neighbourhood bends (a limb at a joint) vertices
/// near the center would miss its tracked position by the bend's sagitta.
/// One frame at a time: all frames' motions would take 96 bytes per center
/// and frame for as long as the deformation runs.
pub(crate) fn center_motions(traj: &Trajectories, omega: &SparseAffinity, f: usize) -> Vec<Rigid> {
    let r = traj.reference;
    let mut motions = omega.fit_frames(traj, r, f);
    for (i, m) in motions.iter_mut().enumerate() {
        m.translation = traj.get(f, i).coords - m.rotation * traj.get(r, i).coords;
    }
    motions
}

/// The dynamic mesh: `mesh` (the trajectories' reference frame as loaded)
/// moved by the trajectories.
pub fn deform(
    mesh: &TriangleMesh,
    traj: &Trajectories,
    omega: &SparseAffinity,
    params: &DeformParams,
) -> Result<DynamicMesh> {
    deform_with(mesh, traj, omega, params, Progress::none())
}

/// [`deform`], returning [`Error::Interrupted`] between frames once
/// `progress` asks to stop.
pub fn deform_with(
    mesh: &TriangleMesh,
    traj: &Trajectories,
    omega: &SparseAffinity,
    params: &DeformParams,
    progress: Progress,
) -> Result<DynamicMesh> {
    if params.neighbors == 0 {
        return Err(Error::InvalidParameter(
            "the number of centers each vertex follows must be at least 1".into(),
        ));
    }
    if traj.centers == 0 || omega.lists.len() != traj.centers {
        return Err(Error::InvalidInput(
            "no centers to deform the mesh with".into(),
        ));
    }
    // Copies of a vertex (a UV seam) are smoothed as the one vertex they are
    // and share its weights, or the seam would open as the mesh moves.
    let (weld, welded) = mesh.welded();
    let smoothed = smooth_bindings(
        &welded,
        bind(mesh, traj.frame(traj.reference), omega, params),
        omega,
        params.smoothing,
        2 * params.neighbors,
    );
    let bindings: Vec<Binding> = weld.iter().map(|&w| smoothed[w as usize].clone()).collect();
    let mut frames = PositionFrames::new(mesh.positions.len(), traj.frames, params.memory)?;
    for f in 0..traj.frames {
        if f == traj.reference {
            frames.push(mesh.positions.clone())?;
            continue;
        }
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
        frames.push(move_vertices(
            &mesh.positions,
            &bindings,
            &center_motions(traj, omega, f),
            params.blending,
        ))?;
    }
    Ok(DynamicMesh {
        base: mesh.clone(),
        frames,
        reference: traj.reference,
    })
}

/// Every vertex moved by the blend of its centers' motions.
pub(crate) fn move_vertices(
    positions: &[Point3],
    bindings: &[Binding],
    motions: &[Rigid],
    blending: Blending,
) -> Vec<Point3> {
    positions
        .par_iter()
        .zip(bindings)
        .map(|(v, b)| match blending {
            Blending::Linear => Point3::from(
                b.centers
                    .iter()
                    .map(|&(c, w)| motions[c as usize].apply(v).coords * w)
                    .sum::<crate::math::Vector3>(),
            ),
            Blending::DualQuaternion => {
                let blended = DualQuaternion::blend(
                    b.centers
                        .iter()
                        .map(|&(c, w)| (DualQuaternion::from_rigid(&motions[c as usize]), w)),
                );
                blended.apply(v)
            }
        })
        .collect()
}

/// Spreads every vertex's weights over its mesh neighbours, `rounds` times
/// (half its own, half their mean), keeping the `keep` largest: the center
/// set then changes gradually across the surface instead of switching
/// between adjacent vertices. Weights cross an edge only when its two
/// vertices' nearest centers are one and the same or have an affinity at
/// all: where two bodies touch in frame 0 and part later, their merged
/// surface still does not mix their centers.
pub fn smooth_bindings(
    triangles: &[[u32; 3]],
    bindings: Vec<Binding>,
    omega: &SparseAffinity,
    rounds: usize,
    keep: usize,
) -> Vec<Binding> {
    if rounds == 0 {
        return bindings;
    }
    let nearest: Vec<Option<usize>> = bindings
        .iter()
        .map(|b| b.centers.first().map(|c| c.0 as usize))
        .collect();
    let linked = |a: usize, b: usize| match (nearest[a], nearest[b]) {
        (Some(x), Some(y)) => x == y || omega.weight(x, y) > 0.0,
        _ => false,
    };
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); bindings.len()];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if linked(a as usize, b as usize) {
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
    }
    for n in &mut neighbours {
        n.sort_unstable();
        n.dedup();
    }
    let mut current = bindings;
    for _ in 0..rounds {
        current = (0..current.len())
            .into_par_iter()
            .map(|v| {
                let mut acc: Vec<(u32, Real)> = current[v]
                    .centers
                    .iter()
                    .map(|&(c, w)| (c, 0.5 * w))
                    .collect();
                let share = 0.5 / neighbours[v].len().max(1) as Real;
                for &u in &neighbours[v] {
                    for &(c, w) in &current[u as usize].centers {
                        match acc.iter_mut().find(|e| e.0 == c) {
                            Some(e) => e.1 += share * w,
                            None => acc.push((c, share * w)),
                        }
                    }
                }
                acc.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
                acc.truncate(keep);
                let total: Real = acc.iter().map(|e| e.1).sum();
                acc.iter_mut().for_each(|e| e.1 /= total);
                Binding { centers: acc }
            })
            .collect();
    }
    current
}
