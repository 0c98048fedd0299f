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

mod appearance;
mod handover;
mod regions;

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
            appearance: Vec::new(),
            grid: None,
            captured: None,
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
/// Only head 3 (and the camera) up: nothing covers head 2's area, so head 3 may found targets
/// there (authority follows live regions).
fn started_without_h2() -> ServerNode {
    let mut s = server();
    s.on_message(ms(0), hello(H3, Role::Head));
    s.on_message(ms(0), hello(CAM, Role::Camera));
    s.take_records();
    s
}

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

/// A stranger (an id the scenario does not declare) flooding the server changes nothing and
/// leaves nothing in the recording: not its messages, not a decision per message, not its
/// link events. It is counted.
#[test]
fn strangers_never_reach_the_recording() {
    let mut s = started();
    let stranger = NodeId(4242);
    s.on_link(ms(5), stranger, true);
    for k in 0..1000 {
        s.on_message(ms(10 + k), env(stranger, Message::Heartbeat));
        s.on_message(ms(10 + k), report(stranger, 1, None, ms(10 + k), 1.0, 1.0));
        s.on_message(ms(10 + k), hello(stranger, Role::Camera));
    }
    s.on_link(ms(2000), stranger, false);
    assert!(s.take_records().is_empty());
    assert_eq!(s.counters().non_members, 3000);
    assert_eq!(s.globals().count(), 0);
    assert!(s.membership().member(stranger).is_none());
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

/// Heads say how loud they hear each tag and are answered with each tag's home (here no
/// track is known to the server, so the louder cluster), the former home at once too; a
/// camera's word on tags is rejected and names no home. A restore from the recording rebuilds
/// the homes.
#[test]
fn each_tag_is_homed_and_a_former_home_is_told_at_once() {
    use proto::TagId;
    use proto::msg::TagHome;
    let mut s = started();
    let heard = |head: NodeId, tags: &[(u64, f32)]| env(head, proto::examples::tags_heard(tags));
    let homes = |out: &[Outgoing], to: NodeId| -> Vec<TagHome> {
        out.iter()
            .filter(|o| o.to == to)
            .find_map(|o| match &o.body {
                Message::TagHomes(h) => Some(h.homes.clone()),
                _ => None,
            })
            .unwrap_or_default()
    };
    // (The tracks these tags claim have no global: the server named none.)
    let home = |tag: u64, head: NodeId| TagHome {
        tag: TagId(tag),
        head,
        shared: false,
    };
    let out = s.on_message(ms(100), heard(H2, &[(7, -78.0), (8, -60.0)]));
    assert_eq!(homes(&out, H2), vec![home(7, H2), home(8, H2)]);
    let out = s.on_message(ms(200), heard(H3, &[(7, -55.0)]));
    assert_eq!(homes(&out, H3), vec![home(7, H3)]);
    // The former home is told at once, not at its next word.
    assert_eq!(homes(&out, H2), vec![home(7, H3)]);
    let out = s.on_message(ms(1100), heard(H2, &[(7, -77.0), (8, -61.0)]));
    assert_eq!(homes(&out, H2), vec![home(7, H3), home(8, H2)]);
    assert_eq!(s.counters().tag_home_moves, 1);
    let rejected = s.counters().rejected;
    let out = s.on_message(ms(1200), heard(CAM, &[(7, -30.0)]));
    assert!(homes(&out, CAM).is_empty());
    assert_eq!(s.counters().rejected, rejected + 1);
    let (mut restored, _) = ServerNode::restore(s.config().clone(), &s.take_records());
    let out = restored.on_message(ms(1300), heard(H2, &[(7, -77.0)]));
    assert_eq!(homes(&out, H2), vec![home(7, H3)]);
}

/// A camera's logging-run frame is recorded as `Record::Measured` and changes nothing else
/// (not even who is a member); from a head it is an input, rejected and recorded as received.
#[test]
fn a_cameras_measured_frame_is_recorded_and_nothing_else() {
    let mut s = server();
    let frame = proto::msg::MeasuredFrame {
        captured: ms(40),
        rssi: vec![proto::msg::RssiReading {
            tag: proto::TagId(5),
            dbm: -60.0,
            time: ms(39),
        }],
        detections: Vec::new(),
    };
    let out = s.on_message(ms(42), env(CAM, Message::MeasuredFrame(frame.clone())));
    assert!(out.is_empty());
    assert!(s.membership().member(CAM).is_none());
    let records = s.take_records();
    assert_eq!(records.len(), 1, "{records:?}");
    assert_eq!(records[0].at, ms(42));
    assert_eq!(
        records[0].record,
        Record::Measured(crate::record::MeasuredFrame::from_wire(CAM, &frame))
    );
    s.on_message(ms(43), env(H2, Message::MeasuredFrame(frame)));
    assert_eq!(s.counters().rejected, 1);
    assert!(matches!(s.take_records()[0].record, Record::Received(_)));
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
    let out = s.on_message(ms(100), report(H2, 5, None, ms(100), 2.0, 2.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // The head is told the id by a naming handover to itself.
    let named = handovers(&out);
    assert_eq!(named.len(), 1);
    assert_eq!(
        (named[0].0, named[0].1.to_head, named[0].1.from_head),
        (H2, H2, None)
    );
    assert_eq!(named[0].1.global, g);
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
    // A report that already carries an (unknown) id gets a new one but is not named again.
    let out = s.on_message(ms(300), report(H2, 6, Some(77), ms(300), 2.0, 6.0));
    assert!(handovers(&out).is_empty());
    assert!(s.global_of(H2, TargetId(6)).is_some_and(|x| x != g));
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
    // Head 2 comes back: its cameras return to it, and head 3 hears it is up (it was told
    // it was down: its floor was anybody's meanwhile).
    let out = s.on_message(ms(3000), hello(H2, Role::Head));
    let told_h3: Vec<(NodeId, bool)> = out
        .iter()
        .filter(|o| o.to == H3)
        .filter_map(|o| match &o.body {
            Message::Liveness(l) => Some((l.node, l.up)),
            _ => None,
        })
        .collect();
    assert_eq!(told_h3, vec![(H2, true)]);
    assert_eq!(s.membership().head_of(CAM), Some(H2));
    assert!(out.iter().any(|o| o.to == H2
        && matches!(&o.body, Message::Assignment(a) if a.node == CAM && a.head == H2)));
}

/// A head that never comes up: after the start-up grace its cameras go to the live head, and
/// that head hears it is down (a head starts no track on a live head's floor, so its floor
/// would stay untracked for good).
#[test]
fn a_head_that_never_came_up_leaves_its_floor_and_cameras_to_the_live_head() {
    let mut s = started_without_h2();
    let liveness_to_h3 = |out: &[Outgoing]| -> Vec<(NodeId, bool)> {
        out.iter()
            .filter(|o| o.to == H3)
            .filter_map(|o| match &o.body {
                Message::Liveness(l) if l.node == H2 => Some((l.node, l.up)),
                _ => None,
            })
            .collect()
    };
    let mut given = None;
    for t in (50..=11_000).step_by(50) {
        s.on_message(ms(t), env(H3, Message::Heartbeat));
        s.on_message(ms(t), env(CAM, Message::Heartbeat));
        let out = s.tick(ms(t));
        if !liveness_to_h3(&out).is_empty() {
            assert_eq!(liveness_to_h3(&out), vec![(H2, false)]);
            assert!(
                out.iter().any(|o| o.to == H3
                    && matches!(&o.body, Message::Assignment(a) if a.node == CAM && a.head == H3)),
                "head 2's camera goes to head 3"
            );
            given = Some(t);
            break;
        }
    }
    let t = given.expect("head 2 declared down");
    assert!(t > 10_000, "not before the grace: {t} ms");
    assert!(
        decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Down { node, .. } if *node == H2))
    );
    assert_eq!(s.membership().head_of(CAM), Some(H3));
    // It starts at last: its camera goes home and head 3 leaves its floor to it again.
    let out = s.on_message(ms(12_000), hello(H2, Role::Head));
    assert_eq!(liveness_to_h3(&out), vec![(H2, true)]);
    assert_eq!(s.membership().head_of(CAM), Some(H2));
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
    // The global id each simulated head labels its track with (learned from handovers).
    let mut label: std::collections::BTreeMap<NodeId, u32> = Default::default();
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
            let global = label.get(&head).copied();
            let out = s.on_message(t, report(head, local, global, t, x + noise(&mut rng), 4.0));
            for (to, h) in handovers(&out) {
                if to == h.to_head {
                    label.insert(to, h.global.0);
                }
                if let Some(from) = h.from_head
                    && to == h.to_head
                    && from != to
                {
                    owner = to;
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
                    bytes_sent: 0,
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
    assert_eq!(r.sync_errors(), vec![(CAM, 1000)]);
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

#[test]
fn a_head_restarting_its_track_of_a_target_keeps_the_global_id() {
    let mut s = started();
    // The target moves at 1 m/s in x (the reports' velocity).
    let x = |k: i64| 1.0 + 0.2 * k as f64;
    for k in 0..5i64 {
        s.on_message(ms(k * 200), report(H2, 5, None, ms(k * 200), x(k), 4.0));
    }
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // Track 5 falls silent; a second later the head starts track 6 at the same place.
    for k in 10..14i64 {
        s.on_message(ms(k * 200), report(H2, 6, None, ms(k * 200), x(k) + 0.05, 4.0));
    }
    assert_eq!(s.global_of(H2, TargetId(6)), Some(g));
    assert_eq!(s.globals().count(), 1);
    // While track 5 is still live, a second track of the same head is a different target.
    s.on_message(ms(2800), report(H2, 7, None, ms(2800), x(14), 4.0));
    assert_ne!(s.global_of(H2, TargetId(7)), Some(g));
}

#[test]
fn a_track_that_leaves_its_global_for_another_joins_that_one() {
    let mut s = started();
    // Head 2 tracks two targets, 3 m apart and still (velocity 1 m/s in the reports is matched
    // by moving them along x).
    let x = |k: i64| 1.0 + 0.2 * k as f64;
    let mut g = Vec::new();
    for k in 0..4i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 1, None, t, x(k), 2.0));
        s.on_message(t, report(H2, 2, None, t, x(k), 5.0));
        // Head 3 sees the first one.
        s.on_message(t, report(H3, 9, None, t, x(k) + 0.1, 2.0));
    }
    g.push(s.global_of(H2, TargetId(1)).unwrap());
    g.push(s.global_of(H2, TargetId(2)).unwrap());
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g[0]));
    // Head 3's track jumps onto the second target (an association swap in its cameras).
    for k in 4..8i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 1, None, t, x(k), 2.0));
        s.on_message(t, report(H2, 2, None, t, x(k), 5.0));
        s.on_message(t, report(H3, 9, None, t, x(k) + 0.1, 5.0));
    }
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g[1]));
    assert_eq!(s.globals().count(), 2, "no new id for a known target");
}

