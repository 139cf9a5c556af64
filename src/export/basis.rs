//! Morph bases: a [`DynamicMesh`]'s frames as frame 0 plus weighted morph
//! targets, either one target per frame (exact) or a compact basis built from
//! the principal components of the displacements (lossy, far smaller for long
//! sequences).
//!
//! The components come from a randomised range finder (Halko, Martinsson and
//! Tropp, 2011) over the displacement matrix, which is only ever read frame by
//! frame: the work grows linearly with the frame count, and the memory with
//! (vertices + frames) × the components sketched, which
//! [`BasisChoice::Auto`] caps (`AUTO_MAX_COMPONENTS`); no frames × frames
//! nor vertices × frames matrix is formed.
//!
//! Every target is a linear combination of the frames' displacements from
//! frame 0, `target_j = Σ_g mix_j(g) · (frame_g − frame_0)`, so anything known
//! per frame (positions, normals) goes through the same
//! `MorphBasis::combine`, and frame 0 is always the base mesh.

use crate::error::{Error, Result};
use crate::math::{Real, Vector3};
use crate::model::rng::SplitMix64;
use crate::model::DynamicMesh;
use crate::model::PositionFrames;
use crate::progress::{Progress, Stage};
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::ops::RangeInclusive;

/// Which morph basis encodes an animation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BasisChoice {
    /// One target per frame after the first: exact, F − 1 targets.
    PerFrame,
    /// The first K principal components (fewer when the motion has lower
    /// rank), K ≥ 1. Lossy; the error is measured and reported.
    Components(usize),
    /// [`PerFrame`](Self::PerFrame) up to [`AUTO_PER_FRAME_LIMIT`] frames;
    /// beyond, the fewest principal components (at most
    /// `AUTO_MAX_COMPONENTS`) whose largest vertex error stays within the
    /// tolerance, or per-frame targets again when no such basis needs fewer
    /// targets.
    Auto,
    /// At any length, the fewest principal components (at most
    /// `AUTO_MAX_COMPONENTS`) whose reconstruction error, over every vertex
    /// of every frame, is at most `mean` on average and `max` at most (scene
    /// units); per-frame targets when no such basis needs fewer targets (and,
    /// in a compressed file of up to [`AUTO_PER_FRAME_LIMIT`] frames, when
    /// one target per frame, as steps, takes fewer bytes).
    /// What `--basis auto` and `--compress` use, with the result's own fit to
    /// the input as the bounds: the basis adds no more error than the result
    /// already has.
    Bounded {
        /// Bound on the mean vertex error, in scene units.
        mean: Real,
        /// Bound on the largest vertex error, in scene units.
        max: Real,
    },
}

/// Longest sequence [`BasisChoice::Auto`] encodes with one target per frame
/// (viewers handle a few hundred targets; past that the compact basis pays).
pub const AUTO_PER_FRAME_LIMIT: usize = 256;

/// Components whose squared singular value is below this fraction of the
/// largest's are numerical noise (singular value under 1e-6 of the largest,
/// beneath f32 resolution of the exported data) and are never used.
const NEGLIGIBLE_SQUARED: Real = 1e-12;

/// Columns of the random sketch beyond the components wanted: they catch
/// what of the wanted subspace the first columns miss (the p of Halko et al.).
const OVERSAMPLING: usize = 10;

/// Power iterations of the range finder: each raises the singular values to a
/// higher power in the sketch, so components close in size to the first one
/// left out are still told apart.
const POWER_ITERATIONS: usize = 2;

/// Components a [`BasisChoice::Components`] of more than this sketches
/// first; every further round doubles it, up to the number asked for.
const COMPONENTS_FIRST: usize = 32;

/// Components [`BasisChoice::Auto`] sketches first; every further round
/// doubles it, up to [`AUTO_MAX_COMPONENTS`].
const AUTO_FIRST_COMPONENTS: usize = 8;

/// Most components [`BasisChoice::Auto`] sketches: a basis of more would
/// take more targets than the per-frame ones viewers are trusted with
/// ([`AUTO_PER_FRAME_LIMIT`]), and the sketch, 3V × components numbers held
/// several times over, would grow with the sequence (at 1,000 frames of a
/// motion no small basis fits, up to V × F). Past it, per-frame targets.
const AUTO_MAX_COMPONENTS: usize = AUTO_PER_FRAME_LIMIT / 2;

/// Seed of the Gaussian test matrix: the same frames give the same basis.
const SKETCH_SEED: u64 = 0x5eed_0022_ba51_5000;

/// Vertices processed together, so that one block of every frame stays in cache.
const VERTEX_CHUNK: usize = 256;

/// Frames whose per-frame vectors [`MorphBasis::combine`] holds at once.
const FRAME_BLOCK: usize = 16;

/// Checks what every animated export relies on: at least one frame and one
/// triangle, every frame with the base mesh's vertex count, finite
/// coordinates, triangle indices in range.
pub fn check_frames(mesh: &DynamicMesh) -> Result<()> {
    let n = mesh.base.positions.len();
    if mesh.frames.is_empty() {
        return Err(Error::InvalidInput("the dynamic mesh has no frames".into()));
    }
    if mesh.base.triangles.is_empty() {
        return Err(Error::InvalidInput(
            "the dynamic mesh has no triangles".into(),
        ));
    }
    if mesh
        .base
        .triangles
        .iter()
        .flatten()
        .any(|&i| i as usize >= n)
    {
        return Err(Error::InvalidInput(format!(
            "a triangle refers to a vertex beyond the {n} of the base mesh"
        )));
    }
    for (f, frame) in mesh.frames.iter().enumerate() {
        let frame = frame?;
        if frame.len() != n {
            return Err(Error::InvalidInput(format!(
                "frame {f} has {} vertices, the base mesh {n}",
                frame.len()
            )));
        }
        if let Some(v) = frame.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(Error::InvalidInput(format!(
                "vertex {v} of frame {f} has a non-finite coordinate"
            )));
        }
    }
    Ok(())
}

