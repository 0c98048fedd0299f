//! Paper 000 §6.1.1: difference against a reference image, windows counted as moving when
//! more than `NP` of their pixels changed by more than `T`, HSI colour segmentation inside the
//! moving windows, 8-neighbour region growing.
//!
//! The reference image is the first frame. So that slow illumination change does not turn the
//! whole image into motion, unchanged pixels creep one level per frame toward the current
//! image (an addition to the paper, which assumes a static scene; `adapt = false` turns it
//! off). Without colour classes, the changed pixels of moving windows form the regions.

use crate::region::{Grid, grow_8};
use proto::sensor::{Detection, hue_distance, rgb_to_hsi};
use proto::sensor::{Frame, FrameError};

/// A colour the target can be characterized by, in HSI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HsiClass {
    /// Hue, radians.
    pub hue: f32,
    /// Largest hue distance accepted, radians.
    pub hue_tolerance: f32,
    pub min_saturation: f32,
    pub min_intensity: f32,
    pub max_intensity: f32,
}

impl HsiClass {
    /// A class around an RGB colour with default tolerances.
    pub fn around_rgb(rgb: [u8; 3]) -> HsiClass {
        let c = rgb_to_hsi(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32);
        HsiClass {
            hue: c.hue,
            hue_tolerance: 0.35,
            min_saturation: (c.saturation * 0.45).max(0.12),
            min_intensity: (c.intensity * 0.3).max(0.04),
            max_intensity: 1.0,
        }
    }

    #[inline]
    fn matches(&self, r: f32, g: f32, b: f32) -> bool {
        let c = rgb_to_hsi(r, g, b);
        c.saturation >= self.min_saturation
            && (self.min_intensity..=self.max_intensity).contains(&c.intensity)
            && hue_distance(c.hue, self.hue) <= self.hue_tolerance
    }
}

/// Parameters of the paper 000 pipeline.
#[derive(Clone, Debug, PartialEq)]
pub struct ColourDifferenceParams {
    /// Colour threshold T, L1 over RGB.
    pub threshold: u16,
    /// Window side, grid pixels.
    pub window: usize,
    /// NP: changed pixels above which a window has motion.
    pub np: u32,
    /// Target colours; empty = take the changed pixels themselves.
    pub classes: Vec<HsiClass>,
    pub adapt: bool,
    pub step: u32,
    pub min_pixels: u32,
    pub max_regions: usize,
}

impl Default for ColourDifferenceParams {
    fn default() -> Self {
        ColourDifferenceParams {
            threshold: 40,
            window: 8,
            np: 6,
            classes: Vec::new(),
            adapt: true,
            step: 1,
            min_pixels: 12,
            max_regions: 32,
        }
    }
}

/// The paper 000 segmenter's state.
#[derive(Debug)]
pub struct ColourDifference {
    params: ColourDifferenceParams,
    grid: Option<Grid>,
    reference: Vec<u8>,
    changed: Vec<u8>,
    windows: Vec<u32>,
    labels: Vec<u8>,
    stack: Vec<u32>,
    /// Class of each RGB colour quantized to 5 bits per channel (0 = none), built once.
    lut: Vec<u8>,
}

/// Index of an RGB colour in the 32×32×32 class table.
#[inline]
fn lut_index(r: u8, g: u8, b: u8) -> usize {
    ((r as usize >> 3) << 10) | ((g as usize >> 3) << 5) | (b as usize >> 3)
}

/// The class table: each 5-bit-per-channel cell takes the class of its centre colour.
fn build_lut(classes: &[HsiClass]) -> Vec<u8> {
    let mut lut = vec![0u8; 1 << 15];
    if classes.is_empty() {
        return lut;
    }
    for (i, cell) in lut.iter_mut().enumerate() {
        let centre = |shift: usize| (((i >> shift) & 31) * 8 + 4) as f32;
        let (r, g, b) = (centre(10), centre(5), centre(0));
        *cell = classes
            .iter()
            .position(|c| c.matches(r, g, b))
            .map_or(0, |p| (p + 1).min(255) as u8);
    }
    lut
}

