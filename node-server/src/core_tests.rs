//! Tests of the server core against the embedded default scenario: server 1, head 2 covering
//! `[0, 6] × [0, 8]`, head 3 covering `[6, 12] × [0, 8]`, cameras 10.. in both clusters.

use crate::core::{ServerConfig, ServerNode};
use crate::decision::{Decision, HandoverReason};
use crate::record::Record;
use proto::msg::{Hello, Message, NodeStatus, TrackReport};
use proto::node::Outgoing;
use proto::{ClusterTime, Envelope, Mode, NodeId, PROTOCOL_VERSION, Role, TargetId};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const H2: NodeId = NodeId(2);
const H3: NodeId = NodeId(3);
const CAM: NodeId = NodeId(10);

fn ms(v: i64) -> ClusterTime {
    ClusterTime::from_millis(v)
}

fn server() -> ServerNode {
    ServerNode::new(ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1)))
}

fn env(source: NodeId, body: Message) -> Envelope {
    Envelope {
        source,
        seq: 0,
        time: ClusterTime::ZERO,
        body,
    }
}

fn hello(node: NodeId, role: Role) -> Envelope {
    env(
        node,
        Message::Hello(Hello {
            version: PROTOCOL_VERSION,
            role,
            node,
        }),
    )
}

fn report(head: NodeId, local: u32, global: Option<u32>, t: ClusterTime, x: f64, y: f64) -> Envelope {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.04;
    }
    env(
        head,
        Message::TrackReport(TrackReport {
            target: TargetId(local),
            global: global.map(TargetId),
            step: 0,
            time: t,
            mean: [x, y, 0.9, 1.0, 0.0, 0.0],
            cov,
            contributors: vec![],
            power_mw: 100.0,
            late: 0,
        }),
    )
}

fn decisions(s: &mut ServerNode) -> Vec<Decision> {
    s.take_records()
        .into_iter()
        .filter_map(|r| match r.record {
            Record::Decision(d) => Some(d),
            _ => None,
        })
        .collect()
}

fn handovers(out: &[Outgoing]) -> Vec<(NodeId, proto::msg::Handover)> {
    out.iter()
        .filter_map(|o| match &o.body {
            Message::Handover(h) => Some((o.to, h.clone())),
            _ => None,
        })
        .collect()
}

/// Both heads and one camera admitted at t = 0.
fn started() -> ServerNode {
    let mut s = server();
    s.on_message(ms(0), hello(H2, Role::Head));
    s.on_message(ms(0), hello(H3, Role::Head));
    s.on_message(ms(0), hello(CAM, Role::Camera));
    s.take_records();
    s
}

#[test]
fn handshake_admits_declared_nodes_and_tells_cameras_their_head() {
    let mut s = server();
    let out = s.on_message(ms(0), hello(CAM, Role::Camera));
    assert!(matches!(&out[0].body, Message::HelloAck(a) if a.accepted));
    assert!(
        out.iter().any(
            |o| o.to == CAM && matches!(&o.body, Message::Assignment(a) if a.node == CAM && a.head == H2)
        )
    );
    assert!(s.membership().is_up(CAM));
}

#[test]
fn bad_handshakes_are_refused_counted_and_change_nothing() {
    let mut s = server();
    for (e, why) in [
        (hello(NodeId(999), Role::Camera), "not in the scenario"),
        (hello(CAM, Role::Head), "declares"),
        (hello(NodeId(5), Role::Server), "second server"),
    ] {
        let out = s.on_message(ms(0), e);
        assert!(
            matches!(&out[0].body, Message::HelloAck(a) if !a.accepted && a.reason.contains(why)),
            "{out:?}"
        );
    }
    let mut wrong_version = hello(CAM, Role::Camera);
    if let Message::Hello(h) = &mut wrong_version.body {
        h.version = PROTOCOL_VERSION + 1;
    }
    s.on_message(ms(0), wrong_version);
    assert_eq!(s.counters().rejected, 4);
    assert_eq!(s.membership().members().count(), 0);
}

#[test]
fn unexpected_messages_are_rejected_without_state_change() {
    let mut s = started();
    // A camera cannot send track reports; an unknown node cannot send anything.
    s.on_message(ms(10), report(CAM, 1, None, ms(10), 1.0, 1.0));
    s.on_message(ms(10), env(NodeId(777), Message::Heartbeat));
    assert_eq!(s.counters().rejected, 2);
    assert_eq!(s.globals().count(), 0);
    assert!(s.membership().member(NodeId(777)).is_none());
    s.on_rejected(ms(11), Some(CAM), "malformed frame: eof");
    assert_eq!(s.counters().rejected, 3);
}

