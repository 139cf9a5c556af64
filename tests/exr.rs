//! OpenEXR output of trajectories and vertex-animation textures, read back
//! with voltrack's own reader: exact positions, metadata (non-ASCII, JSON),
//! byte-identical output across runs and thread counts, errors that name the
//! file, and no temporary file left behind.

use std::path::Path;
use voltrack::export::exr::write_trajectories_exr;
use voltrack::export::vat::{write_vat, VatOptions};
use voltrack::io::exr::read_trajectories_exr;
use voltrack::math::{Point3, Real};
use voltrack::model::DynamicMesh;
use voltrack::model::Trajectories;
use voltrack::model::TrajectoryMetadata;

mod common;
use common::Scratch;

/// Every file under `dir`, recursively, relative names.
fn files_under(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(
                files_under(&p)
                    .into_iter()
                    .map(|n| format!("{}/{n}", e.file_name().to_string_lossy())),
            );
        } else {
            out.push(e.file_name().to_string_lossy().into_owned());
        }
    }
    out.sort();
    out
}

/// Fixed-seed positions with awkward values: negative zero, tiny, huge,
/// values that are not representable in f32.
fn trajectories(frames: usize, centers: usize) -> Trajectories {
    let mut state = 0x1234_5678_9abc_def0_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as Real / (1u64 << 53) as Real
    };
    let mut t = Trajectories::new(frames, centers);
    for f in 0..frames {
        for i in 0..centers {
            t.set(
                f,
                i,
                Point3::new(
                    next() * 10.0 - 5.0,
                    0.1 * f as Real + 1e-3 * i as Real,
                    -1.0 / (1.0 + next()),
                ),
            );
        }
    }
    t.set(0, 0, Point3::new(-0.0, 1e-40, 3.0e30));
    t.set(
        frames - 1,
        centers - 1,
        Point3::new(1.0 / 3.0, -123456.789, Real::MIN_POSITIVE),
    );
    t
}

/// The frames of `t` as an animated mesh (a triangle per three points), for
/// the vertex-animation texture.
fn animated(t: &Trajectories) -> DynamicMesh {
    let frames: Vec<Vec<Point3>> = (0..t.frames).map(|f| t.frame(f).to_vec()).collect();
    let triangles = (0..t.centers as u32 / 3)
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    DynamicMesh {
        base: voltrack::TriangleMesh {
            positions: frames[0].clone(),
            triangles,
            ..Default::default()
        },
        frames: frames.into(),
        reference: 0,
    }
}

fn write_vat_exr(path: &Path, mesh: &DynamicMesh) -> voltrack::Result<()> {
    write_vat(path, mesh, &VatOptions::default()).map(drop)
}

fn metadata() -> TrajectoryMetadata {
    TrajectoryMetadata {
        resolution: Some(256),
        voxel_size: Some(0.0071234567890123),
        first_input: Some("/données/Tänzer ü/φrame_0 😀.obj".into()),
        track: Some(
            serde_json::json!({"centers":13,"rho_p":0.07,"affinity":"max","nested":{"list":[1,2,3],"name":"ß"}}),
        ),
        removed: Some(vec![4, 9, 17]),
        other: [(
            "voltrack.note".to_string(),
            serde_json::json!("quotes \" and back\\slash\nand a second line"),
        )]
        .into(),
        ..Default::default()
    }
}

#[test]
fn trajectories_round_trip_exactly_after_f32_rounding() {
    let dir = Scratch::new("exr", "roundtrip");
    for (frames, centers) in [(1, 1), (7, 13), (40, 3), (2, 600)] {
        let path = dir.join(&format!("c_{frames}_{centers}.exr"));
        let t = trajectories(frames, centers);
        write_trajectories_exr(&path, &t, &metadata()).unwrap();
        let (back, meta) = read_trajectories_exr(&path).unwrap();
        assert_eq!(
            (back.frames, back.centers, back.positions.len()),
            (frames, centers, frames * centers)
        );
        for f in 0..frames {
            for i in 0..centers {
                let (a, b) = (t.get(f, i), back.get(f, i));
                for k in 0..3 {
                    assert_eq!(
                        b[k].to_bits(),
                        (a[k] as f32 as Real).to_bits(),
                        "frame {f}, center {i}, axis {k}: {} vs {}",
                        b[k],
                        a[k]
                    );
                }
            }
        }
        assert_eq!(meta.resolution, Some(256));
        assert_eq!(meta.version.as_deref(), Some(env!("CARGO_PKG_VERSION")));
    }
}

