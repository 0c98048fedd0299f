//! iceoryx2 transport between processes on one host.
//!
//! Every node owns one inbox: a publish-subscribe service of byte slices named
//! `"{domain}/inbox/{node}"` plus an event service of the same name that wakes the owner.
//! Senders open a publisher and a notifier on a recipient's inbox the first time they send
//! to it. All iceoryx2 files carry the prefix `iox2_{domain}_`, so parallel clusters and tests
//! never see each other's services and a test can check that nothing of its domain is left in
//! `/dev/shm`.
//!
//! Receiving happens in the node's own task: the inbox listener's file descriptor is registered
//! with tokio's reactor, so a notification wakes the task that reads the inbox once — there is
//! no receiver thread and no queue in between (a thread hop costs tens of microseconds, more
//! than everything else on the path). The shared-memory buffer is the inbox's only queue; a
//! full one makes publishers discard droppable frames and retry the others; frames for a node
//! that has not yet read its inbox wait in the sender for it (`Outlet::early`). Sending uses
//! iceoryx2's thread-safe service flavour, so `Endpoint::send` publishes straight from the
//! caller's task too. iceoryx2's own signal handling is disabled (tokio owns SIGINT/SIGTERM). At
//! start a process makes its one iceoryx2 node and passes over the domain once, removing what
//! crashed nodes left and refusing an inbox another live process owns (`sweep_and_claim`); a
//! janitor thread sweeps the domain's dead nodes every few seconds after that
//! ([`super::ipc_janitor`]); dropping the node on shutdown removes this node's files.

use super::common::accept;
use super::stats::{TransportStats, add, bump};
use super::{Delivery, Event, Incoming, OutFrame, SendError, ShutdownHandle, TransportError};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use proto::MAX_FRAME_BYTES;
use proto::ids::{NodeId, Role};
use std::collections::VecDeque;
use std::collections::{HashMap, HashSet};
use std::os::fd::{FromRawFd, OwnedFd};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::unix::AsyncFd;
use tokio_util::sync::CancellationToken;

/// iceoryx2's thread-safe flavour of its IPC service: its ports may be used from tokio tasks,
/// so frames are published straight from `Endpoint::send` without a thread hop.
type Svc = ipc_threadsafe::Service;

/// Room in a shared-memory slot beyond [`MAX_FRAME_BYTES`], so that an oversized frame
/// reaches the receiver and is rejected there (counted, logged) like on every other transport.
const SLOT_SLACK: usize = 64;
/// How long a publisher keeps retrying a frame that must not be dropped while the recipient's
/// buffer is full, before giving up on it (counted in `dropped_undelivered`): a crashed
/// receiver's buffer never drains, and the sender thread serves every other link too.
const MUST_DELIVER_PATIENCE: Duration = Duration::from_secs(2);

/// Per-service iceoryx2 limits. The library's defaults (2 publishers, 8 subscribers, a
/// buffer of 2 that silently overwrites) are far too small for a cluster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IpcLimits {
    /// Processes that may open one inbox (every possible sender, plus the owner).
    pub max_nodes: usize,
    /// Senders per inbox.
    pub max_publishers: usize,
    /// Receivers per inbox: the owner, and its restarted successor while the dead one is
    /// cleaned up.
    pub max_subscribers: usize,
    /// Frames an inbox buffers; a full buffer makes publishers discard (never overwrite).
    pub buffer: usize,
}

impl IpcLimits {
    /// Limits for a scenario of `nodes` nodes with per-link queues of `queue_len` frames.
    pub fn for_nodes(nodes: usize, queue_len: usize) -> Self {
        let n = nodes.max(2) + 2;
        IpcLimits {
            max_nodes: 2 * n + 2,
            max_publishers: n,
            max_subscribers: 2,
            buffer: queue_len.max(16),
        }
    }
}

