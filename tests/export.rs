//! The dynamic-mesh exports read back independently: GLB with the gltf crate
//! (every frame rebuilt from base + Σ weight · target), PC2 byte by byte with
//! the OBJ beside it, and the OBJ sequence line by line.

use gltf::animation::Interpolation;
use std::path::{Path, PathBuf};
use voltrack::export::gltf::{write_dynamic_glb, BasisChoice, GltfExportOptions, GltfExportReport};
use voltrack::export::vat::{write_vat, VatOptions};
use voltrack::fixtures;
use voltrack::math::{Point3, Real, Rotation3, Vector3};
use voltrack::model::DynamicMesh;
use voltrack::model::PositionFrames;
use voltrack::Progress;

mod common;
use common::{Scratch, StopAfterPolls as StopAfter};

/// The bundled example's frame-0 mesh carried through its true motion.
fn bending_bar() -> DynamicMesh {
    let base = fixtures::bending_bar(0);
    let frames: Vec<Vec<Point3>> = (0..fixtures::BENDING_BAR_FRAMES)
        .map(|f| {
            base.positions
                .iter()
                .map(|p| fixtures::bending_bar_motion(f, p))
                .collect()
        })
        .collect();
    DynamicMesh {
        base,
        frames: frames.into(),
        reference: 0,
    }
}

/// A torus with UVs moved per frame by `motion(f, p)`.
fn torus(frames: usize, motion: impl Fn(usize, &Point3) -> Point3) -> DynamicMesh {
    let mut base = fixtures::torus(Point3::origin(), 1.0, 0.3, 24, 12);
    base.uvs = Some(
        (0..base.positions.len())
            .map(|v| [(v / 12) as f32 / 24.0, (v % 12) as f32 / 12.0])
            .collect(),
    );
    let frames: Vec<Vec<Point3>> = (0..frames)
        .map(|f| base.positions.iter().map(|p| motion(f, p)).collect())
        .collect();
    DynamicMesh {
        base,
        frames: frames.into(),
        reference: 0,
    }
}

/// Rigid rotation about z plus a lift along z: displacements of rank 3
/// ((cos θ − 1)(x, y, 0), sin θ (−y, x, 0), (0, 0, h)).
fn turning(f: usize, p: &Point3) -> Point3 {
    let angle = 0.8 * (f as Real * 0.05).sin() + 0.002 * f as Real;
    Rotation3::from_axis_angle(&Vector3::z_axis(), angle) * p
        + Vector3::new(0.0, 0.0, 0.003 * f as Real)
}

/// A non-rigid, non-low-rank wobble: each vertex moves on its own.
fn wobble(f: usize, p: &Point3) -> Point3 {
    let t = f as Real;
    p + Vector3::new(
        (1.3 * t + 7.0 * p.x).sin(),
        (0.7 * t + 5.0 * p.y * p.z).cos() - 1.0,
        (0.31 * t * p.x + p.y).sin(),
    ) * 0.05
}

fn diagonal(mesh: &DynamicMesh) -> Real {
    mesh.frames.bounds().unwrap().diagonal()
}

/// What a GLB holds, read with the gltf crate.
struct Glb {
    base: Vec<[f32; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    indices: Vec<u32>,
    /// POSITION (and NORMAL) deltas per target.
    targets: Vec<Vec<[f32; 3]>>,
    normal_targets: Vec<Option<Vec<[f32; 3]>>>,
    /// (min, max) of the base POSITION accessor, then of every target's.
    position_bounds: Vec<(Vec<f32>, Vec<f32>)>,
    target_names: Option<Vec<String>>,
    default_weights: Option<Vec<f32>>,
    /// Keyframe times and one weight vector per keyframe.
    times: Vec<f32>,
    time_bounds: Option<(Vec<f32>, Vec<f32>)>,
    weights: Vec<Vec<f32>>,
    interpolation: Option<Interpolation>,
    animations: usize,
    /// Names of the node, the mesh and the animation.
    node_name: Option<String>,
    mesh_name: Option<String>,
    animation_name: Option<String>,
    /// `extras` of the scene and of the animation.
    scene_extras: Option<serde_json::Value>,
    animation_extras: Option<serde_json::Value>,
}

fn extras_of(e: &gltf::json::Extras) -> Option<serde_json::Value> {
    e.as_ref()
        .map(|raw| serde_json::from_str(raw.get()).unwrap())
}

impl Glb {
    fn read(path: &Path) -> Glb {
        let bytes = std::fs::read(path).unwrap();
        // The GLB header: magic, version 2, total length.
        assert_eq!(&bytes[..4], b"glTF");
        assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), 2);
        assert_eq!(
            u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize,
            bytes.len()
        );
        let doc = gltf::Gltf::from_slice(&bytes).expect("a valid glTF");
        let blob = doc.blob.as_deref().expect("a BIN chunk");
        assert_eq!(doc.meshes().count(), 1);
        let mesh = doc.meshes().next().unwrap();
        assert_eq!(mesh.primitives().count(), 1);
        let primitive = mesh.primitives().next().unwrap();
        assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
        let reader = primitive.reader(|_| Some(blob));
        let bounds = |a: gltf::Accessor| -> (Vec<f32>, Vec<f32>) {
            (
                serde_json::from_value(a.min().expect("POSITION min")).unwrap(),
                serde_json::from_value(a.max().expect("POSITION max")).unwrap(),
            )
        };
        let mut position_bounds = vec![bounds(primitive.get(&gltf::Semantic::Positions).unwrap())];
        position_bounds.extend(
            primitive
                .morph_targets()
                .map(|t| bounds(t.positions().expect("target POSITION"))),
        );
        let (mut targets, mut normal_targets) = (Vec::new(), Vec::new());
        for (p, n, _) in reader.read_morph_targets() {
            targets.push(p.expect("position deltas").collect());
            normal_targets.push(n.map(|n| n.collect()));
        }
        let target_names = mesh.extras().as_ref().map(|e| {
            let v: serde_json::Value = serde_json::from_str(e.get()).unwrap();
            serde_json::from_value(v["targetNames"].clone())
                .expect("targetNames: a list of strings")
        });
        let mut glb = Glb {
            base: reader.read_positions().unwrap().collect(),
            normals: reader.read_normals().map(|n| n.collect()),
            uvs: reader.read_tex_coords(0).map(|t| t.into_f32().collect()),
            indices: reader.read_indices().unwrap().into_u32().collect(),
            targets,
            normal_targets,
            position_bounds,
            target_names,
            default_weights: mesh.weights().map(<[f32]>::to_vec),
            times: Vec::new(),
            time_bounds: None,
            weights: Vec::new(),
            interpolation: None,
            animations: doc.animations().count(),
            node_name: doc.nodes().next().and_then(|n| n.name().map(String::from)),
            mesh_name: mesh.name().map(String::from),
            animation_name: None,
            scene_extras: doc.default_scene().and_then(|s| extras_of(s.extras())),
            animation_extras: None,
        };
        if let Some(animation) = doc.animations().next() {
            glb.animation_name = animation.name().map(String::from);
            glb.animation_extras = extras_of(animation.extras());
            assert_eq!(animation.channels().count(), 1);
            let channel = animation.channels().next().unwrap();
            assert_eq!(
                channel.target().property(),
                gltf::animation::Property::MorphTargetWeights
            );
            assert_eq!(
                channel.target().node().mesh().map(|m| m.index()),
                Some(mesh.index())
            );
            let sampler = channel.sampler();
            glb.interpolation = Some(sampler.interpolation());
            let input = sampler.input();
            glb.time_bounds = Some((
                serde_json::from_value(input.min().unwrap()).unwrap(),
                serde_json::from_value(input.max().unwrap()).unwrap(),
            ));
            let reader = channel.reader(|_| Some(blob));
            glb.times = match reader.read_inputs().unwrap() {
                gltf::accessor::Iter::Standard(it) => it.collect(),
                gltf::accessor::Iter::Sparse(it) => it.collect(),
            };
            let flat: Vec<f32> = match reader.read_outputs().unwrap() {
                gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
                _ => panic!("not a morph-weights channel"),
            };
            assert_eq!(flat.len(), glb.times.len() * glb.targets.len());
            glb.weights = flat
                .chunks(glb.targets.len().max(1))
                .map(<[f32]>::to_vec)
                .collect();
        }
        glb
    }

    /// Positions at keyframe k: base + Σ_t weights[k][t] · target_t, in f64.
    fn frame(&self, k: usize) -> Vec<Point3> {
        (0..self.base.len())
            .map(|v| {
                let mut p = Point3::new(
                    self.base[v][0] as Real,
                    self.base[v][1] as Real,
                    self.base[v][2] as Real,
                );
                for (t, &w) in self.targets.iter().zip(&self.weights[k]) {
                    for a in 0..3 {
                        p[a] += w as Real * t[v][a] as Real;
                    }
                }
                p
            })
            .collect()
    }

    /// Largest and mean vertex distance between the rebuilt frames and `mesh`.
    fn errors(&self, mesh: &DynamicMesh) -> (Real, Real) {
        // One key per frame and the closing one.
        assert_eq!(self.weights.len(), mesh.frames.len() + 1);
        let (mut max, mut sum, mut n): (Real, Real, usize) = (0.0, 0.0, 0);
        for (k, frame) in mesh.frames.to_vec().unwrap().iter().enumerate() {
            for (p, q) in self.frame(k).iter().zip(frame) {
                let d = (p - q).norm();
                max = max.max(d);
                sum += d;
                n += 1;
            }
        }
        (max, sum / n as Real)
    }
}

