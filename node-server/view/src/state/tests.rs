use super::*;
use node_server::{Decision, HandoverReason, Record, Stamped};
use proto::msg::{Contributor, Kinds, Message, NodeStatus, ObservationKind, TrackReport};
use proto::{ClusterTime, Envelope, NodeId, TargetId};

const S: i64 = 1_000_000_000;

fn default_view() -> ViewState {
    ViewState::with_scenario(&Scenario::default_scenario())
}

fn received(at: i64, source: u32, seq: u64, body: Message) -> Stamped {
    Stamped::new(
        ClusterTime(at),
        Record::Received(Envelope {
            source: NodeId(source),
            seq,
            time: ClusterTime(at),
            body,
        }),
    )
}

fn decided(at: i64, d: Decision) -> Stamped {
    Stamped::new(ClusterTime(at), Record::Decision(d))
}

fn report(local: u32, at: i64, x: f64, y: f64) -> Message {
    let mut cov = [[0.0; 6]; 6];
    cov[0][0] = 0.04;
    cov[1][1] = 0.01;
    cov[2][2] = 0.01;
    Message::TrackReport(TrackReport {
        target: TargetId(local),
        global: None,
        step: (at / (S / 5)) as u64,
        time: ClusterTime(at),
        mean: [x, y, 0.25, 0.4, 0.0, 0.0],
        cov,
        contributors: vec![
            Contributor {
                node: NodeId(10),
                kinds: Kinds::of(ObservationKind::Pinhole).union(Kinds::of(ObservationKind::Rssi)),
            },
            Contributor {
                node: NodeId(11),
                kinds: Kinds::of(ObservationKind::Rssi),
            },
        ],
        power_mw: 100.0,
        late: 3,
        appearance: Vec::new(),
        grid: None,
        captured: None,
    })
}

fn new_global(at: i64, head: u32, local: u32, global: u32) -> Stamped {
    decided(
        at,
        Decision::NewGlobal {
            head: NodeId(head),
            local: TargetId(local),
            global: TargetId(global),
        },
    )
}

/// A view with global 7 owned by head 2 (its local 1) at (2, 3).
fn view_with_track() -> ViewState {
    let mut v = default_view();
    v.apply(&received(S, 2, 1, report(1, S, 2.0, 3.0)));
    let changes = v.apply(&new_global(S, 2, 1, 7));
    assert_eq!(changes, vec![Change::Track(7)]);
    v
}

#[test]
fn the_scenario_gives_the_site() {
    let v = default_view();
    assert_eq!(v.scenario, "default");
    assert_eq!(v.world.max, [12.0, 8.0, 3.0]);
    assert_eq!(v.step_ms, 200);
    let cameras: Vec<_> = v.nodes_of(NodeKind::Camera).collect();
    assert_eq!(cameras.len(), 21);
    assert!(cameras.iter().all(|c| c.camera.is_some() && c.head.is_some()));
    let heads: Vec<_> = v.nodes_of(NodeKind::Head).collect();
    assert_eq!(heads.len(), 2);
    assert_eq!(heads[0].region, Some([0.0, 0.0, 6.0, 8.0]));
    // The server is the recorder, so it is up; nobody else has spoken.
    assert!(v.nodes[&1].up);
    assert!(!v.nodes[&2].up && !v.nodes[&10].up);
    assert!(v.problems.is_empty(), "{:?}", v.problems);
}

/// Every camera of the default scenario sees part of the floor, and its wedge stays in the room.
#[test]
fn camera_wedges_lie_on_the_room_floor() {
    let v = default_view();
    for c in v.nodes_of(NodeKind::Camera) {
        let g = c.camera.as_ref().unwrap();
        let inside = |p: &[f64]| p[0] >= -1e-9 && p[0] <= 12.0 + 1e-9 && p[1] >= -1e-9 && p[1] <= 8.0 + 1e-9;
        assert!(
            g.footprint.iter().all(|p| inside(p)),
            "camera {}: {:?}",
            c.id,
            g.footprint
        );
        assert!(
            g.frustum
                .iter()
                .all(|p| inside(p) && p[2] >= -1e-9 && p[2] <= 3.0 + 1e-9)
        );
        // It looks down into the room, and some corner ray reaches the floor.
        assert!(g.forward[2] < 0.0, "camera {}", c.id);
        assert!(g.frustum.iter().any(|p| p[2].abs() < 1e-9), "camera {}", c.id);
    }
}