/// Settings of an iceoryx2 endpoint.
#[derive(Clone)]
pub struct IpcConfig {
    /// Service-name and file prefix: `[A-Za-z0-9_-]`, at most 64 characters.
    pub domain: String,
    pub me: NodeId,
    pub role: Role,
    pub limits: IpcLimits,
    /// Events queued in the inbox.
    pub queue_len: usize,
    /// Send a `Heartbeat` to every node this endpoint has sent to, this often, stamped with
    /// the clock. Shared memory has no connection whose loss tells a peer we are gone, so
    /// liveness on the same host rests on these (as it rests on TCP's own heartbeats).
    pub heartbeat: Option<(std::time::Duration, super::Clock)>,
    /// A peer that sent nothing (not even a heartbeat) for this long is reported down
    /// (`Event::PeerDown`), and up again with its next frame: link liveness as TCP reports it.
    /// `None`: peers are reported up once and never down.
    pub liveness_timeout: Option<Duration>,
}

impl std::fmt::Debug for IpcConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IpcConfig")
            .field("domain", &self.domain)
            .field("me", &self.me)
            .field("role", &self.role)
            .field("limits", &self.limits)
            .field("queue_len", &self.queue_len)
            .field("heartbeat", &self.heartbeat.as_ref().map(|(p, _)| *p))
            .finish()
    }
}

impl IpcConfig {
    pub fn new(domain: impl Into<String>, me: NodeId, role: Role, nodes: usize) -> Self {
        let queue_len = 256;
        IpcConfig {
            domain: domain.into(),
            me,
            role,
            limits: IpcLimits::for_nodes(nodes, queue_len),
            queue_len,
            heartbeat: None,
            liveness_timeout: None,
        }
    }
}

/// The file prefix iceoryx2 uses for `domain`: every shared-memory file of the domain starts
/// with it.
pub fn file_prefix(domain: &str) -> String {
    format!("iox2_{domain}_")
}

/// The iceoryx2 nodes of `domain` on this host: how many are alive and how many are dead with
/// their resources not yet removed (what the janitor is for). For operators and tests.
///
/// # Errors
/// An invalid domain, or iceoryx2 cannot list the nodes.
pub fn ipc_nodes(domain: &str) -> Result<IpcNodes, TransportError> {
    check_domain(domain)?;
    let config = iox_config(domain)?;
    let mut nodes = IpcNodes::default();
    Node::<Svc>::list(&config, |state| {
        match state {
            NodeState::Alive(_) => nodes.alive += 1,
            NodeState::Dead(_) => nodes.dead += 1,
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => nodes.other += 1,
        }
        CallbackProgression::Continue
    })
    .map_err(|e| ipc_err("node list", e))?;
    Ok(nodes)
}

/// What [`ipc_nodes`] counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IpcNodes {
    pub alive: usize,
    pub dead: usize,
    /// Nodes iceoryx2 cannot classify (no permission, damaged details).
    pub other: usize,
}

fn check_domain(domain: &str) -> Result<(), TransportError> {
    let ok = !domain.is_empty()
        && domain.len() <= 64
        && domain
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(TransportError::Config(format!(
            "domain {domain:?} must be 1 to 64 characters of [A-Za-z0-9_-]"
        )))
    }
}

fn ipc_err(what: &str, e: impl std::fmt::Debug) -> TransportError {
    TransportError::Ipc(format!("{what}: {e:?}"))
}

fn iox_config(domain: &str) -> Result<Config, TransportError> {
    quiet_iceoryx2();
    let mut config = Config::default();
    config.global.prefix =
        FileName::new(file_prefix(domain).as_bytes()).map_err(|e| ipc_err("file prefix", e))?;
    Ok(config)
}

/// iceoryx2 logs through its own logger to standard error (a warning that no config file was
/// loaded, in every process). Ours is `tracing`: keep iceoryx2 to its errors unless
/// `IOX2_LOG_LEVEL` asks for more.
fn quiet_iceoryx2() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| set_log_level_from_env_or(LogLevel::Error));
}

/// The iceoryx2 node name of `me`'s inbox owner: one live process per node id and domain.
fn owner_name(me: NodeId) -> String {
    format!("inbox-owner-{}", me.0)
}

