//! Hostile input: truncated and malformed files, inconsistent headers, bad
//! indices, non-finite and degenerate geometry, open and non-manifold
//! surfaces, frames in other units, headers that ask for absurd amounts of
//! memory, unwritable outputs. Every case must end in a clear error that names
//! the file (and line where the format has lines) or, where a user would
//! expect it, convert; never a panic, and never a file left behind.
//!
//! The corpus is generated here from the fixture generator (`voltrack::fixtures`),
//! so each case reads as what it is; only inputs that once crashed a reader
//! (found by the `fuzz/` targets or by [`mutated_fixtures_never_panic`]) are
//! committed, under `tests/corpus/<format>/`, and replayed by
//! [`fuzz_crashers_are_errors`]. Parser cases call the readers directly (a
//! panic fails the test); end-to-end cases run the binary at tiny settings.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};
use voltrack::export::ply::PlyEncoding;
use voltrack::io::{read_binvox, read_frame, read_gltf, read_obj, read_ply};
use voltrack::math::{Point3, Real};
use voltrack::{fixtures, TriangleMesh};

mod common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
/// Tiny settings: every run is well under a second.
const SMALL: [&str; 4] = ["-r", "32", "-n", "20"];

// ---------------------------------------------------------------------------
// Building the corpus

fn bar(f: usize) -> TriangleMesh {
    fixtures::bending_bar(f)
}

use common::{obj_bytes as obj, ply_bytes as ply};

fn glb(m: &TriangleMesh) -> Vec<u8> {
    voltrack::export::gltf::glb_bytes(m, None, &Default::default()).unwrap()
}

/// The cube voxelised at resolution 6, as binvox.
fn binvox() -> Vec<u8> {
    let m = fixtures::cube(Point3::origin(), 1.0);
    let grid = voltrack::model::GridSpec::for_bounds(&m.bounding_box(), 6).unwrap();
    let mut out = Vec::new();
    voltrack::export::binvox::write_binvox(&mut out, &grid, &voltrack::voxel::voxelize(&m, &grid))
        .unwrap();
    out
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// `bytes` with the first occurrence of `from` replaced by `to`.
fn replace(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .unwrap_or_else(|| panic!("{:?} not found", text(from)));
    [&bytes[..at], to, &bytes[at + from.len()..]].concat()
}

/// Byte offset just past `end_header\n`.
fn ply_body(bytes: &[u8]) -> usize {
    bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11
}

/// `bytes` with its 1-based line `line` replaced by `new`.
fn with_line(bytes: &[u8], line: usize, new: &str) -> Vec<u8> {
    let lines: Vec<String> = text(bytes)
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i + 1 == line {
                new.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    (lines.join("\n") + "\n").into_bytes()
}

/// 1-based line number of the first line starting with `prefix`.
fn line_of(bytes: &[u8], prefix: &str) -> usize {
    text(bytes)
        .lines()
        .position(|l| l.starts_with(prefix))
        .unwrap()
        + 1
}

/// `m` plus the vertices `extra_positions` and the triangles `extra`, whose
/// indices from 1000 on refer to the new vertices (1000 the first).
fn with_extra(mut m: TriangleMesh, extra_positions: &[Point3], extra: &[[u32; 3]]) -> TriangleMesh {
    let base = m.positions.len() as u32;
    m.positions.extend_from_slice(extra_positions);
    m.triangles.extend(
        extra
            .iter()
            .map(|t| t.map(|i| if i >= 1000 { base + i - 1000 } else { i })),
    );
    m
}

/// A flat 3 × 3 square sheet (the bar's length) of 2 n² triangles in z = 0,
/// turned by the rotation vector `rotation` (axis times angle).
fn sheet(n: u32, rotation: [Real; 3]) -> TriangleMesh {
    let rot = voltrack::math::Rotation3::new(voltrack::math::Vector3::from(rotation));
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            positions.push(
                rot * Point3::new(
                    3.0 * i as Real / n as Real,
                    3.0 * j as Real / n as Real,
                    0.0,
                ),
            );
        }
    }
    let id = |i: u32, j: u32| j * (n + 1) + i;
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriangleMesh {
        positions,
        triangles,
        ..Default::default()
    }
}

fn scaled(mut m: TriangleMesh, s: Real) -> TriangleMesh {
    m.positions.iter_mut().for_each(|p| *p *= s);
    m
}

// ---------------------------------------------------------------------------
// Checking the library

/// The reader for `name`'s extension, called directly (a panic fails the test).
fn read(name: &str, bytes: &[u8]) -> Result<(), String> {
    let path = Path::new(name);
    let r = match path.extension().and_then(|e| e.to_str()) {
        Some("obj") => read_obj(path, bytes).map(drop),
        Some("ply") => read_ply(path, bytes).map(drop),
        Some("glb") | Some("gltf") => read_gltf(path, bytes).map(drop),
        Some("binvox") => read_binvox(path, bytes).map(drop),
        _ => panic!("no reader for {name}"),
    };
    r.map_err(|e| e.to_string())
}

/// Reads `bytes` as `name`, expecting an error that names the file and
/// contains every one of `needles`; returns the message.
fn read_err(name: &str, bytes: &[u8], needles: &[&str]) -> String {
    let e = match read(name, bytes) {
        Ok(()) => panic!("{name}: expected an error, the reader accepted it"),
        Err(e) => e,
    };
    assert!(
        e.contains(name),
        "{name}: the error does not name the file: {e}"
    );
    for n in needles {
        assert!(e.contains(n), "{name}: the error lacks '{n}': {e}");
    }
    e
}

