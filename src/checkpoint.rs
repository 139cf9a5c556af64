//! Saving a long run's state as it goes and resuming from it: where the
//! files live ([`Checkpointing`]) and the binary format both stages' files
//! share (`track::checkpoint`: the frame loop; `refine::checkpoint`: the
//! batches of the global optimisation).
//!
//! A file is a magic tag naming its kind and format version, the state
//! (little-endian; floats as their bits, so a resumed run continues with
//! exactly the numbers the interrupted one had) and a checksum of all of it
//! (64-bit FNV-1a, which tells apart any two files differing in one byte),
//! so a damaged file is refused rather than resumed. Files are replaced
//! atomically: a kill mid-write leaves the previous one.

use crate::error::{Error, Result};
use crate::math::Real;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Where and how often a run saves its state.
#[derive(Clone, Debug)]
pub struct Checkpointing {
    /// Folder of the checkpoint files ([`CHECKPOINT_FILE`] for tracking,
    /// [`REFINE_CHECKPOINT_FILE`] for refinement); created if missing.
    pub dir: PathBuf,
    /// Save tracking after every this many tracked frames (and when
    /// interrupted, and when tracking ends). Default 10; >= 1.
    pub every: usize,
    /// Refinement saves after every batch, when interrupted, and within a
    /// batch after the first iteration that ends this many seconds after
    /// the last save (an iteration over thousands of frames takes minutes).
    /// Default [`REFINE_SAVE_SECONDS`]; >= 0.
    pub refine_save_seconds: Real,
    /// Continue from the checkpoints in `dir` (which must match the input and
    /// parameters) instead of starting over; without one, start over.
    /// Default false.
    pub resume: bool,
}

impl Checkpointing {
    /// Checkpoints in `dir`, with the other fields at their defaults.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Checkpointing {
            dir: dir.into(),
            every: 10,
            refine_save_seconds: REFINE_SAVE_SECONDS,
            resume: false,
        }
    }

    /// The tracking checkpoint file inside `dir`.
    pub fn path(&self) -> PathBuf {
        self.dir.join(CHECKPOINT_FILE)
    }

    /// The refinement checkpoint file inside `dir`.
    pub fn refine_path(&self) -> PathBuf {
        self.dir.join(REFINE_CHECKPOINT_FILE)
    }
}

/// Name of the tracking checkpoint file inside the checkpoint folder.
pub const CHECKPOINT_FILE: &str = "track.ckpt";
/// Name of the refinement checkpoint file inside the checkpoint folder.
pub const REFINE_CHECKPOINT_FILE: &str = "refine.ckpt";
/// How every checkpoint file starts, whatever its kind and format version:
/// a file of a checkpoint's name that does not may not be replaced.
pub(crate) const MARK: &[u8] = b"voltrack-";
/// Default of [`Checkpointing::refine_save_seconds`].
pub const REFINE_SAVE_SECONDS: Real = 60.0;

/// 64-bit FNV-1a.
pub(crate) struct Fnv(pub u64);

impl Fnv {
    pub(crate) fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// The start of a run's fingerprint: the tool's version, a stage's
    /// parameters and the grid.
    pub(crate) fn run(params: &impl serde::Serialize, grid: &crate::model::GridSpec) -> Self {
        let mut h = Fnv::new();
        h.bytes(env!("CARGO_PKG_VERSION").as_bytes());
        h.bytes(
            serde_json::to_string(params)
                .expect("parameters serialise")
                .as_bytes(),
        );
        for d in grid.dims {
            h.bytes(&(d as u64).to_le_bytes());
        }
        for c in [grid.origin.x, grid.origin.y, grid.origin.z, grid.voxel_size] {
            h.bytes(&c.to_bits().to_le_bytes());
        }
        h
    }
}

/// A writer that hashes what passes through it.
struct Hashing<'w, W: Write> {
    inner: &'w mut W,
    hash: Fnv,
}

impl<W: Write> Write for Hashing<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hash.bytes(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Writes `path` atomically (creating its folder): `magic`, what `state`
/// writes, then the checksum of both. A link at `path` is replaced, never
/// followed.
pub(crate) fn save(
    path: &Path,
    magic: &[u8],
    state: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    crate::files::write_replacing(path, |file| {
        let mut hashed = Hashing {
            inner: file,
            hash: Fnv::new(),
        };
        hashed.write_all(magic)?;
        state(&mut hashed)?;
        let sum = hashed.hash.0;
        put_u64(file, sum)
    })
}

/// Reads `path` back: its state after `magic`, once the tag and the checksum
/// are checked. `kind` names the file in messages ("tracking checkpoint").
pub(crate) fn load(path: &Path, magic: &[u8], kind: &str) -> Result<Vec<u8>> {
    let mut bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if !bytes.starts_with(magic) {
        return Err(Error::parse(
            path,
            None,
            format!("not a voltrack {kind} (or one of another format version)"),
        ));
    }
    let Some((state, sum)) = bytes
        .split_last_chunk::<8>()
        .filter(|(state, _)| state.len() > magic.len())
    else {
        return Err(Error::parse(path, None, "checkpoint is truncated"));
    };
    let mut hash = Fnv::new();
    hash.bytes(state);
    if hash.0 != u64::from_le_bytes(*sum) {
        return Err(Error::parse(
            path,
            None,
            "the checkpoint is damaged (its checksum does not match); drop --resume to start over",
        ));
    }
    bytes.truncate(bytes.len() - 8);
    bytes.drain(..magic.len());
    Ok(bytes)
}

pub(crate) fn put_u64(w: &mut (impl Write + ?Sized), v: u64) -> std::io::Result<()> {
    w.write_all(&v.to_le_bytes())
}

pub(crate) fn put_reals(w: &mut (impl Write + ?Sized), v: &[Real]) -> std::io::Result<()> {
    v.iter()
        .try_for_each(|x| w.write_all(&x.to_bits().to_le_bytes()))
}

pub(crate) fn put_u32s(w: &mut (impl Write + ?Sized), v: &[u32]) -> std::io::Result<()> {
    v.iter().try_for_each(|x| w.write_all(&x.to_le_bytes()))
}

/// Reads little-endian values, failing with the file's name when it ends early.
pub(crate) struct Reader<'a> {
    pub bytes: &'a [u8],
    pub at: usize,
    pub path: &'a Path,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8], path: &'a Path) -> Self {
        Reader { bytes, at: 0, path }
    }
    pub(crate) fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| Error::parse(self.path, None, "checkpoint is truncated"))?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub(crate) fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    pub(crate) fn usize(&mut self) -> Result<usize> {
        usize::try_from(self.u64()?)
            .map_err(|_| Error::parse(self.path, None, "count out of range"))
    }
    pub(crate) fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    pub(crate) fn u32s(&mut self, n: usize) -> Result<Vec<u32>> {
        (0..n).map(|_| self.u32()).collect()
    }
    pub(crate) fn real(&mut self) -> Result<Real> {
        Ok(Real::from_bits(self.u64()?))
    }
    /// Fails unless every byte was read.
    pub(crate) fn finish(&self, what: &str) -> Result<()> {
        if self.at != self.bytes.len() {
            return Err(Error::parse(
                self.path,
                None,
                format!("trailing bytes after the {what}"),
            ));
        }
        Ok(())
    }
}