#[test]
fn a_silent_camera_is_reported_down_to_its_head_and_readmitted() {
    let mut s = started();
    s.on_message(ms(900), env(H2, Message::Heartbeat));
    s.on_message(ms(900), env(H3, Message::Heartbeat));
    let out = s.tick(ms(1200));
    assert!(
        out.iter()
            .any(|o| o.to == H2 && matches!(&o.body, Message::Liveness(l) if l.node == CAM && !l.up))
    );
    assert!(!s.membership().is_up(CAM));
    let out = s.on_message(ms(1300), env(CAM, Message::Heartbeat));
    assert!(
        out.iter()
            .any(|o| o.to == H2 && matches!(&o.body, Message::Liveness(l) if l.node == CAM && l.up))
    );
    assert!(s.membership().is_up(CAM));
}

#[test]
fn first_report_gets_a_global_id() {
    let mut s = started();
    s.on_message(ms(100), report(H2, 5, None, ms(100), 2.0, 2.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    assert_eq!(
        decisions(&mut s),
        vec![Decision::NewGlobal {
            head: H2,
            local: TargetId(5),
            global: g
        }]
    );
    let (_, gt) = s.globals().next().unwrap();
    assert_eq!(gt.owner, H2);
}

#[test]
fn leaving_a_region_hands_the_track_over_with_the_last_posterior() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.0, 4.0));
    // Inside the margin: no handover yet.
    let out = s.on_message(ms(200), report(H2, 5, None, ms(200), 6.2, 4.0));
    assert!(handovers(&out).is_empty());
    let out = s.on_message(ms(400), report(H2, 5, None, ms(400), 6.4, 4.1));
    let h = handovers(&out);
    assert_eq!(h.len(), 2, "sent to the new and the old head: {out:?}");
    assert!(h.iter().any(|(to, _)| *to == H3) && h.iter().any(|(to, _)| *to == H2));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    for (_, m) in &h {
        assert_eq!((m.global, m.to_head, m.from_head), (g, H3, Some(H2)));
        assert_eq!(m.mean[..2], [6.4, 4.1]);
        assert_eq!(m.time, ms(400));
    }
    // The new head continues the track under its own local id, carrying the global id.
    s.on_message(ms(600), report(H3, 1, Some(g.0), ms(600), 6.6, 4.1));
    assert_eq!(s.global_of(H3, TargetId(1)), Some(g));
    assert_eq!(s.globals().next().unwrap().1.owner, H3);
}

#[test]
fn a_dead_heads_targets_and_cameras_move_to_a_live_head() {
    let mut s = started();
    s.on_message(ms(100), report(H2, 5, None, ms(100), 3.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // Head 3 and the camera keep talking; head 2 falls silent after t = 100 ms.
    let mut failover_at = None;
    for t in (200..3000).step_by(50) {
        s.on_message(ms(t), env(H3, Message::Heartbeat));
        s.on_message(ms(t), env(CAM, Message::Heartbeat));
        let out = s.tick(ms(t));
        if let Some((_, h)) = handovers(&out).into_iter().find(|(to, _)| *to == H3) {
            assert_eq!(h.global, g);
            assert_eq!(h.mean[..2], [3.0, 4.0]);
            assert!(
                out.iter()
                    .any(|o| o.to == CAM && matches!(&o.body, Message::Assignment(a) if a.head == H3))
            );
            failover_at = Some(t);
            break;
        }
    }
    // Bounded: by the first tick after the liveness timeout (1000 ms) plus one tick.
    let t = failover_at.expect("failover happened");
    assert!(t > 1100 && t <= 1150, "failover at {t} ms");
    assert_eq!(s.membership().head_of(CAM), Some(H3));
    let d = decisions(&mut s);
    assert!(d.contains(&Decision::Handover {
        global: g,
        from: Some(H2),
        to: H3,
        reason: HandoverReason::Failover
    }));
    // Head 2 comes back: its cameras return to it.
    let out = s.on_message(ms(3000), hello(H2, Role::Head));
    assert_eq!(s.membership().head_of(CAM), Some(H2));
    assert!(out.iter().any(|o| o.to == H2
        && matches!(&o.body, Message::Assignment(a) if a.node == CAM && a.head == H2)));
}

#[test]
fn reports_of_one_target_by_two_heads_merge_after_hysteresis_and_split_back() {
    let mut s = started();
    // Head 3's cameras see the target inside head 2's region, near the border.
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    for k in 1..=3i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 5.0 + 0.1 * k as f64, 4.0));
        s.on_message(t, report(H3, 9, None, t, 5.2 + 0.1 * k as f64, 4.0));
        if k < 3 {
            assert_eq!(s.global_of(H3, TargetId(9)), None, "pending at step {k}");
        }
    }
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g));
    assert_eq!(s.globals().count(), 1, "no id flickered into existence");
    // One stray report does not split.
    s.on_message(ms(800), report(H3, 9, None, ms(800), 9.0, 1.0));
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g));
    for k in 5..=6i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 5.4, 4.0));
        s.on_message(t, report(H3, 9, None, t, 9.0, 1.0));
    }
    let split = s.global_of(H3, TargetId(9)).unwrap();
    assert_ne!(split, g);
    assert!(
        decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Split { from, .. } if *from == g))
    );
}

