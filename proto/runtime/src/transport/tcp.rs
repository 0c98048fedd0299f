//! TCP transport between hosts.
//!
//! Heads and the server listen; cameras dial (`peers`). A link is bidirectional: the dialer
//! sends `Hello { version, role, node }`, the listener answers `HelloAck` and from then on
//! routes frames for that node id over the accepted connection. Frames are length-prefixed
//! ([`super::codec::FrameCodec`], limit [`MAX_FRAME_BYTES`]); oversized, malformed and
//! wrong-version frames are counted and skipped, the link stays up. Each side sends a
//! `Heartbeat` every `heartbeat` and drops a link silent for `liveness_timeout`; these control
//! frames repeat the next data sequence number instead of taking one. Dialed links
//! reconnect with exponential backoff and jitter; their outgoing queue survives reconnects.
//! On shutdown every link writes what is queued, flushes and closes.

use super::codec::{Frame, FrameCodec};
use super::common::{accept, deliver, push, reject};
use super::stats::{TransportStats, bump};
use super::{
    Backoff, Clock, Delivery, Event, OutFrame, SendError, Seqs, ShutdownHandle, TransportError, zero_clock,
};
use bytes::Bytes;
use futures_util::{SinkExt, StreamExt};
use proto::ids::{NodeId, Role};
use proto::msg::{Envelope, Hello, HelloAck, Message};
use proto::wire::{WireError, decode, encode};
use proto::{MAX_FRAME_BYTES, PROTOCOL_VERSION};
use std::collections::{BTreeMap, HashMap};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use thiserror::Error;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio::time::{Instant, sleep, timeout};
use tokio_util::codec::Framed;
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

/// Settings of a TCP endpoint.
#[derive(Clone)]
pub struct TcpConfig {
    pub me: NodeId,
    pub role: Role,
    /// Listen here for peers that dial in (heads, server). Port 0 picks a free port; see
    /// [`super::Endpoint::local_addr`].
    pub listen: Option<SocketAddr>,
    /// Peers this node dials, by id.
    pub peers: BTreeMap<NodeId, SocketAddr>,
    pub heartbeat: Duration,
    pub liveness_timeout: Duration,
    pub handshake_timeout: Duration,
    /// Outgoing frames queued per link (and events queued in the inbox).
    pub queue_len: usize,
    pub backoff: Backoff,
    pub clock: Clock,
}

