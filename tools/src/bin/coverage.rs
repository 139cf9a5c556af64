//! The coverage check ([`voltrack::metrics::coverage`]) of trajectories
//! written by `voltrack track`, per frame, at one or more reach factors:
//! `cargo run --release -p voltrack-tools --bin coverage -- centers.exr INPUT [REACH...]`.

use voltrack::params::CoverageParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        return Err("usage: coverage centers.exr INPUT [REACH...]".into());
    }
    let centers = std::path::Path::new(&args[1]);
    let (traj, attrs) = voltrack::io::exr::read_trajectories_exr(centers)?;
    let resolution = voltrack::pipeline::resolution_of(&attrs, centers)?;
    let files = voltrack::io::FrameFiles::discover(&[args[2].clone().into()])?;
    let seq = voltrack::voxel::voxelize_sequence(
        &files,
        &voltrack::voxel::VoxelParams {
            resolution,
            ..Default::default()
        },
        Default::default(),
    )?;
    let reaches: Vec<f64> = if args.len() > 3 {
        args[3..]
            .iter()
            .map(|s| s.parse())
            .collect::<Result<_, _>>()?
    } else {
        vec![CoverageParams::default().reach]
    };
    for reach in reaches {
        let c = voltrack::metrics::coverage(
            &traj,
            &seq,
            &CoverageParams {
                reach,
                ..Default::default()
            },
        )?;
        println!(
            "reach {reach}: {:.1} voxels per cell; flagged {:?}",
            c.cell_voxels, c.flagged
        );
        for (f, x) in c.frames.iter().enumerate() {
            println!(
                "{f:5} unreached {:7}  lost {:7} ({:.3} %)  largest region {:5.1} cells  farthest {:.2} x reach",
                x.unreached,
                x.lost,
                100.0 * x.lost_share,
                x.largest_region as f64 / c.cell_voxels,
                x.farthest
            );
        }
    }
    Ok(())
}