/// A pending track that leaves the global it was pending on, for another global, joins that
/// one: no id is founded for a target that has one.
#[test]
fn a_pending_track_that_leaves_its_global_for_another_joins_that_one() {
    let mut s = started();
    // Two people standing 3 m apart on head 2's side of the border (x = 6), within the
    // handover margin of head 3's region: head 3's tracks there are its own, not foreign.
    let still = |head: NodeId, local: u32, t: ClusterTime, y: f64| {
        let mut e = report(head, local, None, t, 5.9, y);
        if let Message::TrackReport(r) = &mut e.body {
            r.mean[3] = 0.0;
        }
        e
    };
    let both = |s: &mut ServerNode, t: ClusterTime| {
        s.on_message(t, still(H2, 1, t, 2.0));
        s.on_message(t, still(H2, 2, t, 5.0));
    };
    both(&mut s, ms(0));
    let g = [
        s.global_of(H2, TargetId(1)).unwrap(),
        s.global_of(H2, TargetId(2)).unwrap(),
    ];
    // Head 3 starts a track on the first: pending on its global.
    both(&mut s, ms(200));
    s.on_message(ms(200), still(H3, 9, ms(200), 2.0));
    assert_eq!(s.global_of(H3, TargetId(9)), None, "pending");
    // Its cameras' filter jumps onto the second before the hysteresis is up.
    for k in 2..5i64 {
        let t = ms(k * 200);
        both(&mut s, t);
        s.on_message(t, still(H3, 9, t, 5.0));
    }
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g[1]));
    assert_eq!(s.globals().count(), 2, "no new id for a known target");
    let d = decisions(&mut s);
    assert!(
        d.contains(&Decision::Merged {
            head: H3,
            local: TargetId(9),
            global: g[1],
        }),
        "{d:?}"
    );
}