/// Exact per-component bounds of f32 data, as glTF requires for POSITION.
fn exact_bounds(data: &[[f32; 3]]) -> (Vec<f32>, Vec<f32>) {
    let lo = (0..3)
        .map(|k| data.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min))
        .collect();
    let hi = (0..3)
        .map(|k| data.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max))
        .collect();
    (lo, hi)
}

/// Checks what every animated GLB must satisfy against `mesh` and the report.
fn check_common(glb: &Glb, mesh: &DynamicMesh, report: &GltfExportReport, path: &Path, fps: f32) {
    assert_eq!(report.bytes, std::fs::metadata(path).unwrap().len());
    assert_eq!(glb.targets.len(), report.targets);
    // Base = frame 0 in f32, one connectivity.
    assert_eq!(glb.base.len(), mesh.base.positions.len());
    for (b, p) in glb.base.iter().zip(&mesh.frames.get(0).unwrap()[..]) {
        assert_eq!(*b, [p.x as f32, p.y as f32, p.z as f32]);
    }
    let triangles: Vec<u32> = mesh.base.triangles.iter().flatten().copied().collect();
    assert_eq!(glb.indices, triangles);
    // min/max exact for the base POSITION and every target's.
    assert_eq!(glb.position_bounds.len(), 1 + glb.targets.len());
    assert_eq!(glb.position_bounds[0], exact_bounds(&glb.base));
    for (t, b) in glb.targets.iter().zip(&glb.position_bounds[1..]) {
        assert_eq!(*b, exact_bounds(t));
    }
    if let Some(uv) = &mesh.base.uvs {
        assert_eq!(glb.uvs.as_ref(), Some(uv));
    }
    if report.targets == 0 {
        assert_eq!(glb.animations, 0);
        return;
    }
    // One target name per target, distinct; default weights = frame 0's, all 0.
    let names = glb.target_names.as_ref().expect("mesh.extras.targetNames");
    assert_eq!(names.len(), glb.targets.len());
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "{names:?}");
    assert_eq!(
        glb.default_weights.as_deref(),
        Some(&vec![0.0; report.targets][..])
    );
    // One keyframe per frame at f / fps and a closing one at F / fps that
    // holds the last frame, with the input accessor's bounds.
    let times: Vec<f32> = (0..=mesh.frames.len())
        .map(|f| (f as f64 / fps as f64) as f32)
        .collect();
    assert_eq!(glb.times, times);
    assert_eq!(
        glb.time_bounds,
        Some((vec![times[0]], vec![*times.last().unwrap()]))
    );
    assert_eq!(glb.weights.last(), glb.weights.get(mesh.frames.len() - 1));
    assert!(glb.weights[0].iter().all(|&w| w == 0.0));
    assert!(
        glb.weights
            .iter()
            .flatten()
            .all(|&w| (0.0..=1.0).contains(&w)),
        "weights outside [0, 1]"
    );
}

fn options(basis: BasisChoice) -> GltfExportOptions {
    GltfExportOptions {
        basis,
        ..Default::default()
    }
}

#[test]
fn per_frame_glb_replays_every_frame() {
    let dir = Scratch::new("export", "per-frame");
    let fps = 24.0;
    for (name, mesh) in [("bar", bending_bar()), ("wobble", torus(12, wobble))] {
        let path = dir.join(&format!("{name}.glb"));
        let opts = GltfExportOptions {
            fps,
            ..options(BasisChoice::PerFrame)
        };
        let report = write_dynamic_glb(&path, &mesh, &opts, Progress::none()).unwrap();
        assert_eq!(
            (report.targets, report.basis),
            (mesh.frames.len() - 1, None)
        );
        assert_eq!(
            (
                report.reconstruction_error_max,
                report.reconstruction_error_mean
            ),
            (0.0, 0.0)
        );
        let glb = Glb::read(&path);
        check_common(&glb, &mesh, &report, &path, fps);
        assert_eq!(glb.interpolation, Some(Interpolation::Step));
        let names = glb.target_names.as_ref().unwrap();
        assert_eq!(names[0], "frame_0001");
        assert_eq!(
            names.last().unwrap(),
            &format!("frame_{:04}", mesh.frames.len() - 1)
        );
        // One-hot weights: keyframe f shows target f − 1 only (the closing
        // key shows the last frame's).
        for (f, w) in glb.weights.iter().enumerate() {
            let f = f.min(mesh.frames.len() - 1);
            for (t, &x) in w.iter().enumerate() {
                assert_eq!(x, if t + 1 == f { 1.0 } else { 0.0 });
            }
        }
        let (max, _) = glb.errors(&mesh);
        assert!(max < 1e-5 * diagonal(&mesh), "{name}: {max}");
        // Normals: unit length in every rebuilt frame (they follow the geometry).
        let normals = glb.normals.as_ref().expect("normals by default");
        for f in 0..mesh.frames.len() {
            for (v, n) in normals.iter().enumerate() {
                let mut m = Vector3::new(n[0] as Real, n[1] as Real, n[2] as Real);
                if f > 0 {
                    let d = glb.normal_targets[f - 1].as_ref().expect("NORMAL deltas")[v];
                    m += Vector3::new(d[0] as Real, d[1] as Real, d[2] as Real);
                }
                assert!(
                    (m.norm() - 1.0).abs() < 1e-5,
                    "{name}: frame {f}, vertex {v}: |n| = {}",
                    m.norm()
                );
            }
        }
    }
}

/// Issue 23: a player that loops the clip (three.js' default) wraps at its
/// last key, so the clip must end one frame after the last frame begins.
#[test]
fn the_clip_lasts_every_frame_and_ends_holding_the_last() {
    let dir = Scratch::new("export", "closing-key");
    let fps = 25.0;
    for (name, mesh, basis) in [
        ("per-frame", bending_bar(), BasisChoice::PerFrame),
        ("basis", torus(40, turning), BasisChoice::Components(3)),
        ("auto", torus(300, turning), BasisChoice::Auto),
    ] {
        let path = dir.join(&format!("{name}.glb"));
        let report = write_dynamic_glb(
            &path,
            &mesh,
            &GltfExportOptions {
                fps,
                ..options(basis)
            },
            Progress::none(),
        )
        .unwrap();
        let glb = Glb::read(&path);
        let frames = mesh.frames.len();
        assert_eq!(
            glb.times.len(),
            frames + 1,
            "{name}: one key per frame and a closing one"
        );
        let end = (frames as f64 / fps as f64) as f32;
        assert_eq!(
            *glb.times.last().unwrap(),
            end,
            "{name}: the clip lasts F / fps"
        );
        assert_eq!(glb.time_bounds.as_ref().unwrap().1, vec![end], "{name}");
        // Frame F − 1 is shown from its key to the end, keyed as it is.
        assert_eq!(glb.weights[frames], glb.weights[frames - 1], "{name}");
        let last = glb.frame(frames);
        for (p, q) in last.iter().zip(&mesh.frames.get(frames - 1).unwrap()[..]) {
            assert!(
                (p - q).norm()
                    < 1e-5 * diagonal(&mesh) + report.reconstruction_error_max * diagonal(&mesh),
                "{name}"
            );
        }
        // Every other key is still at f / fps.
        for f in 0..frames {
            assert_eq!(
                glb.times[f],
                (f as f64 / fps as f64) as f32,
                "{name}: key {f}"
            );
        }
    }
}

/// Issue 23: glTF has no frame rate, so it goes where scripts and importers
/// can read it: the scene's and the animation's `extras`.
#[test]
fn glb_records_the_frame_rate_and_count() {
    let dir = Scratch::new("export", "extras");
    for (fps, frames) in [(24.0_f32, 8), (29.97, 12)] {
        let mesh = torus(frames, wobble);
        let path = dir.join("x.glb");
        write_dynamic_glb(
            &path,
            &mesh,
            &GltfExportOptions {
                fps,
                ..options(BasisChoice::PerFrame)
            },
            Progress::none(),
        )
        .unwrap();
        let glb = Glb::read(&path);
        let want = serde_json::json!({"fps": fps, "frames": frames});
        for (what, extras) in [
            ("scene", &glb.scene_extras),
            ("animation", &glb.animation_extras),
        ] {
            let extras = extras
                .as_ref()
                .unwrap_or_else(|| panic!("no {what} extras"));
            assert_eq!(extras["frames"], want["frames"], "{what}: {extras}");
            assert_eq!(
                extras["fps"].as_f64().map(|x| x as f32),
                Some(fps),
                "{what}: {extras}"
            );
        }
        // The rate is written as given, not as its f32 widened (29.969999…).
        let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
        assert!(text.contains(&format!("\"fps\":{fps}")), "{fps}");
    }
    // A single frame has no animation, but the scene still says its rate.
    let mut one = bending_bar();
    one.frames = one.frames.to_vec().unwrap()[..1].to_vec().into();
    let path = dir.join("one.glb");
    write_dynamic_glb(&path, &one, &GltfExportOptions::default(), Progress::none()).unwrap();
    let glb = Glb::read(&path);
    assert_eq!(glb.animations, 0);
    assert_eq!(
        glb.scene_extras,
        Some(serde_json::json!({"fps": 30.0, "frames": 1}))
    );
}

