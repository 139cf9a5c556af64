//! Fitting the deformed mesh to every frame's input surface
//! ([`ConformParams`]; not in the paper). Per frame, the frame-0 mesh is
//! deformed as rigidly as possible (Sorkine & Alexa 2007: every vertex's
//! one-ring keeps its frame-0 edges up to a rotation) while it is pulled
//! through the vertices of that frame's input, starting from the blended
//! result of docs/method.md §10: every input vertex pulls the point of the mesh
//! nearest to it, if the mesh there faces the way of every input triangle
//! at the vertex. The term
//! weighs the distance along the mesh's normal fully and the distance along
//! the surface a little, so the mesh can slide along the surface to where
//! its edges keep their lengths.
//!
//! Why the input's vertices and not its triangles: a capture's vertices are
//! samples of the surface, but the triangles between them cut across every
//! crease wherever that frame's meshing put them. Pulling the mesh's
//! vertices onto the input's triangles made them follow each frame's own
//! cuts, so even a rigid body re-meshed per frame came out wobbling.
//! Pulling the mesh through the input's vertices does not see the cuts
//! (`tests/deform.rs` checks this on a re-meshed tube); the vertices beside
//! a cut, whose triangles face both the side and the cut, pull only mesh
//! triangles facing close to both.
//!
//! Energy per frame, with X the frame-0 positions, y the unknowns, R_i a
//! rotation per vertex, q_j an input vertex, s_j(y) = Σ_k b_jk y_k the
//! mesh's point nearest to it (barycentric b_jk in its triangle), n_j that
//! triangle's normal and w_j 1 when the match is compatible (near enough,
//! facing the same way) else 0:
//!
//! ```text
//! s Σ_edges ik w_ik |(y_i − y_k) − R_i (X_i − X_k)|² (both directions)
//!   + Σ_j w_j ((n_j·(s_j(y) − q_j))² + μ |s_j(y) − q_j|²) + ε Σ_i |y_i − Y_i|²,
//! ```
//!
//! where Y is the blended position and ε a small anchor that keeps a part
//! no input vertex pulls where blending put it. Each round fits the
//! rotations to the current y, matches the input vertices (see
//! [`SEARCH_EVERY`]) and solves the linear system for y by conjugate
//! gradients, warm-started.
//!
//! Joints: with every edge weighed alike, the fit spreads a joint's bend
//! over the rigid parts beside it (a hip bends the body's end). From
//! [`REWEIGH_FROM`] of the rounds on, every [`SEARCH_EVERY`]th round weighs
//! each edge's term w_ik by how little it is strained (iteratively
//! reweighted least squares of a Cauchy loss; 1 before): an
//! edge strained by `bend_strain` weighs half, more strained ones less, down
//! to `least_edge_weight`, so the bend gathers at the few edges across the
//! joint. The weights are per frame: each frame bends its own joints.
//!
//! A joint bends at the same edges in many frames, while one frame's
//! strains also hold that frame's noise (a capture's merged surfaces, a
//! crease re-meshed). So with `joint_strain` set, a first fit of up to
//! [`JOINT_SAMPLES`] frames spread over the take measures every edge's mean
//! strain, and every frame's fit then weighs each edge by that mean strain
//! too (the same Cauchy weight, at least `least_joint_weight`), from its
//! first round on, times its own frame's weight. The bend then gathers at
//! the edges that bend through the take.

use crate::error::{Error, Result};
use crate::math::{Matrix3, Point3, Real, Rotation3, UnitQuaternion, Vector3};
use crate::model::mesh::{Aabb, TriangleMesh};
use crate::model::rotation_from_covariance;
use crate::model::DynamicMesh;
use crate::model::FrameSource;
use crate::params::ConformParams;
use crate::progress::{Counter, Progress, Stage};
use crate::spatial::surface::SurfaceIndex;
use nalgebra::Unit;
use rayon::prelude::*;

