//! Small standalone SVG line plots for people to look at (the irregularity
//! curve, per-frame measures). No fonts or scripts beyond what every browser
//! has, so a plot can be opened directly or inlined in an HTML report.

use crate::math::Real;
use std::fmt::Write;

/// One named polyline.
pub struct Series {
    pub label: String,
    /// (x, y) in data units; non-finite points (and y ≤ 0 on a log axis) are skipped.
    pub points: Vec<(Real, Real)>,
}

/// An axis: its label and whether it is logarithmic (base 10).
pub struct Axis {
    pub label: String,
    pub log: bool,
}

const WIDTH: Real = 720.0;
const HEIGHT: Real = 420.0;
const LEFT: Real = 80.0;
const RIGHT: Real = 20.0;
const TOP: Real = 40.0;
const BOTTOM: Real = 56.0;
const COLORS: [&str; 6] = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b"];

/// Draws `series` on shared axes, with ticks, a title and a legend.
pub fn line_plot(title: &str, x: &Axis, y: &Axis, series: &[Series]) -> String {
    let map = |axis: &Axis, v: Real| if axis.log { v.log10() } else { v };
    let usable = |&(px, py): &(Real, Real)| {
        px.is_finite() && py.is_finite() && (!x.log || px > 0.0) && (!y.log || py > 0.0)
    };
    let data: Vec<Vec<(Real, Real)>> = series
        .iter()
        .map(|s| s.points.iter().filter(|p| usable(p)).map(|&(px, py)| (map(x, px), map(y, py))).collect())
        .collect();
    let range = |pick: fn(&(Real, Real)) -> Real| {
        let (lo, hi) = data.iter().flatten().map(pick).fold((Real::INFINITY, Real::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if !lo.is_finite() {
            (0.0, 1.0)
        } else if hi - lo < 1e-12 * hi.abs().max(1.0) {
            (lo - 0.5, hi + 0.5)
        } else {
            (lo, hi)
        }
    };
    let (x0, x1) = range(|p| p.0);
    let (y0, y1) = range(|p| p.1);
    let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
    let sx = |v: Real| LEFT + (v - x0) / (x1 - x0) * pw;
    let sy = |v: Real| TOP + ph - (v - y0) / (y1 - y0) * ph;

    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(svg, r#"<text x="{}" y="22" text-anchor="middle" font-size="15">{}</text>"#, WIDTH / 2.0, escape(title));
    let _ = writeln!(svg, r##"<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##);
    for (v, label) in ticks(x0, x1, x.log) {
        let px = sx(v);
        let _ = writeln!(svg, r##"<line x1="{px:.1}" y1="{}" x2="{px:.1}" y2="{}" stroke="#444"/>"##, TOP + ph, TOP + ph + 5.0);
        let _ = writeln!(svg, r#"<text x="{px:.1}" y="{}" text-anchor="middle">{label}</text>"#, TOP + ph + 18.0);
    }
    for (v, label) in ticks(y0, y1, y.log) {
        let py = sy(v);
        let _ = writeln!(svg, r##"<line x1="{LEFT}" y1="{py:.1}" x2="{}" y2="{py:.1}" stroke="#ddd"/>"##, LEFT + pw);
        let _ = writeln!(svg, r#"<text x="{}" y="{:.1}" text-anchor="end">{label}</text>"#, LEFT - 6.0, py + 4.0);
    }
    let _ = writeln!(svg, r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#, LEFT + pw / 2.0, HEIGHT - 12.0, escape(&x.label));
    let _ = writeln!(
        svg,
        r#"<text transform="translate(16 {}) rotate(-90)" text-anchor="middle">{}</text>"#,
        TOP + ph / 2.0,
        escape(&y.label)
    );
    for (k, (s, points)) in series.iter().zip(&data).enumerate() {
        let color = COLORS[k % COLORS.len()];
        let path: Vec<String> = points.iter().map(|&(px, py)| format!("{:.1},{:.1}", sx(px), sy(py))).collect();
        let _ = writeln!(svg, r#"<polyline fill="none" stroke="{color}" stroke-width="1.5" points="{}"/>"#, path.join(" "));
        let ly = TOP + 16.0 + 16.0 * k as Real;
        let lx = LEFT + pw - 170.0;
        let _ = writeln!(svg, r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{color}" stroke-width="2"/>"#, lx + 20.0);
        let _ = writeln!(svg, r#"<text x="{}" y="{}">{}</text>"#, lx + 26.0, ly + 4.0, escape(&s.label));
    }
    svg.push_str("</svg>\n");
    svg
}

/// About five ticks at round values in [lo, hi] (mapped units), labelled in
/// data units; powers of ten on a log axis.
fn ticks(lo: Real, hi: Real, log: bool) -> Vec<(Real, String)> {
    if log {
        let (a, b) = (lo.ceil() as i32, hi.floor() as i32);
        let step = ((b - a) / 6 + 1).max(1);
        return (a..=b).step_by(step as usize).map(|e| (e as Real, format!("1e{e}"))).collect();
    }
    let raw = (hi - lo) / 5.0;
    let magnitude = Real::powi(10.0, raw.log10().floor() as i32);
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * magnitude).find(|&s| s >= raw).unwrap_or(10.0 * magnitude);
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let first = (lo / step).ceil() as i64;
    (first..)
        .map(|k| k as Real * step)
        .take_while(|&v| v <= hi + 1e-9 * step)
        .take(20)
        .map(|v| (v, format!("{v:.decimals$}")))
        .collect()
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