/// How far a reconstruction is from the frames, in scene units, over every
/// vertex of every frame (Euclidean distance per vertex).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BasisError {
    /// The largest distance.
    pub max: Real,
    /// The mean distance.
    pub mean: Real,
}

/// Frame f ≈ frame 0 + Σ_j `weights[f][j]` · target_j, with target_j =
/// Σ_(g, a) ∈ `mix[j]` a · (frame_g − frame_0).
#[derive(Clone, Debug, PartialEq)]
pub struct MorphBasis {
    /// Per target, the frames it combines (ascending, never frame 0) and their
    /// coefficients.
    pub mix: Vec<Vec<(usize, Real)>>,
    /// Per frame, one weight per target, all in [0, 1] and all zero at frame 0.
    /// [0, 1] because Blender clamps a shape key's value to its slider range,
    /// which its glTF importer leaves at [0, 1] for weights that start at 0.
    pub weights: Vec<Vec<Real>>,
    /// Number of principal components, `None` for one target per frame.
    pub components: Option<usize>,
    /// One name per target: `frame_0001`, … or `pc_0001_pos`, `pc_0001_neg`, ….
    pub names: Vec<String>,
}

impl MorphBasis {
    /// One target per frame after the first, keyed one-hot: exact.
    pub fn per_frame(frames: usize) -> Self {
        let targets = frames.saturating_sub(1);
        MorphBasis {
            mix: (1..frames).map(|g| vec![(g, 1.0)]).collect(),
            weights: (0..frames)
                .map(|f| {
                    (1..=targets)
                        .map(|j| if j == f { 1.0 } else { 0.0 })
                        .collect()
                })
                .collect(),
            components: None,
            names: (1..frames).map(|g| format!("frame_{g:04}")).collect(),
        }
    }

    /// Number of morph targets.
    pub fn targets(&self) -> usize {
        self.mix.len()
    }

    /// Target `k` alone from per-frame vectors, summed as [`combine`](Self::combine)
    /// sums it (the same f64 operations in the same order, so the same f32):
    /// reads only the frames the target mixes, when it is needed.
    pub(crate) fn target<V>(&self, k: usize, vertices: usize, vectors: V) -> Result<Vec<[f32; 3]>>
    where
        V: Fn(usize) -> Result<Vec<Vector3>>,
    {
        let mut sum = vec![Vector3::zeros(); vertices];
        for &(g, a) in &self.mix[k] {
            for (s, x) in sum.iter_mut().zip(&vectors(g)?) {
                *s += a * x;
            }
        }
        Ok(sum
            .iter()
            .map(|s| [s.x as f32, s.y as f32, s.z as f32])
            .collect())
    }

    /// Applies the mix to per-frame vectors: target j, vertex v =
    /// Σ_(g, a) ∈ `mix[j]` a · `vectors(g)[v]`, summed in f64 in frame order
    /// (deterministic) and rounded to f32, as the exported files store them.
    /// `vectors(g)` (g ≥ 1) must return `vertices` entries (or the error
    /// that stops the work); it is called once
    /// per frame, a few frames at a time in parallel. Reports the frames done
    /// under [`Stage::Export`] and stops between blocks when asked to.
    pub(crate) fn combine<V>(
        &self,
        frames: usize,
        vertices: usize,
        vectors: V,
        progress: Progress,
    ) -> Result<Vec<Vec<[f32; 3]>>>
    where
        V: Fn(usize) -> Result<Vec<Vector3>> + Sync,
    {
        // A target's f64 sum lives only while its frames are being visited, so
        // per-frame targets never hold more than one block in f64.
        let mut sums: Vec<Vec<Vector3>> = vec![Vec::new(); self.targets()];
        let mut out: Vec<Vec<[f32; 3]>> = vec![Vec::new(); self.targets()];
        for start in (1..frames).step_by(FRAME_BLOCK) {
            stop_requested(progress)?;
            progress.report(Stage::Export, start - 1, frames - 1);
            let block = start..(start + FRAME_BLOCK).min(frames);
            let vecs: Vec<Vec<Vector3>> = block
                .clone()
                .into_par_iter()
                .map(&vectors)
                .collect::<Result<_>>()?;
            sums.par_iter_mut()
                .zip(out.par_iter_mut())
                .zip(&self.mix)
                .for_each(|((sum, out), mix)| {
                    let first = mix.partition_point(|&(g, _)| g < block.start);
                    let entries = mix[first..].iter().take_while(|&&(g, _)| g < block.end);
                    for &(g, a) in entries {
                        if sum.is_empty() {
                            *sum = vec![Vector3::zeros(); vertices];
                        }
                        for (s, x) in sum.iter_mut().zip(&vecs[g - block.start]) {
                            *s += a * x;
                        }
                    }
                    if mix.last().is_some_and(|&(g, _)| g < block.end) && !sum.is_empty() {
                        *out = sum
                            .iter()
                            .map(|s| [s.x as f32, s.y as f32, s.z as f32])
                            .collect();
                        *sum = Vec::new();
                    }
                });
        }
        Ok(out)
    }
}

