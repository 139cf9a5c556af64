//! The voxelisation stage: a whole sequence on one grid.

use super::{voxelize_detailed, FrameExtent};
use crate::error::{Error, Result};
use crate::model::mesh::{Aabb, TriangleMesh};
use crate::model::{Frame, FrameSource, GridSpec, Occupancy, OccupancyRuns, MAX_RESOLUTION};
use crate::progress::{Counter, Progress, Stage};
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// Options of the voxelisation stage.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VoxelParams {
    /// Voxels along the longest side of the sequence's bounding box.
    /// Default 256; range 2..=1596. Ignored for `.binvox` input.
    pub resolution: usize,
    /// Largest accepted ratio between a frame's bounding-box diagonal and the
    /// sequence's median one (either way); beyond it the frame is taken to be
    /// in other units. Default 100.
    pub max_extent_ratio: f64,
    /// Bytes the run may take beyond the frames read; a resolution whose
    /// estimated need ([`super::MemoryEstimate`]) is larger fails before any
    /// voxel is filled. Default None: the memory available when the frames
    /// have been read (no check where that is unknown); in (0, 1e9 GiB].
    pub max_memory: Option<f64>,
}

impl VoxelParams {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        crate::params::check_count("the resolution", self.resolution, 2..=MAX_RESOLUTION)?;
        crate::params::check(
            "the largest extent ratio",
            self.max_extent_ratio,
            crate::params::Span::closed(1.0, 1e12),
        )?;
        if let Some(m) = self.max_memory {
            crate::params::check("the memory limit", m, crate::params::MEMORY)?;
        }
        Ok(())
    }
}

impl Default for VoxelParams {
    fn default() -> Self {
        VoxelParams {
            resolution: 256,
            max_extent_ratio: 100.0,
            max_memory: None,
        }
    }
}

/// Every frame's occupancy on the sequence's grid.
#[derive(Clone, Debug)]
pub struct VoxelSequence {
    /// The grid every frame is on.
    pub grid: GridSpec,
    /// Every frame's occupied voxels, compact (expand one with
    /// [`OccupancyRuns::indices`]).
    pub frames: Vec<OccupancyRuns>,
    /// How messages name each frame (its file, for frames read from files).
    pub names: Vec<String>,
    /// Bounding box of all frames (of the grid, for voxel input).
    pub bounds: Aabb,
    /// The first frame's mesh, kept for the deformation stage (None for voxel input).
    pub first_mesh: Option<TriangleMesh>,
    /// Wall-clock seconds spent reading the frames (the first pass, for
    /// their bounding boxes).
    pub read_seconds: f64,
    /// Wall-clock seconds spent voxelising the frames, reading them again
    /// included (0 for voxel input).
    pub voxelize_seconds: f64,
}

/// Largest share of a frame's occupied voxels that no axis vouches for (see
/// [`super::Voxelization::unvouched`]): a capture with holes, or even an open
/// cup seen at an angle, stays well below half; an open sheet, which
/// encloses nothing, is far above it.
const MAX_UNVOUCHED: f64 = 0.5;

/// Largest gap, in median bounding-box diagonals, that joins a frame to the
/// others (see [`check_placement`]). Consecutive frames of a capture touch or
/// nearly so, however far the subject travels; a frame past this gap is
/// out of place, and the common grid, stretched to reach it, would be so
/// coarse for the other frames that they enclose nothing.
const MAX_GAP_DIAGONALS: f64 = 10.0;