impl TcpConfig {
    /// Defaults: heartbeat 200 ms, liveness 1 s, handshake 2 s, 256 frames per queue.
    pub fn new(me: NodeId, role: Role) -> Self {
        TcpConfig {
            me,
            role,
            listen: None,
            peers: BTreeMap::new(),
            heartbeat: Duration::from_millis(200),
            liveness_timeout: Duration::from_secs(1),
            handshake_timeout: Duration::from_secs(2),
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
            .field("listen", &self.listen)
            .field("peers", &self.peers)
            .field("heartbeat", &self.heartbeat)
            .field("liveness_timeout", &self.liveness_timeout)
            .field("queue_len", &self.queue_len)
            .finish_non_exhaustive()
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

/// Routes outgoing frames to the queue of the link to their recipient.
pub(crate) struct Router {
    links: Links,
}

impl Router {
    pub(crate) async fn send(&self, frame: OutFrame, stats: &TransportStats) -> Result<Delivery, SendError> {
        let tx = lock(&self.links).get(&frame.to).map(|(_, tx)| tx.clone());
        let Some(tx) = tx else {
            return Err(SendError::UnknownPeer(frame.to));
        };
        push(&tx, frame.bytes, frame.droppable, &stats.dropped_queue_full).await
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

type Conn = Framed<TcpStream, FrameCodec>;

struct Ctx {
    me: NodeId,
    role: Role,
    heartbeat: Duration,
    liveness_timeout: Duration,
    handshake_timeout: Duration,
    queue_len: usize,
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

    async fn up(&self, peer: NodeId) {
        bump(&self.stats.peers_up);
        tracing::info!(me = %self.me, %peer, "link up");
        let _ = self.events.send(Event::PeerUp(peer)).await;
    }

    async fn down(&self, peer: NodeId, why: &Result<(), LinkError>) {
        if !self.token.is_cancelled() {
            bump(&self.stats.peers_lost);
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
    if cfg.listen.is_none() && cfg.peers.is_empty() {
        return Err(TransportError::Config(
            "a TCP endpoint needs a listen address or peers".into(),
        ));
    }
    let links: Links = Arc::default();
    let ctx = Arc::new(Ctx {
        me: cfg.me,
        role: cfg.role,
        heartbeat: cfg.heartbeat,
        liveness_timeout: cfg.liveness_timeout,
        handshake_timeout: cfg.handshake_timeout,
        queue_len: cfg.queue_len.max(1),
        clock: cfg.clock.clone(),
        stats,
        seqs,
        events,
        token: handle.token.clone(),
        tracker: handle.tracker.clone(),
        links: links.clone(),
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
        handle.tracker.spawn(accept_loop(ctx.clone(), listener));
    }
    for (&peer, &addr) in &cfg.peers {
        let (tx, rx) = mpsc::channel(ctx.queue_len);
        lock(&links).insert(peer, (DIALED, tx));
        handle
            .tracker
            .spawn(dial_loop(ctx.clone(), peer, addr, rx, cfg.backoff.clone()));
    }
    Ok((Router { links }, local))
}

async fn dial_loop(
    ctx: Arc<Ctx>,
    peer: NodeId,
    addr: SocketAddr,
    mut rx: mpsc::Receiver<Bytes>,
    mut backoff: Backoff,
) {
    let mut first = true;
    loop {
        if !first {
            bump(&ctx.stats.reconnects);
        }
        first = false;
        let dialed = tokio::select! {
            _ = ctx.token.cancelled() => return,
            r = dial(&ctx, peer, addr) => r,
        };
        match dialed {
            Ok(conn) => {
                backoff.reset();
                ctx.up(peer).await;
                let r = run_link(&ctx, peer, conn, &mut rx).await;
                ctx.down(peer, &r).await;
                if ctx.token.is_cancelled() {
                    return;
                }
            }
            Err(e) => tracing::debug!(me = %ctx.me, %peer, %addr, error = %e, "dial failed"),
        }
        let delay = backoff.next_delay(&mut rand::rng());
        tokio::select! {
            _ = ctx.token.cancelled() => return,
            _ = sleep(delay) => {}
        }
    }
}

async fn next_frame(conn: &mut Conn, within: Duration, what: &'static str) -> Result<Frame, LinkError> {
    match timeout(within, conn.next()).await {
        Err(_) => Err(LinkError::Timeout(what)),
        Ok(None) => Err(LinkError::Closed),
        Ok(Some(Err(e))) => Err(LinkError::Io(e)),
        Ok(Some(Ok(f))) => Ok(f),
    }
}

async fn dial(ctx: &Ctx, peer: NodeId, addr: SocketAddr) -> Result<Conn, LinkError> {
    let stream = timeout(ctx.handshake_timeout, TcpStream::connect(addr))
        .await
        .map_err(|_| LinkError::Timeout("connect"))??;
    stream.set_nodelay(true)?;
    let mut conn = Framed::new(stream, FrameCodec::new(MAX_FRAME_BYTES));
    let hello = Message::Hello(Hello {
        version: PROTOCOL_VERSION,
        role: ctx.role,
        node: ctx.me,
    });
    conn.send(ctx.frame(peer, hello)?).await?;
    let frame = next_frame(&mut conn, ctx.handshake_timeout, "handshake").await?;
    let Frame::Data(bytes) = frame else {
        bump(&ctx.stats.rejected_oversized);
        return Err(LinkError::Handshake("oversized answer to Hello".into()));
    };
    let Some(env) = accept(&bytes, &ctx.stats, Some(peer), "tcp") else {
        return Err(LinkError::Handshake("unreadable answer to Hello".into()));
    };
    match env.body {
        Message::HelloAck(HelloAck { accepted: true, .. }) => Ok(conn),
        Message::HelloAck(HelloAck { reason, .. }) => {
            bump(&ctx.stats.rejected_handshake);
            Err(LinkError::Refused(reason))
        }
        other => Err(LinkError::Handshake(format!(
            "expected hello_ack, got {}",
            other.kind()
        ))),
    }
}

async fn accept_loop(ctx: Arc<Ctx>, listener: TcpListener) {
    loop {
        tokio::select! {
            _ = ctx.token.cancelled() => return,
            r = listener.accept() => match r {
                Ok((stream, addr)) => {
                    ctx.tracker.spawn(serve(ctx.clone(), stream, addr));
                }
                Err(e) => {
                    tracing::warn!(error = %e, "accept failed");
                    sleep(Duration::from_millis(20)).await;
                }
            },
        }
    }
}

/// Refuse a handshake: count, log, answer (best effort) and let the connection drop.
async fn refuse(ctx: &Ctx, conn: &mut Conn, addr: SocketAddr, to: Option<NodeId>, reason: String) {
    bump(&ctx.stats.rejected_handshake);
    tracing::warn!(me = %ctx.me, %addr, %reason, "handshake refused");
    let ack = Message::HelloAck(HelloAck {
        accepted: false,
        reason,
    });
    if let Ok(f) = ctx.frame(to.unwrap_or(NodeId(u32::MAX)), ack) {
        let _ = timeout(ctx.handshake_timeout, conn.send(f)).await;
    }
}

async fn serve(ctx: Arc<Ctx>, stream: TcpStream, addr: SocketAddr) {
    let _ = stream.set_nodelay(true);
    let mut conn = Framed::new(stream, FrameCodec::new(MAX_FRAME_BYTES));
    let first = tokio::select! {
        _ = ctx.token.cancelled() => return,
        f = next_frame(&mut conn, ctx.handshake_timeout, "handshake") => f,
    };
    let env = match first {
        Ok(Frame::Data(bytes)) => match decode(&bytes) {
            Ok(env) => env,
            Err(e) => {
                reject(&e, bytes.len(), &ctx.stats, "tcp");
                let reason = match &e {
                    WireError::Version { .. } => format!("{e}"),
                    _ => format!("unreadable hello: {e}"),
                };
                refuse(&ctx, &mut conn, addr, None, reason).await;
                return;
            }
        },
        Ok(Frame::Oversized { len }) => {
            bump(&ctx.stats.rejected_oversized);
            refuse(
                &ctx,
                &mut conn,
                addr,
                None,
                format!("oversized hello of {len} bytes"),
            )
            .await;
            return;
        }
        Err(e) => {
            bump(&ctx.stats.rejected_handshake);
            tracing::warn!(me = %ctx.me, %addr, error = %e, "no handshake");
            return;
        }
    };
    let peer = env.source;
    let Message::Hello(hello) = env.body else {
        refuse(
            &ctx,
            &mut conn,
            addr,
            Some(peer),
            format!("expected hello, got {}", env.body.kind()),
        )
        .await;
        return;
    };
    if hello.version != PROTOCOL_VERSION || hello.node != peer {
        let reason = format!(
            "hello claims version {} node {} from node {peer}; this build speaks version {PROTOCOL_VERSION}",
            hello.version, hello.node
        );
        if hello.version != PROTOCOL_VERSION {
            bump(&ctx.stats.rejected_version);
        }
        refuse(&ctx, &mut conn, addr, Some(peer), reason).await;
        return;
    }
    if lock(&ctx.links).get(&peer).is_some_and(|(g, _)| *g == DIALED) {
        refuse(
            &ctx,
            &mut conn,
            addr,
            Some(peer),
            format!("this node dials {peer} itself"),
        )
        .await;
        return;
    }
    let ack = Message::HelloAck(HelloAck {
        accepted: true,
        reason: String::new(),
    });
    match ctx.frame(peer, ack) {
        Ok(f) => {
            if let Err(e) = conn.send(f).await {
                tracing::warn!(%peer, error = %e, "could not answer hello");
                return;
            }
        }
        Err(e) => {
            tracing::warn!(%peer, error = %e, "could not answer hello");
            return;
        }
    }
    tracing::debug!(me = %ctx.me, %peer, role = %hello.role, %addr, "handshake accepted");
    let (tx, mut rx) = mpsc::channel(ctx.queue_len);
    let generation = NEXT_GEN.fetch_add(1, Ordering::Relaxed);
    lock(&ctx.links).insert(peer, (generation, tx));
    ctx.up(peer).await;
    let r = run_link(&ctx, peer, conn, &mut rx).await;
    {
        let mut links = lock(&ctx.links);
        if links.get(&peer).is_some_and(|(g, _)| *g == generation) {
            links.remove(&peer);
        }
    }
    ctx.down(peer, &r).await;
}

/// Move frames both ways on an established link until it fails, goes silent, or shutdown.
async fn run_link(
    ctx: &Ctx,
    peer: NodeId,
    conn: Conn,
    rx: &mut mpsc::Receiver<Bytes>,
) -> Result<(), LinkError> {
    let (mut sink, mut stream) = conn.split();
    let mut heartbeat = tokio::time::interval_at(Instant::now() + ctx.heartbeat, ctx.heartbeat);
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let silence = sleep(ctx.liveness_timeout);
    tokio::pin!(silence);
    loop {
        tokio::select! {
            biased;
            _ = ctx.token.cancelled() => {
                while let Ok(b) = rx.try_recv() {
                    sink.feed(b).await?;
                }
                sink.flush().await?;
                let _ = sink.close().await;
                return Ok(());
            }
            f = stream.next() => match f {
                None => return Err(LinkError::Closed),
                Some(Err(e)) => return Err(LinkError::Io(e)),
                Some(Ok(frame)) => {
                    silence.as_mut().reset(Instant::now() + ctx.liveness_timeout);
                    on_frame(ctx, peer, frame).await?;
                }
            },
            m = rx.recv() => match m {
                None => return Ok(()),
                Some(b) => {
                    sink.feed(b).await?;
                    while let Ok(b) = rx.try_recv() {
                        sink.feed(b).await?;
                    }
                    sink.flush().await?;
                }
            },
            _ = heartbeat.tick() => {
                let frame = ctx.frame(peer, Message::Heartbeat)?;
                super::stats::add(&ctx.stats.bytes_sent, frame.len());
                sink.send(frame).await?;
                bump(&ctx.stats.heartbeats_sent);
            }
            _ = &mut silence => return Err(LinkError::Silent(ctx.liveness_timeout)),
        }
    }
}

async fn on_frame(ctx: &Ctx, peer: NodeId, frame: Frame) -> Result<(), LinkError> {
    match frame {
        Frame::Oversized { len } => {
            reject(
                &WireError::Oversized {
                    len,
                    max: MAX_FRAME_BYTES,
                },
                len,
                &ctx.stats,
                "tcp",
            );
        }
        Frame::Data(bytes) => {
            if let Some(env) = accept(&bytes, &ctx.stats, Some(peer), "tcp") {
                match env.body {
                    Message::Heartbeat => bump(&ctx.stats.heartbeats_received),
                    Message::Hello(_) | Message::HelloAck(_) => {
                        tracing::debug!(%peer, "handshake frame on an established link ignored");
                    }
                    _ => {
                        deliver(&ctx.events, peer, env, &ctx.stats)
                            .await
                            .map_err(|_| LinkError::InboxClosed)?;
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "tcp_tests.rs"]
mod tests;