/// Picks the basis `choice` asks for. `tolerance` (scene units) bounds the
/// largest vertex error for [`BasisChoice::Auto`]. Returns the basis and its
/// reconstruction error (zero for per-frame targets). Reports its passes over
/// the frames under [`Stage::Export`] and returns [`Error::Interrupted`] when
/// `progress` asks it to stop.
pub fn choose(
    frames: &PositionFrames,
    choice: BasisChoice,
    tolerance: Real,
    progress: Progress,
) -> Result<(MorphBasis, BasisError)> {
    choose_with_trials(frames, choice, tolerance, progress).map(|(b, e, _)| (b, e))
}

/// A compact basis [`choose`] measured on the way to its choice.
#[derive(Clone, Debug)]
pub struct BasisTrial {
    /// The basis measured.
    pub basis: MorphBasis,
    /// Its reconstruction error.
    pub error: BasisError,
}

/// Component counts whose bases [`choose_with_trials`] returns when it
/// measured them (with the one chosen): a rate-distortion table's rows.
const TRIAL_COMPONENTS: [usize; 14] = [1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128];

/// [`choose`], and for [`BasisChoice::Auto`] and [`BasisChoice::Bounded`]
/// the compact bases it measured (of 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, … components and
/// the chosen count, fewer targets than one per frame), by increasing size.
pub fn choose_with_trials(
    frames: &PositionFrames,
    choice: BasisChoice,
    tolerance: Real,
    progress: Progress,
) -> Result<(MorphBasis, BasisError, Vec<BasisTrial>)> {
    let exact = || (MorphBasis::per_frame(frames.len()), BasisError::default());
    let untried = |(b, e): (MorphBasis, BasisError)| (b, e, Vec::new());
    let mut passes = Passes { progress, done: 0 };
    match choice {
        BasisChoice::PerFrame => Ok(untried(exact())),
        BasisChoice::Components(0) => Err(Error::InvalidParameter(
            "a compact basis needs at least one component".into(),
        )),
        BasisChoice::Components(k) => {
            // A sketch costs passes over the frames as wide as it is, so a
            // K far above the motion's rank (`--basis 1000` on a rank-30
            // take) would cost what K does: sketch a few first, and double
            // until the sketch shows the rank or reaches K.
            let mut wanted = k.min(COMPONENTS_FIRST);
            let pca = loop {
                let pca = Pca::new(frames, wanted.saturating_add(OVERSAMPLING), &mut passes)?;
                if wanted >= k || pca.rank().is_some() {
                    break pca;
                }
                wanted = wanted.saturating_mul(2).min(k);
            };
            let k = k.min(pca.usable());
            let basis = pca.basis(k);
            // Never more targets than one per frame, which are exact.
            if basis.targets() >= frames.len().saturating_sub(1) {
                log::info!(
                    "{k} components take {} targets, no fewer than one per frame: per-frame targets instead",
                    basis.targets()
                );
                passes.finish();
                return Ok(untried(exact()));
            }
            let error = pca.errors(frames, k..=k, &mut passes)?[0];
            passes.finish();
            Ok((basis, error, Vec::new()))
        }
        BasisChoice::Auto if frames.len() <= AUTO_PER_FRAME_LIMIT => Ok(untried(exact())),
        // One target per frame is the fewest there can be.
        BasisChoice::Bounded { .. } if frames.len() <= 2 => Ok(untried(exact())),
        BasisChoice::Auto | BasisChoice::Bounded { .. } => {
            // Auto bounds the largest error by `tolerance`; Bounded its own.
            let (max, mean) = match choice {
                BasisChoice::Bounded { mean, max } => (max, Some(mean)),
                _ => (tolerance, None),
            };
            let within = |e: &BasisError| e.max <= max && mean.is_none_or(|m| e.mean <= m);
            let moving = frames.len() - 1;
            let mut wanted = AUTO_FIRST_COMPONENTS;
            let choice = loop {
                let pca = Pca::new(frames, wanted + OVERSAMPLING, &mut passes)?;
                // Past F − 2 components per-frame targets are no more, past
                // `sufficient` the error is within tolerance for certain, past
                // the rank nothing is left to add.
                let mut limit = moving.saturating_sub(1);
                if let Some(k) = pca.sufficient(max.min(mean.unwrap_or(max))) {
                    limit = limit.min(k);
                }
                if let Some(rank) = pca.rank() {
                    limit = limit.min(rank);
                }
                let end = limit.min(pca.components.len()).min(AUTO_MAX_COMPONENTS);
                // The largest error need not fall monotonically with k, so
                // every k is measured (one pass, whatever the range).
                let errors = pca.errors(frames, 0..=end, &mut passes)?;
                let chosen = errors.iter().position(within);
                let trials = || -> Vec<BasisTrial> {
                    (1..=end)
                        .filter(|k| TRIAL_COMPONENTS.contains(k) || Some(*k) == chosen)
                        .map(|k| BasisTrial {
                            basis: pca.basis(k),
                            error: errors[k],
                        })
                        .filter(|t| t.basis.targets() < moving)
                        .collect()
                };
                if let Some(k) = chosen {
                    let basis = pca.basis(k);
                    let (b, e) = if basis.targets() < moving {
                        (basis, errors[k])
                    } else {
                        exact()
                    };
                    break (b, e, trials());
                }
                // Nothing within tolerance up to the limit, or more components
                // would need as many targets as the frames, or than Auto
                // sketches: per-frame targets.
                if end == limit
                    || pca.basis(end).targets() >= moving
                    || wanted >= AUTO_MAX_COMPONENTS
                {
                    let (b, e) = exact();
                    break (b, e, trials());
                }
                wanted = (wanted * 2).min(AUTO_MAX_COMPONENTS);
            };
            passes.finish();
            Ok(choice)
        }
    }
}

