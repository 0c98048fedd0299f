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
//! - **Energy per node**: from the latest `NodeStatus.time_in_mode_ns` of each camera node with
//!   its power figures; runs without camera statuses fall back to the heads'
//!   `TrackReport.power_mw` × step time.
//!   `power_mw_mean` is the sum over nodes of their mean power.
//! - **Messages**: `sent` = frames nodes sent to the server (received + sequence gaps) plus
//!   frames the server sent; `dropped` = sequence numbers that never reached the server (link
//!   control frames such as TCP heartbeats take none, so a missing one is a lost frame; one
//!   that arrives late is not: `report/sequence.rs`) plus the
//!   `dropped` counters nodes report (cameras: undeliverable messages; heads: failed sends); `late` = contributions past their deadline as the heads report them;
//!   `rejected` = inputs the server refused.
//! - **Multi-target metrics** (`mota`, `motp_m`, `idf1`, `id_switches`, `fragmentations`,
//!   `mostly_tracked`, `mostly_lost`, `gospa_m`, and everything behind them per run and per
//!   target in `mot`): [`crate::metrics`] on frames built from the owner rows, one per step
//!   after a warm-up, on the floor plane with a 1 m threshold ([`mot`]).
//! - **Sync error**: the `sync_error_ns` each node (camera or head) last reported: the RMS of
//!   its clock's error at the recent sync beacons (`proto::sync`); negative (not synchronized
//!   yet) is left out.
//! - **Bandwidth per node**: `bytes_per_s` = the growth of `NodeStatus.bytes_sent` (the encoded
//!   frames the node's runtime put on the wire, heartbeats included) between its first and last
//!   status, over the time between them (`time_in_mode_ns` summed); a node with one status:
//!   its count over its time so far.

use crate::analysis::Loaded;
use crate::core::{ServerConfig, ServerNode};
use crate::decision::Decision;
use crate::export::{TrackRow, track_rows};
use crate::metrics::MotMetrics;
use crate::record::Record;
use proto::msg::{Message, NodeStatus};
use proto::scenario::NodeRole;
use proto::{Mode, NodeId};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

pub mod mot;
mod sequence;

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

/// What one node put on the wire.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeBandwidth {
    pub node: u32,
    /// `camera` or `head`.
    pub role: &'static str,
    /// Bytes its last status counted.
    pub bytes_sent: u64,
    pub bytes_per_s: f64,
    /// The time the rate is taken over.
    pub seconds: f64,
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
    /// Damaged stretches of the recording that reading skipped.
    pub skipped: Vec<crate::recording::Skipped>,
    /// Bytes per second each node put on the wire.
    pub bandwidth: Vec<NodeBandwidth>,
    /// The standard multi-target metrics against the truth ([`mot`]; `None` without truth):
    /// CLEAR MOT's accuracy and precision (m), IDF1, identity switches, fragmentations, targets
    /// mostly tracked (≥ 80% of their frames) and mostly lost (< 20%), mean GOSPA (m).
    pub mota: Option<f64>,
    pub motp_m: Option<f64>,
    pub idf1: Option<f64>,
    pub id_switches: Option<u64>,
    pub fragmentations: Option<u64>,
    pub mostly_tracked: Option<u64>,
    pub mostly_lost: Option<u64>,
    pub gospa_m: Option<f64>,
    /// Every count behind them, and the same per target (`mot.targets`).
    pub mot: Option<MotMetrics>,
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

/// Where the true targets were, for scoring a run. Only a simulation knows it (the lab gives
/// it from the simulated world); a real deployment's report scores nothing it cannot know.
pub trait Truth {
    /// The true targets' ids.
    fn ids(&self) -> Vec<u32>;
    /// Where target `index` (of [`Truth::ids`]) truly was at cluster time `t` seconds, metres.
    fn position(&self, index: usize, t: f64) -> [f64; 3];
}

/// Compute the report with the default association gate, scoring against `truth` if given.
pub fn compute(loaded: &Loaded, truth: Option<&dyn Truth>) -> Report {
    compute_with(loaded, truth, ASSOCIATION_GATE_M)
}

/// What the run's MOT metrics are computed from: its owner track rows, in recording order, and
/// the span of the recording, seconds of cluster time. One place, so that [`compute_with`]'s
/// counts and [`frame_events`]' frames come from the same rows and frames.
fn mot_input(loaded: &Loaded) -> (Vec<TrackRow>, f64, f64, mot::Scoring) {
    let rows: Vec<TrackRow> = track_rows(loaded).into_iter().filter(|r| r.owner).collect();
    let start = loaded.records.first().map_or(0.0, |s| s.at.as_secs_f64());
    let end = loaded.records.last().map_or(0.0, |s| s.at.as_secs_f64());
    (rows, start, end, mot::Scoring::for_scenario(&loaded.scenario))
}

