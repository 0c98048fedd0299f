//! Frame sources behind one interface: the synthetic renderer ([`crate::render`]), a directory
//! of PNG/JPEG frames, and live V4L2 capture (cargo feature `v4l2`, see [`crate::v4l2`]).
//! The runtime owns the source and hands frames to the core; the core never sees a source.

use proto::ClusterTime;
use proto::sensor::{Frame, FrameSource, SourceError};
use std::path::{Path, PathBuf};

/// A directory of PNG/JPEG frames, in file-name order.
///
/// Timestamps come from a manifest (`<file name> <seconds>` per line, `#` comments) or from a
/// frame rate; a frame's capture time is the first `capture`'s `now` plus its timestamp.
#[derive(Debug)]
pub struct ImageSequence {
    files: Vec<PathBuf>,
    times: Vec<f64>,
    next: usize,
    epoch: Option<ClusterTime>,
    size: (u32, u32),
    looped: bool,
}

fn is_image(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
}

impl ImageSequence {
    /// Frames of `dir` at `fps`.
    ///
    /// # Errors
    /// The directory is unreadable, holds no images, or `fps` is not positive.
    pub fn with_rate(dir: &Path, fps: f64) -> Result<ImageSequence, SourceError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(SourceError::Rate(fps));
        }
        let files = Self::list(dir)?;
        let times = (0..files.len()).map(|i| i as f64 / fps).collect();
        Self::build(files, times)
    }

    /// Frames of `dir` with timestamps from `manifest`. Files the manifest does not name are
    /// skipped.
    ///
    /// # Errors
    /// As [`ImageSequence::with_rate`], plus a malformed manifest line, a name that is not in
    /// the directory, or timestamps that go backwards.
    pub fn with_manifest(dir: &Path, manifest: &Path) -> Result<ImageSequence, SourceError> {
        let text = std::fs::read_to_string(manifest).map_err(|source| SourceError::Io {
            path: manifest.into(),
            source,
        })?;
        let bad = |line: usize, problem: String| SourceError::Manifest {
            path: manifest.into(),
            line,
            problem,
        };
        let mut entries: Vec<(PathBuf, f64)> = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let mut parts = line.split_whitespace();
            let (Some(name), Some(t), None) = (parts.next(), parts.next(), parts.next()) else {
                return Err(bad(i + 1, "expected `<file name> <seconds>`".into()));
            };
            let t: f64 = t
                .parse()
                .map_err(|_| bad(i + 1, format!("`{t}` is not a number of seconds")))?;
            if !t.is_finite() || entries.last().is_some_and(|(_, last)| t < *last) {
                return Err(bad(i + 1, format!("timestamp {t} is not finite and increasing")));
            }
            let path = dir.join(name);
            if !path.is_file() || !is_image(&path) {
                return Err(bad(i + 1, format!("{} is not an image file", path.display())));
            }
            entries.push((path, t));
        }
        if entries.is_empty() {
            return Err(SourceError::Empty {
                path: manifest.into(),
            });
        }
        let (files, times) = entries.into_iter().unzip();
        Self::build(files, times)
    }

    fn list(dir: &Path) -> Result<Vec<PathBuf>, SourceError> {
        let io = |source| SourceError::Io {
            path: dir.into(),
            source,
        };
        let mut files = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(io)? {
            let p = entry.map_err(io)?.path();
            if p.is_file() && is_image(&p) {
                files.push(p);
            }
        }
        files.sort();
        if files.is_empty() {
            return Err(SourceError::Empty { path: dir.into() });
        }
        Ok(files)
    }

    fn build(files: Vec<PathBuf>, times: Vec<f64>) -> Result<ImageSequence, SourceError> {
        let size = image::image_dimensions(&files[0]).map_err(|e| SourceError::Decode {
            path: files[0].clone(),
            message: e.to_string(),
        })?;
        Ok(ImageSequence {
            files,
            times,
            next: 0,
            epoch: None,
            size,
            looped: false,
        })
    }

    /// Start over at the first frame when the sequence ends (timestamps keep increasing).
    pub fn looping(mut self, on: bool) -> Self {
        self.looped = on;
        self
    }

    pub fn len(&self) -> usize {
        self.files.len()
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// Decode one image into an RGB8 frame.
    ///
    /// # Errors
    /// Unreadable or undecodable file.
    pub fn load(path: &Path, captured: ClusterTime) -> Result<Frame, SourceError> {
        let img = image::open(path)
            .map_err(|e| SourceError::Decode {
                path: path.into(),
                message: e.to_string(),
            })?
            .to_rgb8();
        Ok(Frame {
            width: img.width(),
            height: img.height(),
            data: img.into_raw(),
            captured,
        })
    }
}

