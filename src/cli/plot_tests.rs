//! The plots of the report and of `metrics --plot`.

use super::*;
use crate::cli::test_support::assert_well_formed;
use voltrack::math::Real;

#[test]
fn irregularity_curve_is_well_formed_svg() {
    let values = [
        3.0,
        0.0,
        Real::INFINITY,
        1e-3,
        0.5,
        2.0,
        Real::NAN,
        1e-300,
        7e5,
    ];
    let svg = irregularity_curve_svg(&values);
    assert!(svg.starts_with("<svg"), "{svg}");
    assert!(svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("<polyline"));
    assert_well_formed(&svg);
    for bad in ["NaN", "nan", "inf", "Infinity"] {
        assert!(!svg.contains(bad), "{bad} in {svg}");
    }
    // One point per finite positive value (0 has no place on a log axis),
    // inside the picture, falling from left to right (most irregular first).
    let lines = polylines(&svg);
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0].len(), 6);
    for w in lines[0].windows(2) {
        assert!(w[0].0 < w[1].0 && w[0].1 <= w[1].1, "{:?}", lines[0]);
    }
    assert!(lines[0]
        .iter()
        .all(|&(x, y)| (0.0..=720.0).contains(&x) && (0.0..=420.0).contains(&y)));

    // Degenerate inputs still give a valid picture without NaN: nothing,
    // only zeros and infinities, one value, all equal.
    for values in [
        vec![],
        vec![0.0, Real::INFINITY, 0.0],
        vec![Real::INFINITY],
        vec![0.25],
        vec![2.0; 50],
    ] {
        let svg = irregularity_curve_svg(&values);
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{values:?}"
        );
        assert_well_formed(&svg);
        assert!(
            !svg.contains("NaN") && !svg.contains("inf"),
            "{values:?}: {svg}"
        );
        for line in polylines(&svg) {
            assert!(line.iter().all(|&(x, y)| x.is_finite() && y.is_finite()));
        }
    }

    // Several curves, with labels that need escaping.
    let svg = irregularity_curves_svg(&[
        ("before <refine> & after", &[1.0, 2.0, 3.0][..]),
        ("\"quoted\"", &[0.5, 0.25][..]),
    ]);
    assert_well_formed(&svg);
    assert_eq!(polylines(&svg).len(), 2);
    assert!(svg.contains("before &lt;refine&gt; &amp; after"));
}

#[test]
fn plots_for_the_report() {
    // Bars: labels escaped, unusable values drawn as empty bars.
    let svg = bar_chart(
        "Time <per> stage",
        "seconds",
        "s",
        &[
            ("read & parse".into(), 1.5),
            ("odd".into(), Real::NAN),
            ("none".into(), -2.0),
            ("track".into(), 12.0),
        ],
    );
    assert_well_formed(&svg);
    assert!(svg.contains("read &amp; parse") && svg.contains("Time &lt;per&gt; stage"));
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
    let widths: Vec<Real> = svg
        .lines()
        .filter(|l| l.starts_with("<rect x=") && !l.contains("fill=\"none\""))
        .map(|l| {
            l.split("width=\"")
                .nth(1)
                .unwrap()
                .split('"')
                .next()
                .unwrap()
                .parse()
                .unwrap()
        })
        .collect();
    assert_eq!(widths.len(), 4);
    assert!(
        widths[1] == 0.0 && widths[2] == 0.0 && widths[0] > 0.0 && widths[3] > 7.9 * widths[0],
        "{widths:?}"
    );
    assert!(svg.contains(">12.0 s</text>") && svg.contains(">1.50 s</text>"));

    let y_labels = |svg: &str| -> Vec<String> {
        svg.lines()
            .filter(|l| l.contains("text-anchor=\"end\""))
            .map(|l| {
                l.split('>')
                    .nth(1)
                    .unwrap()
                    .split('<')
                    .next()
                    .unwrap()
                    .to_string()
            })
            .collect()
    };
    let x_labels = |svg: &str| -> Vec<String> {
        svg.lines()
            .filter(|l| {
                l.starts_with("<text")
                    && l.contains("text-anchor=\"middle\"")
                    && !l.contains("font-size")
                    && !l.contains("rotate")
            })
            .map(|l| {
                l.split('>')
                    .nth(1)
                    .unwrap()
                    .split('<')
                    .next()
                    .unwrap()
                    .to_string()
            })
            .collect()
    };
    // A log axis spanning less than a decade still gets labelled ticks.
    let narrow = vec![Series::new(
        "I",
        vec![(0.0, 0.45), (1.0, 0.38), (2.0, 0.31)],
    )];
    let svg = line_plot(
        "narrow",
        &Axis::linear("rank").integer(),
        &Axis::log("I"),
        &narrow,
    );
    assert_well_formed(&svg);
    assert!(y_labels(&svg).len() >= 2, "{:?}", y_labels(&svg));
    // Whole-number ticks on an integer axis; 0 included on a from-zero axis.
    assert!(
        x_labels(&svg).iter().all(|l| !l.contains('.')),
        "{:?}",
        x_labels(&svg)
    );
    let svg = line_plot(
        "zero",
        &Axis::linear("frame").integer(),
        &Axis::linear("s").starting_at_zero(),
        &narrow,
    );
    assert_eq!(
        y_labels(&svg).first().map(String::as_str),
        Some("0.0"),
        "{:?}",
        y_labels(&svg)
    );

    // Lines through every corner: the legend gets a band of its own above them.
    let zigzag = vec![
        Series::new("up", vec![(0.0, 0.0), (1.0, 10.0), (2.0, 0.0), (3.0, 10.0)]),
        Series::new(
            "down",
            vec![(0.0, 10.0), (1.0, 0.0), (2.0, 10.0), (3.0, 0.0)],
        )
        .color(3)
        .dashed(),
    ];
    let svg = line_plot("corners", &Axis::linear("x"), &Axis::linear("y"), &zigzag);
    assert_well_formed(&svg);
    let legend = svg
        .lines()
        .find(|l| l.contains("fill-opacity"))
        .expect("a legend");
    let attr = |name: &str| -> Real {
        legend
            .split(&format!(" {name}=\""))
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let (lx, ly, lw, lh) = (attr("x"), attr("y"), attr("width"), attr("height"));
    for line in polylines(&svg) {
        for (x, y) in line {
            assert!(
                !(x >= lx && x <= lx + lw && y >= ly && y <= ly + lh),
                "({x}, {y}) under the legend at {lx} {ly} {lw} {lh}"
            );
        }
    }
    assert_eq!(
        svg.matches("stroke-dasharray").count(),
        2,
        "the dashed line and its legend entry"
    );
    assert_eq!(
        svg.matches("<circle").count(),
        8,
        "short series are marked point by point"
    );

    assert_eq!(significant(0.012345, 3), "0.0123");
    assert_eq!(significant(4.5678, 3), "4.57");
    assert_eq!(significant(1234.6, 3), "1235");
    assert_eq!(significant(0.0, 3), "0");
    assert_eq!(significant(2.5e-7, 2), "2.5e-7");
}

/// The numbers of every `points` attribute of the polylines.
fn polylines(svg: &str) -> Vec<Vec<(Real, Real)>> {
    svg.lines()
        .filter(|l| l.trim_start().starts_with("<polyline"))
        .map(|l| {
            let start = l.find("points=\"").unwrap() + 8;
            let end = start + l[start..].find('"').unwrap();
            l[start..end]
                .split_whitespace()
                .map(|xy| {
                    let (x, y) = xy.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}