/// Every scored frame of `loaded` against `truth` with what CLEAR MOT counted in it: the frames
/// [`compute`]'s `mot` metrics come from (`mot::frame_events`). `None` when the report's `mot`
/// is (no frame fits).
pub fn frame_events(
    loaded: &Loaded,
    truth: &dyn Truth,
) -> Option<Vec<(crate::metrics::Frame<2>, crate::metrics::FrameEvents)>> {
    let (rows, start, end, scoring) = mot_input(loaded);
    mot::frame_events(&rows, truth, start, end, &scoring)
}

/// Compute the report with an association gate (m).
pub fn compute_with(loaded: &Loaded, truth_of: Option<&dyn Truth>, gate_m: f64) -> Report {
    let sc = &loaded.scenario;
    let (rows, start, end, scoring) = mot_input(loaded);
    let truth = truth_of.filter(|t| !t.ids().is_empty());
    let scored = truth.map(|t| score_errors(&rows, t, gate_m)).unwrap_or_default();
    let mot = truth.and_then(|t| mot::score(&rows, t, start, end, &scoring));
    let tally = tally_records(loaded);
    let mut msgs = tally.messages.clone();
    let (handovers, globals, rejected) = replayed_decisions(loaded);
    msgs.rejected += rejected;
    msgs.late = tally.late.values().sum();
    msgs.dropped += tally.status.values().map(|s| s.dropped).sum::<u64>();
    let steps = rows.len() as u64;
    let cams: u64 = rows.iter().map(|r| u64::from(r.cameras)).sum();
    let rssi: u64 = rows.iter().map(|r| u64::from(r.rssi_nodes)).sum();
    let energy = energy(sc, &tally);
    // (An empty f64 sum is −0.0; add +0.0 so an idle run prints 0.)
    let power_mw_mean = energy.iter().map(|e| e.mean_power_mw).sum::<f64>() + 0.0;
    let sync: Vec<NodeSync> = tally
        .status
        .iter()
        .filter(|(_, s)| s.sync_error_ns >= 0)
        .map(|(n, s)| NodeSync {
            node: n.0,
            error_ms: s.sync_error_ns as f64 * 1e-6,
            offset_ms: s.sync_offset_ns as f64 * 1e-6,
        })
        .collect();
    let sync_errs: Vec<f64> = sync.iter().map(|s| s.error_ms).collect();
    let per_step = |x: u64| if steps > 0 { x as f64 / steps as f64 } else { 0.0 };
    let all = &scored.all;
    let (mean, std, rmse) = mean_std(all);
    Report {
        scenario: sc.name.clone(),
        duration_s: match (loaded.records.first(), loaded.records.last()) {
            (Some(a), Some(b)) => b.at.secs_since(a.at),
            _ => 0.0,
        },
        steps,
        truth: truth.is_some(),
        mean_error_m: (!all.is_empty()).then_some(mean),
        error_std_m: (!all.is_empty()).then_some(std),
        rmse_m: (!all.is_empty()).then_some(rmse),
        targets: scored.targets,
        false_tracks: scored.false_tracks,
        false_track_samples: scored.false_samples,
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
        skipped: loaded.skipped.clone(),
        bandwidth: bandwidth(sc, &tally.first_status, &tally.status),
        mota: mot.as_ref().and_then(|m| m.mota),
        motp_m: mot.as_ref().and_then(|m| m.motp_m),
        idf1: mot.as_ref().and_then(|m| m.idf1),
        id_switches: mot.as_ref().map(|m| m.id_switches as u64),
        fragmentations: mot.as_ref().map(|m| m.fragmentations as u64),
        mostly_tracked: mot.as_ref().map(|m| m.mostly_tracked as u64),
        mostly_lost: mot.as_ref().map(|m| m.mostly_lost as u64),
        gospa_m: mot.as_ref().map(|m| m.gospa_m),
        mot,
    }
}

/// Each global associated with the true target nearest it on average, and the errors.
#[derive(Debug, Default)]
struct Scored {
    targets: Vec<TargetError>,
    /// Every associated sample's error.
    all: Vec<f64>,
    false_tracks: u64,
    false_samples: u64,
}

