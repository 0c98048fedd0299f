//! Raw Bayer sensors (paper 004 §2.6.2): instead of demosaicing, each 2×2 cell of the colour
//! filter mosaic becomes one RGB pixel — its red, the mean of its two greens, its blue — so a
//! VGA sensor gives a QVGA frame for tracking, at a quarter of the work.

use proto::ClusterTime;
use proto::sensor::{Frame, MAX_FRAME_SIDE};
use thiserror::Error;

/// Which colour the top-left 2×2 cell's pixels carry, read row by row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BayerPattern {
    Rggb,
    Bggr,
    Grbg,
    Gbrg,
}

impl BayerPattern {
    /// Offsets (within the 2×2 cell, row-major: 0 1 / 2 3) of red, the two greens, blue.
    fn offsets(self) -> (usize, [usize; 2], usize) {
        match self {
            BayerPattern::Rggb => (0, [1, 2], 3),
            BayerPattern::Bggr => (3, [1, 2], 0),
            BayerPattern::Grbg => (1, [0, 3], 2),
            BayerPattern::Gbrg => (2, [0, 3], 1),
        }
    }
}

/// A raw buffer that does not fit its size.
#[derive(Debug, Error, PartialEq)]
pub enum BayerError {
    #[error("Bayer image {width}x{height} must be at least 2x2 and at most {max} per side")]
    Size { width: u32, height: u32, max: u32 },
    #[error("Bayer buffer has {got} bytes, a {width}x{height} 8-bit mosaic needs {want}")]
    Buffer {
        width: u32,
        height: u32,
        got: usize,
        want: usize,
    },
}

/// One RGB pixel per 2×2 cell of an 8-bit mosaic (`width × height` bytes, row-major), into
/// `out` (resized to `width/2 × height/2`; an odd last row or column is dropped).
///
/// # Errors
/// A size outside 2..=[`MAX_FRAME_SIDE`] or a buffer of the wrong length; `out` is unchanged.
pub fn half_resolution_into(
    raw: &[u8],
    width: u32,
    height: u32,
    pattern: BayerPattern,
    captured: ClusterTime,
    out: &mut Frame,
) -> Result<(), BayerError> {
    if !(2..=MAX_FRAME_SIDE).contains(&width) || !(2..=MAX_FRAME_SIDE).contains(&height) {
        return Err(BayerError::Size {
            width,
            height,
            max: MAX_FRAME_SIDE,
        });
    }
    let want = width as usize * height as usize;
    if raw.len() != want {
        return Err(BayerError::Buffer {
            width,
            height,
            got: raw.len(),
            want,
        });
    }
    let (ow, oh) = (width / 2, height / 2);
    if (out.width, out.height) != (ow, oh) || out.data.len() != ow as usize * oh as usize * 3 {
        *out = Frame::new(ow, oh, captured);
    }
    out.captured = captured;
    let (r, [g0, g1], b) = pattern.offsets();
    let w = width as usize;
    for (cy, row) in out.data.chunks_exact_mut(ow as usize * 3).enumerate() {
        let top = &raw[2 * cy * w..2 * cy * w + w];
        let bottom = &raw[(2 * cy + 1) * w..(2 * cy + 2) * w];
        for (cx, px) in row.chunks_exact_mut(3).enumerate() {
            let cell = [top[2 * cx], top[2 * cx + 1], bottom[2 * cx], bottom[2 * cx + 1]];
            px[0] = cell[r];
            px[1] = (cell[g0] as u16 + cell[g1] as u16).div_ceil(2) as u8;
            px[2] = cell[b];
        }
    }
    Ok(())
}

/// [`half_resolution_into`] into a new frame.
///
/// # Errors
/// As [`half_resolution_into`].
pub fn half_resolution(
    raw: &[u8],
    width: u32,
    height: u32,
    pattern: BayerPattern,
    captured: ClusterTime,
) -> Result<Frame, BayerError> {
    let mut out = Frame::new(0, 0, captured);
    half_resolution_into(raw, width, height, pattern, captured, &mut out)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mosaic a sensor with `pattern` gives for an image of known cell colours.
    fn mosaic(colours: &[[u8; 4]], cells_w: usize, pattern: BayerPattern) -> Vec<u8> {
        // colours: per cell (r, g_a, g_b, b).
        let cells_h = colours.len() / cells_w;
        let w = 2 * cells_w;
        let mut raw = vec![0u8; w * 2 * cells_h];
        let (r, [g0, g1], b) = pattern.offsets();
        for (i, c) in colours.iter().enumerate() {
            let (cx, cy) = (i % cells_w, i / cells_w);
            let at = |k: usize| (2 * cy + k / 2) * w + 2 * cx + k % 2;
            raw[at(r)] = c[0];
            raw[at(g0)] = c[1];
            raw[at(g1)] = c[2];
            raw[at(b)] = c[3];
        }
        raw
    }

    #[test]
    fn every_pattern_maps_cells_back_to_their_colours() {
        let colours = [
            [255, 0, 0, 0],
            [0, 255, 255, 0],
            [0, 0, 0, 255],
            [10, 100, 102, 200],
            [200, 51, 50, 7],
            [1, 2, 3, 4],
        ];
        for pattern in [
            BayerPattern::Rggb,
            BayerPattern::Bggr,
            BayerPattern::Grbg,
            BayerPattern::Gbrg,
        ] {
            let raw = mosaic(&colours, 3, pattern);
            let f = half_resolution(&raw, 6, 4, pattern, ClusterTime::from_millis(5)).unwrap();
            assert_eq!(
                (f.width, f.height, f.captured),
                (3, 2, ClusterTime::from_millis(5))
            );
            for (i, c) in colours.iter().enumerate() {
                let g = (c[1] as u16 + c[2] as u16).div_ceil(2) as u8;
                assert_eq!(
                    f.pixel(i as u32 % 3, i as u32 / 3),
                    [c[0], g, c[3]],
                    "{pattern:?} cell {i}"
                );
            }
        }
    }

    #[test]
    fn a_wrong_pattern_swaps_red_and_blue() {
        let raw = mosaic(&[[250, 30, 30, 5]], 1, BayerPattern::Rggb);
        let f = half_resolution(&raw, 2, 2, BayerPattern::Bggr, ClusterTime::ZERO).unwrap();
        assert_eq!(f.pixel(0, 0), [5, 30, 250]);
    }

    #[test]
    fn odd_sizes_drop_the_last_row_and_column_and_bad_buffers_are_rejected() {
        let raw: Vec<u8> = (0..5 * 3).map(|v| v as u8).collect();
        let f = half_resolution(&raw, 5, 3, BayerPattern::Rggb, ClusterTime::ZERO).unwrap();
        assert_eq!((f.width, f.height), (2, 1));
        // Cell (1, 0): raw (2,0)=2 red, (3,0)=3 and (2,1)=7 green, (3,1)=8 blue.
        assert_eq!(f.pixel(1, 0), [2, 5, 8]);
        let mut out = f.clone();
        assert!(matches!(
            half_resolution_into(&raw[1..], 5, 3, BayerPattern::Rggb, ClusterTime::ZERO, &mut out),
            Err(BayerError::Buffer {
                got: 14,
                want: 15,
                ..
            })
        ));
        assert_eq!(out, f, "a rejected buffer leaves the frame as it was");
        assert!(matches!(
            half_resolution(&[0], 1, 1, BayerPattern::Rggb, ClusterTime::ZERO),
            Err(BayerError::Size { .. })
        ));
    }
}
