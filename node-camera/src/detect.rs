//! What segmentation finds: [`Detection`]s (centre, foot point, box, area, colour signature),
//! the HSI colour conversion both pipelines use, and the per-region accumulator that turns
//! pixels into a detection.

use proto::msg::{ColourSignature, PixelBox};

/// One segmented region, in full-resolution pixel coordinates of the frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    /// Centroid of the region's pixels.
    pub centre: [f32; 2],
    /// Foot point: the centroid's column at the bottom of the box (people on the ground).
    pub foot: [f32; 2],
    pub bbox: PixelBox,
    /// Region pixels, counted at full resolution (grid pixels × step²).
    pub area: u32,
    pub colour: ColourSignature,
}

/// Which point of a region stands for the target's state position.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ReferencePoint {
    /// The region centroid: the projection of a solid's centre (`TargetSpec::truth_at`).
    #[default]
    Centre,
    /// Bottom-centre of the box: the ground contact of a standing person (MultiviewX).
    Foot,
}

impl Detection {
    pub fn reference(&self, which: ReferencePoint) -> [f32; 2] {
        match which {
            ReferencePoint::Centre => self.centre,
            ReferencePoint::Foot => self.foot,
        }
    }
}

/// HSI of an RGB8 colour (paper 000 §6.1.1): hue in radians `[0, 2π)`, saturation and
/// intensity in `[0, 1]`.
pub fn rgb_to_hsi(r: f32, g: f32, b: f32) -> ColourSignature {
    let sum = r + g + b;
    let intensity = sum / (3.0 * 255.0);
    let min = r.min(g).min(b);
    let saturation = if sum > 0.0 { 1.0 - 3.0 * min / sum } else { 0.0 };
    let mut hue = (3f32.sqrt() * (g - b)).atan2(2.0 * r - g - b);
    if hue < 0.0 {
        hue += std::f32::consts::TAU;
    }
    ColourSignature {
        hue,
        saturation,
        intensity,
    }
}

/// Smallest angle between two hues, radians.
pub fn hue_distance(a: f32, b: f32) -> f32 {
    let d = (a - b).abs() % std::f32::consts::TAU;
    d.min(std::f32::consts::TAU - d)
}

/// Sums over a region's pixels, in processing-grid coordinates.
#[derive(Clone, Copy, Debug, Default)]
pub struct RegionStats {
    pub n: u32,
    pub sx: u64,
    pub sy: u64,
    pub rgb: [u64; 3],
    pub xmin: u32,
    pub ymin: u32,
    pub xmax: u32,
    pub ymax: u32,
}

impl RegionStats {
    pub fn start(x: u32, y: u32) -> RegionStats {
        RegionStats {
            xmin: x,
            xmax: x,
            ymin: y,
            ymax: y,
            ..RegionStats::default()
        }
    }

    #[inline]
    pub fn add(&mut self, x: u32, y: u32, rgb: [u8; 3]) {
        self.n += 1;
        self.sx += x as u64;
        self.sy += y as u64;
        for (s, v) in self.rgb.iter_mut().zip(rgb) {
            *s += v as u64;
        }
        self.xmin = self.xmin.min(x);
        self.xmax = self.xmax.max(x);
        self.ymin = self.ymin.min(y);
        self.ymax = self.ymax.max(y);
    }

    /// The detection, scaling grid coordinates by `step` back to frame pixels (a grid pixel
    /// covers `step × step` frame pixels; its centre is `step·g + (step−1)/2`).
    pub fn to_detection(&self, step: u32) -> Option<Detection> {
        if self.n == 0 {
            return None;
        }
        let s = step as f32;
        let half = (s - 1.0) * 0.5;
        let n = self.n as f32;
        let cx = self.sx as f32 / n * s + half;
        let cy = self.sy as f32 / n * s + half;
        let bbox = PixelBox {
            xmin: self.xmin as f32 * s,
            ymin: self.ymin as f32 * s,
            xmax: self.xmax as f32 * s + s - 1.0,
            ymax: self.ymax as f32 * s + s - 1.0,
        };
        let mean = |c: usize| self.rgb[c] as f32 / n;
        Some(Detection {
            centre: [cx, cy],
            foot: [cx, bbox.ymax],
            bbox,
            area: self.n.saturating_mul(step * step),
            colour: rgb_to_hsi(mean(0), mean(1), mean(2)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsi_of_primaries() {
        let red = rgb_to_hsi(255.0, 0.0, 0.0);
        assert!(red.hue.abs() < 1e-5 && (red.saturation - 1.0).abs() < 1e-5);
        let green = rgb_to_hsi(0.0, 255.0, 0.0);
        assert!((green.hue - std::f32::consts::TAU / 3.0).abs() < 1e-4);
        let grey = rgb_to_hsi(100.0, 100.0, 100.0);
        assert!(grey.saturation.abs() < 1e-6);
        assert!((grey.intensity - 100.0 / 255.0).abs() < 1e-6);
        assert!((hue_distance(0.1, std::f32::consts::TAU - 0.1) - 0.2).abs() < 1e-5);
    }

    #[test]
    fn stats_scale_with_step() {
        let mut s = RegionStats::start(10, 20);
        s.add(10, 20, [255, 0, 0]);
        s.add(11, 20, [255, 0, 0]);
        let d = s.to_detection(2).unwrap();
        assert_eq!(d.area, 8);
        assert_eq!(d.bbox.xmin, 20.0);
        assert_eq!(d.bbox.xmax, 23.0);
        assert!((d.centre[0] - 21.5).abs() < 1e-5);
        assert_eq!(d.foot[1], 41.0);
    }
}
