//! How separate a frame's parts are: its solid's connected parts and the
//! tunnels through them, by which the tracking chooses its reference frame
//! (`params::Reference::Auto`, issue 47).
//!
//! The solid is the union of the occupied voxels as closed unit cubes, so
//! voxels that share only an edge or a corner are joined (26-connectivity).
//! Its Euler characteristic χ = parts − tunnels + cavities: two hands that
//! clasp close a loop through the arms (one tunnel, χ falls by one), a ball
//! held against a body joins two parts into one (χ falls by one); either
//! parting raises it again. Cavities (voids the outside cannot reach, which
//! a voxelised capture shows now and then where its surfaces fold in) are
//! filled first: they say nothing about contacts.

use crate::model::GridSpec;

/// A frame's parts and the tunnels through them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameTopology {
    /// Connected parts of at least the minimum size asked for.
    pub parts: usize,
    /// Tunnels through those parts (loops a contact closes), counted with
    /// their cavities filled: parts − χ.
    pub tunnels: usize,
    /// Voxels in parts below the minimum size, left out of both.
    pub specks: usize,
}

impl FrameTopology {
    /// How separate the frame's parts are: parts − tunnels, the Euler
    /// characteristic of the solid without its cavities. Every contact that
    /// joins two parts or closes a loop lowers it by one.
    pub fn separation(&self) -> i64 {
        self.parts as i64 - self.tunnels as i64
    }
}

/// The occupied voxels `indices` (linear, ascending, in `grid`) as a dense
/// bit set over their bounding box, one voxel of empty margin on every side
/// so that every neighbour lookup stays inside.
struct Solid {
    min: [usize; 3],
    dims: [usize; 3],
    bits: Vec<u64>,
}

