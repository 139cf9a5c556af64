//! How well tracking and the deformed mesh follow a known rigid motion: the
//! pentagonal prism of `../shared/data`, whose 10 vertices (fixed
//! connectivity) give the true motion of every frame.
//!
//! `cargo run --release -p voltrack-tools --bin rigid_check -- centers` tracks 200 centers
//! on `pentagonal_prism` and measures, per frame, the distance of every center
//! from where the prism's rigid motion carries its frame-0 position (issue 3).
//! `... -- vertices` converts `pent_tvm` (the prism re-meshed per frame) at
//! default settings and measures the same for every vertex of the dynamic
//! mesh (issue 5). Distances are in voxels of the grid used.
//! `VOLTRACK_R`, `VOLTRACK_CENTERS` override the resolution and center count;
//! `VOLTRACK_THRESHOLD`, `VOLTRACK_CONFORM_STIFFNESS`,
//! `VOLTRACK_CONFORM_BEND_STRAIN` and `VOLTRACK_CONFORM_JOINT_STRAIN` the
//! tracking threshold and the conform stage's stiffness, bend strain and
//! joint strain (`--threshold`, `--conform-stiffness`,
//! `--conform-bend-strain`, `--conform-joint-strain`).

use voltrack::math::{Point3, Real};
use voltrack::model::{fit_rigid, Rigid};
use voltrack::params::{ConformParams, DeformParams, RefineParams, TrackParams};
use voltrack::voxel::VoxelParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mode = std::env::args().nth(1).unwrap_or_else(|| "centers".into());
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data");
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let resolution = env("VOLTRACK_R", 256);
    let prism = voltrack::io::discover_frames(&[format!("{data}/pentagonal_prism").into()])?;
    let truth: Vec<Vec<Point3>> = prism
        .iter()
        .map(|p| voltrack::io::read_mesh(p).map(|m| m.positions))
        .collect::<Result<_, _>>()?;
    let motions: Vec<Rigid> = truth
        .iter()
        .map(|f| fit_rigid(&truth[0], f, (0..f.len()).map(|i| (i, 1.0))))
        .collect();
    let fit_residual = truth
        .iter()
        .zip(&motions)
        .flat_map(|(f, m)| {
            truth[0]
                .iter()
                .zip(f)
                .map(move |(p, q)| (m.apply(p) - q).norm())
        })
        .fold(0.0, Real::max);
    let voxel = VoxelParams {
        resolution,
        ..Default::default()
    };
    let (frames, voxel_size): (Vec<Vec<Point3>>, Real) = match mode.as_str() {
        "centers" => {
            let seq = voltrack::voxel::voxelize_sequence(
                &voltrack::io::FrameFiles::new(prism.to_vec()),
                &voxel,
                Default::default(),
            )?;
            let params = TrackParams {
                centers: env("VOLTRACK_CENTERS", 200),
                lloyd_iterations: env("VOLTRACK_LLOYD", TrackParams::default().lloyd_iterations),
                ..Default::default()
            };
            let tracked = voltrack::track::track(&seq, &params, Default::default())?;
            let t = &tracked.trajectories;
            (
                (0..t.frames).map(|f| t.frame(f).to_vec()).collect(),
                seq.grid.voxel_size,
            )
        }
        "vertices" => {
            let inputs = [format!("{data}/pent_tvm").into()];
            let real = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<Real>().ok());
            let defaults = TrackParams::default();
            let track = TrackParams {
                centers: env("VOLTRACK_CENTERS", 1000),
                threshold: real("VOLTRACK_THRESHOLD").unwrap_or(defaults.threshold),
                ..defaults
            };
            let defaults = ConformParams::default();
            let conform = ConformParams {
                stiffness: real("VOLTRACK_CONFORM_STIFFNESS").unwrap_or(defaults.stiffness),
                bend_strain: real("VOLTRACK_CONFORM_BEND_STRAIN").unwrap_or(defaults.bend_strain),
                joint_strain: real("VOLTRACK_CONFORM_JOINT_STRAIN")
                    .unwrap_or(defaults.joint_strain),
                ..defaults
            };
            let conv = voltrack::pipeline::convert(
                &voltrack::io::FrameFiles::discover(&inputs)?,
                &voltrack::pipeline::ConvertOptions {
                    voxel: voxel.clone(),
                    track: track.clone(),
                    refine: Some(RefineParams::default()),
                    deform: DeformParams::default(),
                    conform: conform.clone(),
                    checkpoint: None,
                    ..Default::default()
                },
                Default::default(),
            )?;
            (conv.mesh.frames.to_vec()?, conv.sequence.grid.voxel_size)
        }
        other => return Err(format!("unknown mode {other}: centers or vertices").into()),
    };
    if frames.len() != motions.len() {
        return Err(format!(
            "{} frames tracked, {} in the ground truth",
            frames.len(),
            motions.len()
        )
        .into());
    }
    let mut all = Vec::new();
    let mut worst_frame = (0, 0.0);
    for (f, (points, m)) in frames.iter().zip(&motions).enumerate() {
        let errors: Vec<Real> = frames[0]
            .iter()
            .zip(points)
            .map(|(p0, p)| (m.apply(p0) - p).norm() / voxel_size)
            .collect();
        let max = errors.iter().copied().fold(0.0, Real::max);
        if std::env::var_os("VOLTRACK_VERBOSE").is_some() {
            println!("frame {f}: max {max:.3} voxels");
        }
        if max > worst_frame.1 {
            worst_frame = (f, max);
        }
        all.extend(errors);
    }
    // Split the error: the centers' own best rigid motion against the truth
    // (a collective slide) and the centers' deviation from their own motion.
    let (mut collective, mut own) = (0.0, 0.0);
    for (points, m) in frames.iter().zip(&motions) {
        let fitted = fit_rigid(&frames[0], points, (0..points.len()).map(|i| (i, 1.0)));
        for (p0, p) in frames[0].iter().zip(points) {
            collective = Real::max(
                collective,
                (fitted.apply(p0) - m.apply(p0)).norm() / voxel_size,
            );
            own = Real::max(own, (fitted.apply(p0) - p).norm() / voxel_size);
        }
    }
    all.sort_by(Real::total_cmp);
    let mean = all.iter().sum::<Real>() / all.len() as Real;
    let p95 = all[(0.95 * (all.len() - 1) as Real) as usize];
    println!(
        "{mode}: {} points × {} frames at R = {resolution} (voxel {voxel_size:.5}); truth is rigid to {:.1e} voxels",
        frames[0].len(),
        frames.len(),
        fit_residual / voxel_size
    );
    println!(
        "distance from the rigid motion in voxels: mean {mean:.3}, p95 {p95:.3}, max {:.3} (frame {}); {} of {} within 1 voxel, {} within 2",
        all.last().unwrap(),
        worst_frame.0,
        all.iter().filter(|&&d| d <= 1.0).count(),
        all.len(),
        all.iter().filter(|&&d| d <= 2.0).count()
    );
    println!("largest collective error (the points' own rigid motion against the truth) {collective:.3} voxels, largest deviation from their own rigid motion {own:.3}");
    Ok(())
}
