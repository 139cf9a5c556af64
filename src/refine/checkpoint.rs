//! Saving and resuming refinement between iterations of the global
//! optimisation (`Checkpointing::refine_path`), so a long run interrupted in
//! refinement resumes there instead of at its first batch.
//!
//! The file holds what carries from one iteration to the next: the batches
//! finished, the remaining centers' trajectories, which centers were
//! removed, the energy histories and, within a batch, that batch's ω (it was
//! computed from the trajectories at the batch's start, which the file no
//! longer holds). The cells need not be saved: the kept assignments give the
//! same cells as fresh ones (`refine::cells`). A resumed run therefore ends
//! bit-identical to an uninterrupted one. A fingerprint of the tracked
//! trajectories, the grid and the parameters keeps a file from resuming a
//! different run; the format's checksum keeps a damaged one from resuming.

use super::global::Iteration;
use super::SparseAffinity;
use crate::checkpoint::{put_reals, put_u32s, put_u64, Checkpointing, Fnv, Reader};
use crate::error::{Error, Result};
use crate::math::Point3;
use crate::model::Trajectories;
use crate::params::RefineParams;
use crate::voxel::VoxelSequence;
use std::io::Write;

const MAGIC: &[u8; 16] = b"voltrack-refine\x01";

/// Refinement's state, borrowed for saving.
pub(super) struct Snapshot<'a> {
    /// Batches finished.
    pub batches_done: usize,
    pub trajectories: &'a Trajectories,
    /// Original index of each remaining center.
    pub kept: &'a [usize],
    /// Original indices of the removed centers, in removal order.
    pub removed: &'a [usize],
    /// The finished batches' energy histories.
    pub finished: &'a [Vec<Iteration>],
    /// The batch in progress (its removal done): its ω and its history so far.
    pub current: Option<(&'a SparseAffinity, &'a [Iteration])>,
    /// Seconds spent refining so far.
    pub seconds: f64,
}

impl Restored {
    /// The state before the first batch: every tracked center kept.
    pub(super) fn fresh(tracked: Trajectories) -> Self {
        Restored {
            batches_done: 0,
            kept: (0..tracked.centers).collect(),
            trajectories: tracked,
            removed: Vec::new(),
            finished: Vec::new(),
            current: None,
            seconds: 0.0,
        }
    }
}

/// A state read back.
pub(super) struct Restored {
    pub batches_done: usize,
    pub trajectories: Trajectories,
    pub kept: Vec<usize>,
    pub removed: Vec<usize>,
    pub finished: Vec<Vec<Iteration>>,
    pub current: Option<(SparseAffinity, Vec<Iteration>)>,
    pub seconds: f64,
}

/// 64-bit FNV-1a over the tool version, the parameters, the grid, every
/// frame's number of occupied voxels and the tracked trajectories: two runs
/// with the same fingerprint refine the same way.
pub(super) fn fingerprint(
    tracked: &Trajectories,
    seq: &VoxelSequence,
    params: &RefineParams,
) -> u64 {
    let mut h = Fnv::run(params, &seq.grid);
    for frame in &seq.frames {
        h.bytes(&(frame.len() as u64).to_le_bytes());
    }
    h.bytes(&(tracked.frames as u64).to_le_bytes());
    h.bytes(&(tracked.centers as u64).to_le_bytes());
    for p in &tracked.positions {
        for c in p.coords.iter() {
            h.bytes(&c.to_bits().to_le_bytes());
        }
    }
    h.0
}

/// Writes the state atomically (a kill mid-write leaves the previous one).
pub(super) fn save(ckpt: &Checkpointing, fingerprint: u64, s: &Snapshot) -> Result<()> {
    crate::checkpoint::save(&ckpt.refine_path(), MAGIC, |w| {
        write_state(w, fingerprint, s)
    })
}