impl Solid {
    fn new(grid: &GridSpec, indices: &[u32]) -> Solid {
        let mut lo = [usize::MAX; 3];
        let mut hi = [0usize; 3];
        for &v in indices {
            let c = grid.voxel_coords(v as usize);
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        if indices.is_empty() {
            lo = [0; 3];
            hi = [0; 3];
        }
        // One voxel of margin below (coordinates shift by one) and above.
        let dims = [hi[0] - lo[0] + 3, hi[1] - lo[1] + 3, hi[2] - lo[2] + 3];
        let mut solid = Solid {
            min: lo,
            dims,
            bits: vec![0; (dims[0] * dims[1] * dims[2]).div_ceil(64)],
        };
        for &v in indices {
            let at = solid.local(grid.voxel_coords(v as usize));
            solid.bits[at / 64] |= 1 << (at % 64);
        }
        solid
    }

    /// The local index of grid coordinates `c` (shifted by the margin).
    fn local(&self, c: [usize; 3]) -> usize {
        let [x, y, z] = [
            c[0] + 1 - self.min[0],
            c[1] + 1 - self.min[1],
            c[2] + 1 - self.min[2],
        ];
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    fn get(&self, at: usize) -> bool {
        self.bits[at / 64] >> (at % 64) & 1 == 1
    }

    fn clear(&mut self, at: usize) {
        self.bits[at / 64] &= !(1 << (at % 64));
    }

    /// The 26 neighbours' local offsets.
    fn neighbour_offsets(&self) -> Vec<isize> {
        let (sx, sy) = (1isize, self.dims[0] as isize);
        let sz = sy * self.dims[1] as isize;
        let mut offsets = Vec::with_capacity(26);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if (dx, dy, dz) != (0, 0, 0) {
                        offsets.push(dx * sx + dy * sy + dz * sz);
                    }
                }
            }
        }
        offsets
    }

    /// Removes the parts of fewer than `min_voxels` voxels; returns the
    /// parts kept and the voxels removed.
    fn remove_specks(&mut self, min_voxels: usize) -> (usize, usize) {
        let offsets = self.neighbour_offsets();
        let mut seen = vec![0u64; self.bits.len()];
        let (mut parts, mut removed) = (0, 0);
        let mut stack = Vec::new();
        let mut part = Vec::new();
        for word in 0..self.bits.len() {
            let mut unseen = self.bits[word] & !seen[word];
            while unseen != 0 {
                let start = word * 64 + unseen.trailing_zeros() as usize;
                part.clear();
                stack.push(start);
                seen[start / 64] |= 1 << (start % 64);
                while let Some(at) = stack.pop() {
                    part.push(at);
                    for &o in &offsets {
                        // The margin keeps every occupied voxel's neighbours inside.
                        let n = (at as isize + o) as usize;
                        if self.get(n) && seen[n / 64] >> (n % 64) & 1 == 0 {
                            seen[n / 64] |= 1 << (n % 64);
                            stack.push(n);
                        }
                    }
                }
                if part.len() < min_voxels {
                    removed += part.len();
                    for &at in &part {
                        self.clear(at);
                    }
                } else {
                    parts += 1;
                }
                unseen = self.bits[word] & !seen[word];
            }
        }
        (parts, removed)
    }

    /// Fills the cavities: empty voxels the outside cannot reach through
    /// faces (6-connectivity, the complement's dual of the solid's 26).
    /// Returns the voxels filled.
    fn fill_cavities(&mut self) -> usize {
        let [nx, ny, nz] = self.dims;
        let (sy, sz) = (nx, nx * ny);
        let mut outside = vec![0u64; self.bits.len()];
        // The margin's corner is outside, and the margin joins the whole outside.
        let mut stack = vec![0usize];
        outside[0] |= 1;
        while let Some(at) = stack.pop() {
            let (x, y, z) = (at % nx, at / sy % ny, at / sz);
            let mut visit = |n: usize| {
                if !self.get(n) && outside[n / 64] >> (n % 64) & 1 == 0 {
                    outside[n / 64] |= 1 << (n % 64);
                    stack.push(n);
                }
            };
            if x > 0 {
                visit(at - 1);
            }
            if x + 1 < nx {
                visit(at + 1);
            }
            if y > 0 {
                visit(at - sy);
            }
            if y + 1 < ny {
                visit(at + sy);
            }
            if z > 0 {
                visit(at - sz);
            }
            if z + 1 < nz {
                visit(at + sz);
            }
        }
        let mut filled = 0;
        let total = nx * ny * nz;
        let last = self.bits.len() - 1;
        for (word, (bits, outside)) in self.bits.iter_mut().zip(&outside).enumerate() {
            let mut empty = !(*bits | outside);
            if word == last && total % 64 != 0 {
                empty &= (1u64 << (total % 64)) - 1;
            }
            filled += empty.count_ones() as usize;
            *bits |= empty;
        }
        filled
    }

    /// χ = V − E + F − C of the union of closed cubes, summed vertex by
    /// vertex: each lattice point adds 1 if any of its eight voxels is
    /// occupied, −½ per edge from it, ¼ per face and ⅛ per cube around it
    /// (`VERTEX_TERMS`, in eighths).
    fn euler(&self) -> i64 {
        let [nx, ny, nz] = self.dims;
        let mut eighths = 0i64;
        // Lattice point (x, y, z) is the corner shared by the voxels
        // x-1..=x, y-1..=y, z-1..=z; the margin leaves the outer ones empty.
        for z in 1..nz {
            for y in 1..ny {
                for x in 1..nx {
                    let mut config = 0usize;
                    for (bit, (dx, dy, dz)) in CORNERS.iter().enumerate() {
                        let at = (x - 1 + dx) + nx * ((y - 1 + dy) + ny * (z - 1 + dz));
                        config |= (self.get(at) as usize) << bit;
                    }
                    eighths += VERTEX_TERMS[config] as i64;
                }
            }
        }
        debug_assert_eq!(eighths % 8, 0);
        eighths / 8
    }
}