/// Reads and voxelises every frame of `source` on one grid.
pub fn voxelize_sequence(
    source: &dyn FrameSource,
    params: &VoxelParams,
    progress: Progress,
) -> Result<VoxelSequence> {
    params.validate()?;
    let names: Vec<String> = (0..source.len()).map(|f| source.name(f)).collect();
    let paths: Vec<&Path> = names.iter().map(Path::new).collect();
    if paths.len() < 2 {
        return Err(Error::InvalidInput(match paths.first() {
            Some(p) => format!(
                "{}: a sequence needs at least 2 frames, got only this one",
                p.display()
            ),
            None => "a sequence needs at least 2 frames, got none".into(),
        }));
    }
    // Two passes over the frames, so that memory never holds them all: the
    // first reads each frame for its bounding box (the common grid needs
    // every frame's), the second reads it again and voxelises it. Frame 0's
    // mesh is kept for the deformation stage; voxel frames are kept as read.
    let start = Instant::now();
    let counter = Counter::new(progress, Stage::Read, paths.len());
    let mut summaries: Vec<Summary> = per_frame(source.len(), |f| {
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
        let frame = source.frame(f)?;
        counter.tick();
        Ok(match frame {
            Frame::Mesh(m) => Summary::Mesh {
                extent: FrameExtent::of(&m),
                mesh: (f == 0).then_some(m),
            },
            Frame::Voxels(g, o) => Summary::Voxels(g, o),
        })
    })?;
    let read_seconds = start.elapsed().as_secs_f64();

    let meshes = one_kind(&paths, &summaries)?;
    if meshes == 0 {
        let data = summaries.into_iter().map(|d| match d {
            Summary::Voxels(g, o) => (g, o),
            Summary::Mesh { .. } => unreachable!(),
        });
        return voxel_input(names, data.collect(), read_seconds);
    }
    let extents: Vec<FrameExtent> = summaries
        .iter()
        .map(|d| match d {
            Summary::Mesh { extent, .. } => *extent,
            Summary::Voxels(..) => unreachable!(),
        })
        .collect();
    let boxes: Vec<Aabb> = extents.iter().map(|e| e.bounds).collect();
    check_extents(&paths, &boxes, params.max_extent_ratio)?;
    check_placement(&paths, &boxes)?;
    let bounds = boxes.iter().fold(Aabb::empty(), |a, b| a.union(b));
    let grid = GridSpec::for_bounds(&bounds, params.resolution)?;
    check_memory(&extents, &grid, params, paths.len())?;
    let Summary::Mesh {
        mesh: Some(first_mesh),
        ..
    } = summaries.swap_remove(0)
    else {
        unreachable!("frame 0 is a mesh, kept")
    };
    drop(summaries);

    let start = Instant::now();
    let counter = Counter::new(progress, Stage::Voxelize, paths.len());
    let frames: Vec<OccupancyRuns> = per_frame(source.len(), |f| {
        let path = paths[f];
        if progress.cancelled() {
            return Err(Error::Interrupted { saved: None });
        }
        let read;
        let mesh = if f == 0 {
            &first_mesh
        } else {
            read = match source.frame(f)? {
                Frame::Mesh(m) => m,
                Frame::Voxels(..) => {
                    return Err(Error::mesh(
                        path,
                        "was a mesh when first read, a voxel grid now",
                    ))
                }
            };
            &read
        };
        let runs = voxelize_frame(mesh, &grid, path, progress)?;
        counter.tick();
        Ok(runs)
    })?;
    let voxelize_seconds = start.elapsed().as_secs_f64();
    let (voxels, runs, bytes) = frames.iter().fold((0, 0, 0), |(v, r, b), f| {
        (v + f.len(), r + f.runs(), b + f.bytes())
    });
    log::info!(
        "{voxels} occupied voxels in {runs} runs ({:.1} MiB kept)",
        bytes as f64 / (1u64 << 20) as f64
    );
    Ok(VoxelSequence {
        grid,
        frames,
        names,
        bounds,
        first_mesh: Some(first_mesh),
        read_seconds,
        voxelize_seconds,
    })
}

/// `work(f)` for every frame f of `frames`, in parallel, the results in
/// frame order. Where frames fail, the error is the first failing frame's,
/// whichever thread fails first, so that the same input fails with the same
/// message every run: once a frame fails, the frames after it are skipped,
/// and those before it are still read.
fn per_frame<T: Send>(frames: usize, work: impl Fn(usize) -> Result<T> + Sync) -> Result<Vec<T>> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let first_failed = AtomicUsize::new(usize::MAX);
    let results: Vec<Option<Result<T>>> = (0..frames)
        .into_par_iter()
        .map(|f| {
            if f > first_failed.load(Ordering::Relaxed) {
                return None;
            }
            let result = work(f);
            if result.is_err() {
                first_failed.fetch_min(f, Ordering::Relaxed);
            }
            Some(result)
        })
        .collect();
    // A frame is skipped only after an earlier one failed, so the first
    // failing frame comes before any skipped one.
    results
        .into_iter()
        .map(|r| r.expect("skipped only after an earlier frame failed"))
        .collect()
}

