//! Transports: one interface, three implementations.
//!
//! - [`TransportConfig::Ipc`]: iceoryx2 shared memory between processes on one host
//!   (`ipc`), one inbox service per node under a domain prefix.
//! - [`TransportConfig::Tcp`]: tokio TCP between hosts (`tcp`), mutually authenticated with
//!   TLS ([`tls`]), length-delimited frames, handshake, heartbeats, reconnect with backoff.
//! - [`TransportConfig::InProcess`]: a hub of tokio channels (`inproc`) for tests and
//!   single-process use.
//!
//! [`open`] returns the same four things for each: an [`Endpoint`] to send with, an [`Inbox`]
//! that yields [`Event`]s, the shared [`TransportStats`] and a [`ShutdownHandle`]. Every frame
//! is one `Envelope` encoded by [`proto::wire::encode`]; the endpoint stamps source, per-link
//! sequence number and the caller's cluster time. Receivers decode with
//! [`proto::wire::decode`]; a rejected frame is counted, logged rate-limited (one line per kind
//! and interval, [`proto::log_limit`]), and the receiver carries on.
//!
//! Queues are bounded. When one is full a [`proto::Message::droppable`] message is dropped and
//! counted; any other message (commands, priors, handovers, …) waits for room.

pub mod backoff;
pub mod codec;
mod common;
mod inproc;
mod ipc;
mod ipc_janitor;
pub mod stats;
mod tcp;
pub mod tls;

use bytes::Bytes;
use proto::ids::{NodeId, Role};
use proto::msg::{Envelope, Message};
use proto::node::Outgoing;
use proto::time::ClusterTime;
use proto::wire::{WireError, encode};
use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

pub use backoff::Backoff;
pub use inproc::InProcessHub;
pub use ipc::{IpcConfig, IpcLimits, IpcNodes, file_prefix, ipc_nodes};
pub use stats::{StatsSnapshot, TransportStats};
pub use tcp::{Security, TcpConfig};
pub use tls::{ClusterCa, NodeCert, Tls, TlsError, TlsFiles};

/// Where a transport gets the cluster time for frames it makes itself (handshakes,
/// heartbeats). Node runtimes own the clock and inject it.
pub type Clock = Arc<dyn Fn() -> ClusterTime + Send + Sync>;

/// A clock that always reads zero, for tools and tests that do not care.
pub fn zero_clock() -> Clock {
    Arc::new(|| ClusterTime::ZERO)
}

/// A decoded, validated message and the node it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Incoming {
    pub from: NodeId,
    pub env: Envelope,
}

/// What an [`Inbox`] yields.
///
/// `PeerUp`/`PeerDown` report link liveness: on TCP a peer is up after a successful handshake
/// and down when its connection closes or stays silent past the liveness timeout; on
/// iceoryx2 a peer is up when its first frame arrives (there is no connection to lose:
/// same-host liveness is left to the runtime's own heartbeats); in-process, when it opens.
// Messages are moved once from transport to runtime; boxing them would cost an allocation per
// frame to save bytes on the rare liveness events.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    Message(Incoming),
    PeerUp(NodeId),
    PeerDown(NodeId),
}

/// The receiving half: [`Event`]s for the runtime to `select!` on.
#[derive(Debug)]
pub struct Inbox(InboxKind);

#[derive(Debug)]
enum InboxKind {
    /// Events queued by transport tasks (TCP, in-process).
    Channel(mpsc::Receiver<Event>),
    /// iceoryx2's inbox, read directly by the caller's task (one wake per delivery).
    Ipc(ipc::Receiver),
}

impl Inbox {
    /// The next event, or `None` once the transport has shut down.
    pub async fn recv(&mut self) -> Option<Event> {
        match &mut self.0 {
            InboxKind::Channel(rx) => rx.recv().await,
            InboxKind::Ipc(rx) => rx.recv().await,
        }
    }

    /// The next event if one is ready.
    pub fn try_recv(&mut self) -> Option<Event> {
        match &mut self.0 {
            InboxKind::Channel(rx) => rx.try_recv().ok(),
            InboxKind::Ipc(rx) => rx.try_recv(),
        }
    }
}

