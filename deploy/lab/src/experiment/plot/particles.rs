//! Paper 004's Figs. 6–7 for a particle-filter camera run, in one PNG: the pdf p(X_t | Z_t)
//! over time projected on the image's columns and on its rows (Fig. 6 a, b: time across, the
//! image coordinate up, darker where more sample weight lies), and one frame as the camera saw
//! it with every filter's samples (green, the dot's size its weight) and each filter's mean
//! state (yellow star), as Fig. 7 shows them.

use super::{
    CAPTION_PX, Drawn, HEIGHT, LEGEND_H, PlotError, SUBTITLE, SUBTITLE_PX, TITLE_H, TITLE_PX, WIDTH,
};
use super::{Swatch, chart_builder, draw_figure, draw_legend, mesh, text};
use crate::experiment::{ParticleTrace, PdfSlice, SampleSnapshot};
use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

const SAMPLE: RGBColor = RGBColor(40, 220, 60);
const MEAN: RGBColor = RGBColor(255, 230, 0);
const PDF: RGBColor = RGBColor(20, 40, 140);

/// The figure of `trace` (the first run of `experiment` with `seed`).
///
/// # Errors
/// The embedded font cannot be parsed, or plotters fails to draw.
pub fn render(experiment: &str, seed: u64, trace: &ParticleTrace) -> Result<RgbImage, PlotError> {
    draw_figure(&trace.method, |root| figure(root, experiment, seed, trace))
}

fn figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    experiment: &str,
    seed: u64,
    trace: &ParticleTrace,
) -> Drawn<DB> {
    root.fill(&WHITE)?;
    let (title, body) = root.split_vertically(TITLE_H);
    let centre = |px| text(px).pos(Pos::new(HPos::Center, VPos::Center));
    let mid = WIDTH as i32 / 2;
    title.draw_text(
        &format!("{experiment}: {} — particle pdf and samples", trace.method),
        &centre(TITLE_PX),
        (mid, 24),
    )?;
    title.draw_text(
        &format!(
            "first run (seed {seed}), {} frames of {}×{} px",
            trace.frames.len(),
            trace.width,
            trace.height
        ),
        &centre(SUBTITLE_PX).color(&SUBTITLE),
        (mid, 55),
    )?;
    let panels = body.split_evenly((1, 3));
    let split = |p: &DrawingArea<DB, Shift>| p.split_vertically(HEIGHT - TITLE_H - LEGEND_H);
    let pdf_legend = vec![(
        "sample weight per 4 px bin (darker: more)".to_string(),
        Swatch::Fill(PDF),
    )];
    let (area, legend) = split(&panels[0]);
    pdf_panel(&area, trace, "pdf over time, image column x", trace.width, |s| {
        &s.columns
    })?;
    draw_legend(&legend, &pdf_legend)?;
    let (area, legend) = split(&panels[1]);
    pdf_panel(&area, trace, "pdf over time, image row y", trace.height, |s| {
        &s.rows
    })?;
    draw_legend(&legend, &pdf_legend)?;
    let (area, legend) = split(&panels[2]);
    match &trace.snapshot {
        Some(snap) => {
            samples_panel(&area, trace, snap)?;
            draw_legend(
                &legend,
                &[
                    ("samples (size: weight)".to_string(), Swatch::Dot(SAMPLE)),
                    ("mean state".to_string(), Swatch::Dot(MEAN)),
                ],
            )
        }
        None => {
            let (w, h) = area.dim_in_pixel();
            area.draw_text(
                "no filter alive in this run",
                &centre(CAPTION_PX),
                (w as i32 / 2, h as i32 / 2),
            )
        }
    }
}

/// One marginal over time as a heat map: a cell per frame and bin.
fn pdf_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    trace: &ParticleTrace,
    caption: &str,
    extent_px: u32,
    marginal: impl Fn(&PdfSlice) -> &Vec<f32>,
) -> Drawn<DB> {
    let (t0, t1) = match (trace.frames.first(), trace.frames.last()) {
        (Some(a), Some(b)) if b.t > a.t => (a.t, b.t),
        _ => (0.0, 1.0),
    };
    let dt = (t1 - t0) / trace.frames.len().max(1) as f64;
    let mut chart =
        chart_builder(area, caption).build_cartesian_2d(t0..t1 + dt, f64::from(extent_px)..0.0)?;
    mesh(&mut chart, "time (s)", "pixel")?;
    let bin = f64::from(trace.bin_px);
    chart.draw_series(trace.frames.iter().flat_map(|s| {
        marginal(s)
            .iter()
            .enumerate()
            .filter(|(_, w)| **w > 0.002)
            .map(move |(i, w)| {
                // Saturates at a fifth of one filter's weight in a bin.
                let a = (f64::from(*w) / 0.2).min(1.0);
                let shade = |c: u8| (255.0 - a * (255.0 - f64::from(c))) as u8;
                Rectangle::new(
                    [(s.t, i as f64 * bin), (s.t + dt, (i + 1) as f64 * bin)],
                    RGBColor(shade(PDF.0), shade(PDF.1), shade(PDF.2)).filled(),
                )
            })
    }))?;
    Ok(())
}

/// The snapshot frame, scaled to the panel, with the samples and means over it.
fn samples_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    trace: &ParticleTrace,
    snap: &SampleSnapshot,
) -> Drawn<DB> {
    let (w, h) = (f64::from(trace.width), f64::from(trace.height));
    let caption = format!("samples at t = {:.1} s ({})", snap.t, snap.why);
    let mut chart = chart_builder(area, &caption).build_cartesian_2d(0.0..w, h..0.0)?;
    mesh(&mut chart, "x (px)", "y (px)")?;
    // The frame, one rectangle per pixel (nearest neighbour onto the plotting area).
    let image = &snap.image;
    chart.draw_series(image.enumerate_pixels().map(|(x, y, p)| {
        let (x, y) = (f64::from(x), f64::from(y));
        Rectangle::new([(x, y), (x + 1.0, y + 1.0)], RGBColor(p[0], p[1], p[2]).filled())
    }))?;
    let top = snap.samples.iter().map(|s| s[2]).fold(0.0f32, f32::max).max(1e-9);
    chart.draw_series(snap.samples.iter().map(|s| {
        let r = 1 + (4.0 * s[2] / top).round() as i32;
        Circle::new((f64::from(s[0]), f64::from(s[1])), r, SAMPLE.filled())
    }))?;
    chart.draw_series(
        snap.means
            .iter()
            .map(|m| TriangleMarker::new((f64::from(m[0]), f64::from(m[1])), 9, MEAN.filled())),
    )?;
    chart.draw_series(
        snap.means
            .iter()
            .map(|m| Cross::new((f64::from(m[0]), f64::from(m[1])), 9, MEAN.stroke_width(3))),
    )?;
    Ok(())
}