/// How many of the frames read (`summaries`, of `paths`) are meshes:
/// all or none, a sequence mixing meshes and voxel grids fails.
fn one_kind(paths: &[&Path], summaries: &[Summary]) -> Result<usize> {
    let is_mesh = |d: &Summary| matches!(d, Summary::Mesh { .. });
    let meshes = summaries.iter().filter(|d| is_mesh(d)).count();
    if meshes != 0 && meshes != summaries.len() {
        let first = |mesh: bool| {
            paths[summaries
                .iter()
                .position(|d| is_mesh(d) == mesh)
                .expect("both kinds")]
            .display()
        };
        return Err(Error::InvalidInput(format!(
            "the sequence mixes meshes ({} …) and voxel grids ({} …): give one kind",
            first(true),
            first(false)
        )));
    }
    Ok(meshes)
}

/// Fails where the conversion of `frames` frames of these `extents` on
/// `grid` is estimated to need more memory than `params.max_memory` (or
/// than is available), before any frame is voxelised.
fn check_memory(
    extents: &[FrameExtent],
    grid: &GridSpec,
    params: &VoxelParams,
    frames: usize,
) -> Result<()> {
    let Some(limit) = params.max_memory.or_else(super::available_memory) else {
        return Ok(());
    };
    let estimate = super::MemoryEstimate::of_frames(extents, grid, rayon::current_num_threads());
    let held = super::memory::resident_memory().unwrap_or(0.0);
    let mib = |b: f64| b / (1u64 << 20) as f64;
    log::debug!(
        "memory estimate in MiB: voxels {:.1}, tracking {:.1}, kept cells {:.1} (at most {:.1} under this limit), mesh stages {:.1}, held now {:.1}",
        mib(estimate.bytes),
        mib(estimate.tracking),
        mib(estimate.kept_cells),
        mib(crate::params::kept_cell_share(limit)),
        mib(estimate.mesh_stages),
        mib(held),
    );
    let size = super::memory::size;
    log::info!(
        "estimated memory: {} of {} allowed, on top of {} held now: a peak of at most {}",
        size(estimate.total(limit)),
        size(limit),
        size(held),
        size(held + estimate.total(limit))
    );
    estimate.check(limit, params.resolution, frames)
}

/// One frame's `mesh` (read from `path`) voxelised on `grid`, failing
/// where it encloses no volume; [`Error::Interrupted`] when
/// `progress` asks to stop.
fn voxelize_frame(
    mesh: &TriangleMesh,
    grid: &GridSpec,
    path: &Path,
    progress: Progress,
) -> Result<OccupancyRuns> {
    let v = voxelize_detailed(mesh, grid, &|| progress.cancelled())
        .ok_or(Error::Interrupted { saved: None })?;
    if v.occupancy.is_empty() {
        return Err(Error::mesh(
            path,
            "encloses no voxel at this resolution (an open sheet, or too thin); raise the resolution or close the surface",
        ));
    }
    if v.unvouched as f64 > MAX_UNVOUCHED * v.occupancy.len() as f64 {
        return Err(Error::mesh(
            path,
            format!(
                "encloses no volume: {} of its {} voxels are inside only by a guess, every axis's ray through them passing through a hole \
                 (an open sheet?); close the surface",
                v.unvouched,
                v.occupancy.len()
            ),
        ));
    }
    Ok(OccupancyRuns::from(v.occupancy))
}

/// What the first pass keeps of a frame.
enum Summary {
    Mesh {
        extent: FrameExtent,
        mesh: Option<TriangleMesh>,
    },
    Voxels(GridSpec, Occupancy),
}

fn voxel_input(
    names: Vec<String>,
    data: Vec<(GridSpec, Occupancy)>,
    read_seconds: f64,
) -> Result<VoxelSequence> {
    let mut grid = None;
    let mut frames = Vec::with_capacity(data.len());
    for (d, name) in data.into_iter().zip(&names) {
        let path = Path::new(name);
        let (g, occ) = d;
        match grid {
            None => grid = Some(g),
            Some(first) if first != g => {
                return Err(Error::InvalidInput(format!(
                    "{}: its grid (dims {:?}, origin {:?}, voxel {}) differs from the first frame's (dims {:?}, origin {:?}, voxel {})",
                    path.display(), g.dims, g.origin.coords.as_slice(), g.voxel_size,
                    first.dims, first.origin.coords.as_slice(), first.voxel_size
                )))
            }
            Some(_) => {}
        }
        if occ.is_empty() {
            return Err(Error::mesh(path, "no occupied voxel"));
        }
        frames.push(OccupancyRuns::from(occ));
    }
    let grid = grid.expect("at least two frames");
    Ok(VoxelSequence {
        grid,
        frames,
        names,
        bounds: grid.bounds(),
        first_mesh: None,
        read_seconds,
        voxelize_seconds: 0.0,
    })
}

