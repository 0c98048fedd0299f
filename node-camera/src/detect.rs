//! The per-region accumulator that turns segmented pixels into a [`Detection`].

use proto::msg::PixelBox;
use proto::sensor::{Detection, rgb_to_hsi};

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
