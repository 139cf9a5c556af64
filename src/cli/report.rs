//! The HTML report of a conversion (`voltrack convert --report`): one
//! self-contained file (inline CSS and SVG, no script, nothing fetched) that
//! says what was converted with which parameters, how well the result fits
//! the input frame by frame, how regular the tracking is (irregularity, PCAC,
//! DFU, before and after refinement) and where the time went.
//!
//! Two steps, so the rendering stays a pure function of data:
//! [`Measurements::of`] computes what the [`Conversion`] does not hold yet
//! (qualities, and the fit, which re-reads every input frame), then
//! [`report_html`] or [`write_report`] renders a [`ReportInput`] borrowing both.

use super::plot::{
    bar_chart, escape, irregularity_curves_svg, line_plot, significant, Axis, Series,
};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use voltrack::error::Result;
use voltrack::math::Real;
use voltrack::metrics::frame_runs;
use voltrack::metrics::FrameFit;
use voltrack::metrics::Quality;
use voltrack::params::{ConformParams, DeformParams, RefineParams, TrackParams};
use voltrack::pipeline::{Conversion, Measurements};
use voltrack::progress::Stage;
use voltrack::voxel::VoxelParams;

/// Everything one report shows, borrowed.
pub struct ReportInput<'a> {
    pub conversion: &'a Conversion,
    pub measurements: &'a Measurements,
    /// The input's frame files, in order.
    pub inputs: &'a [PathBuf],
    /// The parameters the conversion ran with.
    pub voxel: &'a VoxelParams,
    pub track: &'a TrackParams,
    /// None when refinement was skipped.
    pub refine: Option<&'a RefineParams>,
    pub deform: &'a DeformParams,
    pub conform: &'a ConformParams,
    /// Seconds per stage: `conversion.seconds`, plus the export's if known.
    pub seconds: &'a [(Stage, f64)],
    /// The file the result was written to, named in the header.
    pub output: Option<&'a Path>,
    /// Its size in bytes (a folder's files added up).
    pub output_bytes: Option<u64>,
    /// What the glTF writer reports: the basis, compression and their error.
    pub gltf: Option<&'a voltrack::export::gltf::GltfExportReport>,
    /// The command line, shown so the run can be repeated.
    pub command: Option<&'a str>,
}

impl<'a> ReportInput<'a> {
    /// A report of `conversion` with its own stage timings, naming no
    /// output file or command line (set those fields when known).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        conversion: &'a Conversion,
        measurements: &'a Measurements,
        inputs: &'a [PathBuf],
        voxel: &'a VoxelParams,
        track: &'a TrackParams,
        refine: Option<&'a RefineParams>,
        deform: &'a DeformParams,
        conform: &'a ConformParams,
    ) -> Self {
        ReportInput {
            conversion,
            measurements,
            inputs,
            voxel,
            track,
            refine,
            deform,
            conform,
            seconds: &conversion.seconds,
            output: None,
            output_bytes: None,
            gltf: None,
            command: None,
        }
    }
}

/// A few frames of the result, drawn (`preview`); nothing when a frame
/// cannot be read back.
fn preview_html(input: &ReportInput) -> String {
    let frames = &input.conversion.mesh.frames;
    let shown = super::preview::frames_shown(frames.len());
    let positions: Vec<_> = match shown.iter().map(|&f| frames.get(f)).collect() {
        Ok(p) => p,
        Err(e) => {
            log::warn!("the report's preview is left out: {e}");
            return String::new();
        }
    };
    let Some(view) = super::preview::View::fitting(positions.iter().map(|p| &p[..])) else {
        return String::new();
    };
    let triangles = &input.conversion.mesh.base.triangles;
    let mut h =
        String::from("<section id=\"preview\">\n<h2>The result</h2>\n<div class=\"preview\">\n");
    for (&f, p) in shown.iter().zip(&positions) {
        let shade = super::preview::raster(p, triangles, &view);
        let label = format!("frame {f}");
        let _ = writeln!(
            h,
            "<figure>{}<figcaption>frame {f}</figcaption></figure>",
            super::preview::svg(&shade, &label)
        );
    }
    h.push_str(
        "</div>\n<p class=\"note\">Seen along &#8722;z with y up, one scale for all frames.</p>\n</section>\n",
    );
    h
}

/// The bases the glTF writer tried: size against error, the one written marked.
fn rate_distortion_table(g: &voltrack::export::gltf::GltfExportReport) -> String {
    let mut h = String::from(
        "<table class=\"numbers\">\n<caption>Sizes of the bases tried (each encoded as the output; error in % of the diagonal)</caption>\n<tr><th>components</th><th>morph targets</th><th>bytes</th><th>error mean</th><th>error max</th><th></th></tr>\n",
    );
    for row in &g.rate_distortion {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"note\">{}</td></tr>",
            row.components.map_or("one per frame".into(), |k| k.to_string()),
            row.targets,
            thousands(row.bytes),
            significant(100.0 * row.error_mean, 3),
            significant(100.0 * row.error_max, 3),
            if row.chosen { "written" } else { "" }
        );
    }
    h.push_str("</table>\n");
    h
}

