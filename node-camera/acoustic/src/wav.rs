//! Reading a two-microphone recording: a 2-channel WAV file (hound), as `f32` samples in
//! [−1, 1], with clear errors for the files an acoustic node cannot use and per-frame quality
//! for the parts it should skip.
//!
//! Refused, each error naming the file and the problem: not a WAV, not 2 channels, another
//! sample rate, truncated (the data chunk ends before the samples its header declares), silent
//! throughout, or clipped in more than [`MAX_CLIPPED_FRACTION`] of its samples. A file that is
//! only partly silent or clipped is read, and [`StereoClip::frames`] marks those frames so
//! the caller skips and counts them.

use std::path::{Path, PathBuf};
use thiserror::Error;

/// A sample at or beyond this magnitude (of full scale 1) counts as clipped.
pub const CLIP_LEVEL: f32 = 0.999;
/// A channel whose RMS is below this (−80 dBFS) is silent.
pub const SILENCE_RMS: f32 = 1e-4;
/// A file with more clipped samples than this fraction is refused.
pub const MAX_CLIPPED_FRACTION: f64 = 0.01;
/// A frame with more clipped samples than this fraction is marked clipped.
pub const FRAME_CLIPPED_FRACTION: f64 = 0.001;

/// Why a WAV file cannot be used.
#[derive(Debug, Error)]
pub enum WavError {
    #[error("{path}: cannot read as WAV: {source}")]
    Open { path: PathBuf, source: hound::Error },
    #[error("{path}: {channels} channel(s); an acoustic node needs 2 (left, right)")]
    Channels { path: PathBuf, channels: u16 },
    #[error("{path}: sample rate {found} Hz; the fingerprints use {expected} Hz")]
    SampleRate {
        path: PathBuf,
        found: u32,
        expected: u32,
    },
    #[error("{path}: truncated: {read} of the {declared} samples its header declares ({problem})")]
    Truncated {
        path: PathBuf,
        read: usize,
        declared: usize,
        problem: String,
    },
    #[error("{path}: silent (RMS below {SILENCE_RMS} of full scale in channel {channel})")]
    Silent { path: PathBuf, channel: &'static str },
    #[error("{path}: clipped: {percent:.1} % of samples at full scale (at most {max:.1} % allowed)")]
    Clipped { path: PathBuf, percent: f64, max: f64 },
}

/// A two-channel recording.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoClip {
    pub path: PathBuf,
    pub sample_rate: u32,
    pub left: Vec<f32>,
    pub right: Vec<f32>,
    /// Samples (either channel) at full scale.
    pub clipped_samples: usize,
}

/// Whether a frame can be analysed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameQuality {
    Good,
    /// More than [`FRAME_CLIPPED_FRACTION`] of its samples at full scale.
    Clipped,
    /// A channel below [`SILENCE_RMS`].
    Silent,
}

/// One frame of a clip.
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// Seconds from the start of the clip to the frame's first sample.
    pub t: f64,
    pub left: &'a [f32],
    pub right: &'a [f32],
    pub quality: FrameQuality,
}

fn rms(x: &[f32]) -> f32 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f32>() / x.len() as f32).sqrt()
}

fn clipped(x: &[f32]) -> usize {
    x.iter().filter(|v| v.abs() >= CLIP_LEVEL).count()
}

