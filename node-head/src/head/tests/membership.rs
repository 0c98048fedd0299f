//! Which nodes a head talks to: nodes it has not heard from, cameras the server assigns to it
//! or away, and their liveness.
use super::*;

/// The server's assignment of camera `node` to `head`.
fn assignment(node: u32, head: u32) -> Envelope {
    env(
        1,
        Message::Assignment(proto::msg::Assignment {
            node: NodeId(node),
            head: NodeId(head),
        }),
    )
}

/// The server's word on `node`'s liveness.
fn liveness(node: u32, up: bool) -> Envelope {
    env(
        1,
        Message::Liveness(proto::msg::Liveness {
            node: NodeId(node),
            up,
        }),
    )
}

/// The nodes a head's outgoing messages send priors to.
fn prior_recipients(out: &[Outgoing]) -> Vec<NodeId> {
    out.iter()
        .filter(|o| matches!(o.body, Message::Priors(_)))
        .map(|o| o.to)
        .collect()
}

#[test]
fn a_node_is_sent_nothing_and_not_waited_for_until_it_was_heard() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, Some(3), 3.0)));
    assert_eq!(h.tracks().len(), 1);
    // Nobody spoke yet (`launch` starts every process at once): no priors, no step waiting.
    let out = h.tick(ClusterTime::from_millis(200));
    assert_eq!(prior_recipients(&out), Vec::<NodeId>::new());
    assert!(
        out.iter().all(|o| !matches!(o.body, Message::Command(_))),
        "{out:?}"
    );
    // A first message from camera 10 (any kind), and camera 11's link coming up.
    h.on_message(ClusterTime::from_millis(210), env(10, Message::Heartbeat));
    h.node_liveness(ClusterTime::from_millis(210), NodeId(11), true);
    let out = h.tick(ClusterTime::from_millis(400));
    // Camera 11 is the planner's to switch off now (`three-mode`), 10 gets the priors:
    // nothing goes to a camera still unheard.
    assert!(
        out.iter()
            .all(|o| [NodeId(1), NodeId(10), NodeId(11)].contains(&o.to)),
        "{out:?}"
    );
    assert_eq!(prior_recipients(&out), vec![NodeId(10)]);
    assert_eq!(h.mode_of(NodeId(11)), Some(Mode::Inactive));
    // Camera 10 was the only one asked: its answer closes the step before its deadline (the
    // unheard cameras are not waited for).
    let prior = first_prior(&out).unwrap();
    let answers = answers_to(&prior, true, ClusterTime::from_millis(400), Mode::Active, None);
    assert!(h.step_open());
    h.on_message(ClusterTime::from_millis(410), env(10, Message::Answers(answers)));
    assert!(!h.step_open(), "the step still waits: {:?}", h.counters());
}

#[test]
fn a_camera_moved_to_a_head_is_sent_nothing_until_it_is_known_to_run() {
    let s = Scenario::default_scenario();
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
    h.tick(ClusterTime::ZERO);
    h.on_message(ClusterTime::ZERO, env(1, handover(7, 2, None, 3.0)));
    // Head 3 went down and the server moves its camera 13 here: maybe it never started.
    h.on_message(ClusterTime::ZERO, assignment(13, 2));
    let out = h.tick(ClusterTime::from_millis(200));
    assert!(!prior_recipients(&out).contains(&NodeId(13)), "{out:?}");
    // The server's word that it runs.
    h.on_message(ClusterTime::from_millis(210), liveness(13, true));
    let out = h.tick(ClusterTime::from_millis(400));
    assert!(
        out.iter().any(|o| o.to == NodeId(13)),
        "camera 13 runs and belongs here but is sent nothing: {out:?}"
    );
}

#[test]
fn assignment_moves_a_camera_out_of_the_cluster() {
    let mut h = head_2_with_global_7();
    let moved = NodeId(10);
    h.on_message(ClusterTime::ZERO, assignment(10, 3));
    let out = h.tick(ClusterTime::from_millis(200));
    assert!(!out.iter().any(|o| o.to == moved));
    let power_before = h.power_mw();
    h.on_message(ClusterTime::ZERO, assignment(10, 2));
    assert!(h.power_mw() > power_before);
}

/// A camera seen going down while in this cluster, then assigned to another head (which heard
/// of it coming back), then assigned here again, is up here again: it gets priors.
#[test]
fn a_camera_assigned_back_is_not_left_down_by_a_stale_liveness() {
    let mut h = head_2_with_global_7();
    let cam = NodeId(10);
    h.on_message(ClusterTime::ZERO, liveness(10, false));
    h.on_message(ClusterTime::ZERO, assignment(10, 3));
    h.on_message(ClusterTime::ZERO, assignment(10, 2));
    let out = h.tick(ClusterTime::from_millis(200));
    assert!(
        out.iter()
            .any(|o| o.to == cam && matches!(o.body, Message::Priors(_))),
        "camera 10 is back in the cluster but gets no prior: {out:?}"
    );
}
