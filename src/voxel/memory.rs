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

/// What the memory estimate needs of a frame's mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameExtent {
    pub bounds: Aabb,
    /// The enclosed volume (absolute signed volume).
    pub volume: f64,
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
}

impl MemoryEstimate {
    /// Occupied voxels are estimated from each mesh's enclosed volume (its
    /// signed volume, bounded by its own box of voxels); voxelising holds
    /// one byte per voxel of a frame's box on each of `threads` threads.
    pub fn of(meshes: &[&TriangleMesh], grid: &GridSpec, threads: usize) -> Self {
        let extents: Vec<FrameExtent> = meshes
            .iter()
            .map(|m| FrameExtent {
                bounds: m.bounding_box(),
                volume: m.signed_volume().abs(),
            })
            .collect();
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
        MemoryEstimate {
            bytes: held + largest_box * threads.max(1) as f64,
            kept_cells,
        }
    }

    /// Bytes the run needs under a limit of `limit` bytes, the kept
    /// assignments included.
    pub fn total(&self, limit: f64) -> f64 {
        self.bytes + self.kept_cells.min(kept_cell_share(limit))
    }

    /// Fails when the estimate exceeds `limit` bytes, naming the largest
    /// resolution that would fit (memory grows as the resolution cubed).
    pub fn check(&self, limit: f64, resolution: usize, frames: usize) -> Result<()> {
        let bytes = self.total(limit);
        if bytes <= limit {
            return Ok(());
        }
        // The kept assignments take at most their share whatever the
        // resolution; the rest grows as its cube.
        let kept = self.kept_cells.min(kept_cell_share(limit));
        let fits =
            (resolution as f64 * ((0.9 * limit - kept) / self.bytes).cbrt()).floor() as usize;
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
fn size(bytes: f64) -> String {
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

/// Memory the process can still get now, if known (Linux): the system's
/// available memory, or less under an address-space limit (`ulimit -v`).
pub(crate) fn available_memory() -> Option<f64> {
    let kib = |text: &str, key: &str| -> Option<f64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? * 1024.0)
    };
    let system = kib(
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
        .and_then(|s| kib(&s, "VmSize:"));
    Some(match (limit, used) {
        (Some(limit), Some(used)) => system.min((limit - used).max(0.0)),
        _ => system,
    })
}
