//! Real video into the camera through GStreamer (cargo feature `gstreamer`): video files,
//! RTSP and HTTP MJPEG streams from IP cameras, and Pi cameras through `libcamerasrc`.
//!
//! GStreamer rather than FFmpeg because it is how a Pi does video: libcamera ships a GStreamer
//! element, the Pi's hardware decoders are GStreamer elements, and RTSP, HTTP and MJPEG are
//! plugins of the same pipeline, so one code path covers them all; `gstreamer-rs` is the
//! project's own, well-kept binding.
//!
//! One pipeline per source:
//!
//! ```text
//! file:      filesrc ! decodebin                          ┐
//! rtsp://    uridecodebin (rtspsrc, latency 200 ms)       │ ! videoconvert ! videoscale
//! http://    souphttpsrc ! multipartdemux ! jpegdec        │   ! video/x-raw,format=RGB,width=W,height=H
//! libcamera  libcamerasrc                                 ┘   ! appsink max-buffers=1
//! ```
//!
//! Streams are live: the appsink keeps only the newest frame (`drop=true`), as a camera does.
//! Files are paced by [`Pacing`]: by default every frame in order, each `capture` taking the
//! next one (the decoder waits for the camera, so a slow camera sees every frame and a run is
//! reproducible); [`Pacing::Newest`] plays the file at its own rate and drops what the camera
//! is too slow for. Frames are stamped with the `now` the runtime passes.
//!
//! Bad input never ends the camera; each event is a log line (repeats rate-limited) and a
//! [`SharedStats`] counter:
//! - a file that ends: [`AtEnd::Stop`] (the default: `capture` returns `Ok(false)`, like an
//!   [`crate::source::ImageSequence`] that does not loop) or [`AtEnd::Loop`] (starts over);
//! - a stream that ends, drops or cannot be reached: the pipeline is torn down and started
//!   again after an exponential [`Backoff`] (counted as `reconnects`);
//! - no frame within [`GstOptions::stall_timeout`] of camera time: a stall, then a reconnect
//!   (time the camera spent not capturing, e.g. switched off by its head, is not a stall);
//! - a resolution change: `videoscale` keeps frames at the camera's size, the change is
//!   counted (`caps_changes`), also across reconnects;
//! - corrupt data: decoder warnings and frames missing from a file's timeline (a decoder
//!   skips what it cannot decode) count as `corrupt_frames`; a decoder or demuxer error
//!   counts as a `decode_error` and restarts a stream, ends a file (or starts a looping file
//!   over). A file that cannot be decoded at all fails [`GstSource::open`].
//!
//! While a stream is away `capture` returns an error at most every
//! [`GstOptions::max_wait`] (it sleeps until the next attempt, bounded so shutdown stays
//! prompt), so the capture thread neither spins nor floods the log.

use crate::source_spec::{Count, SharedStats, SourceSpec, worth_logging};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use gstreamer_video as gst_video;
use proto::ClusterTime;
use proto::sensor::MAX_FRAME_SIDE;
use proto::sensor::SourceError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use runtime::transport::Backoff;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;
use tracing::{info, warn};

/// Where a GStreamer pipeline reads from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GstInput {
    /// A video file; `looping` starts it over at its end.
    File { path: PathBuf, looping: bool },
    /// An RTSP stream.
    Rtsp { url: String },
    /// An HTTP(S) `multipart/x-mixed-replace` stream of JPEGs.
    HttpMjpeg { url: String },
    /// A libcamera camera by name, or the first.
    Libcamera { camera: Option<String> },
}

impl GstInput {
    /// The GStreamer input a `--source` names, if it is one.
    pub fn from_spec(spec: &SourceSpec) -> Option<GstInput> {
        Some(match spec {
            SourceSpec::File { path, looping } => GstInput::File {
                path: path.clone(),
                looping: *looping,
            },
            SourceSpec::Rtsp { url } => GstInput::Rtsp { url: url.clone() },
            SourceSpec::HttpMjpeg { url } => GstInput::HttpMjpeg { url: url.clone() },
            SourceSpec::Libcamera { camera } => GstInput::Libcamera {
                camera: camera.clone(),
            },
            SourceSpec::Synthetic | SourceSpec::Images { .. } | SourceSpec::V4l2 { .. } => return None,
        })
    }

    /// Everything but a file is live: it cannot wait for the camera.
    pub fn is_live(&self) -> bool {
        !matches!(self, GstInput::File { .. })
    }

