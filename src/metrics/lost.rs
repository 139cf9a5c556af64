//! Frames where the result may have lost a part, and the warnings
//! `convert` and `track` print for them.
//!
//! A part the tracking lost shows in one of three ways, each checked on
//! its own in every frame, however well the rest of the frame fits (a lost
//! limb is a few percent of the surface, so no frame-wide figure shows it):
//! - input volume that no tracked cell reaches ([`super::coverage()`]): the
//!   part's centers left, and the cells nearest to it stretch across it;
//! - a connected region of the input's surface far from the result
//!   ([`super::FrameFit::far_input`]): the mesh's part is elsewhere;
//! - a connected region of the result's surface far from the input
//!   ([`super::FrameFit::far_result`]): the mesh holds a part, or a
//!   membrane torn between two, where the input has none.
//!
//! Frames whose fit is far worse than the sequence's usual
//! ([`super::fit_outliers`]) are warned of too, and so are the frames of a
//! run where a region of the result's surface outside the input's volume
//! passes a nearer distance frame after frame ([`LostParts::lasting`]),
//! and the frames next to a warned one where a far region passes a weaker
//! distance ([`LostParts::continued`]).

use super::coverage::{runs, Coverage, FitOutliers};
use super::fit::{FarDistances, FarRegion, SequenceFit};
use crate::math::Real;
use crate::params::CoverageParams;

/// What one frame shows of a lost part.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameLoss {
    /// Share of the frame's occupied volume that no tracked cell reaches,
    /// in connected regions ([`super::FrameCoverage::lost_share`]; in JSON
    /// `unreached_percent`, in percent).
    #[serde(rename = "unreached_percent", serialize_with = "super::as_percent")]
    pub unreached: Real,
    /// The largest region of the input's surface far from the result (None
    /// without a mesh).
    pub far_input: Option<FarRegion>,
    /// The largest region of the result's surface far from the input (None
    /// without a mesh).
    pub far_result: Option<FarRegion>,
    /// The largest regions past the weaker distances
    /// ([`super::FrameFit::weak_input`], `weak_result`; None without a
    /// mesh).
    pub weak_input: Option<FarRegion>,
    /// See `weak_input`.
    pub weak_result: Option<FarRegion>,
    /// The largest region of the result's surface past the distance of a
    /// lasting region ([`super::FrameFit::lasting_result`]; None without a
    /// mesh).
    pub lasting_result: Option<FarRegion>,
    /// The frame's fit is far worse than the sequence's usual.
    pub fit_outlier: bool,
}

/// Every frame's [`FrameLoss`] and the frames warned of.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LostParts {
    /// What each frame shows, in order.
    pub frames: Vec<FrameLoss>,
    /// Frames with unreached volume ([`Coverage::flagged`]).
    pub unreached: Vec<usize>,
    /// Frames with a far region of either surface of at least
    /// `params.far_share` percent of it.
    pub far: Vec<usize>,
    /// Frames whose fit is far worse than the usual.
    pub fit_outliers: Vec<usize>,
    /// Frames of runs of at least `params.lasting_frames` frames, each
    /// with a region of the result's surface as large past the nearer
    /// distance of [`CoverageParams::lasting`]: a part moved off the
    /// input's and left there.
    pub lasting: Vec<usize>,
    /// Frames warned of for none of those, but next to one that is (or to
    /// another of these), with a region of either surface as large past
    /// the weaker distances ([`CoverageParams::weak`]): where a lost part
    /// is on its way out or back.
    pub continued: Vec<usize>,
    /// All of those, in order.
    pub flagged: Vec<usize>,
    /// The distances past which a region counted as far
    /// ([`CoverageParams::far_distances`]; None without a fit).
    pub far_distances: Option<FarDistances>,
    /// The parameters measured with.
    pub params: CoverageParams,
}