#[test]
fn two_globals_that_stay_together_become_one() {
    let mut s = started();
    // On the cluster border (x = 6) each head's cameras start a track of their own, 1.5 m
    // apart (beyond the gate): two globals at first…
    let x = |k: i64| 6.0 + 0.02 * k as f64;
    s.on_message(ms(0), report(H2, 1, None, ms(0), x(0), 2.0));
    s.on_message(ms(0), report(H3, 9, None, ms(0), x(0), 3.5));
    let (a, b) = (
        s.global_of(H2, TargetId(1)).unwrap(),
        s.global_of(H3, TargetId(9)).unwrap(),
    );
    assert_ne!(a, b);
    // …then both converge on the same target: after the hysteresis the younger is absorbed.
    for k in 1..6i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 1, None, t, x(k), 2.0));
        s.on_message(t, report(H3, 9, None, t, x(k), 2.1));
        if k < 3 {
            assert_eq!(s.globals().count(), 2, "not before the hysteresis (step {k})");
        }
    }
    assert_eq!(s.globals().count(), 1);
    assert_eq!(s.global_of(H3, TargetId(9)), Some(a));
    assert!(decisions(&mut s).contains(&Decision::Absorbed { global: b, into: a }));
}

#[test]
fn two_people_one_head_tracks_side_by_side_keep_two_globals() {
    let mut s = started();
    let x = |k: i64| 1.0 + 0.1 * k as f64;
    // Two people walk side by side 0.6 m apart (inside the 1 m gate): head 2 tracks each; the
    // server ticks between reports.
    for k in 0..25i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 1, None, t, x(k), 2.0));
        s.on_message(t, report(H2, 2, None, t, x(k), 2.6));
        s.tick(ms(k * 200 + 100));
    }
    let (a, b) = (s.global_of(H2, TargetId(1)), s.global_of(H2, TargetId(2)));
    assert!(a.is_some() && b.is_some() && a != b, "{a:?} {b:?}");
    assert_eq!(s.globals().count(), 2);
    assert!(
        !decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Absorbed { .. }))
    );
}

/// Over TCP the transport's heartbeats stay inside the transport; the core hears a camera only
/// when it sends its status (about once a second). Its live link keeps it up all the same: no
/// down/up flapping however quiet it is, and down at once when the link goes.
#[test]
fn a_member_with_a_live_link_never_flaps_and_goes_down_with_its_link() {
    let mut s = server();
    for n in [H2, CAM] {
        s.on_link(ms(0), n, true);
    }
    let mut decisions = 0;
    for k in 1..=200 {
        // A status every 1.05 s against a 1 s timeout; ticks every 50 ms for 10 s.
        if k % 21 == 0 {
            s.on_message(ms(k * 50), env(CAM, Message::Heartbeat));
        }
        s.tick(ms(k * 50));
    }
    for r in s.take_records() {
        if let Record::Decision(Decision::Down { .. } | Decision::Up { .. }) = r.record {
            decisions += 1;
        }
    }
    assert_eq!(decisions, 0, "liveness flapped");
    assert!(s.membership().is_up(CAM));
    s.on_link(ms(10_100), CAM, false);
    assert!(!s.membership().is_up(CAM));
}
