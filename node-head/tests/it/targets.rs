//! Several targets: association, birth only from agreeing cameras, death after silence.

use crate::sim::{HEAD, ONE_TARGET, Sim, TWO_TARGETS, error, ring_scenario};
use proto::msg::{Handover, Message};
use proto::{Envelope, NodeId, TargetId};

#[test]
fn two_targets_are_born_tracked_and_one_dies() {
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, TWO_TARGETS);
    let mut sim = Sim::new(&scenario, 41);
    for _ in 0..25 {
        sim.step();
    }
    assert_eq!(sim.head.counters().births, 2, "{:?}", sim.head.counters());
    let r = sim.reports[sim.reports.len() - 2..].to_vec();
    let mut matched = [false; 2];
    for rep in &r {
        let (e0, e1) = (error(&sim, rep, 0), error(&sim, rep, 1));
        let i = usize::from(e1 < e0);
        assert!(e0.min(e1) < 0.3, "track {} errors {e0} {e1}", rep.target);
        matched[i] = true;
    }
    assert_eq!(matched, [true, true]);
    // Target 2 leaves; its track is dropped after the silence timeout (1 s = 5 steps).
    sim.present[1] = false;
    for _ in 0..8 {
        sim.step();
    }
    assert_eq!(sim.head.counters().deaths, 1);
    assert_eq!(sim.head.tracks().len(), 1);
    let last = sim.reports.last().unwrap();
    assert!(error(&sim, last, 0) < 0.3);
    assert_eq!(sim.head.counters().births, 2, "no ghost births");
}

#[test]
fn a_single_camera_detection_does_not_start_a_track() {
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, TWO_TARGETS);
    let mut sim = Sim::new(&scenario, 42);
    // Only camera 0 works: its detections never agree with a second camera.
    for (i, c) in sim.cams.iter_mut().enumerate() {
        c.working = i == 0;
    }
    for _ in 0..10 {
        sim.step();
    }
    assert_eq!(sim.head.counters().births, 0);
}

#[test]
fn a_born_track_is_reported_only_once_confirmed() {
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut sim = Sim::new(&scenario, 43);
    let mut first_track = None;
    let mut first_report = None;
    for k in 0..15 {
        let reports = sim.step();
        if first_track.is_none() && !sim.head.tracks().is_empty() {
            first_track = Some(k);
        }
        if first_report.is_none() && !reports.is_empty() {
            first_report = Some(k);
        }
    }
    let (born, reported) = (first_track.unwrap(), first_report.unwrap());
    assert!(
        reported >= born + node_head::lifecycle::CONFIRM_STEPS as usize,
        "born at step {born}, reported at {reported}"
    );
    assert!(sim.head.tracks()[0].past_tentative());
    assert!(error(&sim, sim.reports.last().unwrap(), 0) < 0.3);
}

/// The lifecycle through a real head: tentative until confirmed (never reported), confirmed
/// while cameras see the target, coasting (still reported, on its prediction) while they do
/// not, confirmed again when they see it once more, and deleted after the silence timeout.
#[test]
fn a_track_goes_tentative_confirmed_coasting_confirmed_deleted() {
    use node_head::lifecycle::Lifecycle::{Coasting, Confirmed, Tentative};
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut sim = Sim::new(&scenario, 45);
    let mut seen = Vec::new();
    for _ in 0..15 {
        let reports = sim.step();
        if let Some(t) = sim.head.tracks().first() {
            // A tentative track is never reported; a confirmed or coasting one every step.
            assert_eq!(reports.is_empty(), t.state() == Tentative, "{:?}", t.state());
            seen.push(t.state());
        }
    }
    assert_eq!(seen.first(), Some(&Tentative));
    assert_eq!(seen.last(), Some(&Confirmed));
    // Hidden from every camera for two steps: coasting, and still reported.
    for c in sim.cams.iter_mut() {
        c.working = false;
    }
    for _ in 0..2 {
        let reports = sim.step();
        assert_eq!(sim.head.tracks()[0].state(), Coasting);
        assert_eq!(reports.len(), 1, "a coasting track is reported");
        let stats = sim.head.last_step();
        assert_eq!((stats.tentative, stats.coasting), (0, 1), "{stats:?}");
    }
    for c in sim.cams.iter_mut() {
        c.working = true;
    }
    sim.step();
    assert_eq!(sim.head.tracks()[0].state(), Confirmed, "seen again");
    assert_eq!(sim.head.counters().deaths, 0);
    // Hidden past the silence timeout (1 s = 5 steps): coasting until then, never unconfirmed
    // on the way, then deleted for its silence.
    for c in sim.cams.iter_mut() {
        c.working = false;
    }
    for _ in 0..4 {
        sim.step();
        assert_eq!(sim.head.tracks()[0].state(), Coasting);
    }
    for _ in 0..4 {
        sim.step();
        if let Some(t) = sim.head.tracks().first() {
            assert_eq!(t.state(), Coasting);
        }
    }
    assert!(sim.head.tracks().is_empty());
    assert_eq!(sim.head.counters().deaths, 1);
    assert_eq!(sim.head.counters().left_world, 0, "ended by its silence");
    let c = sim.head.counters();
    let tentative_steps = seen.iter().filter(|s| **s == Tentative).count() as u64;
    // A step's stats are taken before its births: the step that bore the track does not count it.
    assert_eq!(c.sum_tentative + 1, tentative_steps, "{c:?}");
    assert!(c.sum_coasting >= 2 + 4, "{c:?}");
}

/// The server hands a target this head started (and never named to it) to another head: the
/// head recognises its own track by the posterior and drops it.
#[test]
fn a_track_started_here_is_dropped_when_handed_away() {
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, TWO_TARGETS);
    let mut sim = Sim::new(&scenario, 44);
    for _ in 0..12 {
        sim.step();
    }
    assert_eq!(sim.head.tracks().len(), 2);
    let last = sim.reports.last().unwrap().clone();
    assert_eq!(last.global, None);
    let handover = Handover {
        global: TargetId(9),
        to_head: NodeId(3),
        from_head: Some(NodeId(HEAD)),
        time: last.time,
        mean: last.mean,
        cov: last.cov,
    };
    let env = Envelope {
        source: NodeId(1),
        seq: 0,
        time: sim.now(),
        body: Message::Handover(handover),
    };
    sim.head.on_message(sim.now(), env);
    let left: Vec<_> = sim.head.tracks().iter().map(|t| t.local).collect();
    assert_eq!(left.len(), 1);
    assert_ne!(left[0], last.target);
}
