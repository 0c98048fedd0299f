//! `ocelli bench server`: how fast the server core and its recording are, as JSON.
//!
//! Measures (build with `--release`):
//! - `track_report_us[T]`: one `ServerNode::on_message` for a track report plus draining its
//!   journal, with T live global tracks spread over two heads (T = 1, 10, 100);
//! - `tick_us`: one `ServerNode::tick` with every scenario node up and 100 tracks;
//! - `append_us`: one `Recorder::append` of a recorded track report (one `write(2)`), and
//!   `sync_ms`: one `sync_data` after 1000 appends;
//! - `restore_records_per_s`: `ServerNode::restore` over a recording of the T = 100 run.

use crate::Result;
use node_server::record::{Record, Stamped};
use node_server::recording::Recorder;
use node_server::{ServerConfig, ServerNode};
use proto::msg::{Contributor, Message, TrackReport};
use proto::observation::{Kinds, ObservationKind};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, NodeId, TargetId};
use serde_json::json;
use std::time::Instant;

/// What to measure and how long.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scale the repetition counts (1.0 = default).
    pub scale: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options { scale: 1.0 }
    }
}

fn scenario() -> Scenario {
    Scenario::default_scenario()
}

/// A report from `head` of local track `k` at step `step`: targets on a grid, each inside its
/// head's region, moving slowly.
fn report(head: u32, k: u32, step: u64) -> Envelope {
    let t = ClusterTime::from_millis(step as i64 * 200);
    let x0 = if head == 2 { 0.5 } else { 6.5 };
    let x = x0 + 0.5 * (k % 10) as f64 + 0.001 * step as f64;
    let y = 0.5 + 0.7 * (k / 10 % 10) as f64;
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.02;
    }
    Envelope {
        source: NodeId(head),
        seq: step,
        time: t,
        body: Message::TrackReport(TrackReport {
            target: TargetId(k),
            global: None,
            step,
            time: t,
            mean: [x, y, 0.9, 0.005, 0.0, 0.0],
            cov,
            contributors: (10..14)
                .map(|n| Contributor {
                    node: NodeId(n),
                    kinds: if n % 2 == 0 {
                        Kinds::of(ObservationKind::Pinhole).union(Kinds::of(ObservationKind::Rssi))
                    } else {
                        Kinds::of(ObservationKind::Rssi)
                    },
                })
                .collect(),
            power_mw: 2000.0,
            late: 0,
            appearance: Vec::new(),
            grid: None,
            captured: Some(t),
        }),
    }
}

fn median_us(samples: &mut [f64]) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples.get(samples.len() / 2).copied().unwrap_or(0.0)
}

#[allow(clippy::disallowed_methods)] // a bench owns its clock
/// Run the benchmark; its figures as JSON.
///
/// # Errors
/// A part of the system under test could not be set up.
pub fn run(args: &Options) -> Result<serde_json::Value> {
    let steps = ((200.0 * args.scale) as u64).max(5);
    let sc = scenario();
    let server_id = NodeId(sc.server().map_or(1, |s| s.id));
    let mut per_report = serde_json::Map::new();
    let mut last_records = Vec::new();
    let mut tick_us = 0.0;
    for tracks in [1u32, 10, 100] {
        let mut node = ServerNode::new(ServerConfig::from_scenario(sc.clone(), server_id));
        let mut records = Vec::new();
        let mut samples = Vec::new();
        for step in 0..steps {
            for k in 0..tracks {
                let head = if k % 2 == 0 { 2 } else { 3 };
                let env = report(head, k / 2, step);
                let now = env.time;
                let start = Instant::now();
                let out = node.on_message(now, env);
                let recs = node.take_records();
                samples.push(start.elapsed().as_secs_f64() * 1e6);
                std::hint::black_box(out);
                records.extend(recs);
            }
            let now = ClusterTime::from_millis(step as i64 * 200 + 100);
            let start = Instant::now();
            let out = node.tick(now);
            let recs = node.take_records();
            if tracks == 100 {
                tick_us += start.elapsed().as_secs_f64() * 1e6 / steps as f64;
            }
            std::hint::black_box(out);
            records.extend(recs);
        }
        per_report.insert(tracks.to_string(), json!(median_us(&mut samples)));
        if tracks == 100 {
            last_records = records;
        }
    }

    // Recording: append and sync on a real file.
    let dir = std::env::temp_dir().join(format!("ocelli-bench-server-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let path = dir.join("bench.ocelli");
    let _ = std::fs::remove_file(&path);
    let mut rec = Recorder::create(&path, &sc.name)?;
    let sample = Stamped::new(ClusterTime(1), Record::Received(report(2, 1, 1)));
    let n = ((5000.0 * args.scale) as usize).max(100);
    let mut append = Vec::with_capacity(n);
    let mut sync = Vec::new();
    for i in 0..n {
        let start = Instant::now();
        rec.append(&sample)?;
        append.push(start.elapsed().as_secs_f64() * 1e6);
        if i % 1000 == 999 {
            let start = Instant::now();
            rec.sync()?;
            sync.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let bytes_per_record = rec.bytes() as f64 / n as f64;
    let _ = std::fs::remove_dir_all(&dir);

    let start = Instant::now();
    let (_, stats) = ServerNode::restore(ServerConfig::from_scenario(sc.clone(), server_id), &last_records);
    let restore_s = start.elapsed().as_secs_f64();

    let out = json!({
        "bench": "server",
        "steps": steps,
        "track_report_us": per_report,
        "tick_us": tick_us,
        "append_us": median_us(&mut append),
        "bytes_per_record": bytes_per_record,
        "sync_ms": median_us(&mut sync),
        "restore_records": last_records.len(),
        "restore_records_per_s": last_records.len() as f64 / restore_s.max(1e-9),
        "restore_decisions_mismatched": stats.decisions_mismatched,
    });
    Ok(out)
}
