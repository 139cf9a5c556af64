//! Writes a vertex-animation texture of a long synthetic sequence (a
//! 6,200-vertex torus under a travelling wave, the frames kept in a
//! temporary file as a long conversion's are), to measure what exporting
//! it costs: `/usr/bin/time -v cargo run --release -p voltrack-tools --bin vat_memory --
//! 1044 /tmp/vat/anim.exr` (frames, output; the .glb and .json go beside it).

use voltrack::export::vat::{write_vat, VatOptions};
use voltrack::math::{Point3, Real, Vector3};
use voltrack::model::DynamicMesh;
use voltrack::model::PositionFrames;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [frames, out] = args.as_slice() else {
        return Err("usage: vat_memory FRAMES OUT.exr".into());
    };
    let count: usize = frames.parse()?;
    let base = voltrack::fixtures::torus(Point3::origin(), 1.0, 0.3, 124, 50);
    let mut frames = PositionFrames::new(base.positions.len(), count, 0)?;
    for g in 0..count {
        let wave = |p: &Point3| Vector3::new(0.0, 0.0, 0.1 * (3.0 * p.x + 0.1 * g as Real).sin());
        frames.push(base.positions.iter().map(|p| p + wave(p)).collect())?;
    }
    let mesh = DynamicMesh {
        base,
        frames,
        reference: 0,
    };
    let report = write_vat(out.as_ref(), &mesh, &VatOptions::default())?;
    println!(
        "{} vertices, {count} frames: texture, mesh, sidecar {:?} bytes",
        mesh.base.positions.len(),
        report.bytes
    );
    Ok(())
}
