//! The binvox voxel format (Min's binvox / viewvox): run-length encoded,
//! y fastest, then z, then x. We write cubic grids, which every reader accepts.

use crate::error::{Error, Result};
use crate::math::{Point3, Real};
use crate::model::{GridSpec, Occupancy};

use std::path::Path;

/// Decodes a binvox file into its grid and occupancy.
pub fn read_binvox(path: &Path, bytes: &[u8]) -> Result<(GridSpec, Occupancy)> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut next_line = |pos: &mut usize| -> Result<(usize, String)> {
        let end = bytes[*pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|e| *pos + e)
            .ok_or_else(|| Error::parse(path, None, "the header does not end with 'data'"))?;
        let text = String::from_utf8_lossy(&bytes[*pos..end])
            .trim()
            .to_string();
        *pos = end + 1;
        line_no += 1;
        Ok((line_no, text))
    };
    let (_, magic) = next_line(&mut pos)?;
    if !magic.starts_with("#binvox") {
        return Err(Error::parse(
            path,
            Some(1),
            "not a binvox file (no '#binvox' line)",
        ));
    }
    let (mut dims, mut translate, mut scale) = (None, None, None);
    loop {
        let (n, line) = next_line(&mut pos)?;
        let words: Vec<&str> = line.split_whitespace().collect();
        let nums = |k: usize| -> Result<Vec<f64>> {
            let v: Vec<f64> = words[1..].iter().filter_map(|w| w.parse().ok()).collect();
            if v.len() != k || words.len() != k + 1 || !v.iter().all(|x| x.is_finite()) {
                return Err(Error::parse(
                    path,
                    Some(n),
                    format!("'{}' needs {k} numbers", words[0]),
                ));
            }
            Ok(v)
        };
        match words.first().copied() {
            Some("dim") => {
                let d = nums(3)?;
                if d.iter()
                    .any(|&x| !(1.0..=4096.0).contains(&x) || x.fract() != 0.0)
                {
                    return Err(Error::parse(
                        path,
                        Some(n),
                        "dimensions must be whole numbers in 1..=4096",
                    ));
                }
                // "dim depth height width": x, z, y sizes.
                dims = Some([d[0] as usize, d[2] as usize, d[1] as usize]);
            }
            Some("translate") => translate = Some(nums(3)?),
            Some("scale") => scale = Some(nums(1)?[0]),
            Some("data") => break,
            Some(_) | None => {
                return Err(Error::parse(
                    path,
                    Some(n),
                    format!("unexpected header line '{line}'"),
                ))
            }
        }
    }
    let dims = dims.ok_or_else(|| Error::parse(path, None, "no 'dim' line"))?;
    let t = translate.unwrap_or_else(|| vec![0.0; 3]);
    let scale = scale.unwrap_or(1.0);
    if !(scale > 0.0) {
        return Err(Error::parse(path, None, "scale must be positive"));
    }
    let longest = *dims.iter().max().unwrap();
    let grid = GridSpec {
        origin: Point3::new(t[0], t[1], t[2]),
        voxel_size: scale / longest as Real,
        dims,
    };
    let total = grid.len();
    if total as u64 > u32::MAX as u64 {
        return Err(Error::parse(path, None, "grid too large"));
    }
    // Each run of the data covers at most 255 voxels: a header announcing more
    // voxels than the file can describe fails before anything is allocated.
    let covered = (bytes.len() - pos) / 2 * 255;
    if covered < total {
        return Err(Error::parse(
            path,
            None,
            format!("the data covers at most {covered} of the {total} voxels the header announces; is the file cut short?"),
        ));
    }
    let [nx, ny, nz] = dims;
    let mut occupied = vec![false; total];
    let mut file_index = 0usize;
    for pair in bytes[pos..].chunks(2) {
        if file_index >= total {
            break;
        }
        let [value, count] = pair else {
            return Err(Error::parse(
                path,
                None,
                "run-length data ends in the middle of a pair",
            ));
        };
        let count = *count as usize;
        if count == 0 || file_index + count > total {
            return Err(Error::parse(
                path,
                None,
                format!("bad run of {count} at voxel {file_index} of {total}"),
            ));
        }
        if *value != 0 {
            for f in file_index..file_index + count {
                // f = x * (nz * ny) + z * ny + y
                let (x, r) = (f / (nz * ny), f % (nz * ny));
                let (z, y) = (r / ny, r % ny);
                occupied[x + nx * (y + ny * z)] = true;
            }
        }
        file_index += count;
    }
    if file_index < total {
        return Err(Error::parse(
            path,
            None,
            format!("data covers {file_index} of {total} voxels"),
        ));
    }
    let indices = (0..total as u32)
        .filter(|&i| occupied[i as usize])
        .collect();
    Ok((grid, Occupancy { indices }))
}
