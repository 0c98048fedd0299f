//! `ocelli bench transport`: one-way latency over iceoryx2, plain TCP and mutual-TLS TCP
//! loopback through the real transport interface (the sender stamps the envelope with a monotonic clock just before
//! `Endpoint::send`, which encodes; the receiver reads the clock when the decoded message
//! leaves the inbox), at a fixed rate (30 Hz, a camera's frame rate) and at full rate, plus
//! encode/decode cost per message kind. Sender and receiver are two threads of this process,
//! each with its own current-thread tokio runtime, so they share one clock.

use super::wake;
use crate::error::OrFailed as _;
use crate::{LabError, Result};
use proto::msg::*;
use proto::node::Outgoing;
use proto::{ClusterTime, Envelope, NodeId, Role, decode, encode};
use runtime::transport::{ClusterCa, Event, IpcConfig, Security, TcpConfig, Tls, TransportConfig, open};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// What to measure and how long.
#[derive(Clone, Debug)]
pub struct Options {
    /// Messages in the fixed-rate phase.
    pub rate_messages: usize,
    /// Rate of the fixed-rate phase, Hz.
    pub rate_hz: f64,
    /// Messages in the full-rate phase.
    pub burst_messages: usize,
    /// Iterations per message kind for encode/decode costs.
    pub codec_iterations: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            rate_messages: 300,
            rate_hz: 30.0,
            burst_messages: 20_000,
            codec_iterations: 20_000,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Ipc,
    Tcp,
    /// TCP with mutual TLS, as between hosts.
    Tls,
}

/// Node `id`'s TCP settings for `kind`: its certificate from `ca` for TLS, plain otherwise; no
/// per-link read limit (the bench measures the transport's cost, not its flood protection).
fn tcp_config(kind: Kind, ca: &ClusterCa, id: u32, role: Role) -> Result<TcpConfig> {
    let security = match kind {
        Kind::Tls => Security::Tls(Tls::from_pem(ca.cert_pem(), &ca.issue(NodeId(id), role)?)?),
        _ => Security::Insecure,
    };
    let mut c = TcpConfig::new(NodeId(id), role, security);
    c.roster = Some(BTreeMap::from([
        (NodeId(1), Role::Head),
        (NodeId(2), Role::Camera),
    ]));
    c.max_frames_per_sec = u32::MAX;
    c.queue_len = 4096;
    Ok(c)
}

/// Result of one latency phase.
#[derive(Debug)]
struct Phase {
    sent: usize,
    received: usize,
    dropped: u64,
    latencies_ns: Vec<u64>,
    /// How long each measured `Endpoint::send` call took (stamp to return).
    send_call_ns: Vec<u64>,
    /// Time the sender took to offer every message.
    send_wall: Duration,
    /// From the first to the last measured message received.
    receive_span: Duration,
}

