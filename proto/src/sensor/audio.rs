//! What a two-microphone acoustic node's source delivers: [`AudioFrame`]s of both channels,
//! from an [`AudioSource`] — a WAV file, a live capture device, or the simulated room.

use crate::sensor::SourceError;
use crate::time::ClusterTime;

/// Both channels of one stretch of audio, samples of full scale 1, with the time its last
/// sample was captured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AudioFrame {
    /// Hz.
    pub sample_rate: u32,
    pub left: Vec<f32>,
    pub right: Vec<f32>,
    /// When the frame's last sample was captured, cluster time.
    pub captured: ClusterTime,
}

impl AudioFrame {
    /// Samples per channel (the shorter channel's count if they differ).
    pub fn len(&self) -> usize {
        self.left.len().min(self.right.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Seconds of audio.
    pub fn duration_s(&self) -> f64 {
        if self.sample_rate == 0 {
            return 0.0;
        }
        self.len() as f64 / f64::from(self.sample_rate)
    }
}

/// Something that produces two-channel audio.
pub trait AudioSource {
    /// Sample rate, Hz.
    fn sample_rate(&self) -> u32;

    /// The next `samples` samples per channel into `frame`, the last one captured at about
    /// `now`. `Ok(false)` when the source is exhausted (a file that ended).
    ///
    /// # Errors
    /// The source failed ([`SourceError::Stalled`]: a live stream delivered nothing in time;
    /// the caller counts it and asks again).
    fn capture(
        &mut self,
        now: ClusterTime,
        samples: usize,
        frame: &mut AudioFrame,
    ) -> Result<bool, SourceError>;
}
