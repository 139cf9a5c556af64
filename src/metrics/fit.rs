//! How closely the dynamic mesh fits the input, frame by frame: exact
//! point-to-surface distances in both directions, summarised like the
//! fidelity of `../shared/tools/evaluate.py` (mean, 95th percentile and
//! maximum, relative to the bounding-box diagonal of the whole input).
//!
//! Where this differs from evaluate.py, by design:
//! - it measures from every vertex (weighted by one third of the area of its
//!   triangles, so a finely meshed region counts by its area, not its vertex
//!   count, as evaluate.py's area-uniform samples do) instead of 20 000
//!   random points per surface: deterministic, but blind to error inside a
//!   large triangle;
//! - distances are exact (nearest point on the nearest triangle); evaluate.py
//!   takes the nearest of ~200 000 surface samples and so reads slightly high,
//!   by up to about the samples' spacing (even for a frame identical to the
//!   input, where this reports 0);
//! - the maximum is over vertices, the 95th percentile is the weighted lower
//!   quantile (no interpolation between samples);
//! - it measures the mesh before export: a compact basis' reconstruction
//!   error and f32 rounding in the GLB are not included;
//! - figures are in percent of the diagonal, evaluate.py prints fractions.

use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::model::DynamicMesh;
use crate::model::{FrameSource, TriangleMesh};
use crate::progress::{Progress, Stage};
use crate::spatial::surface::SurfaceIndex;
use rayon::prelude::*;
use std::time::Instant;

/// Mean, 95th percentile and maximum of a set of distances.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DistanceSummary {
    /// The (weighted) mean distance.
    pub mean: Real,
    /// The smallest distance with at least 95 % of the weight at or below it.
    pub p95: Real,
    /// The largest distance.
    pub max: Real,
}

impl DistanceSummary {
    /// Summarises `(distance, weight)` samples: the weighted mean, the
    /// smallest distance with at least 95 % of the weight at or below it,
    /// and the largest distance. Equal weights when they sum to zero;
    /// all zero when there are no samples.
    pub fn of_weighted(samples: &[(Real, Real)]) -> Self {
        if samples.is_empty() {
            return DistanceSummary::default();
        }
        let weighted = total_weight(samples);
        let weight = |s: &(Real, Real)| if weighted.is_some() { s.1 } else { 1.0 };
        let total = weighted.unwrap_or(samples.len() as Real);
        let mean = samples.iter().map(|s| s.0 * weight(s)).sum::<Real>() / total;
        let mut sorted = samples.to_vec();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut below = 0.0;
        let mut p95 = sorted[sorted.len() - 1].0;
        for s in &sorted {
            below += weight(s);
            if below >= 0.95 * total {
                p95 = s.0;
                break;
            }
        }
        DistanceSummary {
            mean,
            p95,
            max: sorted[sorted.len() - 1].0,
        }
    }
}

/// The samples' total weight, None when it is not a positive finite number:
/// the samples then count equally.
fn total_weight(samples: &[(Real, Real)]) -> Option<Real> {
    let total: Real = samples.iter().map(|s| s.1).sum();
    (total > 0.0 && total.is_finite()).then_some(total)
}

/// How closely one frame of the result fits the same frame of the input,
/// every figure in percent of the diagonal passed to [`surface_fit`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FrameFit {
    /// From the result's vertices to the input's surface: where the result
    /// strays from the input (a limb bent too far, a collapsed joint).
    pub result_to_input: DistanceSummary,
    /// From the input's vertices to the result's surface: input the result
    /// fails to cover (a part that stayed behind, detail frame 0 lacks).
    pub input_to_result: DistanceSummary,
    /// Both directions pooled, each with half the weight: evaluate.py's
    /// two-sided fidelity of this frame.
    pub two_sided: DistanceSummary,
    /// The largest connected region of the input's surface farther from
    /// the result than the threshold measured at: a part the result lost.
    pub far_input: FarRegion,
    /// The largest connected region of the result's surface farther from
    /// the input than that and outside the input's volume (when known): a
    /// part the result holds where the input has none. Inside the volume,
    /// such surface is where two parts touch in the input, whose surfaces
    /// merge there while the result keeps both, hidden inside.
    pub far_result: FarRegion,
    /// The same as `far_input` past the weaker distance
    /// ([`FarDistances::weak_input`]): evidence that carries a warning on
    /// from the frame next to this one, but starts none.
    pub weak_input: FarRegion,
    /// The same as `far_result` past [`FarDistances::weak_result`].
    pub weak_result: FarRegion,
    /// The same as `far_result` past [`FarDistances::lasting_result`]:
    /// evidence when it lasts for frames.
    pub lasting_result: FarRegion,
}

