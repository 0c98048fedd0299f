//! Unit tests of the head core: strangers, handover, assignment.
use super::*;
use proto::scenario::Scenario;

fn env(source: u32, body: Message) -> Envelope {
    Envelope {
        source: NodeId(source),
        seq: 0,
        time: ClusterTime::ZERO,
        body,
    }
}

#[test]
fn a_step_without_tracks_sends_nothing_and_strangers_are_rejected() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    let out = h.tick(ClusterTime::ZERO);
    assert!(out.is_empty(), "{out:?}");
    assert!(h.step_open());
    // Node 13 belongs to head 3.
    let c = Contribution {
        target: TargetId(1),
        step: 1,
        info_matrix: [[0.0; 6]; 6],
        info_vector: [0.0; 6],
        camera: false,
        captured: ClusterTime::ZERO,
        mode: Mode::Active,
        rssi: None,
    };
    h.on_message(ClusterTime::ZERO, env(13, Message::Contribution(c.clone())));
    assert_eq!(h.counters().rejected, 1);
    h.on_message(ClusterTime::ZERO, env(10, Message::Contribution(c)));
    assert_eq!(h.counters().unknown_target, 1);
    // Liveness only from the server.
    h.on_message(
        ClusterTime::ZERO,
        env(
            10,
            Message::Liveness(proto::msg::Liveness {
                node: NodeId(11),
                up: false,
            }),
        ),
    );
    assert_eq!(h.counters().rejected, 2);
    assert_eq!(h.mode_of(NodeId(11)), Some(Mode::Active));
}

fn handover(global: u32, to: u32, from: Option<u32>, x: f64) -> Message {
    let mean = State::new(x, 4.0, 0.2, 0.0, 0.0, 0.0);
    Message::Handover(Handover {
        global: TargetId(global),
        to_head: NodeId(to),
        from_head: from.map(NodeId),
        time: ClusterTime::ZERO,
        mean: vec6_to_wire(&mean),
        cov: mat6_to_wire(&(Matrix6::identity() * 0.04)),
    })
}

#[test]
fn handover_starts_a_track_that_reports_its_global_id_and_leaves_again() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    assert_eq!(h.tracks().len(), 1);
    assert_eq!(h.counters().handovers, 1);
    // The same global again does not make a second track; a forged sender is rejected.
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    h.on_message(ClusterTime::ZERO, env(10, handover(8, 2, None, 1.0)));
    assert_eq!(h.tracks().len(), 1);
    assert_eq!(h.counters().rejected, 1);
    // Next step: a prior to every member camera, a report with the global id at the close.
    let t1 = ClusterTime::from_millis(200);
    let out = h.tick(t1);
    let priors = out.iter().filter(|o| matches!(o.body, Message::Prior(_))).count();
    let awake = s.clusters()[&NodeId(2)]
        .iter()
        .filter(|&&n| h.mode_of(n) != Some(Mode::Inactive))
        .count();
    assert!(awake > 0);
    assert_eq!(priors, awake);
    let out = h.tick(ClusterTime::from_millis(281));
    let report = out
        .iter()
        .find_map(|o| match &o.body {
            Message::TrackReport(r) => Some(r.clone()),
            _ => None,
        })
        .unwrap();
    assert_eq!(report.global, Some(TargetId(7)));
    assert_eq!(h.last_step().prediction_only, 1);
    assert!(!h.last_step().complete);
    // The server moves it on to head 3: the track leaves.
    h.on_message(t1, env(1, handover(7, 3, Some(2), 3.0)));
    assert!(h.tracks().is_empty());
}

#[test]
fn assignment_moves_a_camera_out_of_the_cluster() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, None, 3.0)));
    let moved = NodeId(10);
    h.on_message(
        ClusterTime::ZERO,
        env(
            1,
            Message::Assignment(proto::msg::Assignment {
                node: moved,
                head: NodeId(3),
            }),
        ),
    );
    let out = h.tick(ClusterTime::from_millis(200));
    assert!(!out.iter().any(|o| o.to == moved));
    let power_before = h.power_mw();
    h.on_message(
        ClusterTime::ZERO,
        env(
            1,
            Message::Assignment(proto::msg::Assignment {
                node: moved,
                head: NodeId(2),
            }),
        ),
    );
    assert!(h.power_mw() > power_before);
}

#[test]
fn duplicate_tracks_on_one_target_are_merged() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, None, 3.0)));
    h.on_message(ClusterTime::ZERO, env(1, handover(8, 2, None, 3.05)));
    h.on_message(ClusterTime::ZERO, env(1, handover(9, 2, None, 5.0)));
    assert_eq!(h.tracks().len(), 3);
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    assert_eq!(h.counters().merges, 1);
    let globals: Vec<_> = h.tracks().iter().map(|t| t.global).collect();
    assert_eq!(globals, vec![Some(TargetId(7)), Some(TargetId(9))]);
}

/// Paper 002 §V: the cost is an energy, over the step whose information the reward counts.
#[test]
fn activation_cost_is_the_energy_of_one_step() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    h.tick(ClusterTime::from_millis(200));
    h.tick(ClusterTime::from_millis(281));
    let d = h
        .last_step()
        .decision
        .expect("a camera far from the target is switched off");
    let power = s.power_of(d.node.0);
    let step_s = s.method.step_ms as f64 * 1e-3;
    let want = s.method.energy_weight * (power.in_mode(d.to) - power.in_mode(d.from)) * step_s;
    assert!((d.cost - want).abs() < 1e-12, "cost {} vs {want}", d.cost);
}
