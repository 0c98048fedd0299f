//! The viewers' feed against the small test scenario (server 1, heads 2 and 3 splitting the
//! room at x = 6, cameras 10 and 11).

use super::MAX_VIEWERS;
use crate::core::{ServerConfig, ServerNode};
use crate::decision::Decision;
use crate::record::Record;
use proto::msg::{
    Contributor, Kinds, Message, NodeStatus, ObservationKind, TrackReport, ViewSubscribe, ViewUpdate,
};
use proto::node::Outgoing;
use proto::view::{HandoverCause, MAX_VIEW_NODES, MAX_VIEW_TRACKS};
use proto::{ClusterTime, Envelope, Mode, NodeId, Role, TargetId};

const VIEWER: NodeId = NodeId(900);
const H2: NodeId = NodeId(2);
const H3: NodeId = NodeId(3);

fn ms(v: i64) -> ClusterTime {
    ClusterTime::from_millis(v)
}

fn server() -> ServerNode {
    ServerNode::new(ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1)))
}

fn env(source: NodeId, seq: u64, body: Message) -> Envelope {
    Envelope {
        source,
        seq,
        time: ClusterTime::ZERO,
        body,
    }
}

fn subscribe(s: &mut ServerNode, at: i64, who: NodeId) -> Vec<Outgoing> {
    s.on_message(
        ms(at),
        env(who, 0, Message::ViewSubscribe(ViewSubscribe { period_ms: 0 })),
    )
}

fn report(head: NodeId, seq: u64, local: u32, at: i64, x: f64) -> Envelope {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.04 + i as f64 * 0.01;
    }
    env(
        head,
        seq,
        Message::TrackReport(TrackReport {
            target: TargetId(local),
            global: None,
            step: seq,
            time: ms(at),
            mean: [x, 4.0, 0.9, 1.0, 0.0, 0.0],
            cov,
            contributors: vec![Contributor {
                node: NodeId(10),
                kinds: Kinds::of(ObservationKind::Pinhole),
            }],
            power_mw: 100.0,
            late: seq / 10,
            appearance: Vec::new(),
            grid: None,
            captured: None,
        }),
    )
}