impl ColourDifference {
    pub fn new(params: ColourDifferenceParams) -> ColourDifference {
        ColourDifference {
            lut: build_lut(&params.classes),
            params,
            grid: None,
            reference: Vec::new(),
            changed: Vec::new(),
            windows: Vec::new(),
            labels: Vec::new(),
            stack: Vec::new(),
        }
    }

    pub fn params(&self) -> &ColourDifferenceParams {
        &self.params
    }

    fn windows_across(&self, g: &Grid) -> (usize, usize) {
        let w = self.params.window.max(1);
        (g.width.div_ceil(w), g.height.div_ceil(w))
    }

    fn ensure(&mut self, frame: &Frame) -> Result<(Grid, bool), FrameError> {
        frame.check()?;
        if let Some(g) = self.grid {
            if frame.width as usize != g.frame_width || frame.height as usize / g.step != g.height {
                return Err(FrameError::Mismatch {
                    got_w: frame.width,
                    got_h: frame.height,
                    want_w: g.frame_width as u32,
                    want_h: (g.height * g.step) as u32,
                });
            }
            return Ok((g, false));
        }
        let g = Grid::new(frame.width, frame.height, self.params.step);
        self.reference = vec![0; g.len() * 3];
        for gy in 0..g.height {
            for gx in 0..g.width {
                let i = (gy * g.width + gx) * 3;
                self.reference[i..i + 3].copy_from_slice(&g.rgb(frame, gx, gy));
            }
        }
        self.changed = vec![0; g.len()];
        let (wx, wy) = self.windows_across(&g);
        self.windows = vec![0; wx * wy];
        self.labels = vec![0; g.len()];
        self.stack = Vec::with_capacity(g.len().min(1 << 16));
        self.grid = Some(g);
        Ok((g, true))
    }

