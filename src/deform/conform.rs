//! Fitting the deformed mesh to every frame's input surface
//! ([`ConformParams`]; not in the paper). Per frame, the frame-0 mesh is
//! deformed as rigidly as possible (Sorkine & Alexa 2007: every vertex's
//! one-ring keeps its frame-0 edges up to a rotation) while each vertex is
//! pulled onto the nearest compatible point of that frame's input surface,
//! starting from the blended result of method.md §10. The surface term
//! weighs the distance along the surface normal fully and the distance along
//! the surface a little, so the mesh can slide along the surface to where
//! its edges keep their lengths.
//!
//! Energy per frame, with X the frame-0 positions, y the unknowns, R_i a
//! rotation per vertex, (c_i, n_i) the surface point and normal a vertex is
//! pulled to and w_i 1 when that point is compatible (near enough, facing
//! the same way) else 0:
//!   s Σ_edges ij |(y_i − y_j) − R_i (X_i − X_j)|² (both directions)
//!   + Σ_i w_i ((n_i·(y_i − c_i))² + μ |y_i − c_i|²) + ε Σ_i |y_i − Y_i|²,
//! where Y is the blended position and ε a small anchor that keeps a part
//! with no compatible surface where blending put it. Each round fits the
//! rotations to the current y, finds the surface points and solves the
//! linear system for y by conjugate gradients, warm-started.

use super::DynamicMesh;
use crate::error::{Error, Result};
use crate::math::{Matrix3, Point3, Real, UnitQuaternion, Vector3};
use crate::mesh::{Aabb, TriangleMesh};
use crate::metrics::SurfaceIndex;
use crate::params::ConformParams;
use crate::progress::{Counter, Progress, Stage};
use crate::track::rotation_from_covariance;
use nalgebra::Unit;
use rayon::prelude::*;
use std::path::PathBuf;

/// Weight ε of staying at the blended position, against 1 for the surface:
/// only there to keep a part that meets no compatible surface in place.
const ANCHOR: Real = 1e-3;
/// Conjugate-gradient iterations per solve; the solve is warm-started from
/// the last round, so it rarely needs many.
const MAX_SOLVER_ITERATIONS: usize = 50;
/// The solve stops when its next step would move the vertices by about this
/// fraction of `max_distance` (root mean square), far below what the rounds
/// change; relative to a length, not to the right-hand side, which holds
/// absolute positions and would loosen the tolerance far from the origin.
const SOLVER_TOLERANCE: Real = 2e-4;

/// The frame-0 mesh's connectivity, the same for every frame, with copies of
/// a vertex (a UV seam: same frame-0 position) welded into the first: the
/// copies would otherwise each keep only their own side's edges and be fitted
/// apart, opening the seam.
struct Topology {
    /// Per vertex, the first vertex at its frame-0 position.
    weld: Vec<u32>,
    /// The triangles over welded indices.
    triangles: Vec<[u32; 3]>,
    edges: Edges,
}

impl Topology {
    fn new(base: &TriangleMesh) -> Self {
        let (weld, triangles) = base.welded();
        let edges = Edges::new(base.positions.len(), &triangles);
        Topology { weld, triangles, edges }
    }
}

/// The frame-0 mesh's edges, the same for every frame.
struct Edges {
    /// Vertex v's neighbours are `neighbours[start[v]..start[v + 1]]`.
    start: Vec<usize>,
    neighbours: Vec<u32>,
}

impl Edges {
    fn new(vertices: usize, triangles: &[[u32; 3]]) -> Self {
        let mut pairs: Vec<(u32, u32)> =
            triangles.iter().flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3])))).filter(|(a, b)| a != b).collect();
        pairs.sort_unstable();
        pairs.dedup();
        let mut count = vec![0usize; vertices + 1];
        for &(a, b) in &pairs {
            count[a as usize + 1] += 1;
            count[b as usize + 1] += 1;
        }
        for v in 0..vertices {
            count[v + 1] += count[v];
        }
        let start = count.clone();
        let mut neighbours = vec![0u32; 2 * pairs.len()];
        let mut next = count;
        for &(a, b) in &pairs {
            neighbours[next[a as usize]] = b;
            next[a as usize] += 1;
            neighbours[next[b as usize]] = a;
            next[b as usize] += 1;
        }
        Edges { start, neighbours }
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.neighbours[self.start[v]..self.start[v + 1]]
    }
}