fn write_state(w: &mut dyn Write, fingerprint: u64, s: &Snapshot) -> std::io::Result<()> {
    let traj = s.trajectories;
    put_u64(w, fingerprint)?;
    for n in [s.batches_done, traj.frames, traj.centers, s.removed.len()] {
        put_u64(w, n as u64)?;
    }
    for p in &traj.positions {
        put_reals(w, p.coords.as_slice())?;
    }
    for &i in s.kept.iter().chain(s.removed) {
        put_u64(w, i as u64)?;
    }
    put_u64(w, s.finished.len() as u64)?;
    for history in s.finished {
        put_history(w, history)?;
    }
    put_u64(w, s.current.is_some() as u64)?;
    if let Some((omega, history)) = s.current {
        for list in &omega.lists {
            put_u64(w, list.len() as u64)?;
            for &(j, weight) in list {
                put_u32s(w, &[j])?;
                put_reals(w, &[weight])?;
            }
        }
        put_history(w, history)?;
    }
    put_reals(w, &[s.seconds])
}

fn put_history(w: &mut dyn Write, history: &[Iteration]) -> std::io::Result<()> {
    put_u64(w, history.len() as u64)?;
    history
        .iter()
        .try_for_each(|it| put_reals(w, &[it.energy, it.smooth, it.data, it.lambda]))
}

/// Reads the state of `ckpt` back, checking it belongs to this run: refining
/// `tracked` (`centers` at the start) with `params` into `batches` batches.
pub(super) fn load(
    ckpt: &Checkpointing,
    fingerprint: u64,
    tracked: &Trajectories,
    batches: usize,
) -> Result<Restored> {
    let path = ckpt.refine_path();
    let bytes = crate::checkpoint::load(&path, MAGIC, "refinement checkpoint")?;
    let mut r = Reader::new(&bytes, &path);
    if r.u64()? != fingerprint {
        return Err(Error::InvalidInput(format!(
            "{}: the refinement checkpoint was saved for different tracking or refinement parameters; \
             run the same command as before, or drop --resume to start over",
            path.display()
        )));
    }
    let bad = |message: String| Error::parse(&path, None, message);
    let (batches_done, frames, centers, removed) = (r.usize()?, r.usize()?, r.usize()?, r.usize()?);
    if batches_done > batches
        || frames != tracked.frames
        || centers.checked_add(removed) != Some(tracked.centers)
    {
        return Err(bad(format!("inconsistent header: {batches_done} of {batches} batches, {frames} frames, {centers} + {removed} centers")));
    }
    let mut trajectories = Trajectories::new(frames, centers);
    for p in &mut trajectories.positions {
        *p = Point3::new(r.real()?, r.real()?, r.real()?);
    }
    let original = |r: &mut Reader| -> Result<usize> {
        let i = r.usize()?;
        if i >= tracked.centers {
            return Err(bad(format!("center {i} out of range")));
        }
        Ok(i)
    };
    let kept = (0..centers)
        .map(|_| original(&mut r))
        .collect::<Result<_>>()?;
    let removed = (0..removed)
        .map(|_| original(&mut r))
        .collect::<Result<_>>()?;
    let finished_len = r.usize()?;
    if finished_len > batches_done {
        return Err(bad(format!(
            "{finished_len} histories for {batches_done} batches"
        )));
    }
    let finished = (0..finished_len)
        .map(|_| history(&mut r))
        .collect::<Result<_>>()?;
    let current = match r.u64()? {
        0 => None,
        1 if batches_done < batches => {
            let lists = (0..centers)
                .map(|_| {
                    let len = r.usize()?;
                    if len > centers {
                        return Err(bad(format!("{len} neighbours for {centers} centers")));
                    }
                    (0..len)
                        .map(|_| {
                            let j = r.u32()?;
                            if j as usize >= centers {
                                return Err(bad(format!("neighbour {j} out of range")));
                            }
                            Ok((j, r.real()?))
                        })
                        .collect::<Result<Vec<_>>>()
                })
                .collect::<Result<_>>()?;
            Some((SparseAffinity { lists }, history(&mut r)?))
        }
        flag => return Err(bad(format!("unexpected batch-in-progress flag {flag}"))),
    };
    let seconds = r.real()?;
    r.finish("refinement state")?;
    Ok(Restored {
        batches_done,
        trajectories,
        kept,
        removed,
        finished,
        current,
        seconds,
    })
}

fn history(r: &mut Reader) -> Result<Vec<Iteration>> {
    let len = r.usize()?;
    if len > r.bytes.len() {
        return Err(Error::parse(r.path, None, "history longer than the file"));
    }
    (0..len)
        .map(|_| {
            Ok(Iteration {
                energy: r.real()?,
                smooth: r.real()?,
                data: r.real()?,
                lambda: r.real()?,
            })
        })
        .collect()
}
