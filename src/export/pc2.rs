//! Point caches for Blender's Mesh Cache modifier: every frame's positions as
//! a PC2 file, and the mesh to put the modifier on as an OBJ beside it.

use super::basis::check_frames;
use super::normals::FrameNormals;
use super::obj::write_named_obj;
use crate::error::{Error, Result};
use crate::files::write_atomic_all;
use crate::model::mesh::TriangleMesh;
use crate::model::DynamicMesh;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The first words of the mesh written beside a point cache, by which a
/// rerun knows it may replace the file.
pub const MESH_MARK: &str = "# Mesh Cache";

/// The OBJ mesh written beside a point cache at `path`.
pub fn mesh_beside(path: &Path) -> PathBuf {
    path.with_extension("obj")
}

/// Writes the frames of `mesh` as a PC2 point cache at `path` and frame 0 as
/// an OBJ at `path.with_extension("obj")`, both listing the same vertices in
/// the same order, so the Mesh Cache modifier on the imported OBJ replays the
/// sequence. The OBJ holds one object called `name` (not blank, no control
/// characters) and frame 0's vertex normals, computed and welded at UV seams
/// as the GLB's are, so Blender shades it smooth.
///
/// PC2 (3ds Max's format, read by Blender): the header `POINTCACHE2\0`, i32
/// version 1, i32 point count, f32 start frame (0), f32 sampling (1: one
/// sample per frame), i32 sample count; then per sample, per point, x y z as
/// f32, all little-endian. The format counts in frames and has no time base,
/// so `fps` (finite, > 0) is recorded in the OBJ's header comment: set the
/// Blender scene to that frame rate.
///
/// Vertices that no triangle uses are left out of both files: Blender's OBJ
/// importer does not create them, and the modifier needs equal counts. All
/// others keep the mesh's order.
pub fn write_pc2(path: &Path, mesh: &DynamicMesh, fps: f32, name: &str) -> Result<()> {
    let cache = PointCache::new(mesh, fps, name)?;
    let obj_path = mesh_beside(path);
    if obj_path == path {
        return Err(Error::write(
            path,
            "the point cache would overwrite the OBJ of its mesh; name it .pc2",
        ));
    }
    let cache_name = path.file_name().unwrap_or_default().to_string_lossy();
    // Both or neither: a cache without its mesh is of no use.
    write_atomic_all(vec![
        (
            path,
            Box::new(|w: &mut BufWriter<File>| cache.write_cache(w)),
        ),
        (
            &obj_path,
            Box::new(|w: &mut BufWriter<File>| cache.write_mesh(w, &cache_name)),
        ),
    ])
}

/// [`write_pc2`] into two writers of the caller's: the point cache into
/// `cache`, the OBJ of its mesh into `obj`, whose header names the cache
/// `cache_name`. What was written before an error stays written.
pub fn write_pc2_to(
    cache: &mut impl Write,
    obj: &mut impl Write,
    cache_name: &str,
    mesh: &DynamicMesh,
    fps: f32,
    name: &str,
) -> Result<()> {
    let pc2 = PointCache::new(mesh, fps, name)?;
    pc2.write_cache(cache).map_err(Error::WriteStream)?;
    pc2.write_mesh(obj, cache_name).map_err(Error::WriteStream)
}

/// A point cache ready to write: the vertices some triangle uses, and frame
/// 0's mesh of those vertices with its normals.
struct PointCache<'a> {
    mesh: &'a DynamicMesh,
    fps: f32,
    name: &'a str,
    /// The vertices written, in the mesh's order.
    kept: Vec<usize>,
    points: i32,
    samples: i32,
    /// Frame 0 of the kept vertices.
    obj: TriangleMesh,
    normals: Vec<crate::math::Vector3>,
}

impl<'a> PointCache<'a> {
    /// Checks the frame rate, the name and the frames, and keeps the
    /// vertices some triangle uses.
    fn new(mesh: &'a DynamicMesh, fps: f32, name: &'a str) -> Result<Self> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(Error::InvalidParameter(format!(
                "the frame rate must be positive, not {fps}"
            )));
        }
        crate::model::check_name(name)?;
        check_frames(mesh)?;
        let base = &mesh.base;
        let mut used = vec![false; base.positions.len()];
        base.triangles
            .iter()
            .flatten()
            .for_each(|&v| used[v as usize] = true);
        let kept: Vec<usize> = (0..used.len()).filter(|&v| used[v]).collect();
        let mut index = vec![0u32; used.len()];
        kept.iter()
            .enumerate()
            .for_each(|(new, &old)| index[old] = new as u32);
        let too_many = |what| Error::InvalidInput(format!("too many {what} for a PC2 file"));
        let points = i32::try_from(kept.len()).map_err(|_| too_many("vertices"))?;
        let samples = i32::try_from(mesh.frames.len()).map_err(|_| too_many("frames"))?;
        let first = mesh.frames.get(0)?;
        let obj = TriangleMesh {
            positions: kept.iter().map(|&v| first[v]).collect(),
            triangles: base
                .triangles
                .iter()
                .map(|t| t.map(|v| index[v as usize]))
                .collect(),
            uvs: base
                .uvs
                .as_ref()
                .map(|uv| kept.iter().map(|&v| uv[v]).collect()),
            ..Default::default()
        };
        let all_normals = FrameNormals::new(base, &first).base;
        let normals = kept.iter().map(|&v| all_normals[v]).collect();
        Ok(PointCache {
            mesh,
            fps,
            name,
            kept,
            points,
            samples,
            obj,
            normals,
        })
    }

    /// The PC2 file: its header, then every frame's kept vertices.
    fn write_cache(&self, w: &mut impl Write) -> std::io::Result<()> {
        w.write_all(b"POINTCACHE2\0")?;
        w.write_all(&1i32.to_le_bytes())?;
        w.write_all(&self.points.to_le_bytes())?;
        w.write_all(&0f32.to_le_bytes())?;
        w.write_all(&1f32.to_le_bytes())?;
        w.write_all(&self.samples.to_le_bytes())?;
        for frame in self.mesh.frames.iter() {
            let frame = frame.map_err(std::io::Error::other)?;
            for &v in &self.kept {
                for c in frame[v].iter() {
                    w.write_all(&(*c as f32).to_le_bytes())?;
                }
            }
        }
        Ok(())
    }

    /// The OBJ of frame 0, its header naming the cache `cache_name`.
    fn write_mesh(&self, w: &mut impl Write, cache_name: &str) -> std::io::Result<()> {
        let (samples, fps) = (self.samples, self.fps);
        writeln!(w, "{MESH_MARK} {cache_name}: {samples} frames at {fps} fps, start frame 0, one sample per frame")?;
        write_named_obj(
            w,
            &self.obj,
            &self.obj.positions,
            self.name,
            Some(&self.normals),
        )
    }
}
