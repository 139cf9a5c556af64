//! Saving and resuming the tracker between frames, for long runs and Ctrl-C.
//!
//! A checkpoint holds everything the frame loop carries from one frame to the
//! next: the trajectories so far, each frame's cell counts and timings, the
//! affinity state and the voxel owners of the last tracked frame. Floats are
//! stored as their bits, so a resumed run continues with exactly the numbers
//! the interrupted one had and ends byte-identical to an uninterrupted run.
//! A fingerprint of the voxels and parameters keeps a checkpoint from
//! resuming a different run, and a checksum of the whole file (64-bit
//! FNV-1a, which tells apart any two files differing in one byte) keeps a
//! damaged one from resuming.

use super::affinity::{Affinity, Neighbor};
use super::FrameTiming;
use crate::checkpoint::{put_reals, put_u32s, put_u64, Fnv, Reader};
pub use crate::checkpoint::{Checkpointing, CHECKPOINT_FILE};
use crate::error::{Error, Result};
use crate::math::Point3;
use crate::model::Trajectories;
use crate::params::{AffinityKind, TrackParams};
use crate::voxel::VoxelSequence;
use std::io::Write;

const MAGIC: &[u8; 16] = b"voltrack-track\0\x03";

/// What the tracker has done so far, borrowed for saving.
pub(super) struct Snapshot<'a> {
    pub frames_done: usize,
    pub trajectories: &'a Trajectories,
    pub cell_counts: &'a [Vec<u32>],
    pub timings: &'a [FrameTiming],
    pub affinity: &'a Affinity,
    pub owners: &'a [u32],
}

/// A checkpoint read back.
pub(super) struct Restored {
    pub frames_done: usize,
    /// Frames `0..frames_done` filled in; the rest at the origin.
    pub trajectories: Trajectories,
    pub cell_counts: Vec<Vec<u32>>,
    pub timings: Vec<FrameTiming>,
    pub affinity: Affinity,
    pub owners: Vec<u32>,
}

impl Restored {
    /// A fresh start (one frame done) for a tracking of `frames` frames
    /// from the same placement.
    pub(super) fn for_frames(&self, frames: usize) -> Restored {
        debug_assert_eq!(self.frames_done, 1);
        let mut trajectories = Trajectories::new(frames, self.trajectories.centers);
        trajectories
            .frame_mut(0)
            .copy_from_slice(self.trajectories.frame(0));
        Restored {
            frames_done: 1,
            trajectories,
            cell_counts: self.cell_counts.clone(),
            timings: self.timings.clone(),
            affinity: self.affinity.clone(),
            owners: self.owners.clone(),
        }
    }
}

/// 64-bit FNV-1a over the tool version, the parameters, the grid and every
/// frame's occupied voxels: two runs with the same fingerprint track the same
/// way.
pub(super) fn fingerprint(seq: &VoxelSequence, params: &TrackParams) -> u64 {
    let mut h = Fnv::run(params, &seq.grid);
    for frame in &seq.frames {
        h.bytes(&(frame.len() as u64).to_le_bytes());
        for v in frame.iter() {
            h.bytes(&v.to_le_bytes());
        }
    }
    h.0
}

/// Writes the checkpoint atomically (a kill mid-write leaves the previous one).
pub(super) fn save(ckpt: &Checkpointing, fingerprint: u64, s: &Snapshot) -> Result<()> {
    crate::checkpoint::save(&ckpt.path(), MAGIC, |w| write_state(w, fingerprint, s))
}

/// The checkpoint's content before its checksum.
fn write_state(w: &mut dyn Write, fingerprint: u64, s: &Snapshot) -> std::io::Result<()> {
    let traj = s.trajectories;
    put_u64(w, fingerprint)?;
    for n in [traj.frames, traj.centers, s.frames_done] {
        put_u64(w, n as u64)?;
    }
    for p in &traj.positions[..s.frames_done * traj.centers] {
        put_reals(w, p.coords.as_slice())?;
    }
    for counts in &s.cell_counts[..s.frames_done] {
        put_u32s(w, counts)?;
    }
    for t in &s.timings[..s.frames_done] {
        put_reals(w, &[t.total, t.assign, t.fit, t.affinity])?;
        put_u64(w, t.iterations as u64)?;
        put_u64(w, t.dropped_iterations as u64)?;
        put_u64(w, t.kept_guess.code())?;
    }
    let a = s.affinity;
    put_u64(w, a.lists.len() as u64)?;
    for list in &a.lists {
        put_u64(w, list.len() as u64)?;
        for n in list {
            put_u32s(w, &[n.j])?;
            put_reals(w, &[n.w, n.max_d2, n.max_m2])?;
        }
    }
    put_u64(w, a.iir.len() as u64)?;
    for v in &a.iir {
        w.write_all(&v.to_bits().to_le_bytes())?;
    }
    put_u32s(w, s.owners)
}

