//! An established link: frames both ways, heartbeats, the liveness timeout, and the per-link
//! read budget that keeps a flooding peer from crowding out the others.

use super::{Conn, Ctx, LinkError};
use crate::transport::codec::Frame;
use crate::transport::common::{accept, deliver, reject};
use crate::transport::stats::bump;
use bytes::Bytes;
use futures_util::{SinkExt, StreamExt};
use proto::MAX_FRAME_BYTES;
use proto::ids::NodeId;
use proto::msg::Message;
use proto::wire::WireError;
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::time::{Instant, sleep, sleep_until};

/// A token bucket over frames read: `rate` per second, at most `burst` in reserve.
pub(super) struct ReadBudget {
    rate: f64,
    burst: f64,
    tokens: f64,
    at: Instant,
}

impl ReadBudget {
    pub(super) fn new(rate: u32, burst: usize, now: Instant) -> Self {
        let rate = f64::from(rate.max(1));
        let burst = (burst.max(1) as f64).min(rate).max(1.0);
        ReadBudget {
            rate,
            burst,
            tokens: burst,
            at: now,
        }
    }

    fn refill(&mut self, now: Instant) {
        let dt = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + dt * self.rate).min(self.burst);
        self.at = now;
    }

    /// Whether a frame may be read at `now`.
    pub(super) fn ready(&mut self, now: Instant) -> bool {
        self.refill(now);
        self.tokens >= 1.0
    }

    /// Spend one frame's token.
    pub(super) fn spend(&mut self) {
        self.tokens -= 1.0;
    }

    /// When the next token is there.
    pub(super) fn next_at(&self) -> Instant {
        let missing = (1.0 - self.tokens).max(0.0);
        self.at + Duration::from_secs_f64(missing / self.rate)
    }
}

/// Move frames both ways on an established link until it fails, goes silent, or shutdown.
pub(super) async fn run_link(
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
    // A burst of a quarter of the inbox: a flood never fills the inbox the links share.
    let mut budget = ReadBudget::new(ctx.max_frames_per_sec, ctx.queue_len / 4, Instant::now());
    let mut throttled = false;
    loop {
        let may_read = budget.ready(Instant::now());
        if !may_read && !throttled {
            throttled = true;
            bump(&ctx.stats.throttled);
            if let Some(more) = ctx.stats.log_admits("link throttled") {
                tracing::warn!(me = %ctx.me, %peer, per_s = ctx.max_frames_per_sec, more, "peer sends faster than the per-link limit; reading it more slowly");
            }
        }
        throttled &= !may_read;
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
            f = stream.next(), if may_read => match f {
                None => return Err(LinkError::Closed),
                Some(Err(e)) => return Err(LinkError::Io(e)),
                Some(Ok(frame)) => {
                    budget.spend();
                    silence.as_mut().reset(Instant::now() + ctx.liveness_timeout);
                    on_frame(ctx, peer, frame).await?;
                }
            },
            () = sleep_until(budget.next_at()), if !may_read => {}
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
                super::super::stats::add(&ctx.stats.bytes_sent, frame.len());
                sink.send(frame).await?;
                bump(&ctx.stats.heartbeats_sent);
            }
            // A throttled peer is not silent: its frames wait to be read.
            _ = &mut silence, if may_read => return Err(LinkError::Silent(ctx.liveness_timeout)),
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
mod tests {
    use super::*;

    #[test]
    fn the_read_budget_allows_its_rate_and_says_when_the_next_frame_may_be_read() {
        let t0 = Instant::now();
        let mut b = ReadBudget::new(10, 100, t0);
        for _ in 0..10 {
            assert!(b.ready(t0));
            b.spend();
        }
        assert!(!b.ready(t0));
        let next = b.next_at();
        assert!(
            next > t0 && next <= t0 + Duration::from_millis(101),
            "{:?}",
            next - t0
        );
        assert!(b.ready(t0 + Duration::from_millis(100)));
        // Reserve is capped at the burst (here one second's worth: never more).
        assert!(b.ready(t0 + Duration::from_secs(60)));
        for _ in 0..10 {
            b.spend();
        }
        assert!(!b.ready(t0 + Duration::from_secs(60)));
        let mut small = ReadBudget::new(1000, 2, t0);
        small.spend();
        small.spend();
        assert!(!small.ready(t0));
    }
}