/// `n` with its thousands grouped by commas: 1,234,567.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Writes the report to `path` through a temporary file, so a failure
/// leaves no half-written report.
pub fn write_report(path: &Path, input: &ReportInput) -> Result<()> {
    let html = report_html(input);
    voltrack::files::write_atomic(path, |w| std::io::Write::write_all(w, html.as_bytes()))
}

/// The report as one self-contained HTML document.
pub fn report_html(input: &ReportInput) -> String {
    let conv = input.conversion;
    let seq = &conv.sequence;
    let title = sequence_name(input);
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"/>\n\
         <title>voltrack report: {}</title>\n<style>{CSS}</style>\n</head>\n<body>\n<main>\n",
        escape(&title)
    );
    let _ = write!(
        h,
        "<header>\n<h1>Conversion report: {}</h1>\n<p class=\"sub\">{} frames converted into one animated mesh by voltrack {}</p>\n</header>\n",
        escape(&title),
        seq.frames.len(),
        env!("CARGO_PKG_VERSION")
    );
    h.push_str(&glance_html(input));
    h.push_str(&preview_html(input));
    h.push_str(&warning_html(input));
    h.push_str(&input_html(input));
    h.push_str(&fit_html(input));
    h.push_str(&coverage_html(input));
    h.push_str(&tracking_html(input));
    if let Some(r) = &conv.refined {
        if !r.batches.is_empty() {
            h.push_str(&energy_html(r));
        }
    }
    h.push_str(&time_html(input));
    let _ = write!(
        h,
        "<footer>Written by voltrack {}. Sizes (bounding box, voxels) are in the input's units; \
         distances between surfaces in % of the input's bounding-box diagonal ({}).</footer>\n</main>\n</body>\n</html>\n",
        env!("CARGO_PKG_VERSION"),
        significant(conv.fit.diagonal, 4)
    );
    h
}

/// What the sequence is called: its folder when all frames share one, else
/// the first file's name.
fn sequence_name(input: &ReportInput) -> String {
    let paths = input.inputs;
    common_folder(paths).map_or_else(|| file_name(&paths[0]), file_name)
}

/// The folder every one of `paths` is in, when they share one (named).
fn common_folder(paths: &[std::path::PathBuf]) -> Option<&Path> {
    let dir = paths.first()?.parent()?;
    (!dir.as_os_str().is_empty() && paths.iter().all(|p| p.parent() == Some(dir))).then_some(dir)
}

/// The last component of `path` (all of it when there is none, as for `..`).
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

fn percent(v: Real) -> String {
    format!("{}&#8239;%", significant(v, 3))
}

fn seconds(v: f64) -> String {
    format!("{}&#8239;s", significant(v, 3))
}

fn figure(svg: &str, caption: &str) -> String {
    format!("<figure>\n{svg}<figcaption>{caption}</figcaption>\n</figure>\n")
}

fn card(label: &str, value: &str, note: &str) -> String {
    format!("<div class=\"card\"><div class=\"label\">{label}</div><div class=\"value\">{value}</div><div class=\"note\">{note}</div></div>\n")
}

/// The headline figures, one card each.
fn glance_html(input: &ReportInput) -> String {
    let conv = input.conversion;
    let m = input.measurements;
    let fit = conv.fit.summary();
    let worst = conv.fit.worst_frame();
    let tracked_n = conv.tracked.centers;
    let total: f64 = input.seconds.iter().map(|s| s.1).sum();
    let arrow = |a: Real, b: Option<Real>| match b {
        Some(b) => format!("{a:.4} &#8594; {b:.4}"),
        None => format!("{a:.4}"),
    };
    let mut h = String::from("<section class=\"cards\">\n");
    h.push_str(&card(
        "Fit to the input",
        &percent(fit.mean),
        &format!(
            "mean two-sided distance; p95 {}, max {} (worst frame {worst})",
            percent(fit.p95),
            percent(fit.max)
        ),
    ));
    h.push_str(&card(
        "Centers",
        &conv.trajectories.centers.to_string(),
        &conv
            .refined
            .as_ref()
            .map_or("tracked; not refined".into(), |r| {
                format!("{tracked_n} tracked, {} irregular removed", r.removed.len())
            }),
    ));
    let refined = m.refined.as_ref();
    h.push_str(&card(
        "PCAC",
        &arrow(m.tracked.pcac, refined.map(|q| q.pcac)),
        "trajectory complexity; lower is simpler",
    ));
    h.push_str(&card(
        "DFU",
        &arrow(m.tracked.dfu, refined.map(|q| q.dfu)),
        "uneven cell sizes; lower is more even",
    ));
    h.push_str(&card(
        "Time",
        &seconds(total),
        &format!(
            "{} frames, {} per frame",
            conv.sequence.frames.len(),
            seconds(total / conv.sequence.frames.len().max(1) as f64)
        ),
    ));
    h.push_str("</section>\n");
    h
}

