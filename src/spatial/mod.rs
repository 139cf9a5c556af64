//! Spatial queries shared by the stages, internal to the crate: the nearest
//! center of every voxel (Voronoi cells and their sums) and the closest
//! point on a triangle mesh.

pub(crate) mod cells;
pub(crate) mod surface;
