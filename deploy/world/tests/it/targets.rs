//! The simulated world's targets in the scenario files: the default robot's loop is well
//! covered by the cameras, the example shows both trajectory kinds, and broken target tables
//! fail with the path, the field and what was expected.

use proto::scenario::Scenario;
use std::path::Path;
use world::{Target, Trajectory, targets};

/// Cameras that see the target's centre at time `t`: in front and inside the image.
fn cameras_seeing(s: &Scenario, target: &Target, t: f64) -> usize {
    let p = target.position_at(t);
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
    let targets = targets(&s).unwrap();
    let t = &targets[0];
    let Trajectory::Loop { waypoints, speed, .. } = &t.trajectory else {
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
        .map(|k| cameras_seeing(&s, t, period * k as f64 / 400.0))
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
    let targets = targets(&s).unwrap();
    let t = &targets[0];
    for c in s.cameras() {
        let cam = s.camera_model(c.id).unwrap();
        // A proper camera aimed at the floor: the OpenCV import's handedness test agrees.
        assert!(!proto::opencv::sees_ground_behind(&cam.pose), "camera {}", c.id);
        let seen = (0..400)
            .filter(|k| {
                let p = t.position_at(f64::from(*k) * 0.25);
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

fn example_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../proto/scenarios/example.toml"))
        .unwrap()
}

#[test]
fn the_example_shows_both_trajectory_kinds() {
    let s = Scenario::from_toml(&example_text(), "example.toml").unwrap();
    let kinds: std::collections::BTreeSet<_> = targets(&s)
        .unwrap()
        .iter()
        .map(|t| matches!(t.trajectory, Trajectory::Loop { .. }))
        .collect();
    assert_eq!(kinds.len(), 2, "the example shows both a loop and a path");
}

/// A broken target table fails with the scenario, the field and what was expected.
#[test]
fn broken_targets_name_field_and_expectation() {
    let cases: [(&str, &str, &[&str]); 5] = [
        (
            "rssi-tag = true",
            "rssi-tags = true",
            &["unknown field `rssi-tags`", "expected one of"],
        ),
        (
            "id = 2\nsize",
            "id = 1\nsize",
            &["targets[id=1]", "duplicate target id"],
        ),
        (
            "speed = 0.8",
            "speed = -0.8",
            &["targets[id=2].trajectory.speed", "expected a positive speed"],
        ),
        (
            "waypoints = [[0.5, 3.5], [2.5, 2.0], [5.5, 0.5]]",
            "waypoints = [[0.5, 3.5]]",
            &["targets[id=2].trajectory.waypoints", "at least two"],
        ),
        (
            "size = [0.4, 0.4, 1.7]",
            "size = [0.4, 0.0, 1.7]",
            &["targets[id=2].size", "positive"],
        ),
    ];
    let text = example_text();
    for (from, to, wants) in cases {
        assert!(text.contains(from), "`{from}` not in the example");
        let s = Scenario::from_toml(&text.replacen(from, to, 1), "broken.toml").unwrap();
        let e = targets(&s).unwrap_err().to_string();
        assert!(e.contains("example"), "no scenario name in: {e}");
        for want in wants {
            assert!(e.contains(want), "`{from}` → `{to}`: expected `{want}` in: {e}");
        }
    }
}
