//! Morph bases: a [`DynamicMesh`]'s frames as frame 0 plus weighted morph
//! targets, either one target per frame (exact) or a compact basis built from
//! the principal components of the displacements (lossy, far smaller for long
//! sequences).
//!
//! Every target is a linear combination of the frames' displacements from
//! frame 0, `target_j = Σ_g mix_j(g) · (frame_g − frame_0)`, so anything known
//! per frame (positions, normals) goes through the same
//! [`MorphBasis::combine`], and frame 0 is always the base mesh.

use crate::deform::DynamicMesh;
use crate::error::{Error, Result};
use crate::math::{Point3, Real, Vector3};
use crate::progress::Progress;
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;
use std::ops::RangeInclusive;

/// Which morph basis encodes an animation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BasisChoice {
    /// One target per frame after the first: exact, F − 1 targets.
    PerFrame,
    /// The first K principal components (fewer when the motion has lower
    /// rank), K ≥ 1. Lossy; the error is measured and reported.
    Components(usize),
    /// [`PerFrame`](Self::PerFrame) up to [`AUTO_PER_FRAME_LIMIT`] frames;
    /// beyond, the fewest principal components whose largest vertex error
    /// stays within the tolerance, or per-frame targets again when that basis
    /// would not need fewer targets.
    Auto,
}

/// Longest sequence [`BasisChoice::Auto`] encodes with one target per frame
/// (viewers handle a few hundred targets; past that the compact basis pays).
pub const AUTO_PER_FRAME_LIMIT: usize = 256;

/// Components whose eigenvalue is below this fraction of the largest are
/// numerical noise of the Gram matrix (singular value under 1e-6 of the
/// largest, beneath f32 resolution of the exported data) and are never used.
const NEGLIGIBLE_EIGENVALUE: Real = 1e-12;

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
        return Err(Error::InvalidInput("the dynamic mesh has no triangles".into()));
    }
    if mesh.base.triangles.iter().flatten().any(|&i| i as usize >= n) {
        return Err(Error::InvalidInput(format!("a triangle refers to a vertex beyond the {n} of the base mesh")));
    }
    for (f, frame) in mesh.frames.iter().enumerate() {
        if frame.len() != n {
            return Err(Error::InvalidInput(format!("frame {f} has {} vertices, the base mesh {n}", frame.len())));
        }
        if let Some(v) = frame.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(Error::InvalidInput(format!("vertex {v} of frame {f} has a non-finite coordinate")));
        }
    }
    Ok(())
}

/// How far a reconstruction is from the frames, in scene units, over every
/// vertex of every frame (Euclidean distance per vertex).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BasisError {
    pub max: Real,
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
            weights: (0..frames).map(|f| (1..=targets).map(|j| if j == f { 1.0 } else { 0.0 }).collect()).collect(),
            components: None,
            names: (1..frames).map(|g| format!("frame_{g:04}")).collect(),
        }
    }

    pub fn targets(&self) -> usize {
        self.mix.len()
    }

    /// Applies the mix to per-frame vectors: target j, vertex v =
    /// Σ_(g, a) ∈ `mix[j]` a · `vectors(g)[v]`, summed in f64 in frame order
    /// (deterministic) and rounded to f32, as the exported files store them.
    /// `vectors(g)` (g ≥ 1) must return `vertices` entries; it is called once
    /// per frame, a few frames at a time in parallel.
    pub fn combine<V>(&self, frames: usize, vertices: usize, vectors: V) -> Vec<Vec<[f32; 3]>>
    where
        V: Fn(usize) -> Vec<Vector3> + Sync,
    {
        // A target's f64 sum lives only while its frames are being visited, so
        // per-frame targets never hold more than one block in f64.
        let mut sums: Vec<Vec<Vector3>> = vec![Vec::new(); self.targets()];
        let mut out: Vec<Vec<[f32; 3]>> = vec![Vec::new(); self.targets()];
        for start in (1..frames).step_by(FRAME_BLOCK) {
            let block = start..(start + FRAME_BLOCK).min(frames);
            let vecs: Vec<Vec<Vector3>> = block.clone().into_par_iter().map(&vectors).collect();
            sums.par_iter_mut().zip(out.par_iter_mut()).zip(&self.mix).for_each(|((sum, out), mix)| {
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
                    *out = sum.iter().map(|s| [s.x as f32, s.y as f32, s.z as f32]).collect();
                    *sum = Vec::new();
                }
            });
        }
        out
    }
}

