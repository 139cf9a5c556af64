//! Spatial queries shared by the stages: the nearest center of every voxel
//! (Voronoi cells and their sums) and the closest point on a triangle mesh.

pub mod cells;
pub mod surface;
