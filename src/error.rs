//! The library's one error type.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in voltrack. Every variant that concerns a file
/// names it, and a line where the format has lines.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading a file or folder (an input, a checkpoint, a texture) failed,
    /// or creating or using one the run keeps for itself (the checkpoint
    /// folder, a temporary file).
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder concerned.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A file read (a frame, trajectories, a checkpoint, a texture) does not
    /// follow its format or lacks what voltrack needs of it.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        /// The file read.
        path: PathBuf,
        /// The line (from 1) at fault, in formats that have lines.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// An input file whose extension names no format voltrack reads.
    #[error("{}: unsupported file type (expected .obj, .ply, .gltf, .glb or .binvox)", path.display())]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// A frame that was read but cannot be used: no triangle, a non-finite
    /// coordinate, an index out of range, no enclosed volume at the grid's
    /// resolution, or a voxel grid where a mesh is needed.
    #[error("{}: {message}", path.display())]
    InvalidMesh {
        /// The frame's file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Input that is readable but cannot be processed as a sequence.
    #[error("{0}")]
    InvalidInput(String),
    /// An option out of its range, options that contradict each other or the
    /// input, or an unusable temporary folder; found before any work where
    /// possible.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// Writing a file or folder (an output, a checkpoint) failed.
    #[error("{}: cannot write: {message}", path.display())]
    Write {
        /// The output file or folder.
        path: PathBuf,
        /// Why it could not be written.
        message: String,
    },
    /// Writing to a caller's writer (not a file of ours) failed.
    #[error("cannot write the output: {0}")]
    WriteStream(#[source] std::io::Error),
    /// An output the run refuses to write, found before any work: it would
    /// replace an input or another output, or its place takes no file.
    #[error("{}: cannot write: {message}", path.display())]
    OutputRefused {
        /// The output refused.
        path: PathBuf,
        /// Why it is refused.
        message: String,
    },
    /// Stopped on request (Ctrl-C). `saved` says what a resumed run will
    /// not do again, when state was saved.
    #[error("interrupted{}", saved.as_ref().map(|s| format!("; {s}: resume from it to continue")).unwrap_or_default())]
    Interrupted {
        /// What was saved for a resumed run, if anything.
        saved: Option<Saved>,
    },
}

/// What an interrupted run saved for a resumed one.
#[derive(Clone, Debug, PartialEq)]
pub struct Saved {
    /// The tracking checkpoint file.
    pub path: PathBuf,
    /// Tracked frames it holds.
    pub frames: usize,
    /// Refinement batches finished and in all, when refinement saved its
    /// state beside it (`Checkpointing::refine_path`).
    pub refine: Option<(usize, usize)>,
}

impl std::fmt::Display for Saved {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.refine {
            None => write!(
                f,
                "the first {} tracked frames are saved in {}",
                self.frames,
                self.path.display()
            ),
            Some((done, all)) => {
                write!(
                    f,
                    "the refinement ({done} of {all} batches done) is saved in {}",
                    self.path.parent().unwrap_or(&self.path).display()
                )
            }
        }
    }
}

/// `std::result::Result` with voltrack's [`Error`] by default.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }
    pub(crate) fn parse(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Error::Parse {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }
    pub(crate) fn mesh(path: &Path, message: impl Into<String>) -> Self {
        Error::InvalidMesh {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
    pub(crate) fn refuse(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::OutputRefused {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
    pub(crate) fn write(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::Write {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}