/// `s` escaped, as code.
fn code(s: &str) -> String {
    format!("<code>{}</code>", escape(s))
}

/// What was converted, and with which parameters.
fn input_html(input: &ReportInput) -> String {
    let conv = input.conversion;
    let seq = &conv.sequence;
    let g = &seq.grid;
    let mut rows: Vec<(&str, String)> = vec![
        ("Input", input_files(input.inputs)),
        ("Frames", seq.frames.len().to_string()),
        (
            "Reference",
            format!(
                "frame {} ({}), {}",
                conv.tracked.reference.frame,
                code(&seq.names[conv.tracked.reference.frame]),
                escape(&conv.tracked.reference.why)
            ),
        ),
        (
            "Segments",
            if conv.segments.len() > 1 {
                escape(&super::segments_text(&conv.segments))
            } else {
                "one: the parts neither merge nor part".into()
            },
        ),
        (
            "Seed",
            if conv.attempts.len() > 1 {
                escape(&super::attempts_text(conv))
            } else {
                format!(
                    "{}, warned of {} frames",
                    conv.attempts[0].seed,
                    conv.attempts[0].warned.len()
                )
            },
        ),
        ("Vertices", conv.mesh.base.positions.len().to_string()),
        ("Triangles", conv.mesh.base.triangles.len().to_string()),
        (
            "Centers",
            match &conv.refined {
                Some(r) => format!(
                    "{} tracked, {} after removing {} irregular",
                    conv.tracked.centers,
                    conv.trajectories.centers,
                    r.removed.len()
                ),
                None => format!("{} (not refined)", conv.tracked.centers),
            },
        ),
        (
            "Resolution",
            format!(
                "{} voxels along the longest side: grid {} &#215; {} &#215; {}, voxel size {}",
                input.voxel.resolution,
                g.dims[0],
                g.dims[1],
                g.dims[2],
                significant(g.voxel_size, 3)
            ),
        ),
        (
            "Bounding box",
            format!(
                "longest side {}, diagonal {}",
                significant(seq.bounds.longest_side(), 4),
                significant(seq.bounds.diagonal(), 4)
            ),
        ),
    ];
    if let Some(text) = output_text(input) {
        rows.push(("Output", text));
    }
    if let Some(cmd) = input.command {
        rows.push(("Command", code(cmd)));
    }
    rows.push(("voltrack", env!("CARGO_PKG_VERSION").to_string()));
    let mut h = String::from(
        "<section id=\"input\">\n<h2>Input and parameters</h2>\n<table class=\"facts\">\n",
    );
    for (k, v) in rows {
        let _ = writeln!(h, "<tr><th>{k}</th><td>{v}</td></tr>");
    }
    h.push_str("</table>\n");
    if let Some(g) = input.gltf.filter(|g| !g.rate_distortion.is_empty()) {
        h.push_str(&rate_distortion_table(g));
    }
    h.push_str(&parameters_html(input));
    h.push_str("</section>\n");
    h
}

/// The input files: their folder and the first and last names, or the
/// first and last paths where they share no folder.
fn input_files(paths: &[PathBuf]) -> String {
    let (first, last) = (&paths[0], &paths[paths.len() - 1]);
    match common_folder(paths) {
        Some(dir) => format!(
            "{} &#8212; {} &#8230; {}",
            code(&format!("{}/", dir.display())),
            code(&file_name(first)),
            code(&file_name(last))
        ),
        None => format!(
            "{} &#8230; {}",
            code(&first.display().to_string()),
            code(&last.display().to_string())
        ),
    }
}

/// The output file, its size and what the GLB holds, if the run wrote one.
fn output_text(input: &ReportInput) -> Option<String> {
    let out = input.output?;
    let mut text = code(&out.display().to_string());
    if let Some(bytes) = input.output_bytes {
        let _ = write!(text, ", {} bytes", thousands(bytes));
    }
    if let Some(g) = input.gltf {
        let content = match g.basis {
            Some(k) => format!(
                "a compact basis of {k} component{} ({} morph targets)",
                if k == 1 { "" } else { "s" },
                g.targets
            ),
            None => format!("{} morph targets, one per frame", g.targets),
        };
        let _ = write!(text, "; {content}");
        if g.compressed {
            text.push_str(", compressed (KHR_mesh_quantization + EXT_meshopt_compression)");
        }
        if g.basis.is_some() || g.compressed {
            let _ = write!(
                text,
                "; reconstruction error mean {} %, max {} % of the diagonal",
                significant(100.0 * g.reconstruction_error_mean, 3),
                significant(100.0 * g.reconstruction_error_max, 3)
            );
        }
    }
    Some(text)
}

