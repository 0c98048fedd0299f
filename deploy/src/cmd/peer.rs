//! `ocelli peer` (hidden): one transport endpoint as its own process, for integration tests
//! and probes. It prints one JSON object per line on stdout — `ready`, every received
//! message and liveness change, counter snapshots, `sent`, `stopped` — so a test can assert
//! on what really crossed the process boundary.
//!
//! Messages it sends are `SyncBeacon { leader: me, round: k }` (never droppable), so `round`
//! proves order and completeness. `--inject-garbage` first sends a malformed, an oversized and
//! a wrong-version raw frame to prove the receiver rejects them and keeps going.

use anyhow::{Context, Result, bail};
use proto::msg::{Message, SyncBeacon};
use proto::node::Outgoing;
use proto::{ClusterTime, MAX_FRAME_BYTES, NodeId, Role};
use runtime::transport::{
    Event, IpcConfig, IpcLimits, Security, StatsSnapshot, TcpConfig, Tls, TransportConfig, TransportStats,
    open,
};
use serde_json::json;
use std::collections::BTreeMap;
use std::io::Write;
use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Ipc,
    Tcp,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    #[arg(long, value_enum)]
    pub transport: Kind,
    /// This node's id.
    #[arg(long)]
    pub id: u32,
    /// iceoryx2 domain (service and file prefix).
    #[arg(long, default_value = "ocelli")]
    pub domain: String,
    /// Nodes the iceoryx2 limits are sized for.
    #[arg(long, default_value_t = 4)]
    pub nodes: usize,
    /// TCP: listen here (port 0 picks one; the `ready` line tells which).
    #[arg(long)]
    pub listen: Option<SocketAddr>,
    /// TCP: dial this peer, `ID=ADDR`; repeatable.
    #[arg(long = "peer", value_parser = parse_peer)]
    pub peers: Vec<(u32, SocketAddr)>,
    /// Send `--send` beacons to this node.
    #[arg(long)]
    pub to: Option<u32>,
    /// How many beacons to send.
    #[arg(long, default_value_t = 0)]
    pub send: u64,
    /// Pause between beacons.
    #[arg(long, default_value_t = 0)]
    pub interval_ms: u64,
    /// Before the beacons, send a malformed, an oversized and a wrong-version raw frame.
    #[arg(long)]
    pub inject_garbage: bool,
    /// Answer every received message to its sender.
    #[arg(long)]
    pub echo: bool,
    /// Stop this long after the last beacon was sent (0: run until SIGTERM/SIGINT).
    #[arg(long, default_value_t = 0)]
    pub linger_ms: u64,
    /// Heartbeat period and liveness timeout (TCP), ms.
    #[arg(long, default_value_t = 100)]
    pub heartbeat_ms: u64,
    #[arg(long, default_value_t = 500)]
    pub liveness_ms: u64,
    /// TCP: mutual TLS with this directory's `ca.pem`, `node-<ID>.pem`, `node-<ID>.key`
    /// (certificates of tools, `n<ID>.tool.ocelli`).
    #[arg(long)]
    pub tls_dir: Option<std::path::PathBuf>,
    /// TCP: plain, no TLS.
    #[arg(long)]
    pub insecure: bool,
}

fn parse_peer(s: &str) -> Result<(u32, SocketAddr), String> {
    let (id, addr) = s
        .split_once('=')
        .ok_or_else(|| format!("expected ID=ADDR, got {s:?}"))?;
    let id = id.parse().map_err(|e| format!("bad node id {id:?}: {e}"))?;
    let addr = addr.parse().map_err(|e| format!("bad address {addr:?}: {e}"))?;
    Ok((id, addr))
}

fn line(v: serde_json::Value) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{v}");
    let _ = out.flush();
}

fn stats_line(s: &StatsSnapshot) {
    let mut v = serde_json::to_value(s).unwrap_or_default();
    if let Some(o) = v.as_object_mut() {
        o.insert("event".into(), json!("stats"));
    }
    line(v);
}

pub fn run(args: Args) -> Result<ExitCode> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("tokio runtime")?;
    rt.block_on(run_async(args))
}