/// Runs `read` on `bytes`, turning a panic into a test failure that keeps the
/// input (in the temp directory) and says how to replay it.
fn read_no_panic(name: &str, bytes: &[u8], what: &str) -> Result<(), String> {
    match std::panic::catch_unwind(|| read(name, bytes)) {
        Ok(r) => r,
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            let keep = std::env::temp_dir()
                .join(format!("voltrack-crasher-{}-{name}", std::process::id()));
            std::fs::write(&keep, bytes).unwrap();
            panic!(
                "{what}: the {name} reader panicked ({msg}); input kept in {}",
                keep.display()
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Running the binary

fn run(dir: &Scratch, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(&dir.0)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the voltrack binary runs")
}

/// Writes `frames` as `seq/<name>` in `dir`.
fn sequence(dir: &Scratch, frames: &[(&str, Vec<u8>)]) {
    let seq = dir.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    for (name, bytes) in frames {
        std::fs::write(seq.join(name), bytes).unwrap();
    }
}

/// Bar frames `0..n` as OBJ, named `frame_<f>.obj`, with `replace` put in
/// place of frame `k` (under its own name).
fn bar_sequence(dir: &Scratch, n: usize, k: usize, replace: (&str, Vec<u8>)) {
    let mut frames: Vec<(String, Vec<u8>)> = (0..n)
        .map(|f| (format!("frame_{f}.obj"), obj(&bar(f))))
        .collect();
    frames[k] = (replace.0.to_string(), replace.1);
    let frames: Vec<(&str, Vec<u8>)> = frames
        .iter()
        .map(|(n, b)| (n.as_str(), b.clone()))
        .collect();
    sequence(dir, &frames);
}

/// `voltrack <command> <input> -r 32 -n 20 [extra] -o <out>`.
fn args<'a>(command: &'a str, input: &'a str, out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![command, input];
    args.extend(SMALL);
    args.extend(extra);
    args.extend(["-o", out]);
    args
}

/// `voltrack <args>` must fail with exit code 1 and no panic, its message
/// naming every one of `needles`, and leave the directory as it found it (no
/// output, no temporary file).
fn must_fail(dir: &Scratch, args: &[&str], needles: &[&str]) -> String {
    must_exit(dir, args, needles, 1)
}

/// [`must_fail`] for what is refused before any work, as a bad parameter is (exit 2).
fn must_refuse(dir: &Scratch, args: &[&str], needles: &[&str]) -> String {
    must_exit(dir, args, needles, 2)
}

fn must_exit(dir: &Scratch, args: &[&str], needles: &[&str], code: i32) -> String {
    let before = dir.files();
    let o = run(dir, args);
    let stderr = text(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(code),
        "voltrack {args:?}: stdout\n{}\nstderr\n{stderr}",
        text(&o.stdout)
    );
    assert!(
        !stderr.contains("panicked"),
        "voltrack {args:?} panicked:\n{stderr}"
    );
    assert!(stderr.contains("voltrack: error: "), "{stderr}");
    for n in needles {
        assert!(
            stderr.contains(n),
            "voltrack {args:?}: the error lacks '{n}':\n{stderr}"
        );
    }
    assert_eq!(
        dir.files(),
        before,
        "voltrack {args:?} left something behind"
    );
    stderr
}

/// `voltrack <args>` must succeed and add exactly the file `out` to `dir`;
/// returns its bytes (and removes it).
fn must_succeed(dir: &Scratch, args: &[&str], out: &str) -> Vec<u8> {
    let before = dir.files();
    let o = run(dir, args);
    assert!(
        o.status.success(),
        "voltrack {args:?} failed:\n{}",
        text(&o.stderr)
    );
    let mut want = before;
    want.push(out.to_string());
    want.sort();
    assert_eq!(dir.files(), want);
    let bytes = std::fs::read(dir.join(out)).unwrap();
    std::fs::remove_file(dir.join(out)).unwrap();
    bytes
}

/// The GLB parses, has one morph target per frame after the first, and finite
/// base positions and normals.
fn check_glb(bytes: &[u8], frames: usize) {
    let doc = gltf::Gltf::from_slice(bytes).expect("a valid GLB");
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(prim.morph_targets().count(), frames - 1);
    let blob = doc.blob.as_deref().unwrap();
    let reader = prim.reader(|_| Some(blob));
    assert!(reader
        .read_positions()
        .unwrap()
        .flatten()
        .all(f32::is_finite));
    assert!(reader.read_normals().unwrap().flatten().all(f32::is_finite));
}

// ---------------------------------------------------------------------------
// Parser cases

#[test]
fn every_truncation_of_ply_glb_and_binvox_is_an_error() {
    let cube = fixtures::cube(Point3::origin(), 1.0);
    let files = [
        ("cut.ply", ply(&cube, PlyEncoding::Ascii)),
        ("cut_le.ply", ply(&cube, PlyEncoding::BinaryLittleEndian)),
        ("cut_be.ply", ply(&cube, PlyEncoding::BinaryBigEndian)),
        ("cut.glb", glb(&cube)),
        ("cut.binvox", binvox()),
    ];
    for (name, bytes) in &files {
        read(name, bytes).unwrap_or_else(|e| panic!("{name} whole: {e}"));
        // The ASCII PLY's last line may lose its line break and stay valid.
        let whole = if name.ends_with("cut.ply") {
            bytes.len() - 1
        } else {
            bytes.len()
        };
        for len in 0..whole {
            let e = read_no_panic(name, &bytes[..len], &format!("{name} cut to {len} bytes"))
                .err()
                .unwrap_or_else(|| {
                    panic!("{name} cut to {len} of {} bytes was accepted", bytes.len())
                });
            assert!(e.contains(name), "{name} cut to {len}: {e}");
        }
    }
    // What the messages say, at a cut inside the body.
    read_err(
        "cut.ply",
        &files[0].1[..files[0].1.len() - 20],
        &["cut.ply:", "face 10 of 12", "file ends"],
    );
    read_err(
        "cut_le.ply",
        &files[1].1[..files[1].1.len() - 20],
        &["ends before", "byte"],
    );
    read_err("cut.glb", &files[3].1[..400], &["glTF"]);
}

#[test]
fn truncated_obj_is_an_error_or_a_valid_prefix() {
    let bytes = obj(&bar(0));
    for len in 0..bytes.len() {
        if let Err(e) = read_no_panic(
            "cut.obj",
            &bytes[..len],
            &format!("cut.obj cut to {len} bytes"),
        ) {
            assert!(e.contains("cut.obj"), "{e}");
        }
    }
    // Cut among the vertices: no faces at all, or half a vertex (line 5).
    let at = text(&bytes).find("\nv 0.64").unwrap() + 1;
    read_err("cut.obj", &bytes[..at], &["no triangles"]);
    read_err("cut.obj", &bytes[..at + 5], &["cut.obj:5", "three numbers"]);
    // Cut inside a face line, leaving two corners: OBJ faces have three or more.
    let at = text(&bytes).rfind("\nf ").unwrap();
    let line = text(&bytes[..at]).lines().count() + 1;
    let last = text(&bytes[at + 1..]);
    let two = last
        .split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ");
    let cut = [&bytes[..at + 1], two.as_bytes()].concat();
    read_err(
        "cut.obj",
        &cut,
        &[&format!("cut.obj:{line}"), "at least 3 corners"],
    );
}

#[test]
fn ply_element_counts_that_disagree_with_the_body() {
    let m = bar(0);
    let (v, f) = (m.positions.len(), m.triangles.len());
    for (enc, suffix) in [
        (PlyEncoding::Ascii, "ascii"),
        (PlyEncoding::BinaryLittleEndian, "le"),
        (PlyEncoding::BinaryBigEndian, "be"),
    ] {
        let bytes = ply(&m, enc);
        read(&format!("ok_{suffix}.ply"), &bytes).unwrap();
        // The message says which element did not fit (ASCII: an extra vertex
        // finds a face's values on its line; binary: the bytes shift and the
        // first face comes out wrong), or that data is left over.
        let extra_vertex = if enc == PlyEncoding::Ascii {
            format!("vertex {} of {}", v + 1, v + 1)
        } else {
            format!("face 1 of {f}")
        };
        let cases = [
            (
                "vertex_more",
                format!("element vertex {v}\n"),
                format!("element vertex {}\n", v + 1),
                extra_vertex,
            ),
            (
                "vertex_fewer",
                format!("element vertex {v}\n"),
                format!("element vertex {}\n", v - 1),
                format!("face 1 of {f}"),
            ),
            (
                "face_more",
                format!("element face {f}\n"),
                format!("element face {}\n", f + 1),
                format!("face {} of {}: file ends", f + 1, f + 1),
            ),
            (
                "face_fewer",
                format!("element face {f}\n"),
                format!("element face {}\n", f - 1),
                "data after the last element".into(),
            ),
        ];
        for (what, from, to, says) in cases {
            let name = format!("{what}_{suffix}.ply");
            let e = read_err(
                &name,
                &replace(&bytes, from.as_bytes(), to.as_bytes()),
                &[&says],
            );
            if enc == PlyEncoding::Ascii {
                assert!(e.contains(&format!("{name}:")), "no line: {e}");
            } else {
                assert!(e.contains("(at byte "), "no byte offset: {e}");
            }
        }
    }
}

#[test]
fn obj_face_indices() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
    // The triangles as corner ids (x + 2y + 4z), sorted.
    let ok = |name: &str, text: &str| {
        let m =
            read_obj(Path::new(name), text.as_bytes()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut t: Vec<[u64; 3]> = m
            .triangles
            .iter()
            .map(|t| {
                t.map(|i| m.positions[i as usize])
                    .map(|p| (p.x + 2.0 * p.y + 4.0 * p.z) as u64)
            })
            .collect();
        t.sort();
        t
    };
    // Negative indices are relative to the vertices so far: valid ones work.
    let positive = ok(
        "pos.obj",
        &format!("{tri}f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"),
    );
    assert_eq!(positive.len(), 4);
    assert_eq!(
        ok(
            "neg.obj",
            &format!("{tri}f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n")
        ),
        positive
    );
    // Relative to where the face is, not to the end of the file.
    let interleaved =
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -1 -2\nv 0 0 1\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n";
    assert_eq!(ok("interleaved.obj", interleaved), positive);
    // Every bad index is named with its line (5: the first face line).
    let bad = [
        ("range.obj", "f 1 2 5\n"),
        ("zero.obj", "f 0 1 2\n"),
        ("neg_range.obj", "f -1 -2 -5\n"),
        ("huge.obj", "f 1 2 99999999999999999999999\n"),
        ("min.obj", "f 1 2 -9223372036854775808\n"),
        ("word.obj", "f 1 2 three\n"),
        ("uv_range.obj", "f 1/3 2/1 3/1\n"),
        ("uv_zero.obj", "f 1/0 2/0 3/0\n"),
        ("uv_neg.obj", "f 1/-9 2/-9 3/-9\n"),
        ("normal_range.obj", "f 1//1 2//1 3//1\n"),
        ("slashes.obj", "f 1/1/1/1 2 3\n"),
        ("two.obj", "f 1 2\n"),
    ];
    for (name, face) in bad {
        let tri_uv = if name.starts_with("uv") {
            format!("{tri}vt 0 0\nvt 1 0\n")
        } else {
            tri.to_string()
        };
        let bytes = format!("{tri_uv}{face}");
        let line = bytes.lines().count();
        read_err(name, bytes.as_bytes(), &[&format!("{name}:{line}")]);
    }
}

#[test]
fn obj_lines_tobj_refuses_are_named() {
    // Colours on the first vertices only: tobj's "face vertex color index out of bounds".
    let colors = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1\nf 1 2 3\nf 1 2 4\n";
    read_err("colors.obj", colors.as_bytes(), &["colors.obj:4", "colors"]);
    read_err(
        "short_vt.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5\nf 1 2 3\n",
        &["short_vt.obj:4", "two numbers"],
    );
    read_err(
        "short_vn.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 1\nf 1 2 3\n",
        &["short_vn.obj:4", "three numbers"],
    );
    read_err(
        "latin1.obj",
        b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        &["latin1.obj:1", "UTF-8"],
    );
    // A material library that is not a regular file is skipped, not read.
    let m = read_obj(
        Path::new("mtl.obj"),
        b"mtllib /dev/zero\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    assert_eq!(m.triangles.len(), 1);
}

#[test]
fn non_finite_coordinates_are_named() {
    for (name, value) in [
        ("nan.obj", "nan"),
        ("inf.obj", "inf"),
        ("minus_inf.obj", "-inf"),
        ("overflow.obj", "1e309"),
    ] {
        let bytes = format!("v 0 0 0\nv 1 0 0\nv 0 {value} 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\n");
        read_err(
            name,
            bytes.as_bytes(),
            &[&format!("{name}:3"), "non-finite"],
        );
    }
    let m = bar(0);
    let ascii = ply(&m, PlyEncoding::Ascii);
    let line = line_of(&ascii, "end_header") + m.positions.len(); // the last vertex
    read_err(
        "nan.ply",
        &with_line(&ascii, line, "0 nan 0"),
        &[&format!("nan.ply:{line}"), "non-finite"],
    );
    let le = ply(&m, PlyEncoding::BinaryLittleEndian);
    let at = ply_body(&le) + 8; // vertex 0's y
    let mut bad = le.clone();
    bad[at..at + 8].copy_from_slice(&f64::INFINITY.to_le_bytes());
    read_err("inf.ply", &bad, &["non-finite", "vertex 1", "byte"]);
    // A GLB whose buffer holds a NaN (its JSON is untouched).
    let bytes = glb(&m);
    let p = m.positions[0].map(|c| c as f32);
    let first: Vec<u8> = [p.x, p.y, p.z]
        .iter()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let bad = replace(
        &bytes,
        &first,
        &[f32::NAN.to_le_bytes(), p.y.to_le_bytes(), p.z.to_le_bytes()].concat(),
    );
    read_err("nan.glb", &bad, &["non-finite"]);
}

#[test]
fn degenerate_triangles() {
    let m = bar(0);
    let a = m.positions[0];
    let b = m.positions[1];
    // Repeated corners, three collinear points, two coincident vertices.
    let few = with_extra(
        m.clone(),
        &[Point3::from((a.coords + b.coords) / 2.0), a],
        &[[0, 0, 1], [0, 1000, 1], [1001, 0, 2], [2, 2, 2]],
    );
    for (name, bytes) in [
        ("few.obj", obj(&few)),
        ("few.ply", ply(&few, PlyEncoding::BinaryLittleEndian)),
        ("few.glb", glb(&few)),
    ] {
        read(name, &bytes)
            .unwrap_or_else(|e| panic!("{name}: a few degenerate triangles must be accepted: {e}"));
    }
    // Nothing but degenerate triangles: no surface at all.
    let line = TriangleMesh {
        positions: (0..4).map(|i| Point3::new(i as Real, 0.0, 0.0)).collect(),
        triangles: vec![[0, 1, 2], [1, 2, 3], [0, 0, 3]],
        ..Default::default()
    };
    let point = TriangleMesh {
        positions: vec![a; 3],
        triangles: vec![[0, 1, 2]],
        ..Default::default()
    };
    for (stem, mesh) in [("collinear", &line), ("coincident", &point)] {
        for (ext, bytes) in [
            ("obj", obj(mesh)),
            ("ply", ply(mesh, PlyEncoding::Ascii)),
            ("glb", glb(mesh)),
        ] {
            read_err(&format!("{stem}.{ext}"), &bytes, &["degenerate"]);
        }
    }
}

#[test]
fn empty_and_blank_files() {
    let dir = Scratch::new("hostile", "empty");
    for ext in ["obj", "ply", "glb", "gltf", "binvox"] {
        let name = format!("empty.{ext}");
        let p = dir.join(&name);
        std::fs::write(&p, b"").unwrap();
        let e = read_frame(&p).unwrap_err().to_string();
        assert!(e.contains(&name) && e.contains("empty"), "{e}");
        read_err(&name, b"", &[]);
        read_err(&format!("blank.{ext}"), b" \n\n\t\r\n", &[]);
        read_err(&format!("zeros.{ext}"), &[0u8; 64], &[]);
    }
}

#[test]
fn headers_asking_for_absurd_sizes_fail_at_once() {
    let quick = |name: &str, bytes: &[u8]| {
        let start = Instant::now();
        let r = read_no_panic(name, bytes, name);
        assert!(
            // A guard against a reader that allocates or loops by what the
            // header claims (minutes), not a speed figure.
            start.elapsed() < Duration::from_secs(30),
            "{name} took {:?}",
            start.elapsed()
        );
        r
    };
    let props = "property float x\nproperty float y\nproperty float z\n";
    for format in ["ascii", "binary_little_endian"] {
        let name = format!("billions_{format}.ply");
        let bytes = format!("ply\nformat {format} 1.0\nelement vertex 4000000000\n{props}element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n");
        let e = quick(&name, bytes.as_bytes()).unwrap_err();
        assert!(e.contains(&name) && e.contains("4000000000"), "{e}");
        // An element without properties holds nothing, however many there are.
        let name = format!("nothing_{format}.ply");
        let bytes = format!("ply\nformat {format} 1.0\nelement nothing 4000000000\nelement vertex 1\n{props}end_header\n");
        let _ = quick(&name, bytes.as_bytes());
    }
    let e = quick(
        "huge.binvox",
        b"#binvox 1\ndim 100000 100000 100000\ntranslate 0 0 0\nscale 1\ndata\n\x00\xff",
    )
    .unwrap_err();
    assert!(e.contains("huge.binvox:2"), "{e}");
    // 4.3 billion voxels (just inside u32) announced by a file of a few bytes.
    let e = quick(
        "big.binvox",
        b"#binvox 1\ndim 4096 4096 255\ntranslate 0 0 0\nscale 1\ndata\n\x00\xff\x01\xff",
    )
    .unwrap_err();
    assert!(e.contains("big.binvox") && e.contains("4278190080"), "{e}");
    // A sparse POSITION accessor of four billion vertices over 16 bytes.
    let gltf = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
        "buffers":[{"byteLength":16,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAA=="}],
        "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":4},{"buffer":0,"byteOffset":4,"byteLength":12}],
        "accessors":[{"componentType":5126,"type":"VEC3","count":4000000000,"min":[0,0,0],"max":[0,0,0],
            "sparse":{"count":1,"indices":{"bufferView":0,"componentType":5125},"values":{"bufferView":1}}}]}"#;
    let e = quick("sparse.gltf", gltf.as_bytes()).unwrap_err();
    assert!(e.contains("sparse.gltf") && e.contains("4000000000"), "{e}");
}

/// A glTF whose meshes are reached through `nodes` (JSON) from scene node 0;
/// the mesh is one triangle.
fn gltf_with_nodes(nodes: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"type":"VEC3","count":3,"min":[0,0,0],"max":[1,1,0]}}]}}"#
    )
}

