//! Stage 2: seeding centers in the first frame and tracking them forward
//! (docs/method.md §2-§5). One file per algorithm: `lloyd` (frame 0), `affinity`
//! (who moves with whom), `forward` (the frame loop), `claims` (starved
//! parts turned about their joint, `--reclaim`), `checkpoint` (saving and resuming).
//! The Voronoi cells they use are `spatial::cells`, the weighted rigid fits
//! `model::rigid`'s. All but [`checkpoint`] are internal: the API is
//! [`track`], [`track_with_checkpoints`], their result and the reference
//! frame's choice.

pub(crate) mod affinity;
pub mod checkpoint;
mod claims;
mod forward;
mod lloyd;
mod reference;

pub use checkpoint::Checkpointing;
pub(crate) use forward::cell_moments;
pub use forward::{predict, track, track_with_checkpoints, TrackResult};
pub use reference::{check_reference, choose_reference, frame_topologies, ReferenceChoice};

/// The start a frame's kept run came from (see `forward::guesses`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Guess {
    /// The paper's: c^{f-1} + (c^{f-1} − c^{f-2}).
    #[default]
    ConstantVelocity,
    /// [`crate::params::TrackParams::damped_guess`].
    Damped,
    /// [`crate::params::TrackParams::accelerated_guess`].
    Accelerated,
    /// Region by region the best of the others.
    Mixed,
}

impl Guess {
    /// Its number in a checkpoint.
    pub(crate) fn code(self) -> u64 {
        self as u64
    }

    pub(crate) fn from_code(code: u64) -> Option<Guess> {
        [
            Guess::ConstantVelocity,
            Guess::Damped,
            Guess::Accelerated,
            Guess::Mixed,
        ]
        .get(code as usize)
        .copied()
    }
}

/// Where the time of one frame went, in seconds. With several guesses the
/// parts add up all runs, which run side by side: they can exceed `total`.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FrameTiming {
    /// The whole frame.
    pub total: f64,
    /// Assigning voxels to their nearest centers (the Voronoi cells).
    pub assign: f64,
    /// Fitting the centers' rigid motions.
    pub fit: f64,
    /// Updating the affinity at the frame's final positions.
    pub affinity: f64,
    /// Iterations of the run that was kept.
    pub iterations: usize,
    /// Iterations of the runs from the other guesses, dropped (0 with one guess).
    pub dropped_iterations: usize,
    /// The start of the kept run.
    pub kept_guess: Guess,
}

/// ρ_p in the input's units (see [`crate::params::TrackParams::rho_p`]), from the
/// occupied volume of frame `placed`, the one the centers are placed in.
fn rho_p(
    params: &crate::params::TrackParams,
    seq: &crate::voxel::VoxelSequence,
    placed: usize,
    scale: crate::math::Real,
) -> crate::math::Real {
    params.rho_p_in_units(
        scale,
        seq.frames[placed].len() as crate::math::Real * seq.grid.voxel_size.powi(3),
    )
}