/// What became of a sent message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivery {
    /// Handed to the link.
    Queued,
    /// Droppable and the queue was full: dropped and counted.
    Dropped,
}

/// Why a message could not be sent.
#[derive(Debug, Error, PartialEq)]
pub enum SendError {
    #[error("cannot encode the message: {0}")]
    Encode(#[from] WireError),
    #[error("no link to node {0}")]
    UnknownPeer(NodeId),
    #[error("the transport is shut down")]
    Closed,
}

/// Why a transport could not be opened.
#[derive(Debug, Error)]
pub enum TransportError {
    #[error("invalid transport configuration: {0}")]
    Config(String),
    #[error("network: {0}")]
    Io(#[from] std::io::Error),
    #[error("iceoryx2: {0}")]
    Ipc(String),
    /// Another live process already is this node (iceoryx2: it owns the inbox; TCP: the peer
    /// refused a second connection for the id).
    #[error("node {id} is already up ({detail}); stop it first, or start this one with another --id")]
    IdInUse { id: NodeId, detail: String },
}

/// Which transport to open, and its settings.
#[derive(Clone)]
pub enum TransportConfig {
    Ipc(IpcConfig),
    Tcp(TcpConfig),
    InProcess {
        hub: InProcessHub,
        me: NodeId,
        role: Role,
        queue_len: usize,
    },
}

impl std::fmt::Debug for TransportConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TransportConfig::Ipc(c) => f.debug_tuple("Ipc").field(c).finish(),
            TransportConfig::Tcp(c) => f.debug_tuple("Tcp").field(c).finish(),
            TransportConfig::InProcess { me, queue_len, .. } => f
                .debug_struct("InProcess")
                .field("me", me)
                .field("queue_len", queue_len)
                .finish(),
        }
    }
}

/// Per-link sequence numbers, shared by the endpoint and the link tasks.
#[derive(Debug, Default)]
pub(crate) struct Seqs(Mutex<HashMap<NodeId, u64>>);

impl Seqs {
    /// Every node a frame was sent to.
    pub(crate) fn peers(&self) -> Vec<NodeId> {
        let m = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let mut peers: Vec<NodeId> = m.keys().copied().collect();
        peers.sort();
        peers
    }

    /// The number the next data frame to `to` will carry, without taking it: link control
    /// frames (handshake, heartbeats) carry it, so data sequence numbers have no gaps but lost
    /// data frames.
    pub(crate) fn peek(&self, to: NodeId) -> u64 {
        let m = self.0.lock().unwrap_or_else(|p| p.into_inner());
        m.get(&to).copied().unwrap_or(0)
    }

    pub(crate) fn next(&self, to: NodeId) -> u64 {
        let mut m = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let s = m.entry(to).or_insert(0);
        let out = *s;
        *s += 1;
        out
    }
}

/// A frame on its way out: already encoded.
#[derive(Clone, Debug)]
pub(crate) struct OutFrame {
    pub to: NodeId,
    pub bytes: Bytes,
    pub droppable: bool,
}

pub(crate) enum Link {
    InProcess(InProcessHub),
    Tcp(tcp::Router),
    Ipc(ipc::Sender),
}

struct EndpointInner {
    me: NodeId,
    seqs: Arc<Seqs>,
    stats: Arc<TransportStats>,
    link: Link,
    local_addr: Option<SocketAddr>,
}

/// The sending half. Cheap to clone; every clone shares sequence numbers and counters.
#[derive(Clone)]
pub struct Endpoint {
    inner: Arc<EndpointInner>,
}

impl std::fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Endpoint").field("me", &self.inner.me).finish()
    }
}

impl Endpoint {
    pub fn me(&self) -> NodeId {
        self.inner.me
    }