/// Weight ε of staying at the blended position, against 1 for the surface:
/// only there to keep a part that meets no compatible surface in place.
/// Larger holds the mesh where the tracker put it, which a volume tracker
/// gets wrong along a smooth body (a trunk sliding along its own axis): the
/// surface and the edges should decide that.
const ANCHOR: Real = 1e-4;
/// Rounds, from the first, that search every input vertex's nearest mesh
/// point: the mesh moves most in them.
const FIRST_SEARCHES: usize = 3;
/// After those, every this many rounds search again; in between, each input
/// vertex keeps its triangle and barycentric coordinates, which move with
/// the mesh. The later rounds move the mesh little, so a match found a few
/// rounds before is still close to the nearest: searching every round costs
/// far more time for hardly any change in the fit.
const SEARCH_EVERY: usize = 4;
/// The share of the rounds, from the first, with every edge weighed alike:
/// they bring the blended mesh onto the surface, and strains measured before
/// are the blending's, not the joints'.
const REWEIGH_FROM: Real = 1.0 / 3.0;
/// Conjugate-gradient iterations per solve; the solve is warm-started from
/// the last round, so it rarely needs many.
const MAX_SOLVER_ITERATIONS: usize = 50;
/// The solve stops when its next step would move the vertices by about this
/// fraction of `max_distance` (root mean square), far below what the rounds
/// change; relative to a length, not to the right-hand side, which holds
/// absolute positions and would loosen the tolerance far from the origin.
const SOLVER_TOLERANCE: Real = 2e-4;
/// Most frames the first fit measures the edges' strains on, spread evenly
/// over the take: their mean strain is what it needs, which a few frames
/// across the motion give as well as all of them, and a long take costs
/// no more than a short one.
const JOINT_SAMPLES: usize = 16;

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
    /// Per vertex, Σ_u (X_v − X_u) over its edges: the right-hand side's
    /// ½ Σ_u (R_v + R_u)(X_v − X_u) is ½ R_v times it plus ½ Σ_u R_u (X_v − X_u),
    /// one product per edge.
    spread: Vec<Vector3>,
    /// Per vertex v, X_v − X_u for each of its edges' u, in `edges`' order:
    /// every round takes each twice.
    offsets: PerVertex<Vector3>,
}

impl Topology {
    fn new(base: &TriangleMesh) -> Self {
        let (weld, triangles) = base.welded();
        let rest = &base.positions;
        let edges = edges(rest.len(), &triangles);
        let entries: Vec<(u32, Vector3)> = (0..rest.len())
            .flat_map(|v| {
                edges
                    .of(v)
                    .iter()
                    .map(move |&u| (v as u32, rest[v] - rest[u as usize]))
            })
            .collect();
        let offsets = PerVertex::new(rest.len(), &entries);
        let spread = (0..rest.len())
            .map(|v| offsets.of(v).iter().sum())
            .collect();
        Topology {
            weld,
            triangles,
            edges,
            spread,
            offsets,
        }
    }
}

/// Lists per vertex in one array: vertex v's are `items[start[v]..start[v + 1]]`.
struct PerVertex<T> {
    start: Vec<usize>,
    items: Vec<T>,
}

impl<T: Copy + Default> PerVertex<T> {
    /// Every `(v, item)` of `entries` into v's list, in the order given.
    fn new(vertices: usize, entries: &[(u32, T)]) -> Self {
        let mut start = vec![0usize; vertices + 1];
        for &(v, _) in entries {
            start[v as usize + 1] += 1;
        }
        for v in 0..vertices {
            start[v + 1] += start[v];
        }
        let mut next = start.clone();
        let mut items = vec![T::default(); entries.len()];
        for &(v, item) in entries {
            items[next[v as usize]] = item;
            next[v as usize] += 1;
        }
        PerVertex { start, items }
    }

    fn of(&self, v: usize) -> &[T] {
        &self.items[self.start[v]..self.start[v + 1]]
    }
}