/// Issue 23: two imported results must not both be `voltrack`.
#[test]
fn glb_node_mesh_and_animation_carry_the_name() {
    let dir = Scratch::new("export", "names");
    let mesh = bending_bar();
    let path = dir.join("named.glb");
    let named = GltfExportOptions {
        name: "Dancer take 2".into(),
        ..Default::default()
    };
    write_dynamic_glb(&path, &mesh, &named, Progress::none()).unwrap();
    let glb = Glb::read(&path);
    let name = Some("Dancer take 2".to_string());
    assert_eq!(
        (&glb.node_name, &glb.mesh_name, &glb.animation_name),
        (&name, &name, &name)
    );
    // Without a name, the library's default.
    write_dynamic_glb(
        &path,
        &mesh,
        &GltfExportOptions::default(),
        Progress::none(),
    )
    .unwrap();
    let glb = Glb::read(&path);
    let default = Some(voltrack::model::DEFAULT_NAME.to_string());
    assert_eq!(
        (&glb.node_name, &glb.mesh_name, &glb.animation_name),
        (&default, &default, &default)
    );
    // A blank name, or one with a line break, is a bad parameter.
    for bad in ["", "  ", "two\nlines"] {
        let err = write_dynamic_glb(
            &dir.join("bad.glb"),
            &mesh,
            &GltfExportOptions {
                name: bad.into(),
                ..Default::default()
            },
            Progress::none(),
        )
        .unwrap_err();
        assert!(
            matches!(err, voltrack::Error::InvalidParameter(_)),
            "{bad:?}: {err}"
        );
    }
    assert!(!dir.join("bad.glb").exists());
}

#[test]
fn compact_basis_reports_the_error_of_the_file() {
    let dir = Scratch::new("export", "components");
    for (name, mesh, k) in [
        ("bar", bending_bar(), 2),
        ("wobble", torus(30, wobble), 4),
        ("turning", torus(40, turning), 2),
    ] {
        let path = dir.join(&format!("{name}.glb"));
        let report = write_dynamic_glb(
            &path,
            &mesh,
            &options(BasisChoice::Components(k)),
            Progress::none(),
        )
        .unwrap();
        assert_eq!(report.basis, Some(k), "{name}");
        // Each component is one target, or two (positive and negative parts).
        assert!(
            report.targets >= k && report.targets <= 2 * k,
            "{name}: {} targets",
            report.targets
        );
        let glb = Glb::read(&path);
        check_common(&glb, &mesh, &report, &path, 30.0);
        // The same sampler as per-frame targets: each capture held.
        assert_eq!(glb.interpolation, Some(Interpolation::Step));
        let names = glb.target_names.as_ref().unwrap();
        assert!(names.iter().all(|n| n.starts_with("pc_")), "{names:?}");
        let d = diagonal(&mesh);
        let (max, mean) = glb.errors(&mesh);
        assert!(
            (max / d - report.reconstruction_error_max).abs() < 1e-5,
            "{name}: file {} vs reported {}",
            max / d,
            report.reconstruction_error_max
        );
        assert!(
            (mean / d - report.reconstruction_error_mean).abs() < 1e-5,
            "{name}: mean {} vs {}",
            mean / d,
            report.reconstruction_error_mean
        );
        assert!(report.reconstruction_error_mean <= report.reconstruction_error_max);
    }
    // The rank-3 turning motion is reproduced by three components.
    let mesh = torus(40, turning);
    let report = write_dynamic_glb(
        &dir.join("t3.glb"),
        &mesh,
        &options(BasisChoice::Components(3)),
        Progress::none(),
    )
    .unwrap();
    assert!(
        report.reconstruction_error_max < 1e-9,
        "{}",
        report.reconstruction_error_max
    );
}

#[test]
fn components_beyond_the_rank_are_not_written() {
    let dir = Scratch::new("export", "rank");
    // A translation along one direction, back and forth: rank 1.
    let mesh = torus(20, |f, p| {
        p + Vector3::new(1.0, 2.0, -0.5) * (0.7 * f as Real).sin()
    });
    let path = dir.join("shift.glb");
    let report = write_dynamic_glb(
        &path,
        &mesh,
        &options(BasisChoice::Components(5)),
        Progress::none(),
    )
    .unwrap();
    assert_eq!(report.basis, Some(1));
    assert_eq!(
        report.targets, 2,
        "a signed coefficient: positive and negative target"
    );
    assert!(report.reconstruction_error_max < 1e-9);
    let glb = Glb::read(&path);
    check_common(&glb, &mesh, &report, &path, 30.0);
    assert!(glb.errors(&mesh).0 < 1e-5 * diagonal(&mesh));
    // Zero components is a parameter error, and writes nothing.
    let err = write_dynamic_glb(
        &dir.join("zero.glb"),
        &mesh,
        &options(BasisChoice::Components(0)),
        Progress::none(),
    )
    .unwrap_err();
    assert!(matches!(err, voltrack::Error::InvalidParameter(_)), "{err}");
    assert!(!dir.join("zero.glb").exists());
}

#[test]
fn auto_picks_a_compact_basis_for_long_low_rank_motion() {
    let dir = Scratch::new("export", "auto");
    let mesh = torus(300, turning);
    let path = dir.join("long.glb");
    let report = write_dynamic_glb(
        &path,
        &mesh,
        &GltfExportOptions::default(),
        Progress::none(),
    )
    .unwrap();
    let k = report
        .basis
        .expect("past 256 frames Auto picks a compact basis");
    assert!(k <= 3, "{k} components for a rank-3 motion");
    assert!(report.targets <= 2 * k);
    assert!(report.reconstruction_error_max <= GltfExportOptions::default().max_basis_error);
    let glb = Glb::read(&path);
    check_common(&glb, &mesh, &report, &path, 30.0);
    assert_eq!(glb.interpolation, Some(Interpolation::Step));
    let (max, _) = glb.errors(&mesh);
    assert!(
        (max / diagonal(&mesh) - report.reconstruction_error_max).abs() < 1e-5,
        "{max}"
    );
    // Up to 256 frames Auto keeps one target per frame.
    let short = torus(256, turning);
    let report = write_dynamic_glb(
        &dir.join("short.glb"),
        &short,
        &GltfExportOptions::default(),
        Progress::none(),
    )
    .unwrap();
    assert_eq!((report.basis, report.targets), (None, 255));
}

/// Every row of the rate table is the file its basis makes: also where the
/// steps from frame to frame win over the basis the error bound chose, whose
/// row is then measured as it was encoded for that comparison (not encoded
/// again).
#[test]
fn the_rate_table_rows_are_the_files_each_basis_makes() {
    // Parts moving one after another: frame f has the first f of 24
    // sectors of the ring lifted, so each step from frame to frame moves one
    // sector only, while a basis needs a component for each.
    let sectors = 24;
    let mesh = torus(sectors, |f, p| {
        let turn = p.y.atan2(p.x).rem_euclid(std::f64::consts::TAU as Real);
        let sector = (turn / std::f64::consts::TAU as Real * sectors as Real) as usize;
        if sector < f {
            p + Vector3::new(0.0, 0.0, 0.2)
        } else {
            *p
        }
    });
    let dir = Scratch::new("export", "rate-table");
    let compressed = |basis| GltfExportOptions {
        compress: true,
        ..options(basis)
    };
    let report = write_dynamic_glb(
        &dir.join("auto.glb"),
        &mesh,
        &GltfExportOptions {
            rate_distortion: true,
            ..compressed(BasisChoice::Bounded {
                mean: 0.004,
                max: 0.04,
            })
        },
        Progress::none(),
    )
    .unwrap();
    assert!(report.steps, "{report:?}");
    let rows = &report.rate_distortion;
    let chosen: Vec<_> = rows.iter().filter(|r| r.chosen).collect();
    assert_eq!(chosen.len(), 1, "{rows:?}");
    assert_eq!(chosen[0].components, None, "{rows:?}");
    assert_eq!(chosen[0].bytes, report.bytes, "{rows:?}");
    let tried: Vec<usize> = rows.iter().filter_map(|r| r.components).collect();
    assert!(tried.len() >= 2, "{rows:?}");
    assert!(tried.windows(2).all(|k| k[0] < k[1]), "{rows:?}");
    // The bound's basis, the largest tried, is the file exactly; the smaller
    // ones are encoded from the largest's first targets, whose sums round a
    // little differently (and the quantisation a few steps differently).
    let bound = *tried.last().unwrap();
    for row in rows.iter().filter(|r| !r.chosen) {
        let k = row.components.expect("a compact basis");
        let alone = write_dynamic_glb(
            &dir.join(&format!("k{k}.glb")),
            &mesh,
            &compressed(BasisChoice::Components(k)),
            Progress::none(),
        )
        .unwrap();
        assert_eq!(alone.basis, Some(k));
        let (bytes, share) = if k == bound { (0, 0.0) } else { (64, 0.01) };
        let near = |a: Real, b: Real| (a - b).abs() <= share * b;
        assert!(
            row.bytes.abs_diff(alone.bytes) <= bytes
                && near(row.error_max, alone.reconstruction_error_max)
                && near(row.error_mean, alone.reconstruction_error_mean),
            "{k} components: {row:?} against {alone:?}"
        );
    }
}

#[test]
fn auto_keeps_per_frame_targets_when_a_basis_would_not_be_smaller() {
    let dir = Scratch::new("export", "auto-full");
    // 300 frames of independent random displacements of a 60-vertex mesh: the
    // displacements span all 180 dimensions, a basis within tolerance needs
    // nearly all of them, two targets each: more than one target per frame.
    let base = fixtures::torus(Point3::origin(), 1.0, 0.3, 10, 6);
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as Real / (1u64 << 53) as Real - 0.5
    };
    let frames = (0..300)
        .map(|f| {
            base.positions
                .iter()
                .map(|p| {
                    if f == 0 {
                        *p
                    } else {
                        p + Vector3::new(noise(), noise(), noise()) * 0.1
                    }
                })
                .collect()
        })
        .collect();
    let mesh = DynamicMesh {
        base,
        frames,
        reference: 0,
    };
    let path = dir.join("full.glb");
    let report = write_dynamic_glb(
        &path,
        &mesh,
        &GltfExportOptions::default(),
        Progress::none(),
    )
    .unwrap();
    assert_eq!((report.basis, report.targets), (None, 299), "{report:?}");
    let glb = Glb::read(&path);
    check_common(&glb, &mesh, &report, &path, 30.0);
    assert_eq!(glb.interpolation, Some(Interpolation::Step));
    assert!(glb.errors(&mesh).0 < 1e-5 * diagonal(&mesh));
}

