//! The run report: accuracy against ground truth, sensors used, energy, messages and sync,
//! computed from a recording and its scenario (paper 002 Table I's columns).
//!
//! Definitions:
//! - **Error**: per owner track sample (see [`crate::export`]), the 3-D distance between the
//!   estimated position and the true position of the target the global track is associated with
//!   at the report's time (`t − t0`). A global track is associated with the true target it is
//!   nearest to on average over its samples, if that mean distance is within
//!   [`ASSOCIATION_GATE_M`]; otherwise it is a *false track* (clutter, a ghost), counted in
//!   `false_tracks` / `false_track_samples` and not in the error. Ground truth is only read
//!   here, never by a filter.
//! - **Active cameras / RSSI nodes per step**: contributors with a camera measurement / with an
//!   RSSI reading, per owner track report.
//! - **Energy per node**: from the latest `NodeStatus.time_in_mode_ns` with the node's power
//!   figures; heads (or runs) without statuses fall back to `TrackReport.power_mw` × step time.
//!   `power_mw_mean` is the sum over nodes of their mean power.
//! - **Messages**: `sent` = frames nodes sent to the server (received + sequence gaps) plus
//!   frames the server sent; `dropped` = sequence gaps into the server plus the `dropped`
//!   counters nodes report; `late` = contributions past their deadline as the heads report them;
//!   `rejected` = inputs the server refused.
//! - **Sync error**: the `sync_error_ns` each node reports (its regression residual).

use crate::core::{ServerConfig, ServerNode};
use crate::decision::Decision;
use crate::export::track_rows;
use crate::record::Record;
use crate::replay::Loaded;
use proto::msg::{Message, NodeStatus};
use proto::{ClusterTime, Mode, NodeId};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// A global track whose mean distance to every true target exceeds this is a false track, m.
pub const ASSOCIATION_GATE_M: f64 = 2.0;

/// Error statistics of one true target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetError {
    pub target: u32,
    pub samples: u64,
    pub mean_error_m: f64,
    pub error_std_m: f64,
    pub rmse_m: f64,
    /// Global ids associated with this target (more than one means the id changed).
    pub globals: Vec<u32>,
}

/// Energy of one node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeEnergy {
    pub node: u32,
    pub energy_j: f64,
    pub mean_power_mw: f64,
    pub seconds: f64,
    /// `node_status` or `track_report`.
    pub source: &'static str,
}

/// Message accounting.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Messages {
    pub sent: u64,
    pub dropped: u64,
    pub late: u64,
    pub rejected: u64,
}

/// Sync error of one node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeSync {
    pub node: u32,
    pub error_ms: f64,
    pub offset_ms: f64,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    pub scenario: String,
    pub duration_s: f64,
    pub steps: u64,
    pub truth: bool,
    pub mean_error_m: Option<f64>,
    pub error_std_m: Option<f64>,
    pub rmse_m: Option<f64>,
    pub targets: Vec<TargetError>,
    /// Global tracks associated with no true target, and their owner samples.
    pub false_tracks: u64,
    pub false_track_samples: u64,
    pub active_cameras_mean: f64,
    pub rssi_nodes_mean: f64,
    pub power_mw_mean: f64,
    pub energy: Vec<NodeEnergy>,
    pub messages: Messages,
    pub sync_error_ms_mean: Option<f64>,
    pub sync_error_ms_max: Option<f64>,
    pub sync: Vec<NodeSync>,
    pub handovers: u64,
    pub global_ids: u64,
    /// Bytes skipped at a torn tail of the recording.
    pub torn_tail_bytes: u64,
}