/// Frames in different units (mm next to m) would share one grid badly: the
/// frame whose bounding-box diagonal is farthest (as a ratio) from the
/// median frame's is named when that ratio passes `max_ratio`.
fn check_extents(paths: &[&Path], boxes: &[Aabb], max_ratio: f64) -> Result<()> {
    let diag: Vec<f64> = boxes.iter().map(Aabb::diagonal).collect();
    if let Some(i) = diag.iter().position(|&d| !(d > 0.0 && d.is_finite())) {
        return Err(Error::mesh(
            paths[i],
            format!(
                "the bounding box's diagonal is {} (all vertices coincide, or overflow)",
                diag[i]
            ),
        ));
    }
    let mut order: Vec<usize> = (0..diag.len()).collect();
    order.sort_by(|&a, &b| diag[a].total_cmp(&diag[b]));
    let median = order[(order.len() - 1) / 2];
    let ratio = |i: usize| (diag[i] / diag[median]).max(diag[median] / diag[i]);
    let odd = (0..diag.len())
        .max_by(|&a, &b| ratio(a).total_cmp(&ratio(b)))
        .expect("at least one frame");
    if ratio(odd) > max_ratio {
        return Err(Error::InvalidInput(format!(
            "{}: {:.0} times {} than the sequence's median frame {} (bounding-box diagonals {:.4} and {:.4}); are the frames in different units?",
            paths[odd].display(),
            ratio(odd),
            if diag[odd] > diag[median] { "larger" } else { "smaller" },
            paths[median].display(),
            diag[odd],
            diag[median]
        )));
    }
    Ok(())
}

/// A frame in another place (another origin) stretches the common grid until
/// the other frames vanish in it, and they, not it, would be blamed. Frames
/// whose bounding boxes lie within [`MAX_GAP_DIAGONALS`] median diagonals of
/// each other are grouped, transitively, so a subject may travel any
/// distance; with more than one group, the first frame outside the largest
/// (on a tie, the one holding the earliest frame) is named.
fn check_placement(paths: &[&Path], boxes: &[Aabb]) -> Result<()> {
    let mut diag: Vec<f64> = boxes.iter().map(Aabb::diagonal).collect();
    diag.sort_by(f64::total_cmp);
    let reach = MAX_GAP_DIAGONALS * diag[(diag.len() - 1) / 2];
    let gap = |a: &Aabb, b: &Aabb| {
        (a.min - b.max)
            .sup(&(b.min - a.max))
            .sup(&crate::math::Vector3::zeros())
            .norm()
    };
    // Union-find over the frames; the quadratic pass costs far less than
    // voxelising the frames.
    let mut group: Vec<usize> = (0..boxes.len()).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    for i in 0..boxes.len() {
        for j in i + 1..boxes.len() {
            if gap(&boxes[i], &boxes[j]) <= reach {
                let (a, b) = (root(&mut group, i), root(&mut group, j));
                // The lower root stays, so a group's root is its earliest frame.
                group[a.max(b)] = a.min(b);
            }
        }
    }
    let roots: Vec<usize> = (0..boxes.len()).map(|i| root(&mut group, i)).collect();
    let mut sizes = vec![0usize; boxes.len()];
    roots.iter().for_each(|&r| sizes[r] += 1);
    // Largest group; on a tie the earliest root, as max_by_key keeps the last maximum.
    let main = (0..boxes.len())
        .rev()
        .max_by_key(|&r| sizes[r])
        .expect("at least one frame");
    let Some(odd) = (0..boxes.len()).find(|&i| roots[i] != main) else {
        return Ok(());
    };
    let others = (0..boxes.len())
        .filter(|&i| roots[i] == main)
        .fold(Aabb::empty(), |a, i| a.union(&boxes[i]));
    let fmt = |p: &crate::math::Point3| format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z);
    Err(Error::InvalidInput(format!(
        "{}: out of place: its bounding box {} .. {} lies {:.0} times the median frame's diagonal away from those of {} other frames ({} .. {}); \
         is this frame offset (another origin)?",
        paths[odd].display(),
        fmt(&boxes[odd].min),
        fmt(&boxes[odd].max),
        gap(&boxes[odd], &others) / (reach / MAX_GAP_DIAGONALS),
        sizes[main],
        fmt(&others.min),
        fmt(&others.max)
    )))
}