fn updates(out: &[Outgoing], to: NodeId) -> Vec<ViewUpdate> {
    out.iter()
        .filter(|o| o.to == to)
        .filter_map(|o| match &o.body {
            Message::ViewUpdate(u) => Some(u.clone()),
            _ => None,
        })
        .collect()
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

#[test]
fn a_viewer_is_admitted_and_sent_every_track_and_node_at_the_step_rate() {
    let mut s = server();
    assert!(subscribe(&mut s, 0, VIEWER).is_empty());
    assert!(decisions(&mut s).contains(&Decision::Admitted {
        node: VIEWER,
        role: Role::Viewer
    }));
    let status = NodeStatus {
        mode: Mode::CameraOff,
        time_in_mode_ns: [0; 3],
        frames: 7,
        detections: 3,
        dropped: 2,
        rejected: 1,
        sync_offset_ns: 10,
        sync_error_ns: 300_000,
        bytes_sent: 0,
    };
    s.on_message(ms(10), env(NodeId(10), 0, Message::NodeStatus(status.clone())));
    // Head 2 reports a track at 5 Hz; one of its frames (seq 3) never arrives.
    let mut rounds = Vec::new();
    for (i, seq) in [0u64, 1, 2, 4, 5, 6, 7, 8, 9, 10].into_iter().enumerate() {
        let at = 100 + 200 * i as i64;
        s.on_message(ms(at), report(H2, seq, 1, at, 2.0 + 0.2 * i as f64));
        subscribe(&mut s, at, VIEWER); // renewed, as a viewer does
        for tick in [at + 50, at + 100, at + 150] {
            rounds.extend(updates(&s.tick(ms(tick)), VIEWER));
        }
    }
    // One round per 200 ms step (the scenario's), 2 s of ticks.
    assert!((9..=11).contains(&rounds.len()), "{} rounds", rounds.len());
    assert!(rounds.windows(2).all(|w| w[1].round == w[0].round + 1));
    let last = rounds.last().unwrap();
    assert_eq!((last.part, last.parts), (0, 1));
    let t = &last.tracks[0];
    assert_eq!((t.global, t.owner, t.local), (TargetId(1), H2, Some(TargetId(1))));
    assert!((t.mean[0] - 3.8).abs() < 1e-9, "{t:?}");
    assert_eq!(t.cov_pos, [0.04, 0.0, 0.0, 0.05, 0.0, 0.06]);
    assert_eq!(t.contributors.len(), 1);
    let node = |id: u32| last.nodes.iter().find(|n| n.node == NodeId(id)).unwrap();
    let ids: Vec<u32> = last.nodes.iter().map(|n| n.node.0).collect();
    assert_eq!(
        ids,
        vec![1, 2, 3, 10, 11, 900],
        "every declared node and the viewer"
    );
    assert_eq!(last.nodes_total, 6);
    assert!(node(1).up && node(1).role == Role::Server);
    assert!(node(2).up && node(2).steps == 10 && node(2).late == 1);
    assert_eq!(node(2).lost, 1, "the missing seq 3");
    assert!(!node(3).up && node(3).silent_ms == u64::MAX, "never heard from");
    assert_eq!(node(10).status, Some(status));
    assert_eq!(node(10).head, Some(H2));
    assert_eq!(node(900).role, Role::Viewer);
    assert!(last.counters.received >= 11);
}

#[test]
fn handovers_reach_the_viewer_once_each_with_their_cause() {
    let mut s = server();
    subscribe(&mut s, 0, VIEWER);
    s.on_message(ms(0), env(H3, 0, Message::Heartbeat));
    let mut seen = Vec::new();
    for i in 0..40 {
        let at = 100 + 200 * i;
        let x = 4.0 + 0.2 * i as f64;
        s.on_message(ms(at), report(H2, i as u64, 1, at, x));
        s.on_message(ms(at), env(H3, i as u64 + 1, Message::Heartbeat));
        subscribe(&mut s, at, VIEWER);
        for u in updates(&s.tick(ms(at + 100)), VIEWER) {
            for h in u.handovers {
                if !seen.iter().any(|s: &proto::view::ViewHandover| s.seq == h.seq) {
                    seen.push(h);
                }
            }
        }
    }
    // The first is the region handover; each is seen once, in order.
    let h = &seen[0];
    assert_eq!(
        (h.global, h.from, h.to, h.cause),
        (TargetId(1), Some(H2), H3, HandoverCause::Region)
    );
    assert!(seen.windows(2).all(|w| w[1].seq > w[0].seq), "{seen:?}");
}

#[test]
fn a_viewer_has_no_say() {
    let mut s = server();
    // An id the scenario gives a camera cannot subscribe.
    subscribe(&mut s, 0, NodeId(10));
    assert!(matches!(
        decisions(&mut s).as_slice(),
        [Decision::Rejected { source: Some(NodeId(10)), what, reason }] if what == "view_subscribe" && reason.contains("camera")
    ));
    subscribe(&mut s, 0, VIEWER);
    decisions(&mut s);
    // What a viewer sends beyond its subscription is rejected and changes nothing.
    let out = s.on_message(ms(10), report(VIEWER, 1, 1, 10, 2.0));
    assert!(out.is_empty());
    assert_eq!(s.globals().count(), 0);
    assert!(matches!(
        decisions(&mut s).as_slice(),
        [Decision::Rejected { .. }]
    ));
    let fake = env(
        VIEWER,
        2,
        Message::ViewUpdate(
            proto::examples::messages()
                .into_iter()
                .find_map(|e| match e.body {
                    Message::ViewUpdate(u) => Some(u),
                    _ => None,
                })
                .expect("the ViewUpdate fixture"),
        ),
    );
    s.on_message(ms(20), fake);
    assert_eq!(s.counters().rejected, 3);
    let last = updates(&s.tick(ms(300)), VIEWER).pop().unwrap();
    let me = last.nodes.iter().find(|n| n.node == VIEWER).unwrap();
    assert_eq!(me.rejected, 2, "its own rejected messages are counted");
    // At most MAX_VIEWERS at once.
    for k in 1..MAX_VIEWERS as u32 {
        subscribe(&mut s, 400, NodeId(900 + k));
    }
    decisions(&mut s);
    subscribe(&mut s, 400, NodeId(999));
    assert!(matches!(
        decisions(&mut s).as_slice(),
        [Decision::Rejected { reason, .. }] if reason.contains("viewers are subscribed already")
    ));
}

#[test]
fn a_silent_viewer_gets_nothing_until_it_speaks_again() {
    let mut s = server();
    subscribe(&mut s, 0, VIEWER);
    assert_eq!(updates(&s.tick(ms(50)), VIEWER).len(), 1);
    // Liveness timeout 1 s: marked down, no more updates.
    let out = s.tick(ms(1500));
    assert!(updates(&out, VIEWER).is_empty());
    assert!(
        decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Down { node, .. } if *node == VIEWER))
    );
    assert!(updates(&s.tick(ms(1800)), VIEWER).is_empty());
    subscribe(&mut s, 1900, VIEWER);
    assert!(decisions(&mut s).contains(&Decision::Up { node: VIEWER }));
    assert_eq!(updates(&s.tick(ms(2000)), VIEWER).len(), 1);
}

