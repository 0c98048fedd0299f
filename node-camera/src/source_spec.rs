//! What `--source` names, and opening it: `SourceSpec::parse` reads the one-string form the CLI
//! and the scenario use, [`open_source`] turns a spec into a running [`FrameSource`] at the
//! camera's size and rate, and [`SharedStats`] counts what happened to it (frames, ends,
//! errors, and for streams stalls, reconnects, resolution changes and decoder errors).
//!
//! | spec | source | needs |
//! |---|---|---|
//! | `synthetic` | the scenario's rendered world (`world::sources::SyntheticFrames`, injected by the CLI) | — |
//! | `images:DIR[?manifest=FILE][&loop]` | PNG/JPEG frames ([`crate::source::ImageSequence`]) | — |
//! | `v4l2:/dev/videoN` | a V4L2 device ([`crate::v4l2::V4l2Source`]) | feature `v4l2` (default) |
//! | `file:PATH[?loop]` | a video file: any container and codec GStreamer decodes | feature `gstreamer` |
//! | `rtsp://…`, `rtsps://…` | an RTSP stream (IP cameras) | feature `gstreamer` |
//! | `http://…`, `https://…` | an HTTP MJPEG stream (`multipart/x-mixed-replace`) | feature `gstreamer` |
//! | `libcamera[:NAME]` | a Pi camera through `libcamerasrc` | feature `gstreamer` |
//!
//! Finite sources (`file:`, `images:`) stop at their end unless `loop` is given: a recording
//! that starts over makes every person in it jump back to where they were, which a tracker
//! must not be fed silently. Stream URLs are passed on untouched (their own `?query` included).
//! A spec always parses whatever this build holds; [`open_source`] (and
//! [`SourceSpec::missing_feature`]) say which cargo feature a source needs when it is missing.

use crate::source::ImageSequence;
use proto::ClusterTime;
use proto::sensor::{Frame, MAX_FRAME_SIDE};
use proto::sensor::{FrameSource, SourceError};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use thiserror::Error;

/// A frame source named on the command line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SourceSpec {
    /// The scenario's synthetic world.
    Synthetic,
    /// A directory of PNG/JPEG frames, at the camera's rate or timed by a manifest.
    Images {
        dir: PathBuf,
        manifest: Option<PathBuf>,
        looping: bool,
    },
    /// A V4L2 capture device.
    V4l2 { device: PathBuf },
    /// A video file.
    File { path: PathBuf, looping: bool },
    /// An RTSP stream, `rtsp://` or `rtsps://`.
    Rtsp { url: String },
    /// An HTTP(S) MJPEG stream.
    HttpMjpeg { url: String },
    /// A camera through libcamera; `None` takes the first one.
    Libcamera { camera: Option<String> },
}

/// A `--source` that cannot be used.
#[derive(Debug, Error)]
pub enum SpecError {
    #[error("empty --source: expected {FORMS}")]
    Empty,
    #[error("unknown --source `{0}`: expected {FORMS}")]
    Unknown(String),
    #[error("--source `{spec}`: {problem}")]
    Invalid { spec: String, problem: String },
    #[error(
        "--source `{spec}` needs the `{feature}` feature: this ocelli was built without the \
         `{feature}` feature (rebuild with `--features node-camera/{feature}`)"
    )]
    NotBuilt { spec: String, feature: &'static str },
    #[error(
        "--source synthetic renders the scenario's world: build it with \
         `world::sources::SyntheticFrames::new(scenario, id, seed, epoch)`"
    )]
    NeedsScenario,
    #[error("camera size {width}x{height} is outside 1..={MAX_FRAME_SIDE} per side")]
    Size { width: u32, height: u32 },
    #[error("camera frame rate must be positive and finite, got {0}")]
    Rate(f64),
    #[error(transparent)]
    Open(#[from] SourceError),
}

const FORMS: &str = "synthetic, images:DIR[?manifest=FILE][&loop], v4l2:/dev/videoN, \
                     file:PATH[?loop], rtsp://…, http://… (MJPEG) or libcamera[:NAME]";

/// A spec's `?key=value&flag` options, in order.
type Options<'a> = Vec<(&'a str, Option<&'a str>)>;

/// `path[?opt&opt=value]` → the path and its options; an option without `=` is a flag.
fn split_options<'a>(spec: &str, rest: &'a str) -> Result<(&'a str, Options<'a>), SpecError> {
    let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
    if path.is_empty() {
        return Err(SpecError::Invalid {
            spec: spec.into(),
            problem: "the path is empty".into(),
        });
    }
    let options = query
        .split('&')
        .filter(|o| !o.is_empty())
        .map(|o| match o.split_once('=') {
            Some((k, v)) => (k, Some(v)),
            None => (o, None),
        })
        .collect();
    Ok((path, options))
}

