//! The triangle mesh every reader produces.

use crate::error::{Error, Result};
use crate::math::{Point3, Real, Vector3};
use std::path::{Path, PathBuf};

/// One frame's surface: triangles over a shared vertex list.
///
/// Attributes other than positions are optional and are carried only so the
/// first frame can be exported as loaded (UVs, normals, texture).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions, in the input's units.
    pub positions: Vec<Point3>,
    /// Counter-clockwise seen from outside, indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex texture coordinates (glTF convention: v down), if present.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Per-vertex normals, if present in the file.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Base colour texture of the first material, if the file names one.
    pub texture: Option<PathBuf>,
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// The smallest coordinate on each axis.
    pub min: Point3,
    /// The largest coordinate on each axis.
    pub max: Point3,
}

impl Aabb {
    /// The box around nothing (`min` +∞, `max` −∞): growing it by a point
    /// gives that point's box.
    pub fn empty() -> Self {
        Aabb {
            min: Point3::from([Real::INFINITY; 3]),
            max: Point3::from([Real::NEG_INFINITY; 3]),
        }
    }
    /// The smallest box around `points` (empty when there are none).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Point3>) -> Self {
        let mut b = Aabb::empty();
        for p in points {
            b.grow(p);
        }
        b
    }
    /// Enlarges the box to contain `p`.
    pub fn grow(&mut self, p: &Point3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }
    /// The smallest box containing both boxes.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&other.min),
            max: self.max.sup(&other.max),
        }
    }
    /// Whether the box contains no point (`min` exceeds `max` on some axis).
    pub fn is_empty(&self) -> bool {
        (0..3).any(|k| self.min[k] > self.max[k])
    }
    /// The side lengths, `max − min`.
    pub fn extent(&self) -> Vector3 {
        self.max - self.min
    }
    /// The largest side length.
    pub fn longest_side(&self) -> Real {
        self.extent().max()
    }
    /// Whether f32 coordinates (what glTF and most PLY files hold) would
    /// blur what lies in this box by more than 1e-6 of its size: it lies
    /// farther than 16 times its size from the origin (f32 keeps 24 bits),
    /// as a capture in map coordinates does.
    pub fn too_far_for_f32(&self) -> bool {
        let far = (0..3)
            .map(|k| self.min[k].abs().max(self.max[k].abs()))
            .fold(0.0, Real::max);
        !self.is_empty() && self.longest_side() > 0.0 && far > 16.0 * self.longest_side()
    }
    /// Length of the box's diagonal (the unit of figures given in percent of
    /// the diagonal).
    pub fn diagonal(&self) -> Real {
        self.extent().norm()
    }
}

/// Per vertex, the first vertex at exactly the same position: copies a loader
/// made along UV or normal seams map to one vertex, so the seam can be
/// treated as the surface it is.
pub(crate) fn weld_by_position(positions: &[Point3]) -> Vec<u32> {
    let mut first = std::collections::HashMap::new();
    // `+ 0.0` turns −0 into +0, so both weld.
    (0..positions.len() as u32)
        .map(|v| {
            *first
                .entry(positions[v as usize].coords.map(|c| (c + 0.0).to_bits()))
                .or_insert(v)
        })
        .collect()
}

impl TriangleMesh {
    /// The box around every vertex (triangles or not).
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// `weld_by_position` of the vertices, and the triangles over the
    /// welded indices (copies then keep no triangle of their own).
    pub fn welded(&self) -> (Vec<u32>, Vec<[u32; 3]>) {
        let weld = weld_by_position(&self.positions);
        let triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|v| weld[v as usize]))
            .collect();
        (weld, triangles)
    }

    /// Checks what every stage relies on: at least one triangle, finite
    /// coordinates of a measurable extent, indices in range, and some triangle
    /// of non-zero area. `path` names the file in the error.
    pub fn validate(&self, path: &Path) -> Result<()> {
        if self.triangles.is_empty() {
            return Err(Error::mesh(path, "the mesh has no triangles"));
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(Error::mesh(
                path,
                format!("vertex {} has a non-finite coordinate", i + 1),
            ));
        }
        let n = self.positions.len();
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(Error::mesh(
                path,
                format!(
                    "triangle {} refers to a vertex beyond the {n} defined",
                    t + 1
                ),
            ));
        }
        // A few degenerate triangles are normal in captures; only degenerate
        // ones make no surface. "Zero" is relative to the mesh's size, so
        // points rounded onto a common line count as collinear.
        let diagonal = self.bounding_box().diagonal();
        if !diagonal.is_finite() {
            return Err(Error::mesh(
                path,
                "the coordinates are too large: the bounding box's diagonal overflows",
            ));
        }
        let tiny = 1e-12 * diagonal.powi(2);
        if !self.triangles.iter().any(|t| self.doubled_area(t) > tiny) {
            return Err(Error::mesh(
                path,
                format!(
                    "all {} triangles are degenerate (zero area): the mesh has no surface",
                    self.triangles.len()
                ),
            ));
        }
        Ok(())
    }

    /// Twice the area of a triangle.
    fn doubled_area(&self, t: &[u32; 3]) -> Real {
        let [a, b, c] = t.map(|i| self.positions[i as usize]);
        (b - a).cross(&(c - a)).norm()
    }

    /// Signed volume enclosed (exact for closed, consistently oriented meshes).
    pub fn signed_volume(&self) -> Real {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }
}

/// The MIME type of an image glTF can embed (PNG or JPEG), from its first bytes.
pub(crate) fn image_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        Some("image/jpeg")
    } else {
        None
    }
}

/// [`image_mime`] of the file at `path` (None when unreadable).
pub(crate) fn embeddable_image(path: &Path) -> Option<&'static str> {
    let mut head = [0u8; 4];
    let n = std::io::Read::read(&mut std::fs::File::open(path).ok()?, &mut head).ok()?;
    image_mime(&head[..n])
}
