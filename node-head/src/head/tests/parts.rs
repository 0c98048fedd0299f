//! A step's priors in several parts: slots, answers late, twice or confused.
use super::*;

/// A handover of global `100 + k` to head 2 at the k-th point of a 1.3 m grid.
fn grid_handover(k: u32) -> Message {
    let mean = State::new(
        1.0 + f64::from(k % 8) * 1.3,
        1.0 + f64::from(k / 8) * 1.3,
        0.8,
        0.0,
        0.0,
        0.0,
    );
    Message::Handover(Handover {
        global: TargetId(100 + k),
        to_head: NodeId(2),
        from_head: None,
        time: ClusterTime::ZERO,
        mean: vec6_to_wire(&mean),
        cov: mat6_to_wire(&(Matrix6::identity() * 0.01)),
    })
}

/// More tracks than one `Priors` holds: each node gets the step's priors in parts, answers
/// each, and the step closes as soon as every part is answered, even after a track was
/// released mid-step (the window keeps each track's slot from the step's opening). Answers
/// twice, late, for a part the step never had, and contributions to a track their part did
/// not ask are counted and change nothing.
#[test]
fn a_step_in_several_parts_closes_once_every_part_is_answered() {
    let mut s = Scenario::default_scenario();
    s.method.activation = Activation::AllOn;
    let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap()).with_nodes_heard();
    h.tick(ClusterTime::ZERO);
    for k in 0..40 {
        h.on_message(ClusterTime::ZERO, env(1, grid_handover(k)));
    }
    assert_eq!(h.tracks().len(), 40);
    let t1 = ClusterTime::from_millis(200);
    let out = h.tick(t1);
    let sent: Vec<(NodeId, Priors)> = out
        .iter()
        .filter_map(|o| match &o.body {
            Message::Priors(p) => Some((o.to, p.clone())),
            _ => None,
        })
        .collect();
    let first = sent[0].0;
    let mut sizes: Vec<(u16, u16, usize)> = sent
        .iter()
        .filter(|(to, _)| *to == first)
        .map(|(_, p)| (p.part, p.parts, p.tracks.len()))
        .collect();
    sizes.sort_unstable();
    assert_eq!(sizes, vec![(0, 2, MAX_PRIORS), (1, 2, 40 - MAX_PRIORS)]);
    // The server hands the first track to head 3 mid-step: the others shift down.
    let released = Message::Handover(Handover {
        global: TargetId(100),
        to_head: NodeId(3),
        from_head: Some(NodeId(2)),
        time: t1,
        mean: vec6_to_wire(&State::new(1.0, 1.0, 0.8, 0.0, 0.0, 0.0)),
        cov: mat6_to_wire(&(Matrix6::identity() * 0.01)),
    });
    h.on_message(t1, env(1, released));
    assert_eq!(h.tracks().len(), 39);
    let answer = |p: &Priors, part: u16, contributions: Vec<Contribution>| Answers {
        step: p.tracks[0].step,
        part,
        captured: t1,
        mode: Mode::Active,
        rssi: Vec::new(),
        contributions,
    };
    let stranger = Contribution {
        target: sent.iter().find(|(_, p)| p.part == 1).unwrap().1.tracks[0].target,
        info: zero_information(),
        folded: Kinds::of(ObservationKind::Pinhole),
        ground: None,
    };
    let (last, rest) = sent.split_last().unwrap();
    for (i, (to, p)) in rest.iter().enumerate() {
        // The first node's part 0 also names a track of part 1, and comes twice.
        let extra = if i == 0 && p.part == 0 {
            vec![stranger.clone()]
        } else {
            Vec::new()
        };
        h.on_message(t1, env(to.0, Message::Answers(answer(p, p.part, extra))));
        assert!(h.step_open(), "closed before every part was answered");
    }
    let (to0, p0) = &sent[0];
    h.on_message(t1, env(to0.0, Message::Answers(answer(p0, p0.part, Vec::new()))));
    h.on_message(t1, env(to0.0, Message::Answers(answer(p0, 7, Vec::new()))));
    assert!(h.step_open());
    h.on_message(
        t1,
        env(
            last.0.0,
            Message::Answers(answer(&last.1, last.1.part, Vec::new())),
        ),
    );
    assert!(!h.step_open(), "every part answered: the step closes early");
    assert!(h.last_step().complete);
    h.on_message(t1, env(to0.0, Message::Answers(answer(p0, p0.part, Vec::new()))));
    let c = h.counters();
    assert_eq!(
        (c.duplicate, c.future, c.late, c.unknown_target),
        (1, 1, 1, 1),
        "{c:?}"
    );
}