/// Returns [`Error::Interrupted`] when the caller asked the work to stop.
fn stop_requested(progress: Progress) -> Result<()> {
    if progress.cancelled() {
        return Err(Error::Interrupted { saved: None });
    }
    Ok(())
}

/// Counts the passes over the frames for progress reports, and checks for a
/// stop request before each.
struct Passes<'a> {
    progress: Progress<'a>,
    done: usize,
}

impl Passes<'_> {
    /// Before a pass, with `left` passes (this one included) planned so far.
    fn start(&mut self, left: usize) -> Result<()> {
        stop_requested(self.progress)?;
        self.progress
            .report(Stage::Export, self.done, self.done + left);
        self.done += 1;
        Ok(())
    }

    fn finish(&self) {
        self.progress.report(Stage::Export, self.done, self.done);
    }
}

/// The leading principal components of the displacements from frame 0. With A
/// the 3V × (F − 1) matrix of displacements (one column per frame after the
/// first) and A ≈ Σ_k σ_k v_k u_kᵀ its truncated SVD, component k's target is
/// A u_k and frame f's coefficient u_k(f); the first k components reconstruct
/// A as A U_k U_kᵀ, its projection onto their span.
///
/// The SVD comes from a sketch: Y = A Ω for a Gaussian Ω of `width` columns,
/// sharpened by power iterations (Y = A Aᵀ Y, re-orthonormalised each time);
/// with Q an orthonormal basis of Y, the small SVD of Qᵀ A gives the u_k.
/// Every product with A is a pass over the frames in vertex blocks, summed in
/// a fixed order, and the small factorisations are sequential, so the result
/// does not depend on the thread count.
struct Pca {
    /// Column u_k per component (entry g − 1 for frame g), unit length, by
    /// decreasing singular value; the largest-magnitude entry (the first of
    /// equals) is positive, as scikit-learn's `svd_flip` does, so the result
    /// does not depend on the solver's signs.
    components: Vec<Vec<Real>>,
    /// σ_k² of the sketch, decreasing.
    squared: Vec<Real>,
    /// ‖A‖², the squared Frobenius norm of all displacements.
    total: Real,
    /// Whether the sketch has as many columns as A can have rank
    /// (min(3V, F − 1)), so that the components span everything.
    complete: bool,
    frames: usize,
}

impl Pca {
    /// Sketches `width` components (fewer when A is smaller); `passes` counts
    /// its passes over the frames and one error pass after them.
    fn new(frames: &PositionFrames, width: usize, passes: &mut Passes) -> Result<Self> {
        let moving = frames.len().saturating_sub(1);
        let rows = 3 * if frames.is_empty() {
            0
        } else {
            frames.get(0)?.len()
        };
        let width = width.min(moving).min(rows);
        let mut pca = Pca {
            components: Vec::new(),
            squared: Vec::new(),
            total: 0.0,
            complete: width == moving.min(rows),
            frames: frames.len(),
        };
        if width == 0 {
            return Ok(pca);
        }
        // One more than the passes planned: the sketch's and the error pass after.
        let mut left = 2 * POWER_ITERATIONS + 4;
        let mut pass = |passes: &mut Passes| {
            left -= 1;
            passes.start(left)
        };
        pass(passes)?;
        pca.total = squared_norm(frames)?;
        let mut q = orthonormal(
            apply(frames, &gaussian(moving, width), width, passes.progress)?,
            rows,
            width,
        );
        for _ in 0..POWER_ITERATIONS {
            pass(passes)?;
            let z = orthonormal(
                apply_transposed(frames, &q, width, passes.progress)?,
                moving,
                width,
            );
            pass(passes)?;
            q = orthonormal(apply(frames, &z, width, passes.progress)?, rows, width);
        }
        pass(passes)?;
        // (Qᵀ A)ᵀ, F − 1 rows: its left singular vectors are the u_k.
        let projected = apply_transposed(frames, &q, width, passes.progress)?;
        let svd = DMatrix::from_row_slice(moving, width, &projected).svd(true, false);
        let u = svd
            .u
            .as_ref()
            .expect("left singular vectors were asked for");
        let mut order: Vec<usize> = (0..width).collect();
        order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
        pca.components = order
            .iter()
            .map(|&i| {
                let mut u: Vec<Real> = u.column(i).iter().copied().collect();
                let pivot = (0..u.len()).fold(
                    0,
                    |best, r| if u[r].abs() > u[best].abs() { r } else { best },
                );
                if u[pivot] < 0.0 {
                    u.iter_mut().for_each(|x| *x = -*x);
                }
                u
            })
            .collect();
        pca.squared = order
            .iter()
            .map(|&i| svd.singular_values[i].powi(2))
            .collect();
        Ok(pca)
    }

