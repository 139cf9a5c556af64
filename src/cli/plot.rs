//! Small standalone SVG line plots for people to look at (the irregularity
//! curve, per-frame measures). No fonts or scripts beyond what every browser
//! has, so a plot can be opened directly or inlined in an HTML report.

use std::fmt::Write;
use voltrack::math::Real;

/// One named polyline.
pub struct Series {
    pub label: String,
    /// (x, y) in data units; non-finite points (and y ≤ 0 on a log axis) are skipped.
    pub points: Vec<(Real, Real)>,
    /// Slot in the palette; None takes the series' position in the plot.
    pub color: Option<usize>,
    /// Dashed line, to tell apart two series that share a colour.
    pub dashed: bool,
}

impl Series {
    /// A solid line in the colour of its position.
    pub fn new(label: impl Into<String>, points: Vec<(Real, Real)>) -> Self {
        Series {
            label: label.into(),
            points,
            color: None,
            dashed: false,
        }
    }
    /// Drawn in palette colour `slot`.
    pub fn color(mut self, slot: usize) -> Self {
        self.color = Some(slot);
        self
    }
    /// Drawn dashed.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }
    /// Its colour, and its dash attribute (or ""), as the `k`-th series of a plot.
    fn stroke(&self, k: usize) -> (&'static str, &'static str) {
        let color = COLORS[self.color.unwrap_or(k) % COLORS.len()];
        (
            color,
            if self.dashed {
                r#" stroke-dasharray="6 4""#
            } else {
                ""
            },
        )
    }
}

/// An axis: its label, and how its range and ticks are chosen.
pub struct Axis {
    pub label: String,
    /// Logarithmic (base 10).
    pub log: bool,
    /// The range includes 0 (linear axes): for amounts such as seconds or
    /// distances, whose size matters, not only their variation.
    pub from_zero: bool,
    /// Ticks only at whole numbers (frame numbers, counts).
    pub integer: bool,
}

impl Axis {
    /// A linear axis spanning the data.
    pub fn linear(label: impl Into<String>) -> Self {
        Axis {
            label: label.into(),
            log: false,
            from_zero: false,
            integer: false,
        }
    }
    /// A logarithmic axis (base 10) spanning the data.
    pub fn log(label: impl Into<String>) -> Self {
        Axis {
            log: true,
            ..Axis::linear(label)
        }
    }
    /// Its range also covers 0.
    pub fn starting_at_zero(mut self) -> Self {
        self.from_zero = true;
        self
    }
    /// Ticks at whole numbers only.
    pub fn integer(mut self) -> Self {
        self.integer = true;
        self
    }
}

const WIDTH: Real = 720.0;
const HEIGHT: Real = 420.0;
const LEFT: Real = 80.0;
const RIGHT: Real = 20.0;
const TOP: Real = 40.0;
const BOTTOM: Real = 56.0;
const COLORS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b",
];
/// Series with at most this many points also get a dot per point, so a
/// short series (a few frames) reads as measurements, not as a curve.
const MARKED_POINTS: usize = 60;
/// Room left above the highest value, as a fraction of the range, so the
/// largest value is not drawn on the frame.
const HEADROOM: Real = 0.05;
/// Space between the legend and the plot's frame.
const LEGEND_MARGIN: Real = 6.0;

/// Draws `series` on shared axes, with ticks, a title and a legend (placed
/// in the corner the lines cross least).
pub fn line_plot(title: &str, x: &Axis, y: &Axis, series: &[Series]) -> String {
    let layout = Layout::of(x, y, series);
    let mut svg = svg_start(HEIGHT, title);
    layout.draw_axes(&mut svg, x, y);
    layout.draw_lines(&mut svg, series);
    // The legend goes last, on a translucent card, so no line hides it.
    if !series.is_empty() {
        layout.draw_legend(&mut svg, series);
    }
    svg.push_str("</svg>\n");
    svg
}