/// Reads the checkpoint of `ckpt` back, checking it belongs to this run.
pub(super) fn load(
    ckpt: &Checkpointing,
    fingerprint: u64,
    seq: &VoxelSequence,
    params: &TrackParams,
) -> Result<Restored> {
    let path = ckpt.path();
    let bytes = crate::checkpoint::load(&path, MAGIC, "tracking checkpoint")?;
    let mut r = Reader::new(&bytes, &path);
    if r.u64()? != fingerprint {
        return Err(Error::InvalidInput(format!(
            "{}: the checkpoint was saved for different input, resolution or tracking parameters; \
             run the same command as before, or drop --resume to start over",
            path.display()
        )));
    }
    let (frames, centers, frames_done) = (r.usize()?, r.usize()?, r.usize()?);
    if frames != seq.frames.len()
        || centers != params.centers
        || frames_done == 0
        || frames_done > frames
    {
        return Err(Error::parse(
            &path,
            None,
            format!("inconsistent header: {frames_done} of {frames} frames, {centers} centers"),
        ));
    }
    let mut trajectories = Trajectories::new(frames, centers);
    for p in &mut trajectories.positions[..frames_done * centers] {
        *p = Point3::new(r.real()?, r.real()?, r.real()?);
    }
    let cell_counts = (0..frames_done)
        .map(|_| r.u32s(centers))
        .collect::<Result<_>>()?;
    let timings = (0..frames_done)
        .map(|_| {
            Ok(FrameTiming {
                total: r.real()?,
                assign: r.real()?,
                fit: r.real()?,
                affinity: r.real()?,
                iterations: r.usize()?,
                dropped_iterations: r.usize()?,
                kept_guess: guess(&mut r)?,
            })
        })
        .collect::<Result<_>>()?;
    if r.usize()? != centers {
        return Err(Error::parse(
            &path,
            None,
            "affinity lists do not match the number of centers",
        ));
    }
    let lists = (0..centers)
        .map(|_| {
            let len = r.usize()?;
            (0..len)
                .map(|_| {
                    let j = r.u32()?;
                    if j as usize >= centers {
                        return Err(Error::parse(
                            &path,
                            None,
                            format!("neighbour {j} out of range"),
                        ));
                    }
                    Ok(Neighbor {
                        j,
                        w: r.real()?,
                        max_d2: r.real()?,
                        max_m2: r.real()?,
                    })
                })
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    let iir_len = r.usize()?;
    let expected = if params.affinity == AffinityKind::Iir {
        centers * centers
    } else {
        0
    };
    if iir_len != expected {
        return Err(Error::parse(
            &path,
            None,
            "affinity filter state does not match the affinity kind",
        ));
    }
    let iir = (0..iir_len)
        .map(|_| Ok(f32::from_bits(r.u32()?)))
        .collect::<Result<_>>()?;
    let owners = r.u32s(seq.frames[frames_done - 1].len())?;
    r.finish("tracker state")?;
    let scale = params.length_scale(&seq.bounds);
    let affinity = Affinity::restore(
        params.affinity,
        super::rho_p(params, seq, 0, scale),
        params.rho_m * scale,
        params.alpha,
        params.mu,
        lists,
        iir,
    );
    Ok(Restored {
        frames_done,
        trajectories,
        cell_counts,
        timings,
        affinity,
        owners,
    })
}

fn guess(r: &mut Reader) -> Result<super::Guess> {
    let code = r.u64()?;
    super::Guess::from_code(code)
        .ok_or_else(|| Error::parse(r.path, None, format!("unknown guess {code}")))
}