/// Every parameter, stage by stage, folded away.
fn parameters_html(input: &ReportInput) -> String {
    let mut h = String::new();
    let lengths = if input.track.absolute_units {
        "in the input's units"
    } else {
        "as fractions of the bounding box's longest side"
    };
    let _ = writeln!(
        h,
        "<details>\n<summary>All parameters (lengths {lengths})</summary>\n<div class=\"params\">"
    );
    h.push_str(&params_table("Voxelisation", input.voxel));
    h.push_str(&params_table("Tracking", input.track));
    match input.refine {
        Some(r) => h.push_str(&params_table("Refinement", r)),
        None => {
            h.push_str("<table><caption>Refinement</caption><tr><td>skipped</td></tr></table>\n")
        }
    }
    h.push_str(&params_table("Deformation", input.deform));
    h.push_str(&params_table("Conforming to the input", input.conform));
    h.push_str("</div>\n</details>\n");
    h
}

/// One parameter struct as a name/value table, alphabetically.
fn params_table(caption: &str, params: &impl serde::Serialize) -> String {
    let mut h = format!("<table><caption>{caption}</caption>\n");
    if let Ok(serde_json::Value::Object(fields)) = serde_json::to_value(params) {
        for (k, v) in fields {
            let value = match v {
                serde_json::Value::Null => "default".to_string(),
                serde_json::Value::String(s) => s,
                other => other.to_string(),
            };
            let _ = writeln!(
                h,
                "<tr><th>{}</th><td>{}</td></tr>",
                escape(&k),
                escape(&value)
            );
        }
    }
    h.push_str("</table>\n");
    h
}

/// The dynamic mesh against the input, per frame: plot and table.
fn fit_html(input: &ReportInput) -> String {
    let fit = &input.conversion.fit;
    let frames = &fit.frames;
    type Pick = fn(&FrameFit) -> Real;
    let stats: [(&str, usize, Pick, Pick); 3] = [
        (
            "mean",
            0,
            |f| f.result_to_input.mean,
            |f| f.input_to_result.mean,
        ),
        (
            "p95",
            3,
            |f| f.result_to_input.p95,
            |f| f.input_to_result.p95,
        ),
        (
            "max",
            1,
            |f| f.result_to_input.max,
            |f| f.input_to_result.max,
        ),
    ];
    let per_frame = |pick: Pick| {
        frames
            .iter()
            .enumerate()
            .map(|(f, x)| (f as Real, pick(x)))
            .collect::<Vec<_>>()
    };
    let mut series = Vec::new();
    for (name, color, forward, _) in &stats {
        series.push(
            Series::new(format!("result → input, {name}"), per_frame(*forward)).color(*color),
        );
    }
    for (name, color, _, backward) in &stats {
        series.push(
            Series::new(format!("input → result, {name}"), per_frame(*backward))
                .color(*color)
                .dashed(),
        );
    }
    let svg = line_plot(
        "Distance between the result and the input, per frame",
        &Axis::linear("frame").integer(),
        &Axis::linear("distance (% of the bounding-box diagonal)").starting_at_zero(),
        &series,
    );
    let mut h = String::from("<section id=\"fit\">\n<h2>Fit of the result to the input</h2>\n");
    h.push_str(&figure(
        &svg,
        "How far the animated mesh is from the captured surface in each frame. Solid lines: from every vertex of the \
         result to the nearest point of the input (where the result strays); dashed: from every vertex of the input to \
         the result (input the result does not cover). Means and 95th percentiles weight vertices by their surface area; \
         lower is better. Frame 0 is the input mesh itself, so it is 0.",
    ));
    let summary = fit.summary();
    let _ = writeln!(
        h,
        "<p>Over all frames, both directions pooled: mean {}, 95th percentile {}, maximum {} (worst frame by mean: {}). \
         Measured in {} from every vertex to the exact nearest point of the other surface; a measure between random \
         samples of the two surfaces reads a little higher where they nearly coincide.</p>",
        percent(summary.mean),
        percent(summary.p95),
        percent(summary.max),
        fit.worst_frame(),
        seconds(fit.seconds)
    );
    let open = if frames.len() <= 20 { " open" } else { "" };
    let _ = writeln!(
        h,
        "<details{open}>\n<summary>Distances per frame (% of the diagonal)</summary>"
    );
    h.push_str(
        "<table class=\"numbers\">\n<tr><th rowspan=\"2\" class=\"n\">frame</th><th rowspan=\"2\">input file</th>\
         <th colspan=\"3\" class=\"group\">result &#8594; input</th><th colspan=\"3\" class=\"group\">input &#8594; result</th>\
         <th colspan=\"3\" class=\"group\">both directions</th></tr>\n<tr>\
         <th class=\"n group\">mean</th><th class=\"n\">p95</th><th class=\"n\">max</th>\
         <th class=\"n group\">mean</th><th class=\"n\">p95</th><th class=\"n\">max</th>\
         <th class=\"n group\">mean</th><th class=\"n\">p95</th><th class=\"n\">max</th></tr>\n",
    );
    for (f, (x, path)) in frames.iter().zip(input.inputs).enumerate() {
        let _ = write!(
            h,
            "<tr><td>{f}</td><td class=\"file\"><code>{}</code></td>",
            escape(&file_name(path))
        );
        for s in [&x.result_to_input, &x.input_to_result, &x.two_sided] {
            let _ = write!(
                h,
                "<td class=\"group\">{}</td><td>{}</td><td>{}</td>",
                significant(s.mean, 3),
                significant(s.p95, 3),
                significant(s.max, 3)
            );
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n</details>\n</section>\n");
    h
}

/// A box under the headline figures naming the frames where a part may
/// have been lost, one line per kind of evidence; nothing when none were
/// flagged.
fn warning_html(input: &ReportInput) -> String {
    let lost = lost_parts(input);
    let warnings = lost.warnings();
    if warnings.is_empty() {
        return String::new();
    }
    let mut h = String::from(
        "<section class=\"warning\">\n<h2>Warning: a part may have been lost</h2>\n<ul>\n",
    );
    for w in &warnings {
        let text = w.message.strip_prefix("warning: ").unwrap_or(&w.message);
        let _ = writeln!(h, "<li>{}</li>", escape(&capitalised(text)));
    }
    h.push_str(
        "</ul>\n<p>Check these frames in the result. More centers (<code>--centers</code>) or a higher <code>--resolution</code> \
         give a thin part more cells to be tracked by. The section on lost parts below shows the figures per frame.</p>\n</section>\n",
    );
    h
}

/// The frames where the conversion may have lost a part.
fn lost_parts(input: &ReportInput) -> voltrack::metrics::LostParts {
    input.conversion.lost_parts()
}

/// `s` with its first letter upper case.
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |first| {
        first.to_uppercase().chain(c).collect()
    })
}