    /// The pipeline up to decoded video; the elements that take properties are named `src`.
    fn head(&self) -> &'static str {
        match self {
            GstInput::File { .. } => "filesrc name=src ! decodebin",
            GstInput::Rtsp { .. } => "uridecodebin name=src",
            GstInput::HttpMjpeg { .. } => "souphttpsrc name=src ! multipartdemux ! jpegdec",
            GstInput::Libcamera { .. } => "libcamerasrc name=src",
        }
    }
}

impl std::fmt::Display for GstInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GstInput::File { path, .. } => write!(f, "file:{}", path.display()),
            GstInput::Rtsp { url } | GstInput::HttpMjpeg { url } => write!(f, "{url}"),
            GstInput::Libcamera { camera: None } => write!(f, "libcamera"),
            GstInput::Libcamera { camera: Some(c) } => write!(f, "libcamera:{c}"),
        }
    }
}

/// How a file's frames meet the camera's captures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pacing {
    /// Each capture takes the next frame; decoding waits for the camera (files only).
    EveryFrame,
    /// The newest frame wins: a file plays at its own rate, a stream as it comes.
    Newest,
}

/// What a file does at its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtEnd {
    /// `capture` returns `Ok(false)` from then on.
    Stop,
    /// Start over at the first frame.
    Loop,
}

/// Knobs of a [`GstSource`]; [`GstOptions::for_camera`] gives the defaults.
#[derive(Clone, Debug)]
pub struct GstOptions {
    pub pacing: Pacing,
    pub at_end: AtEnd,
    /// No frame for this long (camera time, while capturing) is a stall: reconnect.
    pub stall_timeout: Duration,
    /// The longest one `capture` blocks waiting for a frame or a reconnect.
    pub max_wait: Duration,
    /// How long opening a file may take to decode its first frame.
    pub open_timeout: Duration,
    /// Delay before each reconnect; reset by a frame.
    pub backoff: Backoff,
    /// Seed of the backoff's jitter.
    pub seed: u64,
}

impl GstOptions {
    /// Defaults for `input` at a camera's `fps`: files every frame, streams newest; a 5 s
    /// stall timeout (at least ten frame periods); reconnects from 250 ms doubling to 10 s.
    pub fn for_camera(input: &GstInput, fps: f64) -> GstOptions {
        let period = if fps.is_finite() && fps > 0.0 {
            1.0 / fps
        } else {
            1.0
        };
        GstOptions {
            pacing: if input.is_live() {
                Pacing::Newest
            } else {
                Pacing::EveryFrame
            },
            at_end: match input {
                GstInput::File { looping: true, .. } => AtEnd::Loop,
                _ => AtEnd::Stop,
            },
            stall_timeout: Duration::from_secs_f64((10.0 * period).clamp(5.0, 60.0)),
            max_wait: Duration::from_millis(500),
            open_timeout: Duration::from_secs(10),
            backoff: Backoff::new(Duration::from_millis(250), Duration::from_secs(10), 2.0, 0.3),
            seed: 0,
        }
    }
}

/// A running pipeline; dropping it stops it.
struct Pipeline {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
    bus: gst::Bus,
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// Where the source is between captures.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Playing; `progress` is the camera time of the last frame or (re)start, set by the first
    /// capture after opening.
    Playing { progress: Option<ClusterTime> },
    /// Torn down; start again at `at` (a `reconnect` after a failure, or a file's new lap).
    Waiting { at: ClusterTime, reconnect: bool },
    /// A file that ended (or failed) without looping.
    Ended,
}

/// A [`FrameSource`] reading through a GStreamer pipeline (module docs).
pub struct GstSource {
    input: GstInput,
    size: (u32, u32),
    options: GstOptions,
    pipeline: Option<Pipeline>,
    phase: Phase,
    backoff: Backoff,
    rng: ChaCha8Rng,
    stats: SharedStats,
    /// The decoded size last seen, `w << 32 | h` (0: none yet), kept across reconnects.
    decoded_size: Arc<AtomicU64>,
    last_call: Option<ClusterTime>,
}

impl std::fmt::Debug for GstSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GstSource")
            .field("input", &self.input)
            .field("size", &self.size)
            .field("phase", &self.phase)
            .field("stats", &self.stats.snapshot())
            .finish()
    }
}

fn device(input: &GstInput, problem: impl std::fmt::Display) -> SourceError {
    SourceError::Device(format!("{input}: {problem}"))
}

/// Initialise GStreamer once per process (later calls are cheap).
///
/// # Errors
/// The GStreamer library cannot start (no plugin registry, broken install).
pub fn init() -> Result<(), SourceError> {
    gst::init().map_err(|e| SourceError::Device(format!("GStreamer cannot start: {e}")))
}

