//! Tests of the run report and the track export on a recorded run of the test scenario.

use crate::analysis::load;
use crate::export::{Format, write_rows};
use crate::record::Record;
use crate::record::Stamped;
use crate::recording::Recorder;
use crate::report::*;
use crate::{ServerConfig, ServerNode};
use proto::msg::{Contributor, Hello, TrackReport};
use proto::msg::{Message, NodeStatus};
use proto::observation::{Kinds, ObservationKind};
use proto::{ClusterTime, Mode, NodeId};
use proto::{Envelope, PROTOCOL_VERSION, Role, TargetId};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The test scenario's targets as the report's truth (scenario time 0 at cluster time 0).
struct WorldTruth(Vec<world::Target>);

impl Truth for WorldTruth {
    fn ids(&self) -> Vec<u32> {
        self.0.iter().map(|t| t.id).collect()
    }
    fn position(&self, index: usize, t: f64) -> [f64; 3] {
        let p = self.0[index].position_at(t);
        [p.x, p.y, p.z]
    }
}

fn truth() -> WorldTruth {
    WorldTruth(world::targets(&crate::testkit::scenario()).unwrap())
}

/// Record a 10 s run of the test scenario: the owning head reports the truth shifted 0.1 m
/// in x with two camera and one RSSI-only contributor; heads follow handovers. The recording
/// lies in a scratch folder removed when the returned folder is dropped.
fn record_run(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::Builder::new()
        .prefix(&format!("ocelli-report-{name}-"))
        .tempdir()
        .unwrap();
    let path = dir.path().join("run.ocelli");
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
        let truth = world::targets(&sc).unwrap()[0].truth_at(t.as_secs_f64());
        let mut cov = [[0.0; 6]; 6];
        for (i, row) in cov.iter_mut().enumerate() {
            row[i] = 0.01;
        }
        let c = |n, camera: bool| Contributor {
            node: NodeId(n),
            kinds: if camera {
                Kinds::of(ObservationKind::Pinhole).union(Kinds::of(ObservationKind::Rssi))
            } else {
                Kinds::of(ObservationKind::Rssi)
            },
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
            appearance: Vec::new(),
            grid: None,
            captured: None,
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
        bytes_sent: 20_000,
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
    // A head's status: its sync estimate counts, its energy comes from its track reports.
    let head_status = NodeStatus {
        mode: Mode::Active,
        time_in_mode_ns: [10_000_000_000, 0, 0],
        frames: 0,
        detections: 0,
        dropped: 0,
        rejected: 0,
        sync_offset_ns: -3_000,
        sync_error_ns: 500_000,
        bytes_sent: 0,
    };
    send(
        &mut server,
        &mut rec,
        ClusterTime::from_millis(10_000),
        NodeId(3),
        Message::NodeStatus(head_status),
        0,
    );
    (dir, path)
}

#[test]
fn report_from_a_recorded_run() {
    let (_dir, path) = record_run("report");
    let loaded = load(&path, None).unwrap();
    let r = compute(&loaded, Some(&truth()));
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
    // 8 s Active (650 + 69 mW) + 2 s CameraOff (69 mW) = 5.89 J over 10 s; the head's status
    // adds no energy.
    assert_eq!(r.energy.len(), 1);
    assert!((r.energy[0].energy_j - 5.89).abs() < 1e-9);
    assert!((r.power_mw_mean - 589.0).abs() < 1e-9);
    assert_eq!(r.messages.dropped, 3);
    // Cumulative per head: head 2 last said 2 (handover at step 21), head 3 says 4.
    assert_eq!(r.messages.late, 6);
    assert!(r.messages.sent > 150);
    assert_eq!(r.sync_error_ms_max, Some(2.0));
    assert_eq!(r.sync_error_ms_mean, Some(1.25), "camera 2 ms, head 3 0.5 ms");
    assert_eq!(r.sync.len(), 2);
    // One status each: its count over its 10 s so far.
    let bw: Vec<_> = r
        .bandwidth
        .iter()
        .map(|b| (b.node, b.role, b.bytes_per_s))
        .collect();
    assert_eq!(bw, vec![(3, "head", 0.0), (10, "camera", 2000.0)]);
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
    assert!(json["bandwidth"][0]["bytes_per_s"].is_number());
    assert!(r.to_table().contains("mean error      0.100 m"));
    // The standard metrics: one target followed by one global 0.1 m off from 2 s to 10 s.
    assert_eq!((r.mota, r.idf1), (Some(1.0), Some(1.0)));
    assert!((r.motp_m.unwrap() - 0.1).abs() < 1e-9, "{:?}", r.motp_m);
    assert_eq!(
        (r.id_switches, r.fragmentations, r.mostly_tracked, r.mostly_lost),
        (Some(0), Some(0), Some(1), Some(0))
    );
    assert!((r.gospa_m.unwrap() - 0.1).abs() < 1e-9);
    let mot = r.mot.as_ref().unwrap();
    assert_eq!(mot.frames, 41, "2 s to 10 s every 0.2 s");
    assert_eq!(mot.targets[0].hyp_ids, r.targets[0].globals);
    for key in [
        "mota",
        "motp_m",
        "idf1",
        "id_switches",
        "fragmentations",
        "mostly_tracked",
        "mostly_lost",
        "gospa_m",
    ] {
        assert!(json[key].is_number(), "{key}");
    }
    assert!(json["mot"]["targets"][0]["idf1"].is_number());
    assert!(r.to_table().contains("IDF1            1.000"), "{}", r.to_table());
    assert!(r.to_table().contains("bytes/s"));
}

#[test]
fn without_truth_errors_are_absent_and_power_falls_back_to_reports() {
    let (_dir, path) = record_run("notruth");
    let mut loaded = load(&path, None).unwrap();
    loaded
        .records
        .retain(|s| !matches!(&s.record, Record::Received(e) if matches!(e.body, Message::NodeStatus(_))));
    let r = compute(&loaded, None);
    assert!(!r.truth);
    assert_eq!(r.mean_error_m, None);
    assert_eq!((r.mota, r.idf1, r.gospa_m), (None, None, None));
    assert!(r.mot.is_none() && !r.to_table().contains("IDF1"));
    assert!(r.energy.iter().all(|e| e.source == "track_report"));
    assert!((r.power_mw_mean - 3000.0).abs() < 1e-9, "two heads at 1500 mW");
}

#[test]
fn export_writes_csv_and_json_lines() {
    let (_dir, path) = record_run("export");
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
    let (_dir, path) = record_run("ghost");
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
    let r = compute(&loaded, Some(&truth()));
    assert_eq!(r.false_tracks, 1);
    assert!(r.false_track_samples > 10);
    // The ghost is a false positive in every frame while head 2 owns the target (until the
    // handover), and nothing else changes: MOTA 1 − fp/41, IDF1 2·41/(41 + 41 + fp).
    let fp = r.mot.as_ref().unwrap().false_positives as f64;
    assert!(fp > 10.0, "{fp}");
    assert!(
        (r.mota.unwrap() - (1.0 - fp / 41.0)).abs() < 1e-12,
        "{:?}",
        r.mota
    );
    assert!(
        (r.idf1.unwrap() - 82.0 / (82.0 + fp)).abs() < 1e-12,
        "{:?}",
        r.idf1
    );
    assert!((r.mean_error_m.unwrap() - 0.1).abs() < 1e-9);
}