/// Per frame: input volume no cell reaches, and the fit against its limit.
fn coverage_html(input: &ReportInput) -> String {
    let coverage = &input.conversion.coverage;
    let fit = &input.conversion.fit_outliers;
    let lost: Vec<(Real, Real)> = coverage
        .frames
        .iter()
        .enumerate()
        .map(|(f, c)| (f as Real, 100.0 * c.lost_share))
        .collect();
    let limit: Vec<(Real, Real)> = (0..coverage.frames.len())
        .map(|f| (f as Real, 100.0 * coverage.params.min_share))
        .collect();
    let mut h = String::from("<section id=\"coverage\">\n<h2>Lost parts: volume no cell reaches, surface far from the other</h2>\n");
    h.push_str(&figure(
        &line_plot(
            "Input volume no tracked cell reaches, per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("% of the frame's occupied volume").starting_at_zero(),
            &[Series::new("lost volume", lost), Series::new("flagged above", limit).color(1).dashed()],
        ),
        &format!(
            "Occupied voxels farther from their Voronoi cell's center than {} times that cell's reach in frame 0, \
             counted where they form connected regions of at least {} cells' volume: input volume the tracked centers \
             have left. Lower is better, 0 the best; a frame at or above the dashed line is flagged ({}).",
            significant(coverage.params.reach, 3),
            significant(coverage.params.min_region, 3),
            if coverage.flagged.is_empty() { "none is".to_string() } else { format!("frames {}", frame_runs(&coverage.flagged)) }
        ),
    ));
    let lost = lost_parts(input);
    let far = |of: fn(&voltrack::metrics::FrameLoss) -> Option<voltrack::metrics::FarRegion>| -> Vec<(Real, Real)> {
        lost.frames.iter().enumerate().map(|(f, x)| (f as Real, of(x).map_or(0.0, |r| r.share))).collect()
    };
    let far_limit: Vec<(Real, Real)> = (0..lost.frames.len())
        .map(|f| (f as Real, lost.params.far_share))
        .collect();
    h.push_str(&figure(
        &line_plot(
            "Surface far from the other surface, per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("largest connected region (% of the surface)").starting_at_zero(),
            &[
                Series::new("input far from the result", far(|x| x.far_input)),
                Series::new("result far from the input", far(|x| x.far_result)).color(2),
                Series::new("flagged at", far_limit).color(1).dashed(),
            ],
        ),
        &format!(
            "The largest connected region of the input's surface farther than {} of the diagonal from the result (a part the result \
             lost), and of the result's outside the input's volume and farther than {} from the input (a part carried or torn where the \
             input has none), in % of that surface's area. Lower is better, 0 the best; a frame at or above the dashed line is flagged ({}).",
            percent(lost.far_distances.map_or(lost.params.far, |d| d.input)),
            percent(lost.far_distances.map_or(lost.params.far_result, |d| d.result)),
            if lost.far.is_empty() { "none is".to_string() } else { format!("frames {}", frame_runs(&lost.far)) }
        ),
    ));
    let p95: Vec<(Real, Real)> = fit
        .p95
        .iter()
        .enumerate()
        .map(|(f, &v)| (f as Real, v))
        .collect();
    let fit_limit: Vec<(Real, Real)> = (0..fit.p95.len()).map(|f| (f as Real, fit.limit)).collect();
    h.push_str(&figure(
        &line_plot(
            "Fit to the input against the sequence's usual, per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("p95 distance (% of the diagonal)").starting_at_zero(),
            &[Series::new("both directions, p95", p95), Series::new("flagged above", fit_limit).color(1).dashed()],
        ),
        &format!(
            "The 95th percentile of the distance between the result and the input (both directions) in each frame, against \
             max({} &#215; the lower quartile over the frames, {}) = {}. Lower is better; a frame above the dashed line is \
             flagged ({}).",
            significant(coverage.params.fit_ratio, 3),
            percent(coverage.params.fit_floor),
            percent(fit.limit),
            if fit.flagged.is_empty() { "none is".to_string() } else { format!("frames {}", frame_runs(&fit.flagged)) }
        ),
    ));
    let open = if coverage.frames.len() <= 20 || !lost.flagged.is_empty() {
        " open"
    } else {
        ""
    };
    let _ = writeln!(
        h,
        "<details{open}>\n<summary>Lost parts per frame</summary>"
    );
    h.push_str(
        "<table class=\"numbers\">\n<tr><th class=\"n\">frame</th><th class=\"n\">lost volume</th><th class=\"n\">largest region (cells)</th>\
         <th class=\"n\">farthest (&#215; reach)</th><th class=\"n\">input far</th><th class=\"n\">result far</th><th class=\"n\">fit p95</th><th>flagged</th></tr>\n",
    );
    for (f, c) in coverage.frames.iter().enumerate() {
        let why: Vec<&str> = [
            (&lost.unreached, "volume"),
            (&lost.far, "far"),
            (&lost.fit_outliers, "fit"),
            (&lost.lasting, "lasting"),
            (&lost.continued, "next to one"),
        ]
        .iter()
        .filter(|(frames, _)| frames.contains(&f))
        .map(|(_, name)| *name)
        .collect();
        let share =
            |r: Option<voltrack::metrics::FarRegion>| r.map_or("-".into(), |r| percent(r.share));
        let _ = writeln!(
            h,
            "<tr{}><td>{f}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"note\">{}</td></tr>",
            if why.is_empty() { "" } else { " class=\"flagged\"" },
            percent(100.0 * c.lost_share),
            significant(c.largest_region as Real / coverage.cell_voxels.max(1e-12), 3),
            significant(c.farthest, 3),
            share(lost.frames[f].far_input),
            share(lost.frames[f].far_result),
            fit.p95.get(f).map_or("-".into(), |&v| percent(v)),
            why.join(", "),
        );
    }
    h.push_str("</table>\n</details>\n</section>\n");
    h
}