/// A connected region of one surface (vertices joined by its triangles'
/// edges) that lies far from the other surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct FarRegion {
    /// Its area (the area weights of its vertices), in percent of the
    /// surface's area.
    pub share: Real,
    /// Vertices in it.
    pub vertices: usize,
    /// The largest distance in it, in percent of the diagonal.
    pub farthest: Real,
}

/// A triangle surface borrowed from a mesh or a dynamic mesh's frame.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// Vertex positions.
    pub positions: &'a [Point3],
    /// Triangles, indices into `positions`.
    pub triangles: &'a [[u32; 3]],
}

impl<'a> From<&'a TriangleMesh> for Surface<'a> {
    fn from(m: &'a TriangleMesh) -> Self {
        Surface {
            positions: &m.positions,
            triangles: &m.triangles,
        }
    }
}

impl Surface<'_> {
    /// Each vertex's share of the area (a third of each of its triangles'),
    /// None for a vertex no triangle uses: it is not on the surface.
    fn vertex_weights(&self) -> Vec<Option<Real>> {
        let mut w = vec![None; self.positions.len()];
        for t in self.triangles {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let third = (b - a).cross(&(c - a)).norm() / 6.0;
            for &i in t {
                *w[i as usize].get_or_insert(0.0) += third;
            }
        }
        w
    }

    /// (distance to `to`, area weight) of every vertex on this surface
    /// (None off it), distances scaled by `scale`.
    fn distances_to(&self, to: &SurfaceIndex, scale: Real) -> Vec<Option<(Real, Real)>> {
        let weights = self.vertex_weights();
        weights
            .par_iter()
            .enumerate()
            .map(|(i, w)| w.map(|w| (scale * to.distance(&self.positions[i]), w)))
            .collect()
    }

    /// The largest connected region of the vertices whose distance in
    /// `distances` ([`Surface::distances_to`]) is above `threshold`, but
    /// for those `hidden` holds of: by area, the first found of equals.
    fn largest_far_region(
        &self,
        distances: &[Option<(Real, Real)>],
        threshold: Real,
        hidden: &(dyn Fn(&Point3) -> bool + Sync),
    ) -> FarRegion {
        let far_now: Vec<bool> = distances
            .par_iter()
            .enumerate()
            .map(|(i, d)| d.is_some_and(|(d, _)| d > threshold) && !hidden(&self.positions[i]))
            .collect();
        let far = |i: u32| far_now[i as usize];
        let mut parent: Vec<u32> = (0..distances.len() as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for t in self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if far(a) && far(b) {
                    let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
                    if ra != rb {
                        parent[ra.max(rb) as usize] = ra.min(rb);
                    }
                }
            }
        }
        let total: Real = distances.iter().flatten().map(|(_, w)| w).sum();
        let mut regions: std::collections::BTreeMap<u32, FarRegion> = Default::default();
        for i in 0..distances.len() as u32 {
            if let Some((d, w)) = distances[i as usize].filter(|_| far_now[i as usize]) {
                let r = regions.entry(root(&mut parent, i)).or_default();
                r.share += w;
                r.vertices += 1;
                r.farthest = r.farthest.max(d);
            }
        }
        let mut largest =
            regions.into_values().fold(
                FarRegion::default(),
                |a, b| if b.share > a.share { b } else { a },
            );
        largest.share *= if total > 0.0 { 100.0 / total } else { 0.0 };
        largest
    }
}

