//! The frame every source produces and every segmenter reads: an RGB8 image with its capture
//! time. Sources fill it; the core only reads it.

use crate::time::ClusterTime;
use thiserror::Error;

/// Largest frame side the camera node accepts, pixels (a 4K sensor fits).
pub const MAX_FRAME_SIDE: u32 = 8192;

/// An RGB8 image, row-major, 3 bytes per pixel, no padding, with its capture time.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` bytes.
    pub data: Vec<u8>,
    pub captured: ClusterTime,
}

/// A frame whose shape does not fit its buffer or the camera.
#[derive(Debug, Error, PartialEq)]
pub enum FrameError {
    #[error("frame size {width}x{height} is outside 1..={max} per side")]
    Size { width: u32, height: u32, max: u32 },
    #[error("frame buffer has {got} bytes, a {width}x{height} RGB8 frame needs {want}")]
    Buffer {
        width: u32,
        height: u32,
        got: usize,
        want: usize,
    },
    #[error("frame is {got_w}x{got_h} but the camera is configured for {want_w}x{want_h}")]
    Mismatch {
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
}

impl Frame {
    /// A black frame.
    pub fn new(width: u32, height: u32, captured: ClusterTime) -> Frame {
        Frame {
            width,
            height,
            data: vec![0; width as usize * height as usize * 3],
            captured,
        }
    }

    /// Check that the buffer holds exactly `width × height` RGB8 pixels.
    ///
    /// # Errors
    /// [`FrameError::Size`] or [`FrameError::Buffer`].
    pub fn check(&self) -> Result<(), FrameError> {
        if self.width == 0 || self.height == 0 || self.width > MAX_FRAME_SIDE || self.height > MAX_FRAME_SIDE
        {
            return Err(FrameError::Size {
                width: self.width,
                height: self.height,
                max: MAX_FRAME_SIDE,
            });
        }
        let want = self.width as usize * self.height as usize * 3;
        if self.data.len() != want {
            return Err(FrameError::Buffer {
                width: self.width,
                height: self.height,
                got: self.data.len(),
                want,
            });
        }
        Ok(())
    }

    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = (y as usize * self.width as usize + x as usize) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Draw a rectangle outline (for debugging images and the MultiviewX test's picture).
    pub fn draw_box(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, rgb: [u8; 3], thickness: i64) {
        let (w, h) = (self.width as i64, self.height as i64);
        let mut put = |x: i64, y: i64| {
            if (0..w).contains(&x) && (0..h).contains(&y) {
                let i = ((y * w + x) * 3) as usize;
                self.data[i..i + 3].copy_from_slice(&rgb);
            }
        };
        for t in 0..thickness {
            for x in x0..=x1 {
                put(x, y0 + t);
                put(x, y1 - t);
            }
            for y in y0..=y1 {
                put(x0 + t, y);
                put(x1 - t, y);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_rejects_bad_buffers() {
        let mut f = Frame::new(4, 3, ClusterTime::ZERO);
        assert_eq!(f.check(), Ok(()));
        f.data.pop();
        assert!(matches!(
            f.check(),
            Err(FrameError::Buffer {
                got: 35,
                want: 36,
                ..
            })
        ));
        let z = Frame {
            width: 0,
            height: 3,
            data: vec![],
            captured: ClusterTime::ZERO,
        };
        assert!(matches!(z.check(), Err(FrameError::Size { .. })));
    }
}
