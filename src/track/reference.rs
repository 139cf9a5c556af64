//! The reference frame: where the centers are placed and whose mesh the
//! result deforms (issue 47). The tracking runs from it to the last frame and
//! from it back to the first (`forward::track_with_checkpoints`).
//!
//! Why not always frame 0: the result keeps the reference's connectivity for
//! the whole take, so two things that touch in it (hands clasped at the
//! start, a ball held, then thrown) stay joined by a stretched membrane once
//! they part. Separate things in the reference can merge later and part
//! again without harm: their surfaces then overlap, hidden, as the tracked
//! volumes do.

use crate::error::{Error, Result};
use crate::params::{Reference, TrackParams};
use crate::voxel::{frame_topology, FrameTopology, VoxelSequence};
use rayon::prelude::*;

/// The reference frame a tracking used, and why.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReferenceChoice {
    /// The frame, from 0.
    pub frame: usize,
    /// What was asked for.
    pub asked: Reference,
    /// Each frame's parts and tunnels, when [`Reference::Auto`] measured
    /// them (empty otherwise).
    pub topology: Vec<FrameTopology>,
    /// Why this frame, in a sentence for messages and the report.
    pub why: String,
}

/// The reference frame `params.reference` asks for on `seq`.
/// [`Reference::Auto`] measures every frame's parts and tunnels
/// ([`frame_topology`], parts smaller than half a center's share of the
/// frame's volume left out: no center could follow them) and takes the
/// earliest frame of the largest [`FrameTopology::separation`]. With
/// `checkpointing`, `Auto` is frame 0 (a checkpoint holds one forward
/// tracking) and any other frame an error.
pub fn choose_reference(
    seq: &VoxelSequence,
    params: &TrackParams,
    checkpointing: bool,
) -> Result<ReferenceChoice> {
    let frames = seq.frames.len();
    let asked = params.reference;
    let given = |frame: usize, why: String| ReferenceChoice {
        frame,
        asked,
        topology: Vec::new(),
        why,
    };
    check_reference(asked, frames, checkpointing)?;
    match asked {
        Reference::First => Ok(given(0, "the first frame, as asked".into())),
        Reference::Frame(r) => Ok(given(r, format!("frame {r}, as asked"))),
        Reference::Auto if checkpointing => Ok(given(
            0,
            "the first frame: with checkpoints the tracking starts there".into(),
        )),
        Reference::Auto => {
            let topology = frame_topologies(seq, params.centers);
            let best = topology.iter().map(FrameTopology::separation).max();
            let frame = topology
                .iter()
                .position(|t| Some(t.separation()) == best)
                .unwrap_or(0);
            let t = topology.get(frame).copied().unwrap_or_default();
            let parts = |u: &FrameTopology| {
                format!(
                    "{} part{}, {} tunnel{}",
                    u.parts,
                    plural(u.parts),
                    u.tunnels,
                    plural(u.tunnels)
                )
            };
            let why = if frame == 0 {
                format!(
                    "the first frame, whose parts are as separate as any frame's ({})",
                    parts(&t)
                )
            } else {
                format!(
                    "the first frame whose parts are most separate ({}; frame 0: {})",
                    parts(&t),
                    parts(&topology[0])
                )
            };
            log::info!("reference frame {frame} ({}): {why}", seq.names[frame]);
            Ok(ReferenceChoice {
                frame,
                asked,
                topology,
                why,
            })
        }
    }
}

/// Every frame's parts and tunnels ([`frame_topology`]), parts smaller than
/// half a center's share of the frame's voxels (of `centers` centers) left
/// out: no center could follow them.
pub fn frame_topologies(seq: &VoxelSequence, centers: usize) -> Vec<FrameTopology> {
    seq.frames
        .par_iter()
        .map(|frame| {
            let indices = frame.indices();
            let speck = indices.len() / (2 * centers.max(1));
            frame_topology(&seq.grid, &indices, speck.max(1))
        })
        .collect()
}

/// Whether `reference` can be the reference of a sequence of `frames`
/// frames, tracked with checkpoints or not: found before any frame is read.
pub fn check_reference(reference: Reference, frames: usize, checkpointing: bool) -> Result<()> {
    match reference {
        Reference::Frame(r) if r >= frames => Err(Error::InvalidParameter(format!(
            "reference frame {r} is past the last frame ({})",
            frames.saturating_sub(1)
        ))),
        Reference::Frame(r) if r > 0 && checkpointing => Err(Error::InvalidParameter(format!(
            "reference frame {r} with checkpoints: a checkpoint holds a tracking from the first frame; leave out the checkpoints or the reference"
        ))),
        _ => Ok(()),
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}