#[test]
fn a_target_far_from_others_is_a_new_target() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 1.0, 1.0));
    s.on_message(ms(0), report(H3, 9, None, ms(0), 10.0, 7.0));
    assert_ne!(s.global_of(H2, TargetId(5)), s.global_of(H3, TargetId(9)));
    assert!(s.global_of(H3, TargetId(9)).is_some());
}

#[test]
fn beacons_go_to_every_live_node_at_the_beacon_period() {
    let mut s = started();
    let beacons = |out: &[Outgoing]| {
        out.iter()
            .filter_map(|o| match &o.body {
                Message::SyncBeacon(b) => Some((o.to, b.round, b.leader_time)),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    let b = beacons(&s.tick(ms(0)));
    assert_eq!(b.len(), 3);
    assert!(b.iter().all(|(_, r, t)| *r == 1 && *t == ms(0)));
    assert!(beacons(&s.tick(ms(500))).is_empty());
    let b = beacons(&s.tick(ms(1000)));
    assert!(b.iter().all(|(_, r, t)| *r == 2 && *t == ms(1000)));
    // Quiet ticks are not journaled; beacon ticks are.
    let ticks = s
        .take_records()
        .iter()
        .filter(|r| r.record == Record::Tick)
        .count();
    assert_eq!(ticks, 2);
}

/// A target crossing from head 2's region into head 3's while both heads' cameras see it near
/// the border: one global id for the whole run, one handover.
#[test]
fn a_crossing_target_keeps_one_global_id() {
    let mut s = started();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut owner = H2;
    let mut carried: Option<u32> = None;
    let mut ids = std::collections::BTreeSet::new();
    let mut handed = 0;
    for k in 0..50i64 {
        let t = ms(k * 200);
        let x = 1.0 + 0.2 * k as f64;
        let noise = |rng: &mut ChaCha8Rng| rng.random_range(-0.1..0.1);
        // The owner always reports; the other head sees the target within 1 m of the border.
        for head in [H2, H3] {
            let sees = head == owner || (x - 6.0).abs() < 1.0;
            if !sees {
                continue;
            }
            let local = if head == H2 { 5 } else { 9 };
            let global = if head == owner { carried } else { None };
            let out = s.on_message(t, report(head, local, global, t, x + noise(&mut rng), 4.0));
            for (to, h) in handovers(&out) {
                if to == h.to_head {
                    owner = to;
                    carried = Some(h.global.0);
                    handed += 1;
                }
            }
            if let Some(g) = s.global_of(head, TargetId(local)) {
                ids.insert(g);
            }
        }
    }
    assert_eq!(ids.len(), 1, "ids seen: {ids:?}");
    assert_eq!(handed, 1);
    assert_eq!(owner, H3);
}

#[test]
fn restore_rebuilds_the_same_state_and_reproduces_decisions() {
    let cfg = ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1));
    let mut s = ServerNode::new(cfg.clone());
    let mut records = Vec::new();
    s.on_message(ms(0), hello(H2, Role::Head));
    s.on_message(ms(0), hello(H3, Role::Head));
    s.on_message(ms(0), hello(CAM, Role::Camera));
    for k in 0..40i64 {
        let t = ms(k * 100);
        if k < 15 {
            s.on_message(t, env(H2, Message::Heartbeat));
        }
        s.on_message(t, env(H3, Message::Heartbeat));
        s.on_message(
            t,
            env(
                CAM,
                Message::NodeStatus(NodeStatus {
                    mode: Mode::Active,
                    time_in_mode_ns: [k as u64, 0, 0],
                    frames: 0,
                    detections: 0,
                    dropped: 0,
                    rejected: 0,
                    sync_offset_ns: 0,
                    sync_error_ns: 1000,
                }),
            ),
        );
        if k < 12 {
            s.on_message(t, report(H2, 5, None, t, 3.0 + 0.1 * k as f64, 4.0));
        }
        s.tick(t);
        records.extend(s.take_records());
    }
    let (r, stats) = ServerNode::restore(cfg, &records);
    assert_eq!(stats.decisions_mismatched, 0);
    assert!(stats.decisions_matched > 5, "{stats:?}");
    let a: Vec<_> = s.globals().map(|(g, t)| (g, t.clone())).collect();
    let b: Vec<_> = r.globals().map(|(g, t)| (g, t.clone())).collect();
    assert_eq!(a, b);
    assert_eq!(a[0].1.owner, H3, "failover was replayed");
    let ma: Vec<_> = s.membership().members().map(|(i, m)| (i, m.clone())).collect();
    let mb: Vec<_> = r.membership().members().map(|(i, m)| (i, m.clone())).collect();
    assert_eq!(ma, mb);
    assert_eq!(s.statuses(), r.statuses());
}

#[test]
fn resume_gives_nodes_a_grace_period() {
    let mut s = started();
    s.on_message(ms(100), report(H2, 5, None, ms(100), 3.0, 4.0));
    // The server was down for 10 s; without the grace everything would expire at once.
    s.resume(ms(10_000), 0, 0);
    s.tick(ms(10_100));
    assert!(s.membership().is_up(H2) && s.membership().is_up(CAM));
    assert_eq!(s.globals().count(), 1);
    s.tick(ms(11_200));
    assert!(!s.membership().is_up(H2));
}

#[test]
fn a_closed_link_marks_a_head_down_at_once_and_replays() {
    let cfg = ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1));
    let mut s = ServerNode::new(cfg.clone());
    let mut records = Vec::new();
    // Over TCP the transport does the handshake; the core sees links come up.
    for n in [H2, H3, CAM] {
        s.on_link(ms(0), n, true);
    }
    assert!(s.membership().is_up(H2));
    s.on_message(ms(100), report(H2, 5, None, ms(100), 3.0, 4.0));
    let out = s.on_link(ms(150), H2, false);
    assert!(!s.membership().is_up(H2));
    assert!(
        out.iter()
            .any(|o| o.to == CAM && matches!(&o.body, Message::Assignment(a) if a.head == H3))
    );
    let out = s.tick(ms(160));
    assert!(
        handovers(&out)
            .iter()
            .any(|(to, h)| *to == H3 && h.from_head == Some(H2))
    );
    records.extend(s.take_records());
    let (r, stats) = ServerNode::restore(cfg, &records);
    assert_eq!(stats.decisions_mismatched, 0);
    assert_eq!(r.globals().next().unwrap().1.owner, H3);
}

