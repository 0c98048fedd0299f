//! The camera node as an OS process: [`CameraNode`] driven by `runtime::process::run`, fed by
//! the sources it is given.
//!
//! The caller injects the sources — a frame source opened on the capture thread (a V4L2 handle
//! is not `Send`) and optionally a radio source — so a real camera reads its device and files,
//! and `ocelli launch` injects the simulated world's; the process cannot tell them apart. The
//! capture thread grabs a frame every 1/fps while the core wants frames (Active mode, or any
//! mode in a logging run) and hands it over a queue of two; frames that find the queue full are
//! counted as lost. The radio thread polls the radio source at the frame rate.

use crate::config::{CameraConfig, ConfigError};
use crate::core::{CameraInput, CameraNode, Counters};
use crate::record_all::LogCounters;
use futures_util::StreamExt;
use futures_util::stream::{self, BoxStream};
use proto::NodeId;
use proto::scenario::Scenario;
use proto::sensor::{Frame, FrameSource, RadioSource, ReferencePoint, SourceError};
use runtime::{HostClock, RunError, RunSummary};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

/// Opens the camera's frame source on the capture thread.
pub type OpenFrames = Box<dyn FnOnce() -> Result<Box<dyn FrameSource>, SourceError> + Send>;

/// How to run one camera process.
pub struct ProcessConfig {
    pub scenario: Scenario,
    pub id: u32,
    /// Transport, leader and tick of the shared process runtime.
    pub process: runtime::ProcessConfig,
    /// The frame source, opened on the capture thread.
    pub frames: OpenFrames,
    /// The radio tags this node hears, if it has a radio source.
    pub radio: Option<Box<dyn RadioSource + Send>>,
    /// Which point of a region stands for the target (the foot point for people).
    pub reference: ReferencePoint,
    /// A logging run: capture and measure every frame whatever the mode, and send each
    /// frame's measurements to the server for its recording.
    pub record_measurements: bool,
}

impl std::fmt::Debug for ProcessConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProcessConfig")
            .field("id", &self.id)
            .field("process", &self.process)
            .field("radio", &self.radio.is_some())
            .field("record_measurements", &self.record_measurements)
            .finish()
    }
}

