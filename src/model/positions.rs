//! The vertex positions of an animated mesh, frame by frame: in memory, or in
//! a temporary file of the process's own when the sequence would not fit the
//! memory allowed, so that deforming, fitting and exporting a long capture
//! holds a few frames at a time instead of all of them.
//!
//! Positions are stored as the f64 they are computed in, so a sequence kept
//! in a file reads back bit for bit and every output is the same either way.
//! The same store ([`FrameStore`]) holds the global optimisation's gradients,
//! one vector per center and frame.

use crate::error::{Error, Result};
use crate::math::{Point3, Real, Vector3};
use crate::model::mesh::Aabb;
use std::borrow::Cow;
use std::fs::File;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Bytes one vertex position (or any [`Triple`]) takes, in memory and in the file.
pub const POSITION_BYTES: usize = 24;

/// What a [`FrameStore`] holds: three reals, a point or a vector.
pub trait Triple: Copy + std::fmt::Debug + PartialEq {
    /// The three components, x, y, z.
    fn to_array(self) -> [Real; 3];
    /// The value of three components, x, y, z.
    fn from_array(a: [Real; 3]) -> Self;
}

impl Triple for Point3 {
    fn to_array(self) -> [Real; 3] {
        [self.x, self.y, self.z]
    }
    fn from_array(a: [Real; 3]) -> Self {
        Point3::new(a[0], a[1], a[2])
    }
}

impl Triple for Vector3 {
    fn to_array(self) -> [Real; 3] {
        [self.x, self.y, self.z]
    }
    fn from_array(a: [Real; 3]) -> Self {
        Vector3::new(a[0], a[1], a[2])
    }
}

/// Every frame's vertex positions.
pub type PositionFrames = FrameStore<Point3>;

/// A sequence of frames of `T`s (positions, or vectors). Frames are appended
/// in order ([`push`](Self::push)) and may be replaced
/// ([`replace`](Self::replace)); reading one ([`get`](Self::get),
/// [`rows`](Self::rows)) borrows it from memory or reads it from the file.
#[derive(Debug)]
pub struct FrameStore<T: Triple> {
    storage: Storage<T>,
    len: usize,
}

#[derive(Debug)]
enum Storage<T> {
    /// Frames held as vectors (of any length: the writers check them).
    Memory(Vec<Vec<T>>),
    /// Frames of `vertices` positions each, frame f at byte
    /// f × vertices × [`POSITION_BYTES`].
    File { scratch: Scratch, vertices: usize },
}

/// A temporary file only this process uses. On Unix its name is removed as
/// soon as it is open, so nothing is left behind whatever ends the process;
/// elsewhere it is removed when dropped.
#[derive(Debug)]
struct Scratch {
    file: File,
    /// Where it is, for messages.
    path: PathBuf,
    /// Seeking and reading are two calls without Unix's positioned I/O.
    #[cfg(not(unix))]
    lock: std::sync::Mutex<()>,
}

impl Scratch {
    fn create() -> Result<Self> {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir();
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!(".voltrack-frames-{}-{n}", std::process::id()));
        // create_new: never opens a file that is already there.
        let file = std::fs::OpenOptions::new().read(true).write(true).create_new(true).open(&path).map_err(|e| {
            Error::io(&path, std::io::Error::new(e.kind(), format!("cannot create a temporary file for a long sequence's frames ({e}); set TMPDIR to a writable folder")))
        })?;
        #[cfg(unix)]
        let _ = std::fs::remove_file(&path);
        Ok(Scratch {
            file,
            path,
            #[cfg(not(unix))]
            lock: Default::default(),
        })
    }

    fn read_at(&self, buf: &mut [u8], offset: u64) -> Result<()> {
        #[cfg(unix)]
        let done = std::os::unix::fs::FileExt::read_exact_at(&self.file, buf, offset);
        #[cfg(not(unix))]
        let done = self.at(offset, |mut f| std::io::Read::read_exact(&mut f, buf));
        done.map_err(|e| Error::io(&self.path, e))
    }

    fn write_at(&self, buf: &[u8], offset: u64) -> Result<()> {
        #[cfg(unix)]
        let done = std::os::unix::fs::FileExt::write_all_at(&self.file, buf, offset);
        #[cfg(not(unix))]
        let done = self.at(offset, |mut f| std::io::Write::write_all(&mut f, buf));
        done.map_err(|e| Error::io(&self.path, e))
    }

    /// Seeks to `offset` and runs `op`, one caller at a time.
    #[cfg(not(unix))]
    fn at(
        &self,
        offset: u64,
        op: impl FnOnce(&File) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        let _one = self.lock.lock().unwrap_or_else(|e| e.into_inner());
        std::io::Seek::seek(&mut &self.file, std::io::SeekFrom::Start(offset))?;
        op(&self.file)
    }
}

