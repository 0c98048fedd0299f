//! The other fusion methods through `HeadNode`: centralized EIF (the head linearizes) agrees
//! with the distributed one on the same detections; the previous-frame point helps velocity;
//! maximum likelihood tracks on a known plane.

use crate::sim::{ONE_TARGET, Sim, error, ring_scenario};
use proto::msg::TrackReport;

fn velocity_error(sim: &Sim, r: &TrackReport) -> f64 {
    let t = sim.truth(0, r.time);
    ((r.mean[3] - t[3]).powi(2) + (r.mean[4] - t[4]).powi(2)).sqrt()
}

#[test]
fn centralized_eif_equals_distributed_eif_on_the_same_detections() {
    let mut d = Sim::new(
        &ring_scenario(6, "distributed-eif", "all-on", 0.0, ONE_TARGET),
        51,
    );
    let mut c = Sim::new(
        &ring_scenario(6, "centralized-eif", "all-on", 0.0, ONE_TARGET),
        51,
    );
    let mut compared = 0;
    for _ in 0..40 {
        let (rd, rc) = (d.step(), c.step());
        assert_eq!(rd.len(), rc.len());
        for (a, b) in rd.iter().zip(&rc) {
            for i in 0..6 {
                assert!((a.mean[i] - b.mean[i]).abs() <= 1e-9 * (1.0 + a.mean[i].abs()));
                for j in 0..6 {
                    assert!((a.cov[i][j] - b.cov[i][j]).abs() <= 1e-9 * (1.0 + a.cov[i][j].abs()));
                }
            }
            compared += 1;
        }
    }
    // Every step but the birth and the tentative ones (not reported) is compared.
    assert!(
        compared >= 40 - 2 - node_head::lifecycle::CONFIRM_STEPS as usize,
        "{compared}"
    );
    assert!(c.head.last_step().applied > 0);
}

/// A straight walk: the track starts with zero velocity and must learn it.
const STRAIGHT: &str = r#"
[[targets]]
id = 1
size = [0.4, 0.4, 0.4]
colour = [255, 0, 0]
trajectory = { kind = "path", speed = 0.8, waypoints = [[1.5, 3.0], [6.5, 5.0]] }
"#;

#[test]
fn previous_point_improves_velocity() {
    let run = |prev: bool| {
        let mut s = ring_scenario(4, "centralized-eif", "all-on", 0.0, STRAIGHT);
        s.method.previous_point = prev;
        s.method.pixel_sigma = 8.0;
        let mut sim = Sim::new(&s, 52);
        let (mut ev, mut ep, mut n) = (0.0, 0.0, 0.0);
        // The first second after birth, while velocity is being learnt: the track is still
        // tentative (not reported), so its state is read at the head.
        for k in 0..8 {
            sim.step();
            if k >= 1
                && let Some(t) = sim.head.tracks().first()
            {
                let r = TrackReport {
                    target: t.local,
                    global: t.global,
                    step: 0,
                    time: t.time,
                    mean: proto::models::vec6_to_wire(t.filter.mean()),
                    cov: proto::models::mat6_to_wire(t.filter.cov()),
                    contributors: Vec::new(),
                    power_mw: 0.0,
                    late: 0,
                    appearance: Vec::new(),
                    grid: None,
                    captured: None,
                };
                ev += velocity_error(&sim, &r);
                ep += error(&sim, &r, 0);
                n += 1.0;
            }
        }
        (ev / n, ep / n)
    };
    let (v_without, p_without) = run(false);
    let (v_with, p_with) = run(true);
    assert!(
        v_with < 0.8 * v_without,
        "velocity error {v_with} with p(t-1) vs {v_without} without"
    );
    assert!(p_with < 0.3 && p_without < 0.3);
}

#[test]
fn maximum_likelihood_tracks_on_the_known_plane() {
    let mut sim = Sim::new(&ring_scenario(6, "ml", "all-on", 0.0, ONE_TARGET), 53);
    let (mut e, mut n) = (0.0, 0.0);
    for k in 0..60 {
        let r = sim.step();
        if k >= 5 {
            e += error(&sim, &r[0], 0);
            n += 1.0;
        }
    }
    assert!(e / n < 0.15, "ML mean error {}", e / n);
    assert_eq!(sim.head.counters().births, 1);
}