/// Irregularity, PCAC and DFU, before and after refinement.
fn tracking_html(input: &ReportInput) -> String {
    let m = input.measurements;
    let conv = input.conversion;
    let mut h = String::from("<section id=\"tracking\">\n<h2>Tracking quality</h2>\n");
    let qualities: Vec<(&str, &Quality, usize)> =
        std::iter::once(("forward tracking", &m.tracked, conv.tracked.centers))
            .chain(
                m.refined
                    .as_ref()
                    .zip(conv.refined.as_ref())
                    .map(|(q, _)| ("after refinement", q, conv.trajectories.centers)),
            )
            .collect();
    h.push_str("<table class=\"numbers\">\n<tr><th></th>");
    for (label, _, _) in &qualities {
        let _ = write!(h, "<th class=\"n\">{label}</th>");
    }
    h.push_str("<th></th></tr>\n");
    type Row = (&'static str, fn(&Quality, usize) -> String, &'static str);
    let rows: [Row; 5] = [
        ("centers", |_, n| n.to_string(), ""),
        (
            "PCAC",
            |q, _| format!("{:.4}", q.pcac),
            "PCA compactness of the trajectories; lower = simpler motion",
        ),
        (
            "DFU (mean over frames)",
            |q, _| format!("{:.4}", q.dfu),
            "spread of cell sizes / mean size; lower = more even cover",
        ),
        (
            "DFU (worst frame)",
            |q, _| {
                format!(
                    "{:.4}",
                    q.dfu_per_frame.iter().copied().fold(0.0, Real::max)
                )
            },
            "",
        ),
        (
            "largest I<sub>i</sub>",
            |q, _| {
                q.largest_irregularity(1)
                    .first()
                    .map_or("-".into(), |v| significant(*v, 3))
            },
            "the most irregular trajectory; lower is better",
        ),
    ];
    for (label, value, note) in rows {
        let _ = write!(h, "<tr><th>{label}</th>");
        for (_, q, n) in &qualities {
            let _ = write!(h, "<td>{}</td>", value(q, *n));
        }
        let _ = writeln!(h, "<td class=\"note\">{note}</td></tr>");
    }
    h.push_str("</table>\n");
    if let (Some(after), Some(_)) = (m.refined.as_ref(), conv.refined.as_ref()) {
        if after.dfu > m.tracked.dfu {
            // Users read a rising DFU as refinement gone wrong; it is the
            // trade the global energy makes (docs/method.md §7).
            h.push_str(
                "<p class=\"note\">DFU rises after refinement here. That is expected: the global optimisation moves every \
                 center toward the motion its neighbours predict from the frames before and after (the smoothness term) as \
                 much as toward the middle of its own cell (the centroid term, weighted by β̂), so cells become \
                 somewhat less even in size while the trajectories become more regular (PCAC and the largest I<sub>i</sub>). \
                 A larger β̂ (<code>--beta-hat</code>) keeps the cells more even at the cost of smoothness.</p>\n",
            );
        }
    }

    let curves: Vec<(&str, &[Real])> = qualities
        .iter()
        .map(|(label, q, _)| (*label, q.irregularity.as_slice()))
        .collect();
    h.push_str(&figure(
        &irregularity_curves_svg(&curves),
        "Irregularity I<sub>i</sub> of every center (the summed squared distance of its trajectory to the nearest other \
         trajectory), sorted from the most irregular. Lower is better, above all at the left end, where centers far \
         above the rest are strays that refinement removes first.",
    ));

    let series: Vec<Series> = qualities
        .iter()
        .map(|(label, q, _)| {
            Series::new(
                *label,
                q.dfu_per_frame
                    .iter()
                    .enumerate()
                    .map(|(f, &v)| (f as Real, v))
                    .collect(),
            )
        })
        .collect();
    h.push_str(&figure(
        &line_plot(
            "Deviation from uniformity (DFU) per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("DFU = std / mean of voxels per cell").starting_at_zero(),
            &series,
        ),
        "How unevenly the centers share the volume in each frame: the standard deviation of the number of voxels per \
         Voronoi cell over its mean. Lower is better; a rising curve means cells drift apart over time.",
    ));
    h.push_str("</section>\n");
    h
}