/// Moves every frame after the first of `mesh` onto the input surface of
/// the same frame, read again from `inputs` (one file per frame, as
/// [`crate::voxel::VoxelSequence::paths`]). `bounds` is the input's bounding
/// box, whose longest side `params.max_distance` is a fraction of.
///
/// Frames are fitted in parallel, each independently of the others; frame 0
/// is the mesh as loaded and stays. Reports `(Stage::Conform, frames done,
/// frames after the first)` and stops with [`Error::Interrupted`] when
/// cancelled.
pub fn conform_to_inputs(mesh: DynamicMesh, inputs: &[PathBuf], bounds: &Aabb, params: &ConformParams, progress: Progress) -> Result<DynamicMesh> {
    params.validate()?;
    if params.iterations == 0 {
        return Ok(mesh);
    }
    if mesh.frames.len() != inputs.len() {
        return Err(Error::InvalidInput(format!(
            "the dynamic mesh has {} frames but {} input files were given",
            mesh.frames.len(),
            inputs.len()
        )));
    }
    let topology = Topology::new(&mesh.base);
    let max_distance = params.length_scale(bounds) * params.max_distance;
    let counter = Counter::new(progress, Stage::Conform, inputs.len().saturating_sub(1));
    let fitted: Vec<Vec<Point3>> = (1..inputs.len())
        .into_par_iter()
        .map(|f| {
            if progress.cancelled() {
                return Err(Error::Interrupted { saved: None });
            }
            let input = crate::io::read_mesh(&inputs[f])?;
            input.validate(&inputs[f])?;
            let frame = fit_frame(&mesh.base, &topology, &mesh.frames[f], &input, max_distance, params, &|| progress.cancelled())
                .ok_or(Error::Interrupted { saved: None })?;
            counter.tick();
            Ok(frame)
        })
        .collect::<Result<_>>()?;
    let DynamicMesh { base, mut frames } = mesh;
    frames.truncate(1);
    frames.extend(fitted);
    Ok(DynamicMesh { base, frames })
}

/// One frame: `blended` (positions of `base`'s vertices after method.md
/// §10) fitted to `input`, as [`conform_to_inputs`] fits each frame.
/// `bounds` is the box whose longest side `params.max_distance` is a
/// fraction of (the whole input's, in a sequence). Both
/// meshes' indices must be in range, as [`TriangleMesh::validate`] checks.
pub fn conform_frame(base: &TriangleMesh, blended: &[Point3], input: &TriangleMesh, bounds: &Aabb, params: &ConformParams) -> Result<Vec<Point3>> {
    params.validate()?;
    if blended.len() != base.positions.len() {
        return Err(Error::InvalidInput(format!("{} positions for a mesh of {} vertices", blended.len(), base.positions.len())));
    }
    let max_distance = params.length_scale(bounds) * params.max_distance;
    fit_frame(base, &Topology::new(base), blended, input, max_distance, params, &|| false).ok_or(Error::Interrupted { saved: None })
}