    /// The address a TCP endpoint listens on (useful after binding port 0).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.inner.local_addr
    }

    /// Wrap `out` in an envelope stamped with `time` and deliver it to `out.to`.
    ///
    /// # Errors
    /// [`SendError::Encode`] if the message fails validation or encodes too large,
    /// [`SendError::UnknownPeer`] if there is no link to the recipient, [`SendError::Closed`]
    /// after shutdown. A droppable message meeting a full queue is not an error: it returns
    /// `Ok(Delivery::Dropped)` and is counted.
    pub async fn send(&self, out: Outgoing, time: ClusterTime) -> Result<Delivery, SendError> {
        let i = &self.inner;
        let droppable = out.body.droppable();
        let env = Envelope {
            source: i.me,
            seq: i.seqs.next(out.to),
            time,
            body: out.body,
        };
        let bytes = match encode(&env) {
            Ok(b) => Bytes::from(b),
            Err(e) => {
                stats::bump(&i.stats.encode_errors);
                tracing::warn!(to = %out.to, kind = env.body.kind(), error = %e, "message not sent");
                return Err(SendError::Encode(e));
            }
        };
        self.send_frame(OutFrame {
            to: out.to,
            bytes,
            droppable,
        })
        .await
    }

    /// Send raw bytes as one frame, bypassing encoding. For probes and tests that must prove
    /// a receiver rejects malformed or oversized frames; never for node logic.
    ///
    /// # Errors
    /// As [`Endpoint::send`], minus encoding.
    pub async fn send_raw_frame(&self, to: NodeId, bytes: Vec<u8>) -> Result<Delivery, SendError> {
        self.send_frame(OutFrame {
            to,
            bytes: Bytes::from(bytes),
            droppable: false,
        })
        .await
    }

    /// Make sure this endpoint has, or is making, a link to `peer`: over TCP a peer whose
    /// address the configuration's directory knows is dialed now (a camera reaching the head it
    /// was just assigned to). Returns whether a link exists or is being made; iceoryx2 and
    /// in-process endpoints reach every peer without one and always return true.
    pub fn ensure_link(&self, peer: NodeId) -> bool {
        match &self.inner.link {
            Link::Tcp(router) => router.ensure(peer),
            Link::InProcess(_) | Link::Ipc(_) => true,
        }
    }

    async fn send_frame(&self, frame: OutFrame) -> Result<Delivery, SendError> {
        let i = &self.inner;
        let to = frame.to;
        let len = frame.bytes.len();
        let r = match &i.link {
            Link::InProcess(hub) => hub.deliver(i.me, frame, &i.stats).await,
            Link::Tcp(router) => router.send(frame, &i.stats).await,
            Link::Ipc(tx) => tx.send(frame, &i.stats).await,
        };
        match &r {
            Ok(Delivery::Queued) => {
                stats::bump(&i.stats.sent);
                stats::add(&i.stats.bytes_sent, len);
            }
            Ok(Delivery::Dropped) => {}
            Err(SendError::UnknownPeer(_)) => {
                stats::bump(&i.stats.unroutable);
                if let Some(more) = i.stats.log_admits("no link to recipient") {
                    tracing::warn!(to = %to, more, "no link to recipient");
                }
            }
            Err(_) => {}
        }
        r
    }
}

/// Stops a transport. [`ShutdownHandle::shutdown`] flushes queued frames (TCP), stops tasks
/// and threads and releases shared-memory resources; dropping the handle without calling it
/// still signals stop but does not wait, and may leave the iceoryx2 domain's last file.
pub struct ShutdownHandle {
    token: CancellationToken,
    tracker: TaskTracker,
    threads: Vec<std::thread::JoinHandle<()>>,
    on_stop: Vec<Box<dyn FnOnce() + Send>>,
    after_join: Vec<Box<dyn FnOnce() + Send>>,
}

impl std::fmt::Debug for ShutdownHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShutdownHandle")
            .field("threads", &self.threads.len())
            .finish()
    }
}

impl ShutdownHandle {
    fn new() -> Self {
        ShutdownHandle {
            token: CancellationToken::new(),
            tracker: TaskTracker::new(),
            threads: Vec::new(),
            on_stop: Vec::new(),
            after_join: Vec::new(),
        }
    }

    /// A token cancelled when shutdown starts.
    pub fn token(&self) -> CancellationToken {
        self.token.clone()
    }