/// The temporally global optimisation's energy, batch by batch.
fn energy_html(refined: &voltrack::refine::Refinement) -> String {
    let mut step = 0usize;
    let mut series = Vec::new();
    for (b, history) in refined.batches.iter().enumerate() {
        let points = history
            .iter()
            .map(|it| {
                let p = (step as Real, it.energy);
                step += 1;
                p
            })
            .collect();
        // The next batch starts where this one ended: its first point is the
        // energy after the removal, drawn as a jump at the same step.
        step = step.saturating_sub(1);
        series.push(Series::new(format!("batch {}", b + 1), points));
    }
    let log = refined.batches.iter().flatten().all(|it| it.energy > 0.0);
    let svg = line_plot(
        "Refinement: energy of the global optimisation",
        &Axis::linear("accepted step (all batches in order)").integer(),
        &if log {
            Axis::log("energy Ê (log scale)")
        } else {
            Axis::linear("energy Ê").starting_at_zero()
        },
        &series,
    );
    let mut h = String::from("<section id=\"refinement\">\n<h2>Refinement</h2>\n");
    h.push_str(&figure(
        &svg,
        &format!(
            "The energy Ê = Ê<sub>s</sub> + β&#770; Ê<sub>u</sub> (rigidity of the motion plus distance of centers from their \
             cells' centroids, over all frames at once) after each accepted gradient step; each batch starts after removing \
             irregular centers. Lower is better; a batch that stops early found no step that lowers it. \
             {} centers removed in {} batches, {} in all.",
            refined.removed.len(),
            refined.batches.len(),
            seconds(refined.seconds)
        ),
    ));
    h.push_str("</section>\n");
    h
}