fn flag(spec: &str, key: &str, value: Option<&str>) -> Result<bool, SpecError> {
    match value {
        None | Some("true" | "1" | "yes") => Ok(true),
        Some("false" | "0" | "no") => Ok(false),
        Some(v) => Err(SpecError::Invalid {
            spec: spec.into(),
            problem: format!("option `{key}` takes true or false, not `{v}`"),
        }),
    }
}

fn unknown_option(spec: &str, key: &str, known: &str) -> SpecError {
    SpecError::Invalid {
        spec: spec.into(),
        problem: format!("unknown option `{key}` (known: {known})"),
    }
}

/// A URL's host part must be there and the URL must be one token.
fn check_url(spec: &str, rest: &str) -> Result<String, SpecError> {
    let host = rest.split(['/', '?', '#']).next().unwrap_or("");
    let problem = if host.is_empty() || host.starts_with(':') {
        Some("the URL has no host")
    } else if spec.chars().any(char::is_whitespace) {
        Some("the URL contains white space")
    } else {
        None
    };
    match problem {
        Some(p) => Err(SpecError::Invalid {
            spec: spec.into(),
            problem: p.into(),
        }),
        None => Ok(spec.into()),
    }
}

impl SourceSpec {
    /// Read a `--source` string (forms in the module docs).
    ///
    /// # Errors
    /// [`SpecError::Empty`], [`SpecError::Unknown`] (the forms are listed), or
    /// [`SpecError::Invalid`] naming the problem (empty path, missing host, unknown option).
    pub fn parse(s: &str) -> Result<SourceSpec, SpecError> {
        let spec = s.trim();
        if spec.is_empty() {
            return Err(SpecError::Empty);
        }
        if spec == "synthetic" {
            return Ok(SourceSpec::Synthetic);
        }
        if spec == "libcamera" {
            return Ok(SourceSpec::Libcamera { camera: None });
        }
        if let Some(name) = spec.strip_prefix("libcamera:") {
            if name.is_empty() {
                return Err(SpecError::Invalid {
                    spec: spec.into(),
                    problem: "the camera name is empty (plain `libcamera` takes the first)".into(),
                });
            }
            return Ok(SourceSpec::Libcamera {
                camera: Some(name.into()),
            });
        }
        let lower = spec.to_ascii_lowercase();
        for (scheme, rtsp) in [
            ("rtsp://", true),
            ("rtsps://", true),
            ("http://", false),
            ("https://", false),
        ] {
            if lower.starts_with(scheme) {
                let url = check_url(spec, &spec[scheme.len()..])?;
                return Ok(if rtsp {
                    SourceSpec::Rtsp { url }
                } else {
                    SourceSpec::HttpMjpeg { url }
                });
            }
        }
        if let Some(rest) = spec.strip_prefix("v4l2:") {
            if rest.is_empty() {
                return Err(SpecError::Invalid {
                    spec: spec.into(),
                    problem: "the device is empty (e.g. v4l2:/dev/video0)".into(),
                });
            }
            return Ok(SourceSpec::V4l2 { device: rest.into() });
        }
        if let Some(rest) = spec.strip_prefix("file:") {
            // `file:///abs/path` (a URI) and `file:PATH` both name a file.
            let rest = rest.strip_prefix("//").unwrap_or(rest);
            let (path, options) = split_options(spec, rest)?;
            let mut looping = false;
            for (key, value) in options {
                match key {
                    "loop" => looping = flag(spec, key, value)?,
                    _ => return Err(unknown_option(spec, key, "loop")),
                }
            }
            return Ok(SourceSpec::File {
                path: path.into(),
                looping,
            });
        }
        if let Some(rest) = spec.strip_prefix("images:") {
            let (dir, options) = split_options(spec, rest)?;
            let (mut manifest, mut looping) = (None, false);
            for (key, value) in options {
                match (key, value) {
                    ("manifest", Some(m)) if !m.is_empty() => manifest = Some(PathBuf::from(m)),
                    ("manifest", _) => {
                        return Err(SpecError::Invalid {
                            spec: spec.into(),
                            problem: "option `manifest` needs a file (manifest=FILE)".into(),
                        });
                    }
                    ("loop", _) => looping = flag(spec, key, value)?,
                    _ => return Err(unknown_option(spec, key, "manifest, loop")),
                }
            }
            return Ok(SourceSpec::Images {
                dir: dir.into(),
                manifest,
                looping,
            });
        }
        Err(SpecError::Unknown(spec.into()))
    }