pub use crate::params::FarDistances;

/// Per vertex, (distance to the other surface, area weight); None off the surface.
type Distances = Vec<Option<(Real, Real)>>;

/// The result's vertices' distances to the input's surface and the input's
/// to the result's, in percent of `diagonal`.
fn distances_both_ways(result: Surface, input: Surface, diagonal: Real) -> (Distances, Distances) {
    let scale = 100.0 / diagonal;
    let (to_input, to_result) = rayon::join(
        || SurfaceIndex::new(input.positions, input.triangles),
        || SurfaceIndex::new(result.positions, result.triangles),
    );
    (
        result.distances_to(&to_input, scale),
        input.distances_to(&to_result, scale),
    )
}

/// Whether a point lies inside the input's volume, when known.
pub type InsideInput<'a> = &'a (dyn Fn(&Point3) -> bool + Sync);

/// The fit of `result` to `input` in one frame, in percent of `diagonal`
/// (the input sequence's bounding-box diagonal, > 0), with the largest
/// regions of either surface farther than `far` from the other, the
/// result's outside the input's volume (`inside`; None
/// counts every far point). Both surfaces need triangles. The result does
/// not depend on the thread count.
pub fn surface_fit(
    result: Surface,
    input: Surface,
    diagonal: Real,
    far: FarDistances,
    inside: Option<InsideInput>,
) -> FrameFit {
    let (forward_all, backward_all) = distances_both_ways(result, input, diagonal);
    let forward: Vec<(Real, Real)> = forward_all.iter().flatten().copied().collect();
    let backward: Vec<(Real, Real)> = backward_all.iter().flatten().copied().collect();
    let hidden = inside.unwrap_or(&|_| false);
    FrameFit {
        result_to_input: DistanceSummary::of_weighted(&forward),
        input_to_result: DistanceSummary::of_weighted(&backward),
        two_sided: DistanceSummary::of_weighted(&pool_halves(&forward, &backward)),
        far_input: input.largest_far_region(&backward_all, far.input, &|_| false),
        far_result: result.largest_far_region(&forward_all, far.result, hidden),
        weak_input: input.largest_far_region(&backward_all, far.weak_input, &|_| false),
        weak_result: result.largest_far_region(&forward_all, far.weak_result, hidden),
        lasting_result: result.largest_far_region(&forward_all, far.lasting_result, hidden),
    }
}

/// Whether a point lies inside frame `f`'s occupied voxels of `volume`.
pub fn inside_volume(
    volume: &crate::voxel::VoxelSequence,
    f: usize,
) -> impl Fn(&Point3) -> bool + Sync + '_ {
    let occupied = volume.frames[f].expand();
    move |p: &Point3| {
        volume
            .grid
            .voxel_at(p)
            .is_some_and(|v| occupied.contains(v as u32))
    }
}

/// The largest far regions of the input (first) and of the result (second)
/// at each of `thresholds` (percent of `diagonal`), as [`surface_fit`]
/// finds them at one: for choosing the threshold.
pub fn far_profile(
    result: Surface,
    input: Surface,
    diagonal: Real,
    thresholds: &[Real],
    inside: Option<InsideInput>,
) -> Vec<(FarRegion, FarRegion)> {
    let (forward, backward) = distances_both_ways(result, input, diagonal);
    thresholds
        .iter()
        .map(|&t| {
            (
                input.largest_far_region(&backward, t, &|_| false),
                result.largest_far_region(&forward, t, inside.unwrap_or(&|_| false)),
            )
        })
        .collect()
}

/// Both sample sets with their weights rescaled to sum to ½ each, as
/// evaluate.py draws as many samples from either surface.
fn pool_halves(a: &[(Real, Real)], b: &[(Real, Real)]) -> Vec<(Real, Real)> {
    let half = |s: &[(Real, Real)]| {
        let total = total_weight(s);
        let n = s.len() as Real;
        s.iter()
            .map(move |&(d, w)| (d, total.map_or(0.5 / n, |t| 0.5 * w / t)))
            .collect::<Vec<_>>()
    };
    let mut pooled = half(a);
    pooled.extend(half(b));
    pooled
}