#[test]
fn a_large_cluster_is_sent_in_parts_that_each_fit_a_frame() {
    let mut sc = crate::testkit::scenario();
    let camera = sc.nodes.iter().find(|n| n.id == 10).unwrap().clone();
    for id in 100..180 {
        let mut c = camera.clone();
        c.id = id;
        sc.nodes.push(c);
    }
    let mut s = ServerNode::new(ServerConfig::from_scenario(sc, NodeId(1)));
    subscribe(&mut s, 0, VIEWER);
    // Sixty targets far apart: sixty globals.
    for local in 0..60u32 {
        // A grid 1.2 m by 1.4 m apart, farther than the merge gate.
        let mut r = report(H2, u64::from(local), local, 10, 0.5 + 1.2 * f64::from(local % 10));
        if let Message::TrackReport(t) = &mut r.body {
            t.mean[1] = 0.5 + 1.4 * f64::from(local / 10);
        }
        s.on_message(ms(10), r);
    }
    let globals = s.globals().count();
    assert!(globals > MAX_VIEW_TRACKS, "{globals} globals");
    let round = updates(&s.tick(ms(50)), VIEWER);
    let nodes: usize = 5 + 80 + 1;
    let parts = globals
        .div_ceil(MAX_VIEW_TRACKS)
        .max(nodes.div_ceil(MAX_VIEW_NODES));
    assert_eq!(round.len(), parts);
    let mut tracks = 0;
    let mut listed = 0;
    for (i, u) in round.iter().enumerate() {
        assert_eq!((usize::from(u.part), usize::from(u.parts)), (i, parts));
        assert_eq!(u.tracks_total as usize, globals);
        tracks += u.tracks.len();
        listed += u.nodes.len();
        let e = Envelope {
            source: NodeId(1),
            seq: u64::MAX,
            time: ClusterTime(i64::MAX),
            body: Message::ViewUpdate(u.clone()),
        };
        let frame = proto::encode(&e).expect("each part encodes within the frame limit");
        assert_eq!(proto::decode(&frame).unwrap(), e);
    }
    assert_eq!((tracks, listed), (globals, nodes));
}

#[test]
fn a_restored_server_feeds_viewers_what_the_original_did() {
    let mut s = server();
    let mut inputs = Vec::new();
    let mut feed = |s: &mut ServerNode, at: i64, e: Envelope| {
        s.on_message(ms(at), e);
        inputs.extend(s.take_records());
    };
    let renew = || {
        env(
            VIEWER,
            0,
            Message::ViewSubscribe(ViewSubscribe { period_ms: 400 }),
        )
    };
    for i in 0..20 {
        let at = 100 + 200 * i;
        feed(&mut s, at, report(H2, i as u64 * 2, 1, at, 4.0 + 0.25 * i as f64));
        feed(&mut s, at, env(H3, i as u64, Message::Heartbeat));
        feed(&mut s, at, renew());
    }
    let (mut restored, _) = ServerNode::restore(
        ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1)),
        &inputs,
    );
    let a = updates(&s.tick(ms(4000)), VIEWER);
    let b = updates(&restored.tick(ms(4000)), VIEWER);
    assert_eq!(a.len(), 1);
    assert_eq!(a, b);
    assert!(!a[0].handovers.is_empty() && a[0].nodes.iter().any(|n| n.lost > 0));
}