    /// Segment one frame into `out` (cleared first). The first frame becomes the reference.
    ///
    /// # Errors
    /// A malformed frame or one whose size differs from the first; nothing changes then.
    pub fn process(&mut self, frame: &Frame, out: &mut Vec<Detection>) -> Result<(), FrameError> {
        out.clear();
        let (g, first) = self.ensure(frame)?;
        if first {
            return Ok(());
        }
        let win = self.params.window.max(1);
        let (wx, _) = self.windows_across(&g);
        self.windows.fill(0);
        let t = self.params.threshold as i32;
        let adapt = self.params.adapt;
        let step3 = g.step * 3;
        for gy in 0..g.height {
            let row_off = gy * g.step * g.frame_width * 3;
            let src = &frame.data[row_off..row_off + g.frame_width * 3];
            let a = gy * g.width;
            let refr = &mut self.reference[a * 3..(a + g.width) * 3];
            let changed = &mut self.changed[a..a + g.width];
            let wrow = &mut self.windows[(gy / win) * wx..(gy / win + 1) * wx];
            let pixels = src
                .chunks_exact(step3)
                .zip(refr.chunks_exact_mut(3))
                .zip(changed.iter_mut());
            for (x, ((px, rp), ch)) in pixels.enumerate() {
                let dr = px[0] as i32 - rp[0] as i32;
                let dg = px[1] as i32 - rp[1] as i32;
                let db = px[2] as i32 - rp[2] as i32;
                let c = dr.abs() + dg.abs() + db.abs() > t;
                *ch = u8::from(c);
                wrow[x / win] += u32::from(c);
                // Unchanged pixels creep one level toward the image (a select, not a branch).
                let k = i32::from(adapt && !c);
                rp[0] = (rp[0] as i32 + k * dr.signum()) as u8;
                rp[1] = (rp[1] as i32 + k * dg.signum()) as u8;
                rp[2] = (rp[2] as i32 + k * db.signum()) as u8;
            }
        }
        self.labels.fill(0);
        let np = self.params.np;
        for (wi, &count) in self.windows.iter().enumerate() {
            if count <= np {
                continue;
            }
            let (x0, y0) = ((wi % wx) * win, (wi / wx) * win);
            for y in y0..(y0 + win).min(g.height) {
                for x in x0..(x0 + win).min(g.width) {
                    let i = y * g.width + x;
                    self.labels[i] = if self.params.classes.is_empty() {
                        self.changed[i]
                    } else {
                        let [r, gg, b] = g.rgb(frame, x, y);
                        self.lut[lut_index(r, gg, b)]
                    };
                }
            }
        }
        let p = &self.params;
        grow_8(
            &g,
            &mut self.labels,
            frame,
            &mut self.stack,
            p.min_pixels,
            p.max_regions,
            out,
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::ClusterTime;

    fn scene(t: i64, red_at: Option<usize>, blue_at: Option<usize>, gain: f32) -> Frame {
        let mut f = Frame::new(100, 80, ClusterTime::from_millis(t * 100));
        for y in 0..80 {
            for x in 0..100 {
                let i = (y * 100 + x) * 3;
                let base = if (x / 10 + y / 10) % 2 == 0 { 120.0 } else { 90.0 };
                let v = (base * gain) as u8;
                f.data[i..i + 3].copy_from_slice(&[v, v, v]);
                if red_at.is_some_and(|r| (r..r + 10).contains(&x) && (20..40).contains(&y)) {
                    f.data[i..i + 3].copy_from_slice(&[210, 40, 30]);
                }
                if blue_at.is_some_and(|r| (r..r + 10).contains(&x) && (50..70).contains(&y)) {
                    f.data[i..i + 3].copy_from_slice(&[30, 50, 200]);
                }
            }
        }
        f
    }

    #[test]
    fn colour_classes_pick_the_red_target_only() {
        let mut seg = ColourDifference::new(ColourDifferenceParams {
            classes: vec![HsiClass::around_rgb([220, 40, 30])],
            ..ColourDifferenceParams::default()
        });
        let mut out = Vec::new();
        seg.process(&scene(0, None, None, 1.0), &mut out).unwrap();
        assert!(out.is_empty());
        seg.process(&scene(1, Some(30), Some(60), 1.0), &mut out).unwrap();
        assert_eq!(out.len(), 1, "{out:?}");
        assert!((out[0].centre[0] - 34.5).abs() < 0.6 && (out[0].centre[1] - 29.5).abs() < 0.6);
        assert_eq!(out[0].area, 200);
    }

    #[test]
    fn without_classes_every_moving_blob_is_a_region() {
        let mut seg = ColourDifference::new(ColourDifferenceParams::default());
        let mut out = Vec::new();
        seg.process(&scene(0, None, None, 1.0), &mut out).unwrap();
        seg.process(&scene(1, Some(10), Some(70), 1.0), &mut out).unwrap();
        assert_eq!(out.len(), 2, "{out:?}");
    }

    #[test]
    fn slow_illumination_drift_is_absorbed() {
        let mut seg = ColourDifference::new(ColourDifferenceParams::default());
        let mut out = Vec::new();
        for t in 0..60 {
            let gain = 1.0 + 0.01 * t as f32; // +60 % over 60 frames
            seg.process(&scene(t, None, None, gain), &mut out).unwrap();
            assert!(out.is_empty(), "frame {t}: {out:?}");
        }
        let mut off = ColourDifference::new(ColourDifferenceParams {
            adapt: false,
            ..ColourDifferenceParams::default()
        });
        off.process(&scene(0, None, None, 1.0), &mut out).unwrap();
        off.process(&scene(59, None, None, 1.6), &mut out).unwrap();
        assert!(!out.is_empty(), "without adaptation the drift is motion");
    }
}