    /// Number of components that carry motion (see [`NEGLIGIBLE_SQUARED`]).
    fn usable(&self) -> usize {
        let largest = self.squared.first().copied().unwrap_or(0.0);
        self.squared
            .iter()
            .take_while(|&&s| s > 0.0 && s > NEGLIGIBLE_SQUARED * largest)
            .count()
    }

    /// The numerical rank of A when the sketch reveals it: it is complete, or
    /// its last components are noise.
    fn rank(&self) -> Option<usize> {
        let usable = self.usable();
        (self.complete || usable < self.components.len()).then_some(usable)
    }

    /// Fewest components whose residual's Frobenius norm is within
    /// `tolerance`, if the sketched ones include such a count. The residual
    /// is bounded by √(‖A‖² − Σ_(j < k) σ_j²), as the sketch's σ_j are at most
    /// what its components capture of A; it bounds every single vertex's error,
    /// so this many components certainly suffice.
    fn sufficient(&self, tolerance: Real) -> Option<usize> {
        let mut tail = self.total;
        for k in 0..=self.squared.len() {
            if tail.max(0.0).sqrt() <= tolerance {
                return Some(k);
            }
            tail -= self.squared.get(k).copied().unwrap_or(0.0);
        }
        None
    }

    /// The reconstruction error with the first k components, for every k in
    /// `ks` (k ≤ number of components). Each vertex's trajectory over the
    /// frames is projected onto the components (x − U_k U_kᵀ x), so this costs
    /// one pass over the frames and never stores the residual.
    fn errors(
        &self,
        frames: &PositionFrames,
        ks: RangeInclusive<usize>,
        passes: &mut Passes,
    ) -> Result<Vec<BasisError>> {
        let (k0, k1) = (*ks.start(), *ks.end());
        assert!(
            k0 <= k1 && k1 <= self.components.len(),
            "component range {k0}..={k1} beyond {}",
            self.components.len()
        );
        passes.start(1)?;
        let progress = passes.progress;
        let moving = self.frames - 1;
        let vertices = frames.get(0)?.len();
        let u = &self.components;
        let starts: Vec<usize> = (0..vertices).step_by(VERTEX_CHUNK).collect();
        // Per chunk and k: (largest error, sum of errors).
        let chunks: Vec<Vec<(Real, Real)>> = starts
            .par_iter()
            .map(|&start| {
                stop_requested(progress)?;
                let mut stats = vec![(0.0, 0.0); k1 - k0 + 1];
                let mut y = vec![Vector3::zeros(); k1];
                let mut e = vec![Vector3::zeros(); moving];
                // One vertex's displacements over the frames, contiguous, as
                // every component goes over them.
                let mut x = vec![Vector3::zeros(); moving];
                let end = (start + VERTEX_CHUNK).min(vertices);
                let block = (0..frames.len())
                    .map(|f| frames.rows(f, start..end))
                    .collect::<Result<Vec<_>>>()?;
                for v in 0..end - start {
                    for (x, frame) in x.iter_mut().zip(&block[1..]) {
                        *x = frame[v] - block[0][v];
                    }
                    for (yk, uk) in y.iter_mut().zip(u) {
                        *yk = uk.iter().zip(&x).map(|(&w, x)| w * x).sum();
                    }
                    for (r, er) in e.iter_mut().enumerate() {
                        *er = x[r] - (0..k0).map(|k| u[k][r] * y[k]).sum::<Vector3>();
                    }
                    for (k, s) in (k0..=k1).zip(&mut stats) {
                        if k > k0 {
                            e.iter_mut()
                                .zip(&u[k - 1])
                                .for_each(|(er, &w)| *er -= w * y[k - 1]);
                        }
                        for d in e.iter().map(|er| er.norm()) {
                            s.0 = Real::max(s.0, d);
                            s.1 += d;
                        }
                    }
                }
                Ok(stats)
            })
            .collect::<Result<_>>()?;
        let count = (self.frames * vertices) as Real;
        Ok((0..=k1 - k0)
            .map(|j| BasisError {
                max: chunks.iter().map(|c| c[j].0).fold(0.0, Real::max),
                mean: if count > 0.0 {
                    chunks.iter().map(|c| c[j].1).sum::<Real>() / count
                } else {
                    0.0
                },
            })
            .collect())
    }

    /// The basis of the first `k` components. Each component's coefficient
    /// u_k(f) is split into its positive and negative parts, one target each
    /// (the second only when some coefficient is negative), scaled so the
    /// weights span [0, 1]; their sum interpolates exactly like the signed
    /// coefficient would, LINEAR or not.
    fn basis(&self, k: usize) -> MorphBasis {
        let mut mix = Vec::new();
        let mut names = Vec::new();
        // Weights per target over frames 0..F.
        let mut columns: Vec<Vec<Real>> = Vec::new();
        for (c, u) in self.components[..k].iter().enumerate() {
            let hi = u.iter().copied().fold(0.0, Real::max);
            let lo = u.iter().copied().fold(0.0, Real::min);
            for (scale, sign, part) in [(hi, 1.0, "pos"), (lo, -1.0, "neg")] {
                if scale == 0.0 {
                    continue;
                }
                mix.push(
                    u.iter()
                        .enumerate()
                        .filter(|(_, &x)| x != 0.0)
                        .map(|(r, &x)| (r + 1, scale * x))
                        .collect(),
                );
                names.push(format!("pc_{:04}_{part}", c + 1));
                columns.push(
                    std::iter::once(0.0)
                        .chain(u.iter().map(|&x| (sign * x).max(0.0) / (sign * scale)))
                        .collect(),
                );
            }
        }
        MorphBasis {
            mix,
            weights: (0..self.frames)
                .map(|f| columns.iter().map(|w| w[f]).collect())
                .collect(),
            components: Some(k),
            names,
        }
    }
}