fn config(args: &Args) -> Result<TransportConfig> {
    let me = NodeId(args.id);
    Ok(match args.transport {
        Kind::Ipc => {
            let mut c = IpcConfig::new(args.domain.clone(), me, Role::Tool, args.nodes);
            c.limits = IpcLimits::for_nodes(args.nodes, c.queue_len);
            TransportConfig::Ipc(c)
        }
        Kind::Tcp => {
            let security = match (&args.tls_dir, args.insecure) {
                (Some(dir), _) => Security::Tls(Tls::load(dir, me)?),
                (None, true) => Security::Insecure,
                (None, false) => bail!("tcp needs --tls-dir DIR or --insecure"),
            };
            let mut c = TcpConfig::new(me, Role::Tool, security);
            c.listen = args.listen;
            c.peers = args
                .peers
                .iter()
                .map(|&(id, a)| (NodeId(id), a))
                .collect::<BTreeMap<_, _>>();
            c.heartbeat = Duration::from_millis(args.heartbeat_ms);
            c.liveness_timeout = Duration::from_millis(args.liveness_ms);
            if c.listen.is_none() && c.peers.is_empty() {
                bail!("tcp needs --listen or --peer");
            }
            TransportConfig::Tcp(c)
        }
    })
}

fn beacon(me: NodeId, round: u64) -> Message {
    Message::SyncBeacon(SyncBeacon {
        leader: me,
        round,
        leader_time: ClusterTime(0),
    })
}

async fn run_async(args: Args) -> Result<ExitCode> {
    let me = NodeId(args.id);
    let (endpoint, mut inbox, stats, shutdown) =
        open(config(&args)?).await.context("opening the transport")?;
    line(json!({
        "event": "ready",
        "id": args.id,
        "pid": std::process::id(),
        "listen": endpoint.local_addr().map(|a| a.to_string()),
    }));

    let (done_tx, mut done_rx) = tokio::sync::mpsc::channel::<()>(1);
    if let Some(to) = args.to {
        let ep = endpoint.clone();
        let (count, interval, garbage) = (args.send, args.interval_ms, args.inject_garbage);
        tokio::spawn(async move {
            let to = NodeId(to);
            if garbage {
                let frames = [
                    vec![proto::PROTOCOL_VERSION as u8, 0xff, 0xff, 0xff],
                    vec![0u8; MAX_FRAME_BYTES + 1],
                    vec![9u8, 0],
                ];
                for f in frames {
                    if let Err(e) = ep.send_raw_frame(to, f).await {
                        tracing::warn!(error = %e, "could not inject a raw frame");
                    }
                }
                line(json!({"event": "injected", "frames": 3}));
            }
            let mut sent = 0u64;
            for k in 0..count {
                match ep.send(Outgoing::new(to, beacon(me, k)), ClusterTime(0)).await {
                    Ok(_) => sent += 1,
                    Err(e) => tracing::warn!(error = %e, round = k, "send failed"),
                }
                if interval > 0 {
                    tokio::time::sleep(Duration::from_millis(interval)).await;
                }
            }
            line(json!({"event": "sent", "count": sent}));
            let _ = done_tx.send(()).await;
        });
    } else {
        drop(done_tx);
    }

    let linger = (args.linger_ms > 0).then(|| Duration::from_millis(args.linger_ms));
    let mut ticker = tokio::time::interval(Duration::from_millis(100));
    let mut last = StatsSnapshot::default();
    let mut sending = args.to.is_some();
    let stop_at = tokio::time::sleep(Duration::MAX / 4);
    tokio::pin!(stop_at);
    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
        .context("installing the SIGTERM handler")?;
    loop {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => break,
            _ = term.recv() => break,
            _ = &mut stop_at => break,
            d = done_rx.recv(), if sending => {
                sending = false;
                if let (Some(()), Some(l)) = (d, linger) {
                    stop_at.as_mut().reset(tokio::time::Instant::now() + l);
                }
            }
            _ = ticker.tick() => report_if_changed(&stats, &mut last),
            ev = inbox.recv() => match ev {
                None => break,
                Some(Event::PeerUp(n)) => line(json!({"event": "peer_up", "node": n.0})),
                Some(Event::PeerDown(n)) => line(json!({"event": "peer_down", "node": n.0})),
                Some(Event::Message(m)) => {
                    let round = match &m.env.body {
                        Message::SyncBeacon(b) => Some(b.round),
                        _ => None,
                    };
                    line(json!({
                        "event": "message",
                        "from": m.from.0,
                        "seq": m.env.seq,
                        "kind": m.env.body.kind(),
                        "round": round,
                    }));
                    if args.echo
                        && let Err(e) = endpoint.send(Outgoing::new(m.from, m.env.body), m.env.time).await
                    {
                        tracing::warn!(error = %e, "echo failed");
                    }
                    report_if_changed(&stats, &mut last);
                }
            },
        }
    }
    shutdown.shutdown().await;
    stats_line(&stats.snapshot());
    line(json!({"event": "stopped"}));
    Ok(ExitCode::SUCCESS)
}

fn report_if_changed(stats: &Arc<TransportStats>, last: &mut StatsSnapshot) {
    let now = stats.snapshot();
    if now != *last {
        stats_line(&now);
        *last = now;
    }
}
