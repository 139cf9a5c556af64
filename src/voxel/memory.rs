//! How much memory a run will take, estimated from the grid and the frames
//! before any voxel is filled, so that a resolution the machine cannot hold
//! fails at once instead of after minutes of swapping.

use crate::error::{Error, Result};
use crate::model::mesh::{Aabb, TriangleMesh};
use crate::model::GridSpec;
use crate::params::{kept_cell_share, KEPT_CELL_BYTES_PER_VOXEL, KEPT_CELL_FRAMES};

/// Bytes held per occupied voxel of every frame through the run: its share
/// of the frame's runs ([`crate::model::OccupancyRuns`], 2 to 10 bytes a run;
/// a run holds many voxels in a solid, one in the worst case of scattered
/// voxels, so this is generous for captures).
const BYTES_PER_VOXEL: f64 = 2.0;

/// Bytes per occupied voxel of the largest frame that the tracker holds
/// while it tracks a frame: each guess's run keeps its own cells (owner,
/// distance bounds, runner-ups), and the previous frame's stay; a bound on
/// what the default guesses were measured to take (docs/measurements.md).
const TRACK_BYTES_PER_VOXEL: f64 = 256.0;

/// Bytes per vertex of frame 0 and frame that the mesh stages hold at most:
/// the result's positions (12), their normals and morph deltas as the
/// export builds them (24), the conform and fit passes' per-frame copies,
/// with room to spare (a bound, not a guess).
const MESH_BYTES_PER_VERTEX_FRAME: f64 = 64.0;

/// Bytes per vertex of the largest frame that each thread holds while it
/// reads a frame again (voxelising, the fit pass): the file's parsed
/// buffers, the mesh and a search tree over its triangles.
const READ_BYTES_PER_VERTEX: f64 = 256.0;

/// Working memory of the stages whatever the input's size: the thread
/// pool's stacks and the allocator's per-thread arenas, the tracker's and
/// refinement's tables, the export's buffers: a bound on what runs at a low
/// resolution with the default number of centers were measured to take
/// (docs/measurements.md; it grows with the number of centers).
const WORKING_BYTES: f64 = 48.0 * (1u64 << 20) as f64;

/// What the memory estimate needs of a frame's mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameExtent {
    /// The mesh's bounding box.
    pub bounds: Aabb,
    /// The enclosed volume (absolute signed volume).
    pub volume: f64,
    /// Vertices of the mesh.
    pub vertices: usize,
}

impl FrameExtent {
    /// What the estimate needs of `mesh`.
    pub fn of(mesh: &TriangleMesh) -> Self {
        FrameExtent {
            bounds: mesh.bounding_box(),
            volume: mesh.signed_volume().abs(),
            vertices: mesh.positions.len(),
        }
    }
}

/// The estimate for one sequence on one grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryEstimate {
    /// Bytes the run needs on top of the frames already read, but for the
    /// cell assignments the global optimisation keeps.
    pub bytes: f64,
    /// Bytes the kept assignments take at most ([`KEPT_CELL_FRAMES`] of the
    /// largest frames); they take no more than [`crate::params::KEPT_CELL_SHARE`] of the
    /// memory allowed ([`crate::params::RefineParams::cell_memory`]).
    pub kept_cells: f64,
    /// Bytes the tracker's cells take while it tracks the largest frame;
    /// they are gone before the kept assignments are made, so the run needs
    /// the larger of the two.
    pub tracking: f64,
    /// Bytes the stages take whatever the resolution: the result's mesh over
    /// every frame, the frames read again, the stages' working memory.
    pub mesh_stages: f64,
}

impl MemoryEstimate {
    /// Occupied voxels are estimated from each mesh's enclosed volume (its
    /// signed volume, bounded by its own box of voxels); voxelising holds
    /// one byte per voxel of a frame's box on each of `threads` threads.
    pub fn of(meshes: &[&TriangleMesh], grid: &GridSpec, threads: usize) -> Self {
        let extents: Vec<FrameExtent> = meshes.iter().map(|m| FrameExtent::of(m)).collect();
        Self::of_frames(&extents, grid, threads)
    }