/// Associate each global with its nearest true target on average (within `gate_m`, else it is
/// a false track) and collect the errors of each target's samples.
fn score_errors(rows: &[TrackRow], truth: &dyn Truth, gate_m: f64) -> Scored {
    let ids = truth.ids();
    let d3 = |a: [f64; 3], r: &TrackRow| {
        ((a[0] - r.x).powi(2) + (a[1] - r.y).powi(2) + (a[2] - r.z).powi(2)).sqrt()
    };
    let mut by_global: BTreeMap<u32, Vec<&TrackRow>> = BTreeMap::new();
    for r in rows {
        by_global.entry(r.global).or_default().push(r);
    }
    let mut per_target: BTreeMap<usize, (Vec<f64>, Vec<u32>)> = BTreeMap::new();
    let mut out = Scored::default();
    for (g, rs) in &by_global {
        let best = (0..ids.len())
            .map(|k| {
                let d: f64 = rs.iter().map(|r| d3(truth.position(k, r.t), r)).sum();
                (k, d / rs.len() as f64)
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, mean_d)) = best {
            if mean_d > gate_m {
                out.false_tracks += 1;
                out.false_samples += rs.len() as u64;
                continue;
            }
            let e = per_target.entry(k).or_default();
            e.0.extend(rs.iter().map(|r| d3(truth.position(k, r.t), r)));
            e.1.push(*g);
        }
    }
    out.all = per_target.values().flat_map(|(e, _)| e.iter().copied()).collect();
    out.targets = per_target
        .iter()
        .map(|(k, (e, gs))| {
            let (m, s, r) = mean_std(e);
            TargetError {
                target: ids[*k],
                samples: e.len() as u64,
                mean_error_m: m,
                error_std_m: s,
                rmse_m: r,
                globals: gs.clone(),
            }
        })
        .collect();
    out
}

/// What the received frames say: messages sent and lost, each node's last status, each head's
/// late count and track-report power.
#[derive(Debug, Default)]
struct Tally {
    messages: Messages,
    status: BTreeMap<NodeId, NodeStatus>,
    /// Each node's first status (for its bandwidth).
    first_status: BTreeMap<NodeId, NodeStatus>,
    late: BTreeMap<NodeId, u64>,
    head_power: BTreeMap<NodeId, (f64, u64)>,
}

fn tally_records(loaded: &Loaded) -> Tally {
    let mut t = Tally::default();
    let mut gaps = sequence::SequenceGaps::default();
    for s in &loaded.records {
        match &s.record {
            Record::Received(env) => {
                t.messages.sent += 1;
                gaps.see(env.source, env.seq);
                match &env.body {
                    Message::NodeStatus(st) => {
                        t.first_status.entry(env.source).or_insert_with(|| st.clone());
                        t.status.insert(env.source, st.clone());
                    }
                    Message::TrackReport(r) => {
                        t.late.insert(env.source, r.late);
                        let e = t.head_power.entry(env.source).or_default();
                        e.0 += r.power_mw;
                        e.1 += 1;
                    }
                    _ => {}
                }
            }
            Record::Sent { .. } => t.messages.sent += 1,
            _ => {}
        }
    }
    let lost = gaps.lost();
    t.messages.sent += lost;
    t.messages.dropped += lost;
    t
}

/// Handovers, global ids founded and inputs refused, as this build's server decides them from
/// the recorded inputs (the same replay the track rows come from; for a recording made by this
/// build they equal the recorded ones).
fn replayed_decisions(loaded: &Loaded) -> (u64, u64, u64) {
    let (mut handovers, mut globals, mut rejected) = (0u64, 0u64, 0u64);
    let mut node = ServerNode::new(ServerConfig::from_scenario(
        loaded.scenario.clone(),
        loaded.server_id(),
    ));
    for s in &loaded.records {
        node.feed(s);
        for r in node.take_records() {
            if let Record::Decision(d) = r.record {
                match d {
                    Decision::Rejected { .. } | Decision::Refused { .. } => rejected += 1,
                    Decision::Handover { .. } => handovers += 1,
                    Decision::NewGlobal { .. } | Decision::Split { .. } => globals += 1,
                    _ => {}
                }
            }
        }
    }
    (handovers, globals, rejected)
}

