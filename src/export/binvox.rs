//! Voxel frames written as `.binvox` (Patrick Min's format, as `io` reads it).

use crate::error::{Error, Result};
use crate::files::{replace_dir, Fill};
use crate::math::Real;
use crate::model::{GridSpec, Occupancy};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Encodes a frame as binvox, padding the grid to a cube.
pub fn write_binvox(out: &mut impl Write, grid: &GridSpec, occ: &Occupancy) -> std::io::Result<()> {
    let d = *grid.dims.iter().max().unwrap();
    let mut bits = vec![false; d * d * d];
    for &i in &occ.indices {
        let [x, y, z] = grid.voxel_coords(i as usize);
        bits[x * d * d + z * d + y] = true;
    }
    let o = grid.origin;
    write!(
        out,
        "#binvox 1\ndim {d} {d} {d}\ntranslate {} {} {}\nscale {}\ndata\n",
        o.x,
        o.y,
        o.z,
        grid.voxel_size * d as Real
    )?;
    let mut runs = Vec::new();
    let mut k = 0;
    while k < bits.len() {
        let value = bits[k];
        let mut count = 1;
        while count < 255 && k + count < bits.len() && bits[k + count] == value {
            count += 1;
        }
        runs.push(value as u8);
        runs.push(count as u8);
        k += count;
    }
    out.write_all(&runs)
}

/// Writes every frame of a voxelised sequence as `.binvox` into `dir`
/// (created if needed), named after the input files. The folder is replaced
/// as a whole ([`crate::files::replace_dir`]): on failure the old one stays
/// as it was.
pub fn write_binvox_frames(seq: &crate::voxel::VoxelSequence, dir: &Path) -> Result<Vec<PathBuf>> {
    let mut names: Vec<String> = Vec::with_capacity(seq.names.len());
    for (k, src) in seq.names.iter().enumerate() {
        let name = format!(
            "{}.binvox",
            Path::new(src)
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
        );
        if let Some(j) = names.iter().position(|n| *n == name) {
            return Err(Error::InvalidInput(format!(
                "{} and {} would both be written as {}: rename one",
                seq.names[j],
                seq.names[k],
                dir.join(&name).display()
            )));
        }
        names.push(name);
    }
    let files = seq
        .frames
        .iter()
        .zip(names)
        .map(|(occ, name)| {
            (
                name,
                Box::new(move |w: &mut BufWriter<std::fs::File>| {
                    write_binvox(w, &seq.grid, &occ.expand())
                }) as Fill,
            )
        })
        .collect();
    replace_dir(dir, files)
}
