//! Segments (issue 47): stretches of a take that one reference mesh cannot
//! serve. Deforming one frame's mesh keeps its parts: where the input's
//! parts later merge (a ball pressed into a slab), both surfaces stay,
//! hidden inside the merged volume; where they part, a merged reference
//! stretches a membrane between them. So the take is cut where the number of
//! its solid's parts changes, each stretch deforms a mesh of its own (the
//! first of its frames whose parts are most separate), and the dynamic mesh
//! is their union: in every frame the other segments' vertices all sit on
//! one vertex of the shown segment, their triangles without area, drawn as
//! nothing by any player. One connectivity for the whole take, as
//! compression and every output format need. Frames next to a change that
//! their stretch's mesh does not serve (the fit finds a far region) are cut
//! off into segments of their own ([`split_where_far`]).

use crate::error::Result;
use crate::model::{DynamicMesh, Frame, FrameSource, PositionFrames, TriangleMesh};
use crate::voxel::FrameTopology;
use std::ops::Range;

/// One stretch of frames and the frame whose mesh it deforms.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Segment {
    /// Its frames, `start..end`.
    pub frames: Range<usize>,
    /// The frame whose mesh it deforms, in `frames`.
    pub reference: usize,
    /// Its frames' parts.
    pub parts: usize,
}

/// `frames 0-17 from 8 (2 parts)`: its frames, the frame it deforms, its parts.
impl std::fmt::Display for Segment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "frames {}-{} from {} ({} part{})",
            self.frames.start,
            self.frames.end - 1,
            self.reference,
            self.parts,
            if self.parts == 1 { "" } else { "s" }
        )
    }
}

/// Fewest frames a segment holds: a change of parts shorter than this
/// (two surfaces brushing for a frame) joins the stretch before it.
pub const MIN_SEGMENT_FRAMES: usize = 3;

/// The segments of a take whose frames have `topology`, tracked from
/// `reference`: stretches of one part count, those shorter than
/// [`MIN_SEGMENT_FRAMES`] joined to the one before (the first to the one
/// after); each deforms the frame nearest its middle of those with the
/// most parts less tunnels. One segment (the whole take, deforming
/// `reference`) when the parts never change.
pub fn plan_segments(topology: &[FrameTopology], reference: usize) -> Vec<Segment> {
    let frames = topology.len();
    let mut runs: Vec<(Range<usize>, usize)> = Vec::new();
    for (f, t) in topology.iter().enumerate() {
        match runs.last_mut() {
            Some((range, parts)) if *parts == t.parts => range.end = f + 1,
            _ => runs.push((f..f + 1, t.parts)),
        }
    }
    // Short runs join a neighbour, shortest first, until none is left.
    while runs.len() > 1 {
        let Some(k) = (0..runs.len())
            .filter(|&k| runs[k].0.len() < MIN_SEGMENT_FRAMES)
            .min_by_key(|&k| (runs[k].0.len(), k))
        else {
            break;
        };
        // Into the run before it, or the first into the one after.
        let (range, _) = runs.remove(k);
        let joined = &mut runs[k.saturating_sub(1)].0;
        *joined = joined.start.min(range.start)..joined.end.max(range.end);
        // Neighbours with the same parts are one stretch.
        let mut merged: Vec<(Range<usize>, usize)> = Vec::new();
        for (range, parts) in runs.drain(..) {
            match merged.last_mut() {
                Some((r, p)) if *p == parts => r.end = range.end,
                _ => merged.push((range, parts)),
            }
        }
        runs = merged;
    }
    if runs.len() <= 1 {
        return vec![Segment {
            frames: 0..frames,
            reference,
            parts: topology.get(reference).map_or(0, |t| t.parts),
        }];
    }
    runs.into_iter()
        .map(|(frames, parts)| {
            let reference = most_separate_near_middle(topology, frames.clone());
            Segment {
                frames,
                reference,
                parts,
            }
        })
        .collect()
}

/// `segments` cut again where their meshes cannot serve some frames:
/// `far` (sorted), the frames where a region of either surface lies far from
/// the other (`metrics::LostParts::far`), as it does where the parts merge
/// or part and the stretch's mesh, from its middle, shows them whole or
/// apart. Each run of such frames becomes a segment deforming its own
/// middle frame; what is left of a stretch on either side keeps the
/// stretch's reference where it holds it, else deforms its own middle.
/// The segments unchanged when no frame is far.
pub fn split_where_far(segments: &[Segment], far: &[usize]) -> Vec<Segment> {
    let mut out = Vec::with_capacity(segments.len());
    for s in segments {
        let is_far = |f: usize| far.binary_search(&f).is_ok();
        let mut start = s.frames.start;
        while start < s.frames.end {
            let kind = is_far(start);
            let end = (start..s.frames.end)
                .find(|&f| is_far(f) != kind)
                .unwrap_or(s.frames.end);
            let frames = start..end;
            let reference = if !kind && frames.contains(&s.reference) {
                s.reference
            } else {
                start + (end - start - 1) / 2
            };
            out.push(Segment {
                frames,
                reference,
                parts: s.parts,
            });
            start = end;
        }
    }
    out
}

/// Of the frames `frames` (non-empty, indices into `topology`), the one
/// nearest their middle among those of the most parts less tunnels (the
/// earlier of two as near): the mesh deformed from it goes least far to
/// either end.
pub fn most_separate_near_middle(topology: &[FrameTopology], frames: Range<usize>) -> usize {
    let best = frames
        .clone()
        .map(|f| topology[f].separation())
        .max()
        .expect("at least one frame");
    let middle = frames.start + (frames.len() - 1) / 2;
    frames
        .filter(|&f| topology[f].separation() == best)
        .min_by_key(|&f| f.abs_diff(middle))
        .expect("the best is one of them")
}