    /// [`MemoryEstimate::of`] from what it needs of each mesh.
    pub fn of_frames(frames: &[FrameExtent], grid: &GridSpec, threads: usize) -> Self {
        let voxel = grid.voxel_size.powi(3);
        let mut held = 0.0;
        let mut largest_box: f64 = 0.0;
        let mut voxels = Vec::with_capacity(frames.len());
        for frame in frames {
            let b = &frame.bounds;
            let cells: f64 = (0..3)
                .map(|k| (b.extent()[k] / grid.voxel_size).ceil() + 2.0)
                .product();
            let occupied = (frame.volume / voxel).min(cells);
            held += occupied * BYTES_PER_VOXEL;
            voxels.push(occupied);
            largest_box = largest_box.max(cells);
        }
        // The frames with the most voxels stand for those whose assignments are kept.
        voxels.sort_by(|a, b| b.total_cmp(a));
        let kept_cells =
            voxels.iter().take(KEPT_CELL_FRAMES).sum::<f64>() * KEPT_CELL_BYTES_PER_VOXEL as f64;
        // The result has frame 0's vertices in every frame.
        let result = frames.first().map_or(0, |f| f.vertices) as f64 * frames.len() as f64;
        let largest_mesh = frames.iter().map(|f| f.vertices).max().unwrap_or(0) as f64;
        MemoryEstimate {
            bytes: held + largest_box * threads.max(1) as f64,
            kept_cells,
            tracking: voxels.first().copied().unwrap_or(0.0) * TRACK_BYTES_PER_VOXEL,
            mesh_stages: WORKING_BYTES
                + result * MESH_BYTES_PER_VERTEX_FRAME
                + largest_mesh * READ_BYTES_PER_VERTEX * threads.max(1) as f64,
        }
    }

    /// Bytes the run needs under a limit of `limit` bytes, the kept
    /// assignments and the mesh stages included.
    pub fn total(&self, limit: f64) -> f64 {
        self.bytes
            + self.mesh_stages
            + self
                .tracking
                .max(self.kept_cells.min(kept_cell_share(limit)))
    }

    /// Fails when the estimate exceeds `limit` bytes, naming the largest
    /// resolution that would fit (memory grows as the resolution cubed).
    pub fn check(&self, limit: f64, resolution: usize, frames: usize) -> Result<()> {
        let bytes = self.total(limit);
        if bytes <= limit {
            return Ok(());
        }
        // The voxels' bytes grow as the resolution cubed, the mesh stages'
        // do not; the largest resolution whose estimate keeps a tenth of the
        // limit spare (the estimate grows with the resolution).
        let at = |r: usize| {
            let s = (r as f64 / resolution as f64).powi(3);
            MemoryEstimate {
                bytes: self.bytes * s,
                kept_cells: self.kept_cells * s,
                tracking: self.tracking * s,
                mesh_stages: self.mesh_stages,
            }
            .total(limit)
        };
        let (mut lo, mut hi) = (1, resolution);
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if at(mid) <= 0.9 * limit {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let fits = if at(lo) <= 0.9 * limit { lo } else { 0 };
        let fits = if fits >= 2 {
            format!("the largest resolution that fits is about {fits}")
        } else {
            "no resolution fits".into()
        };
        Err(Error::InvalidParameter(format!(
            "resolution {resolution} over {frames} frames needs about {}, more than the {} allowed (the memory available now, unless a limit is set); \
             {fits}, or raise the memory limit if this estimate is too high",
            size(bytes),
            size(limit),
        )))
    }
}

/// `bytes` in the largest of GiB, MiB and KiB that keeps it at 1 or more,
/// with two significant digits at least (never "0.0 GiB").
pub(crate) fn size(bytes: f64) -> String {
    let (value, unit) = [(30, "GiB"), (20, "MiB"), (10, "KiB")]
        .into_iter()
        .map(|(shift, unit)| (bytes / (1u64 << shift) as f64, unit))
        .find(|(v, _)| *v >= 1.0)
        .unwrap_or((bytes / 1024.0, "KiB"));
    if value >= 10.0 {
        format!("{value:.0} {unit}")
    } else {
        format!("{value:.1} {unit}")
    }
}

/// The bytes of the `key` line of a /proc file's `text` ("VmRSS:  1234 kB").
fn kib_field(text: &str, key: &str) -> Option<f64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
}

/// Memory the process holds now (its resident set), if known (Linux).
pub(crate) fn resident_memory() -> Option<f64> {
    kib_field(
        &std::fs::read_to_string("/proc/self/status").ok()?,
        "VmRSS:",
    )
}

/// Memory the process can still get now, if known (Linux): the system's
/// available memory, or less under an address-space limit (`ulimit -v`).
pub(crate) fn available_memory() -> Option<f64> {
    let system = kib_field(
        &std::fs::read_to_string("/proc/meminfo").ok()?,
        "MemAvailable:",
    )?;
    let limit = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|limits| {
            let line = limits
                .lines()
                .find(|l| l.starts_with("Max address space"))?;
            line.split_whitespace().nth(3)?.parse::<f64>().ok()
        });
    let used = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| kib_field(&s, "VmSize:"));
    Some(match (limit, used) {
        (Some(limit), Some(used)) => system.min((limit - used).max(0.0)),
        _ => system,
    })
}