/// ‖A‖², summed per vertex block and then over the blocks in order.
fn squared_norm(frames: &PositionFrames) -> Result<Real> {
    let vertices = frames.get(0)?.len();
    let starts: Vec<usize> = (0..vertices).step_by(VERTEX_CHUNK).collect();
    let parts: Vec<Real> = starts
        .par_iter()
        .map(|&start| {
            let range = start..(start + VERTEX_CHUNK).min(vertices);
            let base = frames.rows(0, range.clone())?;
            let mut sum = 0.0;
            for f in 1..frames.len() {
                sum += frames
                    .rows(f, range.clone())?
                    .iter()
                    .zip(base.iter())
                    .map(|(p, p0)| (p - p0).norm_squared())
                    .sum::<Real>();
            }
            Ok(sum)
        })
        .collect::<Result<_>>()?;
    Ok(parts.iter().sum())
}

/// A (F − 1) × `width` matrix of independent standard normal entries,
/// row-major, from the fixed seed (Box–Muller).
fn gaussian(rows: usize, width: usize) -> Vec<Real> {
    let mut rng = SplitMix64::new(SKETCH_SEED);
    let mut out = Vec::with_capacity(rows * width + 1);
    while out.len() < rows * width {
        let radius = (-2.0 * (1.0 - rng.unit()).ln()).sqrt();
        let angle = std::f64::consts::TAU * rng.unit();
        out.extend([radius * angle.cos(), radius * angle.sin()]);
    }
    out.truncate(rows * width);
    out
}

/// A X, 3V × `width`, for X with one row per frame after the first (both
/// row-major, A's rows vertex-major: 3v + axis). Parallel over vertex blocks,
/// each writing its own rows, summed over the frames in order.
fn apply(
    frames: &PositionFrames,
    x: &[Real],
    width: usize,
    progress: Progress,
) -> Result<Vec<Real>> {
    let vertices = frames.get(0)?.len();
    let mut y = vec![0.0; 3 * vertices * width];
    y.par_chunks_mut(3 * VERTEX_CHUNK * width)
        .enumerate()
        .try_for_each(|(c, out)| {
            stop_requested(progress)?;
            let start = c * VERTEX_CHUNK;
            let range = start..start + out.len() / (3 * width);
            let base = frames.rows(0, range.clone())?;
            for (f, xg) in (1..frames.len()).zip(x.chunks_exact(width)) {
                let frame = frames.rows(f, range.clone())?;
                for ((p, p0), rows) in frame
                    .iter()
                    .zip(base.iter())
                    .zip(out.chunks_exact_mut(3 * width))
                {
                    let d = p - p0;
                    for (a, row) in rows.chunks_exact_mut(width).enumerate() {
                        axpy(d[a], xg, row);
                    }
                }
            }
            Ok(())
        })?;
    Ok(y)
}

/// Aᵀ Q, (F − 1) × `width`, for Q with 3V rows (layouts as in [`apply`]).
/// Vertex blocks in order, each added to every frame's row in parallel over
/// the frames: every entry is summed in the same order whatever the threads.
fn apply_transposed(
    frames: &PositionFrames,
    q: &[Real],
    width: usize,
    progress: Progress,
) -> Result<Vec<Real>> {
    let vertices = frames.get(0)?.len();
    let mut z = vec![0.0; (frames.len() - 1) * width];
    for start in (0..vertices).step_by(VERTEX_CHUNK) {
        stop_requested(progress)?;
        let end = (start + VERTEX_CHUNK).min(vertices);
        let base = frames.rows(0, start..end)?;
        let block = &q[3 * start * width..3 * end * width];
        z.par_chunks_mut(width)
            .enumerate()
            .try_for_each(|(g, zg)| {
                let frame = frames.rows(g + 1, start..end)?;
                for ((p, p0), rows) in frame
                    .iter()
                    .zip(base.iter())
                    .zip(block.chunks_exact(3 * width))
                {
                    let d = p - p0;
                    for (a, row) in rows.chunks_exact(width).enumerate() {
                        axpy(d[a], row, zg);
                    }
                }
                Ok::<_, Error>(())
            })?;
    }
    Ok(z)
}

/// An orthonormal basis of the columns of a row-major `rows` × `width`
/// matrix (rows ≥ width), row-major: Householder QR, whose Q stays orthonormal
/// when the columns are dependent.
fn orthonormal(m: Vec<Real>, rows: usize, width: usize) -> Vec<Real> {
    // Each copy is as large as the sketch: one dropped before the next is made.
    let a = DMatrix::from_row_slice(rows, width, &m);
    drop(m);
    let q = a.qr().q();
    // Column-major storage of Qᵀ is Q row-major.
    q.transpose().data.into()
}