/// The frame-0 mesh's edges, the same for every frame: every vertex's
/// neighbours.
type Edges = PerVertex<u32>;

fn edges(vertices: usize, triangles: &[[u32; 3]]) -> Edges {
    let mut pairs: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |k| (t[k].min(t[(k + 1) % 3]), t[k].max(t[(k + 1) % 3]))))
        .filter(|(a, b)| a != b)
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let entries: Vec<(u32, u32)> = pairs.iter().flat_map(|&(a, b)| [(a, b), (b, a)]).collect();
    PerVertex::new(vertices, &entries)
}

/// The unit normals of the triangles around every vertex of a mesh, zero
/// for a degenerate one: that faces no way, so (for a positive least
/// cosine) its vertices pull nothing. Re-meshing leaves such slivers along
/// creases, where a vertex's place is least certain: its vertices are
/// better left out than pulling one of the sides.
type Fans = PerVertex<Vector3>;

fn fans(mesh: &TriangleMesh) -> Fans {
    let entries: Vec<(u32, Vector3)> = mesh
        .triangles
        .iter()
        .flat_map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let normal = (b - a)
                .cross(&(c - a))
                .try_normalize(0.0)
                .unwrap_or_else(Vector3::zeros);
            t.map(|v| (v, normal))
        })
        .collect();
    PerVertex::new(mesh.positions.len(), &entries)
}

/// Moves every frame after the first of `mesh` onto the input surface of
/// the same frame, read again from `source` (the frames the mesh was made
/// from, read one per worker at a time). `bounds` is the input's bounding
/// box, whose longest side `params.max_distance` is a fraction of.
///
/// Frames are fitted in parallel, each independently of the others; frame 0
/// is the mesh as loaded and stays. Reports `(Stage::Conform, frames done,
/// frames after the first)` and stops with [`Error::Interrupted`] when
/// cancelled.
pub fn conform(
    mesh: DynamicMesh,
    source: &dyn FrameSource,
    bounds: &Aabb,
    params: &ConformParams,
    progress: Progress,
) -> Result<DynamicMesh> {
    params.validate()?;
    if params.iterations == 0 {
        return Ok(mesh);
    }
    if mesh.frames.len() != source.len() {
        return Err(Error::InvalidInput(format!(
            "the dynamic mesh has {} frames but the input has {}",
            mesh.frames.len(),
            source.len()
        )));
    }
    let topology = Topology::new(&mesh.base);
    let max_distance = params.length_scale(bounds) * params.max_distance;
    // The frames to fit, all but the reference (which is its input): the
    // k-th of them is frame other(k).
    let later = source.len().saturating_sub(1);
    let reference = mesh.reference;
    let other = |k: usize| if k < reference { k } else { k + 1 };
    let samples = if params.joint_strain > 0.0 {
        later.min(JOINT_SAMPLES)
    } else {
        0
    };
    let counter = Counter::new(progress, Stage::Conform, samples + later);
    // A few frames at a time, each replaced where it lies: memory holds a
    // block, whether the frames are in memory or in a file.
    let DynamicMesh {
        base,
        mut frames,
        reference,
    } = mesh;
    let block = 4 * rayon::current_num_threads().max(1);
    let fit = |f: usize,
               blended: &[Point3],
               joints: Option<&[Real]>,
               strains: Option<&mut Vec<Real>>|
     -> Result<Vec<Point3>> {
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
        let input = source.mesh(f)?;
        let fitted = fit_frame(
            &base,
            &topology,
            blended,
            &input,
            max_distance,
            params,
            joints,
            strains,
            &|| progress.cancelled(),
        )
        .ok_or(Error::Interrupted { saved: None })?;
        counter.tick();
        Ok(fitted)
    };
    let joints = if samples > 0 {
        // Summed in frame order, whatever the threads: deterministic.
        let mut total = vec![0.0; topology.edges.items.len()];
        // Frames other than the reference, evenly spread.
        let sampled: Vec<usize> = (0..samples).map(|k| other(k * later / samples)).collect();
        for chunk in sampled.chunks(block) {
            let strains: Vec<Vec<Real>> = chunk
                .par_iter()
                .map(|&f| {
                    let mut strains = Vec::new();
                    fit(f, &frames.get(f)?, None, Some(&mut strains))?;
                    Ok(strains)
                })
                .collect::<Result<_>>()?;
            for strains in strains {
                total.iter_mut().zip(strains).for_each(|(t, s)| *t += s);
            }
        }
        Some(
            total
                .into_iter()
                .map(|t| {
                    cauchy_weight(t / samples as Real, params.joint_strain)
                        .max(params.least_joint_weight)
                })
                .collect::<Vec<Real>>(),
        )
    } else {
        None
    };
    for start in (0..later).step_by(block) {
        let chunk: Vec<usize> = (start..(start + block).min(later)).map(other).collect();
        let fitted: Vec<Vec<Point3>> = chunk
            .par_iter()
            .map(|&f| fit(f, &frames.get(f)?, joints.as_deref(), None))
            .collect::<Result<_>>()?;
        for (&f, frame) in chunk.iter().zip(fitted) {
            frames.replace(f, frame)?;
        }
    }
    Ok(DynamicMesh {
        base,
        frames,
        reference,
    })
}