#[test]
fn a_report_becomes_a_track_when_the_server_names_it() {
    let mut v = default_view();
    let changes = v.apply(&received(S, 2, 1, report(1, S, 2.0, 3.0)));
    assert!(v.tracks.is_empty() && changes.is_empty(), "no global id yet");
    v.apply(&new_global(S, 2, 1, 7));
    let t = &v.tracks[&7];
    assert_eq!((t.owner, t.local), (2, 1));
    assert_eq!(t.position, [2.0, 3.0, 0.25]);
    assert_eq!(t.cameras, vec![10]);
    assert_eq!(t.rssi, vec![10, 11]);
    assert_eq!(t.height_m, Some(0.5));
    let e = t.ellipse.unwrap();
    assert!((e.semi_major - 0.4).abs() < 1e-12 && (e.semi_minor - 0.2).abs() < 1e-12);
    assert!((t.sigma_m - 0.06f64.sqrt()).abs() < 1e-12);
    assert_eq!(v.nodes[&2].health.late, 3);
    // The next report moves it and extends the trail.
    let changes = v.apply(&received(S + S / 5, 2, 2, report(1, S + S / 5, 2.1, 3.0)));
    assert_eq!(changes, vec![Change::Track(7)]);
    assert_eq!(v.tracks[&7].position[0], 2.1);
    assert_eq!(v.tracks[&7].trail.len(), 2);
}

#[test]
fn trails_keep_ten_seconds() {
    let mut v = view_with_track();
    for i in 1..=75 {
        let at = S + i * S / 5; // 15 s of reports at 5 Hz
        v.apply(&received(
            at,
            2,
            1 + i as u64,
            report(1, at, 2.0 + i as f64 * 0.01, 3.0),
        ));
    }
    let trail = &v.tracks[&7].trail;
    let span = trail.back().unwrap()[0] - trail.front().unwrap()[0];
    assert!(span <= 10.0 + 1e-9 && span > 9.5, "{span}");
    assert_eq!(trail.len(), 51);
}

#[test]
fn only_the_owner_moves_a_track() {
    let mut v = view_with_track();
    v.apply(&received(S, 3, 1, report(4, S, 2.3, 3.1)));
    v.apply(&decided(
        S,
        Decision::Merged {
            head: NodeId(3),
            local: TargetId(4),
            global: TargetId(7),
        },
    ));
    let changes = v.apply(&received(2 * S, 3, 2, report(4, 2 * S, 2.5, 3.2)));
    assert!(changes.is_empty());
    assert_eq!(v.tracks[&7].position[0], 2.0);
    assert_eq!(v.tracks[&7].owner, 2);
}

#[test]
fn a_handover_moves_ownership_and_is_listed() {
    let mut v = view_with_track();
    let changes = v.apply(&decided(
        2 * S,
        Decision::Handover {
            global: TargetId(7),
            from: Some(NodeId(2)),
            to: NodeId(3),
            reason: HandoverReason::Region,
        },
    ));
    assert_eq!(changes, vec![Change::Handover(1), Change::Track(7)]);
    let h = v.handovers.back().unwrap();
    assert_eq!(
        (h.global, h.from, h.to, h.reason.as_str()),
        (7, Some(2), 3, "region")
    );
    assert_eq!(h.position, Some([2.0, 3.0]));
    assert_eq!(v.totals.handovers, 1);
    // The old owner's late report no longer moves it; the new owner's claimed track does.
    v.apply(&received(2 * S + 1, 2, 2, report(1, 2 * S, 9.0, 9.0)));
    assert_eq!(v.tracks[&7].position[0], 2.0);
    v.apply(&received(3 * S, 3, 1, report(5, 3 * S, 6.5, 3.0)));
    v.apply(&decided(
        3 * S,
        Decision::Claimed {
            head: NodeId(3),
            local: TargetId(5),
            global: TargetId(7),
        },
    ));
    assert_eq!(v.tracks[&7].position[0], 6.5);
    assert_eq!((v.tracks[&7].owner, v.tracks[&7].local), (3, 5));
}

