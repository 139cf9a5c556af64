//! Inputs that are valid but were read wrongly: hidden files among the
//! frames, frame numbers of any length, wildcards in directories, byte-order
//! marks, classic-Mac line endings, OBJ vertex lines tobj misreads without a
//! line, concave polygons, glTF strips and fans, and a frame out of place.
//! Each case checks what the reader produces (or the error it names), not
//! only that it does not fail.

use std::path::Path;
use std::process::{Command, Output};
use voltrack::export::ply::PlyEncoding;
use voltrack::io::{discover_frames, read_gltf, read_obj, read_ply};
use voltrack::math::{Point3, Real, Rotation3, Vector3};
use voltrack::{fixtures, TriangleMesh};

mod common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
/// Tiny settings: every run is well under a second.
const SMALL: [&str; 4] = ["-r", "32", "-n", "20"];

use common::{obj_bytes as obj, ply_bytes as ply};

/// The reader for `name`'s extension, called directly.
fn read(name: &str, bytes: &[u8]) -> Result<TriangleMesh, String> {
    let path = Path::new(name);
    let r = match path.extension().and_then(|e| e.to_str()) {
        Some("obj") => read_obj(path, bytes),
        Some("ply") => read_ply(path, bytes),
        Some("glb") | Some("gltf") => read_gltf(path, bytes),
        _ => panic!("no reader for {name}"),
    };
    r.map_err(|e| e.to_string())
}

fn read_ok(name: &str, bytes: &[u8]) -> TriangleMesh {
    read(name, bytes).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Reads `bytes` as `name`, expecting an error that contains every one of
/// `needles` (give the file name and line as "name:line").
fn read_err(name: &str, bytes: &[u8], needles: &[&str]) -> String {
    let e = match read(name, bytes) {
        Ok(_) => panic!("{name}: expected an error, the reader accepted it"),
        Err(e) => e,
    };
    for n in needles {
        assert!(e.contains(n), "{name}: the error lacks '{n}': {e}");
    }
    e
}

/// Same vertices (in order) and same triangles over them.
fn assert_same_mesh(name: &str, got: &TriangleMesh, want: &TriangleMesh) {
    assert_eq!(got.positions, want.positions, "{name}: positions differ");
    assert_eq!(got.triangles, want.triangles, "{name}: triangles differ");
}

/// Every LF of `bytes` replaced by `with`.
fn line_ends(bytes: &[u8], with: &[u8]) -> Vec<u8> {
    bytes
        .iter()
        .flat_map(|&b| if b == b'\n' { with.to_vec() } else { vec![b] })
        .collect()
}

fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            out.push(if k <= chunk.len() {
                ABC[(n >> (18 - 6 * k)) as usize & 63] as char
            } else {
                '='
            });
        }
    }
    out
}

/// A .gltf with one node whose mesh has one primitive per `(mode, indices)`,
/// all over `positions`, with the buffer embedded as a data URI.
fn gltf_doc(positions: &[Point3], primitives: &[(u32, &[u32])]) -> String {
    let mut buffer: Vec<u8> = positions
        .iter()
        .flat_map(|p| [p.x, p.y, p.z].map(|c| c as f32))
        .flat_map(f32::to_le_bytes)
        .collect();
    let (lo, hi) = (0..3).fold(([f32::MAX; 3], [f32::MIN; 3]), |(mut lo, mut hi), k| {
        for p in positions {
            lo[k] = lo[k].min(p[k] as f32);
            hi[k] = hi[k].max(p[k] as f32);
        }
        (lo, hi)
    });
    let mut views = vec![format!(r#"{{"buffer":0,"byteLength":{}}}"#, buffer.len())];
    let mut accessors = vec![format!(
        r#"{{"bufferView":0,"componentType":5126,"type":"VEC3","count":{},"min":{lo:?},"max":{hi:?}}}"#,
        positions.len()
    )];
    let mut prims = Vec::new();
    for (mode, indices) in primitives {
        let offset = buffer.len();
        buffer.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}}}"#,
            4 * indices.len()
        ));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5125,"type":"SCALAR","count":{}}}"#,
            views.len() - 1,
            indices.len()
        ));
        prims.push(format!(
            r#"{{"attributes":{{"POSITION":0}},"indices":{},"mode":{mode}}}"#,
            accessors.len() - 1
        ));
    }
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{}]}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}],
        "bufferViews":[{}],"accessors":[{}]}}"#,
        prims.join(","),
        buffer.len(),
        base64(&buffer),
        views.join(","),
        accessors.join(",")
    )
}