#[test]
fn metadata_round_trips() {
    let dir = Scratch::new("exr", "attributes");
    let path = dir.join("c.exr");
    write_trajectories_exr(&path, &trajectories(3, 4), &metadata()).unwrap();
    // Into a writer of the caller's: the same bytes as the file.
    let mut bytes = std::io::Cursor::new(Vec::new());
    voltrack::export::exr::write_trajectories_exr_to(
        &mut bytes,
        "c.exr",
        &trajectories(3, 4),
        &metadata(),
    )
    .unwrap();
    assert_eq!(bytes.get_ref(), &std::fs::read(&path).unwrap());
    let (_, meta) = read_trajectories_exr(&path).unwrap();
    // Every field comes back as written, non-ASCII text (Latin-1 and beyond,
    // including outside the BMP) through EXR's Latin-1 text attributes, the
    // voxel size to the last digit, unknown keys kept; plus the version.
    assert_eq!(
        meta,
        TrajectoryMetadata {
            version: Some(env!("CARGO_PKG_VERSION").into()),
            ..metadata()
        }
    );
    // No metadata at all is fine too.
    let bare = dir.join("bare.exr");
    write_trajectories_exr(&bare, &trajectories(2, 2), &Default::default()).unwrap();
    let (_, meta) = read_trajectories_exr(&bare).unwrap();
    assert_eq!(
        meta,
        TrajectoryMetadata {
            version: Some(env!("CARGO_PKG_VERSION").into()),
            ..Default::default()
        }
    );
}