/// Where a line plot's data land: the ranges its axes show, each series'
/// points in pixels, and the legend's corner and size.
struct Layout {
    x0: Real,
    x1: Real,
    y0: Real,
    y1: Real,
    /// Each series' usable points in pixels.
    pixels: Vec<Vec<(Real, Real)>>,
    /// The legend's top-left corner.
    legend: (Real, Real),
    legend_size: (Real, Real),
}

impl Layout {
    /// The ranges of `series`' points that `x` and `y` can show (on a log
    /// axis, the positive ones), with headroom, and the legend in the corner
    /// the lines cross least; where every corner hides some of a line, the
    /// top of the range is raised until the legend's band above the data is
    /// free.
    fn of(x: &Axis, y: &Axis, series: &[Series]) -> Self {
        let map = |axis: &Axis, v: Real| if axis.log { v.log10() } else { v };
        let usable = |&(px, py): &(Real, Real)| {
            px.is_finite() && py.is_finite() && (!x.log || px > 0.0) && (!y.log || py > 0.0)
        };
        let data: Vec<Vec<(Real, Real)>> = series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .filter(|p| usable(p))
                    .map(|&(px, py)| (map(x, px), map(y, py)))
                    .collect()
            })
            .collect();
        let range = |axis: &Axis, pick: fn(&(Real, Real)) -> Real| {
            let (mut lo, mut hi) = data
                .iter()
                .flatten()
                .map(pick)
                .fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                });
            if !lo.is_finite() {
                return (0.0, 1.0);
            }
            if axis.from_zero && !axis.log {
                (lo, hi) = (lo.min(0.0), hi.max(0.0));
            }
            if hi - lo < 1e-12 * hi.abs().max(1.0) {
                (lo - 0.5, hi + 0.5)
            } else {
                (lo, hi)
            }
        };
        let (x0, x1) = range(x, |p| p.0);
        let (y0, y1) = range(y, |p| p.1);
        let y1 = y1 + HEADROOM * (y1 - y0);
        let y0 = if y.from_zero && y0 == 0.0 {
            y0
        } else {
            y0 - HEADROOM * (y1 - y0)
        };
        let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
        let sx = |v: Real| LEFT + (v - x0) / (x1 - x0) * pw;
        let to_pixels = |y0: Real, y1: Real| -> Vec<Vec<(Real, Real)>> {
            data.iter()
                .map(|points| {
                    points
                        .iter()
                        .map(|&(px, py)| (sx(px), TOP + ph - (py - y0) / (y1 - y0) * ph))
                        .collect()
                })
                .collect()
        };
        let legend_size = (
            34.0 + 7.0
                * series
                    .iter()
                    .map(|s| s.label.chars().count())
                    .max()
                    .unwrap_or(0) as Real,
            8.0 + 16.0 * series.len() as Real,
        );
        let mut pixels = to_pixels(y0, y1);
        let (mut legend, covered) = legend_corner(&pixels, legend_size, (LEFT, TOP, pw, ph));
        let y1 = if covered > 0 && !series.is_empty() {
            let free = (ph - legend_size.1 - 2.0 * LEGEND_MARGIN).max(ph / 2.0);
            let top = y0 + (y1 - y0) * ph / free;
            pixels = to_pixels(y0, top);
            legend = legend_corner(&pixels, legend_size, (LEFT, TOP, pw, ph)).0;
            top
        } else {
            y1
        };
        Layout {
            x0,
            x1,
            y0,
            y1,
            pixels,
            legend,
            legend_size,
        }
    }

    /// The plot's frame, the ticks and their labels, and the axes' labels.
    fn draw_axes(&self, svg: &mut String, x: &Axis, y: &Axis) {
        let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
        let sx = |v: Real| LEFT + (v - self.x0) / (self.x1 - self.x0) * pw;
        let sy = |v: Real| TOP + ph - (v - self.y0) / (self.y1 - self.y0) * ph;
        let _ = writeln!(
            svg,
            r##"<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##
        );
        for (v, label) in ticks(self.x0, self.x1, x) {
            let px = sx(v);
            let _ = writeln!(
                svg,
                r##"<line x1="{px:.1}" y1="{}" x2="{px:.1}" y2="{}" stroke="#444"/>"##,
                TOP + ph,
                TOP + ph + 5.0
            );
            let _ = writeln!(
                svg,
                r#"<text x="{px:.1}" y="{}" text-anchor="middle">{label}</text>"#,
                TOP + ph + 18.0
            );
        }
        for (v, label) in ticks(self.y0, self.y1, y) {
            let py = sy(v);
            let _ = writeln!(
                svg,
                r##"<line x1="{LEFT}" y1="{py:.1}" x2="{}" y2="{py:.1}" stroke="#ddd"/>"##,
                LEFT + pw
            );
            let _ = writeln!(
                svg,
                r#"<text x="{}" y="{:.1}" text-anchor="end">{label}</text>"#,
                LEFT - 6.0,
                py + 4.0
            );
        }
        let _ = writeln!(
            svg,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            LEFT + pw / 2.0,
            HEIGHT - 12.0,
            escape(&x.label)
        );
        let _ = writeln!(
            svg,
            r#"<text transform="translate(16 {}) rotate(-90)" text-anchor="middle">{}</text>"#,
            TOP + ph / 2.0,
            escape(&y.label)
        );
    }

    /// Each series as a line, with a dot per point when it has few.
    fn draw_lines(&self, svg: &mut String, series: &[Series]) {
        for (k, (s, points)) in series.iter().zip(&self.pixels).enumerate() {
            let (color, dash) = s.stroke(k);
            let path: Vec<String> = points
                .iter()
                .map(|&(px, py)| format!("{px:.1},{py:.1}"))
                .collect();
            let _ = writeln!(
                svg,
                r#"<polyline fill="none" stroke="{color}" stroke-width="1.5"{dash} points="{}"/>"#,
                path.join(" ")
            );
            if points.len() <= MARKED_POINTS {
                for &(px, py) in points {
                    let _ = writeln!(
                        svg,
                        r#"<circle cx="{px:.1}" cy="{py:.1}" r="2.5" fill="{color}"/>"#
                    );
                }
            }
        }
    }

    /// The legend: a card with each series' stroke and label.
    fn draw_legend(&self, svg: &mut String, series: &[Series]) {
        let ((lx, top), (width, height)) = (self.legend, self.legend_size);
        let _ = writeln!(
            svg,
            r##"<rect x="{lx:.1}" y="{top:.1}" width="{width:.1}" height="{height}" fill="white" fill-opacity="0.85" stroke="#ccc"/>"##
        );
        for (k, s) in series.iter().enumerate() {
            let (color, dash) = s.stroke(k);
            let ly = top + 12.0 + 16.0 * k as Real;
            let _ = writeln!(
                svg,
                r#"<line x1="{:.1}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{color}" stroke-width="2"{dash}/>"#,
                lx + 6.0,
                lx + 26.0
            );
            let _ = writeln!(
                svg,
                r#"<text x="{:.1}" y="{:.1}">{}</text>"#,
                lx + 32.0,
                ly + 4.0,
                escape(&s.label)
            );
        }
    }
}