pub(super) fn percentile(sorted: &[u64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let idx = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[idx.min(sorted.len() - 1)] as f64 / 1000.0
}

impl Phase {
    fn to_json(&self) -> Value {
        let mut l = self.latencies_ns.clone();
        l.sort_unstable();
        let mean = if l.is_empty() {
            f64::NAN
        } else {
            l.iter().sum::<u64>() as f64 / l.len() as f64 / 1000.0
        };
        let mut c = self.send_call_ns.clone();
        c.sort_unstable();
        json!({
            "sent": self.sent,
            "send_call_p50_us": percentile(&c, 0.50),
            "send_call_p99_us": percentile(&c, 0.99),
            "received": self.received,
            "dropped": self.dropped,
            "p50_us": percentile(&l, 0.50),
            "p90_us": percentile(&l, 0.90),
            "p99_us": percentile(&l, 0.99),
            "max_us": percentile(&l, 1.0),
            "mean_us": mean,
            "offered_msgs_per_s": self.sent as f64 / self.send_wall.as_secs_f64(),
            "delivered_msgs_per_s": self.received.saturating_sub(1) as f64 / self.receive_span.as_secs_f64(),
        })
    }

    fn p99_us(&self) -> f64 {
        self.percentile_us(0.99)
    }

    fn percentile_us(&self, p: f64) -> f64 {
        let mut l = self.latencies_ns.clone();
        l.sort_unstable();
        percentile(&l, p)
    }
}

const WARMUP: usize = 50;

/// The measurement the latency phases send: a camera's detection with its tag readings
/// (the wire contract's fixture), numbered by `step`.
fn measurement(step: u64) -> Message {
    let mut m = proto::examples::messages()[3].body.clone();
    if let Message::Measurement(x) = &mut m {
        x.step = step;
    }
    m
}

fn now_ns(base: Instant) -> i64 {
    base.elapsed().as_nanos() as i64
}

/// Run one phase: `count` measured messages, `interval` apart (`None`: back to back).
fn phase(kind: Kind, count: usize, interval: Option<Duration>, tag: &str) -> Result<Phase> {
    #[allow(clippy::disallowed_methods)] // a benchmark runtime owns its clock
    let base = Instant::now();
    let ca = std::sync::Arc::new(ClusterCa::generate("bench")?);
    let receiver_ca = ca.clone();
    let domain = format!("bench-{}-{tag}", std::process::id());
    let (addr_tx, addr_rx) = std::sync::mpsc::channel();
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let receiver_domain = domain.clone();
    let receiver = std::thread::spawn(move || -> Result<(Vec<u64>, usize, u64, Duration)> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        rt.block_on(async move {
            let cfg = match kind {
                Kind::Ipc => TransportConfig::Ipc(IpcConfig::new(receiver_domain, NodeId(1), Role::Head, 2)),
                Kind::Tcp | Kind::Tls => {
                    let mut c = tcp_config(kind, &receiver_ca, 1, Role::Head)?;
                    c.listen = Some(std::net::SocketAddr::from(([127, 0, 0, 1], 0)));
                    TransportConfig::Tcp(c)
                }
            };
            let (ep, mut inbox, rstats, shutdown) = open(cfg).await?;
            addr_tx
                .send(ep.local_addr())
                .map_err(|_| LabError::failed("transport bench", "sender gone"))?;
            let mut lat = Vec::with_capacity(count);
            let mut received = 0;
            let (mut first, mut last) = (None, 0i64);
            loop {
                let idle = if done_rx.try_recv().is_ok() {
                    Duration::from_millis(500)
                } else {
                    Duration::from_secs(10)
                };
                let ev = match tokio::time::timeout(idle, inbox.recv()).await {
                    Ok(Some(ev)) => ev,
                    Ok(None) | Err(_) => break,
                };
                if let Event::Message(m) = ev {
                    let t = now_ns(base);
                    if let Message::Measurement(meas) = &m.env.body
                        && meas.step == 1
                    {
                        lat.push((t - m.env.time.0).max(0) as u64);
                        first.get_or_insert(t);
                        last = t;
                        received += 1;
                        if received == count {
                            break;
                        }
                    }
                }
            }
            shutdown.shutdown().await;
            let span = Duration::from_nanos((last - first.unwrap_or(last)).max(0) as u64);
            Ok((lat, received, rstats.snapshot().dropped_inbox_full, span))
        })
    });
    let addr = addr_rx
        .recv_timeout(Duration::from_secs(10))
        .map_err(|_| LabError::failed("transport bench", "receiver did not start"))?;
    let sender = std::thread::spawn(move || -> Result<(usize, u64, Duration, Vec<u64>)> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        rt.block_on(async move {
            let cfg = match kind {
                Kind::Ipc => TransportConfig::Ipc(IpcConfig::new(domain, NodeId(2), Role::Camera, 2)),
                Kind::Tcp | Kind::Tls => {
                    let mut c = tcp_config(kind, &ca, 2, Role::Camera)?;
                    c.peers.insert(
                        NodeId(1),
                        addr.ok_or_else(|| LabError::failed("transport bench", "no listen address"))?,
                    );
                    TransportConfig::Tcp(c)
                }
            };
            let (ep, mut inbox, stats, shutdown) = open(cfg).await?;
            if kind != Kind::Ipc {
                loop {
                    match tokio::time::timeout(Duration::from_secs(10), inbox.recv()).await {
                        Ok(Some(Event::PeerUp(_))) => break,
                        Ok(Some(_)) => {}
                        _ => return Err(LabError::failed("transport bench", "tcp link did not come up")),
                    }
                }
            }
            for _ in 0..WARMUP {
                ep.send(
                    Outgoing::new(NodeId(1), measurement(0)),
                    ClusterTime(now_ns(base)),
                )
                .await?;
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
            let dropped_of =
                |s: runtime::transport::StatsSnapshot| s.dropped_queue_full + s.dropped_undelivered;
            let dropped_before = dropped_of(stats.snapshot());
            #[allow(clippy::disallowed_methods)] // a benchmark runtime owns its clock
            let start = Instant::now();
            let mut next = tokio::time::Instant::now();
            let mut calls = Vec::with_capacity(count);
            for _ in 0..count {
                if let Some(iv) = interval {
                    next += iv;
                    tokio::time::sleep_until(next).await;
                }
                let stamp = now_ns(base);
                ep.send(Outgoing::new(NodeId(1), measurement(1)), ClusterTime(stamp))
                    .await?;
                calls.push((now_ns(base) - stamp).max(0) as u64);
            }
            let wall = start.elapsed();
            // Let the link drain before stopping it.
            tokio::time::sleep(Duration::from_millis(200)).await;
            let dropped = dropped_of(stats.snapshot()) - dropped_before;
            shutdown.shutdown().await;
            Ok((count, dropped, wall, calls))
        })
    });
    let (sent, dropped, wall, send_call_ns) = sender
        .join()
        .map_err(|_| LabError::failed("transport bench", "sender panicked"))??;
    let _ = done_tx.send(());
    let (latencies_ns, received, dropped_inbox, span) = receiver
        .join()
        .map_err(|_| LabError::failed("transport bench", "receiver panicked"))??;
    Ok(Phase {
        sent,
        received,
        dropped: dropped + dropped_inbox,
        latencies_ns,
        send_call_ns,
        send_wall: wall,
        receive_span: span,
    })
}