#[test]
fn glb_edge_cases() {
    let dir = Scratch::new("export", "edge");
    // One frame: a static mesh, no targets, no animation.
    let mut one = bending_bar();
    one.frames = one.frames.to_vec().unwrap()[..1].to_vec().into();
    let path = dir.join("one.glb");
    let report =
        write_dynamic_glb(&path, &one, &GltfExportOptions::default(), Progress::none()).unwrap();
    assert_eq!(report.targets, 0);
    let glb = Glb::read(&path);
    check_common(&glb, &one, &report, &path, 30.0);
    assert!(glb.targets.is_empty() && glb.default_weights.is_none());
    // Without normals: no NORMAL attribute nor NORMAL deltas.
    let mesh = torus(5, wobble);
    let path = dir.join("flat.glb");
    let report = write_dynamic_glb(
        &path,
        &mesh,
        &GltfExportOptions {
            normals: false,
            ..options(BasisChoice::PerFrame)
        },
        Progress::none(),
    )
    .unwrap();
    let glb = Glb::read(&path);
    check_common(&glb, &mesh, &report, &path, 30.0);
    assert!(glb.normals.is_none() && glb.normal_targets.iter().all(Option::is_none));
    // Bad options and inconsistent meshes are errors and write nothing.
    let bad = dir.join("bad.glb");
    for fps in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(
            write_dynamic_glb(
                &bad,
                &mesh,
                &GltfExportOptions {
                    fps,
                    ..Default::default()
                },
                Progress::none()
            )
            .is_err(),
            "fps {fps}"
        );
    }
    assert!(write_dynamic_glb(
        &bad,
        &mesh,
        &GltfExportOptions {
            max_basis_error: -1.0,
            ..Default::default()
        },
        Progress::none()
    )
    .is_err());
    let mut frames = mesh.frames.to_vec().unwrap();
    frames[2].pop();
    let ragged = DynamicMesh {
        base: mesh.base.clone(),
        frames: frames.into(),
        reference: 0,
    };
    assert!(write_dynamic_glb(
        &bad,
        &ragged,
        &GltfExportOptions::default(),
        Progress::none()
    )
    .is_err());
    let mut frames = mesh.frames.to_vec().unwrap();
    frames[3][7].y = Real::NAN;
    let nan = DynamicMesh {
        base: mesh.base.clone(),
        frames: frames.into(),
        reference: 0,
    };
    assert!(
        write_dynamic_glb(&bad, &nan, &GltfExportOptions::default(), Progress::none()).is_err()
    );
    let empty = DynamicMesh {
        base: mesh.base.clone(),
        frames: Vec::new().into(),
        reference: 0,
    };
    assert!(write_dynamic_glb(
        &bad,
        &empty,
        &GltfExportOptions::default(),
        Progress::none()
    )
    .is_err());
    assert!(write_dynamic_glb(
        &dir.join("missing/x.glb"),
        &mesh,
        &GltfExportOptions::default(),
        Progress::none()
    )
    .is_err());
    let left: Vec<_> = std::fs::read_dir(&dir.0)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    let mut left = left;
    left.sort();
    assert_eq!(left, ["flat.glb", "one.glb"]);
}

#[test]
fn glb_bytes_do_not_depend_on_threads() {
    let dir = Scratch::new("export", "threads");
    let mesh = torus(40, wobble);
    for basis in [BasisChoice::PerFrame, BasisChoice::Components(3)] {
        let write = |name: &str, threads: usize| {
            let path = dir.join(name);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| write_dynamic_glb(&path, &mesh, &options(basis), Progress::none()))
                .unwrap();
            std::fs::read(path).unwrap()
        };
        let one = write("a.glb", 1);
        assert_eq!(one, write("b.glb", 1), "{basis:?}: two runs differ");
        assert_eq!(one, write("c.glb", 4), "{basis:?}: 1 and 4 threads differ");
    }
}

/// `mesh` with its frames in a temporary file, as a long sequence's are.
fn in_file(mesh: &DynamicMesh) -> DynamicMesh {
    let all = mesh.frames.to_vec().unwrap();
    let mut frames = PositionFrames::new(all[0].len(), all.len(), 0).unwrap();
    for frame in all {
        frames.push(frame).unwrap();
    }
    assert!(frames.in_file());
    DynamicMesh {
        base: mesh.base.clone(),
        frames,
        reference: mesh.reference,
    }
}

#[test]
fn every_writer_writes_the_same_bytes_from_frames_in_a_file() {
    let dir = Scratch::new("export", "in-file");
    let memory = torus(40, wobble);
    let file = in_file(&memory);
    let bytes = |path: PathBuf| std::fs::read(path).unwrap();
    for (k, basis) in [BasisChoice::PerFrame, BasisChoice::Components(3)]
        .into_iter()
        .enumerate()
    {
        for compress in [false, true] {
            let options = GltfExportOptions {
                compress,
                ..options(basis)
            };
            let write = |name: String, mesh: &DynamicMesh| {
                let report =
                    write_dynamic_glb(&dir.join(&name), mesh, &options, Progress::none()).unwrap();
                (report, bytes(dir.join(&name)))
            };
            assert!(
                write(format!("m{k}{compress}.glb"), &memory)
                    == write(format!("f{k}{compress}.glb"), &file),
                "{basis:?}, compress {compress}: differ"
            );
        }
    }
    // The same names in two folders: the files name each other.
    for (name, mesh) in [("m", &memory), ("f", &file)] {
        let out = dir.join(name);
        std::fs::create_dir(&out).unwrap();
        voltrack::export::pc2::write_pc2(&out.join("a.pc2"), mesh, 30.0, "t").unwrap();
        write_vat(&out.join("a.exr"), mesh, &VatOptions::default()).unwrap();
        voltrack::export::obj::write_obj_sequence(&out.join("obj"), mesh, "t").unwrap();
    }
    for file in [
        "a.pc2",
        "a.obj",
        "a.exr",
        "a.glb",
        "a.json",
        "obj/frame_0000.obj",
        "obj/frame_0039.obj",
    ] {
        assert!(
            bytes(dir.join("m").join(file)) == bytes(dir.join("f").join(file)),
            "{file} differs"
        );
    }
}

#[test]
fn compact_basis_bytes_do_not_depend_on_threads() {
    let dir = Scratch::new("export", "basis-threads");
    // Long enough for Auto to sketch, and not of low rank.
    let mesh = torus(300, |f, p| turning(f, p) + (wobble(f, p) - p) * 0.05);
    for basis in [BasisChoice::Auto, BasisChoice::Components(16)] {
        let write = |name: &str, threads: usize| {
            let path = dir.join(name);
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let report = pool
                .install(|| write_dynamic_glb(&path, &mesh, &options(basis), Progress::none()))
                .unwrap();
            assert!(report.basis.is_some(), "{basis:?}: {report:?}");
            std::fs::read(path).unwrap()
        };
        let one = write("a.glb", 1);
        assert_eq!(one, write("b.glb", 2), "{basis:?}: 1 and 2 threads differ");
    }
}

#[test]
fn an_interrupt_stops_the_compact_basis() {
    let dir = Scratch::new("export", "interrupt");
    let mesh = torus(300, |f, p| turning(f, p) + (wobble(f, p) - p) * 0.05);
    let tolerance = GltfExportOptions::default().max_basis_error * diagonal(&mesh);
    let path = dir.join("stopped.glb");
    for basis in [BasisChoice::Auto, BasisChoice::Components(16)] {
        // Unstopped, the basis alone and the whole export poll this often.
        let polls = |work: &dyn Fn(Progress) -> bool| {
            let sink = StopAfter::new(usize::MAX);
            assert!(work(Progress(Some(&sink))), "{basis:?}: failed unstopped");
            sink.polls()
        };
        let choose = |progress: Progress| {
            voltrack::export::basis::choose(&mesh.frames, basis, tolerance, progress).is_ok()
        };
        let write =
            |progress: Progress| write_dynamic_glb(&path, &mesh, &options(basis), progress).is_ok();
        let (in_basis, in_export) = (polls(&choose), polls(&write));
        assert!(
            in_basis >= 3 && in_export > in_basis,
            "{basis:?}: {in_basis} polls in the basis, {in_export} in the export"
        );
        std::fs::remove_file(&path).unwrap();
        // A stop at any of those points is honoured, and writes nothing.
        for after in [0, 2, in_basis / 2, in_basis - 1, in_export - 1] {
            let sink = StopAfter::new(after);
            let err = voltrack::export::basis::choose(
                &mesh.frames,
                basis,
                tolerance,
                Progress(Some(&sink)),
            );
            if after < in_basis {
                assert!(
                    matches!(err, Err(voltrack::Error::Interrupted { saved: None })),
                    "{basis:?}, stop at poll {after}: {:?}",
                    err.map(|b| b.0.components)
                );
            }
            let sink = StopAfter::new(after);
            let err = write_dynamic_glb(&path, &mesh, &options(basis), Progress(Some(&sink)))
                .unwrap_err();
            assert!(
                matches!(err, voltrack::Error::Interrupted { saved: None }),
                "{basis:?}, stop at poll {after}: {err}"
            );
            assert!(!path.exists(), "{basis:?}: a file after an interrupt");
        }
    }
}