/// One pass over the domain's iceoryx2 nodes: remove the resources of the dead ones (a dead
/// owner of `me`'s inbox among them), and refuse to own `me`'s inbox while another live
/// process of the domain owns it (a second `ocelli head --id 2` beside the first). Our own
/// node, of the same name, is passed over by its process id.
///
/// One node and one pass: at a launch every process sweeps the domain while a hundred others
/// start. With a first, unnamed node sweeping (and sweeping again when dropped), a list for the
/// owner and a sweep by the named node, a hall camera's transport took a median 3.0 s to start
/// over iceoryx2, against 0.7 s for its whole start over TCP.
fn sweep_and_claim(config: &Config, domain: &str, me: NodeId) -> Result<(), TransportError> {
    let name = owner_name(me);
    let own = std::process::id() as i32;
    let (mut holder, mut cleanups, mut failed) = (None, 0u32, 0u32);
    let listed = Node::<Svc>::list(config, |state| {
        match state {
            NodeState::Dead(dead) => match dead.blocking_remove_stale_resources(Duration::from_millis(500)) {
                Ok(_) => cleanups += 1,
                Err(_) => failed += 1,
            },
            NodeState::Alive(view) => {
                if let Some(d) = iceoryx2::node::NodeView::details(&view)
                    && d.name().as_str() == name
                    && d.process_id().value() != own
                {
                    holder = Some(d.process_id().value());
                }
            }
            _ => {}
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listed {
        tracing::debug!(error = ?e, "could not list the domain's iceoryx2 nodes");
    }
    if cleanups > 0 || failed > 0 {
        tracing::info!(cleanups, failed, "removed stale iceoryx2 resources of dead nodes");
    }
    match holder {
        Some(pid) => Err(TransportError::IdInUse {
            id: me,
            detail: format!("process {pid} owns its iceoryx2 inbox in domain {domain}"),
        }),
        None => Ok(()),
    }
}

/// The process's iceoryx2 node, named `name`.
fn iox_named_node(config: &Config, name: &str) -> Result<Node<Svc>, TransportError> {
    NodeBuilder::new()
        .name(&NodeName::new(name).map_err(|e| ipc_err("node name", e))?)
        .config(config)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Svc>()
        .map_err(|e| ipc_err("node", e))
}

/// iceoryx2 keeps one small management segment per prefix (a node counter) and never removes
/// it. When the last node of the domain is gone, remove it so a clean stop leaves nothing of
/// the domain in `/dev/shm`.
fn release_domain(domain: &str) {
    let Ok(config) = iox_config(domain) else {
        return;
    };
    let mut nodes = 0usize;
    let listed = Node::<Svc>::list(&config, |_| {
        nodes += 1;
        CallbackProgression::Continue
    });
    if listed.is_err() || nodes > 0 {
        return;
    }
    let prefix = file_prefix(domain);
    let Ok(dir) = std::fs::read_dir(SHM_DIR) else {
        return;
    };
    for entry in dir.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(&prefix) && name.ends_with(".global_mgmt") {
            match std::fs::remove_file(entry.path()) {
                Ok(()) => tracing::debug!(file = %name, "removed the domain's management segment"),
                Err(e) => {
                    tracing::warn!(file = %name, error = %e, "could not remove the domain's management segment")
                }
            }
        }
    }
}

/// Where POSIX shared memory lives on Linux.
const SHM_DIR: &str = "/dev/shm";

fn inbox_name(domain: &str, node: NodeId) -> Result<ServiceName, TransportError> {
    ServiceName::new(&format!("{domain}/inbox/{}", node.0)).map_err(|e| ipc_err("service name", e))
}

type Inbox = (
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], ()>,
    iceoryx2::service::port_factory::event::PortFactory<Svc>,
);

fn open_inbox(node: &Node<Svc>, name: &ServiceName, l: &IpcLimits) -> Result<Inbox, TransportError> {
    let data = node
        .service_builder(name)
        .publish_subscribe::<[u8]>()
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(l.buffer)
        .subscriber_max_borrowed_samples(4)
        .history_size(0)
        .max_publishers(l.max_publishers)
        .max_subscribers(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .open_or_create()
        .map_err(|e| ipc_err("inbox service", e))?;
    let wake = node
        .service_builder(name)
        .event()
        .max_notifiers(l.max_publishers + 1)
        .max_listeners(l.max_subscribers)
        .max_nodes(l.max_nodes)
        .open_or_create()
        .map_err(|e| ipc_err("inbox event service", e))?;
    Ok((data, wake))
}

/// The sending half handed to the endpoint: publishes from the caller's task.
pub(crate) struct Sender {
    inner: Arc<SenderInner>,
}

struct SenderInner {
    cfg: IpcConfig,
    /// `None` once stopped.
    node: Mutex<Option<Node<Svc>>>,
    outlets: Mutex<HashMap<NodeId, Outlet>>,
}

/// What one publish attempt did.
enum Published {
    Delivered,
    /// Reached no receiver although one is subscribed: its buffer is full.
    Full,
    /// Nobody reads this inbox.
    NoReceiver,
    /// Kept for a recipient that has not read its inbox yet ([`Outlet::early`]).
    Held,
}

impl Sender {
    /// Publish `frame` on the recipient's inbox. A frame that must not be dropped and meets
    /// a full inbox is tried again (yielding to the runtime) for up to
    /// [`MUST_DELIVER_PATIENCE`]; a droppable one is dropped at once. A frame for a node that
    /// has never read its inbox is held for it (`Outlet::early`) and counts as queued.
    /// Undelivered frames are counted in `dropped_undelivered`.
    pub(crate) async fn send(&self, frame: OutFrame, stats: &TransportStats) -> Result<Delivery, SendError> {
        let started = tokio::time::Instant::now();
        loop {
            match self.publish_once(&frame, stats)? {
                Some(Published::Delivered) | Some(Published::Held) => return Ok(Delivery::Queued),
                Some(Published::Full) if !frame.droppable && started.elapsed() < MUST_DELIVER_PATIENCE => {
                    tokio::time::sleep(Duration::from_micros(200)).await;
                }
                Some(Published::Full) | Some(Published::NoReceiver) => {
                    bump(&stats.dropped_undelivered);
                    tracing::debug!(to = %frame.to, "frame reached no receiver");
                    return Ok(Delivery::Dropped);
                }
                // Could not be published at all; counted and logged where it failed.
                None => return Ok(Delivery::Dropped),
            }
        }
    }

    fn publish_once(&self, frame: &OutFrame, stats: &TransportStats) -> Result<Option<Published>, SendError> {
        let mut outlets = self.inner.outlets.lock().unwrap_or_else(|p| p.into_inner());
        let outlet = match outlets.entry(frame.to) {
            std::collections::hash_map::Entry::Occupied(o) => o.into_mut(),
            std::collections::hash_map::Entry::Vacant(v) => {
                let node = self.inner.node.lock().unwrap_or_else(|p| p.into_inner());
                let Some(node) = node.as_ref() else {
                    return Err(SendError::Closed);
                };
                match open_outlet(node, &self.inner.cfg, frame.to) {
                    Ok(o) => v.insert(o),
                    Err(e) => {
                        bump(&stats.unroutable);
                        tracing::warn!(to = %frame.to, error = %e, "cannot open the recipient's inbox");
                        return Ok(None);
                    }
                }
            }
        };
        outlet.flush_early(stats);
        if !outlet.early.is_empty() {
            // Its reader is still not there: the new frame waits behind the others.
            return Ok(Some(outlet.hold(frame, self.inner.cfg.limits.buffer)));
        }
        Ok(match publish(outlet, frame, stats) {
            Some(Published::NoReceiver) if !outlet.reached => {
                Some(outlet.hold(frame, self.inner.cfg.limits.buffer))
            }
            r => {
                outlet.reached |= matches!(r, Some(Published::Delivered | Published::Full));
                r
            }
        })
    }

    fn stop(&self, stats: &TransportStats) {
        let mut outlets = self.inner.outlets.lock().unwrap_or_else(|p| p.into_inner());
        let early: usize = outlets.values().map(|o| o.early.len()).sum();
        if early > 0 {
            add(&stats.dropped_undelivered, early);
            tracing::info!(
                frames = early,
                "frames for peers that never read their inbox were not delivered"
            );
        }
        outlets.clear();
        drop(outlets);
        self.inner.node.lock().unwrap_or_else(|p| p.into_inner()).take();
    }
}

pub(crate) fn start(
    cfg: IpcConfig,
    stats: Arc<TransportStats>,
    handle: &mut ShutdownHandle,
) -> Result<(Sender, Receiver), TransportError> {
    check_domain(&cfg.domain)?;
    let config = iox_config(&cfg.domain)?;
    let node = iox_named_node(&config, &owner_name(cfg.me))?;
    sweep_and_claim(&config, &cfg.domain, cfg.me)?;
    let receiver = Receiver::open(&node, &cfg, stats.clone(), handle.token())?;
    let domain = cfg.domain.clone();
    handle.after_join.push(Box::new(move || release_domain(&domain)));
    start_janitor(config, handle)?;
    let sender = Sender {
        inner: Arc::new(SenderInner {
            cfg,
            node: Mutex::new(Some(node)),
            outlets: Mutex::new(HashMap::new()),
        }),
    };
    let on_stop = Sender {
        inner: sender.inner.clone(),
    };
    let ports = receiver.ports.clone();
    handle.on_stop.push(Box::new(move || {
        // The inbox's ports first, then the node: dropping them removes this node's files.
        ports.lock().unwrap_or_else(|p| p.into_inner()).take();
        on_stop.stop(&stats);
    }));
    Ok((sender, receiver))
}

/// Sweep the domain for dead nodes' files in a thread of its own (see [`super::ipc_janitor`]);
/// shutdown stops and joins it.
fn start_janitor(config: Config, handle: &mut ShutdownHandle) -> Result<(), TransportError> {
    let (stop, stopped) = std::sync::mpsc::channel::<()>();
    let pid = std::process::id();
    let thread = std::thread::Builder::new()
        .name("iox2-janitor".into())
        .spawn(move || super::ipc_janitor::run::<Svc>(config, pid, stopped))
        .map_err(TransportError::Io)?;
    handle.on_stop.push(Box::new(move || drop(stop)));
    handle.threads.push(thread);
    Ok(())
}

/// The inbox's ports. Shared with the shutdown handle, which drops them.
struct RxPorts {
    sub: Subscriber<Svc, [u8], ()>,
    listener: Listener<Svc>,
}

/// The receiving half, read by the node's own task: the inbox's subscriber and listener, and
/// the listener's descriptor in tokio's reactor.
pub(crate) struct Receiver {
    ports: Arc<Mutex<Option<RxPorts>>>,
    /// A duplicate of the listener's descriptor: registered with the reactor for as long as
    /// the receiver lives, independently of when shutdown drops the listener itself.
    wake: AsyncFd<OwnedFd>,
    pending: VecDeque<Event>,
    known: HashSet<NodeId>,
    /// When each known peer was last heard, if silence reports a peer down.
    last_heard: HashMap<NodeId, std::time::Instant>,
    liveness_timeout: Option<Duration>,
    stats: Arc<TransportStats>,
    stop: CancellationToken,
}

impl std::fmt::Debug for Receiver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Receiver")
            .field("pending", &self.pending.len())
            .finish_non_exhaustive()
    }
}

