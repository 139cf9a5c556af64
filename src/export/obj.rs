//! Wavefront OBJ writing: one mesh, or every frame of a dynamic mesh.

use crate::error::Result;
use crate::math::{Point3, Vector3};
use crate::model::mesh::TriangleMesh;
use crate::model::DynamicMesh;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `positions` with the connectivity (and UVs) of `mesh`: no object
/// name, no normals (`mesh.normals` is not written).
pub fn write_obj(
    out: &mut impl Write,
    mesh: &TriangleMesh,
    positions: &[Point3],
) -> std::io::Result<()> {
    write_object(out, mesh, positions, None, None)
}

/// [`write_obj`] as one object called `name` (`o name`: what Blender's
/// importer names the object), with one normal per vertex (`vn`, referenced
/// by the vertex's own index) when `normals` is given, so importers shade it
/// smooth. The name should pass [`check_name`](crate::model::check_name).
pub(crate) fn write_named_obj(
    out: &mut impl Write,
    mesh: &TriangleMesh,
    positions: &[Point3],
    name: &str,
    normals: Option<&[Vector3]>,
) -> std::io::Result<()> {
    write_object(out, mesh, positions, Some(name), normals)
}

fn write_object(
    out: &mut impl Write,
    mesh: &TriangleMesh,
    positions: &[Point3],
    name: Option<&str>,
    normals: Option<&[Vector3]>,
) -> std::io::Result<()> {
    writeln!(out, "# voltrack {}", env!("CARGO_PKG_VERSION"))?;
    if let Some(name) = name {
        writeln!(out, "o {name}")?;
    }
    for p in positions {
        writeln!(out, "v {} {} {}", p.x as f32, p.y as f32, p.z as f32)?;
    }
    if let Some(uv) = &mesh.uvs {
        for t in uv {
            writeln!(out, "vt {} {}", t[0], 1.0 - t[1])?;
        }
    }
    for n in normals.unwrap_or_default() {
        writeln!(out, "vn {} {} {}", n.x as f32, n.y as f32, n.z as f32)?;
    }
    let uv = mesh.uvs.is_some();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        match (uv, normals.is_some()) {
            (true, true) => writeln!(out, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?,
            (false, true) => writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?,
            (true, false) => writeln!(out, "f {a}/{a} {b}/{b} {c}/{c}")?,
            (false, false) => writeln!(out, "f {a} {b} {c}")?,
        }
    }
    Ok(())
}

/// Writes every frame of `mesh` into `dir` (created if needed) as
/// `frame_0000.obj`, `frame_0001.obj`, … (more digits past 10 000 frames, so
/// names sort in frame order): the same object `name`, vertex order, faces
/// and UVs in every file, only the positions change. Returns the paths in
/// frame order. The folder is replaced as a whole
/// ([`crate::files::replace_dir`]): on failure the old one stays as it was,
/// and no frame of an earlier, longer run is left among the new ones.
pub fn write_obj_sequence(dir: &Path, mesh: &DynamicMesh, name: &str) -> Result<Vec<PathBuf>> {
    let frames = ObjFrames::new(mesh, name)?;
    let width = (mesh.frames.len() - 1).to_string().len().max(4);
    let frames = &frames;
    let files = (0..mesh.frames.len())
        .map(|f| {
            // Each frame is read as its file is written: one in memory at a time.
            let fill = move |w: &mut _| frames.write(w, f);
            (
                format!("frame_{f:0width$}.obj"),
                Box::new(fill) as crate::files::Fill,
            )
        })
        .collect();
    crate::files::replace_dir(dir, files)
}

/// The frames of a dynamic mesh as OBJ files, each into a writer of the
/// caller's: what [`write_obj_sequence`] writes into its folder.
pub struct ObjFrames<'a> {
    mesh: &'a DynamicMesh,
    name: &'a str,
    normals: super::normals::FrameNormals<'a>,
}

impl<'a> ObjFrames<'a> {
    /// Checks the object's `name` and the frames.
    pub fn new(mesh: &'a DynamicMesh, name: &'a str) -> Result<Self> {
        crate::model::check_name(name)?;
        super::basis::check_frames(mesh)?;
        // Each frame's own normals (welded at UV seams, as the GLB's), so
        // every file is smooth-shaded where it is imported.
        let normals = super::normals::FrameNormals::new(&mesh.base, &mesh.frames.get(0)?);
        Ok(ObjFrames {
            mesh,
            name,
            normals,
        })
    }

    /// Frame `f` (reading it from the mesh's frames) as one OBJ into `out`.
    pub fn write(&self, out: &mut impl Write, f: usize) -> std::io::Result<()> {
        let positions = self.mesh.frames.get(f).map_err(std::io::Error::other)?;
        write_named_obj(
            out,
            &self.mesh.base,
            &positions,
            self.name,
            Some(&self.normals.of(&positions)),
        )
    }
}