/// Picks the basis `choice` asks for. `tolerance` (scene units) bounds the
/// largest vertex error for [`BasisChoice::Auto`]. Returns the basis and its
/// reconstruction error (zero for per-frame targets).
pub fn choose(frames: &[Vec<Point3>], choice: BasisChoice, tolerance: Real, _progress: Progress) -> Result<(MorphBasis, BasisError)> {
    let exact = || (MorphBasis::per_frame(frames.len()), BasisError::default());
    match choice {
        BasisChoice::PerFrame => Ok(exact()),
        BasisChoice::Components(0) => Err(Error::InvalidParameter("a compact basis needs at least one component".into())),
        BasisChoice::Components(k) => {
            let pca = Pca::new(frames);
            let k = k.min(pca.usable());
            Ok((pca.basis(k), pca.errors(frames, k..=k)[0]))
        }
        BasisChoice::Auto if frames.len() <= AUTO_PER_FRAME_LIMIT => Ok(exact()),
        BasisChoice::Auto => {
            let pca = Pca::new(frames);
            // Past `sufficient` the error is within tolerance for certain; past
            // F − 2 components per-frame targets are no more.
            let limit = pca.sufficient(tolerance).min(pca.usable()).min(frames.len() - 2);
            // The largest error need not fall monotonically with k, so scan
            // upwards, in stages of doubling length to keep the cost near the
            // answer's.
            let mut ks = 0..=limit.min(8);
            loop {
                let errors = pca.errors(frames, ks.clone());
                if let Some(i) = errors.iter().position(|e| e.max <= tolerance) {
                    let basis = pca.basis(ks.start() + i);
                    return Ok(if basis.targets() < frames.len() - 1 { (basis, errors[i]) } else { exact() });
                }
                if *ks.end() == limit {
                    return Ok(exact());
                }
                ks = ks.end() + 1..=(2 * ks.end()).min(limit);
            }
        }
    }
}

/// Principal components of the displacements from frame 0, from the Gram
/// matrix of frames 1..F (F − 1 square, cheap next to the vertices × 3
/// columns): with D the displacement rows and D Dᵀ = U Λ Uᵀ, component k's
/// target is Dᵀu_k and frame f's coefficient u_k(f), and the first k
/// components reconstruct D by the optimal rank-k approximation U_k U_kᵀ D.
pub struct Pca {
    /// Column u_k per component (entry g − 1 for frame g), unit length, by
    /// decreasing eigenvalue; the largest-magnitude entry (the first of equals)
    /// is positive, as scikit-learn's `svd_flip` does, so the result does not
    /// depend on the eigensolver's signs.
    components: Vec<Vec<Real>>,
    /// Eigenvalues (squared singular values), decreasing, rounding below 0
    /// clamped to 0.
    eigenvalues: Vec<Real>,
    frames: usize,
}

impl Pca {
    /// Builds the Gram matrix (parallel over its rows, each entry summed in a
    /// fixed order, so the result does not depend on the thread count) and
    /// diagonalises it.
    pub fn new(frames: &[Vec<Point3>]) -> Self {
        let moving = frames.len().saturating_sub(1);
        if moving == 0 {
            return Pca { components: Vec::new(), eigenvalues: Vec::new(), frames: frames.len() };
        }
        let vertices = frames[0].len();
        let mut gram = vec![0.0; moving * moving];
        let mut block = vec![0.0; moving * 3 * VERTEX_CHUNK];
        for start in (0..vertices).step_by(VERTEX_CHUNK) {
            let width = 3 * VERTEX_CHUNK.min(vertices - start);
            let block = &mut block[..moving * width];
            gather(frames, start, width / 3, block);
            let block = &*block;
            gram.par_chunks_mut(moving).enumerate().for_each(|(r, row)| {
                let a = &block[r * width..(r + 1) * width];
                for (c, g) in row[..=r].iter_mut().enumerate() {
                    *g += dot(a, &block[c * width..(c + 1) * width]);
                }
            });
        }
        let eig = SymmetricEigen::new(DMatrix::from_fn(moving, moving, |r, c| gram[r.max(c) * moving + r.min(c)]));
        let mut order: Vec<usize> = (0..moving).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let components = order
            .iter()
            .map(|&i| {
                let mut u: Vec<Real> = eig.eigenvectors.column(i).iter().copied().collect();
                let pivot = (0..u.len()).fold(0, |best, r| if u[r].abs() > u[best].abs() { r } else { best });
                if u[pivot] < 0.0 {
                    u.iter_mut().for_each(|x| *x = -*x);
                }
                u
            })
            .collect();
        let eigenvalues = order.iter().map(|&i| eig.eigenvalues[i].max(0.0)).collect();
        Pca { components, eigenvalues, frames: frames.len() }
    }

    /// Number of components that carry motion (see [`NEGLIGIBLE_EIGENVALUE`]).
    pub fn usable(&self) -> usize {
        let largest = self.eigenvalues.first().copied().unwrap_or(0.0);
        self.eigenvalues.iter().take_while(|&&l| l > 0.0 && l > NEGLIGIBLE_EIGENVALUE * largest).count()
    }

