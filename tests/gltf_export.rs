//! The dynamic-mesh exports read back: GLB with the gltf crate (every frame
//! rebuilt from base + weighted targets), PC2 and the OBJ sequence.

use std::path::PathBuf;
use voltrack::deform::DynamicMesh;
use voltrack::export::gltf::{write_dynamic_glb, BasisChoice, GltfExportOptions};
use voltrack::fixtures;
use voltrack::math::{Point3, Real, Vector3};
use voltrack::mesh::Aabb;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("voltrack-export-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The bending bar's frame-0 mesh carried through its true motion.
fn bending_bar() -> DynamicMesh {
    let base = fixtures::bending_bar(0);
    let frames = (0..fixtures::BENDING_BAR_FRAMES).map(|f| base.positions.iter().map(|p| fixtures::bending_bar_motion(f, p)).collect()).collect();
    DynamicMesh { base, frames }
}

/// A torus turning about z by `frames` small steps: a low-rank motion.
fn turning_torus(frames: usize) -> DynamicMesh {
    let base = fixtures::torus(Point3::origin(), 1.0, 0.3, 24, 12);
    let frames = (0..frames)
        .map(|f| {
            let r = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 0.3 * (f as Real * 0.05).sin());
            base.positions.iter().map(|p| r * p + Vector3::new(0.0, 0.0, 0.01 * f as Real)).collect()
        })
        .collect();
    DynamicMesh { base, frames }
}

/// Reads a GLB back: per-frame positions rebuilt from the base mesh, the
/// targets and the animated weights; the sampler's interpolation; the number
/// of target names; and POSITION min/max.
fn read_back(path: &std::path::Path) -> (Vec<Vec<[f32; 3]>>, gltf::animation::Interpolation, usize, (Vec<f32>, Vec<f32>)) {
    let bytes = std::fs::read(path).unwrap();
    let glb = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = glb.blob.as_deref().unwrap();
    let mesh = glb.meshes().next().unwrap();
    let names = mesh.extras().as_ref().map_or(0, |e| {
        let v: serde_json::Value = serde_json::from_str(e.get()).unwrap();
        v["targetNames"].as_array().map_or(0, Vec::len)
    });
    let primitive = mesh.primitives().next().unwrap();
    let accessor = primitive.get(&gltf::Semantic::Positions).unwrap();
    let min: Vec<f32> = serde_json::from_value(accessor.min().unwrap()).unwrap();
    let max: Vec<f32> = serde_json::from_value(accessor.max().unwrap()).unwrap();
    let reader = primitive.reader(|_| Some(blob));
    let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let targets: Vec<Vec<[f32; 3]>> = reader.read_morph_targets().map(|(p, _, _)| p.unwrap().collect()).collect();
    let animation = glb.animations().next().unwrap();
    let channel = animation.channels().next().unwrap();
    let interpolation = channel.sampler().interpolation();
    let reader = channel.reader(|_| Some(blob));
    let times: Vec<f32> = match reader.read_inputs().unwrap() {
        gltf::accessor::Iter::Standard(it) => it.collect(),
        gltf::accessor::Iter::Sparse(it) => it.collect(),
    };
    let weights: Vec<f32> = match reader.read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("not a weights channel"),
    };
    assert_eq!(weights.len(), times.len() * targets.len());
    let frames = weights
        .chunks(targets.len())
        .map(|w| {
            (0..base.len())
                .map(|v| {
                    let mut p = base[v];
                    for (t, &wt) in targets.iter().zip(w) {
                        for k in 0..3 {
                            p[k] += wt * t[v][k];
                        }
                    }
                    p
                })
                .collect()
        })
        .collect();
    (frames, interpolation, names, (min, max))
}

fn largest_error(mesh: &DynamicMesh, frames: &[Vec<[f32; 3]>]) -> Real {
    assert_eq!(frames.len(), mesh.frames.len());
    let mut worst: Real = 0.0;
    for (a, b) in mesh.frames.iter().zip(frames) {
        for (p, q) in a.iter().zip(b) {
            worst = worst.max((p - Point3::new(q[0] as Real, q[1] as Real, q[2] as Real)).norm());
        }
    }
    worst
}

