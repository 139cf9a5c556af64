//! Deforms the reference frame of a sequence (the first unless the
//! trajectories record another) by trajectories already tracked
//! (`voltrack track -o centers.exr`), to try deformation settings without
//! tracking again: `cargo run --release -p voltrack-tools --bin deform_from -- centers.exr
//! INPUT_DIR out.glb [neighbors]` (an output not ending in .glb is a
//! directory of OBJ files). `VOLTRACK_RHO_GP`, `VOLTRACK_RHO_GM`,
//! `VOLTRACK_MIN_AFFINITY` and `VOLTRACK_BLEND=linear` override the affinity
//! the mesh is bound with and the blending; `VOLTRACK_CONFORM_ITERATIONS`,
//! `_STIFFNESS`, `_POINT_WEIGHT`, `_MAX_DISTANCE`, `_NORMAL_COSINE`, `_BEND_STRAIN`, `_JOINT_STRAIN` and
//! `_LEAST_EDGE_WEIGHT` the fit
//! to the input surfaces; `VOLTRACK_MESH_MEMORY` (MiB) the positions kept in
//! memory before the frames go to a temporary file.

use voltrack::params::{Blending, ConformParams, DeformParams, RefineParams};
use voltrack::voxel::VoxelParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: deform_from CENTERS.exr INPUT OUT.glb [neighbors]".into());
    }
    let (traj, attrs) = voltrack::io::exr::read_trajectories_exr(args[0].as_ref())?;
    let resolution = voltrack::pipeline::resolution_of(&attrs, args[0].as_ref())?;
    let files = voltrack::io::FrameFiles::discover(&[args[1].clone().into()])?;
    let seq = voltrack::voxel::voxelize_sequence(
        &files,
        &VoxelParams {
            resolution,
            ..Default::default()
        },
        Default::default(),
    )?;
    let env = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<f64>().ok());
    let mut params = DeformParams::default();
    if let Some(k) = args.get(3) {
        params.neighbors = k.parse()?;
    }
    let mut refine = RefineParams::default();
    refine.rho_gp = env("VOLTRACK_RHO_GP").unwrap_or(refine.rho_gp);
    refine.rho_gm = env("VOLTRACK_RHO_GM").unwrap_or(refine.rho_gm);
    params.min_affinity = env("VOLTRACK_MIN_AFFINITY").unwrap_or(params.min_affinity);
    if let Some(mib) = env("VOLTRACK_MESH_MEMORY") {
        params.memory = (mib * (1 << 20) as f64) as usize;
    }
    if std::env::var("VOLTRACK_BLEND").is_ok_and(|b| b == "linear") {
        params.blending = Blending::Linear;
    }
    use voltrack::model::FrameSource;
    let reference = files.mesh(traj.reference)?;
    let mesh = voltrack::pipeline::deform_sequence(
        &reference,
        &traj,
        &seq,
        Some(&refine),
        &params,
        voltrack::Progress::none(),
    )?;
    let defaults = ConformParams::default();
    let conform = ConformParams {
        iterations: env("VOLTRACK_CONFORM_ITERATIONS").map_or(defaults.iterations, |i| i as usize),
        stiffness: env("VOLTRACK_CONFORM_STIFFNESS").unwrap_or(defaults.stiffness),
        point_weight: env("VOLTRACK_CONFORM_POINT_WEIGHT").unwrap_or(defaults.point_weight),
        max_distance: env("VOLTRACK_CONFORM_MAX_DISTANCE").unwrap_or(defaults.max_distance),
        min_normal_cosine: env("VOLTRACK_CONFORM_NORMAL_COSINE")
            .unwrap_or(defaults.min_normal_cosine),
        bend_strain: env("VOLTRACK_CONFORM_BEND_STRAIN").unwrap_or(defaults.bend_strain),
        joint_strain: env("VOLTRACK_CONFORM_JOINT_STRAIN").unwrap_or(defaults.joint_strain),
        least_edge_weight: env("VOLTRACK_CONFORM_LEAST_EDGE_WEIGHT")
            .unwrap_or(defaults.least_edge_weight),
        ..defaults
    };
    let mesh = voltrack::deform::conform(mesh, &files, &seq.bounds, &conform, Default::default())?;
    if args[2].ends_with(".glb") {
        let report = voltrack::export::gltf::write_dynamic_glb(
            args[2].as_ref(),
            &mesh,
            &Default::default(),
            Default::default(),
        )?;
        println!("wrote {} ({} targets)", args[2], report.targets);
    } else {
        let files = voltrack::export::obj::write_obj_sequence(
            args[2].as_ref(),
            &mesh,
            voltrack::model::DEFAULT_NAME,
        )?;
        println!("wrote {} OBJ files into {}", files.len(), args[2]);
    }
    Ok(())
}