#[test]
fn an_interrupt_stops_per_frame_targets_while_they_are_computed_or_written() {
    let dir = Scratch::new("export", "interrupt-per-frame");
    let memory = torus(60, wobble);
    let file = in_file(&memory);
    let path = dir.join("stopped.glb");
    for mesh in [&memory, &file] {
        let sink = StopAfter::new(usize::MAX);
        write_dynamic_glb(
            &path,
            mesh,
            &options(BasisChoice::PerFrame),
            Progress(Some(&sink)),
        )
        .unwrap();
        std::fs::remove_file(&path).unwrap();
        let polls = sink.polls();
        // One poll per target for the bounds, one per delta written.
        assert!(polls >= 2 * 59, "{polls} polls");
        for after in [0, polls / 4, polls / 2, polls - 1] {
            let sink = StopAfter::new(after);
            let err = write_dynamic_glb(
                &path,
                mesh,
                &options(BasisChoice::PerFrame),
                Progress(Some(&sink)),
            )
            .unwrap_err();
            assert!(
                matches!(err, voltrack::Error::Interrupted { saved: None }),
                "stop at poll {after} of {polls}: {err}"
            );
            assert!(!path.exists(), "a file after an interrupt at poll {after}");
        }
    }
}

fn i32_at(bytes: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}
fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// `v`, `vt` and `f` lines of an OBJ as numbers / text.
fn obj_lines(text: &str) -> (Vec<[f32; 3]>, Vec<String>, Vec<String>) {
    let mut v = Vec::new();
    let (mut vt, mut f) = (Vec::new(), Vec::new());
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("v ") {
            let c: Vec<f32> = rest
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            assert_eq!(c.len(), 3, "{line}");
            v.push([c[0], c[1], c[2]]);
        } else if line.starts_with("vt ") {
            vt.push(line.to_string());
        } else if line.starts_with("f ") {
            f.push(line.to_string());
        } else {
            let known = ["#", "o ", "vn "].iter().any(|p| line.starts_with(p));
            assert!(
                known || line.trim().is_empty(),
                "unexpected OBJ line {line}"
            );
        }
    }
    (v, vt, f)
}

/// The names of an OBJ's `o` lines and its `vn` normals.
fn obj_objects_and_normals(text: &str) -> (Vec<String>, Vec<[f32; 3]>) {
    let objects = text
        .lines()
        .filter_map(|l| l.strip_prefix("o "))
        .map(String::from)
        .collect();
    let normals = text
        .lines()
        .filter_map(|l| l.strip_prefix("vn "))
        .map(|rest| {
            let c: Vec<f32> = rest
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            [c[0], c[1], c[2]]
        })
        .collect();
    (objects, normals)
}