    fn signal(&mut self) {
        self.token.cancel();
        for f in self.on_stop.drain(..) {
            f();
        }
    }

    /// Stop and wait (at most `timeout` for tasks; threads are joined).
    pub async fn shutdown_within(mut self, timeout: Duration) {
        self.signal();
        self.tracker.close();
        if tokio::time::timeout(timeout, self.tracker.wait()).await.is_err() {
            tracing::warn!(?timeout, "transport tasks did not stop in time");
        }
        let threads = std::mem::take(&mut self.threads);
        let after = std::mem::take(&mut self.after_join);
        let joined = tokio::task::spawn_blocking(move || {
            for t in threads {
                if t.join().is_err() {
                    tracing::warn!("a transport thread panicked");
                }
            }
            for f in after {
                f();
            }
        });
        if tokio::time::timeout(timeout, joined).await.is_err() {
            tracing::warn!(?timeout, "transport threads did not stop in time");
        }
    }

    /// Stop and wait up to two seconds.
    pub async fn shutdown(self) {
        self.shutdown_within(Duration::from_secs(2)).await;
    }
}

impl Drop for ShutdownHandle {
    fn drop(&mut self) {
        self.signal();
    }
}

/// What [`open`] returns.
pub type Opened = (Endpoint, Inbox, Arc<TransportStats>, ShutdownHandle);

/// Open a transport. Must be called inside a tokio runtime.
///
/// # Errors
/// [`TransportError::Config`] for an invalid configuration (bad domain, node id already
/// registered on a hub), [`TransportError::Io`] if a TCP listener cannot bind,
/// [`TransportError::Ipc`] if iceoryx2 services cannot be created.
pub async fn open(cfg: TransportConfig) -> Result<Opened, TransportError> {
    let stats = Arc::new(TransportStats::default());
    let seqs = Arc::new(Seqs::default());
    let mut handle = ShutdownHandle::new();
    let mut heartbeat = None;
    let (me, link, inbox, local_addr) = match cfg {
        TransportConfig::InProcess {
            hub,
            me,
            role: _,
            queue_len,
        } => {
            let (tx, rx) = mpsc::channel(queue_len.max(1));
            hub.register(me, tx, stats.clone())?;
            let hub2 = hub.clone();
            handle.on_stop.push(Box::new(move || hub2.unregister(me)));
            (me, Link::InProcess(hub), InboxKind::Channel(rx), None)
        }
        TransportConfig::Tcp(c) => {
            let me = c.me;
            let (tx, rx) = mpsc::channel(c.queue_len.max(1));
            let (router, addr) = tcp::start(c, tx, stats.clone(), seqs.clone(), &handle).await?;
            (me, Link::Tcp(router), InboxKind::Channel(rx), addr)
        }
        TransportConfig::Ipc(mut c) => {
            heartbeat = c.heartbeat.take();
            let me = c.me;
            let (sender, receiver) = ipc::start(c, stats.clone(), &mut handle)?;
            (me, Link::Ipc(sender), InboxKind::Ipc(receiver), None)
        }
    };
    let endpoint = Endpoint {
        inner: Arc::new(EndpointInner {
            me,
            seqs,
            stats: stats.clone(),
            link,
            local_addr,
        }),
    };
    if let Some((period, clock)) = heartbeat {
        spawn_heartbeats(&handle, endpoint.clone(), period, clock);
    }
    Ok((endpoint, Inbox(inbox), stats, handle))
}

/// Heartbeat every peer this endpoint has sent to, until shutdown.
fn spawn_heartbeats(handle: &ShutdownHandle, endpoint: Endpoint, period: Duration, clock: Clock) {
    let token = handle.token();
    handle.tracker.spawn(async move {
        let mut every = tokio::time::interval(period);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                () = token.cancelled() => break,
                _ = every.tick() => {
                    for peer in endpoint.inner.seqs.peers() {
                        let _ = endpoint.send(Outgoing::new(peer, Message::Heartbeat), clock()).await;
                    }
                }
            }
        }
    });
}

/// Peers to dial, by id.
pub type PeerMap = BTreeMap<NodeId, SocketAddr>;