/// The top-left corner of a legend of `(width, height)` in whichever corner
/// of the plot area `(left, top, width, height)` covers the fewest points of
/// the lines (sampled along each segment), top right among equals; and how
/// many points it covers.
fn legend_corner(
    lines: &[Vec<(Real, Real)>],
    (width, height): (Real, Real),
    (left, top, pw, ph): (Real, Real, Real, Real),
) -> ((Real, Real), usize) {
    let (right, bottom) = (
        left + pw - width - LEGEND_MARGIN,
        top + ph - height - LEGEND_MARGIN,
    );
    let corners = [
        (right, top + LEGEND_MARGIN),
        (left + LEGEND_MARGIN, top + LEGEND_MARGIN),
        (right, bottom),
        (left + LEGEND_MARGIN, bottom),
    ];
    let covered = |&(cx, cy): &(Real, Real)| {
        let inside = |(px, py): (Real, Real)| {
            px >= cx - 4.0 && px <= cx + width + 4.0 && py >= cy - 4.0 && py <= cy + height + 4.0
        };
        lines
            .iter()
            .map(|points| {
                let single = points.len() == 1 && inside(points[0]);
                let along = points
                    .windows(2)
                    .flat_map(|w| {
                        (0..8).map(move |k| {
                            (
                                w[0].0 + (w[1].0 - w[0].0) * k as Real / 8.0,
                                w[0].1 + (w[1].1 - w[0].1) * k as Real / 8.0,
                            )
                        })
                    })
                    .chain(points.last().copied())
                    .filter(|&p| inside(p))
                    .count();
                usize::from(single) + along
            })
            .sum::<usize>()
    };
    corners
        .iter()
        .map(|c| (*c, covered(c)))
        .min_by_key(|&(_, n)| n)
        .expect("four corners")
}