#[test]
fn an_owner_change_shows_the_new_owners_estimate() {
    let mut v = view_with_track();
    v.apply(&received(2 * S, 3, 1, report(4, 2 * S, 2.2, 3.0)));
    v.apply(&decided(
        2 * S,
        Decision::Merged {
            head: NodeId(3),
            local: TargetId(4),
            global: TargetId(7),
        },
    ));
    let changes = v.apply(&decided(
        2 * S,
        Decision::OwnerChanged {
            global: TargetId(7),
            from: NodeId(2),
            to: NodeId(3),
        },
    ));
    assert_eq!(changes, vec![Change::Handover(1), Change::Track(7)]);
    assert_eq!(v.tracks[&7].owner, 3);
    assert_eq!(v.tracks[&7].position[0], 2.2);
    assert_eq!(v.handovers[0].reason, "owner_changed");
}

#[test]
fn lost_and_absorbed_tracks_go() {
    let mut v = view_with_track();
    v.apply(&received(S, 3, 1, report(4, S, 8.0, 3.0)));
    v.apply(&new_global(S, 3, 4, 8));
    assert_eq!(v.tracks.len(), 2);
    let changes = v.apply(&decided(
        2 * S,
        Decision::Absorbed {
            global: TargetId(8),
            into: TargetId(7),
        },
    ));
    assert_eq!(changes, vec![Change::TrackRemoved(8)]);
    assert_eq!(
        v.book.bindings[&(3, 4)],
        7,
        "its local tracks now feed the survivor"
    );
    let changes = v.apply(&decided(3 * S, Decision::Lost { global: TargetId(7) }));
    assert_eq!(changes, vec![Change::TrackRemoved(7)]);
    assert!(v.tracks.is_empty() && v.book.bindings.is_empty());
}

#[test]
fn node_health_liveness_and_staleness() {
    let mut v = default_view();
    v.apply(&decided(
        S,
        Decision::Admitted {
            node: NodeId(10),
            role: proto::Role::Camera,
        },
    ));
    let status = NodeStatus {
        mode: Mode::CameraOff,
        time_in_mode_ns: [0; 3],
        frames: 40,
        detections: 12,
        dropped: 2,
        rejected: 1,
        sync_offset_ns: 1_500_000,
        sync_error_ns: 250_000,
        bytes_sent: 0,
    };
    v.apply(&received(S, 10, 5, Message::NodeStatus(status.clone())));
    // Seq 5 → 9: frames 6, 7, 8 never arrived.
    v.apply(&received(2 * S, 10, 9, Message::NodeStatus(status)));
    let n = &v.nodes[&10];
    assert!(n.up && !n.stale);
    assert_eq!(n.mode, Some(Mode::CameraOff));
    assert_eq!(n.health.sync_error_ms, Some(0.25));
    assert_eq!(n.health.sync_offset_ms, Some(1.5));
    assert_eq!((n.health.dropped, n.health.rejected, n.health.lost), (2, 1, 3));
    // Silent for more than 3 s: stale. Then marked down: down, not stale.
    v.apply(&Stamped::new(ClusterTime(5 * S + 1), Record::Tick));
    assert!(v.nodes[&10].stale);
    v.apply(&decided(
        6 * S,
        Decision::Down {
            node: NodeId(10),
            silent_ms: 4000,
        },
    ));
    assert!(!v.nodes[&10].up && !v.nodes[&10].stale);
    v.apply(&decided(
        7 * S,
        Decision::Assigned {
            camera: NodeId(10),
            head: NodeId(3),
            from: Some(NodeId(2)),
        },
    ));
    assert_eq!(v.nodes[&10].head, Some(3));
}

