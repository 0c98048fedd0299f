//! TCP transport between hosts, mutually authenticated with TLS.
//!
//! Heads and the server listen; cameras dial their head and the server, heads the server
//! (`peers`), and a camera dials whichever head it is assigned to later (`directory`,
//! [`super::Endpoint::ensure_link`]). A link is bidirectional: after the TLS handshake
//! ([`super::tls`]: both ends present a certificate of the cluster's CA naming their node id
//! and role) the dialer sends `Hello { version, role, node }` and the listener answers
//! `HelloAck`. A listener refuses, counts and logs (rate-limited) a peer whose certificate does
//! not certify the id and role its Hello claims, an id or role the scenario does not give it
//! (`roster`), and a second connection for an id that already has a live link — the first is
//! never displaced; once it is really gone (closed, or silent past the liveness timeout) a
//! reconnect is accepted. Plain TCP ([`Security::Insecure`]) skips only the certificates.
//!
//! Frames are length-prefixed ([`super::codec::FrameCodec`], limit [`MAX_FRAME_BYTES`]);
//! oversized, malformed and wrong-version frames are counted and skipped, the link stays up.
//! Each side sends a `Heartbeat` every `heartbeat` and drops a link silent for
//! `liveness_timeout`: the `PeerUp`/`PeerDown` events are the link's liveness. Dialed links
//! reconnect with exponential backoff and jitter; their outgoing queue survives reconnects.
//!
//! Floods cost little: a listener serves at most `max_handshakes` unfinished handshakes (and
//! `max_handshakes_per_ip` from one address), each bounded by `handshake_timeout`; a link is
//! read at most `max_frames_per_sec` (a faster peer is read later, its own TCP window fills,
//! the other links are served as before). On shutdown every link writes what is queued,
//! flushes and closes.

mod accept;
mod dial;
mod link;

use super::common::push;
use super::stats::TransportStats;
use super::tls::Tls;
use super::{
    Backoff, Clock, Delivery, Event, OutFrame, SendError, Seqs, ShutdownHandle, TransportError, zero_clock,
};
use bytes::Bytes;
use proto::MAX_FRAME_BYTES;
use proto::ids::{NodeId, Role};
use proto::msg::{Envelope, Message};
use proto::wire::encode;
use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use thiserror::Error;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::TcpListener;
use tokio::sync::mpsc;
use tokio_util::codec::Framed;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

use super::codec::FrameCodec;

/// How a TCP endpoint proves who it is and checks its peers.
#[derive(Clone, Debug)]
pub enum Security {
    /// Mutual TLS with the cluster's certificates (the default everywhere).
    Tls(Tls),
    /// Plain TCP: anyone who reaches the port may claim any id the roster admits. Only on an
    /// explicit setting (`[network] insecure = true`, `--insecure`), and logged loudly.
    Insecure,
}

/// Settings of a TCP endpoint.
#[derive(Clone)]
pub struct TcpConfig {
    pub me: NodeId,
    pub role: Role,
    pub security: Security,
    /// Listen here for peers that dial in (heads, server). Port 0 picks a free port; see
    /// [`super::Endpoint::local_addr`].
    pub listen: Option<SocketAddr>,
    /// Peers this node dials from the start, by id.
    pub peers: BTreeMap<NodeId, SocketAddr>,
    /// Listen addresses of nodes this one may dial later: sending to one of them, or
    /// [`super::Endpoint::ensure_link`], starts dialing it (a camera and the heads it may be
    /// assigned to).
    pub directory: BTreeMap<NodeId, SocketAddr>,
    /// Who may connect and as what: the scenario's nodes and roles. An id it does not list is
    /// admitted only as a tool. `None` admits any id (tests, probes); certificates still have to
    /// match the claim.
    pub roster: Option<BTreeMap<NodeId, Role>>,
    pub heartbeat: Duration,
    pub liveness_timeout: Duration,
    /// Longest a connection may take from TCP accept to the end of the Hello exchange.
    pub handshake_timeout: Duration,
    /// Unfinished handshakes a listener serves at once; more connections are closed at once.
    pub max_handshakes: usize,
    /// Unfinished handshakes from one IP address.
    pub max_handshakes_per_ip: usize,
    /// Frames per second one link is read at most (with a burst of as many).
    pub max_frames_per_sec: u32,
    /// Outgoing frames queued per link (and events queued in the inbox).
    pub queue_len: usize,
    pub backoff: Backoff,
    pub clock: Clock,
}