/// One message of every kind (the wire contract's fixtures).
fn samples() -> Vec<Message> {
    proto::examples::messages().into_iter().map(|e| e.body).collect()
}

fn codec_costs(iterations: usize) -> Result<Vec<Value>> {
    let mut out = Vec::new();
    for body in samples() {
        let kind = body.kind();
        let env = Envelope {
            source: NodeId(7),
            seq: 1234,
            time: ClusterTime(987_654_321),
            body,
        };
        let frame = encode(&env).or_failed(format!("encoding {kind}"))?;
        #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
        let t = Instant::now();
        let mut bytes = 0usize;
        for _ in 0..iterations {
            bytes += std::hint::black_box(encode(std::hint::black_box(&env))?).len();
        }
        let encode_ns = t.elapsed().as_nanos() as f64 / iterations as f64;
        #[allow(clippy::disallowed_methods)] // a benchmark owns its clock
        let t = Instant::now();
        for _ in 0..iterations {
            std::hint::black_box(decode(std::hint::black_box(&frame))?);
        }
        let decode_ns = t.elapsed().as_nanos() as f64 / iterations as f64;
        std::hint::black_box(bytes);
        out.push(json!({"kind": kind, "bytes": frame.len(), "encode_ns": encode_ns, "decode_ns": decode_ns}));
    }
    Ok(out)
}