impl Receiver {
    fn open(
        node: &Node<Svc>,
        cfg: &IpcConfig,
        stats: Arc<TransportStats>,
        stop: CancellationToken,
    ) -> Result<Receiver, TransportError> {
        let (data, wake) = open_inbox(node, &inbox_name(&cfg.domain, cfg.me)?, &cfg.limits)?;
        let sub = data
            .subscriber_builder()
            .buffer_size(cfg.limits.buffer)
            .create()
            .map_err(|e| ipc_err("subscriber", e))?;
        let listener = wake
            .listener_builder()
            .create()
            .map_err(|e| ipc_err("listener", e))?;
        let wake = watch(duplicate(&listener)?)?;
        Ok(Receiver {
            ports: Arc::new(Mutex::new(Some(RxPorts { sub, listener }))),
            wake,
            pending: VecDeque::new(),
            known: HashSet::new(),
            last_heard: HashMap::new(),
            liveness_timeout: cfg.liveness_timeout,
            stats,
            stop,
        })
    }

    /// The next event, or `None` once the transport has shut down.
    pub(crate) async fn recv(&mut self) -> Option<Event> {
        loop {
            if let Some(ev) = self.pending.pop_front() {
                return Some(ev);
            }
            if self.stop.is_cancelled() || !self.drain() {
                return None;
            }
            self.report_silent();
            if !self.pending.is_empty() {
                continue;
            }
            // Woken now and then to report silent peers even when nothing arrives.
            let check = self.liveness_timeout.map(|l| l / 4);
            tokio::select! {
                () = self.stop.cancelled() => return None,
                () = tokio::time::sleep(check.unwrap_or_default()), if check.is_some() => {}
                ready = self.wake.readable() => match ready {
                    // Cleared before draining: a notification after this point wakes again.
                    Ok(mut guard) => guard.clear_ready(),
                    Err(e) => {
                        tracing::warn!(error = %e, "iceoryx2 listener cannot be polled");
                        return None;
                    }
                },
            }
        }
    }