impl TcpConfig {
    /// Defaults: heartbeat 200 ms, liveness 1 s, handshake 2 s, 32 handshakes (4 per
    /// address), 2000 frames/s per link, 256 frames per queue, no roster.
    pub fn new(me: NodeId, role: Role, security: Security) -> Self {
        TcpConfig {
            me,
            role,
            security,
            listen: None,
            peers: BTreeMap::new(),
            directory: BTreeMap::new(),
            roster: None,
            heartbeat: Duration::from_millis(200),
            liveness_timeout: Duration::from_secs(1),
            handshake_timeout: Duration::from_secs(2),
            max_handshakes: 32,
            max_handshakes_per_ip: 4,
            max_frames_per_sec: 2000,
            queue_len: 256,
            backoff: Backoff::default(),
            clock: zero_clock(),
        }
    }
}

impl std::fmt::Debug for TcpConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TcpConfig")
            .field("me", &self.me)
            .field("role", &self.role)
            .field("tls", &matches!(self.security, Security::Tls(_)))
            .field("listen", &self.listen)
            .field("peers", &self.peers)
            .field("directory", &self.directory)
            .field("heartbeat", &self.heartbeat)
            .field("liveness_timeout", &self.liveness_timeout)
            .field("queue_len", &self.queue_len)
            .finish_non_exhaustive()
    }
}

/// Whether `roster` lets `id` connect as `role`.
///
/// # Errors
/// Why not, in a sentence.
pub(crate) fn admitted(
    roster: Option<&BTreeMap<NodeId, Role>>,
    id: NodeId,
    role: Role,
) -> Result<(), String> {
    let Some(roster) = roster else { return Ok(()) };
    match roster.get(&id) {
        Some(&r) if r == role => Ok(()),
        Some(&r) => Err(format!("the scenario declares {id} as {r}, not {role}")),
        // Tools and viewers are clients with no say in tracking (the server decides what they
        // may ask); with TLS they still need a certificate of the cluster's CA.
        None if matches!(role, Role::Tool | Role::Viewer) => Ok(()),
        None => Err(format!("{id} is not in the scenario (claims {role})")),
    }
}

/// Generation 0 marks a dialed link (its queue outlives connections); accepted links get a
/// fresh generation so a stale connection never removes its successor.
const DIALED: u64 = 0;
static NEXT_GEN: AtomicU64 = AtomicU64::new(1);

type Links = Arc<Mutex<HashMap<NodeId, (u64, mpsc::Sender<Bytes>)>>>;

fn lock(links: &Links) -> std::sync::MutexGuard<'_, HashMap<NodeId, (u64, mpsc::Sender<Bytes>)>> {
    links.lock().unwrap_or_else(|p| p.into_inner())
}

/// Routes outgoing frames to the queue of the link to their recipient, dialing a directory
/// peer the first time it is needed.
pub(crate) struct Router {
    ctx: Arc<Ctx>,
}

impl Router {
    pub(crate) async fn send(&self, frame: OutFrame, stats: &TransportStats) -> Result<Delivery, SendError> {
        let tx = lock(&self.ctx.links).get(&frame.to).map(|(_, tx)| tx.clone());
        let tx = match tx {
            Some(tx) => tx,
            None => self.dial(frame.to).ok_or(SendError::UnknownPeer(frame.to))?,
        };
        push(&tx, frame.bytes, frame.droppable, &stats.dropped_queue_full).await
    }

    /// Make sure there is (or will be) a link to `peer`: true if one exists or is being dialed.
    pub(crate) fn ensure(&self, peer: NodeId) -> bool {
        lock(&self.ctx.links).contains_key(&peer) || self.dial(peer).is_some()
    }

    /// Start dialing `peer` if the directory knows its address; its queue.
    fn dial(&self, peer: NodeId) -> Option<mpsc::Sender<Bytes>> {
        let addr = *self.ctx.directory.get(&peer)?;
        if self.ctx.token.is_cancelled() {
            return None;
        }
        let mut links = lock(&self.ctx.links);
        if let Some((_, tx)) = links.get(&peer) {
            return Some(tx.clone());
        }
        let (tx, rx) = mpsc::channel(self.ctx.queue_len);
        links.insert(peer, (DIALED, tx.clone()));
        drop(links);
        tracing::info!(me = %self.ctx.me, %peer, %addr, "dialing a newly needed peer");
        self.ctx.tracker.spawn(dial::dial_loop(
            self.ctx.clone(),
            peer,
            addr,
            rx,
            self.ctx.backoff.clone(),
        ));
        Some(tx)
    }
}

#[derive(Debug, Error)]
enum LinkError {
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("{0} timed out")]
    Timeout(&'static str),
    #[error("connection closed by peer")]
    Closed,
    #[error("handshake refused: {0}")]
    Refused(String),
    #[error("handshake: {0}")]
    Handshake(String),
    #[error("no frame for {0:?}")]
    Silent(Duration),
    #[error("inbox closed")]
    InboxClosed,
}

/// A byte stream under the frame codec: plain TCP or TLS over it.
trait Io: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Io for T {}

type Conn = Framed<Box<dyn Io>, FrameCodec>;

