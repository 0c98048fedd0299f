//! The listening side: accept within the handshake limits, TLS (the peer's certificate must
//! chain to the cluster's CA), Hello, and the checks that bind a connection to one node id —
//! the certificate names the id and role claimed, the roster gives that id that role, and no
//! live link to that id exists.

use super::dial::next_frame;
use super::link::run_link;
use super::{Conn, Ctx, DIALED, NEXT_GEN, admitted, framed, lock};
use crate::transport::codec::Frame;
use crate::transport::common::reject;
use crate::transport::stats::bump;
use crate::transport::tls::certifies;
use futures_util::SinkExt;
use proto::PROTOCOL_VERSION;
use proto::ids::NodeId;
use proto::msg::{HelloAck, Message};
use proto::wire::{WireError, decode};
use rustls::pki_types::CertificateDer;
use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio::time::{sleep, timeout};

/// Unfinished handshakes, in all and per remote address. A slot is held by a [`Pending`].
#[derive(Default)]
struct Handshakes {
    total: usize,
    by_ip: HashMap<IpAddr, usize>,
}

/// One unfinished handshake's slot, given back when dropped.
struct Pending {
    book: Arc<Mutex<Handshakes>>,
    ip: IpAddr,
}

impl Pending {
    fn take(book: &Arc<Mutex<Handshakes>>, ip: IpAddr, max: usize, max_per_ip: usize) -> Option<Pending> {
        let mut b = book.lock().unwrap_or_else(|p| p.into_inner());
        let mine = b.by_ip.get(&ip).copied().unwrap_or(0);
        if b.total >= max || mine >= max_per_ip {
            return None;
        }
        b.total += 1;
        b.by_ip.insert(ip, mine + 1);
        Some(Pending {
            book: book.clone(),
            ip,
        })
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        let mut b = self.book.lock().unwrap_or_else(|p| p.into_inner());
        b.total = b.total.saturating_sub(1);
        if let Some(n) = b.by_ip.get_mut(&self.ip) {
            *n -= 1;
            if *n == 0 {
                b.by_ip.remove(&self.ip);
            }
        }
    }
}

pub(super) async fn accept_loop(ctx: Arc<Ctx>, listener: TcpListener) {
    let book = Arc::new(Mutex::new(Handshakes::default()));
    loop {
        tokio::select! {
            _ = ctx.token.cancelled() => return,
            r = listener.accept() => match r {
                Ok((stream, addr)) => {
                    match Pending::take(&book, addr.ip(), ctx.max_handshakes, ctx.max_handshakes_per_ip) {
                        Some(slot) => {
                            ctx.tracker.spawn(serve(ctx.clone(), stream, addr, slot));
                        }
                        None => {
                            bump(&ctx.stats.rejected_connections);
                            if let Some(more) = ctx.stats.log_admits("too many handshakes") {
                                tracing::warn!(me = %ctx.me, %addr, more, "connection closed: too many unfinished handshakes");
                            }
                            drop(stream);
                        }
                    }
                }
                Err(e) => {
                    if let Some(more) = ctx.stats.log_admits("accept failed") {
                        tracing::warn!(error = %e, more, "accept failed");
                    }
                    sleep(Duration::from_millis(20)).await;
                }
            },
        }
    }
}

/// Refuse a handshake: count, log (rate-limited), answer (best effort) and let the
/// connection drop.
async fn refuse(ctx: &Ctx, conn: &mut Conn, addr: SocketAddr, to: Option<NodeId>, reason: String) {
    bump(&ctx.stats.rejected_handshake);
    if let Some(more) = ctx.stats.log_admits("handshake refused") {
        tracing::warn!(me = %ctx.me, %addr, %reason, more, "handshake refused");
    }
    let ack = Message::HelloAck(HelloAck {
        accepted: false,
        reason,
    });
    if let Ok(f) = ctx.frame(to.unwrap_or(NodeId(u32::MAX)), ack) {
        let _ = timeout(ctx.handshake_timeout, conn.send(f)).await;
    }
}

/// What the handshake established: the peer, the connection, and the link's outgoing queue
/// (already registered as the one live link to that peer).
struct Admitted {
    peer: NodeId,
    conn: Conn,
    generation: u64,
    rx: mpsc::Receiver<bytes::Bytes>,
}