    /// The next event if one is ready.
    pub(crate) fn try_recv(&mut self) -> Option<Event> {
        if self.pending.is_empty() && !self.stop.is_cancelled() {
            self.drain();
            self.report_silent();
        }
        self.pending.pop_front()
    }

    /// Consume the notifications, then every sample waiting in the inbox, into `pending`.
    /// `false` once the ports are gone (shut down).
    fn drain(&mut self) -> bool {
        let ports = self.ports.lock().unwrap_or_else(|p| p.into_inner());
        let Some(p) = ports.as_ref() else {
            return false;
        };
        if let Err(e) = p.listener.try_wait(|_| {}) {
            tracing::warn!(error = ?e, "iceoryx2 listener wait failed");
        }
        loop {
            let sample = match p.sub.receive() {
                Ok(Some(s)) => s,
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!(error = ?e, "iceoryx2 receive failed");
                    break;
                }
            };
            let Some(env) = accept(sample.payload(), &self.stats, None, "ipc") else {
                continue;
            };
            drop(sample);
            let from = env.source;
            if self.liveness_timeout.is_some() {
                self.last_heard.insert(from, now());
            }
            if self.known.insert(from) {
                bump(&self.stats.peers_up);
                self.pending.push_back(Event::PeerUp(from));
            }
            bump(&self.stats.received);
            self.pending.push_back(Event::Message(Incoming { from, env }));
        }
        true
    }

    /// Report peers silent for the liveness timeout down and forget them (their next frame
    /// reports them up).
    fn report_silent(&mut self) {
        let Some(limit) = self.liveness_timeout else {
            return;
        };
        let t = now();
        let silent: Vec<NodeId> = self
            .last_heard
            .iter()
            .filter(|(_, at)| t.saturating_duration_since(**at) > limit)
            .map(|(n, _)| *n)
            .collect();
        for peer in silent {
            self.last_heard.remove(&peer);
            self.known.remove(&peer);
            bump(&self.stats.peers_lost);
            tracing::warn!(%peer, silent_ms = limit.as_millis() as u64, "peer silent; link down");
            self.pending.push_back(Event::PeerDown(peer));
        }
    }
}