    /// Fewest components whose residual's Frobenius norm, √(Σ_(j ≥ k) λ_j),
    /// is within `tolerance`; it bounds every single vertex's error, so this
    /// many components certainly suffice.
    pub fn sufficient(&self, tolerance: Real) -> usize {
        let mut tail = 0.0;
        let mut k = self.eigenvalues.len();
        for (j, l) in self.eigenvalues.iter().enumerate().rev() {
            tail += l;
            if tail.sqrt() > tolerance {
                break;
            }
            k = j;
        }
        k
    }

    /// The reconstruction error with the first k components, for every k in
    /// `ks` (k ≤ number of components). Each vertex's trajectory over the
    /// frames is projected onto the components (x − U_k U_kᵀ x), so this costs
    /// one pass over the frames and never stores the residual.
    pub fn errors(&self, frames: &[Vec<Point3>], ks: RangeInclusive<usize>) -> Vec<BasisError> {
        let (k0, k1) = (*ks.start(), *ks.end());
        assert!(k0 <= k1 && k1 <= self.components.len(), "component range {k0}..={k1} beyond {}", self.components.len());
        let moving = self.frames - 1;
        let vertices = frames[0].len();
        let u = &self.components;
        let starts: Vec<usize> = (0..vertices).step_by(VERTEX_CHUNK).collect();
        // Per chunk and k: (largest error, sum of errors).
        let chunks: Vec<Vec<(Real, Real)>> = starts
            .par_iter()
            .map(|&start| {
                let n = VERTEX_CHUNK.min(vertices - start);
                let mut block = vec![0.0; moving * 3 * n];
                gather(frames, start, n, &mut block);
                let mut stats = vec![(0.0, 0.0); k1 - k0 + 1];
                let mut y = vec![Vector3::zeros(); k1];
                let mut e = vec![Vector3::zeros(); moving];
                for i in 0..n {
                    let x = |r: usize| Vector3::from_column_slice(&block[r * 3 * n + 3 * i..][..3]);
                    for (yk, uk) in y.iter_mut().zip(u) {
                        *yk = uk.iter().enumerate().map(|(r, &w)| w * x(r)).sum();
                    }
                    for (r, er) in e.iter_mut().enumerate() {
                        *er = x(r) - (0..k0).map(|k| u[k][r] * y[k]).sum::<Vector3>();
                    }
                    for (k, s) in (k0..=k1).zip(&mut stats) {
                        if k > k0 {
                            e.iter_mut().zip(&u[k - 1]).for_each(|(er, &w)| *er -= w * y[k - 1]);
                        }
                        for d in e.iter().map(|er| er.norm()) {
                            s.0 = Real::max(s.0, d);
                            s.1 += d;
                        }
                    }
                }
                stats
            })
            .collect();
        let count = (self.frames * vertices) as Real;
        (0..=k1 - k0)
            .map(|j| BasisError {
                max: chunks.iter().map(|c| c[j].0).fold(0.0, Real::max),
                mean: if count > 0.0 { chunks.iter().map(|c| c[j].1).sum::<Real>() / count } else { 0.0 },
            })
            .collect()
    }

    /// The basis of the first `k` components. Each component's coefficient
    /// u_k(f) is split into its positive and negative parts, one target each
    /// (the second only when some coefficient is negative), scaled so the
    /// weights span [0, 1]; their sum interpolates exactly like the signed
    /// coefficient would, LINEAR or not.
    pub fn basis(&self, k: usize) -> MorphBasis {
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
                mix.push(u.iter().enumerate().filter(|(_, &x)| x != 0.0).map(|(r, &x)| (r + 1, scale * x)).collect());
                names.push(format!("pc_{:04}_{part}", c + 1));
                columns.push(std::iter::once(0.0).chain(u.iter().map(|&x| (sign * x).max(0.0) / (sign * scale))).collect());
            }
        }
        MorphBasis {
            mix,
            weights: (0..self.frames).map(|f| columns.iter().map(|w| w[f]).collect()).collect(),
            components: Some(k),
            names,
        }
    }
}

/// Displacements from frame 0 of vertices `start..start + n` in frames 1..F,
/// frame-major: `out[(g − 1)·3n + 3i + axis]`.
fn gather(frames: &[Vec<Point3>], start: usize, n: usize, out: &mut [Real]) {
    let base = &frames[0][start..start + n];
    for (row, frame) in out.chunks_exact_mut(3 * n).zip(&frames[1..]) {
        for ((d, p), p0) in row.chunks_exact_mut(3).zip(&frame[start..start + n]).zip(base) {
            d.copy_from_slice((p - p0).as_slice());
        }
    }
}

/// Dot product in a fixed summation order (four interleaved partial sums).
fn dot(a: &[Real], b: &[Real]) -> Real {
    let mut s = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: Real = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}