/// y += a x.
fn axpy(a: Real, x: &[Real], y: &mut [Real]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Point3, Rotation3};

    /// The vertices of a torus (radii 1 and 0.3, 24 × 12 of them).
    fn torus() -> Vec<Point3> {
        let tau = 2.0 * std::f64::consts::PI;
        (0..24)
            .flat_map(|i| (0..12).map(move |j| (tau * i as Real / 24.0, tau * j as Real / 12.0)))
            .map(|(u, v)| {
                let r = 1.0 + 0.3 * v.cos();
                Point3::new(r * u.cos(), r * u.sin(), 0.3 * v.sin())
            })
            .collect()
    }

    /// A torus turned, bent and crossed by travelling waves and a chirp: a
    /// spectrum that decays without a sharp cut, like a capture's.
    fn sequence(frames: usize) -> Vec<Vec<Point3>> {
        let base = torus();
        let motion = |f: usize, p: &Point3| {
            let t = f as Real;
            let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.6 * (0.013 * t).sin());
            let wave = 0.05 * (3.0 * p.x - 0.11 * t).sin() + 0.03 * (5.0 * p.y + 0.07 * t).cos();
            let bend = 0.1 * (0.021 * t).sin() * p.x * p.x;
            let chirp = 0.004 * (p.y * (1.0 + 0.002 * t) * 4.0 + 0.05 * t).sin();
            turn * p + Vector3::new(chirp, 0.0, wave + bend)
        };
        (0..frames)
            .map(|f| base.iter().map(|p| motion(f, p)).collect())
            .collect()
    }

    /// The exact decomposition, as the Gram matrix's eigenvectors gave it
    /// before the sketch: the thin SVD of the whole displacement matrix.
    fn exact(frames: &[Vec<Point3>]) -> Pca {
        let moving = frames.len() - 1;
        let rows = 3 * frames[0].len();
        let mut a = vec![0.0; moving * rows];
        gather(frames, 0, frames[0].len(), &mut a);
        let svd = DMatrix::from_row_slice(moving, rows, &a).svd(true, false);
        let u = svd.u.unwrap();
        let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
        order.sort_by(|&x, &y| svd.singular_values[y].total_cmp(&svd.singular_values[x]));
        Pca {
            components: order
                .iter()
                .map(|&i| u.column(i).iter().copied().collect())
                .collect(),
            squared: order
                .iter()
                .map(|&i| svd.singular_values[i].powi(2))
                .collect(),
            total: a.iter().map(|x| x * x).sum(),
            complete: true,
            frames: frames.len(),
        }
    }

    /// Displacements from frame 0 of vertices `start..start + n` in frames 1..F,
    /// frame-major: `out[(g − 1)·3n + 3i + axis]`.
    fn gather(frames: &[Vec<Point3>], start: usize, n: usize, out: &mut [Real]) {
        let base = &frames[0][start..start + n];
        for (row, frame) in out.chunks_exact_mut(3 * n).zip(&frames[1..]) {
            for ((d, p), p0) in row
                .chunks_exact_mut(3)
                .zip(&frame[start..start + n])
                .zip(base)
            {
                d.copy_from_slice((p - p0).as_slice());
            }
        }
    }

    fn no_passes() -> Passes<'static> {
        Passes {
            progress: Progress::none(),
            done: 0,
        }
    }

    /// Within 1 % of the exact error, or 1e-6 of the bounding-box diagonal
    /// where the error itself is that small.
    fn close(sketched: Real, exact: Real, diagonal: Real) -> bool {
        (sketched - exact).abs() <= (0.01 * exact).max(1e-6 * diagonal)
    }

    #[test]
    fn sketched_components_reconstruct_as_well_as_the_exact_decomposition() {
        for count in [150, 400] {
            let raw = sequence(count);
            let diagonal = crate::model::mesh::Aabb::from_points(raw.iter().flatten()).diagonal();
            let reference = exact(&raw);
            let frames = PositionFrames::from(raw);
            let all = reference.errors(&frames, 0..=24, &mut no_passes()).unwrap();
            for k in [1, 2, 3, 5, 8, 12, 16, 24] {
                let pca = Pca::new(&frames, k + OVERSAMPLING, &mut no_passes()).unwrap();
                let got = pca.errors(&frames, k..=k, &mut no_passes()).unwrap()[0];
                let want = all[k];
                assert!(
                    close(got.max, want.max, diagonal),
                    "{count} frames, {k} components: max {} vs exact {}",
                    got.max,
                    want.max
                );
                assert!(
                    close(got.mean, want.mean, diagonal),
                    "{count} frames, {k} components: mean {} vs exact {}",
                    got.mean,
                    want.mean
                );
            }
            // Auto: the exact rule (fewest components within tolerance) gives
            // the same count, within tolerance.
            let tolerance = 1e-3 * diagonal;
            let (basis, error) =
                choose(&frames, BasisChoice::Auto, tolerance, Progress::none()).unwrap();
            if count > AUTO_PER_FRAME_LIMIT {
                let want = all
                    .iter()
                    .position(|e| e.max <= tolerance)
                    .expect("within 24 components");
                assert_eq!(basis.components, Some(want), "{count} frames");
                assert!(
                    error.max <= tolerance && close(error.max, all[want].max, diagonal),
                    "{error:?} vs {:?}",
                    all[want]
                );
            }
            // Bounded, at any length: the fewest components within both
            // bounds; a mean bound halfway between 5 and 6 components' gives 6.
            let mean = 0.5 * (all[5].mean + all[6].mean);
            let max = 2.0 * all[6].max;
            let (basis, error) = choose(
                &frames,
                BasisChoice::Bounded { mean, max },
                0.0,
                Progress::none(),
            )
            .unwrap();
            assert_eq!(basis.components, Some(6), "{count} frames");
            assert!(error.mean <= mean && error.max <= max, "{error:?}");
            // Nothing but the exact frames is within a zero bound.
            let (basis, _) = choose(
                &frames,
                BasisChoice::Bounded {
                    mean: 0.0,
                    max: 0.0,
                },
                0.0,
                Progress::none(),
            )
            .unwrap();
            assert_eq!(basis, MorphBasis::per_frame(count));
        }
    }

    #[test]
    fn the_sketch_finds_the_rank_of_low_rank_motion() {
        // A translation back and forth (rank 1) plus a turn about z (rank 2
        // more): three components, the rest noise.
        let base = torus();
        let frames: Vec<Vec<Point3>> = (0..300)
            .map(|f| {
                let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.01 * f as Real);
                base.iter()
                    .map(|p| turn * p + Vector3::new(1.0, 2.0, -0.5) * (0.7 * f as Real).sin())
                    .collect()
            })
            .collect();
        let frames = PositionFrames::from(frames);
        let pca = Pca::new(&frames, 8 + OVERSAMPLING, &mut no_passes()).unwrap();
        assert_eq!(pca.rank(), Some(3));
        let error = pca.errors(&frames, 3..=3, &mut no_passes()).unwrap()[0];
        assert!(error.max < 1e-9, "{error:?}");
        assert_eq!(pca.sufficient(1e-6), Some(3));
    }

    /// Frames 0..300 of the torus moved by `rank` fixed random fields, each
    /// weighted per frame by a random coefficient: motion of exactly that rank.
    fn random_motion(rank: usize) -> PositionFrames {
        let base = torus();
        let mut rng = SplitMix64::new(rank as u64);
        let mut unit = move || 2.0 * rng.unit() - 1.0;
        let fields: Vec<Vec<Vector3>> = (0..rank)
            .map(|_| {
                base.iter()
                    .map(|_| Vector3::new(unit(), unit(), unit()))
                    .collect()
            })
            .collect();
        let frames: Vec<Vec<Point3>> = (0..300)
            .map(|f| {
                let weights: Vec<Real> = (0..rank)
                    .map(|_| if f == 0 { 0.0 } else { 0.01 * unit() })
                    .collect();
                base.iter()
                    .enumerate()
                    .map(|(v, p)| {
                        p + fields
                            .iter()
                            .zip(&weights)
                            .map(|(d, w)| *w * d[v])
                            .sum::<Vector3>()
                    })
                    .collect()
            })
            .collect();
        PositionFrames::from(frames)
    }

    #[test]
    fn a_k_far_above_the_rank_gives_the_rank_and_never_more_targets_than_frames() {
        // Rank 5 asked for 250 components: the five, exact, from a sketch
        // that stopped at its first round (the rank shows within it).
        let frames = random_motion(5);
        let (basis, error) = choose(
            &frames,
            BasisChoice::Components(250),
            1e-6,
            Progress::none(),
        )
        .unwrap();
        assert_eq!(basis.components, Some(5));
        assert!(error.max < 1e-9, "{error:?}");
        let (first, _) = choose(
            &frames,
            BasisChoice::Components(COMPONENTS_FIRST),
            1e-6,
            Progress::none(),
        )
        .unwrap();
        assert_eq!(
            basis, first,
            "the same sketch as asking for the first round's width"
        );
        // Rank 160 asked for 200: 160 components would take more targets
        // than one per frame (299), so one per frame, exact.
        let frames = random_motion(160);
        let (basis, error) = choose(
            &frames,
            BasisChoice::Components(200),
            1e-6,
            Progress::none(),
        )
        .unwrap();
        assert_eq!(basis, MorphBasis::per_frame(300));
        assert_eq!(error.max, 0.0);
    }

    #[test]
    fn auto_sketches_at_most_its_cap_and_falls_back_to_per_frame_targets() {
        // Rank within the cap: exactly that many components. Beyond it, where
        // a larger sketch would find a basis still smaller than per-frame
        // targets (2 × 140 < 299), per-frame targets, so the sketch, and the
        // memory it takes, stop growing with the sequence; also just beyond,
        // which the cap's oversampled columns would catch.
        let cap = AUTO_MAX_COMPONENTS;
        for (rank, components) in [
            (cap - 8, Some(cap - 8)),
            (cap, Some(cap)),
            (cap + 5, None),
            (cap + 12, None),
        ] {
            let frames = random_motion(rank);
            let (basis, error) =
                choose(&frames, BasisChoice::Auto, 1e-6, Progress::none()).unwrap();
            assert_eq!(basis.components, components, "rank {rank}");
            assert_eq!(
                basis.targets() >= 299,
                components.is_none(),
                "rank {rank}: {} targets",
                basis.targets()
            );
            assert!(error.max <= 1e-6, "rank {rank}: {error:?}");
        }
    }

    #[test]
    fn frames_in_a_file_give_the_basis_of_frames_in_memory_bit_for_bit() {
        let raw = sequence(300);
        let vertices = raw[0].len();
        let mut file = PositionFrames::new(vertices, raw.len(), 0).unwrap();
        for frame in &raw {
            file.push(frame.clone()).unwrap();
        }
        assert!(file.in_file());
        let memory = PositionFrames::from(raw);
        for choice in [BasisChoice::Auto, BasisChoice::Components(5)] {
            let a = choose(&memory, choice, 1e-3, Progress::none()).unwrap();
            let b = choose(&file, choice, 1e-3, Progress::none()).unwrap();
            assert_eq!(a, b, "{choice:?}");
        }
    }
}