/// `fd` registered with the reactor for readability.
#[allow(unsafe_code)]
fn watch(fd: OwnedFd) -> Result<AsyncFd<OwnedFd>, TransportError> {
    // SAFETY: the `OwnedFd` inside the `AsyncFd` keeps the descriptor open for exactly the
    // `AsyncFd`'s lifetime, which is what registering requires.
    unsafe { AsyncFd::register_with_interest(fd, tokio::io::Interest::READABLE) }
        .map_err(|e| TransportError::Io(std::io::Error::from(e)))
}

/// A duplicate of `listener`'s descriptor, owned apart from it.
#[allow(unsafe_code)]
fn duplicate(listener: &Listener<Svc>) -> Result<OwnedFd, TransportError> {
    // SAFETY: the listener's descriptor is open for the duration of this call (we hold the
    // listener); `dup` makes a new descriptor for the same socket, which `OwnedFd` owns alone.
    let fd = unsafe { libc::dup(listener.file_descriptor().native_handle()) };
    if fd < 0 {
        return Err(TransportError::Io(std::io::Error::last_os_error()));
    }
    // SAFETY: `fd` is a fresh descriptor no one else owns.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

/// The receiver's clock, for silence (a runtime owns one).
#[allow(clippy::disallowed_methods)]
fn now() -> std::time::Instant {
    std::time::Instant::now()
}

struct Outlet {
    data: iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], ()>,
    publisher: Publisher<Svc, [u8], ()>,
    notifier: Notifier<Svc>,
    /// Whether the recipient has ever read this inbox (a frame reached it, or found its buffer
    /// full).
    reached: bool,
    /// Frames sent before the recipient first read its inbox, oldest first, published ahead of
    /// the next frame once it does. A launch starts every process at once, and a head's first
    /// words to a server whose inbox is not open yet were lost so, where TCP keeps a dialed
    /// link's frames until it connects. A recipient that read its inbox once and stopped
    /// (crashed, or stopped before us) gets no such wait: its frames are dropped and counted.
    early: VecDeque<OutFrame>,
}