/// One frame: `blended` (positions of `base`'s vertices after docs/method.md
/// §10) fitted to `input`, as [`conform`] fits each frame.
/// `bounds` is the box whose longest side `params.max_distance` is a
/// fraction of (the whole input's, in a sequence). Both
/// meshes' indices must be in range, as [`TriangleMesh::validate`] checks.
pub fn conform_frame(
    base: &TriangleMesh,
    blended: &[Point3],
    input: &TriangleMesh,
    bounds: &Aabb,
    params: &ConformParams,
) -> Result<Vec<Point3>> {
    params.validate()?;
    if blended.len() != base.positions.len() {
        return Err(Error::InvalidInput(format!(
            "{} positions for a mesh of {} vertices",
            blended.len(),
            base.positions.len()
        )));
    }
    let max_distance = params.length_scale(bounds) * params.max_distance;
    fit_frame(
        base,
        &Topology::new(base),
        blended,
        input,
        max_distance,
        params,
        None,
        None,
        &|| false,
    )
    .ok_or(Error::Interrupted { saved: None })
}

/// [`conform_frame`] with the mesh's topology at hand; None when `cancelled`
/// says so (it is asked before every round). Only the first copy of a welded
/// vertex is fitted (the others, in no welded triangle, have no edges or
/// surface terms and stay put), and the others take its place at the end.
/// `joints` are per-edge weights (in `edges`' order) that every edge's own
/// weight is multiplied by, from the first round on; `strains`, if given,
/// receives every edge's strain in the fitted mesh.
#[allow(clippy::too_many_arguments)]
fn fit_frame(
    base: &TriangleMesh,
    topology: &Topology,
    blended: &[Point3],
    input: &TriangleMesh,
    max_distance: Real,
    params: &ConformParams,
    joints: Option<&[Real]>,
    strains: Option<&mut Vec<Real>>,
    cancelled: &dyn Fn() -> bool,
) -> Option<Vec<Point3>> {
    let (rest, edges, triangles, spread, offsets) = (
        &base.positions,
        &topology.edges,
        &topology.triangles,
        &topology.spread,
        &topology.offsets,
    );
    let n = rest.len();
    let stiffness = 2.0 * params.stiffness;
    let mut y: Vec<Vector3> = blended.iter().map(|p| p.coords).collect();
    let fans = fans(input);
    let mut diagonal: Vec<Real> = (0..n)
        .map(|v| stiffness * edges.of(v).len() as Real + ANCHOR)
        .collect();
    // Per edge (in `edges`' order) its weight w_uv and w_uv (X_v − X_u), and
    // per vertex Σ_u w_uv (X_v − X_u).
    let mut weights = PerVertex {
        start: edges.start.clone(),
        items: joints.map_or_else(|| vec![1.0; edges.items.len()], <[Real]>::to_vec),
    };
    let mut weighted = PerVertex {
        start: offsets.start.clone(),
        items: offsets.items.clone(),
    };
    let mut weighted_spread: Vec<Vector3> = spread.clone();
    let reweigh_from = (params.iterations as Real * REWEIGH_FROM).ceil() as usize;
    let mut rhs = vec![Vector3::zeros(); n];
    let mut rotations = vec![UnitQuaternion::identity(); n];
    let mut index: Option<SurfaceIndex> = None;
    // Per input vertex, the mesh triangle nearest to it and the point's
    // barycentric coordinates there.
    let mut matches: Vec<Option<(u32, [Real; 3])>> = vec![None; input.positions.len()];
    let mut flip = false;
    let mut terms: Vec<Term> = Vec::new();
    for round in 0..params.iterations {
        if cancelled() {
            return None;
        }
        let points: Vec<Point3> = y.iter().map(|v| Point3::from(*v)).collect();
        if round < FIRST_SEARCHES || round % SEARCH_EVERY == 0 {
            let index = match &mut index {
                None => index.insert(SurfaceIndex::new(&points, triangles)),
                Some(index) => {
                    index.refit(&points, triangles);
                    index
                }
            };
            match_input(index, &points, triangles, input, max_distance, &mut matches);
            if round == 0 {
                flip = faces_away(&matches, &fans, &points, triangles);
            }
        }
        fit_rotations(&mut rotations, edges, &weighted, &y, round == 0);
        let matrices: Vec<Matrix3> = rotations
            .iter()
            .map(|q| q.to_rotation_matrix().into_inner())
            .collect();
        let reweigh_now = params.bend_strain > 0.0
            && round >= reweigh_from
            && (round - reweigh_from).is_multiple_of(SEARCH_EVERY);
        if reweigh_now {
            reweigh(edges, offsets, &y, &matrices, params, joints, &mut weights);
        }
        // The take's weights apply from the first solve, the frame's own from their first reweighing.
        let weighed = joints.is_some() || (params.bend_strain > 0.0 && round >= reweigh_from);
        if reweigh_now || (round == 0 && joints.is_some()) {
            for ((w, x), wx) in weights
                .items
                .iter()
                .zip(&offsets.items)
                .zip(weighted.items.iter_mut())
            {
                *wx = x * *w;
            }
            for v in 0..n {
                weighted_spread[v] = weighted.of(v).iter().sum();
                diagonal[v] = stiffness * weights.of(v).iter().sum::<Real>() + ANCHOR;
            }
        }
        for v in 0..n {
            let b: Vector3 = matrices[v] * weighted_spread[v]
                + edges
                    .of(v)
                    .iter()
                    .zip(weighted.of(v))
                    .map(|(&u, x)| matrices[u as usize] * x)
                    .sum::<Vector3>();
            rhs[v] = 0.5 * stiffness * b + ANCHOR * blended[v].coords;
        }
        let facing = if flip { -1.0 } else { 1.0 };
        surface_terms(
            input, &matches, &fans, &points, triangles, facing, params, &mut rhs, &mut terms,
        );
        solve(
            edges,
            weighed.then_some(&weights),
            stiffness,
            &diagonal,
            &terms,
            &rhs,
            SOLVER_TOLERANCE * max_distance,
            &mut y,
        );
    }
    if let Some(strains) = strains {
        let matrices: Vec<Matrix3> = rotations
            .iter()
            .map(|q| q.to_rotation_matrix().into_inner())
            .collect();
        strains.clear();
        strains.extend(
            (0..n)
                .flat_map(|v| (edges.start[v]..edges.start[v + 1]).map(move |k| (v, k)))
                .map(|(v, k)| edge_strain(edges, offsets, &y, &matrices, v, k)),
        );
    }
    Some(
        topology
            .weld
            .iter()
            .map(|&w| Point3::from(y[w as usize]))
            .collect(),
    )
}