/// The frames `range` of `source`, as a source of their own.
pub struct FrameRange<'a> {
    /// The whole sequence.
    pub source: &'a dyn FrameSource,
    /// The frames of `source` this one holds; its frame 0 is `range.start`.
    pub range: Range<usize>,
}

impl FrameSource for FrameRange<'_> {
    fn len(&self) -> usize {
        self.range.len()
    }
    fn name(&self, f: usize) -> String {
        self.source.name(self.range.start + f)
    }
    fn frame(&self, f: usize) -> Result<Frame> {
        self.source.frame(self.range.start + f)
    }
}

/// The union of the segments' dynamic meshes (each over its own frames, in
/// the order of `segments`), over the whole take, tracked from `reference`:
/// in each frame the shown segment's vertices where its mesh has them, every
/// other segment's on a point of its own that does not move while it is
/// hidden (its first vertex in its first frame): its triangles have no area,
/// and a file that stores each frame's change from the one before (a
/// compressed GLB's steps) stores nothing for it. `memory` as
/// [`crate::params::DeformParams::memory`].
pub fn union_of_segments(
    segments: &[Segment],
    meshes: Vec<DynamicMesh>,
    reference: usize,
    memory: usize,
) -> Result<DynamicMesh> {
    let sizes: Vec<usize> = meshes.iter().map(|m| m.base.positions.len()).collect();
    let offsets: Vec<usize> = sizes
        .iter()
        .scan(0, |total, &n| {
            let at = *total;
            *total += n;
            Some(at)
        })
        .collect();
    let total: usize = sizes.iter().sum();
    let frames = segments.last().map_or(0, |s| s.frames.end);
    let mut base = TriangleMesh::default();
    let all_normals = meshes.iter().all(|m| m.base.normals.is_some());
    let mut normals = Vec::new();
    for (m, &offset) in meshes.iter().zip(&offsets) {
        base.positions.extend_from_slice(&m.base.positions);
        base.triangles.extend(
            m.base
                .triangles
                .iter()
                .map(|t| t.map(|i| i + offset as u32)),
        );
        if let (true, Some(n)) = (all_normals, &m.base.normals) {
            normals.extend_from_slice(n);
        }
    }
    base.normals = all_normals.then_some(normals);
    let rest = meshes
        .iter()
        .map(|m| Ok(m.frames.get(0)?.first().copied().unwrap_or_default()))
        .collect::<Result<Vec<_>>>()?;
    let mut out = PositionFrames::new(total, frames, memory)?;
    for (s, (segment, mesh)) in segments.iter().zip(&meshes).enumerate() {
        for f in segment.frames.clone() {
            let shown = mesh.frames.get(f - segment.frames.start)?;
            let mut positions = Vec::with_capacity(total);
            for (t, &size) in sizes.iter().enumerate() {
                if t == s {
                    positions.extend_from_slice(&shown);
                } else {
                    positions.extend(std::iter::repeat_n(rest[t], size));
                }
            }
            out.push(positions)?;
        }
    }
    Ok(DynamicMesh {
        base,
        frames: out,
        reference,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topology(parts: &[usize]) -> Vec<FrameTopology> {
        parts
            .iter()
            .map(|&parts| FrameTopology {
                parts,
                ..Default::default()
            })
            .collect()
    }

    #[test]
    fn far_frames_get_segments_of_their_own() {
        let two = [
            Segment {
                frames: 0..10,
                reference: 5,
                parts: 1,
            },
            Segment {
                frames: 10..16,
                reference: 13,
                parts: 2,
            },
        ];
        assert_eq!(split_where_far(&two, &[]), two.to_vec());
        let split = split_where_far(&two, &[8, 9, 10, 15]);
        let seg = |frames: Range<usize>, reference, parts| Segment {
            frames,
            reference,
            parts,
        };
        assert_eq!(
            split,
            [
                seg(0..8, 5, 1),
                seg(8..10, 8, 1),
                seg(10..11, 10, 2),
                seg(11..15, 13, 2),
                seg(15..16, 15, 2),
            ]
        );
        // A stretch left without its reference deforms its own middle.
        assert_eq!(split_where_far(&two[..1], &[4, 5])[2], seg(6..10, 7, 1));
    }

    #[test]
    fn segments_follow_the_parts_and_skip_brief_changes() {
        // One part count throughout: one segment, from the tracking's reference.
        let one = plan_segments(&topology(&[1; 6]), 2);
        assert_eq!(
            one,
            vec![Segment {
                frames: 0..6,
                reference: 2,
                parts: 1
            }]
        );
        // Two frames of contact are not a segment of their own.
        let brief = plan_segments(&topology(&[2, 2, 2, 1, 1, 2, 2, 2]), 0);
        assert_eq!(brief.len(), 1);
        // Apart, merged, apart: three segments, each from its middle.
        let s = plan_segments(&topology(&[1, 1, 1, 2, 2, 2, 2, 1, 1, 1, 1]), 4);
        let frames: Vec<_> = s
            .iter()
            .map(|s| (s.frames.clone(), s.reference, s.parts))
            .collect();
        assert_eq!(frames, vec![(0..3, 1, 1), (3..7, 4, 2), (7..11, 8, 1)]);
    }
}