#[test]
fn gltf_node_graphs_that_are_not_trees() {
    // The triangle through a plain tree reads (and is degenerate-free).
    let tree = gltf_with_nodes(r#"[{"children":[1]},{"mesh":0}]"#);
    read("tree.gltf", tree.as_bytes()).unwrap();
    // A node that is its own child, and a cycle of two.
    read_err(
        "self.gltf",
        gltf_with_nodes(r#"[{"children":[0],"mesh":0}]"#).as_bytes(),
        &[],
    );
    read_err(
        "cycle.gltf",
        gltf_with_nodes(r#"[{"children":[1]},{"children":[0],"mesh":0}]"#).as_bytes(),
        &[],
    );
    // Forty layers of two nodes, each parent of both below: 2^40 paths to the
    // mesh from a file of a few kilobytes.
    let layers: Vec<String> = (0..40)
        .flat_map(|k| {
            let children = if k < 39 {
                format!(r#""children":[{},{}]"#, 2 * k + 2, 2 * k + 3)
            } else {
                r#""mesh":0"#.to_string()
            };
            [format!("{{{children}}}"), format!("{{{children}}}")]
        })
        .collect();
    let start = Instant::now();
    read_err(
        "diamonds.gltf",
        gltf_with_nodes(&format!("[{}]", layers.join(","))).as_bytes(),
        &["more than one parent"],
    );
    // 2^40 paths through the diamonds if walked naively: a guard, not a
    // speed figure.
    assert!(start.elapsed() < Duration::from_secs(30));
}

/// A one-triangle glTF with `positions` and `indices` as its two accessors
/// (JSON objects without `bufferView`, which is view 0 and 1) over a buffer
/// of three vertices and three u16 indices.
fn gltf_with_accessors(positions: &str, indices: &str, views: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"byteLength":44,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}}],
        "bufferViews":{views},
        "accessors":[{{"bufferView":0,"min":[0,0,0],"max":[1,1,0],{positions}}},{{"bufferView":1,{indices}}}]}}"#
    )
}

