//! The acoustic node as an OS process: [`AcousticNode`] driven by `runtime::process::run`, fed
//! by the audio source it is given.
//!
//! The caller injects the source — a WAV file, live capture, or `ocelli launch`'s simulated
//! room — opened on the audio thread. A paced source (a file, the simulated room) is read one
//! frame per frame period; a live one blocks until its frame is captured. Frames that find the
//! queue to the core full are counted as lost; a source that stalls or fails is counted (the
//! core's `stalls`) and asked again, so the node keeps running.

use crate::config::{AcousticConfig, ConfigError};
use crate::node::{AcousticInput, AcousticNode, Counters};
use futures_util::stream;
use proto::NodeId;
use proto::scenario::Scenario;
use proto::sensor::{AudioFrame, AudioSource, SourceError};
use runtime::{HostClock, RunError, RunSummary};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

/// Opens the node's audio source on the audio thread.
pub type OpenAudio = Box<dyn FnOnce() -> Result<Box<dyn AudioSource>, SourceError> + Send>;

/// How to run one acoustic process.
pub struct ProcessConfig {
    pub scenario: Scenario,
    pub id: u32,
    /// Transport, leader and tick of the shared process runtime.
    pub process: runtime::ProcessConfig,
    pub audio: OpenAudio,
    /// Read one frame per frame period (a file, the simulated room); a live source paces
    /// itself.
    pub paced: bool,
}

impl std::fmt::Debug for ProcessConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProcessConfig")
            .field("id", &self.id)
            .field("process", &self.process)
            .field("paced", &self.paced)
            .finish_non_exhaustive()
    }
}

/// Why the acoustic process could not run.
#[derive(Debug, Error)]
pub enum ProcessError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Ild(#[from] crate::IldError),
    #[error("transport: {0}")]
    Transport(#[from] runtime::transport::TransportError),
    #[error("audio source: {0}")]
    Source(#[from] SourceError),
}

/// What a finished run did.
#[derive(Clone, Debug)]
pub struct Summary {
    pub counters: Counters,
    pub run: RunSummary,
    /// Frames captured but lost because the node was busy.
    pub frames_lost: u64,
}

struct AudioLoop {
    source: Box<dyn AudioSource>,
    samples: usize,
    paced: bool,
    clock: HostClock,
    listening: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    lost: Arc<AtomicU64>,
    tx: mpsc::Sender<AcousticInput>,
}

impl AudioLoop {
    fn run(mut self) {
        let rate = f64::from(self.source.sample_rate().max(1));
        let period = Duration::from_secs_f64(self.samples as f64 / rate);
        while !self.stop.load(Ordering::Relaxed) {
            let started = self.clock.now();
            if self.listening.load(Ordering::Relaxed) {
                let mut frame = AudioFrame::default();
                let input = match self.source.capture(started, self.samples, &mut frame) {
                    Ok(true) => AcousticInput::Frame(frame),
                    Ok(false) => {
                        info!("audio source exhausted");
                        return;
                    }
                    Err(e) => {
                        warn!(error = %e, "audio capture failed; counted, trying again");
                        if !matches!(e, SourceError::Stalled { .. }) {
                            // A failing device: do not spin.
                            std::thread::sleep(period.min(Duration::from_millis(200)));
                        }
                        AcousticInput::Stalled
                    }
                };
                match self.tx.try_send(input) {
                    Ok(()) => {}
                    Err(mpsc::error::TrySendError::Full(_)) => {
                        self.lost.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(mpsc::error::TrySendError::Closed(_)) => return,
                }
            } else {
                std::thread::sleep(period);
                continue;
            }
            if self.paced {
                let spent = Duration::from_nanos((self.clock.now() - started).max(0) as u64);
                std::thread::sleep(period.saturating_sub(spent));
            }
        }
    }
}

/// Run acoustic node `cfg.id` until `shutdown` is cancelled.
///
/// # Errors
/// The node is not an acoustic node, its ILD settings are unusable, or the audio source or the
/// transport cannot be opened. Once running, nothing the peers or the source do ends the run.
pub async fn run(
    cfg: ProcessConfig,
    clock: HostClock,
    shutdown: CancellationToken,
) -> Result<Summary, ProcessError> {
    let core_cfg = AcousticConfig::from_scenario(&cfg.scenario, cfg.id)?;
    let samples = core_cfg.frame_samples();
    let mut node = AcousticNode::new(core_cfg, clock.now())?;
    info!(node = cfg.id, samples, "acoustic node starting");
    let listening = Arc::new(AtomicBool::new(node.listening()));
    let stop = Arc::new(AtomicBool::new(false));
    let lost = Arc::new(AtomicU64::new(0));
    let (tx, rx) = mpsc::channel::<AcousticInput>(2);
    let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel::<Result<(), SourceError>>(1);
    let audio = {
        let (clock, listening, stop, lost) = (clock.clone(), listening.clone(), stop.clone(), lost.clone());
        let (open, paced) = (cfg.audio, cfg.paced);
        std::thread::Builder::new()
            .name(format!("acoustic-{}-audio", cfg.id))
            .spawn(move || match open() {
                Ok(source) => {
                    let _ = ready_tx.send(Ok(()));
                    AudioLoop {
                        source,
                        samples,
                        paced,
                        clock,
                        listening,
                        stop,
                        lost,
                        tx,
                    }
                    .run();
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                }
            })
            .map_err(|e| SourceError::Device(format!("audio thread: {e}")))?
    };
    let ready = tokio::task::spawn_blocking(move || ready_rx.recv())
        .await
        .ok()
        .and_then(|r| r.ok())
        .unwrap_or_else(|| Err(SourceError::Device("audio thread ended".into())));
    ready?;
    let sensors = Box::pin(stream::unfold(rx, |mut rx| async move {
        rx.recv().await.map(|a| (a, rx))
    }));
    let mut hooks = runtime::process::SensorSwitch::new(listening, AcousticNode::listening);
    let result = runtime::run(&mut node, cfg.process, clock, sensors, &mut hooks, shutdown).await;
    stop.store(true, Ordering::Relaxed);
    if tokio::task::spawn_blocking(move || audio.join()).await.is_err() {
        warn!(node = cfg.id, "the audio thread did not stop cleanly");
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
    };
    info!(node = %NodeId(cfg.id), frames = summary.counters.frames, stalls = summary.counters.stalls, "acoustic node stopped");
    Ok(summary)
}
