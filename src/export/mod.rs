//! Writing results (glTF, OBJ, PLY, binvox, EXR). Every writer goes through [`write_atomic`], so a failure
//! never leaves a half-written file behind.

pub mod basis;
pub mod exr;
pub mod gltf;
pub mod obj;
pub mod pc2;
pub mod ply;

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` through a temporary file in the same directory, renamed into
/// place only when `fill` succeeded.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let (dir, name) = check_writable(path)?;
    let tmp = dir.join(format!(".{}.{}.partial", name.to_string_lossy(), std::process::id()));
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        fill(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        drop(w);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::write(path, e));
    }
    Ok(())
}

/// Checks, before any work, that `path` names a file in an existing
/// directory; returns the directory and the file name.
pub fn check_writable(path: &Path) -> Result<(&Path, &std::ffi::OsStr)> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::write(path, format!("the directory {} does not exist", dir.display())));
    }
    let name = path.file_name().ok_or_else(|| Error::write(path, "not a file name"))?;
    Ok((dir, name))
}

/// Writes every frame of a voxelised sequence as `.binvox` into `dir`, named
/// after the input files.
pub fn write_binvox_frames(seq: &crate::voxel::VoxelSequence, dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::write(dir, e))?;
    let mut written = Vec::new();
    for (occ, src) in seq.frames.iter().zip(&seq.paths) {
        let stem = src.file_stem().unwrap_or_default().to_string_lossy();
        let out = dir.join(format!("{stem}.binvox"));
        if written.contains(&out) {
            return Err(Error::InvalidInput(format!("two input frames are both named {stem}; outputs would collide")));
        }
        write_atomic(&out, |w| crate::io::write_binvox(w, &seq.grid, occ))?;
        written.push(out);
    }
    Ok(written)
}