#[test]
fn per_frame_glb_replays_every_frame() {
    let dir = scratch("per-frame");
    let mesh = bending_bar();
    let path = dir.join("bar.glb");
    let report = write_dynamic_glb(&path, &mesh, &GltfExportOptions { basis: BasisChoice::PerFrame, ..Default::default() }).unwrap();
    assert_eq!(report.targets, mesh.frames.len() - 1);
    let (frames, interpolation, names, (min, max)) = read_back(&path);
    assert_eq!(interpolation, gltf::animation::Interpolation::Step);
    assert_eq!(names, report.targets);
    let diagonal = Aabb::from_points(mesh.frames.iter().flatten()).diagonal();
    assert!(largest_error(&mesh, &frames) < 1e-5 * diagonal);
    // min/max are exactly those of the stored (f32) base positions.
    for k in 0..3 {
        let stored: Vec<f32> = mesh.frames[0].iter().map(|p| p[k] as f32).collect();
        assert_eq!(min[k], stored.iter().copied().fold(f32::INFINITY, f32::min));
        assert_eq!(max[k], stored.iter().copied().fold(f32::NEG_INFINITY, f32::max));
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn compact_basis_reports_its_own_error() {
    let dir = scratch("basis");
    let mesh = turning_torus(40);
    let path = dir.join("torus.glb");
    let report = write_dynamic_glb(&path, &mesh, &GltfExportOptions { basis: BasisChoice::Components(3), ..Default::default() }).unwrap();
    assert_eq!(report.basis, Some(3));
    let (frames, interpolation, names, _) = read_back(&path);
    assert_eq!(interpolation, gltf::animation::Interpolation::Linear);
    assert_eq!(names, report.targets);
    let diagonal = Aabb::from_points(mesh.frames.iter().flatten()).diagonal();
    let measured = largest_error(&mesh, &frames) / diagonal;
    assert!((measured - report.reconstruction_error_max).abs() < 1e-5, "{measured} vs {}", report.reconstruction_error_max);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn long_sequences_switch_to_a_compact_basis() {
    let dir = scratch("auto");
    let mesh = turning_torus(300);
    let path = dir.join("long.glb");
    let report = write_dynamic_glb(&path, &mesh, &GltfExportOptions::default()).unwrap();
    let k = report.basis.expect("past 256 frames Auto picks a basis");
    assert!(report.targets < 20, "{k} components, {} targets", report.targets);
    assert!(report.reconstruction_error_max <= GltfExportOptions::default().max_basis_error);
    let (frames, _, _, _) = read_back(&path);
    let diagonal = Aabb::from_points(mesh.frames.iter().flatten()).diagonal();
    assert!(largest_error(&mesh, &frames) <= (report.reconstruction_error_max + 1e-5) * diagonal);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn point_cache_and_obj_sequence() {
    let dir = scratch("pc2");
    let mesh = bending_bar();
    let pc2 = dir.join("bar.pc2");
    voltrack::export::pc2::write_pc2(&pc2, &mesh, 30.0).unwrap();
    let bytes = std::fs::read(&pc2).unwrap();
    assert_eq!(&bytes[..12], b"POINTCACHE2\0");
    let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let points = int(16) as usize;
    assert_eq!(int(12), 1);
    assert_eq!(int(28) as usize, mesh.frames.len());
    assert_eq!(bytes.len(), 32 + 12 * points * mesh.frames.len());
    let obj = voltrack::io::read_mesh(&dir.join("bar.obj")).unwrap();
    assert_eq!(obj.positions.len(), points);
    // The last sample of the last point is the last frame's last used vertex.
    let f = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let last = mesh.frames.last().unwrap()[mesh.base.triangles.iter().flatten().copied().max().unwrap() as usize];
    assert_eq!(f(bytes.len() - 12), last.x as f32);

    let seq = dir.join("seq");
    let paths = voltrack::export::obj::write_obj_sequence(&seq, &mesh).unwrap();
    assert_eq!(paths.len(), mesh.frames.len());
    let faces = |p: &PathBuf| std::fs::read_to_string(p).unwrap().lines().filter(|l| l.starts_with("f ")).map(String::from).collect::<Vec<_>>();
    let first = faces(&paths[0]);
    assert_eq!(first.len(), mesh.base.triangles.len());
    assert!(paths.iter().all(|p| faces(p) == first));
    // The `v` lines, in the mesh's vertex order (a reader may reorder them).
    for (path, frame) in paths.iter().zip(&mesh.frames) {
        let text = std::fs::read_to_string(path).unwrap();
        let v: Vec<Point3> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let c: Vec<Real> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                Point3::new(c[0], c[1], c[2])
            })
            .collect();
        assert_eq!(v.len(), frame.len());
        assert!(v.iter().zip(frame).all(|(p, q)| (p - q).norm() < 1e-5));
    }
    std::fs::remove_dir_all(dir).unwrap();
}