/// Matches every input vertex to the point of the mesh (at `points`,
/// indexed by `index`) nearest to it within `max_distance`: its triangle and
/// barycentric coordinates there, None where nothing is that near.
fn match_input(
    index: &SurfaceIndex,
    points: &[Point3],
    triangles: &[[u32; 3]],
    input: &TriangleMesh,
    max_distance: Real,
    matches: &mut [Option<(u32, [Real; 3])>],
) {
    let point_of = |(t, w): (u32, [Real; 3])| -> Point3 {
        Point3::from(
            (0..3)
                .map(|k| points[triangles[t as usize][k] as usize].coords * w[k])
                .sum::<Vector3>(),
        )
    };
    for (q, found) in input.positions.iter().zip(matches.iter_mut()) {
        // Last search's point is still on the mesh: the nearest one
        // is at most that far, which prunes the search.
        let bound = found.map_or(max_distance, |m| (point_of(m) - q).norm().min(max_distance));
        let nearest = match *found {
            Some((t, _)) => index.closest_triangle_near(q, bound, t),
            None => index.closest_triangle_within(q, bound),
        };
        *found = nearest.map(|(t, p)| {
            let [a, b, c] = triangles[t as usize].map(|i| points[i as usize]);
            (t, barycentric(&p, &a, &b, &c))
        });
    }
}

