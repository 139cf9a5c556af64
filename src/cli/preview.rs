//! A small picture of the result for the report: a few frames of the
//! dynamic mesh drawn by our own z-buffer into inline SVG (no image file, no
//! script), so the page stays one self-contained file.
//!
//! Each frame is rasterised at [`SIZE`] pixels with flat shading, seen along
//! −z with y up (glTF's convention); the pixels of one shade are written as
//! one SVG path of row runs, which keeps a frame to tens of kilobytes.

use std::fmt::Write;
use voltrack::math::{Point3, Real, Vector3};
use voltrack::Aabb;

/// Pixels along each side of a frame's picture.
pub const SIZE: usize = 160;

/// Grey levels of the shading (0 is the background).
const LEVELS: u8 = 12;

/// The direction light comes from (normalised when used): front, above, right.
const LIGHT: [Real; 3] = [0.35, 0.55, 0.75];

/// Shade levels of `triangles` over `positions` at `SIZE` × `SIZE` pixels,
/// row-major from the top, 0 where nothing is drawn; `view` maps x, y of
/// the scene to pixels: (x − x0) · scale, (y1 − y) · scale.
pub fn raster(positions: &[Point3], triangles: &[[u32; 3]], view: &View) -> Vec<u8> {
    let mut depth = vec![Real::NEG_INFINITY; SIZE * SIZE];
    let mut shade = vec![0u8; SIZE * SIZE];
    let light = Vector3::from(LIGHT).normalize();
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let normal = (b - a).cross(&(c - a));
        let length = normal.norm();
        // Also skips a NaN normal.
        if length.is_nan() || length <= 0.0 {
            continue;
        }
        // Two-sided: captured meshes are not always consistently oriented.
        let lit = (normal.dot(&light) / length).abs();
        let level = 1 + ((lit * (LEVELS - 1) as Real).round() as u8).min(LEVELS - 1);
        let [pa, pb, pc] = [a, b, c].map(|p| view.pixel(&p));
        let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pc.0 - pa.0) * (pb.1 - pa.1);
        if area.abs() < 1e-12 {
            continue;
        }
        let lo_x = pa.0.min(pb.0).min(pc.0).floor().max(0.0) as usize;
        let hi_x = (pa.0.max(pb.0).max(pc.0).ceil() as isize).clamp(0, SIZE as isize) as usize;
        let lo_y = pa.1.min(pb.1).min(pc.1).floor().max(0.0) as usize;
        let hi_y = (pa.1.max(pb.1).max(pc.1).ceil() as isize).clamp(0, SIZE as isize) as usize;
        for y in lo_y..hi_y {
            for x in lo_x..hi_x {
                // The pixel's centre in barycentric coordinates.
                let (px, py) = (x as Real + 0.5, y as Real + 0.5);
                let w0 = ((pb.0 - px) * (pc.1 - py) - (pc.0 - px) * (pb.1 - py)) / area;
                let w1 = ((pc.0 - px) * (pa.1 - py) - (pa.0 - px) * (pc.1 - py)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * pa.2 + w1 * pb.2 + w2 * pc.2;
                let k = y * SIZE + x;
                if z > depth[k] {
                    depth[k] = z;
                    shade[k] = level;
                }
            }
        }
    }
    shade
}

/// How scene coordinates map to pixels, the same for every frame drawn so
/// that the motion shows.
#[derive(Clone, Copy, Debug)]
pub struct View {
    x0: Real,
    y1: Real,
    scale: Real,
    /// Offsets that centre the drawing in the square.
    margin: (Real, Real),
}

impl View {
    /// The view that fits every point of `frames` (x and y) into the square,
    /// with a pixel of margin.
    pub fn fitting<'a>(frames: impl IntoIterator<Item = &'a [Point3]>) -> Option<View> {
        let bounds = Aabb::from_points(frames.into_iter().flatten());
        let (lo, hi) = ([bounds.min.x, bounds.min.y], [bounds.max.x, bounds.max.y]);
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        if !(extent > 0.0 && extent.is_finite()) {
            return None;
        }
        let scale = (SIZE as Real - 2.0) / extent;
        Some(View {
            x0: lo[0],
            y1: hi[1],
            scale,
            margin: (
                1.0 + (SIZE as Real - 2.0 - (hi[0] - lo[0]) * scale) / 2.0,
                1.0 + (SIZE as Real - 2.0 - (hi[1] - lo[1]) * scale) / 2.0,
            ),
        })
    }

    /// Pixel x, y (from the top) and depth (larger is nearer) of `p`.
    fn pixel(&self, p: &Point3) -> (Real, Real, Real) {
        (
            (p.x - self.x0) * self.scale + self.margin.0,
            (self.y1 - p.y) * self.scale + self.margin.1,
            p.z,
        )
    }
}