/// Head 2 tracks the target in its own region; head 3 sees it from afar, badly.
#[test]
fn a_far_heads_poor_estimate_never_founds_a_second_global() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 3.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // Head 3's track sits 1.5 m off, inside head 2's region: it never gets an id of its own.
    for k in 1..=10i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 3.0, 4.0));
        s.on_message(t, report(H3, 9, None, t, 1.5, 4.0));
        assert_eq!(s.global_of(H3, TargetId(9)), None, "step {k}");
    }
    // Once it agrees it merges; when it drifts off again it loses the id instead of splitting.
    for k in 11..=13i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 3.0, 4.0));
        s.on_message(t, report(H3, 9, None, t, 3.2, 4.0));
    }
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g));
    for k in 14..=20i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 3.0, 4.0));
        s.on_message(t, report(H3, 9, None, t, 1.2, 4.0));
    }
    assert_eq!(s.global_of(H3, TargetId(9)), None);
    assert_eq!(s.globals().count(), 1);
    assert!(
        !decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Split { .. } | Decision::NewGlobal { head: H3, .. }))
    );
}

/// After a handover the old head drops its track; a track it starts again on the target (still
/// near the border) merges back into the global instead of founding a new one.
#[test]
fn the_old_heads_new_track_on_a_handed_over_target_merges_back() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 6.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    let out = s.on_message(ms(200), report(H2, 5, None, ms(200), 6.3, 4.0));
    assert_eq!(handovers(&out).len(), 2);
    for k in 2..=5i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H3, 1, Some(g.0), t, 6.3, 4.0));
        s.on_message(t, report(H2, 6, None, t, 6.2, 4.0));
    }
    assert_eq!(s.global_of(H2, TargetId(6)), Some(g));
    assert_eq!(s.globals().count(), 1);
}
