//! A viewer core and a server core wired by hand (no transport): what the server's feed
//! carries ends up in the view, the pages' JSON and every metric.

use super::{ViewerConfig, ViewerNode, free_id};
use crate::feed::channel;
use crate::state::{NodeKind, ViewState};
use node_server::{ServerConfig, ServerNode};
use proto::msg::{Contributor, Kinds, Message, NodeStatus, ObservationKind, TrackReport};
use proto::node::{Input, Node, Outgoing};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, Mode, NodeId, TargetId};
use std::sync::Arc;

fn ms(v: i64) -> ClusterTime {
    ClusterTime::from_millis(v)
}

struct Wire {
    server: ServerNode,
    viewer: ViewerNode,
    seq: u64,
}

impl Wire {
    fn new() -> Wire {
        let sc = Scenario::default_scenario();
        let id = free_id(&sc);
        let cfg = ViewerConfig::for_scenario(&sc, id).unwrap();
        Wire {
            server: ServerNode::new(ServerConfig::from_scenario(sc.clone(), NodeId(1))),
            viewer: ViewerNode::new(cfg, ViewState::with_scenario(&sc)),
            seq: 0,
        }
    }

    /// Deliver what one side sent to the other (a server's messages to others are dropped).
    fn deliver(&mut self, at: i64, out: Vec<Outgoing>, to_server: bool) {
        for o in out {
            self.seq += 1;
            let env = |source| Envelope {
                source,
                seq: self.seq,
                time: ms(at),
                body: o.body.clone(),
            };
            if to_server {
                let back = self.server.on_message(ms(at), env(self.viewer.id()));
                self.deliver(at, back, false);
            } else if o.to == self.viewer.id() {
                self.viewer.handle(ms(at), Input::Message(env(NodeId(1))));
            }
        }
    }

    fn step(&mut self, at: i64) {
        let out = self.viewer.handle(ms(at), Input::Tick);
        self.deliver(at, out, true);
        let out = self.server.tick(ms(at));
        self.deliver(at, out, false);
    }
}

fn from(node: u32, seq: u64, at: i64, body: Message) -> Envelope {
    Envelope {
        source: NodeId(node),
        seq,
        time: ms(at),
        body,
    }
}