#[cfg(not(unix))]
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

impl<T: Triple> FrameStore<T> {
    /// An empty sequence for `frames` frames of `vertices` positions (or
    /// vectors), kept in memory when they take at most `memory` bytes
    /// ([`POSITION_BYTES`] per vertex and frame), in a temporary file otherwise.
    pub fn new(vertices: usize, frames: usize, memory: usize) -> Result<Self> {
        let bytes = vertices
            .saturating_mul(frames)
            .saturating_mul(POSITION_BYTES);
        let storage = if bytes <= memory {
            Storage::Memory(Vec::with_capacity(frames))
        } else {
            log::debug!(
                "{frames} frames of {vertices} ({:.0} MiB) are kept in a temporary file",
                bytes as f64 / (1 << 20) as f64
            );
            Storage::File {
                scratch: Scratch::create()?,
                vertices,
            }
        };
        Ok(FrameStore { storage, len: 0 })
    }

    /// Checks that a temporary file for the frames can be made, so that a
    /// temporary folder that takes none fails before any work, not when a
    /// long sequence's mesh needs it.
    pub fn check_temporary_folder() -> Result<()> {
        Scratch::create()
            .map(drop)
            .map_err(|e| Error::InvalidParameter(e.to_string()))
    }

    /// Number of frames appended.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no frame has been appended.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the frames are in a temporary file rather than in memory.
    pub fn in_file(&self) -> bool {
        matches!(self.storage, Storage::File { .. })
    }

    /// Appends a frame; in a file, it must have as many positions as the
    /// sequence was made for.
    pub fn push(&mut self, frame: Vec<T>) -> Result<()> {
        match &mut self.storage {
            Storage::Memory(frames) => frames.push(frame),
            Storage::File { scratch, vertices } => {
                check_length(*vertices, &frame, self.len)?;
                scratch.write_at(&encode(&frame), offset(*vertices, self.len, 0))?;
            }
        }
        self.len += 1;
        Ok(())
    }

    /// Replaces frame `f` (`f < len()`) by one of the same length.
    pub fn replace(&mut self, f: usize, frame: Vec<T>) -> Result<()> {
        assert!(f < self.len, "frame {f} of {}", self.len);
        match &mut self.storage {
            Storage::Memory(frames) => {
                check_length(frames[f].len(), &frame, f)?;
                frames[f] = frame;
            }
            Storage::File { scratch, vertices } => {
                check_length(*vertices, &frame, f)?;
                scratch.write_at(&encode(&frame), offset(*vertices, f, 0))?;
            }
        }
        Ok(())
    }