/// Horizontal bars, one per `(label, value)` from the top, each with its
/// value (and `unit`) written at its end: a few named quantities, such as
/// the time each stage took. Non-finite and negative values draw as 0.
pub fn bar_chart(title: &str, value_axis: &str, unit: &str, bars: &[(String, Real)]) -> String {
    const LABELS: Real = 110.0;
    const BAR: Real = 22.0;
    const GAP: Real = 10.0;
    const VALUES: Real = 90.0;
    let value = |v: Real| if v.is_finite() && v > 0.0 { v } else { 0.0 };
    let largest = bars.iter().map(|b| value(b.1)).fold(0.0, Real::max);
    let top = if largest > 0.0 { largest } else { 1.0 };
    let height = TOP + bars.len() as Real * (BAR + GAP) + BOTTOM;
    let pw = WIDTH - LABELS - RIGHT - VALUES;
    let sx = |v: Real| LABELS + v / top * pw;
    let axis_y = TOP + bars.len() as Real * (BAR + GAP);

    let mut svg = svg_start(height, title);
    for (v, label) in linear_ticks(0.0, top, false) {
        let px = sx(v);
        let _ = writeln!(
            svg,
            r##"<line x1="{px:.1}" y1="{TOP}" x2="{px:.1}" y2="{}" stroke="#ddd"/>"##,
            axis_y + 5.0
        );
        let _ = writeln!(
            svg,
            r#"<text x="{px:.1}" y="{}" text-anchor="middle">{label}</text>"#,
            axis_y + 18.0
        );
    }
    for (k, (label, v)) in bars.iter().enumerate() {
        let y = TOP + GAP / 2.0 + k as Real * (BAR + GAP);
        let w = sx(value(*v)) - LABELS;
        let color = COLORS[k % COLORS.len()];
        let _ = writeln!(
            svg,
            r#"<text x="{}" y="{:.1}" text-anchor="end">{}</text>"#,
            LABELS - 8.0,
            y + BAR / 2.0 + 4.0,
            escape(label)
        );
        let _ = writeln!(
            svg,
            r#"<rect x="{LABELS}" y="{y:.1}" width="{w:.1}" height="{BAR}" fill="{color}"/>"#
        );
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}">{} {}</text>"#,
            LABELS + w + 6.0,
            y + BAR / 2.0 + 4.0,
            significant(value(*v), 3),
            escape(unit)
        );
    }
    let _ = writeln!(
        svg,
        r##"<line x1="{LABELS}" y1="{TOP}" x2="{LABELS}" y2="{axis_y}" stroke="#444"/>"##
    );
    let _ = writeln!(
        svg,
        r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
        LABELS + pw / 2.0,
        height - 12.0,
        escape(value_axis)
    );
    svg.push_str("</svg>\n");
    svg
}

/// `v` with `digits` significant digits, without exponent for everyday
/// magnitudes (1e-3 to 1e6): 0.0123, 4.56; whole numbers keep all their
/// digits (1235).
pub fn significant(v: Real, digits: usize) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { v.to_string() };
    }
    let magnitude = v.abs().log10().floor() as i32;
    if !(-3..6).contains(&magnitude) {
        return format!("{:.*e}", digits.saturating_sub(1), v);
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{v:.decimals$}")
}