/// `shade` (from [`raster`]) as an inline SVG of `SIZE` × `SIZE` units
/// shown at `SIZE` pixels: one path per grey level, one subpath per run of
/// pixels in a row.
pub fn svg(shade: &[u8], label: &str) -> String {
    let mut paths = vec![String::new(); LEVELS as usize + 1];
    for y in 0..SIZE {
        let row = &shade[y * SIZE..(y + 1) * SIZE];
        let mut x = 0;
        while x < SIZE {
            let level = row[x];
            let start = x;
            while x < SIZE && row[x] == level {
                x += 1;
            }
            if level > 0 {
                let _ = write!(
                    paths[level as usize],
                    "M{start} {y}h{}v1h-{}z",
                    x - start,
                    x - start
                );
            }
        }
    }
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 {SIZE} {SIZE}\" width=\"{SIZE}\" height=\"{SIZE}\" shape-rendering=\"crispEdges\" role=\"img\" aria-label=\"{label}\">"
    );
    for (level, d) in paths.iter().enumerate().skip(1) {
        if d.is_empty() {
            continue;
        }
        // Darker where the surface turns away from the light.
        let grey = 70 + (level as u32 * 150) / LEVELS as u32;
        let _ = write!(
            out,
            "<path fill=\"rgb({grey},{grey},{})\" d=\"{d}\"/>",
            (grey + 15).min(255)
        );
    }
    out.push_str("</svg>");
    out
}

/// The frames a preview shows: the first, the last and two between.
pub fn frames_shown(frames: usize) -> Vec<usize> {
    let mut shown: Vec<usize> = (0..4).map(|k| k * (frames.saturating_sub(1)) / 3).collect();
    shown.dedup();
    shown
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed box of `size`, corner at the origin.
    fn cube(size: Real) -> (Vec<Point3>, Vec<[u32; 3]>) {
        let positions = (0..8)
            .map(|i| {
                Point3::new(
                    size * (i & 1) as Real,
                    size * ((i >> 1) & 1) as Real,
                    size * (i >> 2) as Real,
                )
            })
            .collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (positions, triangles)
    }

    /// Seen along z a cube fitted to the view is its front face: every
    /// pixel inside the margin drawn, in the front face's one shade.
    #[test]
    fn a_cube_fills_the_view_with_its_front_face() {
        let (positions, triangles) = cube(2.0);
        let view = View::fitting([&positions[..]]).unwrap();
        let shade = raster(&positions, &triangles, &view);
        let drawn = shade.iter().filter(|&&s| s > 0).count();
        let inner = (SIZE - 2) * (SIZE - 2);
        assert!(drawn >= inner && drawn <= SIZE * SIZE, "{drawn} of {inner}");
        let front = shade[SIZE * SIZE / 2 + SIZE / 2];
        assert!(front > 0);
        assert!(shade.iter().all(|&s| s == 0 || s == front));
        // Nothing outside the margin.
        assert!(shade[..SIZE].iter().all(|&s| s == 0));
    }

    /// A cube a quarter the size in the same view covers about a sixteenth
    /// of the pixels; the SVG's runs cover exactly the drawn pixels.
    #[test]
    fn area_and_runs_match_the_geometry() {
        let (big, _) = cube(4.0);
        let (small, triangles) = cube(1.0);
        let view = View::fitting([&big[..]]).unwrap();
        let shade = raster(&small, &triangles, &view);
        let drawn = shade.iter().filter(|&&s| s > 0).count() as Real;
        let expected = ((SIZE - 2) as Real / 4.0).powi(2);
        assert!(
            (drawn / expected - 1.0).abs() < 0.05,
            "{drawn} against {expected}"
        );
        let svg = svg(&shade, "frame 0");
        // Each run is "M{x} {y}h{w}v1h-{w}z".
        let widths: usize = svg
            .split("v1h-")
            .skip(1)
            .map(|w| w.split('z').next().unwrap().parse::<usize>().unwrap())
            .sum();
        assert_eq!(widths as Real, drawn);
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
    }

    #[test]
    fn the_frames_shown_span_the_take() {
        assert_eq!(frames_shown(1), vec![0]);
        assert_eq!(frames_shown(2), vec![0, 1]);
        assert_eq!(frames_shown(10), vec![0, 3, 6, 9]);
    }
}