/// Why the camera process could not run.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("transport: {0}")]
    Transport(#[from] runtime::transport::TransportError),
    #[error("frame source: {0}")]
    Source(#[from] SourceError),
}

/// What a finished run did.
#[derive(Clone, Debug)]
pub struct Summary {
    pub counters: Counters,
    pub run: RunSummary,
    /// Frames captured but lost because the node was busy.
    pub frames_lost: u64,
    /// A logging run's frames: measured, refused, truncated (all zero otherwise).
    pub logged: LogCounters,
}

impl Summary {
    /// A logging run's frames that did not reach the transport or that it dropped.
    pub fn measured_dropped(&self) -> u64 {
        self.run.undelivered.get("measured_frame").copied().unwrap_or(0)
    }
}

/// Capture at `fps` while `capturing`, until `stop` or the source ends.
fn capture_loop(
    mut source: Box<dyn FrameSource>,
    fps: f64,
    clock: HostClock,
    capturing: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    lost: Arc<AtomicU64>,
    tx: mpsc::Sender<Frame>,
) {
    let period = Duration::from_secs_f64(1.0 / fps.max(0.01));
    while !stop.load(Ordering::Relaxed) {
        let started = clock.now();
        if capturing.load(Ordering::Relaxed) {
            let mut frame = Frame::new(0, 0, started);
            match source.capture(started, &mut frame) {
                Ok(true) => match tx.try_send(frame) {
                    Ok(()) => {}
                    Err(mpsc::error::TrySendError::Full(_)) => {
                        lost.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(mpsc::error::TrySendError::Closed(_)) => return,
                },
                Ok(false) => {
                    info!("frame source exhausted");
                    return;
                }
                Err(e) => {
                    warn!(error = %e, "capture failed");
                    lost.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        let spent = Duration::from_nanos((clock.now() - started).max(0) as u64);
        std::thread::sleep(period.saturating_sub(spent));
    }
}

/// Poll the radio every `period` until `stop` or the source ends.
fn radio_loop(
    mut radio: Box<dyn RadioSource + Send>,
    period: Duration,
    clock: HostClock,
    stop: Arc<AtomicBool>,
    tx: mpsc::Sender<CameraInput>,
) {
    let mut heard = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let started = clock.now();
        heard.clear();
        match radio.read(started, &mut heard) {
            Ok(more) => {
                for r in heard.drain(..) {
                    if tx.blocking_send(CameraInput::Tag(r)).is_err() {
                        return;
                    }
                }
                if !more {
                    info!("radio source exhausted");
                    return;
                }
            }
            Err(e) => warn!(error = %e, "radio read failed"),
        }
        let spent = Duration::from_nanos((clock.now() - started).max(0) as u64);
        std::thread::sleep(period.saturating_sub(spent));
    }
}

/// Run camera `cfg.id` until `shutdown` is cancelled.
///
/// # Errors
/// The node is not a camera, the frame source or the transport cannot be opened. Once
/// running, nothing the peers do ends the run: lost messages are counted.
pub async fn run(
    cfg: ProcessConfig,
    clock: HostClock,
    shutdown: CancellationToken,
) -> Result<Summary, ProcessError> {
    let mut core_cfg = CameraConfig::from_scenario(&cfg.scenario, cfg.id)?;
    core_cfg.reference = cfg.reference;
    core_cfg.record_all = cfg.record_measurements;
    let fps = core_cfg.fps;
    let mut node = CameraNode::new(core_cfg, clock.now());
    info!(node = cfg.id, fps, "camera starting");

    let capturing = Arc::new(AtomicBool::new(node.capturing()));
    let stop = Arc::new(AtomicBool::new(false));
    let lost = Arc::new(AtomicU64::new(0));
    let (frames_tx, frames_rx) = mpsc::channel::<Frame>(2);
    // The source is opened on its own thread, which reports whether that worked before the
    // loop starts.
    let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel::<Result<(), SourceError>>(1);
    let capture = {
        let (clock, on, stop, lost) = (clock.clone(), capturing.clone(), stop.clone(), lost.clone());
        let open = cfg.frames;
        std::thread::Builder::new()
            .name(format!("camera-{}-capture", cfg.id))
            .spawn(move || match open() {
                Ok(source) => {
                    let _ = ready_tx.send(Ok(()));
                    capture_loop(source, fps, clock, on, stop, lost, frames_tx);
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                }
            })
            .map_err(|e| SourceError::Device(format!("capture thread: {e}")))?
    };
    let ready = tokio::task::spawn_blocking(move || ready_rx.recv())
        .await
        .ok()
        .and_then(|r| r.ok())
        .unwrap_or_else(|| Err(SourceError::Device("capture thread ended".into())));
    ready?;

    let frames: BoxStream<'static, CameraInput> = stream::unfold(frames_rx, |mut rx| async move {
        rx.recv().await.map(|f| (CameraInput::Frame(f), rx))
    })
    .boxed();
    let mut radio_thread = None;
    let sensors = match cfg.radio {
        Some(radio) => {
            let (tx, rx) = mpsc::channel::<CameraInput>(64);
            let (clock, stop) = (clock.clone(), stop.clone());
            let period = Duration::from_secs_f64(1.0 / fps.max(0.01));
            radio_thread = Some(
                std::thread::Builder::new()
                    .name(format!("camera-{}-radio", cfg.id))
                    .spawn(move || radio_loop(radio, period, clock, stop, tx))
                    .map_err(|e| SourceError::Device(format!("radio thread: {e}")))?,
            );
            let tags = stream::unfold(rx, |mut rx| async move { rx.recv().await.map(|r| (r, rx)) });
            stream::select(frames, tags).boxed()
        }
        None => frames,
    };

    let mut hooks = runtime::process::SensorSwitch::new(capturing, CameraNode::capturing);
    let result = runtime::run(&mut node, cfg.process, clock, sensors, &mut hooks, shutdown).await;
    stop.store(true, Ordering::Relaxed);
    for t in [Some(capture), radio_thread].into_iter().flatten() {
        if tokio::task::spawn_blocking(move || t.join()).await.is_err() {
            warn!(node = cfg.id, "a sensor thread did not stop cleanly");
        }
    }
    let run = match result {
        Ok(run) => run,
        Err(RunError::Transport(e)) => return Err(e.into()),
        Err(RunError::Node(never)) => match never {},
    };
    let summary = Summary {
        counters: node.counters(),
        run,
        frames_lost: lost.load(Ordering::Relaxed),
        logged: node.record_all().map(|l| l.counters()).unwrap_or_default(),
    };
    info!(
        node = %NodeId(cfg.id),
        frames = summary.counters.frames,
        dropped = summary.counters.dropped,
        "camera stopped"
    );
    Ok(summary)
}