/// About five ticks at round values in [lo, hi] (mapped units), labelled in
/// data units: on a log axis powers of ten, or 1-2-5 steps when the range
/// spans less than two decades.
fn ticks(lo: Real, hi: Real, axis: &Axis) -> Vec<(Real, String)> {
    if axis.log {
        let (a, b) = (lo.ceil() as i32, hi.floor() as i32);
        if b - a >= 1 {
            let step = ((b - a) / 6 + 1).max(1);
            return (a..=b)
                .step_by(step as usize)
                .map(|e| (e as Real, format!("1e{e}")))
                .collect();
        }
        let (coarse, fine): (&[Real], &[Real]) = (
            &[1.0, 2.0, 5.0],
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        );
        for mantissas in [coarse, fine] {
            let found: Vec<(Real, String)> = (lo.floor() as i32..=hi.ceil() as i32)
                .flat_map(|e| mantissas.iter().map(move |&m| (e, m)))
                .map(|(e, m): (i32, Real)| (m.log10() + e as Real, log_label(m, e)))
                .filter(|(v, _)| *v >= lo && *v <= hi)
                .collect();
            if found.len() >= 2 {
                return found;
            }
        }
        // Less than a factor of two: round values of the data themselves.
        return linear_ticks(Real::powf(10.0, lo), Real::powf(10.0, hi), false)
            .into_iter()
            .map(|(v, l)| (v.log10(), l))
            .collect();
    }
    linear_ticks(lo, hi, axis.integer)
}

fn linear_ticks(lo: Real, hi: Real, integer: bool) -> Vec<(Real, String)> {
    let raw = (hi - lo) / 5.0;
    let magnitude = Real::powi(10.0, raw.log10().floor() as i32);
    let mut step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * magnitude)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * magnitude);
    if integer {
        step = step.max(1.0).round();
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let first = (lo / step).ceil() as i64;
    (first..)
        .map(|k| k as Real * step)
        .take_while(|&v| v <= hi + 1e-9 * step)
        .take(20)
        .map(|v| (v, format!("{v:.decimals$}")))
        .collect()
}

/// m × 10^e, plainly for everyday magnitudes.
fn log_label(m: Real, e: i32) -> String {
    if (-3..5).contains(&e) {
        significant(m * Real::powi(10.0, e), 1)
    } else {
        format!("{m}e{e}")
    }
}

/// `s` safe as XML/HTML text or a quoted attribute value.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The opening of a plot: the root element, a white background and the title.
fn svg_start(height: Real, title: &str) -> String {
    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" viewBox="0 0 {WIDTH} {height}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#,
        WIDTH / 2.0,
        escape(title)
    );
    svg
}

/// The irregularity curve (I_i sorted in decreasing order, log scale) as a
/// standalone SVG, optionally against other curves (label, values) for
/// comparison; a better result's curve falls faster.
pub fn irregularity_curve_svg(irregularity: &[Real]) -> String {
    irregularity_curves_svg(&[("centers", irregularity)])
}

/// Several irregularity curves in one plot, e.g. before and after refinement.
pub fn irregularity_curves_svg(curves: &[(&str, &[Real])]) -> String {
    let series: Vec<Series> = curves
        .iter()
        .map(|(label, values)| {
            let mut v: Vec<Real> = values.iter().copied().filter(|x| x.is_finite()).collect();
            v.sort_by(|a, b| b.total_cmp(a));
            Series::new(
                *label,
                v.iter().enumerate().map(|(r, &x)| (r as Real, x)).collect(),
            )
        })
        .collect();
    line_plot(
        "Irregularity curve",
        &Axis::linear("rank (most irregular first)").integer(),
        &Axis::log("I_i (squared length, log scale)"),
        &series,
    )
}

#[cfg(test)]
#[path = "plot_tests.rs"]
mod tests;