/// The fit of every frame of a dynamic mesh to the input it was made from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SequenceFit {
    /// One per frame, in percent of `diagonal`.
    pub frames: Vec<FrameFit>,
    /// The length the figures are relative to: the diagonal of the bounding
    /// box of every input frame (`VoxelSequence::bounds`), as evaluate.py's.
    pub diagonal: Real,
    /// The distances past which a region counted as far.
    pub far: FarDistances,
    /// Wall-clock seconds spent re-reading the input and measuring.
    pub seconds: f64,
}

impl SequenceFit {
    /// evaluate.py's summary of the two-sided figures: the mean over frames
    /// of each frame's mean and of its 95th percentile, and the largest
    /// maximum of any frame.
    pub fn summary(&self) -> DistanceSummary {
        let n = self.frames.len().max(1) as Real;
        DistanceSummary {
            mean: self.frames.iter().map(|f| f.two_sided.mean).sum::<Real>() / n,
            p95: self.frames.iter().map(|f| f.two_sided.p95).sum::<Real>() / n,
            max: self
                .frames
                .iter()
                .map(|f| f.two_sided.max)
                .fold(0.0, Real::max),
        }
    }

    /// The frame with the largest two-sided mean (evaluate.py's worst frame);
    /// the first of equals.
    pub fn worst_frame(&self) -> usize {
        (0..self.frames.len()).fold(0, |w, f| {
            if self.frames[f].two_sided.mean > self.frames[w].two_sided.mean {
                f
            } else {
                w
            }
        })
    }
}

/// Measures every frame of `mesh` against the input frame it stands for,
/// reading frame f of `source` one frame at a time so memory holds at most
/// two input frames, the next one being read while the current one is
/// measured.
/// `diagonal` is what the figures are percentages of: the input's
/// bounding-box diagonal (`VoxelSequence::bounds.diagonal()`); `far` how
/// far a region must lie to count in [`FrameFit::far_input`] and
/// [`FrameFit::far_result`]; `volume`, when
/// given, the input voxelised (the result's far regions inside it are
/// not counted).
///
/// Reports `(Stage::Fit, frames measured, frames)` to `progress`.
pub fn fit_to_input(
    mesh: &DynamicMesh,
    source: &dyn FrameSource,
    diagonal: Real,
    far: FarDistances,
    volume: Option<&crate::voxel::VoxelSequence>,
    progress: Progress,
) -> Result<SequenceFit> {
    if mesh.frames.len() != source.len() {
        return Err(Error::InvalidInput(format!(
            "the dynamic mesh has {} frames but the input has {}",
            mesh.frames.len(),
            source.len()
        )));
    }
    if !(diagonal > 0.0 && diagonal.is_finite()) {
        return Err(Error::InvalidInput(format!(
            "cannot measure relative to a bounding-box diagonal of {diagonal}"
        )));
    }
    let start = Instant::now();
    let read = |f: usize| source.mesh(f);
    let total = source.len();
    progress.report(Stage::Fit, 0, total);
    let mut frames = Vec::with_capacity(total);
    let mut next = if total > 0 { Some(read(0)) } else { None };
    for f in 0..total {
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
        let input = next.take().expect("read ahead")?;
        let positions = mesh.frames.get(f)?;
        let result = Surface {
            positions: &positions,
            triangles: &mesh.base.triangles,
        };
        let inside = volume.map(|v| inside_volume(v, f));
        let inside = inside.as_ref().map(|i| i as InsideInput);
        let (fit, following) = rayon::join(
            || surface_fit(result, Surface::from(&input), diagonal, far, inside),
            || (f + 1 < total).then(|| read(f + 1)),
        );
        next = following;
        frames.push(fit);
        progress.report(Stage::Fit, f + 1, total);
    }
    Ok(SequenceFit {
        frames,
        diagonal,
        far,
        seconds: start.elapsed().as_secs_f64(),
    })
}