fn framed(io: Box<dyn Io>) -> Conn {
    Framed::new(io, FrameCodec::new(MAX_FRAME_BYTES))
}

struct Ctx {
    me: NodeId,
    role: Role,
    tls: Option<Tls>,
    roster: Option<BTreeMap<NodeId, Role>>,
    directory: BTreeMap<NodeId, SocketAddr>,
    heartbeat: Duration,
    liveness_timeout: Duration,
    handshake_timeout: Duration,
    max_handshakes: usize,
    max_handshakes_per_ip: usize,
    max_frames_per_sec: u32,
    queue_len: usize,
    backoff: Backoff,
    clock: Clock,
    stats: Arc<TransportStats>,
    seqs: Arc<Seqs>,
    events: mpsc::Sender<Event>,
    token: CancellationToken,
    tracker: TaskTracker,
    links: Links,
}

impl Ctx {
    /// A link control frame (hello, hello-ack, heartbeat). It never reaches the peer's node
    /// logic, so it takes no sequence number: a gap in what the peer records is a lost frame.
    fn frame(&self, to: NodeId, body: Message) -> Result<Bytes, LinkError> {
        let env = Envelope {
            source: self.me,
            seq: self.seqs.peek(to),
            time: (self.clock)(),
            body,
        };
        encode(&env)
            .map(Bytes::from)
            .map_err(|e| LinkError::Handshake(format!("cannot encode own frame: {e}")))
    }

    /// The role the roster gives `peer` (a tool when it lists none).
    fn role_of(&self, peer: NodeId) -> Role {
        self.roster
            .as_ref()
            .and_then(|r| r.get(&peer).copied())
            .unwrap_or(Role::Tool)
    }

    async fn up(&self, peer: NodeId) {
        super::stats::bump(&self.stats.peers_up);
        tracing::info!(me = %self.me, %peer, "link up");
        let _ = self.events.send(Event::PeerUp(peer)).await;
    }

    async fn down(&self, peer: NodeId, why: &Result<(), LinkError>) {
        if !self.token.is_cancelled() {
            super::stats::bump(&self.stats.peers_lost);
        }
        match why {
            Ok(()) => tracing::info!(me = %self.me, %peer, "link closed"),
            Err(e) => tracing::warn!(me = %self.me, %peer, reason = %e, "link lost"),
        }
        let _ = self.events.send(Event::PeerDown(peer)).await;
    }
}

pub(crate) async fn start(
    cfg: TcpConfig,
    events: mpsc::Sender<Event>,
    stats: Arc<TransportStats>,
    seqs: Arc<Seqs>,
    handle: &ShutdownHandle,
) -> Result<(Router, Option<SocketAddr>), TransportError> {
    if cfg.listen.is_none() && cfg.peers.is_empty() && cfg.directory.is_empty() {
        return Err(TransportError::Config(
            "a TCP endpoint needs a listen address or peers".into(),
        ));
    }
    let tls = match cfg.security {
        Security::Tls(t) => Some(t),
        Security::Insecure => {
            tracing::warn!(
                me = %cfg.me,
                "INSECURE: TCP links without TLS — any host that reaches this node can claim to be any node of the scenario"
            );
            None
        }
    };
    let mut directory = cfg.directory;
    directory.extend(cfg.peers.iter().map(|(k, v)| (*k, *v)));
    let ctx = Arc::new(Ctx {
        me: cfg.me,
        role: cfg.role,
        tls,
        roster: cfg.roster,
        directory,
        heartbeat: cfg.heartbeat,
        liveness_timeout: cfg.liveness_timeout,
        handshake_timeout: cfg.handshake_timeout,
        max_handshakes: cfg.max_handshakes.max(1),
        max_handshakes_per_ip: cfg.max_handshakes_per_ip.max(1),
        max_frames_per_sec: cfg.max_frames_per_sec.max(1),
        queue_len: cfg.queue_len.max(1),
        backoff: cfg.backoff,
        clock: cfg.clock.clone(),
        stats,
        seqs,
        events,
        token: handle.token.clone(),
        tracker: handle.tracker.clone(),
        links: Arc::default(),
    });
    let mut local = None;
    if let Some(addr) = cfg.listen {
        let listener = TcpListener::bind(addr).await.map_err(|e| {
            let hint = if e.kind() == std::io::ErrorKind::AddrInUse {
                " (another process listens there: is this node already up?)"
            } else {
                ""
            };
            std::io::Error::new(e.kind(), format!("cannot listen on {addr}: {e}{hint}"))
        })?;
        local = Some(listener.local_addr()?);
        handle.tracker.spawn(accept::accept_loop(ctx.clone(), listener));
    }
    let router = Router { ctx };
    for &peer in cfg.peers.keys() {
        router.ensure(peer);
    }
    Ok((router, local))
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_tls;