/// Run the benchmark; its figures as JSON.
///
/// # Errors
/// A part of the system under test could not be set up.
pub fn run(args: &Options) -> Result<serde_json::Value> {
    let interval = Duration::from_secs_f64(1.0 / args.rate_hz.max(0.1));
    let codec = codec_costs(args.codec_iterations.max(1))?;
    let baseline = wake::thread(args.rate_messages, interval);
    let tokio_baseline = wake::tokio(args.rate_messages, interval)?;
    let socket_baseline = wake::socket(args.rate_messages, interval)?;
    let iceoryx2_baseline = wake::iceoryx2(args.rate_messages, interval)?;
    let mut transports = serde_json::Map::new();
    let mut p99 = serde_json::Map::new();
    let mut tls_cost = serde_json::Map::new();
    for (kind, name) in [(Kind::Ipc, "ipc"), (Kind::Tcp, "tcp"), (Kind::Tls, "tls")] {
        let rate = phase(kind, args.rate_messages, Some(interval), "rate")?;
        let full = phase(kind, args.burst_messages, None, "full")?;
        p99.insert(format!("{name}_p99_us"), json!(rate.p99_us()));
        if kind != Kind::Ipc {
            for (phase_name, ph) in [("fixed_rate", &rate), ("full_rate", &full)] {
                tls_cost.insert(
                    format!("{phase_name}_{name}_p50_us"),
                    json!(ph.percentile_us(0.5)),
                );
                tls_cost.insert(
                    format!("{phase_name}_{name}_p99_us"),
                    json!(ph.percentile_us(0.99)),
                );
            }
        }
        transports.insert(
            name.into(),
            json!({"fixed_rate": rate.to_json(), "full_rate": full.to_json()}),
        );
    }
    // The issue's yardstick: the iceoryx2 transport's p99 over each floor's, in this run.
    let ipc_p99 = p99.get("ipc_p99_us").and_then(Value::as_f64).unwrap_or(f64::NAN);
    let over = |floor: &Value| ipc_p99 / floor["p99_us"].as_f64().unwrap_or(f64::NAN);
    let ipc_p99_over = json!({
        "thread_wake": over(&baseline),
        "tokio_wake": over(&tokio_baseline),
        "socket_wake": over(&socket_baseline),
        "iceoryx2": over(&iceoryx2_baseline),
    });
    let frame_bytes = encode(&Envelope {
        source: NodeId(2),
        seq: 0,
        time: ClusterTime(0),
        body: measurement(1),
    })?
    .len();
    let mut report = json!({
        "bench": "transport",
        "mode": "two threads in one process (sender, receiver), each with its own current-thread tokio runtime",
        "latency": "one-way, stamped before Endpoint::send (encode included), read after the decoded message leaves the Inbox",
        "message": "measurement",
        "frame_bytes": frame_bytes,
        "rate_hz": args.rate_hz,
        "p99_of": "fixed_rate phase",
        "full_rate": "measurements offered back to back; droppable, so beyond the queues they are dropped and counted (sender queue + receiver inbox); latency of those delivered",
        "hops": {
            "ipc": "sender task publishes (iceoryx2 thread-safe service) -> shared memory + event -> the receiver task, woken by the listener's descriptor in its own reactor, decodes",
            "tcp": "sender task -> link task (same runtime) -> loopback socket -> reader task (decode) -> receiver task (same runtime)",
            "tls": "as tcp, with TLS 1.3 (rustls, ring) encryption and decryption on each end; mutual certificates checked once, at connect"
        },
        "goals": {"ipc_p99_us": 20, "tcp_p99_us": 200},
        "transports": transports,
        "tls_cost": tls_cost,
        "codec": codec,
        "thread_wake_baseline": baseline,
        "tokio_wake_baseline": tokio_baseline,
        "socket_wake_baseline": socket_baseline,
        "ipc_p99_over": ipc_p99_over,
        "iceoryx2_baseline": iceoryx2_baseline,
    });
    if let Some(o) = report.as_object_mut() {
        for (k, v) in p99 {
            o.insert(k, v);
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_sample_encodes_and_decodes_back() {
        let s = samples();
        assert_eq!(
            s.len(),
            proto::wire::MESSAGE_KINDS.len(),
            "one sample per message kind"
        );
        for body in s {
            let env = Envelope {
                source: NodeId(1),
                seq: 0,
                time: ClusterTime(0),
                body,
            };
            assert_eq!(decode(&encode(&env).unwrap()).unwrap(), env);
        }
    }

    #[test]
    fn percentiles_pick_the_right_rank() {
        let v: Vec<u64> = (1..=100).map(|x| x * 1000).collect();
        assert_eq!(percentile(&v, 0.5), 51.0);
        assert_eq!(percentile(&v, 0.99), 99.0);
        assert_eq!(percentile(&v, 1.0), 100.0);
        assert!(percentile(&[], 0.5).is_nan());
    }
}
