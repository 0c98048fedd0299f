//! What a detector finds in a frame: [`Detection`]s (centre, foot point, box, area, colour
//! signature) and the HSI colour conversion they are described with. Segmenters on the camera,
//! the measurement-level simulation and external detectors all speak it.

use crate::msg::{ColourSignature, PixelBox};

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
    /// The region centroid: the projection of a solid's centre (a target's state position).
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
}