impl GstSource {
    /// Open `input` for a camera of `width`×`height`. Files are decoded up to their first
    /// frame here, so a missing or undecodable file fails now; a stream that cannot be reached
    /// is retried with backoff from the first `capture` on.
    ///
    /// # Errors
    /// GStreamer cannot start, a size outside `1..=MAX_FRAME_SIDE`, a missing element
    /// (e.g. `libcamerasrc` without Debian's `gstreamer1.0-libcamera`), or a file that is
    /// missing or cannot be decoded (also counted in `stats`).
    pub fn open(
        input: GstInput,
        width: u32,
        height: u32,
        options: GstOptions,
        stats: SharedStats,
    ) -> Result<GstSource, SourceError> {
        init()?;
        if width == 0 || height == 0 || width > MAX_FRAME_SIDE || height > MAX_FRAME_SIDE {
            return Err(device(
                &input,
                format!("camera size {width}x{height} is outside 1..={MAX_FRAME_SIDE}"),
            ));
        }
        if let GstInput::File { path, .. } = &input {
            std::fs::File::open(path).map_err(|source| {
                stats.bump(Count::StreamError);
                SourceError::Io {
                    path: path.clone(),
                    source,
                }
            })?;
        }
        let mut source = GstSource {
            size: (width, height),
            backoff: options.backoff.clone(),
            rng: ChaCha8Rng::seed_from_u64(options.seed),
            options,
            pipeline: None,
            phase: Phase::Playing { progress: None },
            stats,
            decoded_size: Arc::new(AtomicU64::new(0)),
            last_call: None,
            input,
        };
        let pipeline = source.build()?;
        if !source.input.is_live() {
            source.preroll(&pipeline)?;
        }
        pipeline
            .pipeline
            .set_state(gst::State::Playing)
            .map_err(|e| device(&source.input, format!("cannot start: {e}")))?;
        source.pipeline = Some(pipeline);
        info!(source = %source.input, width, height, "GStreamer source open");
        Ok(source)
    }

    /// What happened so far (shared with whoever holds a clone of the stats).
    pub fn stats(&self) -> &SharedStats {
        &self.stats
    }

    /// Build the pipeline (not yet started).
    fn build(&self) -> Result<Pipeline, SourceError> {
        let input = &self.input;
        let description = format!(
            "{} ! videoconvert name=convert ! videoscale ! capsfilter name=caps ! appsink name=sink",
            input.head()
        );
        let pipeline = gst::parse::launch(&description)
            .map_err(|e| {
                let hint = match input {
                    GstInput::Libcamera { .. } => " (libcamerasrc is in Debian's gstreamer1.0-libcamera)",
                    _ => " (GStreamer's base and good plugins are needed)",
                };
                device(input, format!("cannot build `{description}`: {e}{hint}"))
            })?
            .downcast::<gst::Pipeline>()
            .map_err(|_| device(input, "the description is not a pipeline"))?;
        let named = |name: &str| {
            pipeline
                .by_name(name)
                .ok_or_else(|| device(input, format!("pipeline has no element `{name}`")))
        };
        let src = named("src")?;
        match input {
            GstInput::File { path, .. } => src.set_property("location", path.to_string_lossy().as_ref()),
            GstInput::Rtsp { url } => {
                src.set_property("uri", url);
                src.connect("source-setup", false, |args| {
                    if let Some(Ok(rtspsrc)) = args.get(1).map(|a| a.get::<gst::Element>())
                        && rtspsrc.has_property("latency")
                    {
                        rtspsrc.set_property("latency", 200u32);
                    }
                    None
                });
            }
            GstInput::HttpMjpeg { url } => {
                src.set_property("location", url);
                src.set_property("is-live", true);
                // Every drop is ours to see, count and back off from.
                src.set_property("retries", 0i32);
            }
            GstInput::Libcamera { camera } => {
                if let Some(name) = camera {
                    src.set_property("camera-name", name);
                }
            }
        }
        let caps = gst_video::VideoCapsBuilder::new()
            .format(gst_video::VideoFormat::Rgb)
            .width(self.size.0 as i32)
            .height(self.size.1 as i32)
            .build();
        named("caps")?.set_property("caps", &caps);
        let sink = named("sink")?
            .dynamic_cast::<gst_app::AppSink>()
            .map_err(|_| device(input, "`sink` is not an appsink"))?;
        let every_frame = self.options.pacing == Pacing::EveryFrame && !input.is_live();
        sink.set_max_buffers(1);
        sink.set_drop(!every_frame);
        // A file played newest-first runs at its own rate on the pipeline clock.
        sink.set_sync(!every_frame && !input.is_live());
        sink.set_property("enable-last-sample", false);
        let convert_sink = named("convert")?
            .static_pad("sink")
            .ok_or_else(|| device(input, "videoconvert has no sink pad"))?;
        watch_decoded_size(
            &convert_sink,
            input.to_string(),
            self.decoded_size.clone(),
            self.stats.clone(),
        );
        if !input.is_live() {
            watch_timeline(&convert_sink, input.to_string(), self.stats.clone());
        }
        let bus = pipeline
            .bus()
            .ok_or_else(|| device(input, "pipeline has no bus"))?;
        Ok(Pipeline { pipeline, sink, bus })
    }

