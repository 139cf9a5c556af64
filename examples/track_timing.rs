//! Seconds per frame of forward tracking on a shared sequence.
//! `cargo run --release --example track_timing -- DIR [RESOLUTION] [CENTERS] [FRAMES]`
use voltrack::params::TrackParams;
use voltrack::voxel::{voxelize_sequence, VoxelParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).cloned().unwrap_or_else(|| "../shared/data/crane_tvm".into());
    let r: usize = args.get(2).map_or(256, |s| s.parse().unwrap());
    let n: usize = args.get(3).map_or(1000, |s| s.parse().unwrap());
    let frames: usize = args.get(4).map_or(usize::MAX, |s| s.parse().unwrap());
    let mut paths = voltrack::io::discover_frames(&[dir.into()])?;
    paths.truncate(frames);
    let seq = voxelize_sequence(&paths, &VoxelParams { resolution: r, ..Default::default() }, Default::default())?;
    let occ: usize = seq.frames.iter().map(|f| f.len()).sum::<usize>() / seq.frames.len();
    println!("{} frames, R={r}, grid {:?}, {occ} occupied voxels/frame, voxelised in {:.2} s", seq.frames.len(), seq.grid.dims, seq.voxelize_seconds);
    let params = TrackParams { centers: n, ..Default::default() };
    let res = voltrack::track::track(&seq, &params, Default::default())?;
    let t = &res.timings;
    let tracked = &t[1..];
    let total: f64 = tracked.iter().map(|x| x.total).sum();
    let sum = |f: fn(&voltrack::track::FrameTiming) -> f64| tracked.iter().map(f).sum::<f64>();
    let iters: usize = tracked.iter().map(|x| x.iterations).sum();
    println!("lloyd (frame 0): {:.2} s", t[0].total);
    println!(
        "tracking: {:.3} s/frame ({} frames), {:.1} iterations/frame; assign {:.3}, fit {:.3}, affinity {:.3} s/frame",
        total / tracked.len() as f64,
        tracked.len(),
        iters as f64 / tracked.len() as f64,
        sum(|x| x.assign) / tracked.len() as f64,
        sum(|x| x.fit) / tracked.len() as f64,
        sum(|x| x.affinity) / tracked.len() as f64
    );
    Ok(())
}