#[test]
fn the_feed_fills_the_view_and_every_metric_from_real_data() {
    let mut w = Wire::new();
    assert_eq!(w.viewer.id(), NodeId(900));
    let status = |mode| NodeStatus {
        mode,
        time_in_mode_ns: [0; 3],
        frames: 50,
        detections: 20,
        dropped: 3,
        rejected: 2,
        sync_offset_ns: 1_000,
        sync_error_ns: 250_000,
        bytes_sent: 0,
    };
    for i in 0..30i64 {
        let at = 100 + 200 * i;
        let seq = u64::try_from(i).unwrap();
        // Head 2 reports a target walking east; frame 5 of head 2 is lost on the way.
        if i != 5 {
            let report = TrackReport {
                target: TargetId(4),
                global: None,
                step: seq + 1,
                time: ms(at),
                mean: [1.0 + 0.1 * i as f64, 2.0, 0.8, 0.5, 0.0, 0.0],
                cov: std::array::from_fn(|r| std::array::from_fn(|c| if r == c { 0.02 } else { 0.0 })),
                contributors: vec![Contributor {
                    node: NodeId(10),
                    kinds: Kinds::of(ObservationKind::Pinhole),
                }],
                power_mw: 900.0,
                late: seq / 4,
                appearance: Vec::new(),
                grid: None,
                captured: None,
            };
            w.server
                .on_message(ms(at), from(2, seq, at, Message::TrackReport(report)));
        }
        w.server.on_message(
            ms(at),
            from(10, seq, at, Message::NodeStatus(status(Mode::CameraOff))),
        );
        w.server.on_message(
            ms(at),
            from(2, 1000 + seq, at, Message::NodeStatus(status(Mode::Active))),
        );
        // A node the server does not know is rejected.
        if i == 3 {
            w.server.on_message(
                ms(at),
                from(
                    10,
                    100,
                    at,
                    Message::Priors(proto::msg::Priors {
                        part: 0,
                        parts: 1,
                        tracks: vec![proto::msg::Prior {
                            target: TargetId(1),
                            step: 0,
                            mean: [0.0; 6],
                            cov: [[0.0; 6]; 6],
                            deadline: ms(0),
                            radio: false,
                        }],
                    }),
                ),
            );
        }
        w.step(at + 50);
    }
    let v = w.viewer.state();
    assert!(w.viewer.counters().updates >= 25, "{:?}", w.viewer.counters());
    let t = &v.tracks[&1];
    assert_eq!((t.owner, t.local), (2, 4));
    assert!((t.position[0] - 3.9).abs() < 1e-9, "{t:?}");
    assert_eq!(t.cameras, vec![10]);
    assert!(t.trail.len() > 10 && t.ellipse.is_some());
    let head = &v.nodes[&2];
    assert!(head.up && head.role == NodeKind::Head);
    assert_eq!((head.health.steps, head.health.late), (30, 7));
    let cam = &v.nodes[&10];
    assert_eq!(cam.mode, Some(Mode::CameraOff));
    assert_eq!(
        (
            cam.health.dropped,
            cam.health.rejected,
            cam.health.rejected_by_server
        ),
        (3, 2, 1)
    );
    assert_eq!(cam.health.sync_error_ms, Some(0.25));
    assert!(!v.nodes[&11].up, "never heard from");
    assert_eq!(v.nodes[&900].role, NodeKind::Viewer);
    assert_eq!(v.totals.rejected, 1);

    // The metrics a scrape shows come from that state.
    let (mut p, feed) = channel(ViewState::new());
    p.publish(Arc::new(v.clone()));
    let text = crate::metrics::render(&feed.latest(), feed.stats()).unwrap();
    let has = |line: &str| text.lines().any(|l| l == line);
    for line in [
        r#"ocelli_steps_total{head="2"} 30"#,
        r#"ocelli_late_total{head="2"} 7"#,
        r#"ocelli_dropped_total{node="10"} 3"#,
        r#"ocelli_rejected_total{node="10"} 2"#,
        r#"ocelli_sync_error_seconds{node="10"} 0.00025"#,
        r#"ocelli_node_up{node="2",role="head"} 1"#,
        r#"ocelli_node_up{node="11",role="camera"} 0"#,
        r#"ocelli_camera_mode{mode="camera_off",node="10"} 1"#,
        "ocelli_tracks 1",
        "ocelli_server_rejected_total 1",
    ] {
        assert!(has(line), "{line} missing:\n{text}");
    }
    assert!(text.contains(r#"ocelli_lost_total{node="2"} "#));
    assert!(
        !has(r#"ocelli_lost_total{node="2"} 0"#),
        "head 2's lost frame is counted"
    );
}

#[test]
fn a_track_the_server_dropped_leaves_the_view_and_a_quiet_server_is_said() {
    let mut w = Wire::new();
    let report = |at: i64| TrackReport {
        target: TargetId(1),
        global: None,
        step: 1,
        time: ms(at),
        mean: [2.0, 2.0, 0.8, 0.0, 0.0, 0.0],
        cov: std::array::from_fn(|r| std::array::from_fn(|c| if r == c { 0.02 } else { 0.0 })),
        contributors: vec![],
        power_mw: 0.0,
        late: 0,
        appearance: Vec::new(),
        grid: None,
        captured: None,
    };
    w.server
        .on_message(ms(100), from(2, 0, 100, Message::TrackReport(report(100))));
    w.step(150);
    assert!(w.viewer.state().tracks.contains_key(&1));
    // No more reports: the server drops the track after its timeout, and so does the view.
    let timeout = i64::try_from(Scenario::default_scenario().method.track_timeout_ms).unwrap();
    let mut at = 150;
    while at < timeout + 1000 {
        at += 200;
        w.step(at);
    }
    assert!(
        w.viewer.state().tracks.is_empty(),
        "{:?}",
        w.viewer.state().tracks.keys()
    );
    // The server stops answering: the viewer says so once.
    for k in 1..40 {
        let out = w.viewer.handle(ms(at + 100 * k), Input::Tick);
        assert!(out.iter().all(|o| matches!(o.body, Message::ViewSubscribe(_))));
    }
    let problems = &w.viewer.state().problems;
    assert_eq!(
        problems
            .iter()
            .filter(|p| p.text.contains("no update from the server"))
            .count(),
        1,
        "{problems:?}"
    );
    assert!(w.viewer.take_changed().is_some());
    assert!(w.viewer.take_changed().is_none());
}
