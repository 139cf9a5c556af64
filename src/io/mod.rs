//! Reading sequences: which files, in which order, and each file's contents.

mod binvox;
pub mod exr;
mod gltf;
mod obj;
mod ply;
mod polygon;
mod sequence;

pub use binvox::read_binvox;
pub use gltf::read_gltf;
pub use obj::read_obj;
pub use ply::read_ply;
pub(crate) use polygon::triangulate_polygon;
pub use sequence::{discover_frames, sequence_name};
pub(crate) use sequence::{is_supported, would_discover};

use crate::error::{Error, Result};
use crate::model::mesh::TriangleMesh;
use crate::model::Frame;
use crate::model::FrameSource;
use std::path::{Path, PathBuf};

/// `bytes` without a leading UTF-8 byte-order mark, which some editors write
/// and which would otherwise glue itself to the first word.
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes)
}

/// `bytes` with every classic-Mac line end (a CR not followed by LF) turned
/// into LF, so line-based readers see, and count, the lines an editor shows.
/// The length is kept, so byte offsets stay valid.
pub(crate) fn lone_cr_to_lf(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let lone = |i: usize| bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n');
    if !(0..bytes.len()).any(lone) {
        return std::borrow::Cow::Borrowed(bytes);
    }
    std::borrow::Cow::Owned(
        (0..bytes.len())
            .map(|i| if lone(i) { b'\n' } else { bytes[i] })
            .collect(),
    )
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Reads one frame, choosing the format by extension.
pub fn read_frame(path: &Path) -> Result<Frame> {
    let ext = extension(path);
    if !is_supported(path) {
        return Err(Error::UnsupportedFormat {
            path: path.to_path_buf(),
        });
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.is_empty() {
        return Err(Error::parse(path, None, "the file is empty"));
    }
    // The parsers are ours or well fuzzed, but a panic on hostile input must
    // still become an error that names the file.
    let parsed = std::panic::catch_unwind(|| match ext.as_str() {
        "obj" => read_obj(path, &bytes).map(Frame::Mesh),
        "ply" => read_ply(path, &bytes).map(Frame::Mesh),
        "gltf" | "glb" => read_gltf(path, &bytes).map(Frame::Mesh),
        _ => read_binvox(path, &bytes).map(|(g, o)| Frame::Voxels(g, o)),
    });
    parsed.unwrap_or_else(|_| {
        Err(Error::parse(
            path,
            None,
            "the reader failed on malformed content",
        ))
    })
}

/// Reads one mesh frame; a voxel file is an error here.
pub fn read_mesh(path: &Path) -> Result<TriangleMesh> {
    match read_frame(path)? {
        Frame::Mesh(m) => Ok(m),
        Frame::Voxels(..) => Err(Error::mesh(path, "a voxel grid where a mesh is needed")),
    }
}

/// A sequence's frame files, read one at a time when a stage asks for a
/// frame: memory holds only the frames being worked on. Stages read a frame
/// more than once (voxelising, the mesh stages, the fit), so each read
/// checks that the file is still the one read first.
#[derive(Clone, Debug)]
pub struct FrameFiles {
    paths: Vec<PathBuf>,
    /// Each file's [`Stamp`] at its first read.
    stamps: Vec<std::sync::OnceLock<Stamp>>,
}

/// What tells a file changed between two reads: its size, modification
/// time and inode (a file replaced by a rename keeps neither).
#[derive(Clone, Debug, PartialEq)]
struct Stamp {
    len: u64,
    modified: Option<std::time::SystemTime>,
    inode: u64,
}

impl Stamp {
    fn of(path: &Path) -> Result<Stamp> {
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        #[cfg(unix)]
        let inode = std::os::unix::fs::MetadataExt::ino(&meta);
        #[cfg(not(unix))]
        let inode = 0;
        Ok(Stamp {
            len: meta.len(),
            modified: meta.modified().ok(),
            inode,
        })
    }
}

impl FrameFiles {
    /// The frames `inputs` name, as [`discover_frames`] finds and orders them.
    pub fn discover(inputs: &[PathBuf]) -> Result<Self> {
        Ok(Self::new(discover_frames(inputs)?))
    }

    /// These files, in this order.
    pub fn new(paths: Vec<PathBuf>) -> Self {
        let stamps = paths.iter().map(|_| std::sync::OnceLock::new()).collect();
        FrameFiles { paths, stamps }
    }

    /// The frame files, in frame order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }
}

impl FrameSource for FrameFiles {
    fn len(&self) -> usize {
        self.paths.len()
    }
    fn name(&self, f: usize) -> String {
        self.paths[f].display().to_string()
    }
    fn frame(&self, f: usize) -> Result<Frame> {
        let path = &self.paths[f];
        let now = Stamp::of(path)?;
        let first = self.stamps[f].get_or_init(|| now.clone());
        if *first != now {
            return Err(Error::InvalidInput(format!(
                "{}: the file changed during the run ({} bytes, then {}); the result would not match it: run again once the capture is complete",
                path.display(),
                first.len,
                now.len
            )));
        }
        read_frame(path)
    }
}
