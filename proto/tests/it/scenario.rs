//! The scenario files: the embedded default, the commented example, and how broken files fail.

use proto::scenario::{DEFAULT_SCENARIO_TOML, Scenario, ScenarioError};
use std::path::Path;

/// Cameras that see the target's centre at time `t`: in front and inside the image.
fn cameras_seeing(s: &Scenario, target: usize, t: f64) -> usize {
    let p = proto::models::position(&s.targets[target].truth_at(t));
    s.cameras()
        .filter(|c| {
            let cam = s.camera_model(c.id).unwrap();
            cam.project(&p).is_some_and(|px| {
                px.x >= 0.0
                    && px.y >= 0.0
                    && px.x < f64::from(cam.intrinsics.width)
                    && px.y < f64::from(cam.intrinsics.height)
            })
        })
        .count()
}

/// Every point of the default robot's loop is seen by at least six cameras.
#[test]
fn default_loop_is_seen_by_many_cameras() {
    let s = Scenario::default_scenario();
    assert_eq!(s.cameras().count(), 21);
    let t = &s.targets[0];
    let proto::scenario::Trajectory::Loop { waypoints, speed } = &t.trajectory else {
        panic!("the default target drives a loop")
    };
    let perimeter: f64 = (0..waypoints.len())
        .map(|i| {
            let (a, b) = (waypoints[i], waypoints[(i + 1) % waypoints.len()]);
            ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt()
        })
        .sum();
    let period = perimeter / speed;
    let counts: Vec<usize> = (0..400)
        .map(|k| cameras_seeing(&s, 0, period * k as f64 / 400.0))
        .collect();
    let min = *counts.iter().min().unwrap();
    let mean = counts.iter().sum::<usize>() as f64 / counts.len() as f64;
    eprintln!("default loop coverage: min {min} cameras, mean {mean:.1}");
    assert!(min >= 6, "a loop point is seen by only {min} cameras");
}

/// Each camera of the default sees part of the loop (none is placed uselessly).
#[test]
fn every_default_camera_sees_part_of_the_loop() {
    let s = Scenario::default_scenario();
    let t = &s.targets[0];
    for c in s.cameras() {
        let cam = s.camera_model(c.id).unwrap();
        let seen = (0..400)
            .filter(|k| {
                let p = proto::models::position(&t.truth_at(f64::from(*k) * 0.25));
                cam.project(&p).is_some_and(|px| {
                    px.x >= 0.0
                        && px.y >= 0.0
                        && px.x < f64::from(cam.intrinsics.width)
                        && px.y < f64::from(cam.intrinsics.height)
                })
            })
            .count();
        eprintln!("camera {}: {seen}/400", c.id);
        assert!(
            seen >= 40,
            "camera {} sees the loop in only {seen}/400 samples",
            c.id
        );
    }
}

/// `ocelli scenario default` prints the embedded text; it parses to the default, and the
/// default serializes to TOML that parses back to the same scenario.
#[test]
fn default_scenario_text_round_trips() {
    let s = Scenario::from_toml(DEFAULT_SCENARIO_TOML, "<printed>").unwrap();
    assert_eq!(s, Scenario::default_scenario());
    let again = Scenario::from_toml(&s.to_toml(), "<to_toml>").unwrap();
    assert_eq!(again, s);
}