/// Vertex indices of `f` lines (1-based in the file, 0-based here).
fn face_indices(faces: &[String]) -> Vec<[u32; 3]> {
    faces
        .iter()
        .map(|l| {
            let idx: Vec<u32> = l[2..]
                .split_whitespace()
                .map(|c| c.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
                .collect();
            [idx[0], idx[1], idx[2]]
        })
        .collect()
}

#[test]
fn point_cache_header_counts_and_positions() {
    let dir = Scratch::new("export", "pc2");
    // The bar plus one vertex no triangle uses, which both files leave out.
    let mut mesh = bending_bar();
    let unused = mesh.base.positions.len();
    mesh.base.positions.push(Point3::new(9.0, 9.0, 9.0));
    let mut frames = mesh.frames.to_vec().unwrap();
    frames
        .iter_mut()
        .for_each(|f| f.push(Point3::new(9.0, 9.0, 9.0)));
    mesh.frames = frames.into();
    let path = dir.join("bar.pc2");
    voltrack::export::pc2::write_pc2(&path, &mesh, 25.0, "bar").unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let points = unused; // every other vertex is used
    let samples = mesh.frames.len();
    let mut header = b"POINTCACHE2\0".to_vec();
    header.extend(1i32.to_le_bytes());
    header.extend((points as i32).to_le_bytes());
    header.extend(0f32.to_le_bytes());
    header.extend(1f32.to_le_bytes());
    header.extend((samples as i32).to_le_bytes());
    assert_eq!(&bytes[..32], &header[..]);
    assert_eq!(
        (i32_at(&bytes, 16), i32_at(&bytes, 28)),
        (points as i32, samples as i32)
    );
    assert_eq!(bytes.len(), 32 + 12 * points * samples);
    for (f, frame) in mesh.frames.to_vec().unwrap().iter().enumerate() {
        for (v, position) in frame.iter().enumerate().take(points) {
            for k in 0..3 {
                assert_eq!(
                    f32_at(&bytes, 32 + 12 * (f * points + v) + 4 * k),
                    position[k] as f32,
                    "frame {f}, vertex {v}"
                );
            }
        }
    }
    // The OBJ beside it: frame 0, the same vertices in the same order, the
    // same triangles, and the frame rate in its header.
    let text = std::fs::read_to_string(dir.join("bar.obj")).unwrap();
    assert!(
        text.lines().next().unwrap().contains("bar.pc2")
            && text.contains("25 fps")
            && text.contains(&format!("{samples} frames")),
        "{}",
        text.lines().next().unwrap()
    );
    let (v, vt, f) = obj_lines(&text);
    assert_eq!(v.len(), points);
    assert!(vt.is_empty());
    assert_eq!(
        obj_objects_and_normals(&text),
        (vec!["bar".to_string()], obj_objects_and_normals(&text).1)
    );
    assert_eq!(
        obj_objects_and_normals(&text).1.len(),
        points,
        "a normal for every vertex kept, none for the unused one"
    );
    for (a, p) in v.iter().zip(&mesh.frames.get(0).unwrap()[..]) {
        assert_eq!(*a, [p.x as f32, p.y as f32, p.z as f32]);
    }
    assert_eq!(face_indices(&f), mesh.base.triangles);
    // Into the caller's writers: the same bytes as the files.
    let (mut cache, mut obj) = (Vec::new(), Vec::new());
    voltrack::export::pc2::write_pc2_to(&mut cache, &mut obj, "bar.pc2", &mesh, 25.0, "bar")
        .unwrap();
    assert_eq!(cache, bytes);
    assert_eq!(String::from_utf8(obj).unwrap(), text);
    // Bad frame rates and names, and a path that would overwrite the OBJ, are refused.
    for fps in [0.0, -2.0, f32::NAN] {
        assert!(voltrack::export::pc2::write_pc2(&dir.join("x.pc2"), &mesh, fps, "bar").is_err());
    }
    for name in ["", "a\nb"] {
        assert!(
            voltrack::export::pc2::write_pc2(&dir.join("x.pc2"), &mesh, 30.0, name).is_err(),
            "{name:?}"
        );
    }
    assert!(voltrack::export::pc2::write_pc2(&dir.join("x.obj"), &mesh, 30.0, "bar").is_err());
    assert!(!dir.join("x.pc2").exists() && !dir.join("x.obj").exists());
}

/// A torus whose vertices at u = 0 are duplicated along a UV seam, as a
/// loader makes them: the triangles on the far side of the seam use the
/// copies. Returns the mesh (UVs set) and the (original, copy) pairs.
fn seamed_torus() -> (voltrack::TriangleMesh, Vec<(usize, usize)>) {
    let (n_major, n_minor) = (24u32, 12u32);
    let mut m = fixtures::torus(Point3::origin(), 1.0, 0.3, n_major, n_minor);
    let mut uvs: Vec<[f32; 2]> = (0..m.positions.len())
        .map(|v| {
            [
                (v as u32 / n_minor) as f32 / n_major as f32,
                (v as u32 % n_minor) as f32 / n_minor as f32,
            ]
        })
        .collect();
    let mut pairs = Vec::new();
    for j in 0..n_minor as usize {
        pairs.push((j, m.positions.len()));
        m.positions.push(m.positions[j]);
        uvs.push([1.0, uvs[j][1]]);
    }
    let last_ring = |v: u32| v / n_minor == n_major - 1;
    for t in m.triangles.iter_mut() {
        if t.iter().any(|&v| last_ring(v)) {
            for v in t.iter_mut() {
                if *v < n_minor {
                    *v = pairs[*v as usize].1 as u32;
                }
            }
        }
    }
    m.uvs = Some(uvs);
    (m, pairs)
}

/// Issue 23: the point cache's OBJ is named and carries frame 0's normals,
/// welded at UV seams and equal to the GLB's, so Blender shades it smooth.
#[test]
fn point_cache_obj_is_named_and_smooth() {
    let dir = Scratch::new("export", "pc2-normals");
    let (base, pairs) = seamed_torus();
    let frames = (0..4)
        .map(|f| base.positions.iter().map(|p| turning(f, p)).collect())
        .collect();
    let mesh = DynamicMesh {
        base,
        frames,
        reference: 0,
    };
    let path = dir.join("torus.pc2");
    voltrack::export::pc2::write_pc2(&path, &mesh, 30.0, "Torus").unwrap();
    let text = std::fs::read_to_string(dir.join("torus.obj")).unwrap();
    let (objects, normals) = obj_objects_and_normals(&text);
    assert_eq!(objects, ["Torus"]);
    let (v, _, f) = obj_lines(&text);
    assert_eq!(normals.len(), v.len(), "one normal per vertex");
    // Each corner names its vertex's own UV and normal.
    for line in &f {
        for corner in line[2..].split_whitespace() {
            let idx: Vec<&str> = corner.split('/').collect();
            assert!(
                idx.len() == 3 && idx[1] == idx[0] && idx[2] == idx[0],
                "{line}"
            );
        }
    }
    // The same normals as the GLB's NORMAL attribute.
    let glb_path = dir.join("torus.glb");
    write_dynamic_glb(
        &glb_path,
        &mesh,
        &GltfExportOptions::default(),
        Progress::none(),
    )
    .unwrap();
    assert_eq!(Glb::read(&glb_path).normals.as_ref(), Some(&normals));
    // Smooth across the seam: a copy has its original's normal, which is
    // the torus' own (area-weighted over the whole fan, not half of it).
    let n = |v: usize| {
        Vector3::new(
            normals[v][0] as Real,
            normals[v][1] as Real,
            normals[v][2] as Real,
        )
    };
    for &(original, copy) in &pairs {
        assert_eq!(
            normals[original], normals[copy],
            "vertex {original} and its copy {copy}"
        );
        let p = mesh.frames.get(0).unwrap()[original];
        let ring = Vector3::new(p.x, p.y, 0.0).normalize();
        let exact = (p.coords - ring).normalize();
        assert!(
            n(original).dot(&exact) > 0.99,
            "vertex {original}: {:?} vs {exact:?}",
            n(original)
        );
    }
    for v in 0..normals.len() {
        assert!((n(v).norm() - 1.0).abs() < 1e-6, "vertex {v}");
    }
}

#[test]
fn obj_sequence_shares_one_connectivity() {
    let dir = Scratch::new("export", "objseq");
    for (name, mesh) in [("bar", bending_bar()), ("torus", torus(11, wobble))] {
        let out = dir.join(name);
        let paths = voltrack::export::obj::write_obj_sequence(&out, &mesh, name).unwrap();
        let want: Vec<PathBuf> = (0..mesh.frames.len())
            .map(|f| out.join(format!("frame_{f:04}.obj")))
            .collect();
        assert_eq!(paths, want);
        let mut listed: Vec<PathBuf> = std::fs::read_dir(&out)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        listed.sort();
        // The frames, and the hidden list of them that lets a later run replace the folder.
        let manifest = out.join(voltrack::files::FOLDER_MANIFEST);
        assert_eq!(
            listed,
            std::iter::once(manifest.clone())
                .chain(want.iter().cloned())
                .collect::<Vec<_>>(),
            "only the frames are in the directory"
        );
        let names: Vec<String> = std::fs::read_to_string(&manifest)
            .unwrap()
            .lines()
            .skip(1)
            .map(String::from)
            .collect();
        assert_eq!(
            names,
            want.iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
        );
        // Into the caller's writers: the same bytes as the files.
        let frames = voltrack::export::obj::ObjFrames::new(&mesh, name).unwrap();
        for (f, path) in paths.iter().enumerate() {
            let mut bytes = Vec::new();
            frames.write(&mut bytes, f).unwrap();
            assert_eq!(bytes, std::fs::read(path).unwrap(), "frame {f}");
        }
        let first = mesh.frames.get(0).unwrap();
        let (_, vt0, f0) = obj_lines(&std::fs::read_to_string(&paths[0]).unwrap());
        assert_eq!(f0.len(), mesh.base.triangles.len());
        assert_eq!(face_indices(&f0), mesh.base.triangles);
        if let Some(uv) = &mesh.base.uvs {
            assert_eq!(vt0.len(), uv.len());
            assert!(
                f0.iter().all(|l| l.matches('/').count() == 6),
                "v/vt/vn corners: {}",
                f0[0]
            );
        } else {
            assert!(
                f0.iter().all(|l| l.matches("//").count() == 3),
                "v//vn corners: {}",
                f0[0]
            );
        }
        for (path, frame) in paths.iter().zip(&mesh.frames.to_vec().unwrap()) {
            let text = std::fs::read_to_string(path).unwrap();
            let (objects, normals) = obj_objects_and_normals(&text);
            assert_eq!(objects, [name], "{}: one object, named", path.display());
            // This frame's own normals, so every file is smooth-shaded: per
            // vertex, the area-weighted sum of its faces' normals over every
            // copy of it at a UV seam (brute force: copies by frame-0 position).
            assert_eq!(normals.len(), frame.len(), "{}", path.display());
            let mut sum = vec![Vector3::zeros(); frame.len()];
            for t in &mesh.base.triangles {
                let [a, b, c] = t.map(|i| frame[i as usize]);
                for &i in t {
                    sum[i as usize] += (b - a).cross(&(c - a));
                }
            }
            for (i, n) in normals.iter().enumerate() {
                let copies = (0..frame.len()).filter(|&j| first[j] == first[i]);
                let Some(want) = copies.map(|j| sum[j]).sum::<Vector3>().try_normalize(1e-12)
                else {
                    continue;
                };
                let got = Vector3::new(n[0] as Real, n[1] as Real, n[2] as Real);
                assert!(
                    (got - want).norm() < 1e-5,
                    "{}: normal {i} is {got:?}, want {want:?}",
                    path.display()
                );
            }
            let (v, vt, f) = obj_lines(&text);
            assert_eq!(f, f0, "{}: face lines differ", path.display());
            assert_eq!(vt, vt0, "{}: texture coordinates differ", path.display());
            assert_eq!(v.len(), frame.len());
            for (a, p) in v.iter().zip(frame) {
                assert_eq!(*a, [p.x as f32, p.y as f32, p.z as f32]);
            }
        }
    }
    // A file where the directory should go: an error naming it.
    std::fs::write(dir.join("taken"), b"x").unwrap();
    let err = voltrack::export::obj::write_obj_sequence(&dir.join("taken"), &bending_bar(), "bar")
        .unwrap_err()
        .to_string();
    assert!(err.contains("taken"), "{err}");
    // A frame that cannot be written: none of the others stays.
    let out = dir.join("new/frames");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::create_dir(out.join("frame_0003.obj")).unwrap();
    let err = voltrack::export::obj::write_obj_sequence(&out, &bending_bar(), "bar")
        .unwrap_err()
        .to_string();
    assert!(err.contains("frame_0003.obj"), "{err}");
    let left: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    assert_eq!(left, [out.join("frame_0003.obj")]);
}

/// Issue 23: a mesh of 100,000 vertices wraps into rows a GPU samples
/// (one column per vertex was 100,000 texels wide), every vertex of every
/// frame at the texel the layout names; with `power_of_two` both sides are
/// powers of two and the texels no vertex uses are zero.
#[test]
fn vat_of_100k_vertices_fits_a_gpu_texture() {
    let dir = Scratch::new("export", "vat_width");
    let base = fixtures::torus(Point3::origin(), 1.0, 0.3, 500, 200);
    let vertices = base.positions.len();
    assert_eq!(vertices, 100_000);
    let frames = (0..3)
        .map(|f| base.positions.iter().map(|p| turning(f, p)).collect())
        .collect();
    let mesh = DynamicMesh {
        base,
        frames,
        reference: 0,
    };
    // 100,000 vertices in rows of 8192: 13 rows per frame, the last holding 1696.
    for (power_of_two, height) in [(false, 39), (true, 64)] {
        let path = dir.join(if power_of_two {
            "pow2.exr"
        } else {
            "plain.exr"
        });
        let report = write_vat(
            &path,
            &mesh,
            &VatOptions {
                power_of_two,
                ..Default::default()
            },
        )
        .unwrap();
        let layout = report.layout;
        assert_eq!(
            (layout.width, layout.rows_per_frame, layout.height),
            (8192, 13, height),
            "power of two: {power_of_two}"
        );
        let (texture, _) = voltrack::io::exr::read_trajectories_exr(&path).unwrap();
        assert_eq!(
            (texture.centers, texture.frames),
            (layout.width, layout.height)
        );
        assert!(texture.centers <= 8192);
        if power_of_two {
            assert!(texture.centers.is_power_of_two() && texture.frames.is_power_of_two());
        }
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path.with_extension("json")).unwrap())
                .unwrap();
        assert_eq!(
            (
                info["width"].as_u64(),
                info["height"].as_u64(),
                info["rows_per_frame"].as_u64()
            ),
            (Some(8192), Some(height as u64), Some(13))
        );
        for (f, frame) in mesh.frames.to_vec().unwrap().iter().enumerate() {
            for v in (0..vertices).step_by(97).chain([vertices - 1]) {
                let (column, row) = (v % 8192, f * 13 + v / 8192);
                assert_eq!(layout.texel(v, f), (column, row));
                let texel = texture.get(row, column);
                assert!(
                    (0..3).all(|a| texel[a] == frame[v][a] as f32 as Real),
                    "vertex {v} of frame {f}"
                );
            }
            // The rest of each frame's last row is unused.
            assert_eq!(texture.get(f * 13 + 12, 1696), Point3::origin());
            assert_eq!(texture.get(f * 13 + 12, 8191), Point3::origin());
        }
        // Padding rows, with power_of_two.
        for row in 39..height {
            assert!(
                (0..8192)
                    .step_by(511)
                    .all(|c| texture.get(row, c) == Point3::origin()),
                "row {row}"
            );
        }
    }
}

