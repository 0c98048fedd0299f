//! PNG figures of an experiment's first run per method, drawn with the `image` crate (no fonts:
//! tick values in a built-in 3×5 digit font). One file per method, three panels:
//! - **trajectory** (x–y plane, m): truth in blue, estimate in red, its 3σ band (σ = √ trace
//!   of the position covariance) as light-red rings around every k-th estimate;
//! - **error over time** (s, m): error in red, 3σ in light red (clipped to the panel, which is
//!   scaled to the error), the experiment's window (loss, occlusion) shaded grey;
//! - **active sensors over time** (s, count): cameras in blue, RSSI readings in green.

use super::{Outcome, Trace};
use image::{Rgb, RgbImage};
use std::path::{Path, PathBuf};

const PANEL_W: u32 = 400;
const PANEL_H: u32 = 360;
const MARGIN: f64 = 34.0;
const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const BLACK: Rgb<u8> = Rgb([0, 0, 0]);
const GREY: Rgb<u8> = Rgb([225, 225, 225]);
const BLUE: Rgb<u8> = Rgb([30, 80, 220]);
const RED: Rgb<u8> = Rgb([220, 30, 30]);
const PINK: Rgb<u8> = Rgb([250, 195, 195]);
const GREEN: Rgb<u8> = Rgb([20, 160, 60]);

/// A panel's data-to-pixel map.
struct Panel {
    x0: f64,
    lo: (f64, f64),
    hi: (f64, f64),
}

impl Panel {
    fn new(index: u32, lo: (f64, f64), hi: (f64, f64)) -> Panel {
        let pad = |a: f64, b: f64| {
            if (b - a).abs() < 1e-9 {
                (a - 0.5, b + 0.5)
            } else {
                (a, b)
            }
        };
        let (x, y) = (pad(lo.0, hi.0), pad(lo.1, hi.1));
        Panel {
            x0: f64::from(index * PANEL_W),
            lo: (x.0, y.0),
            hi: (x.1, y.1),
        }
    }

    fn px(&self, x: f64, y: f64) -> (f64, f64) {
        let w = f64::from(PANEL_W) - 2.0 * MARGIN;
        let h = f64::from(PANEL_H) - 2.0 * MARGIN;
        (
            self.x0 + MARGIN + (x - self.lo.0) / (self.hi.0 - self.lo.0) * w,
            f64::from(PANEL_H) - MARGIN - (y - self.lo.1) / (self.hi.1 - self.lo.1) * h,
        )
    }

    fn scale(&self) -> f64 {
        (f64::from(PANEL_W) - 2.0 * MARGIN) / (self.hi.0 - self.lo.0)
    }
}

fn put(img: &mut RgbImage, x: f64, y: f64, c: Rgb<u8>) {
    if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Rgb<u8>) {
    let n = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as usize;
    for i in 0..=n {
        let f = i as f64 / n as f64;
        put(img, a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1), c);
    }
}

/// A circle of radius `r` px (two pixels wide), clipped to the plot area of panel `p`.
fn ring(img: &mut RgbImage, p: &Panel, c: (f64, f64), r: f64, col: Rgb<u8>) {
    let r = r.clamp(1.0, 4.0 * f64::from(PANEL_W));
    let (x_lo, x_hi) = (p.x0 + MARGIN, p.x0 + f64::from(PANEL_W) - MARGIN);
    let (y_lo, y_hi) = (MARGIN, f64::from(PANEL_H) - MARGIN);
    let n = (r * 8.0).ceil().max(16.0) as usize;
    for k in 0..n {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        for rr in [r, r + 1.0] {
            let (x, y) = (c.0 + rr * a.cos(), c.1 + rr * a.sin());
            if x >= x_lo && x <= x_hi && y >= y_lo && y <= y_hi {
                put(img, x, y, col);
            }
        }
    }
}