    /// The cargo feature this source needs that this build lacks, if any.
    pub fn missing_feature(&self) -> Option<&'static str> {
        match self {
            SourceSpec::Synthetic | SourceSpec::Images { .. } => None,
            SourceSpec::V4l2 { .. } => (!cfg!(feature = "v4l2")).then_some("v4l2"),
            SourceSpec::File { .. }
            | SourceSpec::Rtsp { .. }
            | SourceSpec::HttpMjpeg { .. }
            | SourceSpec::Libcamera { .. } => (!cfg!(feature = "gstreamer")).then_some("gstreamer"),
        }
    }

    /// Whether the source ends (a file or a directory without `loop`), so that an end is not a
    /// fault.
    pub fn is_finite(&self) -> bool {
        matches!(
            self,
            SourceSpec::File { looping: false, .. } | SourceSpec::Images { looping: false, .. }
        )
    }
}

impl std::fmt::Display for SourceSpec {
    /// The spec in the form [`SourceSpec::parse`] reads.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let looped = |on: bool, first: char| if on { format!("{first}loop") } else { String::new() };
        match self {
            SourceSpec::Synthetic => write!(f, "synthetic"),
            SourceSpec::Images {
                dir,
                manifest,
                looping,
            } => {
                write!(f, "images:{}", dir.display())?;
                match manifest {
                    Some(m) => write!(f, "?manifest={}{}", m.display(), looped(*looping, '&')),
                    None => write!(f, "{}", looped(*looping, '?')),
                }
            }
            SourceSpec::V4l2 { device } => write!(f, "v4l2:{}", device.display()),
            SourceSpec::File { path, looping } => {
                write!(f, "file:{}{}", path.display(), looped(*looping, '?'))
            }
            SourceSpec::Rtsp { url } | SourceSpec::HttpMjpeg { url } => write!(f, "{url}"),
            SourceSpec::Libcamera { camera: None } => write!(f, "libcamera"),
            SourceSpec::Libcamera { camera: Some(c) } => write!(f, "libcamera:{c}"),
        }
    }
}

/// What happened to a source so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SourceStats {
    /// Frames delivered.
    pub frames: u64,
    /// `capture` calls that failed (each one is a frame the camera did not get).
    pub errors: u64,
    /// Ends of a file, a directory or a stream (a stream that ends is reconnected).
    pub ends: u64,
    /// Times no frame came within the stall timeout.
    pub stalls: u64,
    /// Pipelines started again after a stall, an error or a stream's end.
    pub reconnects: u64,
    /// Changes of the incoming resolution (frames keep the camera's size).
    pub caps_changes: u64,
    /// Errors from decoders and demuxers (corrupt data).
    pub decode_errors: u64,
    /// Errors reaching the source (connection refused or lost, file unreadable).
    pub stream_errors: u64,
    /// Frames lost to corrupt data: decoder warnings, and frames missing from a file's
    /// timeline (decoders drop what they cannot decode without an error).
    pub corrupt_frames: u64,
}

/// Which [`SourceStats`] counter to bump.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Count {
    Frame,
    Error,
    End,
    Stall,
    Reconnect,
    CapsChange,
    DecodeError,
    StreamError,
    CorruptFrame,
}

/// [`SourceStats`] shared between the capture thread (which counts) and the runtime (which
/// reads); cloning shares.
#[derive(Clone, Debug, Default)]
pub struct SharedStats(Arc<[AtomicU64; 9]>);

impl SharedStats {
    /// Add one to `what`; returns the new count (for rate-limited logging).
    pub fn bump(&self, what: Count) -> u64 {
        self.add(what, 1)
    }

    /// Add `n` to `what`; returns the new count.
    pub fn add(&self, what: Count, n: u64) -> u64 {
        self.0[what as usize].fetch_add(n, Ordering::Relaxed) + n
    }

    pub fn snapshot(&self) -> SourceStats {
        let get = |c: Count| self.0[c as usize].load(Ordering::Relaxed);
        SourceStats {
            frames: get(Count::Frame),
            errors: get(Count::Error),
            ends: get(Count::End),
            stalls: get(Count::Stall),
            reconnects: get(Count::Reconnect),
            caps_changes: get(Count::CapsChange),
            decode_errors: get(Count::DecodeError),
            stream_errors: get(Count::StreamError),
            corrupt_frames: get(Count::CorruptFrame),
        }
    }
}