/// Time per stage and per tracked frame.
fn time_html(input: &ReportInput) -> String {
    let conv = input.conversion;
    let total: f64 = input.seconds.iter().map(|s| s.1).sum();
    let bars: Vec<(String, Real)> = input
        .seconds
        .iter()
        .map(|(s, t)| (s.name().to_string(), *t))
        .collect();
    let mut h = String::from("<section id=\"time\">\n<h2>Time</h2>\n");
    h.push_str(&figure(
        &bar_chart("Time per stage", "seconds (wall clock)", "s", &bars),
        &format!(
            "Wall-clock time of each stage, {} in all; measuring the fit for this report took {} more. Lower is faster.",
            seconds(total),
            seconds(input.conversion.fit.seconds)
        ),
    ));
    let timings = &conv.tracked.timings;
    // Every frame but the reference, where the centers were placed.
    let placed = conv.tracked.reference.frame;
    let tracked: Vec<(usize, &voltrack::track::FrameTiming)> = timings
        .iter()
        .enumerate()
        .filter(|&(f, _)| f != placed)
        .collect();
    let per_frame = |pick: fn(&voltrack::track::FrameTiming) -> f64| {
        tracked
            .iter()
            .map(|(f, t)| (*f as Real, pick(t)))
            .collect::<Vec<_>>()
    };
    let series = vec![
        Series::new("total", per_frame(|t| t.total)),
        Series::new("Voronoi assignment", per_frame(|t| t.assign)),
        Series::new("rigid fits", per_frame(|t| t.fit)),
        Series::new("affinity update", per_frame(|t| t.affinity)),
    ];
    let lloyd = timings.first().copied().unwrap_or_default();
    h.push_str(&figure(
        &line_plot(
            "Tracking time per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("seconds").starting_at_zero(),
            &series,
        ),
        &format!(
            "Seconds spent tracking each frame, and on what. Frame 0 (placing the centers by {} Lloyd iterations, {}) is \
             not drawn. Lower is faster; peaks mark frames with fast or large motion.{}",
            lloyd.iterations,
            seconds(lloyd.total),
            if input.track.damped_guess.is_some() {
                " Each frame is tracked twice side by side (from two guesses), so the parts add up both runs and can exceed the total."
            } else {
                ""
            }
        ),
    ));
    let limit = input.track.max_iterations;
    let at_limit = tracked
        .iter()
        .filter(|(_, t)| t.iterations >= limit)
        .count();
    h.push_str(&figure(
        &line_plot(
            "Tracking iterations per frame",
            &Axis::linear("frame").integer(),
            &Axis::linear("iterations until converged").starting_at_zero(),
            &[Series::new("iterations", per_frame(|t| t.iterations as f64))],
        ),
        &format!(
            "Iterations until no center moved farther than the threshold, at most {limit}, in the run kept. Fewer is better; a frame at \
             the limit did not converge and its centers may lag behind the surface ({}).",
            match at_limit {
                0 => "none did".to_string(),
                1 => "1 frame did".to_string(),
                n => format!("{n} frames did"),
            }
        ),
    ));
    h.push_str("</section>\n");
    h
}

const CSS: &str = r#"
:root { color-scheme: light; }
body { margin: 0; background: #f5f6f8; color: #1c2230; font: 15px/1.55 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif; }
main { max-width: 1000px; margin: 0 auto; padding: 24px 28px 48px; }
h1 { font-size: 26px; margin: 6px 0 2px; letter-spacing: -0.01em; }
h2 { font-size: 19px; margin: 36px 0 10px; padding-bottom: 4px; border-bottom: 1px solid #d7dbe2; }
p { max-width: 72ch; }
.sub { color: #5a6374; margin: 0; }
code { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; font-size: 13px; word-break: break-all; }
.cards { display: flex; flex-wrap: wrap; gap: 12px; margin: 22px 0 8px; }
.card { flex: 1 1 170px; background: #fff; border: 1px solid #e0e3e9; border-radius: 8px; padding: 10px 14px; }
.card .label { font-size: 12px; text-transform: uppercase; letter-spacing: 0.05em; color: #5a6374; }
.card .value { font-size: 22px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card .note { font-size: 12px; color: #5a6374; }
figure { margin: 18px 0; background: #fff; border: 1px solid #e0e3e9; border-radius: 8px; padding: 10px; }
figure svg { display: block; max-width: 100%; height: auto; margin: 0 auto; }
.preview { display: flex; flex-wrap: wrap; gap: 12px; }
.preview figure { margin: 0; }
figcaption { font-size: 14px; color: #363e4c; padding: 8px 8px 2px; max-width: 80ch; margin: 0 auto; }
table { border-collapse: collapse; background: #fff; font-variant-numeric: tabular-nums; margin: 8px 0; }
/* Wide tables scroll inside the page on a narrow screen instead of overflowing it. */
table.numbers { display: block; max-width: 100%; overflow-x: auto; }
p.note { color: #363e4c; max-width: 80ch; }
caption { text-align: left; font-weight: 600; padding: 4px 0; }
th, td { padding: 4px 10px; border-bottom: 1px solid #e7e9ee; text-align: left; vertical-align: top; }
th { font-weight: 600; color: #363e4c; }
table.facts th { width: 9em; }
table.numbers td { text-align: right; }
table.numbers td.note { text-align: left; color: #5a6374; font-size: 13px; }
table.numbers td.file { text-align: left; }
table.numbers td code { font-size: 12px; }
table.numbers .group { border-left: 1px solid #d7dbe2; }
table.numbers th.n { text-align: right; }
table.numbers th[colspan] { text-align: center; }
.params { display: flex; flex-wrap: wrap; gap: 16px; align-items: flex-start; }
details { margin: 10px 0; }
summary { cursor: pointer; color: #2a4d8f; }
.warning { background: #fff4e5; border: 1px solid #e8a33d; border-radius: 8px; padding: 4px 16px 8px; margin: 16px 0; }
.warning h2 { border: none; margin: 10px 0 4px; color: #8a4b00; }
tr.flagged td { background: #fff4e5; }
footer { margin-top: 40px; font-size: 13px; color: #5a6374; }
"#;

#[cfg(test)]
#[path = "report_tests.rs"]
mod tests;
