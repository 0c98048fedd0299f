//! The two-microphone acoustic node of paper 001 (§3.1, §3.3): audio in, weighted interaural
//! level difference (ILD) vectors out.
//!
//! - [`wav`]: 2-channel WAV files, with clear errors for the ones that cannot be used and
//!   per-frame quality (silent, clipped) for the parts to skip;
//! - [`ild`]: per frame, the FFT of both channels, the ILD per frequency and its Macaulay
//!   weights (eq. 13–15), and the timing of one frame;
//! - [`survey`]: the fingerprint database from recordings at known positions;
//! - [`frames`]: a recording as timed ILD vectors, for the grid estimator's `locate` (which
//!   lives with the estimator in `node-head::grid::locate`).
//!
//! The vocabulary (ILD vector, settings, fingerprints) is `proto::acoustic`'s; this crate adds
//! only what needs an FFT or a file.

pub mod frames;
pub mod ild;
pub mod survey;
pub mod wav;

pub use ild::{IldAnalyzer, IldError, bench_ild};
pub use wav::{FrameQuality, StereoClip, WavError, read_stereo};