const BOM: &[u8] = b"\xef\xbb\xbf";

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn run(dir: &Scratch, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(&dir.0)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the voltrack binary runs")
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
        .map(|p| {
            p.strip_prefix(&dir.0)
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
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
    assert_eq!(
        discovered(&dir, "seq"),
        ["seq/frame_1.obj", "seq/frame_2.obj"]
    );
    assert_eq!(
        discovered(&dir, "seq/*.obj"),
        ["seq/frame_1.obj", "seq/frame_2.obj"]
    );
    assert_eq!(
        discovered(&dir, "seq/*frame_?.obj"),
        ["seq/frame_1.obj", "seq/frame_2.obj"]
    );
    // Asked for by name, as a shell would: a pattern starting with '.'.
    assert_eq!(discovered(&dir, "seq/.frame_*.obj"), ["seq/.frame_8.obj"]);
    // Hidden directories are not matched by a wildcard either.
    let e = discover_frames(&[dir.join("seq/*/frame_0.obj")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("no file matches this pattern"), "{e}");
    assert_eq!(
        discovered(&dir, "seq/.*/frame_0.obj"),
        ["seq/.hidden_dir/frame_0.obj"]
    );
}

#[test]
fn frame_numbers_of_any_length_keep_their_order() {
    let dir = Scratch::new("formats", "longnumbers");
    // 10^40 + k for k in 0..12, written out: past u128 (about 3.4 * 10^38).
    let names: Vec<String> = (0..12)
        .map(|k| format!("seq/frame_1{}{k:02}.obj", "0".repeat(38)))
        .collect();
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
    assert_eq!(
        discovered(&dir, "takes/take_*/mesh.obj"),
        [
            "takes/take_1/mesh.obj",
            "takes/take_2/mesh.obj",
            "takes/take_10/mesh.obj"
        ]
    );
    assert_eq!(
        discovered(&dir, "seq*/frame_*.obj"),
        ["seq2/frame_9.obj", "seq2/frame_10.obj", "seq10/frame_1.obj"]
    );
    assert_eq!(discovered(&dir, "seq?/frame_1*.obj"), ["seq2/frame_10.obj"]);
    assert_eq!(
        discovered(&dir, "*/take_?/*.obj"),
        [
            "takes/take_1/mesh.obj",
            "takes/take_2/mesh.obj",
            "takes/take_3/other.obj"
        ]
    );
    // Nothing matches: the pattern is named, not a missing file.
    for pattern in [
        "takes/take_*/absent.obj",
        "nothing_*/mesh.obj",
        "takes/take_*/*.ply",
    ] {
        let e = discover_frames(&[dir.join(pattern)])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(pattern) && e.contains("no file matches this pattern"),
            "{e}"
        );
    }
    // Relative patterns run from the current directory, as on the command line.
    for (k, take) in ["take_1", "take_2", "take_10"].iter().enumerate() {
        std::fs::write(
            dir.join(&format!("takes/{take}/mesh.obj")),
            obj(&fixtures::bending_bar(k)),
        )
        .unwrap();
    }
    let mut args = vec!["track", "takes/take_*/mesh.obj"];
    args.extend(SMALL);
    args.extend(["-o", "c.exr"]);
    let o = run(&dir, &args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(dir.join("c.exr").is_file());
}

// ---------------------------------------------------------------------------
// Text encodings: byte-order marks and line ends

#[test]
fn a_byte_order_mark_is_skipped() {
    let m = fixtures::bending_bar(2);
    let (o, a) = (obj(&m), ply(&m, PlyEncoding::Ascii));
    let want_obj = read_ok("plain.obj", &o);
    // The mark glued to the first `v` made tobj skip that vertex, shifting every face.
    assert!(
        text(&o).starts_with("# "),
        "the OBJ writer's comment line moved"
    );
    let first_v = text(&o).find("\nv ").unwrap() + 1;
    let bom_at_v = [BOM, &o[first_v..]].concat();
    let without_comment = read_ok("no_comment.obj", &o[first_v..]);
    assert_same_mesh(
        "bom_v.obj",
        &read_ok("bom_v.obj", &bom_at_v),
        &without_comment,
    );
    assert_same_mesh(
        "bom.obj",
        &read_ok("bom.obj", &[BOM, &o].concat()),
        &want_obj,
    );
    // An unused last vertex: the shift went unnoticed, every face one vertex off.
    let tetra =
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let shifted = read_ok("bom_tetra.obj", &[BOM, tetra].concat());
    assert_same_mesh("bom_tetra.obj", &shifted, &read_ok("tetra.obj", tetra));
    assert!((shifted.signed_volume() - 1.0 / 6.0).abs() < 1e-12);
    assert_same_mesh(
        "bom.ply",
        &read_ok("bom.ply", &[BOM, &a].concat()),
        &read_ok("plain.ply", &a),
    );
    // A .gltf's JSON.
    let cube = fixtures::cube(Point3::origin(), 1.0);
    let indices: Vec<u32> = cube.triangles.iter().flatten().copied().collect();
    let gltf = gltf_doc(&cube.positions, &[(4, &indices)]);
    assert_same_mesh(
        "bom.gltf",
        &read_ok("bom.gltf", &[BOM, gltf.as_bytes()].concat()),
        &read_ok("plain.gltf", gltf.as_bytes()),
    );
    // Errors still count lines from the first.
    let bad = [BOM, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"].concat();
    read_err("bom_bad.obj", &bad, &["bom_bad.obj:4"]);
}

#[test]
fn classic_mac_line_ends_read_like_unix_ones() {
    let m = fixtures::bending_bar(3);
    let o = obj(&m);
    let want = read_ok("lf.obj", &o);
    assert_same_mesh("cr.obj", &read_ok("cr.obj", &line_ends(&o, b"\r")), &want);
    assert_same_mesh(
        "crlf.obj",
        &read_ok("crlf.obj", &line_ends(&o, b"\r\n")),
        &want,
    );
    let a = ply(&m, PlyEncoding::Ascii);
    let want = read_ok("lf.ply", &a);
    assert_same_mesh("cr.ply", &read_ok("cr.ply", &line_ends(&a, b"\r")), &want);
    assert_same_mesh(
        "crlf.ply",
        &read_ok("crlf.ply", &line_ends(&a, b"\r\n")),
        &want,
    );
    // Line numbers in errors count CR-ended lines.
    read_err(
        "cr_bad.obj",
        b"v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 7\r",
        &["cr_bad.obj:4"],
    );
    let header_lines = text(&a).lines().position(|l| l == "end_header").unwrap() + 1;
    let bad_vertex = text(&a)
        .replacen("\nend_header\n", "\nend_header\n0 nan 0\n", 1)
        .replacen(
            &format!("element vertex {}", m.positions.len()),
            &format!("element vertex {}", m.positions.len() + 1),
            1,
        );
    read_err(
        "cr_bad.ply",
        &line_ends(bad_vertex.as_bytes(), b"\r"),
        &[&format!("cr_bad.ply:{}", header_lines + 1), "non-finite"],
    );
}

// ---------------------------------------------------------------------------
// OBJ vertex lines

#[test]
fn obj_vertex_lines_tobj_misreads_are_named() {
    let faces = "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let with_third = |v: &str| format!("v 0 0 0\nv 1 0 0\n{v}\nv 0 0 1\n{faces}");
    for (name, v, says) in [
        ("w_zero.obj", "v 0 1 0 0", "w = 0"),
        ("w_nan.obj", "v 0 1 0 NaN", "w = NaN"),
        ("w_inf.obj", "v 0 1 0 inf", "w = inf"),
        ("w_overflow.obj", "v 0 1e300 0 1e-300", "non-finite"),
        ("five.obj", "v 0 1 0 1 1", "5 numbers"),
        ("seven.obj", "v 0 1 0 1 0 0 1", "7 numbers"),
        ("nine.obj", "v 0 1 0 1 0 0 1 2 3", "9 numbers"),
        ("word.obj", "v 0 1 0 one", "'one' is not a number"),
        ("color_word.obj", "v 0 1 0 1 red 0", "'red' is not a number"),
        ("two.obj", "v 0 1", "three numbers"),
    ] {
        read_err(
            name,
            with_third(v).as_bytes(),
            &[&format!("{name}:3"), "vertex", says],
        );
    }
    // The valid forms: a weight divides the coordinates, colours are read past.
    let tetra = |v: &str| read_ok("ok.obj", with_third(v).as_bytes());
    let plain = tetra("v 0 1 0");
    assert_same_mesh("w.obj", &tetra("v 0 2 0 2"), &plain);
    assert_same_mesh("w_one.obj", &tetra("v 0 1 0 1"), &plain);
    let colored = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1 1 1 1\n";
    assert_same_mesh(
        "rgb.obj",
        &read_ok("rgb.obj", format!("{colored}{faces}").as_bytes()),
        &plain,
    );
}

// ---------------------------------------------------------------------------
// Concave polygons

/// The 10 corners of a five-pointed star (radii 1 and 0.4), counter-clockwise.
fn star() -> Vec<[Real; 2]> {
    (0..10)
        .map(|k| {
            let (r, t) = (
                if k % 2 == 0 { 1.0 } else { 0.4 },
                k as Real * std::f64::consts::PI / 5.0,
            );
            [r * t.cos(), r * t.sin()]
        })
        .collect()
}

fn shoelace(p: &[[Real; 2]]) -> Real {
    (0..p.len())
        .map(|i| p[i][0] * p[(i + 1) % p.len()][1] - p[(i + 1) % p.len()][0] * p[i][1])
        .sum::<Real>()
        / 2.0
}

/// Crossing number: strictly inside the polygon.
fn inside(p: [Real; 2], poly: &[[Real; 2]]) -> bool {
    let mut odd = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
        {
            odd = !odd;
        }
    }
    odd
}

/// A star prism of height 0.5 turned by `rot`: vertices 0..10 the bottom
/// star (z = 0), 10..20 the top one; the two star caps as single faces of 10
/// corners, the sides as quads, all facing out.
fn star_prism(rot: &Rotation3) -> (Vec<Point3>, Vec<Vec<u32>>) {
    let s = star();
    let positions: Vec<Point3> = [0.0, 0.5]
        .iter()
        .flat_map(|&z| s.iter().map(move |p| Point3::new(p[0], p[1], z)))
        .map(|p| rot * p)
        .collect();
    let mut faces = vec![(0..10).rev().collect::<Vec<u32>>(), (10..20).collect()];
    faces.extend((0..10).map(|i| vec![i, (i + 1) % 10, 10 + (i + 1) % 10, 10 + i]));
    (positions, faces)
}

/// The triangles of `m` in the plane z = `z` (after undoing `rot`) must tile
/// the star: as many as a triangulation has, centroids inside the star,
/// facing `up` (+1 or -1 along z), areas summing to the star's.
fn check_cap(name: &str, m: &TriangleMesh, rot: &Rotation3, z: Real, up: Real) {
    let local: Vec<Point3> = m.positions.iter().map(|p| rot.inverse() * p).collect();
    let cap: Vec<[Point3; 3]> = m
        .triangles
        .iter()
        .map(|t| t.map(|i| local[i as usize]))
        .filter(|t| t.iter().all(|p| (p.z - z).abs() < 1e-5))
        .collect();
    assert_eq!(cap.len(), 8, "{name}: a 10-corner face is 8 triangles");
    let star = star();
    let mut area = 0.0;
    for [a, b, c] in &cap {
        let facing = (b - a).cross(&(c - a)).z * up;
        assert!(
            facing > 0.0,
            "{name}: cap triangle {a} {b} {c} inverted or flat"
        );
        area += facing / 2.0;
        let centroid = (a.coords + b.coords + c.coords) / 3.0;
        assert!(
            inside([centroid.x, centroid.y], &star),
            "{name}: cap triangle {a} {b} {c} lies outside the star"
        );
    }
    let want = shoelace(&star);
    assert!(
        (area - want).abs() < 1e-5 * want,
        "{name}: cap area {area}, the star's {want}"
    );
}

#[test]
fn concave_polygons_are_triangulated_inside_the_face() {
    // Tilted, so the cap is triangulated in its own plane.
    for rot in [
        Rotation3::identity(),
        Rotation3::new(Vector3::new(0.4, -0.9, 0.3)),
    ] {
        let (positions, faces) = star_prism(&rot);
        let mut o = String::new();
        for p in &positions {
            o += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        for f in &faces {
            o += &format!(
                "f {}\n",
                f.iter()
                    .map(|i| (i + 1).to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        let mut a = format!(
            "ply\nformat ascii 1.0\nelement vertex 20\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            faces.len()
        );
        for p in &positions {
            a += &format!("{} {} {}\n", p.x, p.y, p.z);
        }
        for f in &faces {
            a += &format!(
                "{} {}\n",
                f.len(),
                f.iter().map(u32::to_string).collect::<Vec<_>>().join(" ")
            );
        }
        for (name, bytes) in [("star.obj", o.into_bytes()), ("star.ply", a.into_bytes())] {
            let m = read_ok(name, &bytes);
            check_cap(name, &m, &rot, 0.0, -1.0);
            check_cap(name, &m, &rot, 0.5, 1.0);
            // Closed and facing out: the prism's volume.
            let volume = 0.5 * shoelace(&star());
            assert!(
                (m.signed_volume() - volume).abs() < 1e-5 * volume,
                "{name}: volume {} vs {volume}",
                m.signed_volume()
            );
        }
    }
}

// ---------------------------------------------------------------------------
// glTF strips and fans

/// The unit cube's corners, corner k at (k & 1, k >> 1 & 1, k >> 2 & 1).
fn cube_corners() -> Vec<Point3> {
    (0..8)
        .map(|k| Point3::new((k & 1) as Real, (k >> 1 & 1) as Real, (k >> 2 & 1) as Real))
        .collect()
}

/// The cube's faces, counter-clockwise seen from outside.
const CUBE_FACES: [[u32; 4]; 6] = [
    [0, 2, 3, 1],
    [4, 5, 7, 6],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 4, 6, 2],
    [1, 3, 7, 5],
];

/// The mesh is the closed unit cube, every triangle facing out.
fn assert_unit_cube(name: &str, m: &TriangleMesh) {
    assert_eq!(m.triangles.len(), 12, "{name}");
    let center = Point3::new(0.5, 0.5, 0.5);
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        let out = (b - a)
            .cross(&(c - a))
            .dot(&(Point3::from((a.coords + b.coords + c.coords) / 3.0) - center));
        assert!(out > 0.0, "{name}: triangle {a} {b} {c} faces in");
    }
    assert!(
        (m.signed_volume() - 1.0).abs() < 1e-9,
        "{name}: volume {}",
        m.signed_volume()
    );
}

#[test]
fn gltf_triangle_strips_and_fans() {
    const STRIP: u32 = 5;
    const FAN: u32 = 6;
    let corners = cube_corners();
    // One strip through all six faces (each p0 p1 p3 p2), joined by
    // repeating the last index of a face and the first of the next: the
    // triangles between faces are degenerate and must be left out.
    let mut strip = Vec::new();
    for (k, [p0, p1, p2, p3]) in CUBE_FACES.iter().enumerate() {
        if k > 0 {
            strip.extend([*strip.last().unwrap(), *p0]);
        }
        strip.extend([p0, p1, p3, p2]);
    }
    assert_unit_cube(
        "strip.gltf",
        &read_ok(
            "strip.gltf",
            gltf_doc(&corners, &[(STRIP, &strip)]).as_bytes(),
        ),
    );
    // A strip per face: its second triangle is the one wound the other way.
    let per_face: Vec<Vec<u32>> = CUBE_FACES
        .iter()
        .map(|[p0, p1, p2, p3]| vec![*p0, *p1, *p3, *p2])
        .collect();
    let prims: Vec<(u32, &[u32])> = per_face.iter().map(|s| (STRIP, s.as_slice())).collect();
    assert_unit_cube(
        "strips.gltf",
        &read_ok("strips.gltf", gltf_doc(&corners, &prims).as_bytes()),
    );
    // A fan per face, from its first corner.
    let prims: Vec<(u32, &[u32])> = CUBE_FACES.iter().map(|f| (FAN, f.as_slice())).collect();
    assert_unit_cube(
        "fans.gltf",
        &read_ok("fans.gltf", gltf_doc(&corners, &prims).as_bytes()),
    );
    // Points and lines next to triangles are skipped; alone, they are an error.
    let all: Vec<u32> = (0..8).collect();
    let with_points = gltf_doc(&corners, &[(0, &all), (STRIP, &strip), (1, &all)]);
    assert_unit_cube("mixed.gltf", &read_ok("mixed.gltf", with_points.as_bytes()));
    for mode in [0, 1, 2, 3] {
        read_err(
            "lines.gltf",
            gltf_doc(&corners, &[(mode, &all)]).as_bytes(),
            &["lines.gltf", "points or lines"],
        );
    }
}

// ---------------------------------------------------------------------------
// A frame out of place

/// `m` moved by `by`.
fn moved(mut m: TriangleMesh, by: Vector3) -> TriangleMesh {
    m.positions.iter_mut().for_each(|p| *p += by);
    m
}

/// Bar frames `0..n` as `seq/frame_<f>.obj`, frame f moved by `offset(f)`.
fn bar_sequence(dir: &Scratch, n: usize, offset: impl Fn(usize) -> Vector3) {
    let _ = std::fs::remove_dir_all(dir.join("seq"));
    for f in 0..n {
        write_files(
            dir,
            &[(
                &format!("seq/frame_{f}.obj"),
                &obj(&moved(fixtures::bending_bar(f), offset(f))),
            )],
        );
    }
}

fn track(dir: &Scratch) -> Output {
    let mut args = vec!["track", "seq"];
    args.extend(SMALL);
    args.extend(["-o", "c.exr"]);
    run(dir, &args)
}

#[test]
fn a_frame_out_of_place_is_named() {
    let dir = Scratch::new("formats", "placement");
    let far = Vector3::new(1000.0, 0.0, 0.0);
    for (odd, offset) in [
        (vec![5], far),
        (vec![0], -far),
        (vec![5, 6], Vector3::new(0.0, 600.0, 800.0)),
    ] {
        bar_sequence(&dir, 8, |f| {
            if odd.contains(&f) {
                offset
            } else {
                Vector3::zeros()
            }
        });
        let o = track(&dir);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        let named = format!("seq/frame_{}.obj", odd[0]);
        assert!(
            stderr.contains(&named) && stderr.contains("out of place"),
            "{odd:?}: {stderr}"
        );
        // Only the odd frame is named.
        let others = (0..8)
            .filter(|f| *f != odd[0])
            .map(|f| format!("frame_{f}.obj"))
            .find(|f| stderr.contains(f.as_str()));
        assert_eq!(others, None, "{stderr}");
        assert!(!dir.join("c.exr").exists());
    }
    // A subject that travels far, a little each frame, is in place throughout.
    bar_sequence(&dir, 8, |f| Vector3::new(0.0, 0.0, 2.0 * f as Real));
    let o = track(&dir);
    assert!(o.status.success(), "{}", text(&o.stderr));
}