/// What decides the texture's size: the widest row allowed, powers of two,
/// and a height past the largest allowed refused with a message that says why.
#[test]
fn vat_layout_sizes_and_limits() {
    let plain = VatOptions::default();
    let pow2 = VatOptions {
        power_of_two: true,
        ..Default::default()
    };
    let size = |o: &VatOptions, v: usize, f: usize| {
        o.layout(v, f)
            .map(|l| (l.width, l.rows_per_frame, l.height))
            .unwrap()
    };
    assert_eq!(size(&plain, 50, 6), (50, 1, 6));
    assert_eq!(size(&pow2, 50, 6), (64, 1, 8));
    assert_eq!(size(&plain, 8192, 3), (8192, 1, 3));
    assert_eq!(size(&plain, 8193, 3), (8192, 2, 6));
    // A width that is no power of two: the largest one within it.
    let narrow = VatOptions {
        max_width: 1000,
        power_of_two: true,
        ..Default::default()
    };
    assert_eq!(size(&narrow, 5000, 2), (512, 10, 32));
    assert_eq!(
        size(
            &VatOptions {
                max_width: 1000,
                ..Default::default()
            },
            5000,
            2
        ),
        (1000, 5, 10)
    );
    let l = plain.layout(8193, 3).unwrap();
    assert_eq!(
        (l.texel(8192, 2), l.vertex_at(0, 5), l.vertex_at(1, 5)),
        ((0, 5), Some((8192, 2)), None)
    );
    let uv = l.uv(8192);
    assert_eq!(uv, [0.5 / 8192.0, 1.5 / 6.0]);
    // Too high: refused, with the numbers.
    let err = plain.layout(100_000, 1261).unwrap_err().to_string();
    assert!(err.contains("16393") && err.contains("16384"), "{err}");
    assert!(plain.layout(100_000, 1260).is_ok());
    assert!(plain.check_frames(16_385).is_err() && plain.check_frames(16_384).is_ok());
    // 17 rows fit 30, but not as 32.
    assert!(VatOptions {
        max_height: 30,
        ..Default::default()
    }
    .layout(10, 17)
    .is_ok());
    let err = VatOptions {
        max_height: 30,
        ..pow2.clone()
    }
    .layout(10, 17)
    .unwrap_err()
    .to_string();
    assert!(err.contains("32 as a power of two"), "{err}");
    // Out-of-range options.
    for bad in [
        VatOptions {
            max_width: 0,
            ..Default::default()
        },
        VatOptions {
            max_height: 65_537,
            ..Default::default()
        },
        VatOptions {
            fps: 0.0,
            ..Default::default()
        },
        VatOptions {
            name: " ".into(),
            ..Default::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}

/// The mesh beside the texture: frame 0 with normals, its UVs and TEXCOORD_1
/// at each vertex's frame-0 texel center, marked as a VAT's mesh near the
/// start of its JSON, where a rerun looks before replacing it.
#[test]
fn vat_mesh_carries_frame_0_and_texel_uvs() {
    let dir = Scratch::new("export", "vat_mesh");
    let mesh = torus(5, turning);
    let path = dir.join("walk.exr");
    let options = VatOptions {
        fps: 24.0,
        name: "walk".into(),
        max_width: 100,
        ..Default::default()
    };
    let layout = write_vat(&path, &mesh, &options).unwrap().layout;
    assert_eq!((layout.width, layout.rows_per_frame), (100, 3));
    let bytes = std::fs::read(path.with_extension("glb")).unwrap();
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).into_owned();
    assert!(head.contains(voltrack::export::vat::MESH_MARK), "{head}");
    let doc = gltf::Gltf::from_slice(&bytes).unwrap();
    let blob = doc.blob.as_deref().unwrap();
    assert_eq!(
        (doc.animations().count(), doc.nodes().next().unwrap().name()),
        (0, Some("walk"))
    );
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert!(primitive.morph_targets().next().is_none());
    let reader = primitive.reader(|_| Some(blob));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    assert!(positions
        .iter()
        .zip(&mesh.frames.get(0).unwrap()[..])
        .all(|(a, b)| (0..3).all(|k| a[k] == b[k] as f32)));
    assert_eq!(reader.read_normals().unwrap().count(), positions.len());
    let uv0: Vec<[f32; 2]> = reader.read_tex_coords(0).unwrap().into_f32().collect();
    assert_eq!(Some(&uv0), mesh.base.uvs.as_ref());
    let uv1: Vec<[f32; 2]> = reader.read_tex_coords(1).unwrap().into_f32().collect();
    for (v, uv) in uv1.iter().enumerate() {
        let (column, row) = layout.texel(v, 0);
        assert_eq!(
            *uv,
            [
                ((column as f64 + 0.5) / 100.0) as f32,
                ((row as f64 + 0.5) / 15.0) as f32
            ],
            "vertex {v}"
        );
    }
    let scene: serde_json::Value = serde_json::from_str(
        doc.default_scene()
            .unwrap()
            .extras()
            .as_ref()
            .unwrap()
            .get(),
    )
    .unwrap();
    assert_eq!(scene, serde_json::json!({"fps": 24.0, "frames": 5}));

    // Into the caller's writers, under the same names: the same bytes as the files.
    let (mut texture, mut glb, mut sidecar) =
        (std::io::Cursor::new(Vec::new()), Vec::new(), Vec::new());
    let names = voltrack::export::vat::VatNames {
        texture: "walk.exr",
        mesh: "walk.glb",
        sidecar: "walk.json",
    };
    let report = voltrack::export::vat::write_vat_to(
        &mut texture,
        &mut glb,
        &mut sidecar,
        &names,
        &mesh,
        &options,
    )
    .unwrap();
    assert_eq!(texture.get_ref(), &std::fs::read(&path).unwrap());
    assert_eq!(glb, bytes);
    assert_eq!(sidecar, std::fs::read(path.with_extension("json")).unwrap());
    assert_eq!(report.layout, layout);
    assert_eq!(report.bytes[0], texture.get_ref().len() as u64);
}

/// Decodes one accessor of a compressed GLB as meshoptimizer and glTF say:
/// EXT_meshopt_compression's stream decoded with the meshopt crate, then the
/// normalized SHORT or BYTE components dequantised to [-1, 1].
fn decode_quantised(json: &serde_json::Value, bin: &[u8], accessor: usize) -> Vec<[f64; 3]> {
    let acc = &json["accessors"][accessor];
    let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let ext = &view["extensions"]["EXT_meshopt_compression"];
    assert_eq!(ext["mode"], "ATTRIBUTES");
    assert_eq!(acc["normalized"], true);
    let (off, len) = (
        ext["byteOffset"].as_u64().unwrap() as usize,
        ext["byteLength"].as_u64().unwrap() as usize,
    );
    let count = ext["count"].as_u64().unwrap() as usize;
    assert_eq!(count, acc["count"].as_u64().unwrap() as usize);
    let data = &bin[off..off + len];
    match acc["componentType"].as_u64().unwrap() {
        5122 => {
            assert_eq!(ext["byteStride"], 8);
            let v: Vec<[i16; 4]> = meshopt::decode_vertex_buffer(data, count).unwrap();
            v.iter()
                .map(|q| [0, 1, 2].map(|k| (q[k] as f64 / 32767.0).max(-1.0)))
                .collect()
        }
        5120 => {
            assert_eq!(ext["byteStride"], 4);
            let v: Vec<[i8; 4]> = meshopt::decode_vertex_buffer(data, count).unwrap();
            v.iter()
                .map(|q| [0, 1, 2].map(|k| (q[k] as f64 / 127.0).max(-1.0)))
                .collect()
        }
        other => panic!("component type {other}"),
    }
}

#[test]
fn compressed_glb_decodes_to_every_frame_within_the_reported_error() {
    let dir = Scratch::new("export", "compress");
    // 96 × 40 = 3840 vertices, 40 frames of a bend plus a turn.
    let mut base = fixtures::torus(Point3::origin(), 1.0, 0.3, 96, 40);
    base.uvs = Some(
        (0..base.positions.len())
            .map(|v| [(v / 40) as f32 / 96.0, (v % 40) as f32 / 40.0])
            .collect(),
    );
    let frames = (0..40)
        .map(|f| {
            base.positions
                .iter()
                .map(|p| {
                    turning(f, p)
                        + Vector3::new(0.0, 0.0, 0.2 * (f as Real * 0.1).sin() * p.x * p.x)
                })
                .collect()
        })
        .collect();
    let mesh = DynamicMesh {
        base,
        frames,
        reference: 0,
    };
    let d = diagonal(&mesh);
    for basis in [BasisChoice::PerFrame, BasisChoice::Components(4)] {
        let plain = write_dynamic_glb(
            &dir.join("plain.glb"),
            &mesh,
            &options(basis),
            Progress::none(),
        )
        .unwrap();
        let path = dir.join("compressed.glb");
        let report = write_dynamic_glb(
            &path,
            &mesh,
            &GltfExportOptions {
                compress: true,
                ..options(basis)
            },
            Progress::none(),
        )
        .unwrap();
        assert!(report.compressed && !plain.compressed);
        assert_eq!(report.bytes, std::fs::metadata(&path).unwrap().len());
        assert!(
            report.bytes * 3 <= plain.bytes,
            "{basis:?}: {} bytes compressed vs {} plain",
            report.bytes,
            plain.bytes
        );
        assert!(
            report.reconstruction_error_max < 0.0005,
            "{basis:?}: {}",
            report.reconstruction_error_max
        );
        eprintln!(
            "{basis:?}: {} bytes plain, {} compressed, error max {} mean {}",
            plain.bytes,
            report.bytes,
            report.reconstruction_error_max,
            report.reconstruction_error_mean
        );

        let bytes = std::fs::read(&path).unwrap();
        let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
        let json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
        let bin = glb.bin.unwrap();
        let required: Vec<&str> = json["extensionsRequired"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_str().unwrap())
            .collect();
        assert_eq!(
            required,
            ["EXT_meshopt_compression", "KHR_mesh_quantization"]
        );
        assert_eq!(
            json["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"],
            true
        );
        let node = &json["nodes"][0];
        let t: Vec<f64> = node["translation"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let s: Vec<f64> = node["scale"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(s[0] == s[1] && s[1] == s[2], "uniform scale {s:?}");
        let prim = &json["meshes"][0]["primitives"][0];
        let at = |v: &serde_json::Value| v.as_u64().unwrap() as usize;
        let positions = decode_quantised(&json, &bin, at(&prim["attributes"]["POSITION"]));
        let normals = decode_quantised(&json, &bin, at(&prim["attributes"]["NORMAL"]));
        assert!(normals
            .iter()
            .all(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 0.02));
        let targets: Vec<Vec<[f64; 3]>> = prim["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| decode_quantised(&json, &bin, at(&t["POSITION"])))
            .collect();
        // The indices too.
        let idx_acc = &json["accessors"][at(&prim["indices"])];
        let idx_ext = &json["bufferViews"][at(&idx_acc["bufferView"])]["extensions"]
            ["EXT_meshopt_compression"];
        assert_eq!(idx_ext["mode"], "TRIANGLES");
        let (off, len) = (at(&idx_ext["byteOffset"]), at(&idx_ext["byteLength"]));
        let indices: Vec<u32> =
            meshopt::decode_index_buffer(&bin[off..off + len], at(&idx_ext["count"])).unwrap();
        // The file holds the vertices in its own order (for the codecs):
        // each of its vertices is the mesh's vertex at its place in frame 0,
        // one to one, and its triangles are the mesh's through that match.
        let frames = mesh.frames.to_vec().unwrap();
        let world = |q: [f64; 3]| [0, 1, 2].map(|k| q[k] * s[k] + t[k]);
        let original: Vec<usize> = positions
            .iter()
            .map(|&q| {
                let w = world(q);
                (0..frames[0].len())
                    .min_by(|&a, &b| {
                        let da =
                            (frames[0][a] - voltrack::math::Point3::new(w[0], w[1], w[2])).norm();
                        let db =
                            (frames[0][b] - voltrack::math::Point3::new(w[0], w[1], w[2])).norm();
                        da.total_cmp(&db)
                    })
                    .unwrap()
            })
            .collect();
        let mut seen = original.clone();
        seen.sort();
        seen.dedup();
        assert_eq!(seen.len(), original.len(), "{basis:?}: not one to one");
        let sorted = |t: [usize; 3]| {
            let mut t = t;
            t.sort();
            t
        };
        let mut ours: Vec<[usize; 3]> = indices
            .chunks_exact(3)
            .map(|t| sorted([0, 1, 2].map(|c| original[t[c] as usize])))
            .collect();
        let mut theirs: Vec<[usize; 3]> = mesh
            .base
            .triangles
            .iter()
            .map(|t| sorted(t.map(|v| v as usize)))
            .collect();
        ours.sort();
        theirs.sort();
        assert_eq!(ours, theirs, "{basis:?}: the triangles differ");
        // Every frame: base + Σ w · delta at its keyed weights, then the node transform.
        let read = Glb::read_weights(&json, &bin);
        let (mut max, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
        for (f, frame) in frames.iter().enumerate() {
            for (i, &v) in original.iter().enumerate() {
                let p = frame[v];
                let mut q = positions[i];
                for (w, target) in read[f].iter().zip(&targets) {
                    for k in 0..3 {
                        q[k] += *w as f64 * target[i][k];
                    }
                }
                let world = world(q);
                let e = ((world[0] - p.x).powi(2)
                    + (world[1] - p.y).powi(2)
                    + (world[2] - p.z).powi(2))
                .sqrt()
                    / d as f64;
                assert!(
                    e <= report.reconstruction_error_max as f64 + 1e-6,
                    "{basis:?} frame {f} vertex {v}: {e} > {}",
                    report.reconstruction_error_max
                );
                max = max.max(e);
                sum += e;
                n += 1;
            }
        }
        assert!(
            (max - report.reconstruction_error_max as f64).abs() < 1e-6,
            "{basis:?}: decoded max {max} vs reported {}",
            report.reconstruction_error_max
        );
        assert!((sum / n as f64 - report.reconstruction_error_mean as f64).abs() < 1e-6);
        // One target per frame: steps from frame to frame, frame f keying
        // the first f at weight 1 (the closing key as the last frame).
        let per_frame = matches!(basis, BasisChoice::PerFrame);
        assert_eq!(report.steps, per_frame, "{basis:?}");
        if per_frame {
            for (f, w) in read.iter().enumerate() {
                let f = f.min(frames.len() - 1);
                for (t, &x) in w.iter().enumerate() {
                    assert_eq!(x, if t < f { 1.0 } else { 0.0 }, "key {f}, target {t}");
                }
            }
        }
        // The normals every frame decodes to: within a few degrees of the
        // uncompressed file's (bytes hold 1/127; steps do not add up their
        // rounding).
        let plain = Glb::read(&dir.join("plain.glb"));
        let normal_targets: Vec<Vec<[f64; 3]>> = prim["targets"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| decode_quantised(&json, &bin, at(&t["NORMAL"])))
            .collect();
        let mut worst = 0.0f64;
        for (f, w) in read.iter().enumerate().take(frames.len()) {
            for (i, &v) in original.iter().enumerate() {
                let add = |n: &mut [f64; 3], w: f32, d: [f64; 3]| {
                    n.iter_mut().zip(d).for_each(|(c, d)| *c += w as f64 * d);
                };
                let mut ours = normals[i];
                for (&w, t) in w.iter().zip(&normal_targets) {
                    add(&mut ours, w, t[i]);
                }
                let mut theirs = plain.normals.as_ref().unwrap()[v].map(f64::from);
                for (&w, t) in plain.weights[f].iter().zip(&plain.normal_targets) {
                    add(&mut theirs, w, t.as_ref().unwrap()[v].map(f64::from));
                }
                let unit = |n: [f64; 3]| {
                    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                    n.map(|c| c / l)
                };
                let (a, b) = (unit(ours), unit(theirs));
                let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0);
                worst = worst.max(cos.acos().to_degrees());
            }
        }
        assert!(worst < 3.0, "{basis:?}: a normal {worst:.2}° off");
    }
    // A single frame: no animation, the base mesh quantised alone.
    let still = DynamicMesh {
        base: mesh.base.clone(),
        frames: mesh.frames.to_vec().unwrap()[..1].to_vec().into(),
        reference: 0,
    };
    let report = write_dynamic_glb(
        &dir.join("still.glb"),
        &still,
        &GltfExportOptions {
            compress: true,
            ..Default::default()
        },
        Progress::none(),
    )
    .unwrap();
    assert_eq!(report.targets, 0);
    assert!(
        report.compressed
            && report.reconstruction_error_max > 0.0
            && report.reconstruction_error_max < 0.0005,
        "{report:?}"
    );
}

impl Glb {
    /// The keyed weight vectors of the file's one animation (stored uncompressed).
    fn read_weights(json: &serde_json::Value, bin: &[u8]) -> Vec<Vec<f32>> {
        let sampler = &json["animations"][0]["samplers"][0];
        let floats = |a: &serde_json::Value| -> Vec<f32> {
            let acc = &json["accessors"][a.as_u64().unwrap() as usize];
            let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
            let count = acc["count"].as_u64().unwrap() as usize;
            let ext = &view["extensions"]["EXT_meshopt_compression"];
            if ext.is_null() {
                assert_eq!(view["buffer"], 0);
                let off = view["byteOffset"].as_u64().unwrap_or(0) as usize;
                (0..count).map(|i| f32_at(bin, off + 4 * i)).collect()
            } else {
                let (off, len) = (
                    ext["byteOffset"].as_u64().unwrap() as usize,
                    ext["byteLength"].as_u64().unwrap() as usize,
                );
                assert_eq!(
                    (
                        ext["mode"].as_str(),
                        ext["byteStride"].as_u64(),
                        ext["count"].as_u64()
                    ),
                    (Some("ATTRIBUTES"), Some(4), Some(count as u64))
                );
                meshopt::decode_vertex_buffer::<f32>(&bin[off..off + len], count).unwrap()
            }
        };
        let times = floats(&sampler["input"]);
        let weights = floats(&sampler["output"]);
        weights
            .chunks(weights.len() / times.len())
            .map(|c| c.to_vec())
            .collect()
    }
}

/// A writer that takes `room` bytes, then fails.
struct Full {
    room: usize,
    taken: Vec<u8>,
}

impl std::io::Write for Full {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.room == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                "no room",
            ));
        }
        let n = buf.len().min(self.room);
        self.room -= n;
        self.taken.extend_from_slice(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Into any writer, the bytes the file would hold; a writer that fails is
/// an error of its own kind (no path to name), whatever part it fails in.
#[test]
fn glb_into_a_writer_is_the_file_and_its_failure_is_reported() {
    use voltrack::export::gltf::write_dynamic_glb_to;
    let dir = Scratch::new("export", "writer");
    let mesh = bending_bar();
    for opts in [
        options(BasisChoice::PerFrame),
        GltfExportOptions {
            compress: true,
            ..Default::default()
        },
    ] {
        let path = dir.join("bar.glb");
        let report = write_dynamic_glb(&path, &mesh, &opts, Progress::none()).unwrap();
        let mut bytes = Vec::new();
        let streamed = write_dynamic_glb_to(&mut bytes, &mesh, &opts, Progress::none()).unwrap();
        assert_eq!(bytes, std::fs::read(&path).unwrap());
        assert_eq!(streamed, report);
        for room in [0, 11, 20, bytes.len() / 2, bytes.len() - 1] {
            let mut full = Full {
                room,
                taken: Vec::new(),
            };
            let err = write_dynamic_glb_to(&mut full, &mesh, &opts, Progress::none()).unwrap_err();
            assert!(
                matches!(err, voltrack::Error::WriteStream(_)),
                "{room}: {err}"
            );
            assert!(err.to_string().contains("no room"), "{err}");
            assert_eq!(full.taken[..], bytes[..room]);
        }
    }
}
