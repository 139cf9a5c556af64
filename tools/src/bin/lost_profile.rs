//! Converts sequences at the defaults and prints, per frame, what the
//! lost-part warnings look at (`voltrack::metrics::lost_parts`): the volume
//! no tracked cell reaches, and the largest connected regions of the input
//! far from the result and of the result far from the input at several
//! distances. For checking the warnings' thresholds on sequences whose
//! parts are all kept (no frame may be warned of).
//!
//! `cargo run --release -p voltrack-tools --bin lost_profile -- DIR...`: one JSON line
//! per sequence on stdout. With `VOLTRACK_GLB_DIR=OUT`, each result is also
//! written as `OUT/NAME.glb` (NAME: the input folder's name) for
//! evaluate.py.

use voltrack::metrics::{fit::far_profile, Surface};
use voltrack::pipeline::{convert, ConvertOptions};

/// Distances (percent of the diagonal) the far regions are measured at.
const DISTANCES: [f64; 5] = [1.0, 1.5, 2.0, 3.0, 5.0];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for dir in std::env::args().skip(1) {
        let source = voltrack::io::FrameFiles::discover(&[dir.clone().into()])?;
        let conv = convert(&source, &ConvertOptions::default(), Default::default())?;
        let lost = conv.lost_parts();
        if let Ok(out) = std::env::var("VOLTRACK_GLB_DIR") {
            let name = std::path::Path::new(&dir)
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| "result".into());
            let path = std::path::Path::new(&out).join(format!("{name}.glb"));
            voltrack::export::gltf::write_dynamic_glb(
                &path,
                &conv.mesh,
                &Default::default(),
                Default::default(),
            )?;
        }
        let diagonal = conv.sequence.bounds.diagonal();
        let mut profile = Vec::new();
        for f in 0..conv.mesh.frames.len() {
            let positions = conv.mesh.frames.get(f)?;
            let input = voltrack::FrameSource::mesh(&source, f)?;
            let result = Surface {
                positions: &positions,
                triangles: &conv.mesh.base.triangles,
            };
            let inside = voltrack::metrics::fit::inside_volume(&conv.sequence, f);
            let regions = far_profile(
                result,
                Surface::from(&input),
                diagonal,
                &DISTANCES,
                Some(&inside),
            );
            profile.push(
                regions
                    .iter()
                    .map(|(i, r)| [i.share, i.farthest, r.share, r.farthest])
                    .collect::<Vec<_>>(),
            );
        }
        let line = serde_json::json!({
            "input": dir,
            "far_thresholds": DISTANCES,
            "far_profile": profile,
            "coverage": conv.coverage.frames.iter().map(|c| c.lost_share).collect::<Vec<_>>(),
            "flagged": lost.flagged,
            "warnings": lost.warnings().iter().map(|w| &w.message).collect::<Vec<_>>(),
        });
        println!("{line}");
    }
    Ok(())
}
