//! Issue 47's generated takes of a ball and a slab whose surfaces merge and
//! part, converted (segments on, the reference chosen) and measured against
//! their truth, in % of the diagonal:
//! `cargo run --release -p voltrack-tools --bin ball_takes -- [RESOLUTION [CENTERS [SEED]]]`
//! (the defaults of `voltrack convert` without arguments).

use voltrack::params::TrackParams;
use voltrack::pipeline::ConvertOptions;
use voltrack::voxel::VoxelParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |k: usize| args.get(k).map(|s| s.parse::<u64>()).transpose();
    let mut options = ConvertOptions {
        ..Default::default()
    };
    options.voxel = VoxelParams {
        resolution: arg(0)?.map_or(options.voxel.resolution, |r| r as usize),
        ..options.voxel
    };
    options.track = TrackParams {
        centers: arg(1)?.map_or(options.track.centers, |n| n as usize),
        seed: arg(2)?.unwrap_or(options.track.seed),
        ..options.track
    };
    println!(
        "resolution {}, {} centers, seed {}",
        options.voxel.resolution, options.track.centers, options.track.seed
    );
    for take in voltrack::fixtures::ball_takes() {
        let input = take.meshes();
        let clock = std::time::Instant::now();
        let conv = voltrack::pipeline::convert(&input, &options, Default::default())?;
        let seconds = clock.elapsed().as_secs_f64();
        let result = conv.mesh.frames.to_vec()?;
        let s = take.score(&input, &conv.segments, &result);
        let segments: Vec<String> = conv.segments.iter().map(ToString::to_string).collect();
        println!(
            "{:<8} mean {:.3} p95 {:.3} max {:.3}  lost {:?}  segments {}  tracked from {}  {seconds:.1} s",
            take.name,
            s.mean,
            s.p95,
            s.max,
            s.lost,
            segments.join(", "),
            conv.trajectories.reference
        );
        println!(
            "         worst part per frame {:.2?}",
            s.worst_part.iter().map(|w| w.1).collect::<Vec<_>>()
        );
    }
    Ok(())
}