async fn serve(ctx: Arc<Ctx>, stream: TcpStream, addr: SocketAddr, slot: Pending) {
    let _ = stream.set_nodelay(true);
    let admitted = tokio::select! {
        _ = ctx.token.cancelled() => return,
        r = timeout(ctx.handshake_timeout, handshake(&ctx, stream, addr)) => match r {
            Ok(Some(a)) => a,
            Ok(None) => return,
            Err(_) => {
                bump(&ctx.stats.rejected_connections);
                if let Some(more) = ctx.stats.log_admits("handshake timed out") {
                    tracing::warn!(me = %ctx.me, %addr, more, "connection closed: no handshake in time");
                }
                return;
            }
        },
    };
    drop(slot);
    let Admitted {
        peer,
        conn,
        generation,
        mut rx,
    } = admitted;
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

/// TLS, then the Hello and its checks. `None`: refused (counted, logged, answered).
async fn handshake(ctx: &Ctx, stream: TcpStream, addr: SocketAddr) -> Option<Admitted> {
    let (mut conn, cert) = match &ctx.tls {
        None => (framed(Box::new(stream)), None),
        Some(tls) => match tls.acceptor().accept(stream).await {
            Ok(s) => {
                let cert = s.get_ref().1.peer_certificates().and_then(|c| c.first()).cloned();
                (framed(Box::new(s)), cert)
            }
            Err(e) => {
                bump(&ctx.stats.rejected_identity);
                bump(&ctx.stats.rejected_handshake);
                if let Some(more) = ctx.stats.log_admits("TLS handshake failed") {
                    tracing::warn!(me = %ctx.me, %addr, error = %e, more, "TLS handshake refused");
                }
                return None;
            }
        },
    };
    let first = next_frame(&mut conn, ctx.handshake_timeout, "handshake").await;
    let env = match first {
        Ok(Frame::Data(bytes)) => match decode(&bytes) {
            Ok(env) => env,
            Err(e) => {
                reject(&e, bytes.len(), &ctx.stats, "tcp");
                let reason = match &e {
                    WireError::Version { .. } => format!("{e}"),
                    _ => format!("unreadable hello: {e}"),
                };
                refuse(ctx, &mut conn, addr, None, reason).await;
                return None;
            }
        },
        Ok(Frame::Oversized { len }) => {
            bump(&ctx.stats.rejected_oversized);
            let reason = format!("oversized hello of {len} bytes");
            refuse(ctx, &mut conn, addr, None, reason).await;
            return None;
        }
        Err(e) => {
            if matches!(e, super::LinkError::Timeout(_)) {
                bump(&ctx.stats.rejected_connections);
            } else {
                bump(&ctx.stats.rejected_handshake);
            }
            if let Some(more) = ctx.stats.log_admits("no handshake") {
                tracing::warn!(me = %ctx.me, %addr, error = %e, more, "no handshake");
            }
            return None;
        }
    };
    let peer = env.source;
    let Message::Hello(hello) = env.body else {
        let reason = format!("expected hello, got {}", env.body.kind());
        refuse(ctx, &mut conn, addr, Some(peer), reason).await;
        return None;
    };
    if hello.version != PROTOCOL_VERSION || hello.node != peer {
        let reason = format!(
            "hello claims version {} node {} from node {peer}; this build speaks version {PROTOCOL_VERSION}",
            hello.version, hello.node
        );
        if hello.version != PROTOCOL_VERSION {
            bump(&ctx.stats.rejected_version);
        }
        refuse(ctx, &mut conn, addr, Some(peer), reason).await;
        return None;
    }
    let identity = admitted(ctx.roster.as_ref(), peer, hello.role).and_then(|()| match (&ctx.tls, &cert) {
        (None, _) => Ok(()),
        (Some(_), Some(c)) => certifies(&CertificateDer::from(c.as_ref()), peer, hello.role),
        (Some(_), None) => Err("no client certificate".into()),
    });
    if let Err(reason) = identity {
        bump(&ctx.stats.rejected_identity);
        refuse(ctx, &mut conn, addr, Some(peer), reason).await;
        return None;
    }
    // One live link per id, decided under the lock so two racing handshakes cannot both win.
    let (tx, rx) = mpsc::channel(ctx.queue_len);
    let generation = NEXT_GEN.fetch_add(1, Ordering::Relaxed);
    let taken = {
        let mut links = lock(&ctx.links);
        match links.get(&peer) {
            Some((g, _)) if *g == DIALED => Some(format!("this node dials {peer} itself")),
            Some(_) => Some(format!("{peer} already has a live link to this node")),
            None => {
                links.insert(peer, (generation, tx));
                None
            }
        }
    };
    if let Some(reason) = taken {
        bump(&ctx.stats.rejected_duplicate);
        refuse(ctx, &mut conn, addr, Some(peer), reason).await;
        return None;
    }
    let ack = Message::HelloAck(HelloAck {
        accepted: true,
        reason: String::new(),
    });
    let sent = match ctx.frame(peer, ack) {
        Ok(f) => conn.send(f).await.map_err(|e| e.to_string()),
        Err(e) => Err(e.to_string()),
    };
    if let Err(e) = sent {
        tracing::warn!(%peer, error = %e, "could not answer hello");
        let mut links = lock(&ctx.links);
        if links.get(&peer).is_some_and(|(g, _)| *g == generation) {
            links.remove(&peer);
        }
        return None;
    }
    tracing::debug!(me = %ctx.me, %peer, role = %hello.role, %addr, "handshake accepted");
    Some(Admitted {
        peer,
        conn,
        generation,
        rx,
    })
}