fn mean_std(xs: &[f64]) -> (f64, f64, f64) {
    if xs.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let rmse = (xs.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
    (mean, var.sqrt(), rmse)
}

fn status_energy(s: &NodeStatus, power: &proto::scenario::PowerFigures) -> (f64, f64) {
    let mut energy_mj = 0.0;
    let mut secs = 0.0;
    for m in Mode::ALL {
        let t = s.time_in_mode_ns[m.index()] as f64 * 1e-9;
        secs += t;
        energy_mj += t * power.in_mode(m);
    }
    (energy_mj * 1e-3, secs)
}

/// Compute the report with the default association gate; `t0` is the cluster time at which
/// the scenario's trajectories start.
pub fn compute(loaded: &Loaded, t0: ClusterTime) -> Report {
    compute_with(loaded, t0, ASSOCIATION_GATE_M)
}

/// Compute the report with an association gate (m).
pub fn compute_with(loaded: &Loaded, t0: ClusterTime, gate_m: f64) -> Report {
    let sc = &loaded.scenario;
    let rows: Vec<_> = track_rows(loaded).into_iter().filter(|r| r.owner).collect();
    let truth = !sc.targets.is_empty();
    let true_pos = |target: usize, t: f64| {
        let s = sc.targets[target].truth_at(t - t0.as_secs_f64());
        [s[0], s[1], s[2]]
    };
    let d3 = |a: [f64; 3], r: &crate::export::TrackRow| {
        ((a[0] - r.x).powi(2) + (a[1] - r.y).powi(2) + (a[2] - r.z).powi(2)).sqrt()
    };
    // Associate each global with its nearest true target on average.
    let mut by_global: BTreeMap<u32, Vec<&crate::export::TrackRow>> = BTreeMap::new();
    for r in &rows {
        by_global.entry(r.global).or_default().push(r);
    }
    let mut per_target: BTreeMap<usize, (Vec<f64>, Vec<u32>)> = BTreeMap::new();
    let (mut false_tracks, mut false_samples) = (0u64, 0u64);
    if truth {
        for (g, rs) in &by_global {
            let best = (0..sc.targets.len())
                .map(|k| {
                    let d: f64 = rs.iter().map(|r| d3(true_pos(k, r.t), r)).sum();
                    (k, d / rs.len() as f64)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((k, mean_d)) = best {
                if mean_d > gate_m {
                    false_tracks += 1;
                    false_samples += rs.len() as u64;
                    continue;
                }
                let e = per_target.entry(k).or_default();
                e.0.extend(rs.iter().map(|r| d3(true_pos(k, r.t), r)));
                e.1.push(*g);
            }
        }
    }
    let all: Vec<f64> = per_target.values().flat_map(|(e, _)| e.iter().copied()).collect();
    let (mean, std, rmse) = mean_std(&all);
    let targets = per_target
        .iter()
        .map(|(k, (e, gs))| {
            let (m, s, r) = mean_std(e);
            TargetError {
                target: sc.targets[*k].id,
                samples: e.len() as u64,
                mean_error_m: m,
                error_std_m: s,
                rmse_m: r,
                globals: gs.clone(),
            }
        })
        .collect();

    // Sensors per step, messages, statuses, power fallback.
    let (mut cams, mut rssi, mut steps) = (0u64, 0u64, 0u64);
    let mut status: BTreeMap<NodeId, NodeStatus> = BTreeMap::new();
    let mut late: BTreeMap<NodeId, u64> = BTreeMap::new();
    let mut head_power: BTreeMap<NodeId, (f64, u64)> = BTreeMap::new();
    let mut last_seq: BTreeMap<NodeId, u64> = BTreeMap::new();
    let mut msgs = Messages::default();
    let (mut handovers, mut globals) = (0u64, 0u64);
    for s in &loaded.records {
        match &s.record {
            Record::Received(env) => {
                msgs.sent += 1;
                if let Some(prev) = last_seq.insert(env.source, env.seq)
                    && env.seq > prev
                {
                    let gap = env.seq - prev - 1;
                    msgs.sent += gap;
                    msgs.dropped += gap;
                }
                match &env.body {
                    Message::NodeStatus(st) => {
                        status.insert(env.source, st.clone());
                    }
                    Message::TrackReport(r) => {
                        late.insert(env.source, r.late);
                        let e = head_power.entry(env.source).or_default();
                        e.0 += r.power_mw;
                        e.1 += 1;
                    }
                    _ => {}
                }
            }
            Record::Sent { .. } => msgs.sent += 1,
            _ => {}
        }
    }
    // Decisions as this build's server makes them from the recorded inputs (the same replay
    // the track rows come from; for a recording made by this build they equal the recorded
    // ones).
    let mut node = ServerNode::new(ServerConfig::from_scenario(sc.clone(), loaded.server_id()));
    for s in &loaded.records {
        node.feed(s);
        for r in node.take_records() {
            if let Record::Decision(d) = r.record {
                match d {
                    Decision::Rejected { .. } | Decision::Refused { .. } => msgs.rejected += 1,
                    Decision::Handover { .. } => handovers += 1,
                    Decision::NewGlobal { .. } | Decision::Split { .. } => globals += 1,
                    _ => {}
                }
            }
        }
    }
    for r in &rows {
        steps += 1;
        cams += u64::from(r.cameras);
        rssi += u64::from(r.rssi_nodes);
    }
    msgs.late = late.values().sum();
    msgs.dropped += status.values().map(|s| s.dropped).sum::<u64>();

    let step_s = sc.method.step_ms as f64 * 1e-3;
    let mut energy = Vec::new();
    for (node, st) in &status {
        let (e, secs) = status_energy(st, &sc.power_of(node.0));
        energy.push(NodeEnergy {
            node: node.0,
            energy_j: e,
            mean_power_mw: if secs > 0.0 { e * 1e3 / secs } else { 0.0 },
            seconds: secs,
            source: "node_status",
        });
    }
    if status.is_empty() {
        for (head, (sum_mw, n)) in &head_power {
            let secs = *n as f64 * step_s;
            energy.push(NodeEnergy {
                node: head.0,
                energy_j: sum_mw * step_s * 1e-3,
                mean_power_mw: sum_mw / *n as f64,
                seconds: secs,
                source: "track_report",
            });
        }
    }
    // (An empty f64 sum is −0.0; add +0.0 so an idle run prints 0.)
    let power_mw_mean = energy.iter().map(|e| e.mean_power_mw).sum::<f64>() + 0.0;

    let sync: Vec<NodeSync> = status
        .iter()
        .filter(|(_, s)| s.sync_error_ns >= 0)
        .map(|(n, s)| NodeSync {
            node: n.0,
            error_ms: s.sync_error_ns as f64 * 1e-6,
            offset_ms: s.sync_offset_ns as f64 * 1e-6,
        })
        .collect();
    let sync_errs: Vec<f64> = sync.iter().map(|s| s.error_ms).collect();
    let duration_s = match (loaded.records.first(), loaded.records.last()) {
        (Some(a), Some(b)) => b.at.secs_since(a.at),
        _ => 0.0,
    };
    let per_step = |x: u64| if steps > 0 { x as f64 / steps as f64 } else { 0.0 };
    Report {
        scenario: sc.name.clone(),
        duration_s,
        steps,
        truth,
        mean_error_m: (!all.is_empty()).then_some(mean),
        error_std_m: (!all.is_empty()).then_some(std),
        rmse_m: (!all.is_empty()).then_some(rmse),
        targets,
        false_tracks,
        false_track_samples: false_samples,
        active_cameras_mean: per_step(cams),
        rssi_nodes_mean: per_step(rssi),
        power_mw_mean,
        energy,
        messages: msgs,
        sync_error_ms_mean: (!sync_errs.is_empty())
            .then(|| sync_errs.iter().sum::<f64>() / sync_errs.len() as f64),
        sync_error_ms_max: sync_errs.iter().copied().reduce(f64::max),
        sync,
        handovers,
        global_ids: globals,
        torn_tail_bytes: loaded.tail.as_ref().map_or(0, |t| t.skipped_bytes),
    }
}

impl Report {
    /// A human-readable table.
    pub fn to_table(&self) -> String {
        let mut s = String::new();
        let opt = |v: Option<f64>, unit: &str| v.map_or("–".to_string(), |v| format!("{v:.3} {unit}"));
        let _ = writeln!(s, "scenario        {}", self.scenario);
        let _ = writeln!(
            s,
            "duration        {:.1} s, {} steps",
            self.duration_s, self.steps
        );
        let _ = writeln!(s, "mean error      {}", opt(self.mean_error_m, "m"));
        let _ = writeln!(s, "error std       {}", opt(self.error_std_m, "m"));
        let _ = writeln!(s, "rmse            {}", opt(self.rmse_m, "m"));
        if self.truth {
            let _ = writeln!(
                s,
                "false tracks    {} ({} samples)",
                self.false_tracks, self.false_track_samples
            );
        }
        let _ = writeln!(s, "active cameras  {:.2} per step", self.active_cameras_mean);
        let _ = writeln!(s, "rssi nodes      {:.2} per step", self.rssi_nodes_mean);
        let _ = writeln!(s, "power           {:.0} mW (mean total)", self.power_mw_mean);
        let m = &self.messages;
        let _ = writeln!(
            s,
            "messages        {} sent, {} dropped, {} late, {} rejected",
            m.sent, m.dropped, m.late, m.rejected
        );
        let _ = writeln!(
            s,
            "sync error      {} mean, {} max",
            opt(self.sync_error_ms_mean, "ms"),
            opt(self.sync_error_ms_max, "ms")
        );
        let _ = writeln!(s, "handovers       {}", self.handovers);
        let _ = writeln!(s, "global ids      {}", self.global_ids);
        if self.torn_tail_bytes > 0 {
            let _ = writeln!(s, "torn tail       {} bytes skipped", self.torn_tail_bytes);
        }
        if !self.targets.is_empty() {
            let _ = writeln!(
                s,
                "\n{:>6} {:>8} {:>9} {:>9} {:>9}  globals",
                "target", "samples", "mean m", "std m", "rmse m"
            );
            for t in &self.targets {
                let _ = writeln!(
                    s,
                    "{:>6} {:>8} {:>9.3} {:>9.3} {:>9.3}  {:?}",
                    t.target, t.samples, t.mean_error_m, t.error_std_m, t.rmse_m, t.globals
                );
            }
        }
        if !self.energy.is_empty() {
            let _ = writeln!(
                s,
                "\n{:>6} {:>10} {:>12} {:>9}  source",
                "node", "energy J", "mean mW", "seconds"
            );
            for e in &self.energy {
                let _ = writeln!(
                    s,
                    "{:>6} {:>10.2} {:>12.1} {:>9.1}  {}",
                    e.node, e.energy_j, e.mean_power_mw, e.seconds, e.source
                );
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::{Format, write_rows};
    use crate::record::Stamped;
    use crate::recording::Recorder;
    use crate::replay::load;
    use proto::msg::{Contributor, Hello, TrackReport};
    use proto::{Envelope, PROTOCOL_VERSION, Role, TargetId};
    use std::path::PathBuf;

    /// Record a 10 s run of the test scenario: the owning head reports the truth shifted 0.1 m
    /// in x with two camera and one RSSI-only contributor; heads follow handovers.
    fn record_run(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ocelli-report-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.ocelli");
        let sc = crate::testkit::scenario();
        let mut rec = Recorder::create(&path, &sc.name).unwrap();
        rec.append(&Stamped::new(ClusterTime::ZERO, Record::Scenario(sc.to_toml())))
            .unwrap();
        let mut server = ServerNode::new(ServerConfig::from_scenario(sc.clone(), NodeId(1)));
        let mut seq: BTreeMap<NodeId, u64> = BTreeMap::new();
        let mut send = |server: &mut ServerNode,
                        rec: &mut Recorder,
                        t: ClusterTime,
                        src: NodeId,
                        body: Message,
                        skip: u64| {
            let s = seq.entry(src).or_insert(0);
            *s += skip;
            let env = Envelope {
                source: src,
                seq: *s,
                time: t,
                body,
            };
            *s += 1;
            let out = server.on_message(t, env);
            for r in server.take_records() {
                rec.append(&r).unwrap();
            }
            for (i, o) in out.iter().enumerate() {
                let env = Envelope {
                    source: NodeId(1),
                    seq: i as u64,
                    time: t,
                    body: o.body.clone(),
                };
                rec.append(&Stamped::new(t, Record::Sent { to: o.to, env }))
                    .unwrap();
            }
            out
        };
        for (n, role) in [(2, Role::Head), (3, Role::Head), (10, Role::Camera)] {
            let hello = Message::Hello(Hello {
                version: PROTOCOL_VERSION,
                role,
                node: NodeId(n),
            });
            send(&mut server, &mut rec, ClusterTime::ZERO, NodeId(n), hello, 0);
        }
        let mut owner = NodeId(2);
        let mut carried = None;
        for k in 0..50i64 {
            let t = ClusterTime::from_millis(k * 200);
            let truth = sc.targets[0].truth_at(t.as_secs_f64());
            let mut cov = [[0.0; 6]; 6];
            for (i, row) in cov.iter_mut().enumerate() {
                row[i] = 0.01;
            }
            let c = |n, camera| Contributor {
                node: NodeId(n),
                camera,
                rssi: true,
            };
            let r = TrackReport {
                target: TargetId(if owner == NodeId(2) { 5 } else { 9 }),
                global: carried,
                step: k as u64,
                time: t,
                mean: [truth[0] + 0.1, truth[1], truth[2], truth[3], truth[4], truth[5]],
                cov,
                contributors: vec![c(10, true), c(11, true), c(12, false)],
                power_mw: 1500.0,
                late: k as u64 / 10,
            };
            let out = send(&mut server, &mut rec, t, owner, Message::TrackReport(r), 0);
            for o in out {
                if let Message::Handover(h) = o.body
                    && o.to == h.to_head
                    && h.from_head.is_some()
                {
                    owner = h.to_head;
                    carried = Some(h.global);
                }
            }
            let hb = Message::Heartbeat;
            send(&mut server, &mut rec, t, NodeId(2), hb.clone(), 0);
            send(&mut server, &mut rec, t, NodeId(3), hb, 0);
            server.tick(t);
            for r in server.take_records() {
                rec.append(&r).unwrap();
            }
        }
        let status = NodeStatus {
            mode: Mode::Active,
            time_in_mode_ns: [8_000_000_000, 2_000_000_000, 0],
            frames: 50,
            detections: 50,
            dropped: 1,
            rejected: 0,
            sync_offset_ns: 5_000,
            sync_error_ns: 2_000_000,
        };
        // Two camera frames were lost on the way: a sequence gap of 2.
        send(
            &mut server,
            &mut rec,
            ClusterTime::from_millis(10_000),
            NodeId(10),
            Message::NodeStatus(status),
            2,
        );
        path
    }

    #[test]
    fn report_from_a_recorded_run() {
        let path = record_run("report");
        let loaded = load(&path, None).unwrap();
        let r = compute(&loaded, ClusterTime::ZERO);
        assert!(r.truth);
        assert_eq!(r.steps, 50);
        assert!(
            (r.mean_error_m.unwrap() - 0.1).abs() < 1e-9,
            "{:?}",
            r.mean_error_m
        );
        assert!(r.error_std_m.unwrap() < 1e-9);
        assert_eq!(r.targets.len(), 1);
        assert_eq!(r.targets[0].globals.len(), 1, "one global id for the target");
        assert_eq!(r.false_tracks, 0);
        assert_eq!(r.handovers, 1);
        assert!((r.active_cameras_mean - 2.0).abs() < 1e-12);
        assert!((r.rssi_nodes_mean - 3.0).abs() < 1e-12);
        // 8 s Active (650 + 69 mW) + 2 s CameraOff (69 mW) = 5.89 J over 10 s.
        assert_eq!(r.energy.len(), 1);
        assert!((r.energy[0].energy_j - 5.89).abs() < 1e-9);
        assert!((r.power_mw_mean - 589.0).abs() < 1e-9);
        assert_eq!(r.messages.dropped, 3);
        // Cumulative per head: head 2 last said 2 (handover at step 21), head 3 says 4.
        assert_eq!(r.messages.late, 6);
        assert!(r.messages.sent > 150);
        assert_eq!(r.sync_error_ms_max, Some(2.0));
        let json = serde_json::to_value(&r).unwrap();
        for key in [
            "mean_error_m",
            "error_std_m",
            "active_cameras_mean",
            "rssi_nodes_mean",
            "power_mw_mean",
        ] {
            assert!(json[key].is_number(), "{key}");
        }
        for key in ["sent", "dropped", "late"] {
            assert!(json["messages"][key].is_number(), "messages.{key}");
        }
        assert!(r.to_table().contains("mean error      0.100 m"));
    }

    #[test]
    fn without_truth_errors_are_absent_and_power_falls_back_to_reports() {
        let path = record_run("notruth");
        let mut sc = crate::testkit::scenario();
        sc.targets.clear();
        let mut loaded = load(&path, Some(sc)).unwrap();
        loaded.records.retain(
            |s| !matches!(&s.record, Record::Received(e) if matches!(e.body, Message::NodeStatus(_))),
        );
        let r = compute(&loaded, ClusterTime::ZERO);
        assert!(!r.truth);
        assert_eq!(r.mean_error_m, None);
        assert!(r.energy.iter().all(|e| e.source == "track_report"));
        assert!((r.power_mw_mean - 3000.0).abs() < 1e-9, "two heads at 1500 mW");
    }

    #[test]
    fn export_writes_csv_and_json_lines() {
        let path = record_run("export");
        let loaded = load(&path, None).unwrap();
        let rows = crate::export::track_rows(&loaded);
        assert_eq!(rows.len(), 50);
        assert!(rows.iter().all(|r| r.global == rows[0].global));
        assert!(rows.iter().any(|r| r.head == 3) && rows.iter().any(|r| r.head == 2));
        let mut csv = Vec::new();
        write_rows(&rows, Format::Csv, &mut csv).unwrap();
        let csv = String::from_utf8(csv).unwrap();
        assert_eq!(csv.lines().count(), 51);
        assert!(csv.starts_with("t,global,head,local,step,x,y,z,vx,vy,vz,sigma_m,owner"));
        let mut jl = Vec::new();
        write_rows(&rows, Format::JsonLines, &mut jl).unwrap();
        let lines: Vec<serde_json::Value> = String::from_utf8(jl)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 50);
        assert!((lines[0]["sigma_m"].as_f64().unwrap() - 0.03f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_ghost_track_is_a_false_track_not_an_error() {
        let path = record_run("ghost");
        let mut loaded = load(&path, None).unwrap();
        // Head 2 also reports a stationary ghost far from the target's path.
        let mut extra = Vec::new();
        for s in &loaded.records {
            if let Record::Received(env) = &s.record
                && let Message::TrackReport(r) = &env.body
                && env.source == NodeId(2)
            {
                let mut ghost = r.clone();
                ghost.target = TargetId(77);
                ghost.global = None;
                ghost.mean = [1.0, 7.5, 0.5, 0.0, 0.0, 0.0];
                let mut env = env.clone();
                env.body = Message::TrackReport(ghost);
                extra.push((s.at, env));
            }
        }
        for (at, env) in extra {
            loaded.records.push(Stamped::new(at, Record::Received(env)));
        }
        loaded.records.sort_by_key(|s| s.at);
        let r = compute(&loaded, ClusterTime::ZERO);
        assert_eq!(r.false_tracks, 1);
        assert!(r.false_track_samples > 10);
        assert!((r.mean_error_m.unwrap() - 0.1).abs() < 1e-9);
    }
}
