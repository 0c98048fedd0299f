//! The two-microphone acoustic node of paper 001 (§3.1, §3.3): audio in, weighted interaural
//! level difference (ILD) vectors out.
//!
//! - [`wav`]: 2-channel WAV files, with clear errors for the ones that cannot be used and
//!   per-frame quality (silent, clipped) for the parts to skip;
//! - [`ild`]: per frame, the FFT of both channels, the ILD per frequency and its Macaulay
//!   weights (eq. 13–15), and the timing of one frame;
//! - [`survey`]: the fingerprint database from recordings at known positions;
//! - [`frames`]: a recording as timed ILD vectors, for the grid estimator's `locate` (which
//!   lives with the estimator in `node-head::grid::locate`);
//! - [`node`]: the node core (`proto::node::Node`): audio frames in, ILD observations to its
//!   head, status like a camera's; [`config`] builds it from the scenario;
//! - [`source`]: WAV files as an `AudioSource`; `live` (feature `cpal`): capture devices;
//! - [`process`]: the node as an OS process on `runtime::process::run`.
//!
//! The vocabulary (ILD vector, settings, fingerprints) is `proto::acoustic`'s; this crate adds
//! only what needs an FFT or a file.

pub mod config;
pub mod frames;
pub mod ild;
#[cfg(feature = "cpal")]
pub mod live;
pub mod node;
pub mod process;
pub mod source;
pub mod survey;
pub mod wav;

pub use ild::{IldAnalyzer, IldError, bench_ild};
pub use node::{AcousticInput, AcousticNode};
pub use wav::{FrameQuality, StereoClip, WavError, read_stereo, write_stereo};
