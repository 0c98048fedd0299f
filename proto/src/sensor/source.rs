//! Where a node's raw input comes from, behind one interface per kind: [`FrameSource`] for
//! cameras (files, streams, devices, or the simulated world's renderer) and [`RadioSource`] for
//! the radio tags a node hears (BLE, recorded files, or the simulated radio). A node's runtime owns
//! its sources and hands what they deliver to the core; the core never sees a source, and a
//! real node is given real sources only.

use crate::ids::TagId;
use crate::sensor::Frame;
use crate::time::ClusterTime;
use std::path::PathBuf;
use thiserror::Error;

/// Why a source could not deliver a frame.
#[derive(Debug, Error)]
pub enum SourceError {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("cannot decode image {path}: {message}")]
    Decode { path: PathBuf, message: String },
    #[error("{path}: no PNG or JPEG frames")]
    Empty { path: PathBuf },
    #[error("{path}:{line}: {problem}")]
    Manifest {
        path: PathBuf,
        line: usize,
        problem: String,
    },
    #[error("frame rate must be positive and finite, got {0}")]
    Rate(f64),
    #[error("image {path} is {got_w}x{got_h}, the sequence is {want_w}x{want_h}")]
    Size {
        path: PathBuf,
        got_w: u32,
        got_h: u32,
        want_w: u32,
        want_h: u32,
    },
    #[error("capture device: {0}")]
    Device(String),
    #[error("{path}: no readings of sensor {sensor}")]
    NoReadings { path: PathBuf, sensor: TagId },
    #[error("{source_name}: stalled, no samples for {waited_ms} ms")]
    Stalled { source_name: String, waited_ms: u64 },
}

/// Something that produces frames.
pub trait FrameSource {
    /// Frame size, pixels.
    fn size(&self) -> (u32, u32);

    /// Capture the frame due at `now` into `frame` (resized if needed). `Ok(false)` when the
    /// source is exhausted.
    ///
    /// # Errors
    /// The source failed (device gone, unreadable file); `frame` is unspecified then.
    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError>;
}

/// One packet from a radio tag: who sent it, how strong it arrived, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TagReading {
    pub tag: TagId,
    /// Received power, dBm.
    pub dbm: f64,
    /// When the packet was received, cluster time.
    pub time: ClusterTime,
}

/// Something that hears radio tags.
pub trait RadioSource {
    /// Append the readings received up to `now` (since the last call) to `out`. `Ok(false)`
    /// when the source is exhausted (a recorded file that ended).
    ///
    /// # Errors
    /// The source failed (adapter gone, unreadable file).
    fn read(&mut self, now: ClusterTime, out: &mut Vec<TagReading>) -> Result<bool, SourceError>;
}