/// The local step: every vertex's rotation fitted to its one-ring's
/// current edges `y` against the frame-0 ones (`weighted`: weighted by
/// edge); the `first` fit from scratch, later ones refined from the last.
fn fit_rotations(
    rotations: &mut [UnitQuaternion],
    edges: &Edges,
    weighted: &PerVertex<Vector3>,
    y: &[Vector3],
    first: bool,
) {
    for (v, q) in rotations.iter_mut().enumerate() {
        // A = Σ w_uv (y_v − y_u)(X_v − X_u)ᵀ: its rotation carries the frame-0
        // edges onto the current ones.
        let a: Matrix3 = edges
            .of(v)
            .iter()
            .zip(weighted.of(v))
            .map(|(&u, x)| (y[v] - y[u as usize]) * x.transpose())
            .sum();
        if first {
            // Already a rotation: no polar decomposition needed.
            *q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
                rotation_from_covariance(&a.transpose()),
            ));
        } else {
            refine_rotation(&a, q);
        }
    }
}

/// The surface terms of the input vertices whose matches are compatible,
/// into `terms` (cleared first), and their share of the right-hand side
/// into `rhs`. Compatible: the mesh's triangle faces (turned by `facing`)
/// within the least cosine's angle of every input triangle at the vertex.
/// A vertex whose triangles turn sharply (beside a crease they cut) pulls
/// fewer parts of the mesh, and one on a sliver pulls none, nor one in no
/// triangle (a stray point, not surface).
#[allow(clippy::too_many_arguments)]
fn surface_terms(
    input: &TriangleMesh,
    matches: &[Option<(u32, [Real; 3])>],
    fans: &Fans,
    points: &[Point3],
    triangles: &[[u32; 3]],
    facing: Real,
    params: &ConformParams,
    rhs: &mut [Vector3],
    terms: &mut Vec<Term>,
) {
    terms.clear();
    for (j, (q, found)) in input.positions.iter().zip(matches).enumerate() {
        let Some((t, weights)) = *found else { continue };
        let corners = triangles[t as usize];
        let [a, b, c] = corners.map(|i| points[i as usize]);
        let Some(normal) = (b - a).cross(&(c - a)).try_normalize(0.0) else {
            continue;
        };
        let fan = fans.of(j);
        if fan.is_empty()
            || fan
                .iter()
                .any(|n| facing * n.dot(&normal) < params.min_normal_cosine)
        {
            continue;
        }
        let m = normal * normal.transpose() + Matrix3::identity() * params.point_weight;
        let mq = m * q.coords;
        for k in 0..3 {
            rhs[corners[k] as usize] += mq * weights[k];
        }
        terms.push(Term {
            corners,
            weights,
            m,
        });
    }
}