/// Finds the frames with a lost part from the unreached volume and, when
/// the result's mesh was measured against the input (`fit`, with its
/// outliers), its far regions; by `coverage.params`, which `fit` and the
/// outliers must have been measured with.
pub fn lost_parts(coverage: &Coverage, fit: Option<(&SequenceFit, &FitOutliers)>) -> LostParts {
    let params = &coverage.params;
    let frames: Vec<FrameLoss> = (0..coverage.frames.len())
        .map(|f| {
            let frame_fit = fit.and_then(|(s, _)| s.frames.get(f));
            FrameLoss {
                unreached: coverage.frames[f].lost_share,
                far_input: frame_fit.map(|x| x.far_input),
                far_result: frame_fit.map(|x| x.far_result),
                weak_input: frame_fit.map(|x| x.weak_input),
                weak_result: frame_fit.map(|x| x.weak_result),
                lasting_result: frame_fit.map(|x| x.lasting_result),
                fit_outlier: fit.is_some_and(|(_, o)| o.flagged.contains(&f)),
            }
        })
        .collect();
    let far: Vec<usize> = frames
        .iter()
        .enumerate()
        .filter(|(_, x)| {
            [x.far_input, x.far_result]
                .iter()
                .any(|r| counts(*r, params))
        })
        .map(|(f, _)| f)
        .collect();
    let fit_outliers: Vec<usize> = fit.map(|(_, o)| o.flagged.clone()).unwrap_or_default();
    let marked: Vec<usize> = frames
        .iter()
        .enumerate()
        .filter(|(_, x)| counts(x.lasting_result, params))
        .map(|(f, _)| f)
        .collect();
    let lasting = lasting_runs(&marked, params.lasting_frames);
    let mut flagged: Vec<usize> = coverage
        .flagged
        .iter()
        .chain(&far)
        .chain(&fit_outliers)
        .chain(&lasting)
        .copied()
        .collect();
    flagged.sort_unstable();
    flagged.dedup();
    let weak: Vec<bool> = frames
        .iter()
        .map(|x| {
            [x.weak_input, x.weak_result]
                .iter()
                .any(|r| counts(*r, params))
        })
        .collect();
    let continued = carried_on(&flagged, &weak);
    flagged.extend(&continued);
    flagged.sort_unstable();
    LostParts {
        frames,
        unreached: coverage.flagged.clone(),
        far,
        fit_outliers,
        lasting,
        continued,
        flagged,
        far_distances: fit.map(|(s, _)| s.far),
        params: params.clone(),
    }
}

/// The frames of `marked` (sorted) in runs of at least `frames`
/// consecutive ones, in order.
fn lasting_runs(marked: &[usize], frames: usize) -> Vec<usize> {
    runs(marked)
        .into_iter()
        .filter(|&(a, b)| b - a + 1 >= frames)
        .flat_map(|(a, b)| a..=b)
        .collect()
}

/// The frames not in `flagged` (sorted) that `weak` marks and that join
/// a flagged frame through a run of marked frames, in order.
fn carried_on(flagged: &[usize], weak: &[bool]) -> Vec<usize> {
    let mut on = vec![false; weak.len()];
    for &f in flagged {
        on[f] = true;
    }
    let mut continued = Vec::new();
    let mut carry = |from: usize, to: usize| {
        if on[from] && !on[to] && weak[to] {
            on[to] = true;
            continued.push(to);
        }
    };
    // Forward then backward: each pass carries a warning along a run.
    for f in 1..weak.len() {
        carry(f - 1, f);
    }
    for f in (1..weak.len()).rev() {
        carry(f, f - 1);
    }
    continued.sort_unstable();
    continued
}

/// Whether `region` is large enough to warn of (`params.far_share`).
fn counts(region: Option<FarRegion>, params: &CoverageParams) -> bool {
    region.is_some_and(|r| r.vertices > 0 && r.share >= params.far_share)
}

/// One warning: the frames it names and the sentence shown to the user.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LostPartWarning {
    /// The frames warned of, in order.
    pub frames: Vec<usize>,
    /// The sentence shown to the user.
    pub message: String,
}

