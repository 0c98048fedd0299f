//! The camera node's process runtime: one OS process per camera, driving [`CameraNode`] from a
//! transport (iceoryx2, TCP or in-process), a frame source and timers.
//!
//! The source captures on its own thread at the camera's frame rate (a V4L2 device blocks, and
//! its handle is not `Send`), only while the node is in Active mode, and hands frames over a
//! queue of two; frames that find the queue full are counted as lost. Synthetic scenarios also
//! get RSSI readings of every tagged target at the frame rate ([`crate::radio`]). When the head
//! or the server is away, messages to them are counted as dropped and the node keeps going.
//! The server's sync beacons feed a [`SyncEstimator`] whose offset and error go out in the
//! node's `NodeStatus`.
//! With `record_measurements` (a logging run, [`crate::logging`]) the source captures whatever
//! the mode, and every frame's measurements also go to the server; those the transport drops
//! under backpressure are counted apart (`Summary::measured_dropped`).
//! `shutdown` stops the loop; the capture thread is joined and the transport shut down.

use crate::config::{CameraConfig, ConfigError};
use crate::core::{CameraNode, Counters};
use crate::logging::{FrameLogger, LogCounters};
use crate::radio::{self, MultipathField};
use crate::render::SyntheticSource;
use crate::source::ImageSequence;
use nalgebra::Vector3;
use proto::msg::Message;
use proto::scenario::{Scenario, TransportKind};
use proto::sensor::Frame;
use proto::sensor::ReferencePoint;
use proto::sensor::{FrameSource, SourceError};
use proto::sync::SyncEstimator;
use proto::{ClusterTime, NodeId, Role, TargetId};
use runtime::transport::{
    Clock, Delivery, Event, IpcConfig, StatsSnapshot, TcpConfig, TransportConfig, TransportError, open,
};
use std::net::ToSocketAddrs;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};

/// Where frames come from.
#[derive(Clone, Debug)]
pub enum SourceSpec {
    /// The synthetic world of the scenario.
    Synthetic,
    /// A directory of PNG/JPEG frames, at the camera's rate or with a manifest; loops.
    Images { dir: PathBuf, manifest: Option<PathBuf> },
    /// A V4L2 device (feature `v4l2`).
    #[cfg(feature = "v4l2")]
    V4l2 { device: String },
}

