//! Tracks takes of the generated family and measures how far their centers
//! are from where the take's truth moves them (each center follows the part
//! of the frame-0 vertex nearest to it), in voxels: the quick measure of a
//! change to the tracker, before the whole pipeline's (`cargo bench --bench
//! family`).
//!
//! `cargo run --release -p voltrack-tools --bin family_centers -- NAMES [FRAMES]`: NAMES
//! is `dev`, `held-out`, `all` or names, comma-separated; FRAMES cuts each
//! take short. One line per take: the mean and 95th percentile of the
//! centers' errors over all frames, the share of (frame, center) pairs off
//! by more than 10 voxels, and the worst part's median error in its worst
//! frame. `VOLTRACK_SEED`, `VOLTRACK_RESOLUTION`, `VOLTRACK_CENTERS`,
//! `VOLTRACK_REFINE=1` (refine before measuring), `VOLTRACK_FRAMES=1` (a
//! line per frame too), `VOLTRACK_THRESHOLD`, `VOLTRACK_CONVERGENCE_WINDOW`
//! (the tracker's `--threshold`, `--convergence-window`).

use voltrack::fixtures::family::{build, family, TakeSpec};
use voltrack::math::Real;
use voltrack::params::{RefineParams, TrackParams};
use voltrack::voxel::{voxelize_sequence, VoxelParams};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn median(v: &mut [Real]) -> Real {
    v.sort_by(Real::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let names = args.next().ok_or("usage: family_centers NAMES [FRAMES]")?;
    let frames: Option<usize> = args.next().map(|f| f.parse()).transpose()?;
    let chosen = |s: &TakeSpec| match names.as_str() {
        "all" => true,
        "dev" => !s.held_out,
        "held-out" => s.held_out,
        list => list.split(',').any(|n| s.name.starts_with(n)),
    };
    let mut totals = (0.0, 0.0, 0usize, 0usize);
    for mut spec in family().into_iter().filter(chosen) {
        if let Some(f) = frames {
            spec = TakeSpec {
                frames: f.min(spec.frames),
                ..spec
            };
        }
        let take = build(&spec);
        let voxel = VoxelParams {
            resolution: env("VOLTRACK_RESOLUTION").unwrap_or(256),
            ..Default::default()
        };
        let seq = voxelize_sequence(&take.meshes, &voxel, Default::default())?;
        let defaults = TrackParams::default();
        let params = TrackParams {
            seed: env("VOLTRACK_SEED").unwrap_or(0),
            centers: env("VOLTRACK_CENTERS").unwrap_or(1000),
            threshold: env("VOLTRACK_THRESHOLD").unwrap_or(defaults.threshold),
            convergence_window: env("VOLTRACK_CONVERGENCE_WINDOW")
                .unwrap_or(defaults.convergence_window),
            ..defaults
        };
        let clock = std::time::Instant::now();
        let tracked = voltrack::track::track(&seq, &params, Default::default())?;
        let seconds = clock.elapsed().as_secs_f64();
        let traj = if env::<u8>("VOLTRACK_REFINE") == Some(1) {
            voltrack::refine::refine(
                tracked.trajectories.clone(),
                &seq,
                &RefineParams::default(),
                Default::default(),
            )?
            .trajectories
        } else {
            tracked.trajectories.clone()
        };
        let first = &take.meshes[0].positions;
        let index = kiddo::ImmutableKdTree::<f64, 3>::new_from_slice(
            &first.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
        )
        .expect("a tree of the vertices");
        let labels: Vec<usize> = (0..traj.centers)
            .map(|i| {
                let c = traj.get(0, i);
                take.truth.labels[index
                    .query(&[c.x, c.y, c.z])
                    .nearest_one::<kiddo::SquaredEuclidean<f64>>()
                    .execute()
                    .item as usize] as usize
            })
            .collect();
        let voxel_size = seq.grid.voxel_size;
        let mut all = Vec::new();
        let mut worst = (0.0, 0, String::new());
        for f in 0..traj.frames {
            let mut by_part: Vec<Vec<Real>> = vec![Vec::new(); take.truth.parts.len()];
            for (i, &k) in labels.iter().enumerate() {
                let e = (traj.get(f, i) - take.truth.motions[f][k] * traj.get(0, i)).norm()
                    / voxel_size;
                all.push(e);
                by_part[k].push(e);
            }
            // A part is lost when most of its centers are, not one stray.
            let (k, e) = by_part
                .iter_mut()
                .enumerate()
                .filter(|(_, p)| !p.is_empty())
                .map(|(k, p)| (k, median(p)))
                .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
            if e > worst.0 {
                worst = (e, f, take.truth.parts[k].clone());
            }
            if env::<u8>("VOLTRACK_FRAMES") == Some(1) {
                let row = &all[all.len() - traj.centers..];
                let t = &tracked.timings[f];
                let empty = tracked.cell_counts[f].iter().filter(|&&n| n == 0).count();
                if let Ok(part) = std::env::var("VOLTRACK_PART") {
                    let k = take
                        .truth
                        .parts
                        .iter()
                        .position(|p| *p == part)
                        .expect("a part of the take");
                    let mine: Vec<usize> = (0..traj.centers).filter(|&i| labels[i] == k).collect();
                    let errors: Vec<String> = mine
                        .iter()
                        .map(|&i| {
                            format!(
                                "{:.1}",
                                (traj.get(f, i) - take.truth.motions[f][k] * traj.get(0, i)).norm()
                                    / voxel_size
                            )
                        })
                        .collect();
                    let counts: Vec<u32> =
                        mine.iter().map(|&i| tracked.cell_counts[f][i]).collect();
                    println!("        {part}: errors {errors:?} cells {counts:?}");
                }
                println!("  {f:4} mean {:6.2}  >10: {:4}  empty cells {empty:3}  worst {:<16} median {e:6.2}  {:?} {} it", row.iter().sum::<Real>() / row.len() as Real, row.iter().filter(|&&e| e > 10.0).count(), take.truth.parts[k], t.kept_guess, t.iterations);
            }
        }
        let mean = all.iter().sum::<Real>() / all.len() as Real;
        let strays = all.iter().filter(|&&e| e > 10.0).count();
        all.sort_by(Real::total_cmp);
        let p95 = all[all.len() * 95 / 100];
        println!(
            "{:<18} {:>3} frames  mean {mean:6.2}  p95 {p95:6.2}  >10 voxels {:5.2} %  worst part {} median {:.1} in frame {}  ({seconds:.1} s)",
            spec.name,
            traj.frames,
            100.0 * strays as Real / all.len() as Real,
            worst.2,
            worst.0,
            worst.1
        );
        totals.0 += mean;
        totals.1 += 100.0 * strays as Real / all.len() as Real;
        totals.2 += 1;
        totals.3 += (worst.0 > 10.0) as usize;
    }
    let n = totals.2.max(1) as Real;
    println!("ALL {} takes: mean of means {:.3}, mean stray share {:.3} %, {} takes with a part's median off by more than 10 voxels", totals.2, totals.0 / n, totals.1 / n, totals.3);
    Ok(())
}
