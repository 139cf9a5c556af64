//! How far the voxeliser's ray vote is from the generalised winding number
//! (GWN, threshold 0.5, brute force over every triangle) on a real capture.
//!
//! `cargo run --release -p voltrack-tools --bin gwn_agreement -- [DIR] [FRAME]` voxelises
//! the sequence in DIR (default `../shared/data/dancer`) on its common grid at
//! R = 256 (`VOLTRACK_R` to change), then evaluates the GWN at the center of
//! every voxel of frame FRAME's bounding box (plus one voxel around it) and
//! counts the voxels where the two classifications differ.
//! `VOLTRACK_GWN_STRIDE=s` evaluates only every s-th voxel per axis, for a
//! quick estimate. This takes minutes: O(voxels × triangles).

use rayon::prelude::*;
use std::time::Instant;
use voltrack::math::Real;
use voltrack::voxel::{voxelize, voxelize_sequence, VoxelParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/dancer").into());
    let frame: usize = args.next().map(|s| s.parse()).transpose()?.unwrap_or(0);
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (resolution, stride) = (env("VOLTRACK_R", 256), env("VOLTRACK_GWN_STRIDE", 1).max(1));
    let paths = voltrack::io::discover_frames(&[dir.clone().into()])?;
    let seq = voxelize_sequence(
        &voltrack::io::FrameFiles::new(paths.to_vec()),
        &VoxelParams {
            resolution,
            ..Default::default()
        },
        Default::default(),
    )?;
    let mesh = voltrack::io::read_mesh(&paths[frame])?;
    let grid = &seq.grid;
    let occupied = voxelize(&mesh, grid);
    assert_eq!(
        occupied.indices,
        seq.frames[frame].indices(),
        "frame voxelised alone differs from the sequence"
    );

    // Triangles as flat coordinate arrays: the inner loop is all that matters.
    let tris: Vec<[[Real; 3]; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.positions[i as usize].coords.into()))
        .collect();
    let gwn = |p: [Real; 3]| -> Real {
        let mut total = 0.0;
        for t in &tris {
            let [a, b, c] = t.map(|v| [v[0] - p[0], v[1] - p[1], v[2] - p[2]]);
            let dot = |u: [Real; 3], v: [Real; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
            let (la, lb, lc) = (dot(a, a).sqrt(), dot(b, b).sqrt(), dot(c, c).sqrt());
            let bxc = [
                b[1] * c[2] - b[2] * c[1],
                b[2] * c[0] - b[0] * c[2],
                b[0] * c[1] - b[1] * c[0],
            ];
            let div = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
            total += 2.0 * dot(a, bxc).atan2(div);
        }
        total / (4.0 * std::f64::consts::PI)
    };

    let bounds = mesh.bounding_box();
    let lo = grid
        .to_grid(&bounds.min)
        .map(|c| (c.floor() as i64 - 1).max(0) as usize);
    let hi = grid.to_grid(&bounds.max);
    let hi: Vec<usize> = (0..3)
        .map(|k| ((hi[k].ceil() as i64 + 1).max(0) as usize).min(grid.dims[k]))
        .collect();
    let axis = |k: usize| (lo[k]..hi[k]).step_by(stride).collect::<Vec<_>>();
    let (xs, ys, zs) = (axis(0), axis(1), axis(2));
    let clock = Instant::now();
    // Per z slice: (evaluated, occupied, occupied but GWN < 0.5, empty but GWN ≥ 0.5).
    let counts: Vec<[usize; 4]> = zs
        .par_iter()
        .map(|&z| {
            let mut c = [0usize; 4];
            for &y in &ys {
                for &x in &xs {
                    let index = grid.linear_index([x, y, z]);
                    let inside = gwn(grid.voxel_center(index).coords.into()) >= 0.5;
                    let occ = occupied.contains(index as u32);
                    c[0] += 1;
                    c[1] += occ as usize;
                    c[2] += (occ && !inside) as usize;
                    c[3] += (!occ && inside) as usize;
                }
            }
            c
        })
        .collect();
    let total = counts.iter().fold([0usize; 4], |s, c| {
        [s[0] + c[0], s[1] + c[1], s[2] + c[2], s[3] + c[3]]
    });
    let seconds = clock.elapsed().as_secs_f64();
    println!(
        "{} frame {frame} ({} triangles), R = {resolution}, grid {:?}, stride {stride}",
        paths[frame].display(),
        tris.len(),
        grid.dims
    );
    println!(
        "evaluated {} voxels of the frame's bounding box ({} occupied) in {seconds:.0} s",
        total[0], total[1]
    );
    println!(
        "disagreements: {} occupied with GWN < 0.5, {} empty with GWN >= 0.5: {} in all = {:.3} % of the occupied voxels",
        total[2],
        total[3],
        total[2] + total[3],
        100.0 * (total[2] + total[3]) as f64 / total[1].max(1) as f64
    );
    Ok(())
}
