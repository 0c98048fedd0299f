//! PNG figures of an experiment's first run per method, drawn with `plotters` into an RGB
//! buffer that `image` encodes. Text is DejaVu Sans, embedded in the crate and registered once
//! with plotters' `ab_glyph` font backend: no system fonts, so a figure looks the same on any
//! machine. One file per method: a title band (experiment, method, seed), then three panels,
//! each with a caption, axis labels with units and a legend strip under it:
//! - **trajectory** (x–y plane, m, equal scales): truth, estimate, and the 3σ band (σ = √ trace
//!   of the position covariance) as rings around every k-th estimate;
//! - **error over time** (s, m): the estimate's error, its 3σ bound (the panel is scaled to the
//!   error; a larger bound is clipped at the top), the experiment's window (loss, occlusion)
//!   shaded;
//! - **active sensors over time** (s, count): cameras with a measurement, RSSI readings.

use super::runner::Sample;
use super::{Outcome, Trace};
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Figure size, px.
pub const WIDTH: u32 = 1500;
pub const HEIGHT: u32 = 600;
/// Height of the title band, px: the panels start below it.
pub const TITLE_H: u32 = 70;
/// Height of the legend strip under each panel, px.
pub const LEGEND_H: u32 = 62;

pub const TRUTH: RGBColor = RGBColor(30, 80, 220);
pub const ESTIMATE: RGBColor = RGBColor(220, 30, 30);
/// The 3σ rings and bound.
pub const BAND: RGBColor = RGBColor(245, 150, 150);
/// The experiment's window (loss, occlusion).
pub const WINDOW: RGBColor = RGBColor(215, 215, 215);
pub const CAMERAS: RGBColor = RGBColor(30, 80, 220);
pub const RSSI: RGBColor = RGBColor(20, 160, 60);
const GRID: RGBColor = RGBColor(236, 236, 236);
const SUBTITLE: RGBColor = RGBColor(70, 70, 70);

/// The family plotters knows the embedded font by (every text style here asks for it).
const FAMILY: &str = "sans-serif";
/// DejaVu Sans 2.37 (Debian's fonts-dejavu-core), unmodified. Licence: Bitstream Vera, the
/// DejaVu changes in the public domain; it allows redistribution with the notice, which is in
/// `assets/fonts/LICENSE` beside the file.
static FONT: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/fonts/DejaVuSans.ttf"
));

/// Font sizes, px.
const TITLE_PX: f64 = 30.0;
const SUBTITLE_PX: f64 = 19.0;
const CAPTION_PX: f64 = 23.0;
const AXIS_PX: f64 = 20.0;
const TICK_PX: f64 = 17.0;
const LEGEND_PX: f64 = 17.0;

/// Chart margins and label areas, px.
const MARGIN: u32 = 12;
const X_LABELS: u32 = 52;
const Y_LABELS: u32 = 68;

/// Why a figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("the embedded font (DejaVu Sans) cannot be parsed")]
    Font,
    #[error("drawing the figure of {method:?}: {detail}")]
    Draw { method: String, detail: String },
    #[error("creating {path}: {source}")]
    CreateDir { path: PathBuf, source: std::io::Error },
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: image::ImageError,
    },
}

/// Register the embedded font with plotters, once per process.
fn register_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok =
        *REGISTERED.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

fn text(px: f64) -> TextStyle<'static> {
    (FAMILY, px).into_font().color(&BLACK)
}

/// What a drawing step returns: plotters' error for the backend.
type Drawn<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// The figure of one method's trace: the title band names the experiment, the method and the
/// run's seed; below it the three panels (a line saying so when the run has no estimate).
///
/// # Errors
/// The embedded font cannot be parsed, or plotters fails to draw.
pub fn render(experiment: &str, seed: u64, trace: &Trace) -> Result<RgbImage, PlotError> {
    draw_figure(&trace.method, |root| figure(root, experiment, seed, trace))
}

/// A [`WIDTH`] × [`HEIGHT`] figure drawn by `draw` into an RGB buffer (`method` names it in
/// errors).
fn draw_figure(
    method: &str,
    draw: impl for<'a> FnOnce(&DrawingArea<BitMapBackend<'a>, Shift>) -> Drawn<BitMapBackend<'a>>,
) -> Result<RgbImage, PlotError> {
    register_font()?;
    let mut buf = vec![0u8; WIDTH as usize * HEIGHT as usize * 3];
    let drawn = {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        draw(&root).and_then(|()| root.present())
    };
    drawn.map_err(|e| PlotError::Draw {
        method: method.to_string(),
        detail: e.to_string(),
    })?;
    RgbImage::from_raw(WIDTH, HEIGHT, buf).ok_or_else(|| PlotError::Draw {
        method: method.to_string(),
        detail: "the pixel buffer does not match the figure's size".into(),
    })
}

