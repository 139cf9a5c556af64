//! Center trajectories and vertex-animation textures as OpenEXR: round trip,
//! metadata, determinism, errors.

use std::path::PathBuf;
use voltrack::export::exr::{write_trajectories_exr, write_vat_exr};
use voltrack::io::exr::read_trajectories_exr;
use voltrack::math::{Point3, Real};
use voltrack::track::Trajectories;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("voltrack-exr-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn trajectories() -> Trajectories {
    Trajectories::from_frames(
        (0..7)
            .map(|f| (0..13).map(|i| Point3::new(i as Real * 0.1 + f as Real, (f * i) as Real * 1e-3, -1.0 / (1.0 + i as Real))).collect())
            .collect(),
    )
}

fn attrs() -> Vec<(String, String)> {
    vec![
        ("voltrack.resolution".into(), "256".into()),
        ("voltrack.first_input".into(), "données/tänzer_0.obj".into()),
        ("voltrack.track".into(), r#"{"centers":13,"rho_p":0.07}"#.into()),
    ]
}

#[test]
fn trajectories_round_trip_with_metadata() {
    let dir = scratch("roundtrip");
    let path = dir.join("c.exr");
    let t = trajectories();
    write_trajectories_exr(&path, &t, &attrs()).unwrap();
    let (back, meta) = read_trajectories_exr(&path).unwrap();
    assert_eq!((back.frames, back.centers), (t.frames, t.centers));
    for (a, b) in t.positions.iter().zip(&back.positions) {
        for k in 0..3 {
            assert_eq!(b[k], a[k] as f32 as Real);
        }
    }
    let get = |k: &str| meta.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
    assert_eq!(get("voltrack.resolution").as_deref(), Some("256"));
    assert_eq!(get("voltrack.first_input").as_deref(), Some("données/tänzer_0.obj"));
    let track: serde_json::Value = serde_json::from_str(&get("voltrack.track").unwrap()).unwrap();
    assert_eq!(track["centers"], 13);
    assert_eq!(get("version").as_deref(), Some(env!("CARGO_PKG_VERSION")));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn bytes_do_not_depend_on_runs_or_threads() {
    let dir = scratch("determinism");
    let t = trajectories();
    let write = |name: &str, threads: usize| {
        let path = dir.join(name);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| write_trajectories_exr(&path, &t, &attrs())).unwrap();
        std::fs::read(path).unwrap()
    };
    let one = write("a.exr", 1);
    assert_eq!(one, write("b.exr", 1));
    assert_eq!(one, write("c.exr", 4));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn unreadable_files_are_named() {
    let dir = scratch("errors");
    let missing = dir.join("missing.exr");
    let err = read_trajectories_exr(&missing).unwrap_err().to_string();
    assert!(err.contains("missing.exr"), "{err}");
    let garbage = dir.join("garbage.exr");
    std::fs::write(&garbage, b"v 1 2 3\n").unwrap();
    let err = read_trajectories_exr(&garbage).unwrap_err().to_string();
    assert!(err.contains("garbage.exr"), "{err}");
    // A write into a directory that does not exist fails and leaves nothing.
    let bad = dir.join("no/such/dir/c.exr");
    assert!(write_trajectories_exr(&bad, &trajectories(), &[]).is_err());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn vertex_animation_texture_with_sidecar() {
    let dir = scratch("vat");
    let path = dir.join("anim.exr");
    let t = trajectories();
    let frames: Vec<Vec<Point3>> = (0..t.frames).map(|f| t.frame(f).to_vec()).collect();
    write_vat_exr(&path, &frames).unwrap();
    let (back, _) = read_trajectories_exr(&path).unwrap();
    assert_eq!((back.frames, back.centers), (7, 13));
    let info: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("anim.json")).unwrap()).unwrap();
    assert_eq!(info["frames"], 7);
    assert_eq!(info["vertices"], 13);
    let min = info["bounds_min"].as_array().unwrap();
    assert_eq!(min[0].as_f64().unwrap(), 0.0);
    assert_eq!(info["bounds_max"][0].as_f64().unwrap(), 1.2 + 6.0);
    std::fs::remove_dir_all(dir).unwrap();
}
