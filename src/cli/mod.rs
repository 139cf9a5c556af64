//! Command-line definitions and the glue from flags to library calls.

mod bars;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use voltrack::voxel::{voxelize_sequence, VoxelParams};

#[derive(Parser)]
#[command(name = "voltrack", version, about = "Time-varying meshes to dynamic meshes by volume tracking")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args)]
struct InputArgs {
    /// Frames: a directory, a pattern such as 'seq/frame_*.obj', or files in order
    #[arg(required = true, value_name = "INPUT")]
    input: Vec<PathBuf>,
    /// Voxels along the longest side of the sequence's bounding box
    #[arg(long, short = 'r', default_value_t = 256)]
    resolution: usize,
}

#[derive(Subcommand)]
enum Command {
    /// Voxelise every frame on one grid and write one .binvox per frame
    Voxelize {
        #[command(flatten)]
        input: InputArgs,
        /// Output directory
        #[arg(long, short = 'o')]
        output: PathBuf,
        /// Print a machine-readable summary on stdout
        #[arg(long)]
        json: bool,
    },
}

pub fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Voxelize { input, output, json } => voxelize(input, output, json),
    }
}

fn voxelize(input: InputArgs, output: PathBuf, json: bool) -> Result<()> {
    let paths = voltrack::io::discover_frames(&input.input)?;
    let params = VoxelParams { resolution: input.resolution, ..Default::default() };
    let bars = bars::Bars::new();
    let seq = voxelize_sequence(&paths, &params, bars.progress())?;
    let written = voltrack::export::write_binvox_frames(&seq, &output)?;
    bars.finish();
    let g = &seq.grid;
    if json {
        let frames: Vec<_> = seq
            .frames
            .iter()
            .zip(&paths)
            .zip(&written)
            .map(|((o, p), w)| serde_json::json!({"input": p, "output": w, "occupied": o.len()}))
            .collect();
        let summary = serde_json::json!({
            "frames": frames,
            "resolution": params.resolution,
            "grid": {"dims": g.dims, "origin": g.origin.coords.as_slice(), "voxel_size": g.voxel_size},
            "seconds": {"read": seq.read_seconds, "voxelize": seq.voxelize_seconds},
        });
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "grid {} x {} x {} voxels of {:.6} (origin {:.4} {:.4} {:.4})",
            g.dims[0], g.dims[1], g.dims[2], g.voxel_size, g.origin.x, g.origin.y, g.origin.z
        );
        for (o, w) in seq.frames.iter().zip(&written) {
            println!("{:>10} occupied  {}", o.len(), w.display());
        }
        println!(
            "{} frames: read {:.2} s, voxelised {:.2} s ({:.1} ms/frame)",
            seq.frames.len(),
            seq.read_seconds,
            seq.voxelize_seconds,
            1000.0 * seq.voxelize_seconds / seq.frames.len() as f64
        );
    }
    Ok(())
}
