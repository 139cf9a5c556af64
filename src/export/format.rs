//! The output formats `convert` writes: their names, what each carries and
//! the files each writes for one output path. The command line parses it,
//! the output plan (`OutputPlan::output`) guards its files, and the writer
//! of each format writes them.

use std::path::{Path, PathBuf};

/// An output format of a conversion.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum OutputFormat {
    /// Binary glTF with morph targets
    Glb,
    /// glTF as JSON with the binary buffer embedded (the GLB's content in one text file)
    Gltf,
    /// Center trajectories (as `voltrack track`)
    Exr,
    /// Per-vertex positions as an EXR vertex-animation texture, with its mesh (.glb) and a JSON sidecar
    Vat,
    /// Blender point cache (.pc2) with the base mesh as OBJ beside it
    Pc2,
    /// A directory of OBJ files sharing one connectivity
    ObjSequence,
}

/// One file (or folder) an output format writes for an output path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputFile {
    /// Where it is written.
    pub path: PathBuf,
    /// What it is, as the user is told ("the output", "its mesh").
    pub what: &'static str,
    /// What it is to the output plan.
    pub kind: OutputKind,
}

/// How the output plan treats an [`OutputFile`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// The output path itself.
    File,
    /// A file beside the output, named after it, that a rerun may replace
    /// only where it begins with this mark (voltrack wrote it).
    Sidecar(&'static str),
    /// A folder the output's files are written into, replaced as a whole.
    Folder,
}

impl OutputFormat {
    /// The format's name, as `--format` takes it.
    pub fn name(self) -> &'static str {
        match self {
            OutputFormat::Glb => "glb",
            OutputFormat::Gltf => "gltf",
            OutputFormat::Exr => "exr",
            OutputFormat::Vat => "vat",
            OutputFormat::Pc2 => "pc2",
            OutputFormat::ObjSequence => "obj-sequence",
        }
    }

    /// The format an output's extension (any case, without the dot) names,
    /// if any: a VAT's texture is an `.exr` too, so `exr` names the
    /// trajectories unless asked otherwise.
    pub fn from_extension(ext: &str) -> Option<Self> {
        match ext.to_ascii_lowercase().as_str() {
            "glb" => Some(OutputFormat::Glb),
            "gltf" => Some(OutputFormat::Gltf),
            "exr" => Some(OutputFormat::Exr),
            "pc2" => Some(OutputFormat::Pc2),
            _ => None,
        }
    }

    /// glTF, binary or text: morph targets, samplers, normals, a basis and
    /// compression.
    pub fn is_gltf(self) -> bool {
        matches!(self, OutputFormat::Glb | OutputFormat::Gltf)
    }

    /// Whether the output plays at a frame rate (an animation, not
    /// trajectories or a folder of frames).
    pub fn is_timed(self) -> bool {
        matches!(
            self,
            OutputFormat::Glb | OutputFormat::Gltf | OutputFormat::Vat | OutputFormat::Pc2
        )
    }

    /// Whether the output holds a mesh, which carries the object's name.
    pub fn has_mesh(self) -> bool {
        self != OutputFormat::Exr
    }

    /// The files written for output path `out`, the output first; its
    /// sidecars are `out` with their own extensions.
    pub fn files(self, out: &Path) -> Vec<OutputFile> {
        let file = |path: PathBuf, what, kind| OutputFile { path, what, kind };
        let output = file(out.to_path_buf(), "the output", OutputKind::File);
        match self {
            OutputFormat::Glb | OutputFormat::Gltf | OutputFormat::Exr => vec![output],
            OutputFormat::Vat => {
                let (mesh, sidecar) = super::vat::files_beside(out);
                vec![
                    output,
                    file(mesh, "its mesh", OutputKind::Sidecar(super::vat::MESH_MARK)),
                    file(
                        sidecar,
                        "its JSON sidecar",
                        OutputKind::Sidecar(super::vat::SIDECAR_MARK),
                    ),
                ]
            }
            OutputFormat::Pc2 => vec![
                output,
                file(
                    super::pc2::mesh_beside(out),
                    "its OBJ mesh",
                    OutputKind::Sidecar(super::pc2::MESH_MARK),
                ),
            ],
            OutputFormat::ObjSequence => vec![file(
                out.to_path_buf(),
                "the output folder",
                OutputKind::Folder,
            )],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every format's files start with the output itself, and its sidecars
    /// differ from it (a sidecar named as the output would replace it).
    #[test]
    fn each_format_writes_its_output_and_distinct_sidecars() {
        let all = [
            OutputFormat::Glb,
            OutputFormat::Gltf,
            OutputFormat::Exr,
            OutputFormat::Vat,
            OutputFormat::Pc2,
            OutputFormat::ObjSequence,
        ];
        for format in all {
            let out = Path::new("dir/take.out");
            let files = format.files(out);
            assert_eq!(files[0].path, out, "{}", format.name());
            assert!(files[1..]
                .iter()
                .all(|f| f.path != out && f.path.parent() == out.parent()));
            assert_eq!(
                files
                    .iter()
                    .filter(|f| f.kind == OutputKind::Folder)
                    .count(),
                usize::from(format == OutputFormat::ObjSequence)
            );
        }
        for (ext, format) in [
            ("GLB", OutputFormat::Glb),
            ("gltf", OutputFormat::Gltf),
            ("exr", OutputFormat::Exr),
            ("Pc2", OutputFormat::Pc2),
        ] {
            assert_eq!(OutputFormat::from_extension(ext), Some(format));
            assert_eq!(format.name(), ext.to_ascii_lowercase());
        }
    }
}