/// The eight voxels around a lattice point, as offsets (0 or 1) from the
/// one below it on every axis; bit `k` of a configuration is `CORNERS[k]`.
const CORNERS: [(usize, usize, usize); 8] = [
    (0, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (1, 1, 0),
    (0, 0, 1),
    (1, 0, 1),
    (0, 1, 1),
    (1, 1, 1),
];

/// Eight times a lattice point's share of χ for each configuration of its
/// eight voxels.
const VERTEX_TERMS: [i8; 256] = vertex_terms();

/// Whether voxel (dx, dy, dz) of a lattice point's eight is in `config`.
const fn occupied(config: usize, dx: usize, dy: usize, dz: usize) -> bool {
    config >> (dx + 2 * dy + 4 * dz) & 1 == 1
}

const fn vertex_terms() -> [i8; 256] {
    let mut table = [0i8; 256];
    let mut config = 0;
    while config < 256 {
        let mut terms = if config != 0 { 8 } else { 0 };
        // Edges from the point: along each axis, one on either side; each
        // borders the four voxels on its side of that axis.
        let mut axis = 0;
        while axis < 3 {
            let mut side = 0;
            while side < 2 {
                let mut any = false;
                let mut k = 0;
                while k < 4 {
                    let (a, b) = (k & 1, k >> 1);
                    any |= match axis {
                        0 => occupied(config, side, a, b),
                        1 => occupied(config, a, side, b),
                        _ => occupied(config, a, b, side),
                    };
                    k += 1;
                }
                terms -= 4 * any as i8;
                side += 1;
            }
            // Faces through the point across this axis: four, each between
            // the two voxels on either side of it.
            let mut k = 0;
            while k < 4 {
                let (a, b) = (k & 1, k >> 1);
                let any = match axis {
                    0 => occupied(config, 0, a, b) || occupied(config, 1, a, b),
                    1 => occupied(config, a, 0, b) || occupied(config, a, 1, b),
                    _ => occupied(config, a, b, 0) || occupied(config, a, b, 1),
                };
                terms += 2 * any as i8;
                k += 1;
            }
            axis += 1;
        }
        terms -= (config as u32).count_ones() as i8;
        table[config] = terms;
        config += 1;
    }
    table
}

/// The parts of `indices` (a frame's occupied voxels in `grid`, linear and
/// ascending) of at least `min_voxels` voxels, and the tunnels through them.
pub fn frame_topology(grid: &GridSpec, indices: &[u32], min_voxels: usize) -> FrameTopology {
    let mut solid = Solid::new(grid, indices);
    let (parts, specks) = solid.remove_specks(min_voxels);
    solid.fill_cavities();
    let euler = solid.euler();
    FrameTopology {
        parts,
        tunnels: (parts as i64 - euler).max(0) as usize,
        specks,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Point3;

    fn topo(parts: usize, tunnels: usize, specks: usize) -> FrameTopology {
        FrameTopology {
            parts,
            tunnels,
            specks,
        }
    }

    fn grid(n: usize) -> GridSpec {
        GridSpec {
            origin: Point3::origin(),
            voxel_size: 1.0,
            dims: [n, n, n],
        }
    }

    fn voxels(grid: &GridSpec, inside: impl Fn(usize, usize, usize) -> bool) -> Vec<u32> {
        (0..grid.len())
            .filter(|&v| {
                let [x, y, z] = grid.voxel_coords(v);
                inside(x, y, z)
            })
            .map(|v| v as u32)
            .collect()
    }

    #[test]
    fn solids_of_known_topology() {
        let g = grid(12);
        let cube = voxels(&g, |x, y, z| {
            (2..6).contains(&x) && (2..6).contains(&y) && (2..6).contains(&z)
        });
        assert_eq!(frame_topology(&g, &cube, 1), topo(1, 0, 0));
        // A ring: one part, one tunnel.
        let ring = voxels(&g, |x, y, z| {
            (1..10).contains(&x)
                && (1..10).contains(&y)
                && z == 4
                && !((3..7).contains(&x) && (3..7).contains(&y))
        });
        assert_eq!(frame_topology(&g, &ring, 1), topo(1, 1, 0));
        assert_eq!(frame_topology(&g, &ring, 1).separation(), 0);
        // A hollow box: one part, its cavity filled.
        let shell = voxels(&g, |x, y, z| {
            let inside = |c: usize| (2..9).contains(&c);
            let core = |c: usize| (3..8).contains(&c);
            inside(x) && inside(y) && inside(z) && !(core(x) && core(y) && core(z))
        });
        assert_eq!(frame_topology(&g, &shell, 1), topo(1, 0, 0));
        // A ring whose hole is walled in on both sides is a cavity, no tunnel.
        let lidded = voxels(&g, |x, y, z| {
            (1..10).contains(&x)
                && (1..10).contains(&y)
                && (3..6).contains(&z)
                && !((3..7).contains(&x) && (3..7).contains(&y) && z == 4)
        });
        assert_eq!(frame_topology(&g, &lidded, 1).tunnels, 0);
        // Two cubes apart, and a speck left out.
        let two = voxels(&g, |x, y, z| {
            ((1..4).contains(&x) || (6..10).contains(&x))
                && (1..4).contains(&y)
                && (1..4).contains(&z)
                || (x, y, z) == (10, 10, 10)
        });
        assert_eq!(frame_topology(&g, &two, 2), topo(2, 0, 1));
        assert_eq!(frame_topology(&g, &two, 1), topo(3, 0, 0));
        assert_eq!(frame_topology(&g, &two, 2).separation(), 2);
        // Two voxels sharing only a corner are one part.
        let corner = voxels(&g, |x, y, z| {
            (x, y, z) == (3, 3, 3) || (x, y, z) == (4, 4, 4)
        });
        assert_eq!(frame_topology(&g, &corner, 1), topo(1, 0, 0));
        assert_eq!(frame_topology(&g, &[], 1), FrameTopology::default());
    }
}