/// Read a 2-channel WAV at `expected_rate` Hz.
///
/// # Errors
/// Any [`WavError`]: each names the file and what is wrong with it.
pub fn read_stereo(path: &Path, expected_rate: u32) -> Result<StereoClip, WavError> {
    let open = |source| WavError::Open {
        path: path.into(),
        source,
    };
    let mut reader = hound::WavReader::open(path).map_err(open)?;
    let spec = reader.spec();
    if spec.channels != 2 {
        return Err(WavError::Channels {
            path: path.into(),
            channels: spec.channels,
        });
    }
    if spec.sample_rate != expected_rate {
        return Err(WavError::SampleRate {
            path: path.into(),
            found: spec.sample_rate,
            expected: expected_rate,
        });
    }
    let declared = reader.len() as usize;
    let mut interleaved = Vec::with_capacity(declared);
    let truncated = |read: usize, problem: String| WavError::Truncated {
        path: path.into(),
        read,
        declared,
        problem,
    };
    match spec.sample_format {
        hound::SampleFormat::Float => {
            for s in reader.samples::<f32>() {
                interleaved.push(s.map_err(|e| truncated(interleaved.len(), e.to_string()))?);
            }
        }
        hound::SampleFormat::Int => {
            let scale = 1.0 / (1u64 << (spec.bits_per_sample - 1)) as f32;
            for s in reader.samples::<i32>() {
                let v = s.map_err(|e| truncated(interleaved.len(), e.to_string()))?;
                interleaved.push(v as f32 * scale);
            }
        }
    }
    if interleaved.len() < declared || interleaved.len() % 2 != 0 {
        return Err(truncated(interleaved.len(), "the data ends early".into()));
    }
    let (left, right): (Vec<f32>, Vec<f32>) = interleaved.chunks_exact(2).map(|p| (p[0], p[1])).unzip();
    for (channel, samples) in [("left", &left), ("right", &right)] {
        if rms(samples) < SILENCE_RMS {
            return Err(WavError::Silent {
                path: path.into(),
                channel,
            });
        }
    }
    let clipped_samples = clipped(&left) + clipped(&right);
    let fraction = clipped_samples as f64 / interleaved.len().max(1) as f64;
    if fraction > MAX_CLIPPED_FRACTION {
        return Err(WavError::Clipped {
            path: path.into(),
            percent: 100.0 * fraction,
            max: 100.0 * MAX_CLIPPED_FRACTION,
        });
    }
    Ok(StereoClip {
        path: path.into(),
        sample_rate: spec.sample_rate,
        left,
        right,
        clipped_samples,
    })
}

/// Write a 2-channel 32-bit float WAV (for recordings the simulated room renders, and tests).
///
/// # Errors
/// The file cannot be created or written ([`WavError::Open`] naming it).
pub fn write_stereo(path: &Path, sample_rate: u32, left: &[f32], right: &[f32]) -> Result<(), WavError> {
    let open = |source| WavError::Open {
        path: path.into(),
        source,
    };
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).map_err(open)?;
    for (l, r) in left.iter().zip(right) {
        w.write_sample(*l).map_err(open)?;
        w.write_sample(*r).map_err(open)?;
    }
    w.finalize().map_err(open)
}

/// The quality of one frame of samples.
pub fn frame_quality(left: &[f32], right: &[f32]) -> FrameQuality {
    let n = (left.len() + right.len()).max(1) as f64;
    if (clipped(left) + clipped(right)) as f64 / n > FRAME_CLIPPED_FRACTION {
        FrameQuality::Clipped
    } else if rms(left) < SILENCE_RMS || rms(right) < SILENCE_RMS {
        FrameQuality::Silent
    } else {
        FrameQuality::Good
    }
}

impl StereoClip {
    /// Duration, seconds.
    pub fn duration(&self) -> f64 {
        self.left.len() as f64 / f64::from(self.sample_rate)
    }

    /// Consecutive frames of `frame_len` samples (a shorter tail is dropped), with quality.
    pub fn frames(&self, frame_len: usize) -> impl Iterator<Item = Frame<'_>> {
        let frame_len = frame_len.max(1);
        let rate = f64::from(self.sample_rate);
        self.left
            .chunks_exact(frame_len)
            .zip(self.right.chunks_exact(frame_len))
            .enumerate()
            .map(move |(k, (left, right))| Frame {
                t: (k * frame_len) as f64 / rate,
                left,
                right,
                quality: frame_quality(left, right),
            })
    }
}

#[cfg(test)]
pub(crate) mod tests;