/// How to run one camera process.
#[derive(Clone)]
pub struct ProcessConfig {
    pub scenario: Scenario,
    pub id: u32,
    pub transport: TransportConfig,
    pub source: SourceSpec,
    pub seed: u64,
    /// Cluster time of scenario time 0 (the synthetic world's origin).
    pub epoch: ClusterTime,
    /// The runtime's clock; the core only ever sees what it returns.
    pub clock: Clock,
    /// Period of `tick`.
    pub tick: Duration,
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
            .field("transport", &self.transport)
            .field("source", &self.source)
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
    Transport(#[from] TransportError),
    #[error("frame source: {0}")]
    Source(#[from] SourceError),
    #[error("scenario: {0}")]
    Scenario(#[from] proto::scenario::ScenarioError),
    #[error("node {node}: cannot resolve address {addr:?} of node {peer}")]
    Address { node: u32, peer: u32, addr: String },
}

/// What a finished run did.
#[derive(Clone, Debug)]
pub struct Summary {
    pub counters: Counters,
    pub transport: StatsSnapshot,
    /// Frames captured but lost because the node was busy.
    pub frames_lost: u64,
    /// Messages the transport refused (no link to the peer, shut down).
    pub send_failures: u64,
    /// A logging run's frames: measured, refused, truncated (all zero otherwise).
    pub logged: LogCounters,
    /// A logging run's frames that did not reach the transport or that it dropped.
    pub measured_dropped: u64,
}

/// The transport configuration of camera `id`: iceoryx2 in the scenario's domain, or TCP
/// dialling its head and the server at their `listen` addresses.
///
/// # Errors
/// A head or server address that does not resolve.
pub fn transport_config(
    scenario: &Scenario,
    id: u32,
    kind: TransportKind,
    clock: Clock,
) -> Result<TransportConfig, ProcessError> {
    let me = NodeId(id);
    let net = &scenario.network;
    Ok(match kind {
        TransportKind::Ipc => {
            let mut c = IpcConfig::new(net.domain.clone(), me, Role::Camera, scenario.nodes.len());
            c.queue_len = net.queue_len.max(1);
            c.heartbeat = Some((Duration::from_millis(net.heartbeat_ms.max(1)), clock));
            TransportConfig::Ipc(c)
        }
        TransportKind::Tcp => {
            let mut c = TcpConfig::new(me, Role::Camera);
            c.heartbeat = Duration::from_millis(net.heartbeat_ms.max(1));
            c.liveness_timeout = Duration::from_millis(net.liveness_timeout_ms.max(1));
            c.queue_len = net.queue_len.max(1);
            c.clock = clock;
            let cfg = CameraConfig::from_scenario(scenario, id)?;
            for peer in [cfg.head, cfg.server].into_iter().flatten() {
                let Some(addr) = scenario.node(peer.0).and_then(|n| n.listen.clone()) else {
                    continue;
                };
                let resolved = addr
                    .to_socket_addrs()
                    .ok()
                    .and_then(|mut a| a.next())
                    .ok_or_else(|| ProcessError::Address {
                        node: id,
                        peer: peer.0,
                        addr: addr.clone(),
                    })?;
                c.peers.insert(peer, resolved);
            }
            TransportConfig::Tcp(c)
        }
    })
}

fn make_source(cfg: &ProcessConfig, fps: f64) -> Result<Box<dyn FrameSource>, ProcessError> {
    Ok(match &cfg.source {
        SourceSpec::Synthetic => Box::new(SyntheticSource::new(&cfg.scenario, cfg.id, cfg.seed, cfg.epoch)?),
        SourceSpec::Images { dir, manifest } => {
            let seq = match manifest {
                Some(m) => ImageSequence::with_manifest(dir, m)?,
                None => ImageSequence::with_rate(dir, fps)?,
            };
            Box::new(seq.looping(true))
        }
        #[cfg(feature = "v4l2")]
        SourceSpec::V4l2 { device } => {
            let cam = cfg.scenario.camera_model(cfg.id)?;
            Box::new(crate::v4l2::V4l2Source::open(
                device,
                cam.intrinsics.width,
                cam.intrinsics.height,
                fps,
            )?)
        }
    })
}

/// Capture at `fps` while `camera_on`, until `stop`.
#[allow(clippy::too_many_arguments)]
fn capture_loop(
    mut source: Box<dyn FrameSource>,
    fps: f64,
    clock: Clock,
    camera_on: Arc<AtomicBool>,
    stop: Arc<AtomicBool>,
    lost: Arc<AtomicU64>,
    tx: mpsc::Sender<Frame>,
) {
    let period = Duration::from_secs_f64(1.0 / fps.max(0.01));
    let mut spare = Frame::new(0, 0, ClusterTime::ZERO);
    while !stop.load(Ordering::Relaxed) {
        let started = clock();
        if camera_on.load(Ordering::Relaxed) {
            match source.capture(started, &mut spare) {
                Ok(true) => match tx.try_send(std::mem::replace(&mut spare, Frame::new(0, 0, started))) {
                    Ok(()) => {}
                    Err(mpsc::error::TrySendError::Full(f)) => {
                        lost.fetch_add(1, Ordering::Relaxed);
                        spare = f;
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
        let spent = Duration::from_nanos((clock() - started).max(0) as u64);
        std::thread::sleep(period.saturating_sub(spent));
    }
}

/// Feed a beacon from the server to the sync estimator and hand its estimate to the core,
/// which reports it in `NodeStatus`. The node's clock is the host's: processes on one host
/// share it, and across hosts chrony keeps it; what the beacons show is how far it is from the
/// server's.
fn observe_beacon(sync: &mut SyncEstimator, node: &mut CameraNode, local_ns: i64, leader: ClusterTime) {
    if let Err(e) = sync.observe(local_ns, leader) {
        debug!(error = %e, "sync beacon not used");
        return;
    }
    let error = sync.prediction_error_ns().map_or(-1, |e| e.round() as i64);
    node.set_sync(sync.offset_ns(local_ns), error);
}

/// The RSSI of the scenario's tag at this node at cluster time `at`, dBm, when exactly one
/// target carries a tag (as the simulation's logging runs record it).
fn tag_dbm(
    cfg: &ProcessConfig,
    field: &MultipathField,
    node_pos: &Vector3<f64>,
    at: ClusterTime,
) -> Option<f64> {
    let mut tagged = cfg.scenario.targets.iter().filter(|t| t.rssi_tag);
    let (Some(tag), None) = (tagged.next(), tagged.next()) else {
        return None;
    };
    let t = at.secs_since(cfg.epoch);
    let x = tag.truth_at(t);
    let pos = Vector3::new(x[0], x[1], x[2]);
    Some(radio::reading(
        &cfg.scenario.world,
        field,
        cfg.id,
        node_pos,
        tag.id,
        &pos,
        t,
        cfg.seed,
    ))
}

/// Run camera `cfg.id` until `shutdown` is cancelled.
///
/// # Errors
/// The node is not a camera, the source or the transport cannot be opened. Once running,
/// nothing the peers do ends the run: lost messages are counted.
pub async fn run(cfg: ProcessConfig, shutdown: CancellationToken) -> Result<Summary, ProcessError> {
    let mut core_cfg = CameraConfig::from_scenario(&cfg.scenario, cfg.id)?;
    core_cfg.reference = cfg.reference;
    let fps = core_cfg.fps;
    let clock = cfg.clock.clone();
    let (endpoint, mut inbox, stats, handle) = open(cfg.transport.clone()).await?;
    let mut node = CameraNode::new(core_cfg, clock());
    info!(node = cfg.id, fps, source = ?cfg.source, "camera running");

    // A logging run captures whatever the mode.
    let mut logger = cfg.record_measurements.then(|| FrameLogger::new(node.config()));
    let capture_now = |node: &CameraNode| cfg.record_measurements || node.mode().camera_on();
    let camera_on = Arc::new(AtomicBool::new(capture_now(&node)));
    let stop = Arc::new(AtomicBool::new(false));
    let lost = Arc::new(AtomicU64::new(0));
    let (tx, rx) = mpsc::channel::<Frame>(2);
    // The source is opened on its own thread (a V4L2 handle is not `Send`), which reports
    // whether that worked before the loop starts.
    let (ready_tx, ready_rx) = std::sync::mpsc::sync_channel::<Result<(), ProcessError>>(1);
    let capture = {
        let (clock, on, stop, lost) = (clock.clone(), camera_on.clone(), stop.clone(), lost.clone());
        let source_cfg = cfg.clone();
        std::thread::Builder::new()
            .name(format!("camera-{}-capture", cfg.id))
            .spawn(move || match make_source(&source_cfg, fps) {
                Ok(source) => {
                    let _ = ready_tx.send(Ok(()));
                    capture_loop(source, fps, clock, on, stop, lost, tx);
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
        .unwrap_or_else(|| Err(SourceError::Device("capture thread ended".into()).into()));
    if let Err(e) = ready {
        handle.shutdown().await;
        return Err(e);
    }
    let mut frames = Some(rx);

    // Synthetic radio: every tagged target's RSSI at this node, at the frame rate.
    let synthetic = matches!(cfg.source, SourceSpec::Synthetic);
    let node_pos: Vector3<f64> = node.config().camera.pose.centre();
    let field = MultipathField::new(&cfg.scenario.world.radio, cfg.id, cfg.seed);
    let mut tick = tokio::time::interval(cfg.tick);
    let mut radio_tick = tokio::time::interval(Duration::from_secs_f64(1.0 / fps.max(0.01)));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    radio_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut send_failures = 0u64;
    let mut sync = SyncEstimator::default();
    let mut measured_dropped = 0u64;

    loop {
        let outs = tokio::select! {
            _ = shutdown.cancelled() => break,
            ev = inbox.recv() => match ev {
                None => {
                    warn!(node = cfg.id, "transport closed");
                    break;
                }
                Some(Event::Message(m)) => {
                    if let Message::SyncBeacon(b) = &m.env.body
                        && Some(m.from) == node.config().server
                    {
                        observe_beacon(&mut sync, &mut node, clock().0, b.leader_time);
                    }
                    node.on_message(clock(), m.env)
                }
                Some(Event::PeerUp(p)) => {
                    info!(node = cfg.id, peer = %p, "peer up");
                    Vec::new()
                }
                Some(Event::PeerDown(p)) => {
                    warn!(node = cfg.id, peer = %p, "peer down; counting what is lost");
                    Vec::new()
                }
            },
            f = async {
                match frames.as_mut() {
                    Some(rx) => rx.recv().await,
                    None => std::future::pending().await,
                }
            } => match f {
                Some(frame) => match logger.as_mut() {
                    None => node.on_frame(clock(), &frame),
                    Some(l) => {
                        let dbm = if synthetic { tag_dbm(&cfg, &field, &node_pos, frame.captured) } else { None };
                        l.log(&mut node, clock(), &frame, dbm).unwrap_or_else(|e| {
                            warn!(node = cfg.id, error = %e, "logging run: frame refused");
                            Vec::new()
                        })
                    }
                },
                None => {
                    frames = None;
                    Vec::new()
                }
            },
            _ = tick.tick() => node.tick(clock()),
            _ = radio_tick.tick(), if synthetic => {
                let now = clock();
                let t = now.secs_since(cfg.epoch);
                for tg in cfg.scenario.targets.iter().filter(|t| t.rssi_tag) {
                    let x = tg.truth_at(t);
                    let tag = Vector3::new(x[0], x[1], x[2]);
                    let dbm = radio::reading(&cfg.scenario.world, &field, cfg.id, &node_pos, tg.id, &tag, t, cfg.seed);
                    node.on_rssi(now, TargetId(tg.id), dbm);
                }
                Vec::new()
            }
        };
        camera_on.store(capture_now(&node), Ordering::Relaxed);
        for out in outs {
            let to = out.to;
            let measured = matches!(out.body, Message::MeasuredFrame(_));
            match endpoint.send(out, clock()).await {
                Ok(Delivery::Queued) => {}
                Ok(Delivery::Dropped) => {
                    node.record_dropped(1);
                    measured_dropped += u64::from(measured);
                }
                Err(e) => {
                    node.record_dropped(1);
                    measured_dropped += u64::from(measured);
                    send_failures += 1;
                    debug!(node = cfg.id, to = %to, error = %e, "not delivered");
                }
            }
        }
    }

    stop.store(true, Ordering::Relaxed);
    drop(frames);
    if tokio::task::spawn_blocking(move || capture.join()).await.is_err() {
        warn!(node = cfg.id, "capture thread did not stop cleanly");
    }
    handle.shutdown().await;
    let summary = Summary {
        counters: node.counters(),
        transport: stats.snapshot(),
        frames_lost: lost.load(Ordering::Relaxed),
        send_failures,
        logged: logger.map(|l| l.counters()).unwrap_or_default(),
        measured_dropped,
    };
    info!(
        node = cfg.id,
        frames = summary.counters.frames,
        dropped = summary.counters.dropped,
        "camera stopped"
    );
    Ok(summary)
}