impl FrameSource for ImageSequence {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        let n = self.files.len();
        if self.next >= n && !self.looped {
            return Ok(false);
        }
        let epoch = *self.epoch.get_or_insert(now);
        let (lap, i) = (self.next / n, self.next % n);
        let period = self.times[n - 1] + self.times.get(1).map_or(1.0, |t1| t1 - self.times[0]);
        let t = self.times[i] + lap as f64 * period;
        let path = &self.files[i];
        let loaded = Self::load(path, epoch + (t * 1e9) as i64)?;
        if (loaded.width, loaded.height) != self.size {
            return Err(SourceError::Size {
                path: path.clone(),
                got_w: loaded.width,
                got_h: loaded.height,
                want_w: self.size.0,
                want_h: self.size.1,
            });
        }
        *frame = loaded;
        self.next += 1;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmpdir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ocelli-cam-src-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write_png(path: &Path, w: u32, h: u32, v: u8) {
        image::RgbImage::from_pixel(w, h, image::Rgb([v, v, v]))
            .save(path)
            .unwrap();
    }

    #[test]
    fn sequence_in_name_order_with_rate_and_manifest() {
        let d = tmpdir("seq");
        write_png(&d.join("b.png"), 8, 6, 20);
        write_png(&d.join("a.png"), 8, 6, 10);
        std::fs::write(d.join("notes.txt"), "not a frame").unwrap();
        let mut s = ImageSequence::with_rate(&d, 4.0).unwrap();
        assert_eq!(s.len(), 2);
        let mut f = Frame::new(1, 1, ClusterTime::ZERO);
        assert!(s.capture(ClusterTime::from_millis(1000), &mut f).unwrap());
        assert_eq!((f.width, f.height, f.data[0]), (8, 6, 10));
        assert!(s.capture(ClusterTime::from_millis(5000), &mut f).unwrap());
        assert_eq!(f.data[0], 20);
        assert_eq!(f.captured, ClusterTime::from_millis(1250));
        assert!(!s.capture(ClusterTime::ZERO, &mut f).unwrap());

        std::fs::write(d.join("m.txt"), "# name seconds\nb.png 0.0\na.png 0.5\n").unwrap();
        let mut m = ImageSequence::with_manifest(&d, &d.join("m.txt")).unwrap();
        m.capture(ClusterTime::ZERO, &mut f).unwrap();
        assert_eq!(f.data[0], 20);
        m.capture(ClusterTime::ZERO, &mut f).unwrap();
        assert_eq!((f.data[0], f.captured), (10, ClusterTime::from_millis(500)));

        std::fs::write(d.join("bad.txt"), "b.png 1.0\na.png 0.5\n").unwrap();
        let e = ImageSequence::with_manifest(&d, &d.join("bad.txt")).unwrap_err();
        assert!(e.to_string().contains(":2:"), "{e}");
        std::fs::write(d.join("bad2.txt"), "zzz.png 1.0\n").unwrap();
        assert!(ImageSequence::with_manifest(&d, &d.join("bad2.txt")).is_err());
        assert!(matches!(
            ImageSequence::with_rate(&d, 0.0),
            Err(SourceError::Rate(_))
        ));
        let _ = std::fs::remove_dir_all(&d);
    }
}
