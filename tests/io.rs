//! Sequence discovery and readers, including their errors on bad input.

use std::path::{Path, PathBuf};
use voltrack::io::{discover_frames, read_frame, read_mesh};
use voltrack::Error;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voltrack-io-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[test]
fn directories_sort_naturally_and_skip_other_files() {
    let d = tmpdir("natural");
    for n in ["mesh_10.obj", "mesh_2.obj", "mesh_1.obj", "notes.txt"] {
        write(&d, n, TRI);
    }
    let names: Vec<String> = discover_frames(std::slice::from_ref(&d))
        .unwrap()
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["mesh_1.obj", "mesh_2.obj", "mesh_10.obj"]);
    let pattern = d.join("mesh_1*.obj");
    assert_eq!(discover_frames(&[pattern]).unwrap().len(), 2);
}

#[test]
fn explicit_files_keep_their_order() {
    let d = tmpdir("explicit");
    let a = write(&d, "b.obj", TRI);
    let b = write(&d, "a.obj", TRI);
    assert_eq!(
        discover_frames(&[a.clone(), b.clone()]).unwrap(),
        vec![a, b]
    );
}

#[test]
fn obj_polygons_negative_indices_and_uvs() {
    let d = tmpdir("obj");
    let p = write(
        &d,
        "quad.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf -4/-4 -3/-3 -2/-2 -1/-1\n",
    );
    let m = read_mesh(&p).unwrap();
    assert_eq!(m.triangles.len(), 2);
    assert_eq!(m.positions.len(), 4);
    let uv = m.uvs.unwrap();
    assert_eq!(uv.len(), 4);
    assert!(uv.contains(&[1.0, 0.0])); // (1, 1) in OBJ's v-up convention
}

fn err_text(r: voltrack::Result<impl std::fmt::Debug>) -> String {
    r.expect_err("expected an error").to_string()
}