    /// Frame `f` (`f < len()`).
    pub fn get(&self, f: usize) -> Result<Cow<'_, [T]>> {
        match &self.storage {
            Storage::Memory(frames) => Ok(Cow::Borrowed(&frames[f])),
            Storage::File { vertices, .. } => self.rows(f, 0..*vertices),
        }
    }

    /// Positions `range` of frame `f` (`f < len()`, the range within the
    /// frame): a block of vertices, read without the rest of the frame.
    pub fn rows(&self, f: usize, range: Range<usize>) -> Result<Cow<'_, [T]>> {
        assert!(f < self.len, "frame {f} of {}", self.len);
        match &self.storage {
            Storage::Memory(frames) => Ok(Cow::Borrowed(&frames[f][range])),
            Storage::File { scratch, vertices } => {
                assert!(range.end <= *vertices, "positions {range:?} of {vertices}");
                let mut bytes = vec![0u8; range.len() * POSITION_BYTES];
                scratch.read_at(&mut bytes, offset(*vertices, f, range.start))?;
                Ok(Cow::Owned(decode(&bytes)))
            }
        }
    }

    /// Every frame, in order, read one at a time.
    pub fn iter(&self) -> impl Iterator<Item = Result<Cow<'_, [T]>>> + '_ {
        (0..self.len).map(|f| self.get(f))
    }

    /// All frames as vectors (for short sequences and tests).
    pub fn to_vec(&self) -> Result<Vec<Vec<T>>> {
        self.iter().map(|f| f.map(Cow::into_owned)).collect()
    }
}

impl PositionFrames {
    /// The box around every position of every frame.
    pub fn bounds(&self) -> Result<Aabb> {
        let mut all = Aabb::empty();
        for frame in self.iter() {
            frame?.iter().for_each(|p| all.grow(p));
        }
        Ok(all)
    }
}

impl<T: Triple> From<Vec<Vec<T>>> for FrameStore<T> {
    /// Frames already in memory, kept there.
    fn from(frames: Vec<Vec<T>>) -> Self {
        FrameStore {
            len: frames.len(),
            storage: Storage::Memory(frames),
        }
    }
}

impl<T: Triple> FromIterator<Vec<T>> for FrameStore<T> {
    /// Frames collected in memory.
    fn from_iter<I: IntoIterator<Item = Vec<T>>>(frames: I) -> Self {
        FrameStore::from(frames.into_iter().collect::<Vec<_>>())
    }
}

fn check_length<T>(vertices: usize, frame: &[T], f: usize) -> Result<()> {
    if frame.len() != vertices {
        return Err(Error::InvalidInput(format!(
            "frame {f} has {} vertices, the mesh {vertices}",
            frame.len()
        )));
    }
    Ok(())
}

fn offset(vertices: usize, f: usize, first: usize) -> u64 {
    ((f * vertices + first) * POSITION_BYTES) as u64
}

fn encode<T: Triple>(frame: &[T]) -> Vec<u8> {
    frame
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f64::to_le_bytes)
        .collect()
}

fn decode<T: Triple>(bytes: &[u8]) -> Vec<T> {
    bytes
        .chunks_exact(POSITION_BYTES)
        .map(|b| {
            let c = |k: usize| f64::from_le_bytes(b[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            T::from_array([c(0), c(1), c(2)])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(f: usize, n: usize) -> Vec<Point3> {
        (0..n)
            .map(|v| Point3::new(f as f64 + 0.1, v as f64 * 1e-3, -(v as f64).sqrt() / 7.0))
            .collect()
    }

    #[test]
    fn a_file_reads_back_what_memory_holds() {
        let (n, frames) = (37, 5);
        let mut memory = PositionFrames::new(n, frames, usize::MAX).unwrap();
        let mut file = PositionFrames::new(n, frames, 0).unwrap();
        assert!(!memory.in_file() && file.in_file());
        for f in 0..frames {
            memory.push(frame(f, n)).unwrap();
            file.push(frame(f, n)).unwrap();
        }
        memory.replace(3, frame(9, n)).unwrap();
        file.replace(3, frame(9, n)).unwrap();
        assert_eq!(memory.to_vec().unwrap(), file.to_vec().unwrap());
        assert_eq!(file.get(3).unwrap().as_ref(), &frame(9, n)[..]);
        assert_eq!(file.rows(4, 10..20).unwrap().as_ref(), &frame(4, n)[10..20]);
        assert!(file.push(frame(0, n + 1)).is_err());
        assert!(file.replace(0, frame(0, n - 1)).is_err());
        assert_eq!(file.len(), frames);
    }
}