fn figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    experiment: &str,
    seed: u64,
    trace: &Trace,
) -> Drawn<DB> {
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(TITLE_H);
    let centre = |px| text(px).pos(Pos::new(HPos::Center, VPos::Center));
    let mid = WIDTH as i32 / 2;
    title.draw_text(
        &format!("{experiment}: {}", trace.method),
        &centre(TITLE_PX),
        (mid, 24),
    )?;
    let s = &trace.samples;
    let span = match (s.first(), s.last()) {
        (Some(a), Some(b)) => format!(", {} estimates over {:.0} s", s.len(), b.t - a.t),
        _ => String::new(),
    };
    title.draw_text(
        &format!("first run of the experiment (seed {seed}){span}"),
        &centre(SUBTITLE_PX).color(&SUBTITLE),
        (mid, 55),
    )?;
    if s.is_empty() {
        let (w, h) = body.dim_in_pixel();
        return body.draw_text(
            "no estimate of the target in this run",
            &centre(CAPTION_PX),
            (w as i32 / 2, h as i32 / 2),
        );
    }
    let panels = body.split_evenly((1, 3));
    let split = |p: &DrawingArea<DB, Shift>| p.split_vertically(HEIGHT - TITLE_H - LEGEND_H);
    let (area, legend) = split(&panels[0]);
    draw_legend(&legend, &trajectory(&area, s)?)?;
    let (area, legend) = split(&panels[1]);
    draw_legend(&legend, &error(&area, s, trace.window, experiment)?)?;
    let (area, legend) = split(&panels[2]);
    draw_legend(&legend, &sensors(&area, s)?)
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
enum Swatch {
    Line(RGBColor),
    Ring(RGBColor),
    Fill(RGBColor),
    Dot(RGBColor),
}

/// A panel's chart: captioned, with the label areas every panel uses.
fn chart_builder<'a, 'b, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: &str,
) -> ChartBuilder<'a, 'b, DB> {
    let mut b = ChartBuilder::on(area);
    b.caption(caption, text(CAPTION_PX))
        .margin(MARGIN)
        .margin_right(2 * MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS);
    b
}

/// The trajectory panel; returns its legend.
fn trajectory<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &[Sample],
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
    // Equal metres per pixel on both axes: the ranges take the plotting area's aspect. The
    // plotting area is the panel less the caption, margins and label areas.
    let (w, h) = area.dim_in_pixel();
    let plot_w = f64::from(w.saturating_sub(3 * MARGIN + Y_LABELS).max(1));
    let plot_h = f64::from(
        h.saturating_sub(2 * MARGIN + X_LABELS + CAPTION_PX as u32 + 10)
            .max(1),
    );
    let (x, y) = square_ranges(
        s.iter()
            .flat_map(|v| [(v.truth[0], v.truth[1]), (v.est[0], v.est[1])]),
        plot_w / plot_h,
    );
    let mut chart = chart_builder(area, "Trajectory (x–y plane)").build_cartesian_2d(x.clone(), y.clone())?;
    mesh(&mut chart, "x (m)", "y (m)")?;
    // The band as rings around every k-th estimate: filled, a filter that assumes more noise
    // than it gets would hide the trajectory under it.
    let every = (s.len() / 24).max(1);
    for v in s.iter().step_by(every) {
        for arc in ring(v.est[0], v.est[1], 3.0 * v.sigma_m, &x, &y) {
            chart.draw_series(std::iter::once(PathElement::new(arc, BAND.stroke_width(2))))?;
        }
    }
    let xy = |p: &[f64; 3]| (p[0], p[1]);
    chart.draw_series(LineSeries::new(
        s.iter().map(|v| xy(&v.truth)),
        TRUTH.stroke_width(3),
    ))?;
    chart.draw_series(LineSeries::new(
        s.iter().map(|v| xy(&v.est)),
        ESTIMATE.stroke_width(2),
    ))?;
    let start = xy(&s[0].truth);
    chart.draw_series(std::iter::once(Circle::new(start, 6, BLACK.filled())))?;
    Ok(vec![
        ("truth".into(), Swatch::Line(TRUTH)),
        ("estimate".into(), Swatch::Line(ESTIMATE)),
        (band_label(every), Swatch::Ring(BAND)),
        ("start".into(), Swatch::Dot(BLACK)),
    ])
}

fn band_label(every: usize) -> String {
    if every == 1 {
        "3σ around each estimate".into()
    } else {
        format!("3σ around one estimate in {every}")
    }
}