/// [`conform_frame`] with the mesh's topology at hand; None when `cancelled`
/// says so (it is asked before every round). Only the first copy of a welded
/// vertex is fitted (the others, left without edges or surface points, stay
/// put), and the others take its place at the end.
fn fit_frame(
    base: &TriangleMesh,
    topology: &Topology,
    blended: &[Point3],
    input: &TriangleMesh,
    max_distance: Real,
    params: &ConformParams,
    cancelled: &dyn Fn() -> bool,
) -> Option<Vec<Point3>> {
    let (rest, edges) = (&base.positions, &topology.edges);
    let n = rest.len();
    let surface = SurfaceIndex::new(&input.positions, &input.triangles);
    let stiffness = 2.0 * params.stiffness;
    let mut y: Vec<Vector3> = blended.iter().map(|p| p.coords).collect();
    // Round 0's search, from the blended positions with the full reach, also
    // tells which way the input faces.
    // Copies of a welded vertex need no surface point: they take the first's.
    let first_copy = |v: usize| topology.weld[v] as usize == v;
    let mut normals = vertex_normals(&y, &topology.triangles);
    let mut found: Vec<Option<(Point3, Vector3)>> =
        blended.iter().enumerate().map(|(v, p)| if first_copy(v) { surface.closest_point_within(p, max_distance) } else { None }).collect();
    let flip = faces_away(&found, &normals);
    let diagonal: Vec<Real> = (0..n).map(|v| stiffness * edges.of(v).len() as Real + ANCHOR).collect();
    let mut data = vec![Matrix3::zeros(); n];
    let mut rhs = vec![Vector3::zeros(); n];
    let mut rotations = vec![UnitQuaternion::identity(); n];
    for round in 0..params.iterations {
        if cancelled() {
            return None;
        }
        if round > 0 {
            normals = vertex_normals(&y, &topology.triangles);
            // The point found last round is still on the surface: the
            // nearest one is at most that far, which prunes the search.
            found = y
                .iter()
                .zip(&found)
                .enumerate()
                .map(|(v, (y, last))| {
                    if !first_copy(v) {
                        return None;
                    }
                    let p = Point3::from(*y);
                    let bound = last.map_or(max_distance, |(c, _)| (c - p).norm().min(max_distance));
                    surface.closest_point_within(&p, bound)
                })
                .collect();
        }
        for (v, q) in rotations.iter_mut().enumerate() {
            // A = Σ (y_v − y_u)(X_v − X_u)ᵀ: its rotation carries the frame-0
            // edges onto the current ones.
            let a: Matrix3 = edges.of(v).iter().map(|&u| (y[v] - y[u as usize]) * (rest[v] - rest[u as usize]).transpose()).sum();
            if round == 0 {
                *q = UnitQuaternion::from_matrix(&rotation_from_covariance(&a.transpose()));
            } else {
                refine_rotation(&a, q);
            }
        }
        let matrices: Vec<Matrix3> = rotations.iter().map(|q| q.to_rotation_matrix().into_inner()).collect();
        for v in 0..n {
            let mut b = Vector3::zeros();
            for &u in edges.of(v) {
                let u = u as usize;
                b += 0.5 * (matrices[v] + matrices[u]) * (rest[v] - rest[u]);
            }
            rhs[v] = stiffness * b + ANCHOR * blended[v].coords;
            data[v] = Matrix3::zeros();
            let Some((c, mut normal)) = found[v] else { continue };
            if flip {
                normal = -normal;
            }
            if normal.dot(&normals[v]) >= params.min_normal_cosine {
                data[v] = normal * normal.transpose() + Matrix3::identity() * params.point_weight;
                rhs[v] += data[v] * c.coords;
            }
        }
        solve(edges, stiffness, &diagonal, &data, &rhs, SOLVER_TOLERANCE * max_distance, &mut y);
    }
    Some(topology.weld.iter().map(|&w| Point3::from(y[w as usize])).collect())
}

/// Whether the input is oriented the other way from the mesh: most of the
/// mesh's normals point against those of the surface points `found` within
/// reach. An input
/// that is consistently inside-out (another exporter's winding) is then used
/// turned round instead of rejecting every surface point.
fn faces_away(found: &[Option<(Point3, Vector3)>], normals: &[Vector3]) -> bool {
    let agreement: Real = found.iter().zip(normals).filter_map(|(f, n)| f.map(|(_, m)| m.dot(n))).sum();
    agreement < 0.0
}

/// Steps of [`refine_rotation`] per round.
const ROTATION_STEPS: usize = 3;