/// A filled axis-aligned rectangle between two pixel corners.
fn rect(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), col: Rgb<u8>) {
    let (x0, x1) = (a.0.min(b.0).max(0.0) as u32, a.0.max(b.0).max(0.0) as u32);
    let (y0, y1) = (a.1.min(b.1).max(0.0) as u32, a.1.max(b.1).max(0.0) as u32);
    for y in y0..=y1.min(img.height().saturating_sub(1)) {
        for x in x0..=x1.min(img.width().saturating_sub(1)) {
            img.put_pixel(x, y, col);
        }
    }
}

/// 3×5 glyphs of `0-9 . -`, rows top to bottom, bit 2 = left column.
fn glyph(ch: char) -> Option<[u8; 5]> {
    Some(match ch {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '-' => [0, 0, 7, 0, 0],
        _ => return None,
    })
}

fn text(img: &mut RgbImage, x: f64, y: f64, s: &str) {
    for (k, ch) in s.chars().enumerate() {
        let Some(g) = glyph(ch) else { continue };
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for (sx, sy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                        let px = x + (k * 8 + col * 2) as f64 + sx;
                        put(img, px, y + (row * 2) as f64 + sy, BLACK);
                    }
                }
            }
        }
    }
}

fn axes(img: &mut RgbImage, p: &Panel) {
    let (a, b) = (p.px(p.lo.0, p.lo.1), p.px(p.hi.0, p.hi.1));
    line(img, a, (b.0, a.1), BLACK);
    line(img, a, (a.0, b.1), BLACK);
    for k in 0..=4 {
        let f = f64::from(k) / 4.0;
        let (x, y) = (p.lo.0 + f * (p.hi.0 - p.lo.0), p.lo.1 + f * (p.hi.1 - p.lo.1));
        let tx = p.px(x, p.lo.1);
        line(img, tx, (tx.0, tx.1 + 4.0), BLACK);
        text(img, tx.0 - 8.0, tx.1 + 7.0, &format!("{x:.1}"));
        let ty = p.px(p.lo.0, y);
        line(img, ty, (ty.0 - 4.0, ty.1), BLACK);
        text(img, ty.0 - 32.0, ty.1 - 12.0, &format!("{y:.1}"));
    }
}

fn bounds(pts: impl Iterator<Item = (f64, f64)>) -> ((f64, f64), (f64, f64)) {
    pts.filter(|p| p.0.is_finite() && p.1.is_finite())
        .fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
            ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
        })
}

