//! Library use: frames from a source of your own (here a sphere generated
//! on demand, as a capture server or a decoder would hand them over, one at
//! a time), converted in memory and encoded as GLB bytes.
//!
//! `cargo run --release --example own_source -- out.glb` (the file is
//! optional: without it the bytes are only counted).

use voltrack::export::gltf::{write_dynamic_glb_to, GltfExportOptions};
use voltrack::math::{Point3, Real};
use voltrack::pipeline::{convert, ConvertOptions};
use voltrack::{params::TrackParams, voxel::VoxelParams};
use voltrack::{Frame, FrameSource, TriangleMesh};

/// A sphere squashed and moved a little more in every frame, made when a
/// frame is asked for: nothing is held in memory between frames.
struct Bouncing {
    frames: usize,
}

impl FrameSource for Bouncing {
    fn len(&self) -> usize {
        self.frames
    }

    fn name(&self, f: usize) -> String {
        format!("bounce frame {f}")
    }

    fn frame(&self, f: usize) -> voltrack::Result<Frame> {
        let t = f as Real / self.frames as Real;
        let (rings, segments) = (12, 24);
        let mut positions = vec![Point3::new(0.0, 1.0, 0.0)];
        for r in 1..rings {
            let theta = std::f64::consts::PI * r as Real / rings as Real;
            for s in 0..segments {
                let phi = std::f64::consts::TAU * s as Real / segments as Real;
                positions.push(Point3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ));
            }
        }
        positions.push(Point3::new(0.0, -1.0, 0.0));
        // Squashed by up to a third and moved along x.
        let squash = 1.0 - 0.33 * (std::f64::consts::PI * t).sin();
        for p in &mut positions {
            *p = Point3::new(
                p.x / squash.sqrt() + 2.0 * t,
                p.y * squash,
                p.z / squash.sqrt(),
            );
        }
        let ring = |r: usize, s: usize| (1 + r * segments + s % segments) as u32;
        let last = positions.len() as u32 - 1;
        let mut triangles = Vec::new();
        for s in 0..segments {
            triangles.push([0, ring(0, s + 1), ring(0, s)]);
            triangles.push([last, ring(rings - 2, s), ring(rings - 2, s + 1)]);
            for r in 0..rings - 2 {
                triangles.push([ring(r, s), ring(r, s + 1), ring(r + 1, s)]);
                triangles.push([ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s)]);
            }
        }
        Ok(Frame::Mesh(TriangleMesh {
            positions,
            triangles,
            ..Default::default()
        }))
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let source = Bouncing { frames: 12 };
    let options = ConvertOptions {
        voxel: VoxelParams {
            resolution: 48,
            ..Default::default()
        },
        track: TrackParams {
            centers: 150,
            ..Default::default()
        },
        ..Default::default()
    };
    let result = convert(&source, &options, Default::default())?;
    let mut glb = Vec::new();
    let report = write_dynamic_glb_to(
        &mut glb,
        &result.mesh,
        &GltfExportOptions::default(),
        Default::default(),
    )?;
    println!(
        "{} frames, {} vertices: {} bytes of GLB, {} morph targets",
        result.mesh.frames.len(),
        result.mesh.base.positions.len(),
        glb.len(),
        report.targets
    );
    if let Some(path) = std::env::args_os().nth(1) {
        std::fs::write(&path, &glb)?;
        println!("wrote {}", std::path::Path::new(&path).display());
    }
    Ok(())
}
