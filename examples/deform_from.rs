//! Deforms the first frame of a sequence by trajectories already tracked
//! (`voltrack track -o centers.exr`), to try deformation settings without
//! tracking again: `cargo run --release --example deform_from -- centers.exr
//! INPUT_DIR out.glb [neighbors]`.

use voltrack::params::DeformParams;
use voltrack::voxel::VoxelParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: deform_from CENTERS.exr INPUT OUT.glb [neighbors]".into());
    }
    let (traj, attrs) = voltrack::io::exr::read_trajectories_exr(args[0].as_ref())?;
    let resolution = voltrack::pipeline::resolution_of(&attrs, args[0].as_ref())?;
    let seq = voltrack::pipeline::load(&[args[1].clone().into()], &VoxelParams { resolution, ..Default::default() }, Default::default())?;
    let mut params = DeformParams::default();
    if let Some(k) = args.get(3) {
        params.neighbors = k.parse()?;
    }
    let first = seq.first_mesh.as_ref().ok_or("no mesh")?;
    let mesh = voltrack::pipeline::deform_sequence(first, &traj, &seq, None, &params)?;
    let report = voltrack::export::gltf::write_dynamic_glb(args[2].as_ref(), &mesh, &Default::default())?;
    println!("wrote {} ({} targets)", args[2], report.targets);
    Ok(())
}
