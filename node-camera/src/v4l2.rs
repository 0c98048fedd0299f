//! Live capture from a V4L2 device (cargo feature `v4l2`; Linux only).
//!
//! Uses the `rscam` crate with its `no_wrapper` feature, so it talks to the kernel through
//! plain ioctls and needs no libv4l at build or run time. The device is asked for YUYV (which
//! nearly every UVC camera and the Pi camera's V4L2 driver offer) at the camera's resolution
//! and frame rate and converted to RGB8 (BT.601); MJPG is accepted as a fallback and decoded.
//!
//! ```text
//! cargo build -p deploy --release --features node-camera/v4l2
//! ocelli camera --scenario pi.toml --id 10 --source v4l2:/dev/video0
//! ```
//! The tests never open a device.

use proto::ClusterTime;
use proto::sensor::Frame;
use proto::sensor::{FrameSource, SourceError};

/// A V4L2 capture device.
pub struct V4l2Source {
    camera: rscam::Camera,
    size: (u32, u32),
    format: [u8; 4],
}

impl std::fmt::Debug for V4l2Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("V4l2Source")
            .field("size", &self.size)
            .field("format", &String::from_utf8_lossy(&self.format))
            .finish()
    }
}

impl V4l2Source {
    /// Open `device` (e.g. `/dev/video0`) and start streaming at `width`×`height`, `fps`.
    ///
    /// # Errors
    /// The device cannot be opened or offers neither YUYV nor MJPG at that size and rate.
    pub fn open(device: &str, width: u32, height: u32, fps: f64) -> Result<V4l2Source, SourceError> {
        let dev = |e: String| SourceError::Device(format!("{device}: {e}"));
        let mut camera = rscam::Camera::new(device).map_err(|e| dev(e.to_string()))?;
        let interval = (1000, (fps * 1000.0).round().max(1.0) as u32);
        let mut last = String::new();
        for format in [b"YUYV", b"MJPG"] {
            let cfg = rscam::Config {
                interval,
                resolution: (width, height),
                format,
                ..rscam::Config::default()
            };
            match camera.start(&cfg) {
                Ok(()) => {
                    return Ok(V4l2Source {
                        camera,
                        size: (width, height),
                        format: *format,
                    });
                }
                Err(e) => last = format!("{}: {e}", String::from_utf8_lossy(format)),
            }
        }
        Err(dev(format!("no usable format ({last})")))
    }
}

/// YUYV (4:2:2) → RGB8, BT.601 limited range, integer arithmetic.
pub fn yuyv_to_rgb(src: &[u8], out: &mut [u8]) {
    fn px(y: i32, u: i32, v: i32, o: &mut [u8]) {
        let c = 298 * (y - 16);
        let (d, e) = (u - 128, v - 128);
        o[0] = ((c + 409 * e + 128) >> 8).clamp(0, 255) as u8;
        o[1] = ((c - 100 * d - 208 * e + 128) >> 8).clamp(0, 255) as u8;
        o[2] = ((c + 516 * d + 128) >> 8).clamp(0, 255) as u8;
    }
    for (s, o) in src.chunks_exact(4).zip(out.chunks_exact_mut(6)) {
        let (y0, u, y1, v) = (s[0] as i32, s[1] as i32, s[2] as i32, s[3] as i32);
        px(y0, u, v, &mut o[0..3]);
        px(y1, u, v, &mut o[3..6]);
    }
}

impl FrameSource for V4l2Source {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        let raw = self
            .camera
            .capture()
            .map_err(|e| SourceError::Device(e.to_string()))?;
        let (w, h) = raw.resolution;
        frame.width = w;
        frame.height = h;
        frame.captured = now;
        frame.data.resize(w as usize * h as usize * 3, 0);
        if &self.format == b"YUYV" {
            yuyv_to_rgb(&raw, &mut frame.data);
        } else {
            let img = image::load_from_memory_with_format(&raw, image::ImageFormat::Jpeg)
                .map_err(|e| SourceError::Device(format!("MJPG frame: {e}")))?
                .to_rgb8();
            frame.data.copy_from_slice(img.as_raw());
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_grey_and_red() {
        let mut out = [0u8; 6];
        yuyv_to_rgb(&[126, 128, 126, 128], &mut out);
        assert!(out.iter().all(|&v| (126..=130).contains(&v)), "{out:?}");
        yuyv_to_rgb(&[81, 90, 81, 240], &mut out);
        assert!(out[0] > 230 && out[1] < 20 && out[2] < 20, "{out:?}");
    }
}