/// Frame numbers as runs: "3, 7-9".
pub fn frame_runs(frames: &[usize]) -> String {
    runs(frames)
        .iter()
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}-{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

impl LostParts {
    /// One warning per kind of evidence, naming its frames and the worst
    /// figure among them.
    pub fn warnings(&self) -> Vec<LostPartWarning> {
        let mut out = Vec::new();
        let largest =
            |frames: &[usize], of: &dyn Fn(&FrameLoss) -> Option<FarRegion>| {
                frames.iter().filter_map(|&f| of(&self.frames[f])).fold(
                    FarRegion::default(),
                    |a, b| if b.share > a.share { b } else { a },
                )
            };
        let far_input: Vec<usize> = self
            .far
            .iter()
            .copied()
            .filter(|&f| counts(self.frames[f].far_input, &self.params))
            .collect();
        if !far_input.is_empty() {
            let r = largest(&far_input, &|x| x.far_input);
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: a part of the input's surface lies far from the result (a connected region of up to {:.2} % of the surface, up to {:.1} % of the diagonal away): \
                     a part was lost or left behind there; check these frames, and try more --centers or a higher --resolution",
                    frame_runs(&far_input),
                    r.share,
                    r.farthest
                ),
                frames: far_input,
            });
        }
        let far_result: Vec<usize> = self
            .far
            .iter()
            .copied()
            .filter(|&f| counts(self.frames[f].far_result, &self.params))
            .collect();
        if !far_result.is_empty() {
            let r = largest(&far_result, &|x| x.far_result);
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: a part of the result lies far from the input's surface (a connected region of up to {:.2} % of it, up to {:.1} % of the diagonal away): \
                     a part was torn or carried where the input has none; check these frames",
                    frame_runs(&far_result),
                    r.share,
                    r.farthest
                ),
                frames: far_result,
            });
        }
        if !self.unreached.is_empty() {
            let worst = self
                .unreached
                .iter()
                .map(|&f| self.frames[f].unreached)
                .fold(0.0, Real::max);
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: up to {:.2} % of the input volume is not reached by any tracked cell: \
                     a fast or thin part may have been lost, its centers left in the body or another part; check these frames, \
                     and try more --centers or a higher --resolution",
                    frame_runs(&self.unreached),
                    100.0 * worst
                ),
                frames: self.unreached.clone(),
            });
        }
        // Whole runs, frames the far-region warning names among them, so
        // that every stretch listed is as long as the sentence says.
        if !self.lasting.is_empty() {
            let lasting = self.lasting.clone();
            let r = largest(&lasting, &|x| x.lasting_result);
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: for {} frames or more in a row, a part of the result lies outside the input's volume \
                     (a connected region of up to {:.2} % of its surface, up to {:.1} % of the diagonal away): \
                     a part has likely drifted off its place in the input; check these frames",
                    frame_runs(&lasting),
                    self.params.lasting_frames,
                    r.share,
                    r.farthest
                ),
                frames: lasting,
            });
        }
        if !self.continued.is_empty() {
            let r = largest(&self.continued, &|x| {
                let (i, r) = (
                    x.weak_input.unwrap_or_default(),
                    x.weak_result.unwrap_or_default(),
                );
                Some(if i.share >= r.share { i } else { r })
            });
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: next to frames warned of, a part of either surface lies nearly as far from the other \
                     (a connected region of up to {:.2} % of it, up to {:.1} % of the diagonal away): the part is likely lost there too",
                    frame_runs(&self.continued),
                    r.share,
                    r.farthest
                ),
                frames: self.continued.clone(),
            });
        }
        if !self.fit_outliers.is_empty() {
            out.push(LostPartWarning {
                message: format!(
                    "warning: frames {}: the result fits the input far worse than in the rest of the take: \
                     a part may have been lost or torn between two parts; --report FILE shows every frame's fit",
                    frame_runs(&self.fit_outliers)
                ),
                frames: self.fit_outliers.clone(),
            });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::coverage::FrameCoverage;
    use crate::metrics::fit::{DistanceSummary, FrameFit};

    /// [`lost_parts`] of a take with these frames' fits, nothing unreached
    /// and no fit outlier.
    fn lost_of(frames: Vec<FrameFit>, params: &CoverageParams) -> LostParts {
        let n = frames.len();
        let fit = SequenceFit {
            frames,
            diagonal: 1.0,
            far: params.far_distances(1.0, 0.001),
            seconds: 0.0,
        };
        let outliers = FitOutliers {
            p95: vec![0.0; n],
            usual: 0.0,
            limit: 1.0,
            flagged: Vec::new(),
        };
        let coverage = Coverage {
            frames: vec![FrameCoverage::default(); n],
            flagged: Vec::new(),
            cell_voxels: 1.0,
            params: params.clone(),
        };
        lost_parts(&coverage, Some((&fit, &outliers)))
    }

    fn region(share: Real, farthest: Real) -> FarRegion {
        FarRegion {
            share,
            vertices: 10,
            farthest,
        }
    }

    /// Frame 3 has a far region of the input; frames 1-2 and 4-5 one past
    /// the weaker distance only, as has frame 8 on its own; frame 6 has a
    /// weak region too small to count. The warning is carried from 3 to
    /// 1-5, not to 6 and not to 8, which joins no warned frame.
    #[test]
    fn weaker_evidence_carries_a_warning_on_but_starts_none() {
        let params = CoverageParams::default();
        let (strong, weak, tiny) = (region(0.5, 4.0), region(0.5, 1.5), region(0.01, 1.5));
        let none = FarRegion::default();
        let per_frame = [
            (none, none),
            (none, weak),
            (none, weak),
            (strong, weak),
            (none, weak),
            (none, weak),
            (none, tiny),
            (none, none),
            (none, weak),
            (none, none),
        ];
        let frames: Vec<FrameFit> = per_frame
            .iter()
            .enumerate()
            .map(|(f, &(far, weak))| FrameFit {
                result_to_input: DistanceSummary::default(),
                input_to_result: DistanceSummary::default(),
                two_sided: DistanceSummary::default(),
                far_input: far,
                far_result: none,
                // The weak regions alternate between the surfaces.
                weak_input: if f % 2 == 0 { weak } else { none },
                weak_result: if f % 2 == 1 { weak } else { none },
                lasting_result: none,
            })
            .collect();
        let lost = lost_of(frames, &params);
        assert_eq!(lost.far, [3]);
        assert_eq!(lost.continued, [1, 2, 4, 5]);
        assert_eq!(lost.flagged, [1, 2, 3, 4, 5]);
        let warnings = lost.warnings();
        let carried = warnings
            .iter()
            .find(|w| w.frames == lost.continued)
            .expect("a warning of the frames carried on");
        assert!(
            carried.message.contains("frames 1-2, 4-5"),
            "{}",
            carried.message
        );

        // Runs on either side, to the ends of the take.
        assert_eq!(
            carried_on(
                &[8],
                &[false, true, false, false, false, false, false, true, true, true]
            ),
            [7, 9]
        );
        assert_eq!(carried_on(&[0], &[true, true, true]), [1, 2]);
        assert_eq!(carried_on(&[2], &[true, true, false]), [0, 1]);
        assert!(carried_on(&[], &[true, true]).is_empty());
    }

    /// A region of the result past the lasting distance in frames 2-6 (as
    /// many as `lasting_frames`) is warned of there, the whole run listed
    /// though frame 4's is also past the far distance; the same in frames
    /// 9-11, two frames short, is not, nor frame 13's tiny one.
    #[test]
    fn a_far_result_region_that_lasts_is_warned_of() {
        let params = CoverageParams::default();
        assert_eq!(params.lasting_frames, 5);
        let (lasting, tiny, none) = (region(0.5, 3.5), region(0.01, 3.5), FarRegion::default());
        let frames: Vec<FrameFit> = (0..15)
            .map(|f| FrameFit {
                result_to_input: DistanceSummary::default(),
                input_to_result: DistanceSummary::default(),
                two_sided: DistanceSummary::default(),
                far_input: none,
                far_result: if f == 4 { lasting } else { none },
                weak_input: none,
                weak_result: none,
                lasting_result: match f {
                    2..=6 | 9..=11 => lasting,
                    13 => tiny,
                    _ => none,
                },
            })
            .collect();
        let lost = lost_of(frames, &params);
        assert_eq!(lost.lasting, [2, 3, 4, 5, 6]);
        assert_eq!(lost.flagged, [2, 3, 4, 5, 6]);
        let warnings = lost.warnings();
        assert_eq!(warnings.len(), 2);
        assert_eq!(warnings[0].frames, [4]);
        assert_eq!(warnings[1].frames, [2, 3, 4, 5, 6]);
        assert!(
            warnings[1]
                .message
                .contains("frames 2-6: for 5 frames or more"),
            "{}",
            warnings[1].message
        );

        // A run length of 1 is every marked frame.
        assert_eq!(lasting_runs(&[0, 1, 3], 2), [0, 1]);
        assert_eq!(lasting_runs(&[1, 2, 5, 6, 7], 3), [5, 6, 7]);
        assert_eq!(lasting_runs(&[0, 2], 1), [0, 2]);
        assert!(lasting_runs(&[], 3).is_empty());
    }
}
