//! Recordings for unit tests: a scenario and head reports written through the server's own
//! recorder, so tests read back what a real server writes.

use node_server::{Record, Recorder, Stamped};
use proto::msg::{Contributor, Kinds, Message, NodeStatus, ObservationKind, TrackReport};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, Mode, NodeId, TargetId};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};

pub const S: i64 = 1_000_000_000;

/// A fresh path under the system's temporary folder (removed by [`TempFile`]'s drop).
pub struct TempFile(pub PathBuf);

impl TempFile {
    pub fn new(name: &str) -> TempFile {
        static N: AtomicU32 = AtomicU32::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        TempFile(std::env::temp_dir().join(format!("ocelli-view-{}-{n}-{name}", std::process::id())))
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

pub fn report(head: u32, seq: u64, local: u32, t: i64, x: f64, y: f64) -> Stamped {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = if i < 3 { 0.02 } else { 0.1 };
    }
    Stamped::new(
        ClusterTime(t),
        Record::Received(Envelope {
            source: NodeId(head),
            seq,
            time: ClusterTime(t),
            body: Message::TrackReport(TrackReport {
                target: TargetId(local),
                global: None,
                step: seq,
                time: ClusterTime(t),
                mean: [x, y, 0.25, 0.5, 0.0, 0.0],
                cov,
                contributors: vec![Contributor {
                    node: NodeId(10),
                    kinds: Kinds::of(ObservationKind::Pinhole),
                }],
                power_mw: 700.0,
                late: 0,
                appearance: Vec::new(),
                grid: None,
                captured: None,
            }),
        }),
    )
}

pub fn status(node: u32, seq: u64, t: i64, mode: Mode) -> Stamped {
    Stamped::new(
        ClusterTime(t),
        Record::Received(Envelope {
            source: NodeId(node),
            seq,
            time: ClusterTime(t),
            body: Message::NodeStatus(NodeStatus {
                mode,
                time_in_mode_ns: [0; 3],
                frames: seq,
                detections: 0,
                dropped: 0,
                rejected: 0,
                sync_offset_ns: 0,
                sync_error_ns: 100_000,
                bytes_sent: 0,
            }),
        }),
    )
}

/// The records of a run: the default scenario, then `seconds` of head 2 reporting one target
/// walking +x at 0.5 m/s from (1, 2) at 5 Hz (the server's decisions are not written: a
/// replay makes them), and camera 10's status every second.
pub fn run_records(seconds: i64) -> Vec<Stamped> {
    let sc = Scenario::default_scenario();
    let mut out = vec![Stamped::new(ClusterTime(0), Record::Scenario(sc.to_toml()))];
    for i in 0..=seconds * 5 {
        let t = S + i * S / 5;
        let seq = u64::try_from(i).unwrap_or(0) + 1;
        out.push(report(2, seq, 1, t, 1.0 + 0.1 * i as f64, 2.0));
        if i % 5 == 0 {
            out.push(status(10, seq / 5 + 1, t, Mode::Active));
        }
    }
    out
}

/// Write records as a recording.
pub fn write(path: &std::path::Path, records: &[Stamped]) {
    let mut rec = Recorder::create(path, "default").expect("create a test recording");
    for r in records {
        rec.append(r).expect("append a test record");
    }
}

/// Records with the server's decisions, as a live server would have written them: the inputs
/// fed through a server core, its journal taken.
pub fn with_decisions(records: &[Stamped]) -> Vec<Stamped> {
    let sc = Scenario::default_scenario();
    let cfg = node_server::ServerConfig::from_scenario(sc, NodeId(1));
    let mut node = node_server::ServerNode::new(cfg);
    let mut out = Vec::new();
    for r in records {
        if node.feed(r) {
            out.extend(node.take_records());
        } else {
            out.push(r.clone());
        }
    }
    out
}
