//! The HTML report, rendered from a real conversion of the bundled bar.

use super::*;
use crate::cli::test_support::{assert_well_formed, Scratch};
use std::path::{Path, PathBuf};
use voltrack::fixtures::BENDING_BAR_FRAMES;
use voltrack::metrics::DistanceSummary;
use voltrack::params::{ConformParams, DeformParams, RefineParams, TrackParams};
use voltrack::voxel::VoxelParams;
use voltrack::{Error, Progress};

fn fixture_frames() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar");
    (0..BENDING_BAR_FRAMES)
        .map(|f| dir.join(format!("frame_{f}.obj")))
        .collect()
}

/// Every text between `<open` and `close`.
fn between<'a>(html: &'a str, open: &str, close: &str) -> Vec<&'a str> {
    html.split(open)
        .skip(1)
        .map(|s| &s[..s.find(close).expect("closed")])
        .collect()
}

#[test]
fn report_of_a_conversion() {
    let dir = Scratch::new("report", "bar");
    // A folder name that must be escaped wherever it is shown.
    let input = dir.join("bar <&> \"x\"");
    std::fs::create_dir(&input).unwrap();
    for p in fixture_frames() {
        std::fs::copy(&p, input.join(p.file_name().unwrap())).unwrap();
    }
    let files = voltrack::io::FrameFiles::discover(std::slice::from_ref(&input)).unwrap();
    let inputs = files.paths().to_vec();
    let voxel = VoxelParams {
        resolution: 48,
        ..Default::default()
    };
    let track = TrackParams {
        centers: 150,
        seed: 3,
        ..Default::default()
    };
    let refine = RefineParams {
        remove: Some(3),
        batches: 2,
        ..Default::default()
    };
    let deform = DeformParams::default();
    let conv = voltrack::pipeline::convert(
        &files,
        &voltrack::pipeline::ConvertOptions {
            voxel: voxel.clone(),
            track: track.clone(),
            refine: Some(refine.clone()),
            deform: deform.clone(),
            conform: Default::default(),
            checkpoint: None,
            measure_tracked: true,
            ..Default::default()
        },
        Progress::none(),
    )
    .unwrap();
    let measured = Measurements::of(&conv).unwrap();

    // The fit: frame 0 is the input mesh itself; later frames are close (the
    // bar bends by up to 0.84 rad) but not exact.
    let fit = &conv.fit;
    assert_eq!(fit.frames.len(), BENDING_BAR_FRAMES);
    assert!((fit.diagonal - conv.sequence.bounds.diagonal()).abs() == 0.0);
    assert_eq!(fit.frames[0].result_to_input, DistanceSummary::default());
    assert_eq!(fit.frames[0].input_to_result, DistanceSummary::default());
    for (f, x) in fit.frames.iter().enumerate().skip(1) {
        for s in [&x.result_to_input, &x.input_to_result] {
            assert!(
                s.mean > 0.0 && s.mean <= s.p95 && s.p95 <= s.max,
                "frame {f}: {x:?}"
            );
            assert!(
                s.mean < 1.0 && s.p95 < 3.0 && s.max < 8.0,
                "frame {f} is off by more than a few % of the diagonal: {x:?}"
            );
        }
    }
    let summary = fit.summary();
    assert!(summary.mean < 0.75, "{summary:?}");

    let glb = dir.join("out <b>.glb");
    let seconds: Vec<_> = conv
        .seconds
        .iter()
        .copied()
        .chain([(voltrack::Stage::Export, 0.25)])
        .collect();
    let command = format!(
        "voltrack convert '{}' -r 48 -n 150 --report r.html",
        input.display()
    );
    let conform = ConformParams::default();
    let written = voltrack::export::gltf::GltfExportReport {
        targets: 10,
        basis: Some(9),
        reconstruction_error_max: 0.0041,
        reconstruction_error_mean: 0.000123,
        bytes: 1_234_567,
        compressed: true,
        steps: false,
        rate_distortion: vec![
            voltrack::export::gltf::RateRow {
                components: Some(4),
                targets: 8,
                bytes: 654_321,
                error_max: 0.0123,
                error_mean: 0.000456,
                chosen: false,
            },
            voltrack::export::gltf::RateRow {
                components: Some(9),
                targets: 10,
                bytes: 1_234_567,
                error_max: 0.0041,
                error_mean: 0.000123,
                chosen: true,
            },
        ],
    };
    let report = ReportInput {
        seconds: &seconds,
        output: Some(&glb),
        output_bytes: Some(1_234_567),
        gltf: Some(&written),
        command: Some(&command),
        ..ReportInput::new(
            &conv,
            &measured,
            &inputs,
            &voxel,
            &track,
            Some(&refine),
            &deform,
            &conform,
        )
    };
    let html = report_html(&report);
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(
        assert_well_formed(&html) > 100,
        "a report of some substance"
    );

    // Self-contained: nothing to fetch, nothing to run. The SVG namespace is
    // a name, not a resource.
    let without_namespace = html.replace("xmlns=\"http://www.w3.org/2000/svg\"", "");
    for bad in [
        "http://", "https://", "<script", "<link", " src=", " href=", "url(", "@import", "<img",
        "<iframe",
    ] {
        assert!(!without_namespace.contains(bad), "{bad} in the report");
    }

    // The output's size, content and error.
    for shown in [
        "1,234,567 bytes",
        "a compact basis of 9 components (10 morph targets)",
        "compressed (KHR_mesh_quantization + EXT_meshopt_compression)",
        "reconstruction error mean 0.0123 %, max 0.410 % of the diagonal",
        "<tr><td>4</td><td>8</td><td>654,321</td><td>0.0456</td><td>1.23</td><td class=\"note\"></td></tr>",
        "<tr><td>9</td><td>10</td><td>1,234,567</td><td>0.0123</td><td>0.410</td><td class=\"note\">written</td></tr>",
    ] {
        assert!(html.contains(shown), "{shown:?} not in the report");
    }

    // Names from the file system are escaped everywhere.
    assert!(
        !html.contains("bar <&>") && !html.contains("out <b>"),
        "unescaped file name"
    );
    assert!(html.contains("<title>voltrack report: bar &lt;&amp;&gt; &quot;x&quot;</title>"));
    assert!(html.contains("out &lt;b&gt;.glb"));
    assert!(html.contains("-r 48 -n 150"));

    // The result drawn at frames 0, 2, 4 and 7 (of 8), in one view: every
    // picture has shaded pixels.
    let preview = between(&html, "<section id=\"preview\">", "</section>");
    assert_eq!(preview.len(), 1);
    let pictures = between(preview[0], "<svg", "</svg>");
    assert_eq!(pictures.len(), 4, "preview");
    for (picture, f) in pictures.iter().zip([0, 2, 4, 7]) {
        assert!(
            picture.contains(&format!("aria-label=\"frame {f}\"")),
            "{picture}"
        );
        assert!(picture.contains("<path fill="), "{picture}");
    }
    let plots = html.replace(preview[0], "");

    // Ten plots, each in a figure whose caption says which way is better.
    let svgs = between(&plots, "<svg", "</svg>");
    assert_eq!(svgs.len(), 10, "plots");
    assert_eq!(plots.matches("<figure>").count(), 10);
    for caption in between(&plots, "<figcaption>", "</figcaption>") {
        assert!(
            caption.contains("is better") || caption.contains("is faster"),
            "caption without a direction: {caption}"
        );
    }
    for title in [
        "Distance between the result and the input, per frame",
        "Irregularity curve",
        "Deviation from uniformity (DFU) per frame",
        "Refinement: energy of the global optimisation",
        "Time per stage",
        "Tracking time per frame",
        "Tracking iterations per frame",
        "Input volume no tracked cell reaches, per frame",
        "Surface far from the other surface, per frame",
        "Fit to the input against the sequence's usual, per frame",
    ] {
        let plot = svgs
            .iter()
            .find(|s| s.contains(&format!(">{title}</text>")))
            .unwrap_or_else(|| panic!("no plot titled {title}"));
        assert!(
            plot.contains("<polyline") || plot.contains("<rect x="),
            "{title} draws nothing"
        );
    }
    // The fit plot: both directions, three statistics each, one point per frame.
    let fit_plot = svgs[0];
    assert_eq!(fit_plot.matches("<polyline").count(), 6);
    assert_eq!(fit_plot.matches("<circle").count(), 6 * BENDING_BAR_FRAMES);
    assert_eq!(
        fit_plot.matches("stroke-dasharray").count(),
        3 + 3,
        "dashed lines and their legend entries"
    );
    // Coverage: the lost volume and the fit, each with its limit; the bar
    // is tracked well, so no warning and no flagged frame.
    assert_eq!(svgs[1].matches("<polyline").count(), 2);
    // Far surface: each direction's largest far region and the limit.
    assert_eq!(svgs[2].matches("<polyline").count(), 3);
    assert_eq!(svgs[3].matches("<polyline").count(), 2);
    assert!(
        !html.contains("Warning: a part may have been lost") && !html.contains("class=\"flagged\"")
    );
    // Irregularity and DFU: before and after refinement.
    assert_eq!(svgs[4].matches("<polyline").count(), 2);
    assert_eq!(svgs[5].matches("<polyline").count(), 2);
    assert!(svgs[4].contains("forward tracking") && svgs[4].contains("after refinement"));
    // Energy: one line per batch. Stages: one bar each.
    assert_eq!(
        svgs[6].matches("<polyline").count(),
        conv.refined.as_ref().unwrap().batches.len()
    );
    for stage in ["read", "voxelize", "track", "refine", "deform", "export"] {
        assert!(
            svgs[7].contains(&format!(">{stage}</text>")),
            "no bar for {stage}"
        );
    }

    // The numbers: header facts, qualities before and after, the fit table.
    let refined = measured.refined.as_ref().unwrap();
    for number in [
        format!("{:.4}", measured.tracked.pcac),
        format!("{:.4}", refined.pcac),
        format!("{:.4}", measured.tracked.dfu),
        format!("{:.4}", refined.dfu),
        format!(
            "<th>Vertices</th><td>{}</td>",
            conv.mesh.base.positions.len()
        ),
        format!(
            "<th>Triangles</th><td>{}</td>",
            conv.mesh.base.triangles.len()
        ),
        format!("<th>Frames</th><td>{BENDING_BAR_FRAMES}</td>"),
        "150 tracked, 147 after removing 3 irregular".to_string(),
        "48 voxels along the longest side".to_string(),
        format!("voltrack {}", env!("CARGO_PKG_VERSION")),
        super::super::plot::significant(summary.mean, 3),
    ] {
        assert!(html.contains(&number), "{number} missing");
    }
    assert_eq!(
        html.matches("<td class=\"file\"><code>frame_").count(),
        BENDING_BAR_FRAMES,
        "one table row per frame"
    );
    // Users have no evaluate.py; a DFU that rises with refinement is explained;
    // wide tables scroll within a narrow page.
    assert!(
        !html.contains("evaluate"),
        "the report names a tool users do not have"
    );
    assert_eq!(
        html.contains("DFU rises after refinement here"),
        refined.dfu > measured.tracked.dfu
    );
    assert!(html.contains("table.numbers { display: block; max-width: 100%; overflow-x: auto; }"));
    for (name, value) in [
        ("centers", "150"),
        ("rho_gm", "0.0167"),
        ("blending", "dualquaternion"),
        ("resolution", "48"),
    ] {
        assert!(
            html.contains(&format!("<tr><th>{name}</th><td>{value}</td></tr>")),
            "parameter {name}"
        );
    }

    // Written whole or not at all.
    let path = dir.join("report.html");
    write_report(&path, &report).unwrap();
    let written = std::fs::read_to_string(&path).unwrap();
    assert_eq!(written.len(), html.len());
    assert!(written.contains("<h2>Fit of the result to the input</h2>"));
    let err = write_report(&dir.join("no/such/dir/report.html"), &report).unwrap_err();
    assert!(matches!(err, Error::Write { .. }), "{err}");
    assert!(
        dir.files().iter().all(|f| !f.contains("partial")),
        "{:?}",
        dir.files()
    );

    // Without refinement: no refinement section, one curve per quality plot.
    let conv = voltrack::pipeline::convert(
        &files,
        &voltrack::pipeline::ConvertOptions {
            voxel: voxel.clone(),
            track: track.clone(),
            refine: None,
            deform: deform.clone(),
            conform: Default::default(),
            checkpoint: None,
            measure_tracked: true,
            ..Default::default()
        },
        Progress::none(),
    )
    .unwrap();
    let measured = Measurements::of(&conv).unwrap();
    assert!(measured.refined.is_none());
    let html = report_html(&ReportInput::new(
        &conv,
        &measured,
        &inputs,
        &voxel,
        &track,
        None,
        &deform,
        &Default::default(),
    ));
    assert_well_formed(&html);
    // Four pictures of the result, then the plots.
    let svgs = between(&html, "<svg", "</svg>");
    assert_eq!(svgs.len(), 4 + 9);
    let svgs = &svgs[4..];
    assert!(
        !html.contains("Refinement: energy")
            && html.contains("<caption>Refinement</caption><tr><td>skipped</td></tr>")
    );
    assert_eq!(svgs[4].matches("<polyline").count(), 1);
    assert!(html.contains("150 (not refined)"));
}

#[test]
fn thousands_are_grouped() {
    for (n, text) in [
        (0, "0"),
        (999, "999"),
        (1000, "1,000"),
        (383_400, "383,400"),
        (1_096_404, "1,096,404"),
    ] {
        assert_eq!(super::thousands(n), text);
    }
}
