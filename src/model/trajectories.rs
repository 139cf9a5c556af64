//! Center positions over all frames: the tracker's result.

use crate::math::Point3;

/// Positions of `centers` volume elements in each of `frames` frames, stored
/// frame-major (`positions[f * centers + i]` is center i in frame f).
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectories {
    /// Number of frames.
    pub frames: usize,
    /// Number of centers, the same in every frame.
    pub centers: usize,
    /// Every center's position in every frame, frame-major, in the input's
    /// units.
    pub positions: Vec<Point3>,
    /// The frame the centers were placed in and tracked from, forward and
    /// backward (`params::Reference`); the dynamic mesh deforms this
    /// frame's mesh. 0 unless the tracking chose another.
    pub reference: usize,
}

impl Trajectories {
    /// `centers` centers in each of `frames` frames, all at the origin,
    /// tracked from frame 0.
    pub fn new(frames: usize, centers: usize) -> Self {
        Trajectories {
            frames,
            centers,
            positions: vec![Point3::origin(); frames * centers],
            reference: 0,
        }
    }

    /// Builds from one `Vec` of center positions per frame (all the same length).
    pub fn from_frames(frames: Vec<Vec<Point3>>) -> Self {
        let centers = frames.first().map_or(0, Vec::len);
        assert!(
            frames.iter().all(|f| f.len() == centers),
            "every frame needs the same number of centers"
        );
        Trajectories {
            frames: frames.len(),
            centers,
            positions: frames.into_iter().flatten().collect(),
            reference: 0,
        }
    }

    /// Position of center `center` in frame `frame`.
    #[inline]
    pub fn get(&self, frame: usize, center: usize) -> Point3 {
        self.positions[frame * self.centers + center]
    }

    /// Sets the position of center `center` in frame `frame`.
    #[inline]
    pub fn set(&mut self, frame: usize, center: usize, p: Point3) {
        self.positions[frame * self.centers + center] = p;
    }

    /// All centers in one frame.
    pub fn frame(&self, frame: usize) -> &[Point3] {
        &self.positions[frame * self.centers..(frame + 1) * self.centers]
    }

    /// All centers in one frame, to change.
    pub fn frame_mut(&mut self, frame: usize) -> &mut [Point3] {
        &mut self.positions[frame * self.centers..(frame + 1) * self.centers]
    }

    /// The frames `frames` alone, tracked from `reference` among them
    /// (counted from `frames.start`).
    pub fn window(&self, frames: std::ops::Range<usize>, reference: usize) -> Trajectories {
        Trajectories {
            frames: frames.len(),
            centers: self.centers,
            positions: self.positions[frames.start * self.centers..frames.end * self.centers]
                .to_vec(),
            reference,
        }
    }

    /// One center's path through all frames.
    pub fn trajectory(&self, center: usize) -> impl Iterator<Item = Point3> + '_ {
        (0..self.frames).map(move |f| self.get(f, center))
    }

    /// Removes the given centers (indices into this set), keeping the others'
    /// order, in place: a long sequence's trajectories are not copied.
    /// Returns the kept centers' former indices, in their new order.
    pub fn remove_centers(&mut self, removed: &[usize]) -> Vec<usize> {
        let keep: Vec<usize> = (0..self.centers).filter(|i| !removed.contains(i)).collect();
        let (n, m) = (self.centers, keep.len());
        // Each kept position moves to an index at most its own: forward
        // order never overwrites one still to be moved.
        for f in 0..self.frames {
            for (k, &i) in keep.iter().enumerate() {
                self.positions[f * m + k] = self.positions[f * n + i];
            }
        }
        self.positions.truncate(self.frames * m);
        self.centers = m;
        keep
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Real;

    #[test]
    fn removing_centers_keeps_the_others_in_order_and_names_them() {
        let (frames, centers) = (3, 6);
        let mut t = Trajectories::new(frames, centers);
        for f in 0..frames {
            for (i, p) in t.frame_mut(f).iter_mut().enumerate() {
                *p = Point3::new(f as Real, i as Real, (10 * f + i) as Real);
            }
        }
        let kept = t.remove_centers(&[4, 0, 2]);
        assert_eq!(kept, vec![1, 3, 5]);
        assert_eq!(t.centers, 3);
        for f in 0..frames {
            for (k, &i) in kept.iter().enumerate() {
                assert_eq!(
                    t.get(f, k),
                    Point3::new(f as Real, i as Real, (10 * f + i) as Real)
                );
            }
        }
    }
}
