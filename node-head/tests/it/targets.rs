//! Several targets: association, birth only from agreeing cameras, death after silence.

use crate::sim::{Sim, TWO_TARGETS, error, ring_scenario};

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