/// Moves `q` towards the rotation of A's polar decomposition (Müller et al.
/// 2016, "A robust method to extract the rotational part of deformations"):
/// from the last round's rotation a few steps suffice, where an SVD per
/// vertex per round took a fifth of the stage's time.
fn refine_rotation(a: &Matrix3, q: &mut UnitQuaternion) {
    for _ in 0..ROTATION_STEPS {
        let r = q.to_rotation_matrix().into_inner();
        let (mut torque, mut alignment) = (Vector3::zeros(), 0.0);
        for k in 0..3 {
            torque += r.column(k).cross(&a.column(k));
            alignment += r.column(k).dot(&a.column(k));
        }
        let omega = torque / (alignment.abs() + 1e-9 * a.norm() + Real::MIN_POSITIVE);
        let angle = omega.norm();
        if !(angle > 1e-12) {
            break;
        }
        *q = UnitQuaternion::from_axis_angle(&Unit::new_unchecked(omega / angle), angle) * *q;
    }
}

/// Area-weighted unit vertex normals (zero where the triangles cancel).
fn vertex_normals(positions: &[Vector3], triangles: &[[u32; 3]]) -> Vec<Vector3> {
    let mut normals = vec![Vector3::zeros(); positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let area_normal = (b - a).cross(&(c - a));
        for &i in t {
            normals[i as usize] += area_normal;
        }
    }
    normals.iter().map(|n| n.try_normalize(0.0).unwrap_or_else(Vector3::zeros)).collect()
}

/// Solves A y = rhs by conjugate gradients preconditioned with A's 3×3
/// diagonal blocks, from the `y` given, where
/// (A y)_v = (diagonal_v I + data_v) y_v − stiffness Σ_{u ~ v} y_u.
/// A is symmetric positive definite: a graph Laplacian plus positive
/// semi-definite blocks plus the anchor. Stops when the preconditioned
/// residual r·M⁻¹r, about Σ_v diagonal_v |step_v|², falls to what steps of
/// `tolerance` at every vertex would give.
fn solve(edges: &Edges, stiffness: Real, diagonal: &[Real], data: &[Matrix3], rhs: &[Vector3], tolerance: Real, y: &mut [Vector3]) {
    let n = y.len();
    let apply = |x: &[Vector3], out: &mut [Vector3]| {
        for v in 0..n {
            let neighbours: Vector3 = edges.of(v).iter().map(|&u| x[u as usize]).sum();
            out[v] = x[v] * diagonal[v] + data[v] * x[v] - neighbours * stiffness;
        }
    };
    let inverse: Vec<Matrix3> =
        (0..n).map(|v| (Matrix3::identity() * diagonal[v] + data[v]).try_inverse().unwrap_or_else(|| Matrix3::identity() / diagonal[v])).collect();
    let dot = |a: &[Vector3], b: &[Vector3]| -> Real { a.iter().zip(b).map(|(x, y)| x.dot(y)).sum() };
    let mut ay = vec![Vector3::zeros(); n];
    apply(y, &mut ay);
    let mut r: Vec<Vector3> = rhs.iter().zip(&ay).map(|(b, a)| b - a).collect();
    let mut z: Vec<Vector3> = r.iter().zip(&inverse).map(|(r, m)| m * r).collect();
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let tolerance = tolerance * tolerance * diagonal.iter().sum::<Real>();
    let mut ap = ay;
    for _ in 0..MAX_SOLVER_ITERATIONS {
        if !(rz > tolerance) {
            break;
        }
        apply(&p, &mut ap);
        let alpha = rz / dot(&p, &ap);
        for v in 0..n {
            y[v] += alpha * p[v];
            r[v] -= alpha * ap[v];
            z[v] = inverse[v] * r[v];
        }
        let next = dot(&r, &z);
        let beta = next / rz;
        rz = next;
        for v in 0..n {
            p[v] = z[v] + beta * p[v];
        }
    }
}