/// Whether to log the `n`-th occurrence of something that can repeat every frame: the first
/// few, then at powers of two (the counters hold the exact number).
pub fn worth_logging(n: u64) -> bool {
    n <= 3 || n.is_power_of_two()
}

/// Counts frames, failed captures and the end of any source that does not count for itself.
#[derive(Debug)]
pub struct Counted<S> {
    inner: S,
    stats: SharedStats,
    ended: bool,
}

impl<S: FrameSource> Counted<S> {
    pub fn new(inner: S, stats: SharedStats) -> Self {
        Counted {
            inner,
            stats,
            ended: false,
        }
    }
}

impl<S: FrameSource> FrameSource for Counted<S> {
    fn size(&self) -> (u32, u32) {
        self.inner.size()
    }

    fn capture(&mut self, now: ClusterTime, frame: &mut Frame) -> Result<bool, SourceError> {
        let got = self.inner.capture(now, frame);
        match &got {
            Ok(true) => {
                self.stats.bump(Count::Frame);
            }
            Ok(false) if !self.ended => {
                self.ended = true;
                self.stats.bump(Count::End);
            }
            Ok(false) => {}
            Err(_) => {
                self.stats.bump(Count::Error);
            }
        }
        got
    }
}

/// An opened source and its counters.
pub struct OpenedSource {
    pub source: Box<dyn FrameSource>,
    pub stats: SharedStats,
}

impl std::fmt::Debug for OpenedSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OpenedSource")
            .field("size", &self.source.size())
            .field("stats", &self.stats.snapshot())
            .finish()
    }
}

/// Open `spec` for a camera of `width`×`height` pixels at `fps`. Video files and streams are
/// scaled to that size; directories and devices deliver their own size (the core checks it).
/// GStreamer sources use [`crate::gst::GstOptions::for_camera`]'s defaults.
///
/// # Errors
/// [`SpecError::NeedsScenario`] for `synthetic` (the runtime builds it from the scenario),
/// [`SpecError::NotBuilt`] when this build lacks the source's feature, [`SpecError::Size`] /
/// [`SpecError::Rate`] for an impossible camera, or [`SpecError::Open`] when the source cannot
/// be opened (no such directory, device or file, an undecodable file, a missing GStreamer
/// element). An unreachable stream is not an error: it is retried with backoff.
pub fn open_source(spec: &SourceSpec, width: u32, height: u32, fps: f64) -> Result<OpenedSource, SpecError> {
    if width == 0 || height == 0 || width > MAX_FRAME_SIDE || height > MAX_FRAME_SIDE {
        return Err(SpecError::Size { width, height });
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(SpecError::Rate(fps));
    }
    if let Some(feature) = spec.missing_feature() {
        return Err(SpecError::NotBuilt {
            spec: spec.to_string(),
            feature,
        });
    }
    let stats = SharedStats::default();
    let source: Box<dyn FrameSource> = match spec {
        SourceSpec::Synthetic => return Err(SpecError::NeedsScenario),
        SourceSpec::Images {
            dir,
            manifest,
            looping,
        } => {
            let seq = match manifest {
                Some(m) => ImageSequence::with_manifest(dir, m)?,
                None => ImageSequence::with_rate(dir, fps)?,
            };
            Box::new(Counted::new(seq.looping(*looping), stats.clone()))
        }
        #[cfg(feature = "v4l2")]
        SourceSpec::V4l2 { device } => {
            let dev = crate::v4l2::V4l2Source::open(&device.to_string_lossy(), width, height, fps)?;
            Box::new(Counted::new(dev, stats.clone()))
        }
        #[cfg(feature = "gstreamer")]
        SourceSpec::File { .. }
        | SourceSpec::Rtsp { .. }
        | SourceSpec::HttpMjpeg { .. }
        | SourceSpec::Libcamera { .. } => {
            use crate::gst::{GstInput, GstOptions, GstSource};
            let input = GstInput::from_spec(spec).ok_or_else(|| SpecError::Unknown(spec.to_string()))?;
            let options = GstOptions::for_camera(&input, fps);
            Box::new(GstSource::open(input, width, height, options, stats.clone())?)
        }
        #[allow(unreachable_patterns)] // reached only when a feature is off, and caught above
        _ => {
            return Err(SpecError::NotBuilt {
                spec: spec.to_string(),
                feature: spec.missing_feature().unwrap_or("?"),
            });
        }
    };
    Ok(OpenedSource { source, stats })
}

#[cfg(test)]
mod tests;