impl Outlet {
    /// Keep `frame` until the recipient reads its inbox, at most `cap` frames; beyond them the
    /// frame reached no receiver (the caller counts it).
    fn hold(&mut self, frame: &OutFrame, cap: usize) -> Published {
        if self.early.len() >= cap {
            return Published::NoReceiver;
        }
        self.early.push_back(frame.clone());
        Published::Held
    }

    /// Publish the held frames, oldest first, while the recipient reads its inbox. One that
    /// meets a full buffer is dropped and counted: the recipient is up, and a frame that
    /// waited for it is not worth blocking the sender.
    fn flush_early(&mut self, stats: &TransportStats) {
        while let Some(frame) = self.early.front() {
            match publish(self, frame, stats) {
                Some(Published::NoReceiver) | Some(Published::Held) => return,
                Some(Published::Delivered) => self.reached = true,
                Some(Published::Full) => {
                    self.reached = true;
                    bump(&stats.dropped_undelivered);
                }
                // Could not be published at all; counted where it failed.
                None => {}
            }
            self.early.pop_front();
        }
    }
}

/// Open a publisher and notifier on `to`'s inbox. A full inbox makes the publisher discard
/// (never overwrite); [`Sender::send`] decides whether to try again.
fn open_outlet(node: &Node<Svc>, cfg: &IpcConfig, to: NodeId) -> Result<Outlet, TransportError> {
    let (data, wake) = open_inbox(node, &inbox_name(&cfg.domain, to)?, &cfg.limits)?;
    let publisher = data
        .publisher_builder()
        .initial_max_slice_len(MAX_FRAME_BYTES + SLOT_SLACK)
        .allocation_strategy(AllocationStrategy::Static)
        .backpressure_strategy(BackpressureStrategy::DiscardData)
        .max_loaned_samples(2)
        .create()
        .map_err(|e| ipc_err("publisher", e))?;
    let notifier = wake
        .notifier_builder()
        .create()
        .map_err(|e| ipc_err("notifier", e))?;
    Ok(Outlet {
        data,
        publisher,
        notifier,
        reached: false,
        early: VecDeque::new(),
    })
}

/// Publish one frame and wake the recipient; `None` if it could not even be loaned (counted).
fn publish(outlet: &Outlet, frame: &OutFrame, stats: &TransportStats) -> Option<Published> {
    use iceoryx2::service::port_factory::PortFactory;
    let to = frame.to;
    let sample = match outlet.publisher.loan_slice_uninit(frame.bytes.len()) {
        Ok(s) => s,
        Err(e) => {
            bump(&stats.rejected_oversized);
            tracing::warn!(%to, len = frame.bytes.len(), error = ?e, "frame does not fit a shared-memory slot");
            return None;
        }
    };
    let sample = sample.write_from_slice(&frame.bytes);
    match sample.send() {
        Ok(0) => {
            if outlet.data.dynamic_config().number_of_subscribers() > 0 {
                // Wake the reader so it drains.
                let _ = outlet.notifier.notify();
                Some(Published::Full)
            } else {
                Some(Published::NoReceiver)
            }
        }
        Ok(_) => {
            if let Err(e) = outlet.notifier.notify() {
                tracing::warn!(%to, error = ?e, "iceoryx2 notify failed");
            }
            Some(Published::Delivered)
        }
        Err(e) => {
            tracing::warn!(%to, error = ?e, "iceoryx2 send failed");
            Some(Published::NoReceiver)
        }
    }
}

#[cfg(test)]
mod tests;
