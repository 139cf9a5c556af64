//! The frames of a sequence as the stages read them: one at a time, from
//! files (`io::FrameFiles`) or from memory (a slice of meshes).

use super::{GridSpec, Occupancy, TriangleMesh};
use crate::error::{Error, Result};
use std::path::Path;

/// What one frame holds.
#[derive(Clone, Debug)]
pub enum Frame {
    /// A triangle mesh (from OBJ, PLY, glTF/GLB, or memory), to be voxelised.
    Mesh(TriangleMesh),
    /// A voxel frame (`.binvox`): voxelisation is skipped.
    Voxels(GridSpec, Occupancy),
}

/// A sequence's frames, read when a stage asks for one, so that a stage can
/// hold one frame at a time. Implemented by `io::FrameFiles` (lazy reading
/// of frame files) and by `[TriangleMesh]` / `Vec<TriangleMesh>` (frames
/// already in memory).
pub trait FrameSource: Sync {
    /// Number of frames.
    fn len(&self) -> usize;

    /// Whether there is no frame.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// How messages name frame `f`: its file, or `frame f` in memory.
    fn name(&self, f: usize) -> String;

    /// Frame `f` (`f < len()`), read or copied.
    fn frame(&self, f: usize) -> Result<Frame>;

    /// Frame `f` as a mesh, checked ([`TriangleMesh::validate`]); a voxel
    /// frame is an error naming it.
    fn mesh(&self, f: usize) -> Result<TriangleMesh> {
        let name = self.name(f);
        match self.frame(f)? {
            Frame::Mesh(m) => {
                m.validate(Path::new(&name))?;
                Ok(m)
            }
            Frame::Voxels(..) => Err(Error::mesh(
                Path::new(&name),
                "a voxel grid where a mesh is needed",
            )),
        }
    }
}

impl FrameSource for [TriangleMesh] {
    fn len(&self) -> usize {
        <[TriangleMesh]>::len(self)
    }
    fn name(&self, f: usize) -> String {
        format!("frame {f}")
    }
    fn frame(&self, f: usize) -> Result<Frame> {
        Ok(Frame::Mesh(self[f].clone()))
    }
}

impl FrameSource for Vec<TriangleMesh> {
    fn len(&self) -> usize {
        self.as_slice().len()
    }
    fn name(&self, f: usize) -> String {
        self.as_slice().name(f)
    }
    fn frame(&self, f: usize) -> Result<Frame> {
        self.as_slice().frame(f)
    }
}
