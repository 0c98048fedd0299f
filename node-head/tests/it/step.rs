//! The distributed step through `HeadNode`: prediction-only growth, late and duplicate
//! contributions, nodes going down.

use crate::sim::{ONE_TARGET, SERVER, Sim, error, ring_scenario};
use proto::msg::{Answers, Contribution, Information, Liveness};
use proto::{ClusterTime, Envelope, Message, Mode, NodeId};

fn trace_pos(r: &proto::msg::TrackReport) -> f64 {
    r.cov[0][0] + r.cov[1][1] + r.cov[2][2]
}

#[test]
fn steps_without_contributions_are_prediction_only_and_uncertainty_grows() {
    let scenario = ring_scenario(6, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut sim = Sim::new(&scenario, 3);
    for _ in 0..15 {
        sim.step();
    }
    assert_eq!(sim.head.counters().births, 1);
    let before = sim.reports.last().unwrap().clone();
    assert!(
        error(&sim, &before, 0) < 0.3,
        "tracking error {}",
        error(&sim, &before, 0)
    );
    for c in &mut sim.cams {
        c.working = false;
    }
    let mut last = trace_pos(&before);
    for _ in 0..4 {
        let r = sim.step();
        assert_eq!(r.len(), 1);
        let tr = trace_pos(&r[0]);
        assert!(tr > last, "uncertainty did not grow: {tr} <= {last}");
        last = tr;
        assert_eq!(sim.head.last_step().prediction_only, 1);
        assert!(r[0].contributors.is_empty());
    }
    for c in &mut sim.cams {
        c.working = true;
    }
    let r = sim.step();
    assert!(trace_pos(&r[0]) < last * 0.5);
    assert_eq!(sim.head.last_step().prediction_only, 0);
}

#[test]
fn duplicates_and_late_contributions_are_counted_and_never_applied() {
    let scenario = ring_scenario(6, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut a = Sim::new(&scenario, 11);
    let mut b = Sim::new(&scenario, 11);
    for _ in 0..8 {
        a.step();
        b.step();
    }
    assert!(
        a.head.last_step().complete,
        "a full step closes as soon as all answered"
    );
    // Camera 0 answers twice in `a`, once in `b`: same posterior.
    let ra = a.step_with(|c| if c == 0 { 2 } else { 1 });
    let rb = b.step();
    assert_eq!(a.head.counters().duplicate, 1);
    assert_eq!(b.head.counters().duplicate, 0);
    assert_eq!(ra[0].mean, rb[0].mean);
    assert_eq!(ra[0].cov, rb[0].cov);
    // Camera 1 misses the deadline in both; the step closes at the deadline.
    let ra = a.step_with(|c| usize::from(c != 1));
    let rb = b.step_with(|c| usize::from(c != 1));
    assert!(!a.head.last_step().complete);
    assert_eq!(ra[0].mean, rb[0].mean);
    // Its contribution turns up after the close: counted late, not applied.
    let filter_before = a.head.tracks()[0].filter.clone();
    let late = Answers {
        step: ra[0].step,
        part: 0,
        captured: ra[0].time,
        mode: Mode::Active,
        rssi: Vec::new(),
        contributions: vec![Contribution {
            target: a.head.tracks()[0].local,
            info: Some(Information {
                matrix: [[0.0; 6]; 6],
                vector: [0.0; 6],
            }),
            folded: proto::observation::Kinds::of(proto::observation::ObservationKind::Pinhole),
            ground: None,
        }],
    };
    let env = Envelope {
        source: a.cams[1].id,
        seq: 999,
        time: ra[0].time,
        body: Message::Answers(late),
    };
    let t = ClusterTime(ra[0].time.0 + 150_000_000);
    assert!(a.head.on_message(t, env).is_empty());
    assert_eq!(a.head.counters().late, 1);
    assert_eq!(a.head.tracks()[0].filter, filter_before);
    // Reports carry the cumulative late count.
    let next = a.step();
    assert_eq!(next[0].late, 1);
}

#[test]
fn a_node_reported_down_is_not_waited_for() {
    let scenario = ring_scenario(6, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut sim = Sim::new(&scenario, 5);
    for _ in 0..5 {
        sim.step();
    }
    let down = sim.cams[2].id;
    let env = Envelope {
        source: NodeId(SERVER),
        seq: 1,
        time: sim.now(),
        body: Message::Liveness(Liveness {
            node: down,
            up: false,
        }),
    };
    sim.head.on_message(sim.now(), env);
    // The dead camera stops answering; the step still closes as soon as the others did.
    let r = sim.step_with(|c| usize::from(c != 2));
    assert!(sim.head.last_step().complete);
    assert!(!r[0].contributors.iter().any(|c| c.node == down));
    assert!(error(&sim, &r[0], 0) < 0.3);
    // It also gets no prior any more and draws no power.
    let out = sim.head.tick(sim.now());
    assert!(!out.iter().any(|o| o.to == down));
}
