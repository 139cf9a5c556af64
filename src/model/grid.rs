//! The one grid every frame of a sequence is voxelised on, and the compact
//! occupancy of one frame.

use crate::error::{Error, Result};
use crate::math::{Point3, Real, Vector3};
use crate::model::mesh::Aabb;

/// Voxels beyond the sequence's bounding box on every side, so that no
/// occupied voxel touches the grid's border.
pub const GRID_MARGIN: usize = 2;

/// Largest resolution: linear voxel indices must fit in u32.
pub const MAX_RESOLUTION: usize = 1600 - 2 * GRID_MARGIN;

/// A regular grid of cubic voxels. Voxel (i, j, k) spans
/// `origin + [i, i+1] × [j, j+1] × [k, k+1] · voxel_size`; its linear index is
/// `i + dims[0] * (j + dims[1] * k)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// World position of the grid's lowest corner (that of voxel (0, 0, 0)).
    pub origin: Point3,
    /// Edge length of a voxel, in world units.
    pub voxel_size: Real,
    /// Voxels along x, y and z (with [`for_bounds`](Self::for_bounds), the
    /// margins included).
    pub dims: [usize; 3],
}

impl GridSpec {
    /// The grid for a sequence whose frames all lie in `bbox`: `resolution`
    /// voxels along the box's longest side, plus [`GRID_MARGIN`] on every side.
    pub fn for_bounds(bbox: &Aabb, resolution: usize) -> Result<GridSpec> {
        if !(2..=MAX_RESOLUTION).contains(&resolution) {
            return Err(Error::InvalidParameter(format!(
                "resolution {resolution} is outside 2..={MAX_RESOLUTION}"
            )));
        }
        let longest = bbox.longest_side();
        if bbox.is_empty() || !(longest > 0.0) || !longest.is_finite() {
            return Err(Error::InvalidInput(
                "the sequence's bounding box is empty or degenerate".into(),
            ));
        }
        let voxel_size = longest / resolution as Real;
        let extent = bbox.extent();
        let dims = [0, 1, 2].map(|k| {
            ((extent[k] / voxel_size).ceil() as usize).clamp(1, resolution) + 2 * GRID_MARGIN
        });
        let origin = bbox.min - Vector3::repeat(GRID_MARGIN as Real * voxel_size);
        Ok(GridSpec {
            origin,
            voxel_size,
            dims,
        })
    }

    /// Number of voxels in the grid.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Whether the grid has no voxel (some dimension is 0).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The linear index of the voxel at grid coordinates (i, j, k).
    #[inline]
    pub fn linear_index(&self, [i, j, k]: [usize; 3]) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The grid coordinates (i, j, k) of the voxel at a linear index.
    #[inline]
    pub fn voxel_coords(&self, index: usize) -> [usize; 3] {
        let i = index % self.dims[0];
        let r = index / self.dims[0];
        [i, r % self.dims[1], r / self.dims[1]]
    }

    /// World position of a voxel's center.
    #[inline]
    pub fn voxel_center(&self, index: usize) -> Point3 {
        self.center_at(self.voxel_coords(index))
    }

    /// World position of the center of the voxel at grid coordinates `c`.
    #[inline]
    pub fn center_at(&self, c: [usize; 3]) -> Point3 {
        self.origin
            + Vector3::new(c[0] as Real + 0.5, c[1] as Real + 0.5, c[2] as Real + 0.5)
                * self.voxel_size
    }

    /// The linear index of the voxel holding `p`; None outside the grid.
    pub fn voxel_at(&self, p: &Point3) -> Option<usize> {
        let g = self.to_grid(p);
        let c: [Real; 3] = [g.x, g.y, g.z];
        if c.iter()
            .zip(self.dims)
            .any(|(&x, d)| !(x >= 0.0 && x < d as Real))
        {
            return None;
        }
        Some(self.linear_index(c.map(|x| x as usize)))
    }

    /// Continuous grid coordinates (voxel units from the origin) of a world point.
    #[inline]
    pub fn to_grid(&self, p: &Point3) -> Vector3 {
        (p - self.origin) / self.voxel_size
    }

    /// The world box the grid covers.
    pub fn bounds(&self) -> Aabb {
        let ext = Vector3::new(
            self.dims[0] as Real,
            self.dims[1] as Real,
            self.dims[2] as Real,
        ) * self.voxel_size;
        Aabb {
            min: self.origin,
            max: self.origin + ext,
        }
    }
}

