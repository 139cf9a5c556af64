//! The warnings of parts the tracking may have lost, from the unreached
//! volume ([`super::coverage`]) and the fit to the input
//! ([`super::fit_outliers`]), as `convert` and `track` print them.

use super::coverage::{runs, Coverage, FitOutliers};

/// One warning: the frames it names and the sentence shown to the user.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LostPartWarning {
    /// The frames warned of, in order.
    pub frames: Vec<usize>,
    pub message: String,
}

/// Frame numbers as runs: "3, 7-9".
pub fn frame_runs(frames: &[usize]) -> String {
    runs(frames).iter().map(|&(a, b)| if a == b { a.to_string() } else { format!("{a}-{b}") }).collect::<Vec<_>>().join(", ")
}

/// Warnings of parts the tracking may have lost. With the result's fit to
/// the input (`convert`), volume left unreached is warned of only where the
/// fit is bad too (within a frame): a few unreached voxels where the result
/// lies on the input are a cell lagging, not a part lost. Without it
/// (`track`), the unreached volume is all there is to go by.
pub fn lost_part_warnings(coverage: &Coverage, fit: Option<&FitOutliers>) -> Vec<LostPartWarning> {
    let mut out = Vec::new();
    let confirmed = |a: usize, b: usize| fit.is_none_or(|f| f.flagged.iter().any(|&k| k + 1 >= a && k <= b + 1));
    for (a, b) in coverage.flagged_runs() {
        if !confirmed(a, b) {
            log::info!("frames {a}-{b}: some input volume is not reached by any tracked cell, but the result fits the input there");
            continue;
        }
        let frames = &coverage.frames[a..=b];
        let worst = frames.iter().map(|c| c.lost_share).fold(0.0, f64::max);
        let region = frames.iter().map(|c| c.largest_region).max().unwrap_or(0) as f64 / coverage.cell_voxels.max(1e-12);
        let which = if a == b { format!("frame {a}") } else { format!("frames {a}-{b}") };
        out.push(LostPartWarning {
            frames: (a..=b).collect(),
            message: format!(
                "warning: {which}: up to {:.2} % of the input volume is not reached by any tracked cell (a connected region of {region:.1} cells' volume): \
                 a fast or thin part may have been lost, its centers left in the body or another part; check these frames, \
                 and try more --centers or a higher --resolution",
                100.0 * worst
            ),
        });
    }
    if let Some(fit) = fit.filter(|f| !f.flagged.is_empty()) {
        out.push(LostPartWarning {
            frames: fit.flagged.clone(),
            message: format!(
                "warning: frames {}: the result is far from the input (p95 distance above {:.2} % of the diagonal, against a usual {:.2} %): \
                 a part may have been lost or torn between two parts; --report FILE shows every frame's fit",
                frame_runs(&fit.flagged),
                fit.limit,
                fit.usual
            ),
        });
    }
    out
}
