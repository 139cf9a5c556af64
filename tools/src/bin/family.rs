//! Writes the generated family of takes (`voltrack::fixtures::family`) as
//! OBJ sequences, each with a `gt.npz` that `../shared/tools/evaluate.py`
//! reads (`traj`, `ambiguous`, `label`), and prints what each take is.
//!
//! `cargo run --release -p voltrack-tools --bin family -- DIR [NAME...]` (every take when
//! no name is given; a name may be a prefix).

use std::io::Write;
use voltrack::fixtures::family::{build, family};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = std::path::PathBuf::from(args.next().ok_or("usage: family DIR [NAME...]")?);
    let names: Vec<String> = args.collect();
    for spec in family()
        .into_iter()
        .filter(|s| names.is_empty() || names.iter().any(|n| s.name.starts_with(n.as_str())))
    {
        let clock = std::time::Instant::now();
        let take = build(&spec);
        let out = dir.join(spec.name);
        std::fs::create_dir_all(&out)?;
        for (f, m) in take.meshes.iter().enumerate() {
            let mut obj = Vec::new();
            voltrack::export::obj::write_obj(&mut obj, m, &m.positions)?;
            std::fs::write(out.join(format!("frame_{f:04}.obj")), obj)?;
        }
        let first = &take.meshes[0].positions;
        let traj: Vec<f32> = (0..take.meshes.len())
            .flat_map(|f| take.truth.frame(f, first))
            .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        let v = first.len();
        let npz = npz(&[
            (
                "traj",
                npy(
                    "<f4",
                    &[take.meshes.len(), v, 3],
                    &traj
                        .iter()
                        .flat_map(|x| x.to_le_bytes())
                        .collect::<Vec<u8>>(),
                ),
            ),
            (
                "ambiguous",
                npy(
                    "|b1",
                    &[v],
                    &take
                        .truth
                        .ambiguous
                        .iter()
                        .map(|&a| a as u8)
                        .collect::<Vec<u8>>(),
                ),
            ),
            (
                "label",
                npy(
                    "<i4",
                    &[v],
                    &take
                        .truth
                        .labels
                        .iter()
                        .flat_map(|&l| (l as i32).to_le_bytes())
                        .collect::<Vec<u8>>(),
                ),
            ),
        ]);
        std::fs::write(out.join("gt.npz"), npz)?;
        let vertices: Vec<usize> = take.meshes.iter().map(|m| m.positions.len()).collect();
        let ambiguous = take.truth.ambiguous.iter().filter(|&&a| a).count() as f64 / v as f64;
        println!(
            "{:<18} {:>3} frames, {:>5}-{:>5} vertices, limbs {:.1} voxels, fastest {:.1} % of the diagonal a frame, {} parts, {:.0} % ambiguous, built in {:.1} s{}",
            spec.name,
            take.meshes.len(),
            vertices.iter().min().unwrap(),
            vertices.iter().max().unwrap(),
            take.limb_voxels,
            take.fastest_percent,
            take.truth.parts.len(),
            100.0 * ambiguous,
            clock.elapsed().as_secs_f64(),
            if spec.held_out { " (held out)" } else { "" }
        );
        std::io::stdout().flush()?;
    }
    Ok(())
}

/// A .npy file: the header for `descr` and `shape`, then `data`.
fn npy(descr: &str, shape: &[usize], data: &[u8]) -> Vec<u8> {
    let dims = shape
        .iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    let shape = if shape.len() == 1 {
        format!("({dims},)")
    } else {
        format!("({dims})")
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    // The header, magic and lengths included, ends on a multiple of 64 with a newline.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

/// An uncompressed zip of `name.npy` members: what numpy's `np.load` reads as .npz.
fn npz(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut central = Vec::new();
    for (name, data) in members {
        let name = format!("{name}.npy");
        let crc = crc32(data);
        let offset = out.len() as u32;
        let local = |sig: u32, out: &mut Vec<u8>, central: bool| {
            out.extend_from_slice(&sig.to_le_bytes());
            if central {
                out.extend_from_slice(&20u16.to_le_bytes());
            }
            for v in [20u16, 0, 0, 0, 0x21] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&crc.to_le_bytes());
            out.extend_from_slice(&(data.len() as u32).to_le_bytes());
            out.extend_from_slice(&(data.len() as u32).to_le_bytes());
            out.extend_from_slice(&(name.len() as u16).to_le_bytes());
            out.extend_from_slice(&0u16.to_le_bytes());
            if central {
                for v in [0u16, 0, 0] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.extend_from_slice(&0u32.to_le_bytes());
                out.extend_from_slice(&offset.to_le_bytes());
            }
            out.extend_from_slice(name.as_bytes());
        };
        local(0x0403_4b50, &mut out, false);
        out.extend_from_slice(data);
        local(0x0201_4b50, &mut central, true);
    }
    let start = out.len() as u32;
    out.extend_from_slice(&central);
    out.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
    for v in [0u16, 0, members.len() as u16, members.len() as u16] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(central.len() as u32).to_le_bytes());
    out.extend_from_slice(&start.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    out
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}