#[test]
fn gltf_accessors_the_gltf_crate_takes_on_trust() {
    let views = r#"[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}]"#;
    let pos = r#""componentType":5126,"type":"VEC3","count":3"#;
    let ind = r#""componentType":5123,"type":"SCALAR","count":3"#;
    read("ok.gltf", gltf_with_accessors(pos, ind, views).as_bytes()).unwrap();
    let cases = [
        // The crate's index reader has `unreachable!()` for float indices.
        (
            "float_indices.gltf",
            pos.to_string(),
            ind.replace("5123", "5126"),
            views.to_string(),
            "indices",
        ),
        (
            "vec2_positions.gltf",
            pos.replace("VEC3", "VEC2"),
            ind.into(),
            views.into(),
            "POSITION",
        ),
        (
            "no_vertices.gltf",
            pos.replace(r#""count":3"#, r#""count":0"#),
            ind.into(),
            views.into(),
            "0 elements",
        ),
        (
            "too_many.gltf",
            pos.replace(r#""count":3"#, r#""count":4"#),
            ind.into(),
            views.into(),
            "do not fit",
        ),
        (
            "offset.gltf",
            format!(r#"{pos},"byteOffset":18446744073709551615"#),
            ind.into(),
            views.into(),
            "do not fit",
        ),
        (
            "stride.gltf",
            pos.into(),
            ind.into(),
            views.replace(r#""byteLength":36}"#, r#""byteLength":36,"byteStride":4}"#),
            "stride",
        ),
        (
            "view_beyond.gltf",
            pos.into(),
            ind.into(),
            views.replace(r#""byteOffset":36"#, r#""byteOffset":40"#),
            "beyond its buffer",
        ),
        // Indices read from position bytes: the upper half of 1.0f32 is 16256.
        (
            "index_range.gltf",
            pos.into(),
            ind.into(),
            views.replace(
                r#""byteOffset":36,"byteLength":6"#,
                r#""byteOffset":12,"byteLength":6"#,
            ),
            "16256 is beyond",
        ),
    ];
    for (name, p, i, v, says) in cases {
        read_err(name, gltf_with_accessors(&p, &i, &v).as_bytes(), &[says]);
    }
    // External buffers are files beside the glTF (the regular-file check
    // behind that: gltf_buffer_uris_are_files_beside_the_gltf).
    let dev = gltf_with_accessors(pos, ind, views).replace("data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA=", "/dev/zero");
    read_err(
        "device.gltf",
        dev.as_bytes(),
        &["/dev/zero", "absolute path"],
    );
}

/// A small deterministic generator for the mutation test.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One to three random edits: overwrite a byte, flip a bit, delete or
/// duplicate a run, insert an extreme number or random bytes.
fn mutate(rng: &mut Rng, bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for _ in 0..1 + rng.below(3) {
        let len = b.len().max(1);
        let at = rng.below(len).min(b.len());
        let i = at.min(b.len().saturating_sub(1));
        match rng.below(6) {
            0 if !b.is_empty() => b[i] = rng.next() as u8,
            1 if !b.is_empty() => b[i] ^= 1 << rng.below(8),
            2 => {
                let end = (at + 1 + rng.below(16)).min(b.len());
                b.drain(at..end);
            }
            3 => {
                let end = (at + 1 + rng.below(32)).min(b.len());
                let run = b[at..end].to_vec();
                b.splice(at..at, run);
            }
            4 => {
                let word: &[u8] = [
                    &b"-1"[..],
                    b"0",
                    b"4294967295",
                    b"-2147483648",
                    b"1e308",
                    b"nan",
                    b"255",
                    b"\xff\xff\xff\x7f",
                ][rng.below(8)];
                b.splice(at..at, word.iter().copied());
            }
            _ => {
                let v = rng.next().to_le_bytes();
                b.splice(at..at, v[..1 + rng.below(8)].iter().copied());
            }
        }
    }
    b
}

#[test]
fn mutated_fixtures_never_panic() {
    let cube = fixtures::cube(Point3::origin(), 1.0);
    let textured = {
        let mut m = cube.clone();
        m.uvs = Some(
            m.positions
                .iter()
                .map(|p| [p.x as f32 + 0.5, p.y as f32 + 0.5])
                .collect(),
        );
        m
    };
    let files = [
        ("m.obj", obj(&textured)),
        ("m.ply", ply(&cube, PlyEncoding::Ascii)),
        ("m_le.ply", ply(&cube, PlyEncoding::BinaryLittleEndian)),
        ("m_be.ply", ply(&cube, PlyEncoding::BinaryBigEndian)),
        ("m.glb", glb(&textured)),
        ("m.binvox", binvox()),
    ];
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for (name, bytes) in &files {
        for k in 0..3000 {
            let input = mutate(&mut rng, bytes);
            if let Err(e) = read_no_panic(name, &input, &format!("{name} mutation {k}")) {
                assert!(e.contains(name), "{name} mutation {k}: {e}");
            }
        }
    }
}

#[test]
fn fuzz_crashers_are_errors() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut replayed = 0;
    for format in ["obj", "ply", "gltf", "binvox"] {
        let Ok(entries) = std::fs::read_dir(root.join(format)) else {
            continue;
        };
        let mut paths: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file())
            .collect();
        paths.sort();
        for p in paths {
            let bytes = std::fs::read(&p).unwrap();
            let ext = if format == "gltf" && bytes.starts_with(b"glTF") {
                "glb"
            } else {
                format
            };
            let name = format!("crasher.{ext}");
            let e = read_no_panic(&name, &bytes, &p.display().to_string())
                .err()
                .unwrap_or_else(|| panic!("{}: accepted", p.display()));
            assert!(e.contains(&name), "{}: {e}", p.display());
            replayed += 1;
        }
    }
    assert!(replayed > 0, "no input under tests/corpus");
}

#[test]
fn exr_trajectories_truncated_or_mangled() {
    let dir = Scratch::new("hostile", "exr");
    let traj =
        voltrack::model::Trajectories::from_frames(vec![vec![Point3::new(1.0, 2.0, 3.0); 5]; 3]);
    let path = dir.join("c.exr");
    voltrack::export::exr::write_trajectories_exr(&path, &traj, &Default::default()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let bad = dir.join("bad.exr");
    let mut rng = Rng(42);
    let mut inputs: Vec<Vec<u8>> = (0..bytes.len())
        .step_by(7)
        .map(|n| bytes[..n].to_vec())
        .collect();
    inputs.extend((0..300).map(|_| mutate(&mut rng, &bytes)));
    for input in inputs {
        std::fs::write(&bad, &input).unwrap();
        // The exr crate may accept a mutated pixel; it must not panic.
        if let Err(e) = voltrack::io::exr::read_trajectories_exr(&bad) {
            assert!(e.to_string().contains("bad.exr"), "{e}");
        }
    }
}

// ---------------------------------------------------------------------------
// End to end

#[test]
fn truncated_frames_fail_naming_the_file() {
    let dir = Scratch::new("hostile", "truncated");
    let m = bar(1);
    let o = obj(&m);
    let vertex_cut = text(&o).lines().take(4).map(|l| l.len() + 1).sum::<usize>() + 6;
    let face_cut = text(&o).rfind("\nf ").unwrap() + 5;
    let ascii = ply(&m, PlyEncoding::Ascii);
    let le = ply(&m, PlyEncoding::BinaryLittleEndian);
    let g = glb(&m);
    let cases: [(&str, Vec<u8>, &[&str]); 5] = [
        (
            "frame_1.obj",
            o[..vertex_cut].to_vec(),
            &["seq/frame_1.obj:", "three numbers"],
        ),
        (
            "frame_1.obj",
            o[..face_cut].to_vec(),
            &["seq/frame_1.obj:", "at least 3 corners"],
        ),
        (
            "frame_1.ply",
            ascii[..ascii.len() * 2 / 3].to_vec(),
            &["seq/frame_1.ply:", "file ends"],
        ),
        (
            "frame_1.ply",
            le[..le.len() - 5].to_vec(),
            &["seq/frame_1.ply", "file ends", "byte"],
        ),
        (
            "frame_1.glb",
            g[..g.len() - 100].to_vec(),
            &["seq/frame_1.glb"],
        ),
    ];
    for (name, bytes, needles) in cases {
        let _ = std::fs::remove_dir_all(dir.join("seq"));
        bar_sequence(&dir, 3, 1, (name, bytes));
        must_fail(&dir, &args("convert", "seq", "out.glb", &[]), needles);
        must_fail(&dir, &args("track", "seq", "c.exr", &[]), needles);
    }
}

#[test]
fn bad_headers_indices_and_coordinates_fail_naming_the_line() {
    let dir = Scratch::new("hostile", "lines");
    let m = bar(1);
    let ascii = ply(&m, PlyEncoding::Ascii);
    let faces = m.triangles.len();
    let fewer_faces = replace(
        &ascii,
        format!("element face {faces}\n").as_bytes(),
        format!("element face {}\n", faces - 2).as_bytes(),
    );
    let o = obj(&m);
    let first_face = line_of(&o, "f ");
    let bad_face = |face: &str| with_line(&o, first_face, face);
    let v = m.positions.len();
    let nan_line = line_of(&o, "v ") + 5;
    let nan = with_line(&o, nan_line, "v 0 NaN 0");
    let cases: Vec<(&str, Vec<u8>, String)> = vec![
        ("frame_1.ply", fewer_faces, "seq/frame_1.ply:".into()),
        (
            "frame_1.obj",
            bad_face(&format!("f 1 2 {}", v + 1)),
            format!("seq/frame_1.obj:{first_face}"),
        ),
        (
            "frame_1.obj",
            bad_face("f 0 1 2"),
            format!("seq/frame_1.obj:{first_face}"),
        ),
        (
            "frame_1.obj",
            bad_face(&format!("f -1 -2 -{}", v + 1)),
            format!("seq/frame_1.obj:{first_face}"),
        ),
        ("frame_1.obj", nan, format!("seq/frame_1.obj:{nan_line}")),
    ];
    for (name, bytes, needle) in cases {
        let _ = std::fs::remove_dir_all(dir.join("seq"));
        bar_sequence(&dir, 3, 1, (name, bytes));
        must_fail(&dir, &args("convert", "seq", "out.glb", &[]), &[&needle]);
    }
}

#[test]
fn relative_indices_degenerate_triangles_and_non_manifold_edges_convert() {
    let dir = Scratch::new("hostile", "convert");
    // Frame 0: negative (relative) indices throughout.
    let m0 = bar(0);
    let n0 = m0.positions.len() as i64;
    let mut rel = String::new();
    for p in &m0.positions {
        rel.push_str(&format!("v {} {} {}\n", p.x as f32, p.y as f32, p.z as f32));
    }
    for t in &m0.triangles {
        let [a, b, c] = t.map(|i| i as i64 - n0);
        rel.push_str(&format!("f {a} {b} {c}\n"));
    }
    // Frame 1: a few degenerate triangles, as captures have.
    let m1 = bar(1);
    let (a, b) = (m1.positions[0], m1.positions[1]);
    let degenerate = with_extra(
        m1,
        &[Point3::from((a.coords + b.coords) / 2.0), a],
        &[[0, 0, 1], [0, 1000, 1], [1001, 0, 2]],
    );
    // Frame 2: non-manifold: a fin on an edge (four triangles share it) and
    // a triangle listed twice.
    let m2 = bar(2);
    let [e0, e1, _] = m2.triangles[0];
    let fin_tip = m2.positions[e0 as usize] + voltrack::math::Vector3::new(0.0, -0.3, 0.3);
    let t = m2.triangles[10];
    let non_manifold = with_extra(m2, &[fin_tip], &[[e0, e1, 1000], [e1, e0, 1000], t]);
    sequence(
        &dir,
        &[
            ("frame_0.obj", rel.into_bytes()),
            (
                "frame_1.ply",
                ply(&degenerate, PlyEncoding::BinaryLittleEndian),
            ),
            ("frame_2.glb", glb(&non_manifold)),
            ("frame_3.obj", obj(&bar(3))),
        ],
    );
    check_glb(
        &must_succeed(&dir, &args("convert", "seq", "out.glb", &[]), "out.glb"),
        4,
    );
    must_succeed(&dir, &args("track", "seq", "c.exr", &[]), "c.exr");
    // Degenerate triangles in frame 0 end up in the output mesh: its normals stay finite.
    std::fs::write(dir.join("seq/frame_0.obj"), obj(&degenerate)).unwrap();
    check_glb(
        &must_succeed(
            &dir,
            &args("convert", "seq", "out.glb", &["--no-refine"]),
            "out.glb",
        ),
        4,
    );
}

#[test]
fn frames_without_volume_fail_naming_the_file() {
    let dir = Scratch::new("hostile", "novolume");
    let only_degenerate = TriangleMesh {
        positions: vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(3.0, 0.0, 0.0),
            Point3::new(1.5, 0.0, 0.0),
            Point3::new(0.0, 0.4, 0.4),
        ],
        triangles: vec![[0, 1, 2], [2, 1, 0], [3, 3, 3]],
        ..Default::default()
    };
    let cases: [(&str, Vec<u8>, &[&str]); 4] = [
        (
            "frame_1.obj",
            obj(&only_degenerate),
            &["seq/frame_1.obj", "degenerate"],
        ),
        // A flat sheet in an axis plane, and one tilted so that no axis sees it edge-on.
        (
            "frame_1.ply",
            ply(&sheet(8, [0.0, 0.0, 0.0]), PlyEncoding::Ascii),
            &["seq/frame_1.ply", "encloses no"],
        ),
        (
            "frame_1.glb",
            glb(&sheet(8, [0.3, 0.5, 0.2])),
            &["seq/frame_1.glb", "encloses no"],
        ),
        (
            "frame_0.obj",
            obj(&sheet(8, [0.7, -0.4, 0.1])),
            &["seq/frame_0.obj", "encloses no"],
        ),
    ];
    for (name, bytes, needles) in cases {
        let k = name[6..7].parse().unwrap();
        let _ = std::fs::remove_dir_all(dir.join("seq"));
        bar_sequence(&dir, 3, k, (name, bytes));
        must_fail(&dir, &args("convert", "seq", "out.glb", &[]), needles);
        must_fail(&dir, &args("track", "seq", "c.exr", &[]), needles);
    }
}

#[test]
fn a_frame_in_other_units_is_named() {
    let dir = Scratch::new("hostile", "units");
    for (scale, word) in [(1000.0, "larger"), (0.001, "smaller")] {
        let _ = std::fs::remove_dir_all(dir.join("seq"));
        bar_sequence(&dir, 5, 3, ("frame_3.obj", obj(&scaled(bar(3), scale))));
        let e = must_fail(
            &dir,
            &args("convert", "seq", "out.glb", &[]),
            &["seq/frame_3.obj", word, "units"],
        );
        // Only the odd frame is blamed first.
        assert!(
            e.find("frame_3.obj")
                < ["frame_0", "frame_1", "frame_2", "frame_4"]
                    .iter()
                    .filter_map(|f| e.find(f))
                    .min(),
            "{e}"
        );
    }
    // Frame 0 is the odd one: still named, not its neighbours.
    let _ = std::fs::remove_dir_all(dir.join("seq"));
    bar_sequence(&dir, 4, 0, ("frame_0.obj", obj(&scaled(bar(0), 1000.0))));
    must_fail(
        &dir,
        &args("track", "seq", "c.exr", &[]),
        &["seq/frame_0.obj: ", "larger", "units"],
    );
}

#[test]
fn too_few_voxels_for_the_centers() {
    let dir = Scratch::new("hostile", "centers");
    bar_sequence(&dir, 3, 0, ("frame_0.obj", obj(&bar(0))));
    let before = dir.files();
    let o = run(
        &dir,
        &["convert", "seq", "-r", "8", "-n", "2000", "-o", "out.glb"],
    );
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("seq/frame_0.obj")
            && stderr.contains("2000 centers")
            && stderr.contains("occupied voxels"),
        "{stderr}"
    );
    assert_eq!(dir.files(), before);
}

#[test]
fn empty_files_and_directories() {
    let dir = Scratch::new("hostile", "empties");
    bar_sequence(&dir, 3, 2, ("frame_2.ply", Vec::new()));
    must_fail(
        &dir,
        &args("convert", "seq", "out.glb", &[]),
        &["seq/frame_2.ply", "empty"],
    );
    std::fs::create_dir(dir.join("nomesh")).unwrap();
    std::fs::write(dir.join("nomesh/readme.txt"), "frames go here").unwrap();
    std::fs::write(dir.join("nomesh/frame_0.stl"), "solid").unwrap();
    must_fail(
        &dir,
        &args("convert", "nomesh", "out.glb", &[]),
        &["nomesh", "no mesh"],
    );
    must_fail(
        &dir,
        &args("track", "nomesh", "c.exr", &[]),
        &["nomesh", "no mesh"],
    );
    // One usable frame is not a sequence.
    std::fs::write(dir.join("nomesh/frame_0.obj"), obj(&bar(0))).unwrap();
    must_fail(
        &dir,
        &args("convert", "nomesh", "out.glb", &[]),
        &["nomesh/frame_0.obj", "at least 2"],
    );
}

#[test]
fn voxel_frames_on_different_grids_or_mixed_with_meshes() {
    let dir = Scratch::new("hostile", "binvox");
    let other = replace(&binvox(), b"scale ", b"scale 2");
    sequence(
        &dir,
        &[("frame_0.binvox", binvox()), ("frame_1.binvox", other)],
    );
    must_fail(
        &dir,
        &args("track", "seq", "c.exr", &[]),
        &["seq/frame_1.binvox", "differs"],
    );
    std::fs::write(
        dir.join("seq/frame_1.binvox"),
        b"#binvox 1\ndim 6 6 6\ndata\n\x01\xd8",
    )
    .unwrap();
    must_fail(
        &dir,
        &args("track", "seq", "c.exr", &[]),
        &["seq/frame_1.binvox", "differs"],
    );
    std::fs::write(dir.join("seq/frame_1.binvox"), &binvox()[..40]).unwrap();
    must_fail(
        &dir,
        &args("track", "seq", "c.exr", &[]),
        &["seq/frame_1.binvox"],
    );
    std::fs::remove_file(dir.join("seq/frame_1.binvox")).unwrap();
    std::fs::write(dir.join("seq/frame_1.obj"), obj(&bar(0))).unwrap();
    must_fail(
        &dir,
        &args("track", "seq", "c.exr", &[]),
        &["seq/frame_0.binvox", "seq/frame_1.obj", "voxel"],
    );
}

#[test]
fn unwritable_outputs_leave_nothing_behind() {
    let dir = Scratch::new("hostile", "unwritable");
    bar_sequence(&dir, 3, 0, ("frame_0.obj", obj(&bar(0))));
    std::fs::write(dir.join("somefile.txt"), b"a regular file").unwrap();
    std::fs::create_dir(dir.join("taken.glb")).unwrap();
    for out in [
        "somefile.txt/out.glb",
        "no_such_dir/out.glb",
        "no/such/dir/out.glb",
        "taken.glb",
    ] {
        must_refuse(&dir, &args("convert", "seq", out, &["--no-refine"]), &[out]);
    }
    must_refuse(
        &dir,
        &args("convert", "seq", "somefile.txt/out.glb", &["--no-refine"]),
        &["somefile.txt", "not a directory"],
    );
    for out in ["somefile.txt/c.exr", "no_such_dir/c.exr"] {
        must_refuse(&dir, &args("track", "seq", out, &[]), &[out]);
    }
    // The voxel frames of `voxelize` go into a directory it creates: not under a file.
    must_refuse(
        &dir,
        &["voxelize", "seq", "-r", "16", "-o", "somefile.txt/voxels"],
        &["somefile.txt"],
    );
    // Files written together: a companion's name taken fails the whole
    // output, and leaves neither file.
    std::fs::create_dir(dir.join("anim.json")).unwrap();
    must_refuse(
        &dir,
        &args("convert", "seq", "anim.exr", &["--no-refine", "--vat"]),
        &["anim.json"],
    );
    std::fs::create_dir(dir.join("cache.obj")).unwrap();
    must_refuse(
        &dir,
        &args("convert", "seq", "cache.pc2", &["--no-refine"]),
        &["cache.obj"],
    );
    must_refuse(
        &dir,
        &args("convert", "seq", "somefile.txt/frames", &["--no-refine"]),
        &["somefile.txt", "not a directory"],
    );
    assert!(dir.join("taken.glb").is_dir());
    assert_eq!(
        std::fs::read(dir.join("somefile.txt")).unwrap(),
        b"a regular file"
    );

    // Outputs are checked before any work: with a bad frame and a bad output
    // path, the output is what the error names.
    std::fs::write(dir.join("seq/frame_1.obj"), b"v 0 0 0\nf 1 2 3\n").unwrap();
    let voxelize = vec!["voxelize", "seq", "-r", "16", "-o", "somefile.txt/voxels"];
    for run in [
        args("convert", "seq", "no_such_dir/out.glb", &[]),
        args("track", "seq", "no_such_dir/c.exr", &[]),
        voxelize,
    ] {
        let e = must_refuse(&dir, &run, &[run.last().unwrap()]);
        assert!(!e.contains("frame_1.obj"), "{e}");
    }
    std::fs::write(dir.join("seq/frame_1.obj"), obj(&bar(1))).unwrap();

    // A read-only directory: only meaningful where permissions bind (not as root).
    use std::os::unix::fs::PermissionsExt;
    let ro = dir.join("readonly");
    std::fs::create_dir(&ro).unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    let binding = std::fs::write(ro.join("probe"), b"").is_err();
    if binding {
        must_refuse(
            &dir,
            &args("convert", "seq", "readonly/out.glb", &["--no-refine"]),
            &["readonly/out.glb"],
        );
        assert_eq!(std::fs::read_dir(&ro).unwrap().count(), 0);
    } else {
        std::fs::remove_file(ro.join("probe")).unwrap();
    }
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
}

#[test]
fn voxelize_with_colliding_frame_names_writes_nothing() {
    let dir = Scratch::new("hostile", "collide");
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::create_dir_all(dir.join("b")).unwrap();
    std::fs::write(dir.join("a/frame.obj"), obj(&bar(0))).unwrap();
    std::fs::write(dir.join("a/other.obj"), obj(&bar(1))).unwrap();
    std::fs::write(dir.join("b/frame.obj"), obj(&bar(2))).unwrap();
    let before = dir.files();
    let o = run(
        &dir,
        &[
            "voxelize",
            "a/frame.obj",
            "a/other.obj",
            "b/frame.obj",
            "-r",
            "16",
            "-o",
            "vox",
        ],
    );
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("frame"), "{stderr}");
    assert_eq!(dir.files(), before, "{stderr}");
    assert!(!dir.join("vox").exists());
}

#[test]
fn voxelize_writes_every_frame_or_none() {
    let dir = Scratch::new("hostile", "voxsets");
    bar_sequence(&dir, 3, 0, ("frame_0.obj", obj(&bar(0))));
    // The last frame's output name is taken by a directory voltrack did not
    // make: refused before any work, nothing written.
    std::fs::create_dir_all(dir.join("vox/frame_2.binvox")).unwrap();
    must_refuse(
        &dir,
        &["voxelize", "seq", "-r", "16", "-o", "vox"],
        &["frame_2.binvox", "not written by voltrack"],
    );
    std::fs::remove_dir(dir.join("vox/frame_2.binvox")).unwrap();
    let o = run(&dir, &["voxelize", "seq", "-r", "16", "-o", "vox"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let shown = |d: &Path| {
        std::fs::read_dir(d)
            .unwrap()
            .flatten()
            .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
            .count()
    };
    assert_eq!(shown(&dir.join("vox")), 3);
}

/// A folder written as a set ([`voltrack::files::replace_dir`]) whose
/// writing fails halfway leaves the old folder as it was and nothing beside
/// it; written completely, it replaces the old one whole.
#[test]
fn a_folder_written_as_a_set_replaces_the_old_one_whole_or_not_at_all() {
    use voltrack::files::{replace_dir, Fill};
    let dir = Scratch::new("hostile", "folder-sets");
    let bytes =
        |b: &'static [u8]| -> Fill<'static> { Box::new(move |w| std::io::Write::write_all(w, b)) };
    let failing = || -> Fill<'static> { Box::new(|_| Err(std::io::Error::other("disk full"))) };
    let out = dir.join("frames");
    replace_dir(
        &out,
        vec![
            ("a.obj".into(), bytes(b"a1")),
            ("b.obj".into(), bytes(b"b1")),
            ("c.obj".into(), bytes(b"c1")),
        ],
    )
    .unwrap();
    let before = dir.files();
    let e = replace_dir(
        &out,
        vec![("a.obj".into(), bytes(b"a2")), ("b.obj".into(), failing())],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("b.obj") && e.contains("disk full"), "{e}");
    assert_eq!(
        dir.files(),
        before,
        "a failed write changed the folder or left something beside it"
    );
    assert_eq!(std::fs::read(out.join("a.obj")).unwrap(), b"a1");
    // Fewer files the second time: c.obj does not stay.
    replace_dir(
        &out,
        vec![
            ("a.obj".into(), bytes(b"a2")),
            ("b.obj".into(), bytes(b"b2")),
        ],
    )
    .unwrap();
    let want: Vec<String> = [".voltrack-files", "a.obj", "b.obj"]
        .iter()
        .map(|n| format!("frames/{n}"))
        .collect();
    assert_eq!(dir.files(), want);
    assert_eq!(std::fs::read(out.join("b.obj")).unwrap(), b"b2");
}

#[test]
fn files_written_as_a_set_appear_together_or_not_at_all() {
    use voltrack::files::{write_atomic_all, Fill};
    let dir = Scratch::new("hostile", "sets");
    let bytes =
        |b: &'static [u8]| -> Fill<'static> { Box::new(move |w| std::io::Write::write_all(w, b)) };
    let (a, b) = (dir.join("a.exr"), dir.join("a.json"));
    // The second target is a directory: the first, written already, goes too.
    std::fs::create_dir(&b).unwrap();
    let e = write_atomic_all(vec![
        (a.as_path(), bytes(b"one")),
        (b.as_path(), bytes(b"two")),
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("a.json"), "{e}");
    assert_eq!(dir.files(), Vec::<String>::new());
    std::fs::remove_dir(&b).unwrap();
    // The second fill fails.
    let failing: Fill = Box::new(|_| Err(std::io::Error::other("no space left")));
    let e = write_atomic_all(vec![(a.as_path(), bytes(b"one")), (b.as_path(), failing)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("a.json") && e.contains("no space left"), "{e}");
    assert_eq!(dir.files(), Vec::<String>::new());
    // Both succeed.
    write_atomic_all(vec![
        (a.as_path(), bytes(b"one")),
        (b.as_path(), bytes(b"two")),
    ])
    .unwrap();
    assert_eq!(dir.files(), ["a.exr", "a.json"]);
    assert_eq!(std::fs::read(&b).unwrap(), b"two");
}

/// Issue 49, item 14: messages that said the wrong thing. A `.glb` without
/// the binary header was reported as bad JSON; an index past i64 as "not a
/// whole number"; a tiny memory limit as "0.0 GiB" with "about 2" fitting.
#[test]
fn messages_say_what_is_wrong() {
    read_err(
        "magic.glb",
        b"GLTF\x02\x00\x00\x00{\"asset\":{}}",
        &["not a binary glTF", "'GLTF'"],
    );
    read_err(
        "big.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",
        &["big.obj:4", "too large"],
    );
    let dir = Scratch::new("hostile", "memory-message");
    bar_sequence(&dir, 3, 0, ("frame_0.obj", obj(&bar(0))));
    let stderr = must_refuse(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "64",
            "-o",
            "x.glb",
            "--max-memory",
            "0.000001",
        ],
        &["KiB", "the 1.0 KiB allowed"],
    );
    assert!(!stderr.contains("0.0 GiB"), "{stderr}");
    let stderr = must_refuse(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "64",
            "-o",
            "x.glb",
            "--max-memory",
            "0.000000001",
        ],
        &["no resolution fits"],
    );
    assert!(!stderr.contains("about 2"), "{stderr}");
}

/// OBJ as tools write it: a comment after the data, a line continued by
/// `\`, a `usemtl` naming nothing. Each reads as the plain file does, and
/// an error after a continued line still names its own line.
#[test]
fn obj_comments_continuations_and_bare_usemtl_read_as_written() {
    let plain = read_obj(Path::new("plain.obj"), TETRA_OBJ.as_bytes()).unwrap();
    let variants = [
        TETRA_OBJ.replace("v 1 0 0\n", "v 1 0 0 # the x axis\n"),
        TETRA_OBJ.replace("v 1 0 0\n", "v 1 \\\n 0 0\n"),
        TETRA_OBJ.replace("f 1 2 3\n", "f 1 \\\r\n 2 \\\n 3\n"),
        format!("usemtl\n{TETRA_OBJ}"),
        format!("usemtl   # none\n{TETRA_OBJ}"),
    ];
    for text in &variants {
        let mesh = read_obj(Path::new("variant.obj"), text.as_bytes())
            .unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_eq!(mesh.positions, plain.positions, "{text:?}");
        assert_eq!(mesh.triangles, plain.triangles, "{text:?}");
    }
    read_err(
        "continued.obj",
        format!("v 0 \\\n0 \\\n0\n{}f 1 2 9\n", &TETRA_OBJ[8..]).as_bytes(),
        &["continued.obj:11:", "only 4 vertices"],
    );
    read_err(
        "huge.obj",
        b"v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n",
        &["huge.obj:2:", "1e39", "32-bit float"],
    );
}

/// A tetrahedron, one `v` or `f` per line, its first line `v 0 0 0`.
const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// glTF buffer URIs that are not files beside the glTF are refused, naming
/// the URI; a percent-encoded name is decoded.
#[test]
fn gltf_buffer_uris_are_files_beside_the_gltf() {
    let dir = Scratch::new("hostile", "gltf-uris");
    let positions: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let buffer: Vec<u8> = positions.iter().flat_map(|c| c.to_le_bytes()).collect();
    std::fs::write(dir.join("my buffer.bin"), &buffer).unwrap();
    let gltf = |uri: &str| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "buffers":[{{"uri":"{uri}","byteLength":36}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}]}}"#
        )
    };
    let path = dir.join("a.gltf");
    let read_uri = |uri: &str| {
        let text = gltf(uri);
        std::fs::write(&path, &text).unwrap();
        read_gltf(&path, text.as_bytes()).map_err(|e| e.to_string())
    };
    let mesh = read_uri("my%20buffer.bin").expect("a percent-encoded name");
    assert_eq!(mesh.positions.len(), 3);
    // Only a regular file: a link to a device must not hang the reader.
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.bin")).unwrap();
    let e = read_uri("zero.bin").expect_err("a device");
    assert!(e.contains("zero.bin") && e.contains("regular file"), "{e}");
    for (uri, needle) in [
        ("http://example.com/b.bin", "'http:' URI"),
        ("file:///etc/passwd", "'file:' URI"),
        ("/etc/passwd", "absolute path"),
        ("a.gltf", "the glTF file itself"),
        ("../missing.bin", "missing.bin"),
        ("bad%zzname", "percent-encoding"),
    ] {
        let e = read_uri(uri).expect_err(uri);
        assert!(
            e.contains("a.gltf")
                && e.contains(&format!("buffer URI '{uri}'"))
                && e.contains(needle),
            "{uri}: {e}"
        );
    }
}

/// A frame is read by more than one pass; its warnings are printed once.
#[test]
fn a_frame_read_twice_warns_once() {
    let dir = Scratch::new("hostile", "warn-once");
    let mut frame = b"usemtl\n".to_vec();
    frame.extend(obj(&bar(0)));
    bar_sequence(&dir, 3, 0, ("frame_0.obj", frame));
    let o = run(&dir, &args("convert", "seq", "x.glb", &[]));
    let stderr = text(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert_eq!(
        stderr
            .matches("frame_0.obj:1: 'usemtl' names no material")
            .count(),
        1,
        "{stderr}"
    );
}
