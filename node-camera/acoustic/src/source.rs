//! Where an acoustic node's audio comes from, behind `proto::sensor::AudioSource`: a 2-channel
//! WAV file played at its own pace ([`WavSource`]), or live capture (`live`, feature `cpal`).
//! The simulated room's source lives with the simulated world.

use crate::wav::{StereoClip, WavError, read_stereo};
use proto::ClusterTime;
use proto::sensor::{AudioFrame, AudioSource, SourceError};
use std::path::Path;

/// A 2-channel WAV file as a stream of frames, from its start, optionally looping.
#[derive(Clone, Debug)]
pub struct WavSource {
    clip: StereoClip,
    next: usize,
    looping: bool,
}

impl WavSource {
    /// Read `path`, which must be recorded at `sample_rate` Hz.
    ///
    /// # Errors
    /// Every problem [`read_stereo`] names (mono, another rate, truncated, silent, clipped).
    pub fn open(path: &Path, sample_rate: u32) -> Result<WavSource, WavError> {
        Ok(WavSource {
            clip: read_stereo(path, sample_rate)?,
            next: 0,
            looping: false,
        })
    }

    /// Start again at the end instead of ending.
    pub fn looping(mut self, on: bool) -> Self {
        self.looping = on;
        self
    }
}

impl AudioSource for WavSource {
    fn sample_rate(&self) -> u32 {
        self.clip.sample_rate
    }

    fn capture(
        &mut self,
        now: ClusterTime,
        samples: usize,
        frame: &mut AudioFrame,
    ) -> Result<bool, SourceError> {
        let len = self.clip.left.len();
        if self.next + samples > len {
            if !self.looping || samples > len {
                return Ok(false);
            }
            self.next = 0;
        }
        let range = self.next..self.next + samples;
        frame.sample_rate = self.clip.sample_rate;
        frame.left.clear();
        frame.left.extend_from_slice(&self.clip.left[range.clone()]);
        frame.right.clear();
        frame.right.extend_from_slice(&self.clip.right[range]);
        frame.captured = now;
        self.next += samples;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wav_file_streams_in_frames_and_ends_or_loops() {
        let dir = std::env::temp_dir().join(format!("ocelli-wavsource-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.wav");
        let left: Vec<f32> = (0..1000).map(|i| 0.1 * ((i as f32) * 0.3).sin()).collect();
        let right: Vec<f32> = left.iter().map(|v| 0.5 * v).collect();
        crate::wav::write_stereo(&path, 8000, &left, &right).unwrap();
        let mut s = WavSource::open(&path, 8000).unwrap();
        let mut f = AudioFrame::default();
        assert!(s.capture(ClusterTime(5), 400, &mut f).unwrap());
        assert_eq!((f.len(), f.sample_rate, f.captured), (400, 8000, ClusterTime(5)));
        assert!((f.left[10] - left[10]).abs() < 1e-6);
        assert!(s.capture(ClusterTime(6), 400, &mut f).unwrap());
        assert!(
            !s.capture(ClusterTime(7), 400, &mut f).unwrap(),
            "200 samples left"
        );
        let mut s = WavSource::open(&path, 8000).unwrap().looping(true);
        for _ in 0..5 {
            assert!(s.capture(ClusterTime(8), 400, &mut f).unwrap());
        }
        assert!(WavSource::open(&path, 48_000).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