/// The attribute's text is what the first versions wrote (numbers as text,
/// parameters and lists as JSON), so files stay readable both ways.
#[test]
fn metadata_keeps_its_format_on_disk() {
    let text = serde_json::to_string(&metadata()).unwrap();
    assert!(text.contains(r#""voltrack.resolution":"256""#), "{text}");
    assert!(
        text.contains(r#""voltrack.voxel_size":"7.1234567890123e-3""#),
        "{text}"
    );
    assert!(text.contains(r#""voltrack.removed":[4,9,17]"#), "{text}");
    let old = r#"{"version":"0.1.0","voltrack.frames":"8","voltrack.grid":{"dims":[5,6,7],"origin":[0.5,1.0,-2.0],"voxel_size":0.25},"voltrack.resolution":"64","voltrack.track":{"absolute_units":true},"voltrack.voxel_size":"2.5e-1"}"#;
    let meta: TrajectoryMetadata = serde_json::from_str(old).unwrap();
    assert_eq!(
        (meta.frames, meta.resolution, meta.voxel_size),
        (Some(8), Some(64), Some(0.25))
    );
    assert_eq!(meta.grid.unwrap().dims, [5, 6, 7]);
    assert!(meta.absolute_units());
    assert!(
        serde_json::from_str::<TrajectoryMetadata>(r#"{"voltrack.resolution":"many"}"#).is_err()
    );
}

#[test]
fn output_is_byte_identical_across_runs_and_thread_counts() {
    let dir = Scratch::new("exr", "determinism");
    let t = trajectories(33, 257);
    let frames = animated(&t);
    let write = |name: &str, threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        // One folder per run: the VAT's sidecar and mesh name its files.
        std::fs::create_dir(dir.join(name)).unwrap();
        let exr = dir.join(&format!("{name}/c.exr"));
        let vat = dir.join(&format!("{name}/vat.exr"));
        pool.install(|| {
            write_trajectories_exr(&exr, &t, &metadata()).unwrap();
            write_vat_exr(&vat, &frames).unwrap();
        });
        let json = std::fs::read(vat.with_extension("json")).unwrap();
        let mesh = std::fs::read(vat.with_extension("glb")).unwrap();
        (
            std::fs::read(exr).unwrap(),
            std::fs::read(vat).unwrap(),
            json,
            mesh,
        )
    };
    let first = write("a", 1);
    // assert!, not assert_eq!: the bytes are too many to print.
    assert!(first == write("b", 1), "two runs differ");
    assert!(first == write("c", 4), "1 and 4 threads differ");
    assert!(first == write("d", 2), "1 and 2 threads differ");
}

#[test]
fn unreadable_files_give_errors_that_name_them() {
    let dir = Scratch::new("exr", "errors");
    let missing = dir.join("missing centers.exr");
    let err = read_trajectories_exr(&missing).unwrap_err().to_string();
    assert!(err.contains("missing centers.exr"), "{err}");

    let cases: [(&str, Vec<u8>); 4] = [
        ("text.exr", b"v 1 2 3\nf 1 2 3\n".to_vec()),
        ("empty.exr", Vec::new()),
        ("magic_only.exr", vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0]),
        ("truncated.exr", {
            let good = dir.join("good.exr");
            write_trajectories_exr(&good, &trajectories(9, 40), &metadata()).unwrap();
            let bytes = std::fs::read(&good).unwrap();
            bytes[..bytes.len() / 2].to_vec()
        }),
    ];
    for (name, bytes) in cases {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = read_trajectories_exr(&path).unwrap_err().to_string();
        assert!(err.contains(name), "{name}: {err}");
    }
    // A directory is not a file either.
    let err = read_trajectories_exr(&dir.0).unwrap_err().to_string();
    assert!(err.contains(&*dir.0.to_string_lossy()), "{err}");
}

/// The numbers of the array `key` in a JSON text, parsed exactly.
fn json_numbers(json: &str, key: &str) -> Vec<Real> {
    let at = json
        .find(&format!("\"{key}\""))
        .unwrap_or_else(|| panic!("no {key} in {json}"));
    let open = at + json[at..].find('[').unwrap();
    let close = open + json[open..].find(']').unwrap();
    json[open + 1..close]
        .split(',')
        .map(|x| x.trim().parse().unwrap())
        .collect()
}

#[test]
fn vertex_animation_texture_with_json_sidecar() {
    let dir = Scratch::new("exr", "vat");
    let path = dir.join("anim.exr");
    let t = trajectories(6, 50);
    let mesh = animated(&t);
    write_vat_exr(&path, &mesh).unwrap();
    assert_eq!(
        files_under(&dir.0),
        vec!["anim.exr", "anim.glb", "anim.json"]
    );

    let (back, meta) = read_trajectories_exr(&path).unwrap();
    assert_eq!((back.frames, back.centers), (6, 50));
    for (a, b) in t.positions.iter().zip(&back.positions) {
        assert!((0..3).all(|k| b[k] == a[k] as f32 as Real));
    }
    let sidecar = std::fs::read_to_string(dir.join("anim.json")).unwrap();
    let info: serde_json::Value = serde_json::from_str(&sidecar).unwrap();
    assert_eq!(info["frames"], 6);
    assert_eq!(info["vertices"], 50);
    // The bounds, exactly: parsed from the text with Rust's correctly rounded
    // parser (serde_json's default one may be off by an ulp, e.g. on 3e30).
    let (min, max) = (
        json_numbers(&sidecar, "bounds_min"),
        json_numbers(&sidecar, "bounds_max"),
    );
    for k in 0..3 {
        let lo = t
            .positions
            .iter()
            .map(|p| p[k])
            .fold(Real::INFINITY, Real::min);
        let hi = t
            .positions
            .iter()
            .map(|p| p[k])
            .fold(Real::NEG_INFINITY, Real::max);
        assert_eq!(min[k], lo, "axis {k}");
        assert_eq!(max[k], hi, "axis {k}");
    }
    // The same description is in the EXR header.
    let vat = meta.other["vat"].clone();
    assert_eq!(vat, info);

    // Frames of different lengths, no vertices, or a name that would collide
    // with the sidecar or the mesh: errors, nothing written.
    let mut frames = mesh.frames.to_vec().unwrap();
    frames[1].pop();
    let ragged = DynamicMesh {
        base: mesh.base.clone(),
        frames: frames.into(),
        reference: 0,
    };
    assert!(write_vat_exr(&dir.join("ragged.exr"), &ragged).is_err());
    let empty = DynamicMesh {
        base: Default::default(),
        frames: vec![vec![], vec![]].into(),
        reference: 0,
    };
    assert!(write_vat_exr(&dir.join("none.exr"), &empty).is_err());
    assert!(write_vat_exr(
        &dir.join("none.exr"),
        &DynamicMesh {
            frames: Vec::new().into(),
            base: mesh.base.clone(),
            reference: 0
        }
    )
    .is_err());
    assert!(write_vat_exr(&dir.join("clash.json"), &mesh).is_err());
    assert!(write_vat_exr(&dir.join("clash.glb"), &mesh).is_err());
    assert_eq!(
        files_under(&dir.0),
        vec!["anim.exr", "anim.glb", "anim.json"]
    );
}

#[test]
fn failed_writes_leave_nothing_behind() {
    let dir = Scratch::new("exr", "failed");
    let t = trajectories(4, 5);
    let frames = animated(&t);
    // Into a directory that does not exist.
    let nowhere = dir.join("no/such/dir/c.exr");
    let err = write_trajectories_exr(&nowhere, &t, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("c.exr"), "{err}");
    assert!(write_vat_exr(&dir.join("missing/anim.exr"), &frames).is_err());
    // Onto an existing directory: the temporary file is written, the rename fails.
    let occupied = dir.join("occupied.exr");
    std::fs::create_dir_all(occupied.join("inside")).unwrap();
    assert!(write_trajectories_exr(&occupied, &t, &Default::default()).is_err());
    // Nothing to write: 0 centers or 0 frames.
    assert!(write_trajectories_exr(
        &dir.join("empty.exr"),
        &Trajectories::new(3, 0),
        &Default::default()
    )
    .is_err());
    assert!(write_trajectories_exr(
        &dir.join("empty.exr"),
        &Trajectories::new(0, 3),
        &Default::default()
    )
    .is_err());
    // Below the parent of `nowhere`: a file where a directory should be.
    std::fs::write(dir.join("plain"), b"x").unwrap();
    assert!(write_trajectories_exr(&dir.join("plain/c.exr"), &t, &Default::default()).is_err());
    let left = files_under(&dir.0);
    assert!(left.iter().all(|n| !n.contains(".partial")), "{left:?}");
    // (The empty directory `occupied.exr/inside` holds no file.)
    assert_eq!(left, vec!["plain".to_string()]);
    // An existing file is replaced whole by a successful write.
    let target = dir.join("replace.exr");
    std::fs::write(&target, vec![0u8; 1 << 16]).unwrap();
    write_trajectories_exr(&target, &t, &Default::default()).unwrap();
    assert_eq!(read_trajectories_exr(&target).unwrap().0.frames, 4);
}

#[test]
fn numbers_round_trip_to_the_last_digit() {
    let dir = Scratch::new("exr", "numeric");
    let path = dir.join("c.exr");
    for voxel_size in [3e30, 1e3, 5.6e-5, 0.1 + 0.2, f64::MIN_POSITIVE] {
        let meta = TrajectoryMetadata {
            voxel_size: Some(voxel_size),
            resolution: Some(1596),
            frames: Some(9000),
            ..Default::default()
        };
        write_trajectories_exr(&path, &trajectories(2, 3), &meta).unwrap();
        let (_, back) = read_trajectories_exr(&path).unwrap();
        assert_eq!(
            back.voxel_size.map(f64::to_bits),
            Some(voxel_size.to_bits())
        );
        assert_eq!((back.resolution, back.frames), (Some(1596), Some(9000)));
    }
}