/// One frame's occupied voxels as sorted linear indices into its [`GridSpec`]:
/// 4 bytes per occupied voxel.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Occupancy {
    /// Linear indices of the occupied voxels, ascending.
    pub indices: Vec<u32>,
}

impl Occupancy {
    /// Number of occupied voxels.
    pub fn len(&self) -> usize {
        self.indices.len()
    }
    /// Whether no voxel is occupied.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
    /// Whether the voxel at linear index `index` is occupied.
    pub fn contains(&self, index: u32) -> bool {
        self.indices.binary_search(&index).is_ok()
    }
    /// Occupied volume in world units.
    pub fn volume(&self, grid: &GridSpec) -> Real {
        self.indices.len() as Real * grid.voxel_size.powi(3)
    }
    /// World positions of the occupied voxels' centers.
    pub fn centers<'a>(&'a self, grid: &'a GridSpec) -> impl Iterator<Item = Point3> + 'a {
        self.indices
            .iter()
            .map(move |&i| grid.voxel_center(i as usize))
    }
}

/// One frame's occupied voxels as runs of consecutive linear indices, each
/// `[first, length]`: the voxels of a solid lie in long rows along x, so a
/// frame takes a small share of [`Occupancy`]'s 4 bytes per voxel. A
/// sequence keeps every frame this way and expands one when a stage works
/// on it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OccupancyRuns {
    /// Each run as two LEB128 varints, its gap from the previous run's end
    /// and its length: mostly one or two bytes each, where two `u32` would
    /// take 8, so a long sequence's frames take a third of the memory.
    encoded: Vec<u8>,
    runs: usize,
    count: usize,
}

impl OccupancyRuns {
    /// Occupied voxels.
    pub fn len(&self) -> usize {
        self.count
    }
    /// Whether no voxel is occupied.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
    /// Runs stored.
    pub fn runs(&self) -> usize {
        self.runs
    }
    /// Bytes the runs take.
    pub fn bytes(&self) -> usize {
        self.encoded.len()
    }
    /// The runs as (first index, length), ascending.
    fn decoded(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        let mut bytes = self.encoded.iter();
        let mut next = move || {
            let mut value = 0u32;
            for shift in (0..35).step_by(7) {
                let b = *bytes.next()?;
                value |= ((b & 0x7f) as u32) << shift;
                if b & 0x80 == 0 {
                    break;
                }
            }
            Some(value)
        };
        let mut end = 0u32;
        std::iter::from_fn(move || {
            let first = end + next()?;
            let len = next()?;
            end = first + len;
            Some((first, len))
        })
    }
    /// The occupied voxels' linear indices, ascending.
    pub fn iter(&self) -> impl Iterator<Item = u32> + '_ {
        self.decoded().flat_map(|(first, len)| first..first + len)
    }
    /// The occupied voxels' linear indices, ascending, as one list.
    pub fn indices(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.count);
        out.extend(self.iter());
        out
    }
    /// The frame as an [`Occupancy`].
    pub fn expand(&self) -> Occupancy {
        Occupancy {
            indices: self.indices(),
        }
    }
}

fn put_varint(out: &mut Vec<u8>, mut value: u32) {
    while value >= 0x80 {
        out.push((value as u8 & 0x7f) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

impl From<&Occupancy> for OccupancyRuns {
    /// `occ`'s indices must ascend, as every [`Occupancy`]'s do.
    fn from(occ: &Occupancy) -> Self {
        let mut runs: Vec<[u32; 2]> = Vec::new();
        for &i in &occ.indices {
            match runs.last_mut() {
                Some([first, len]) if *first + *len == i => *len += 1,
                _ => runs.push([i, 1]),
            }
        }
        let mut encoded = Vec::with_capacity(3 * runs.len());
        let mut end = 0;
        for &[first, len] in &runs {
            put_varint(&mut encoded, first - end);
            put_varint(&mut encoded, len);
            end = first + len;
        }
        encoded.shrink_to_fit();
        OccupancyRuns {
            encoded,
            runs: runs.len(),
            count: occ.indices.len(),
        }
    }
}

impl From<Occupancy> for OccupancyRuns {
    fn from(occ: Occupancy) -> Self {
        OccupancyRuns::from(&occ)
    }
}