/// The error panel; returns its legend.
fn error<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &[Sample],
    window: Option<(f64, f64)>,
    experiment: &str,
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
    let t = time_range(s);
    let err_hi = s.iter().map(|v| v.error_m).fold(0.0, f64::max);
    let band_hi = s.iter().map(|v| 3.0 * v.sigma_m).fold(0.0, f64::max);
    // Scaled to the error; the bound up to 10 m above it, clipped there.
    let e_hi = (err_hi.max(band_hi.min(10.0)) * 1.08).max(0.1);
    let mut chart = chart_builder(area, "Error over time").build_cartesian_2d(t.clone(), 0.0..e_hi)?;
    mesh(&mut chart, "time (s)", "error (m)")?;
    let mut legend = Vec::new();
    if let Some((a, b)) = window {
        let (a, b) = (a.max(t.start), b.min(t.end));
        if a < b {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(a, 0.0), (b, e_hi)],
                WINDOW.filled(),
            )))?;
            legend.push((window_label(experiment).into(), Swatch::Fill(WINDOW)));
        }
    }
    let clip = |v: f64| v.min(e_hi);
    chart.draw_series(LineSeries::new(
        s.iter().map(|v| (v.t, clip(3.0 * v.sigma_m))),
        BAND.stroke_width(2),
    ))?;
    chart.draw_series(LineSeries::new(
        s.iter().map(|v| (v.t, clip(v.error_m))),
        ESTIMATE.stroke_width(2),
    ))?;
    let bound = if band_hi > e_hi {
        "3σ (clipped at the top)"
    } else {
        "3σ"
    };
    legend.splice(
        0..0,
        [
            ("error".into(), Swatch::Line(ESTIMATE)),
            (bound.into(), Swatch::Line(BAND)),
        ],
    );
    Ok(legend)
}

/// What an experiment's window is, for the legend.
fn window_label(experiment: &str) -> &'static str {
    match experiment {
        "paper000-table1" => "cameras 2 and 3 lost",
        "paper001" | "paper002-occlusion" => "hidden from every camera (first window)",
        _ => "the experiment's window",
    }
}

/// The active-sensors panel; returns its legend.
fn sensors<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    s: &[Sample],
) -> Result<Vec<(String, Swatch)>, DrawingAreaErrorKind<DB::ErrorType>> {
    let t = time_range(s);
    let n_hi = s
        .iter()
        .map(|v| v.cameras.max(v.rssi_nodes))
        .max()
        .unwrap_or(1)
        .max(1);
    let top = i32::try_from(n_hi).unwrap_or(i32::MAX - 1) + 1;
    let mut chart = chart_builder(area, "Active sensors").build_cartesian_2d(t, 0..top)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("sensors per step")
        .axis_desc_style(text(AXIS_PX))
        .label_style(text(TICK_PX))
        .bold_line_style(GRID)
        .light_line_style(TRANSPARENT)
        .y_labels(usize::try_from(top).unwrap_or(1).min(12) + 1)
        .draw()?;
    let count = |n: u32| i32::try_from(n).unwrap_or(i32::MAX);
    // RSSI first: where both counts are equal the cameras' line stays visible over it.
    chart.draw_series(LineSeries::new(
        steps(s, |v| count(v.rssi_nodes)),
        RSSI.stroke_width(3),
    ))?;
    chart.draw_series(LineSeries::new(
        steps(s, |v| count(v.cameras)),
        CAMERAS.stroke_width(2),
    ))?;
    Ok(vec![
        ("cameras with a measurement".into(), Swatch::Line(CAMERAS)),
        ("RSSI readings".into(), Swatch::Line(RSSI)),
    ])
}

/// A step line of `f` over the samples: each value held until the next sample.
fn steps(s: &[Sample], f: impl Fn(&Sample) -> i32) -> Vec<(f64, i32)> {
    let mut out = Vec::with_capacity(2 * s.len());
    for (k, v) in s.iter().enumerate() {
        if k > 0 {
            out.push((v.t, f(&s[k - 1])));
        }
        out.push((v.t, f(v)));
    }
    out
}

/// The mesh of a panel with f64 axes: axis labels, tick labels, a light grid.
fn mesh<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    x_desc: &str,
    y_desc: &str,
) -> Drawn<DB> {
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style(text(AXIS_PX))
        .label_style(text(TICK_PX))
        .bold_line_style(GRID)
        .light_line_style(TRANSPARENT)
        .x_labels(8)
        .y_labels(8)
        .draw()
}

/// The scenario seconds the samples span (from 0 at the latest).
fn time_range(s: &[Sample]) -> Range<f64> {
    let lo = s.first().map_or(0.0, |v| v.t.min(0.0));
    let hi = s.last().map_or(1.0, |v| v.t);
    if hi > lo { lo..hi } else { lo..lo + 1.0 }
}