/// The strain of `edges`' k-th item, from v to u: |(y_v − y_u) − R (X_v − X_u)|
/// over |X_v − X_u|, averaged over R = R_v and R_u, so the same for both
/// directions of an edge.
fn edge_strain(
    edges: &Edges,
    offsets: &PerVertex<Vector3>,
    y: &[Vector3],
    rotations: &[Matrix3],
    v: usize,
    k: usize,
) -> Real {
    let u = edges.items[k] as usize;
    let (x, d) = (offsets.items[k], y[v] - y[u]);
    0.5 * ((d - rotations[v] * x).norm() + (d - rotations[u] * x).norm())
        / x.norm().max(Real::MIN_POSITIVE)
}

/// 1 / (1 + (strain / half)²): 1 unstrained, ½ at `half`.
fn cauchy_weight(strain: Real, half: Real) -> Real {
    let s = strain / half;
    1.0 / (1.0 + s * s)
}

/// Every edge's weight [`cauchy_weight`] of its [`edge_strain`] and
/// `bend_strain`, at least `least_edge_weight`, times its weight in `joints`
/// if given: the same for both directions of an edge, so the system stays
/// symmetric.
fn reweigh(
    edges: &Edges,
    offsets: &PerVertex<Vector3>,
    y: &[Vector3],
    rotations: &[Matrix3],
    params: &ConformParams,
    joints: Option<&[Real]>,
    weights: &mut PerVertex<Real>,
) {
    for v in 0..y.len() {
        for k in edges.start[v]..edges.start[v + 1] {
            let own = cauchy_weight(
                edge_strain(edges, offsets, y, rotations, v, k),
                params.bend_strain,
            )
            .max(params.least_edge_weight);
            weights.items[k] = own * joints.map_or(1.0, |j| j[k]);
        }
    }
}

/// One input vertex q pulling the mesh's point nearest to it, s = Σ_k w_k
/// y_{corners[k]}: the term is (s − q)ᵀ m (s − q), with m = n nᵀ + μ I for
/// the normal n of the mesh's triangle there.
struct Term {
    corners: [u32; 3],
    weights: [Real; 3],
    m: Matrix3,
}

/// Barycentric coordinates of `p`, a point of triangle `abc` (the centroid's
/// for a degenerate triangle).
fn barycentric(p: &Point3, a: &Point3, b: &Point3, c: &Point3) -> [Real; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d00, d01, d11, d20, d21) = (
        ab.dot(&ab),
        ab.dot(&ac),
        ac.dot(&ac),
        ap.dot(&ab),
        ap.dot(&ac),
    );
    let denominator = d00 * d11 - d01 * d01;
    if !(denominator.abs() > Real::MIN_POSITIVE) {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / denominator;
    let w = (d00 * d21 - d01 * d20) / denominator;
    [1.0 - v - w, v, w]
}

/// Whether the input is oriented the other way from the mesh: at most of
/// the input vertices `matches` pairs with a mesh triangle, the input's
/// triangles there (`fans`) face against the mesh's. An input that is
/// consistently inside-out (another exporter's winding) is then used turned
/// round instead of rejecting every match.
fn faces_away(
    matches: &[Option<(u32, [Real; 3])>],
    fans: &Fans,
    points: &[Point3],
    triangles: &[[u32; 3]],
) -> bool {
    let agreement: Real = matches
        .iter()
        .enumerate()
        .filter_map(|(j, m)| {
            let [a, b, c] = triangles[m.as_ref()?.0 as usize].map(|i| points[i as usize]);
            let normal = (b - a).cross(&(c - a)).try_normalize(0.0)?;
            Some(fans.of(j).iter().map(|n| n.dot(&normal)).sum::<Real>())
        })
        .sum();
    agreement < 0.0
}