/// The three panels of one method's trace.
pub fn render(trace: &Trace) -> RgbImage {
    let mut img = RgbImage::from_pixel(3 * PANEL_W, PANEL_H, WHITE);
    let s = &trace.samples;
    if s.is_empty() {
        return img;
    }
    // Trajectory, with equal scales on x and y.
    let (mut lo, mut hi) = bounds(
        s.iter()
            .flat_map(|v| [(v.truth[0], v.truth[1]), (v.est[0], v.est[1])]),
    );
    let span = (hi.0 - lo.0).max(hi.1 - lo.1).max(1.0) * 0.5 + 0.5;
    let mid = ((lo.0 + hi.0) * 0.5, (lo.1 + hi.1) * 0.5);
    (lo, hi) = ((mid.0 - span, mid.1 - span), (mid.0 + span, mid.1 + span));
    let p = Panel::new(0, lo, hi);
    // The band as rings around every k-th estimate: filled, a filter that assumes more noise
    // than it gets would hide the trajectory under it.
    let every = (s.len() / 24).max(1);
    for v in s.iter().step_by(every) {
        ring(
            &mut img,
            &p,
            p.px(v.est[0], v.est[1]),
            3.0 * v.sigma_m * p.scale(),
            PINK,
        );
    }
    for w in s.windows(2) {
        line(
            &mut img,
            p.px(w[0].truth[0], w[0].truth[1]),
            p.px(w[1].truth[0], w[1].truth[1]),
            BLUE,
        );
    }
    for w in s.windows(2) {
        line(
            &mut img,
            p.px(w[0].est[0], w[0].est[1]),
            p.px(w[1].est[0], w[1].est[1]),
            RED,
        );
    }
    axes(&mut img, &p);

    // Error over time.
    let t_lo = s.first().map_or(0.0, |v| v.t.min(0.0));
    let t_hi = s.last().map_or(1.0, |v| v.t);
    let e_hi = s
        .iter()
        .map(|v| v.error_m.max(3.0 * v.sigma_m))
        .fold(0.1, f64::max)
        .min(10.0);
    let p = Panel::new(1, (t_lo, 0.0), (t_hi, e_hi));
    if let Some((a, b)) = trace.window {
        rect(&mut img, p.px(a.max(t_lo), 0.0), p.px(b.min(t_hi), e_hi), GREY);
    }
    for w in s.windows(2) {
        let c = |v: &super::runner::Sample| (3.0 * v.sigma_m).min(e_hi);
        line(&mut img, p.px(w[0].t, c(&w[0])), p.px(w[1].t, c(&w[1])), PINK);
        let e = |v: &super::runner::Sample| v.error_m.min(e_hi);
        line(&mut img, p.px(w[0].t, e(&w[0])), p.px(w[1].t, e(&w[1])), RED);
    }
    axes(&mut img, &p);

    // Active sensors over time.
    let n_hi = s
        .iter()
        .map(|v| v.cameras.max(v.rssi_nodes))
        .max()
        .unwrap_or(1)
        .max(1);
    let p = Panel::new(2, (t_lo, 0.0), (t_hi, f64::from(n_hi)));
    for w in s.windows(2) {
        let r = |v: &super::runner::Sample| f64::from(v.rssi_nodes);
        line(&mut img, p.px(w[0].t, r(&w[0])), p.px(w[1].t, r(&w[0])), GREEN);
        line(&mut img, p.px(w[1].t, r(&w[0])), p.px(w[1].t, r(&w[1])), GREEN);
        let c = |v: &super::runner::Sample| f64::from(v.cameras);
        line(&mut img, p.px(w[0].t, c(&w[0])), p.px(w[1].t, c(&w[0])), BLUE);
        line(&mut img, p.px(w[1].t, c(&w[0])), p.px(w[1].t, c(&w[1])), BLUE);
    }
    axes(&mut img, &p);
    img
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

/// Write one PNG per traced method into `dir`; returns the paths.
///
/// # Errors
/// The directory cannot be created or a file cannot be written.
pub fn write_all(o: &Outcome, dir: &Path) -> crate::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|source| crate::LabError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut out = Vec::new();
    for t in &o.traces {
        let path = dir.join(format!("{}-{}.png", o.experiment, slug(&t.method)));
        render(t)
            .save(&path)
            .map_err(|e| crate::LabError::failed(format!("writing {}", path.display()), e.to_string()))?;
        out.push(path);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::runner::Sample;

    #[test]
    fn a_trace_draws_truth_estimate_and_band_in_their_colours() {
        let samples: Vec<Sample> = (0..50)
            .map(|k| {
                let t = f64::from(k) * 0.2;
                Sample {
                    t,
                    est: [t * 0.4 + 0.1, 2.0, 0.25],
                    truth: [t * 0.4, 2.0, 0.25],
                    sigma_m: 0.05,
                    error_m: 0.1,
                    cameras: 3,
                    rssi_nodes: 1,
                }
            })
            .collect();
        let img = render(&Trace {
            method: "m".into(),
            samples,
            window: Some((2.0, 4.0)),
        });
        let count = |c: Rgb<u8>| img.pixels().filter(|p| **p == c).count();
        for (name, c) in [
            ("blue", BLUE),
            ("red", RED),
            ("pink", PINK),
            ("green", GREEN),
            ("grey", GREY),
        ] {
            assert!(count(c) > 20, "{name}: {} pixels", count(c));
        }
        assert_eq!(slug("Active perception (cost 0.2)"), "active-perception-cost-0-2");
    }
}