/// Ranges holding every finite point with a margin, widened so that a metre is as long on x as
/// on y in a plotting area of width / height `aspect`.
fn square_ranges(pts: impl Iterator<Item = (f64, f64)>, aspect: f64) -> (Range<f64>, Range<f64>) {
    let (lo, hi) = pts
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
            ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
        });
    let (lo, hi) = if lo.0 <= hi.0 {
        (lo, hi)
    } else {
        ((0.0, 0.0), (1.0, 1.0))
    };
    let mid = ((lo.0 + hi.0) * 0.5, (lo.1 + hi.1) * 0.5);
    // Half-spans with a 10% margin and at least 0.5 m.
    let mut half = (((hi.0 - lo.0) * 0.55).max(0.5), ((hi.1 - lo.1) * 0.55).max(0.5));
    if half.0 / half.1 < aspect {
        half.0 = half.1 * aspect;
    } else {
        half.1 = half.0 / aspect;
    }
    (mid.0 - half.0..mid.0 + half.0, mid.1 - half.1..mid.1 + half.1)
}

/// A circle of radius `r` around `(cx, cy)` as arcs inside the ranges (plotters does not clip
/// to the plotting area).
fn ring(cx: f64, cy: f64, r: f64, x: &Range<f64>, y: &Range<f64>) -> Vec<Vec<(f64, f64)>> {
    const N: usize = 72;
    let inside = |p: &(f64, f64)| x.contains(&p.0) && y.contains(&p.1);
    let mut arcs = vec![Vec::new()];
    if !(r.is_finite() && r > 0.0) {
        return Vec::new();
    }
    for k in 0..=N {
        let a = std::f64::consts::TAU * k as f64 / N as f64;
        let p = (cx + r * a.cos(), cy + r * a.sin());
        if inside(&p) {
            if let Some(arc) = arcs.last_mut() {
                arc.push(p);
            }
        } else if arcs.last().is_some_and(|arc| !arc.is_empty()) {
            arcs.push(Vec::new());
        }
    }
    arcs.retain(|arc| arc.len() > 1);
    arcs
}

/// A legend strip: its entries in rows, swatch then label, left-aligned with the plotting area.
fn draw_legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, entries: &[(String, Swatch)]) -> Drawn<DB> {
    let (w, _) = area.dim_in_pixel();
    let style = text(LEGEND_PX).pos(Pos::new(HPos::Left, VPos::Center));
    let (left, right) = (i32::try_from(MARGIN + Y_LABELS).unwrap_or(0) - 20, w as i32 - 10);
    let (mut x, mut y) = (left, 16);
    for (label, swatch) in entries {
        let (tw, _) = area.estimate_text_size(label, &style)?;
        let width = 34 + tw as i32 + 22;
        if x + width > right && x > left {
            (x, y) = (left, y + 26);
        }
        match *swatch {
            Swatch::Line(c) => area.draw(&PathElement::new(vec![(x, y), (x + 26, y)], c.stroke_width(3)))?,
            Swatch::Ring(c) => area.draw(&Circle::new((x + 13, y), 8, c.stroke_width(2)))?,
            Swatch::Fill(c) => area.draw(&Rectangle::new([(x, y - 8), (x + 26, y + 8)], c.filled()))?,
            Swatch::Dot(c) => area.draw(&Circle::new((x + 13, y), 6, c.filled()))?,
        }
        area.draw_text(label, &style, (x + 34, y))?;
        x += width;
    }
    Ok(())
}

/// A file-name-safe form of a method label.
pub fn slug(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_matches('-').to_string()
}

/// Write one PNG per traced method into `dir` (`EXPERIMENT-METHOD.png`), and the particle
/// figure (`EXPERIMENT-particles.png`) when the experiment kept one; returns the paths.
///
/// # Errors
/// The directory cannot be created, a figure cannot be drawn, or a file cannot be written.
pub fn write_all(o: &Outcome, dir: &Path) -> Result<Vec<PathBuf>, PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    let save = |image: RgbImage, path: PathBuf| {
        image
            .save_with_format(&path, image::ImageFormat::Png)
            .map_err(|source| PlotError::Write {
                path: path.clone(),
                source,
            })
            .map(|()| path)
    };
    let mut out = Vec::new();
    for t in &o.traces {
        let path = dir.join(format!("{}-{}.png", o.experiment, slug(&t.method)));
        out.push(save(render(&o.experiment, o.seed, t)?, path)?);
    }
    if let Some(p) = &o.particles {
        let path = dir.join(format!("{}-particles.png", o.experiment));
        out.push(save(particles::render(&o.experiment, o.seed, p)?, path)?);
    }
    Ok(out)
}

mod particles;

#[cfg(test)]
mod tests;