/// Steps of [`refine_rotation`] per round.
const ROTATION_STEPS: usize = 3;

/// Moves `q` towards the rotation of A's polar decomposition (Müller et al.
/// 2016, "A robust method to extract the rotational part of deformations"):
/// from the last round's rotation a few steps suffice, far cheaper than an
/// SVD per vertex per round.
fn refine_rotation(a: &Matrix3, q: &mut UnitQuaternion) {
    let floor = 1e-9 * a.norm() + Real::MIN_POSITIVE;
    for _ in 0..ROTATION_STEPS {
        let r = q.to_rotation_matrix().into_inner();
        let (mut torque, mut alignment) = (Vector3::zeros(), 0.0);
        for k in 0..3 {
            torque += r.column(k).cross(&a.column(k));
            alignment += r.column(k).dot(&a.column(k));
        }
        let omega = torque / (alignment.abs() + floor);
        let angle = omega.norm();
        if !(angle > 1e-12) {
            break;
        }
        *q = UnitQuaternion::from_axis_angle(&Unit::new_unchecked(omega / angle), angle) * *q;
    }
}

/// Solves A y = rhs by conjugate gradients preconditioned with A's 3×3
/// diagonal blocks, from the `y` given, where
/// A y = (diagonal_v y_v − stiffness Σ_{u ~ v} w_uv y_u)_v + Σ_terms bᵀ ⊗ m (b y)
/// (w_uv = 1 without `weights`),
/// each term adding m (Σ_k w_k y_k) to its corners, weighted w_k.
/// A is symmetric positive definite: a graph Laplacian plus positive
/// semi-definite terms plus the anchor. Stops when the preconditioned
/// residual r·M⁻¹r, about Σ_v diagonal_v |step_v|², falls to what steps of
/// `tolerance` at every vertex would give.
#[allow(clippy::too_many_arguments)]
fn solve(
    edges: &Edges,
    weights: Option<&PerVertex<Real>>,
    stiffness: Real,
    diagonal: &[Real],
    terms: &[Term],
    rhs: &[Vector3],
    tolerance: Real,
    y: &mut [Vector3],
) {
    let n = y.len();
    let apply = |x: &[Vector3], out: &mut [Vector3]| {
        match weights {
            Some(weights) => {
                for v in 0..n {
                    let neighbours: Vector3 = edges
                        .of(v)
                        .iter()
                        .zip(weights.of(v))
                        .map(|(&u, &w)| x[u as usize] * w)
                        .sum();
                    out[v] = x[v] * diagonal[v] - neighbours * stiffness;
                }
            }
            None => {
                for v in 0..n {
                    let neighbours: Vector3 = edges.of(v).iter().map(|&u| x[u as usize]).sum();
                    out[v] = x[v] * diagonal[v] - neighbours * stiffness;
                }
            }
        }
        for t in terms {
            let s: Vector3 = (0..3)
                .map(|k| x[t.corners[k] as usize] * t.weights[k])
                .sum();
            let ms = t.m * s;
            for k in 0..3 {
                out[t.corners[k] as usize] += ms * t.weights[k];
            }
        }
    };
    let mut blocks: Vec<Matrix3> = (0..n).map(|v| Matrix3::identity() * diagonal[v]).collect();
    for t in terms {
        for k in 0..3 {
            blocks[t.corners[k] as usize] += t.m * (t.weights[k] * t.weights[k]);
        }
    }
    let inverse: Vec<Matrix3> = (0..n)
        .map(|v| {
            blocks[v]
                .try_inverse()
                .unwrap_or_else(|| Matrix3::identity() / diagonal[v])
        })
        .collect();
    let dot =
        |a: &[Vector3], b: &[Vector3]| -> Real { a.iter().zip(b).map(|(x, y)| x.dot(y)).sum() };
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

#[cfg(test)]
#[path = "conform_tests.rs"]
mod tests;
