//! Stages 2-3: seeding centers in the first frame and tracking them forward
//! (method.md §2-§5). One file per algorithm: `lloyd` (frame 0), `assign`
//! (Voronoi cells), `rigid` (weighted Kabsch), `affinity` (who moves with
//! whom), `forward` (the frame loop).

pub mod affinity;
pub mod checkpoint;
mod forward;
pub mod lloyd;

pub use checkpoint::Checkpointing;
pub(crate) use forward::cell_moments;
pub use forward::{predict, track, track_with_checkpoints, TrackResult};

/// Where the time of one frame went, in seconds. With a damped guess the
/// parts add up both runs, which run side by side: they can exceed `total`.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FrameTiming {
    pub total: f64,
    pub assign: f64,
    pub fit: f64,
    pub affinity: f64,
    /// Iterations of the run that was kept.
    pub iterations: usize,
    /// Iterations of the run from the other guess, dropped (0 with one guess).
    pub dropped_iterations: usize,
    /// The run from the damped guess ended with the lower energy and was kept.
    pub damped_guess_kept: bool,
}

/// ρ_p in the input's units (see [`crate::params::TrackParams::rho_p`]), from frame 0's
/// occupied volume.
fn rho_p(params: &crate::params::TrackParams, seq: &crate::voxel::VoxelSequence, scale: crate::math::Real) -> crate::math::Real {
    params.rho_p_in_units(scale, seq.frames[0].len() as crate::math::Real * seq.grid.voxel_size.powi(3))
}