    /// Decode a file up to its first frame, or say why not.
    fn preroll(&self, p: &Pipeline) -> Result<(), SourceError> {
        let failed = |message: String| {
            self.stats.bump(Count::DecodeError);
            device(&self.input, format!("cannot be decoded: {message}"))
        };
        if let Err(e) = p.pipeline.set_state(gst::State::Paused) {
            let why = p
                .bus
                .pop_filtered(&[gst::MessageType::Error])
                .map_or_else(|| e.to_string(), |m| describe(&m));
            return Err(failed(why));
        }
        let timeout = gst::ClockTime::from_nseconds(self.options.open_timeout.as_nanos() as u64);
        match p
            .bus
            .timed_pop_filtered(timeout, &[gst::MessageType::Error, gst::MessageType::AsyncDone])
        {
            Some(m) if matches!(m.view(), gst::MessageView::AsyncDone(_)) => Ok(()),
            Some(m) => Err(failed(describe(&m))),
            None => Err(failed(format!(
                "no frame within {:.1} s",
                self.options.open_timeout.as_secs_f64()
            ))),
        }
    }
}

/// An error or warning message as one line: the element, the message and GStreamer's detail.
fn describe(m: &gst::Message) -> String {
    let from = m.src().map_or_else(|| "?".into(), |s| s.name().to_string());
    let (text, debug) = match m.view() {
        gst::MessageView::Error(e) => (e.error().to_string(), e.debug()),
        gst::MessageView::Warning(w) => (w.error().to_string(), w.debug()),
        _ => (format!("{:?}", m.type_()), None),
    };
    match debug {
        Some(d) => format!("{from}: {text} ({d})"),
        None => format!("{from}: {text}"),
    }
}

/// Count changes of the decoded size arriving at `pad` (frames keep the camera's size).
fn watch_decoded_size(pad: &gst::Pad, what: String, last: Arc<AtomicU64>, stats: SharedStats) {
    pad.add_probe(gst::PadProbeType::EVENT_DOWNSTREAM, move |_, info| {
        if let Some(gst::EventView::Caps(c)) = info.event().map(|e| e.view())
            && let Some(s) = c.caps().structure(0)
            && let (Ok(w), Ok(h)) = (s.get::<i32>("width"), s.get::<i32>("height"))
        {
            let packed = (u64::from(w.unsigned_abs()) << 32) | u64::from(h.unsigned_abs());
            let before = last.swap(packed, Ordering::Relaxed);
            if before != 0 && before != packed {
                let n = stats.bump(Count::CapsChange);
                let (bw, bh) = (before >> 32, before & 0xffff_ffff);
                if worth_logging(n) {
                    info!(source = %what, from = %format!("{bw}x{bh}"), to = %format!("{w}x{h}"), changes = n,
                        "source resolution changed; frames stay at the camera's size");
                }
            }
        }
        gst::PadProbeReturn::Ok
    });
}

/// Count frames missing from a file's timeline at `pad` (before any frame is dropped for
/// pacing): a decoder skips a frame it cannot decode with only a debug message, so a gap of
/// more than one and a half frame durations between decoded frames is frames lost.
fn watch_timeline(pad: &gst::Pad, what: String, stats: SharedStats) {
    let last = std::sync::Mutex::new(None::<gst::ClockTime>);
    pad.add_probe(gst::PadProbeType::BUFFER, move |_, info| {
        if let Some(buffer) = info.buffer()
            && let Some(pts) = buffer.pts()
            && let Ok(mut last) = last.lock()
        {
            if let (Some(before), Some(duration)) = (*last, buffer.duration())
                && duration.nseconds() > 0
                && pts > before
            {
                let periods = (pts - before).nseconds() as f64 / duration.nseconds() as f64;
                let missing = (periods - 0.5).floor() as u64;
                if missing > 0 {
                    let n = stats.add(Count::CorruptFrame, missing);
                    if worth_logging(n) {
                        warn!(source = %what, missing, at_s = pts.seconds_f64(), corrupt_frames = n,
                            "frames missing from the video (undecodable)");
                    }
                }
            }
            *last = Some(pts);
        }
        gst::PadProbeReturn::Ok
    });
}

mod capture;

#[cfg(test)]
mod tests;
