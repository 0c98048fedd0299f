//! The dialing side of a link: connect, TLS (requiring the listener's certificate to name the
//! node meant), Hello, and reconnect with backoff for as long as the endpoint runs.

use super::link::run_link;
use super::{Conn, Ctx, LinkError, framed};
use crate::transport::Backoff;
use crate::transport::codec::Frame;
use crate::transport::common::accept;
use crate::transport::stats::bump;
use crate::transport::tls::Tls;
use bytes::Bytes;
use futures_util::{SinkExt, StreamExt};
use proto::PROTOCOL_VERSION;
use proto::ids::NodeId;
use proto::msg::{Hello, HelloAck, Message};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio::time::{sleep, timeout};

pub(super) async fn dial_loop(
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
            r = timeout(ctx.handshake_timeout, dial(&ctx, peer, addr)) => {
                r.unwrap_or(Err(LinkError::Timeout("handshake")))
            }
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
            Err(e @ LinkError::Refused(_)) => {
                if let Some(more) = ctx.stats.log_admits("dial refused") {
                    tracing::warn!(me = %ctx.me, %peer, %addr, error = %e, more, "peer refused the link");
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

pub(super) async fn next_frame(
    conn: &mut Conn,
    within: Duration,
    what: &'static str,
) -> Result<Frame, LinkError> {
    match timeout(within, conn.next()).await {
        Err(_) => Err(LinkError::Timeout(what)),
        Ok(None) => Err(LinkError::Closed),
        Ok(Some(Err(e))) => Err(LinkError::Io(e)),
        Ok(Some(Ok(f))) => Ok(f),
    }
}

async fn dial(ctx: &Ctx, peer: NodeId, addr: SocketAddr) -> Result<Conn, LinkError> {
    let stream = TcpStream::connect(addr).await?;
    stream.set_nodelay(true)?;
    let mut conn = match &ctx.tls {
        None => framed(Box::new(stream)),
        Some(tls) => {
            let name = Tls::expect(peer, ctx.role_of(peer));
            match tls.connector().connect(name, stream).await {
                Ok(s) => framed(Box::new(s)),
                Err(e) => {
                    bump(&ctx.stats.rejected_identity);
                    return Err(LinkError::Refused(format!("TLS: {e}")));
                }
            }
        }
    };
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
