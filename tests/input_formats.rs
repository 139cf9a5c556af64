//! Inputs that are valid but were read wrongly: hidden files among the
//! frames, frame numbers of any length, wildcards in directories, byte-order
//! marks, classic-Mac line endings, OBJ vertex lines tobj misreads without a
//! line, concave polygons, glTF strips and fans, and a frame out of place.
//! Each case checks what the reader produces (or the error it names), not
//! only that it does not fail.

use std::process::{Command, Output};
use voltrack::io::discover_frames;
use voltrack::{fixtures, TriangleMesh};

mod common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
/// Tiny settings: every run is well under a second.
const SMALL: [&str; 4] = ["-r", "32", "-n", "20"];

fn obj(m: &TriangleMesh) -> Vec<u8> {
    let mut out = Vec::new();
    voltrack::export::obj::write_obj(&mut out, m, &m.positions).unwrap();
    out
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn run(dir: &Scratch, args: &[&str]) -> Output {
    Command::new(BIN).args(args).current_dir(&dir.0).env("RUST_LOG", "warn").output().expect("the voltrack binary runs")
}

/// Writes each `(relative path, bytes)` under `dir`, creating directories.
fn write_files(dir: &Scratch, files: &[(&str, &[u8])]) {
    for (name, bytes) in files {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
}

/// The frames `discover_frames` finds for `input`, relative to `dir`.
fn discovered(dir: &Scratch, input: &str) -> Vec<String> {
    discover_frames(&[dir.join(input)])
        .unwrap_or_else(|e| panic!("{input}: {e}"))
        .iter()
        .map(|p| p.strip_prefix(&dir.0).unwrap().to_string_lossy().into_owned())
        .collect()
}

const TRI: &[u8] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

// ---------------------------------------------------------------------------
// Which files, in which order

#[test]
fn hidden_files_are_not_frames() {
    let dir = Scratch::new("formats", "hidden");
    write_files(
        &dir,
        &[
            ("seq/frame_1.obj", TRI),
            ("seq/frame_2.obj", TRI),
            ("seq/.frame_8.obj", TRI),
            ("seq/.out.glb.4242.partial", TRI),
            ("seq/.hidden_dir/frame_0.obj", TRI),
        ],
    );
    assert_eq!(discovered(&dir, "seq"), ["seq/frame_1.obj", "seq/frame_2.obj"]);
    assert_eq!(discovered(&dir, "seq/*.obj"), ["seq/frame_1.obj", "seq/frame_2.obj"]);
    assert_eq!(discovered(&dir, "seq/*frame_?.obj"), ["seq/frame_1.obj", "seq/frame_2.obj"]);
    // Asked for by name, as a shell would: a pattern starting with '.'.
    assert_eq!(discovered(&dir, "seq/.frame_*.obj"), ["seq/.frame_8.obj"]);
    // Hidden directories are not matched by a wildcard either.
    let e = discover_frames(&[dir.join("seq/*/frame_0.obj")]).unwrap_err().to_string();
    assert!(e.contains("no file matches this pattern"), "{e}");
    assert_eq!(discovered(&dir, "seq/.*/frame_0.obj"), ["seq/.hidden_dir/frame_0.obj"]);
}

#[test]
fn frame_numbers_of_any_length_keep_their_order() {
    let dir = Scratch::new("formats", "longnumbers");
    // 10^40 + k for k in 0..12, written out: past u128 (about 3.4 * 10^38).
    let names: Vec<String> = (0..12).map(|k| format!("seq/frame_1{}{k:02}.obj", "0".repeat(38))).collect();
    // Written in an order that is not the natural one.
    for name in names.iter().rev() {
        write_files(&dir, &[(name, TRI)]);
    }
    assert_eq!(discovered(&dir, "seq"), names);
    // Shorter numbers before longer ones whatever their digits.
    write_files(&dir, &[("seq/frame_99.obj", TRI), ("seq/frame_2.obj", TRI)]);
    let all = discovered(&dir, "seq");
    assert_eq!(&all[..2], ["seq/frame_2.obj", "seq/frame_99.obj"]);
    assert_eq!(&all[2..], names);
}

#[test]
fn wildcards_in_directories() {
    let dir = Scratch::new("formats", "dirglob");
    write_files(
        &dir,
        &[
            ("takes/take_10/mesh.obj", TRI),
            ("takes/take_2/mesh.obj", TRI),
            ("takes/take_1/mesh.obj", TRI),
            ("takes/take_3/other.obj", TRI),
            ("takes/.take_0/mesh.obj", TRI),
            ("takes/take_4.obj", TRI),
            ("seq10/frame_1.obj", TRI),
            ("seq2/frame_10.obj", TRI),
            ("seq2/frame_9.obj", TRI),
            ("seq2/notes.txt", b"not a frame"),
        ],
    );
    assert_eq!(discovered(&dir, "takes/take_*/mesh.obj"), ["takes/take_1/mesh.obj", "takes/take_2/mesh.obj", "takes/take_10/mesh.obj"]);
    assert_eq!(discovered(&dir, "seq*/frame_*.obj"), ["seq2/frame_9.obj", "seq2/frame_10.obj", "seq10/frame_1.obj"]);
    assert_eq!(discovered(&dir, "seq?/frame_1*.obj"), ["seq2/frame_10.obj"]);
    assert_eq!(discovered(&dir, "*/take_?/*.obj"), ["takes/take_1/mesh.obj", "takes/take_2/mesh.obj", "takes/take_3/other.obj"]);
    // Nothing matches: the pattern is named, not a missing file.
    for pattern in ["takes/take_*/absent.obj", "nothing_*/mesh.obj", "takes/take_*/*.ply"] {
        let e = discover_frames(&[dir.join(pattern)]).unwrap_err().to_string();
        assert!(e.contains(pattern) && e.contains("no file matches this pattern"), "{e}");
    }
    // Relative patterns run from the current directory, as on the command line.
    for (k, take) in ["take_1", "take_2", "take_10"].iter().enumerate() {
        std::fs::write(dir.join(&format!("takes/{take}/mesh.obj")), obj(&fixtures::bending_bar(k))).unwrap();
    }
    let mut args = vec!["track", "takes/take_*/mesh.obj"];
    args.extend(SMALL);
    args.extend(["-o", "c.exr"]);
    let o = run(&dir, &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(dir.join("c.exr").is_file());
}