#[test]
fn bad_input_is_named_and_counted() {
    let mut v = default_view();
    v.apply(&decided(
        S,
        Decision::Rejected {
            source: Some(NodeId(11)),
            what: "prior".into(),
            reason: "a server does not take prior from a camera".into(),
        },
    ));
    v.apply(&decided(
        S,
        Decision::Rejected {
            source: Some(NodeId(11)),
            what: "prior".into(),
            reason: "a server does not take prior from a camera".into(),
        },
    ));
    assert_eq!(v.totals.rejected, 2);
    assert_eq!(v.nodes[&11].health.rejected_by_server, 2);
    assert_eq!(
        v.problems.len(),
        1,
        "a repeated problem is counted, not listed twice"
    );
    assert_eq!(v.problems[0].count, 2);
    let changes = v.apply(&Stamped::new(ClusterTime(S), Record::Scenario("name = ".into())));
    assert_eq!(changes, vec![Change::Problem]);
    assert!(
        v.problems[1].text.contains("recorded scenario"),
        "{:?}",
        v.problems
    );
    assert_eq!(v.scenario, "default", "a bad scenario changes nothing");
    for i in 0..(MAX_PROBLEMS + 5) {
        v.note_problem(0, format!("problem {i}"));
    }
    assert_eq!(v.problems.len(), MAX_PROBLEMS);
    assert_eq!(
        v.problems.back().unwrap().text,
        format!("problem {}", MAX_PROBLEMS + 4)
    );
}

#[test]
fn unknown_senders_are_shown_with_what_they_do() {
    let mut v = ViewState::new();
    v.apply(&received(S, 42, 1, report(1, S, 1.0, 1.0)));
    v.apply(&new_global(S, 42, 1, 1));
    assert_eq!(v.nodes[&42].role, NodeKind::Head);
    assert_eq!(v.tracks[&1].owner, 42);
    // A view started mid-run: a bound track with no report seen appears with the next one.
    v.apply(&decided(
        S,
        Decision::Merged {
            head: NodeId(43),
            local: TargetId(2),
            global: TargetId(2),
        },
    ));
    assert!(!v.tracks.contains_key(&2));
    v.apply(&received(2 * S, 43, 1, report(2, 2 * S, 4.0, 4.0)));
    assert_eq!(v.tracks[&2].position[0], 4.0);
}

#[test]
fn json_has_the_snapshot_shape_and_round_trips() {
    let v = view_with_track();
    let json = serde_json::to_value(&v).unwrap();
    assert!(json["time"].as_f64().unwrap() > 0.0);
    assert_eq!(json["nodes"].as_array().unwrap().len(), 24);
    assert_eq!(json["tracks"][0]["global"], 7);
    assert!((json["tracks"][0]["ellipse"]["semi_major"].as_f64().unwrap() - 0.4).abs() < 1e-12);
    assert_eq!(json["nodes"][0]["role"], "server");
    assert!(json.get("book").is_none());
    // Back from JSON: the same document (numbers to the last bit or two: serde_json parses
    // floats fast, not exactly).
    let text = serde_json::to_string(&v).unwrap();
    let back: ViewState = serde_json::from_str(&text).unwrap();
    same(&serde_json::to_value(&back).unwrap(), &json, "$");
    assert_eq!(back.tracks[&7].position, v.tracks[&7].position);
}

fn same(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!((x - y).abs() <= 1e-12 * (1.0 + x.abs()), "{at}: {x} vs {y}");
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}");
            for (i, (x, y)) in x.iter().zip(y).enumerate() {
                same(x, y, &format!("{at}[{i}]"));
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(x.keys().collect::<Vec<_>>(), y.keys().collect::<Vec<_>>(), "{at}");
            for (k, x) in x {
                same(x, &y[k], &format!("{at}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}
