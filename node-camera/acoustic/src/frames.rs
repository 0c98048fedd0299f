//! A recording as timed ILD vectors, one per frame of `frame_ms`: what `ocelli acoustic
//! locate` feeds the grid estimator (`node_head::grid::locate`). Silent and clipped frames
//! carry no ILD (the estimator only predicts over them) and are counted.

use crate::ild::{IldAnalyzer, IldError};
use crate::wav::{FrameQuality, StereoClip};
use proto::acoustic::{IldSettings, IldVector};
use thiserror::Error;

/// Why a recording could not be cut into frames.
#[derive(Debug, Error)]
pub enum FramesError {
    #[error(
        "{path}: frames of {frame_ms} ms are {samples} samples, shorter than one {block} sample FFT block"
    )]
    FrameTooShort {
        path: String,
        frame_ms: f64,
        samples: usize,
        block: usize,
    },
    #[error("{path}: sample rate {found} Hz; the fingerprints use {expected} Hz")]
    SampleRate { path: String, found: u32, expected: u32 },
    #[error("{path}: {source}")]
    Ild { path: String, source: IldError },
}

/// One frame's observation.
#[derive(Clone, Debug, PartialEq)]
pub struct TimedIld {
    /// Seconds from the start of the recording to the frame's first sample.
    pub t: f64,
    /// `None` for a frame that was silent or clipped.
    pub ild: Option<IldVector>,
    pub quality: FrameQuality,
}

/// How many frames of each quality a recording had.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameCounts {
    pub good: usize,
    pub silent: usize,
    pub clipped: usize,
}

/// Cut `clip` into consecutive frames of `frame_ms` and analyse each good one.
///
/// # Errors
/// A frame shorter than one FFT block, a clip at another sample rate than `settings`, or
/// invalid settings.
pub fn frame_ilds(
    clip: &StereoClip,
    settings: &IldSettings,
    frame_ms: f64,
) -> Result<(Vec<TimedIld>, FrameCounts), FramesError> {
    let path = clip.path.display().to_string();
    if clip.sample_rate != settings.sample_rate {
        return Err(FramesError::SampleRate {
            path,
            found: clip.sample_rate,
            expected: settings.sample_rate,
        });
    }
    let samples = (frame_ms / 1000.0 * f64::from(clip.sample_rate)).round();
    if !(samples.is_finite() && samples >= settings.block_len as f64) {
        return Err(FramesError::FrameTooShort {
            path,
            frame_ms,
            samples: samples.max(0.0) as usize,
            block: settings.block_len,
        });
    }
    let mut analyzer = IldAnalyzer::new(settings).map_err(|source| FramesError::Ild {
        path: path.clone(),
        source,
    })?;
    let mut counts = FrameCounts::default();
    let mut out = Vec::new();
    for frame in clip.frames(samples as usize) {
        let ild = match frame.quality {
            FrameQuality::Good => {
                counts.good += 1;
                Some(
                    analyzer
                        .analyze(frame.left, frame.right)
                        .map_err(|source| FramesError::Ild {
                            path: path.clone(),
                            source,
                        })?,
                )
            }
            FrameQuality::Silent => {
                counts.silent += 1;
                None
            }
            FrameQuality::Clipped => {
                counts.clipped += 1;
                None
            }
        };
        out.push(TimedIld {
            t: frame.t,
            ild,
            quality: frame.quality,
        });
    }
    if counts.silent + counts.clipped > 0 {
        tracing::warn!(
            file = %path,
            silent = counts.silent,
            clipped = counts.clipped,
            good = counts.good,
            "frames skipped"
        );
    }
    Ok((out, counts))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn clip(left: Vec<f32>, right: Vec<f32>) -> StereoClip {
        StereoClip {
            path: PathBuf::from("mem.wav"),
            sample_rate: 48_000,
            left,
            right,
            clipped_samples: 0,
        }
    }

    #[test]
    fn frames_are_timed_analysed_and_skipped_when_silent() {
        let n = 48_000;
        let left: Vec<f32> = (0..n)
            .map(|i| 0.1 * ((i as f32) * 0.37).sin() + 0.05 * ((i as f32) * 1.91).sin())
            .collect();
        let mut right: Vec<f32> = left.iter().map(|v| 0.5 * v).collect();
        right[12_000..24_000].fill(0.0); // the second 250 ms frame is silent on the right
        let (frames, counts) = frame_ilds(&clip(left, right), &IldSettings::default(), 250.0).unwrap();
        assert_eq!(frames.len(), 4);
        assert_eq!(
            counts,
            FrameCounts {
                good: 3,
                silent: 1,
                clipped: 0
            }
        );
        assert_eq!(frames[1].ild, None);
        assert_eq!(frames[1].quality, FrameQuality::Silent);
        assert!((frames[3].t - 0.75).abs() < 1e-12);
        assert!(frames[0].ild.as_ref().unwrap().values.iter().any(|v| *v > 0.0));
    }

    #[test]
    fn frames_shorter_than_a_block_are_refused() {
        let c = clip(vec![0.1; 4800], vec![0.1; 4800]);
        let e = frame_ilds(&c, &IldSettings::default(), 10.0).unwrap_err();
        assert!(
            e.to_string().contains("mem.wav") && e.to_string().contains("480 samples"),
            "{e}"
        );
    }
}