#[test]
fn bad_obj_names_file_and_line() {
    let d = tmpdir("badobj");
    let p = write(&d, "nan.obj", "# c\nv 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = err_text(read_mesh(&p));
    assert!(e.contains("nan.obj:3"), "{e}");
    let p = write(
        &d,
        "range.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
    );
    let e = err_text(read_mesh(&p));
    assert!(e.contains("range.obj:5"), "{e}");
    let p = write(&d, "zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    let e = err_text(read_mesh(&p));
    assert!(e.contains("zero.obj:4"), "{e}");
    let p = write(&d, "garbage.obj", "v 0 0 0\nv 1 x 0\n");
    let e = err_text(read_mesh(&p));
    assert!(e.contains("garbage.obj:2"), "{e}");
    let p = write(&d, "empty_mesh.obj", "v 0 0 0\n");
    let e = err_text(read_mesh(&p));
    assert!(
        e.contains("empty_mesh.obj") && e.contains("no triangles"),
        "{e}"
    );
}

#[test]
fn bad_files_are_named() {
    let d = tmpdir("badfiles");
    let e = err_text(read_frame(&d.join("missing.obj")));
    assert!(e.contains("missing.obj"), "{e}");
    let p = write(&d, "mesh.stl", "solid");
    assert!(matches!(
        read_frame(&p),
        Err(Error::UnsupportedFormat { .. })
    ));
    let p = write(&d, "zero.ply", "");
    let e = err_text(read_frame(&p));
    assert!(e.contains("zero.ply") && e.contains("empty"), "{e}");
    let p = write(&d, "trunc.glb", "glTF\x02\x00\x00\x00");
    let e = err_text(read_frame(&p));
    assert!(e.contains("trunc.glb"), "{e}");
    let empty = tmpdir("nomeshes");
    write(&empty, "readme.txt", "hi");
    let e = err_text(discover_frames(&[empty]));
    assert!(e.contains("no mesh"), "{e}");
}

#[test]
fn bad_ply_names_file_and_line() {
    let d = tmpdir("badply");
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let p = write(&d, "short.ply", &format!("{head}0 0 0\n1 0 0\n"));
    let e = err_text(read_mesh(&p));
    assert!(e.contains("short.ply") && e.contains("ends"), "{e}");
    let p = write(
        &d,
        "word.ply",
        &format!("{head}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"),
    );
    let e = err_text(read_mesh(&p));
    assert!(e.contains("word.ply:11"), "{e}");
    let p = write(
        &d,
        "index.ply",
        &format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
    );
    let e = err_text(read_mesh(&p));
    assert!(e.contains("index.ply") && e.contains("beyond"), "{e}");
    let p = write(
        &d,
        "header.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty quux x\nend_header\n",
    );
    let e = err_text(read_mesh(&p));
    assert!(e.contains("header.ply:4"), "{e}");
    // Extra properties and elements are skipped.
    let p = write(
        &d,
        "extra.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nproperty int flags\nelement edge 1\nproperty int a\nproperty int b\nend_header\n0 0 0 9\n1 0 0 9\n0 1 0 9\n3 0 1 2 7\n0 1\n",
    );
    assert_eq!(read_mesh(&p).unwrap().triangles.len(), 1);
}

#[test]
fn sequences_reject_one_frame_and_mixed_units() {
    use voltrack::voxel::{voxelize_sequence, VoxelParams};
    let d = tmpdir("seq");
    let a = write(
        &d,
        "a.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    let b = write(
        &d,
        "b.obj",
        "v 0 0 0\nv 1000 0 0\nv 0 1000 0\nv 0 0 1000\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    let p = VoxelParams::default();
    let e = err_text(voxelize_sequence(
        &voltrack::io::FrameFiles::new([a.clone()].to_vec()),
        &p,
        Default::default(),
    ));
    assert!(e.contains("a.obj") && e.contains("at least 2"), "{e}");
    let e = err_text(voxelize_sequence(
        &voltrack::io::FrameFiles::new([a.clone(), b.clone()].to_vec()),
        &p,
        Default::default(),
    ));
    assert!(
        e.contains("b.obj") && e.contains("a.obj") && e.contains("units"),
        "{e}"
    );
    let sheet = write(&d, "sheet.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = err_text(voxelize_sequence(
        &voltrack::io::FrameFiles::new([a, sheet].to_vec()),
        &p,
        Default::default(),
    ));
    assert!(
        e.contains("sheet.obj") && e.contains("encloses no voxel"),
        "{e}"
    );
}

/// Issue 23: the result is named after its input, so two imported results
/// are not both `voltrack`.
#[test]
fn a_sequence_is_named_after_its_folder_or_its_frames() {
    use voltrack::io::sequence_name;
    let d = tmpdir("names");
    let named = |inputs: &[PathBuf]| sequence_name(inputs, &discover_frames(inputs).unwrap());
    // A directory: its name, also when given as "." or with a trailing '/'.
    let seq = d.join("Dancer take 2");
    std::fs::create_dir(&seq).unwrap();
    for f in 1..=12 {
        write(&seq, &format!("scan_2024_{f:04}.obj"), TRI);
    }
    assert_eq!(named(std::slice::from_ref(&seq)), "Dancer take 2");
    assert_eq!(
        named(&[PathBuf::from(format!("{}/", seq.display()))]),
        "Dancer take 2"
    );
    assert_eq!(named(&[seq.join(".")]), "Dancer take 2");
    // A pattern or files: their common prefix, less the frame number's
    // leading digits and the separators before it.
    assert_eq!(named(&[seq.join("scan_*.obj")]), "scan_2024");
    assert_eq!(
        named(&[
            seq.join("scan_2024_0001.obj"),
            seq.join("scan_2024_0002.obj")
        ]),
        "scan_2024"
    );
    let names = |stems: &[&str]| {
        sequence_name(
            &[],
            &stems
                .iter()
                .map(|s| PathBuf::from(format!("x/{s}.obj")))
                .collect::<Vec<_>>(),
        )
    };
    assert_eq!(names(&["walk_0001", "walk_0002", "walk_0010"]), "walk");
    assert_eq!(names(&["take2_01", "take2_02"]), "take2");
    assert_eq!(names(&["frame-0", "frame-1"]), "frame");
    assert_eq!(names(&["bar. 1", "bar. 2"]), "bar");
    assert_eq!(names(&["left_hand", "left_foot"]), "left");
    // One file: its stem as it is; nothing in common: the first frame's stem.
    assert_eq!(names(&["mesh2"]), "mesh2");
    assert_eq!(names(&["1", "2"]), "1");
    assert_eq!(names(&["a_1", "b_1"]), "a_1");
    // Never a name the writers refuse.
    assert_eq!(names(&["tab\there_1", "tab\there_2"]), "tab_here");
    for n in [
        names(&["tab\there_1"]),
        names(&["_1", "_2"]),
        names(&[" ", "  "]),
    ] {
        assert!(voltrack::model::check_name(&n).is_ok(), "{n:?}");
    }
    let _ = std::fs::remove_dir_all(&d);
}
