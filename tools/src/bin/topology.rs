//! Each frame's parts and tunnels, and the reference frame
//! `--reference auto` chooses by them:
//! `cargo run --release -p voltrack-tools --bin topology -- INPUT [RESOLUTION [CENTERS]]`.

use voltrack::params::TrackParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 2 {
        return Err("usage: topology INPUT [RESOLUTION [CENTERS]]".into());
    }
    let resolution = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(256);
    let centers = args.get(3).map(|s| s.parse()).transpose()?;
    let files = voltrack::io::FrameFiles::discover(&[args[1].clone().into()])?;
    let seq = voltrack::voxel::voxelize_sequence(
        &files,
        &voltrack::voxel::VoxelParams {
            resolution,
            ..Default::default()
        },
        Default::default(),
    )?;
    let params = TrackParams {
        centers: centers.unwrap_or(TrackParams::default().centers),
        ..Default::default()
    };
    let clock = std::time::Instant::now();
    let choice = voltrack::track::choose_reference(&seq, &params, false)?;
    let seconds = clock.elapsed().as_secs_f64();
    for (f, t) in choice.topology.iter().enumerate() {
        println!(
            "{f}\t{}\tparts {}\ttunnels {}\tspecks {}",
            seq.names[f], t.parts, t.tunnels, t.specks
        );
    }
    let central = voltrack::deform::segments::most_separate_near_middle(
        &choice.topology,
        0..choice.topology.len(),
    );
    println!("most separate nearest the middle: frame {central}");
    println!(
        "reference: frame {} ({}), {} [{seconds:.2} s for {} frames]",
        choice.frame,
        seq.names[choice.frame],
        choice.why,
        seq.frames.len()
    );
    Ok(())
}