/// Energy from camera nodes' statuses; heads report theirs in their track reports (their
/// statuses carry sync and failures), used only when no camera status was recorded.
fn energy(sc: &proto::scenario::Scenario, tally: &Tally) -> Vec<NodeEnergy> {
    let step_s = sc.method.step_ms as f64 * 1e-3;
    let mut energy = Vec::new();
    let cameras: Vec<(&NodeId, &NodeStatus)> = tally
        .status
        .iter()
        .filter(|(n, _)| sc.node(n.0).is_some_and(|d| d.role == NodeRole::Camera))
        .collect();
    for &(node, st) in &cameras {
        let (e, secs) = status_energy(st, &sc.power_of(node.0));
        energy.push(NodeEnergy {
            node: node.0,
            energy_j: e,
            mean_power_mw: if secs > 0.0 { e * 1e3 / secs } else { 0.0 },
            seconds: secs,
            source: "node_status",
        });
    }
    if cameras.is_empty() {
        for (head, (sum_mw, n)) in &tally.head_power {
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
    energy
}

/// Each node's bytes per second between its first and last status (see the module docs).
fn bandwidth(
    sc: &proto::scenario::Scenario,
    first: &BTreeMap<NodeId, NodeStatus>,
    last: &BTreeMap<NodeId, NodeStatus>,
) -> Vec<NodeBandwidth> {
    let secs = |s: &NodeStatus| s.time_in_mode_ns.iter().sum::<u64>() as f64 * 1e-9;
    last.iter()
        .filter_map(|(node, b)| {
            let role = match sc.node(node.0)?.role {
                NodeRole::Camera => "camera",
                NodeRole::Head => "head",
                NodeRole::Acoustic => "acoustic",
                NodeRole::Server => return None,
            };
            let a = first
                .get(node)
                .filter(|a| secs(b) > secs(a))
                .cloned()
                .unwrap_or(NodeStatus {
                    time_in_mode_ns: [0; 3],
                    bytes_sent: 0,
                    ..b.clone()
                });
            let seconds = secs(b) - secs(&a);
            let bytes = b.bytes_sent.saturating_sub(a.bytes_sent);
            Some(NodeBandwidth {
                node: node.0,
                role,
                bytes_sent: b.bytes_sent,
                bytes_per_s: if seconds > 0.0 {
                    bytes as f64 / seconds
                } else {
                    0.0
                },
                seconds,
            })
        })
        .collect()
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
        if let Some(m) = &self.mot {
            let _ = writeln!(s, "MOTA / MOTP     {} / {}", opt(m.mota, ""), opt(m.motp_m, "m"));
            let _ = writeln!(s, "IDF1            {}", opt(m.idf1, ""));
            let _ = writeln!(
                s,
                "id switches     {}, fragmentations {}",
                m.id_switches, m.fragmentations
            );
            let _ = writeln!(
                s,
                "mostly tracked  {} of {} targets, mostly lost {}",
                m.mostly_tracked, m.unique_objects, m.mostly_lost
            );
            let _ = writeln!(s, "GOSPA           {:.3} m", m.gospa_m);
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
        if !self.skipped.is_empty() {
            let mut at: Vec<String> = self
                .skipped
                .iter()
                .take(5)
                .map(|k| k.offset.to_string())
                .collect();
            if self.skipped.len() > at.len() {
                at.push("…".into());
            }
            let _ = writeln!(
                s,
                "damage          {} bytes skipped in {} stretches (at bytes {})",
                crate::recording::skipped_bytes(&self.skipped),
                self.skipped.len(),
                at.join(", ")
            );
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
        if let Some(m) = self.mot.as_ref().filter(|m| !m.targets.is_empty()) {
            let _ = writeln!(
                s,
                "\n{:>6} {:>9} {:>6} {:>8} {:>9} {:>6}  ids",
                "target", "coverage", "idf1", "motp m", "switches", "frags"
            );
            for t in &m.targets {
                let _ = writeln!(
                    s,
                    "{:>6} {:>9.3} {:>6.3} {:>8} {:>9} {:>6}  {:?}",
                    t.id,
                    t.coverage,
                    t.idf1,
                    t.motp_m.map_or("–".into(), |x| format!("{x:.3}")),
                    t.id_switches,
                    t.fragmentations,
                    t.hyp_ids
                );
            }
        }
        if !self.bandwidth.is_empty() {
            let _ = writeln!(
                s,
                "\n{:>6} {:>7} {:>12} {:>12} {:>9}",
                "node", "role", "bytes sent", "bytes/s", "seconds"
            );
            for b in &self.bandwidth {
                let _ = writeln!(
                    s,
                    "{:>6} {:>7} {:>12} {:>12.0} {:>9.1}",
                    b.node, b.role, b.bytes_sent, b.bytes_per_s, b.seconds
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
