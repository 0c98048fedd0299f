use super::*;
use crate::grid::{Belief, Correction};
use approx::assert_abs_diff_eq;
use proto::camera::{Distortion, Intrinsics, Pose};
use std::sync::Arc;

/// An 8 × 6 m room with a wall from (4, 0) to (4, 3); a camera at (1, 3, 2.5) looking down
/// the room along +x.
fn setup(params: OpticalParams) -> (World, Arc<Grid>, CameraModel, OpticalSensor) {
    let world: World = toml::from_str(
        "min = [0.0, 0.0, 0.0]\nmax = [8.0, 6.0, 3.0]\nwalls = [{ from = [4.0, 0.0], to = [4.0, 3.0], height = 2.5 }]",
    )
    .unwrap();
    let grid = Arc::new(Grid::new(&world, 0.1).unwrap());
    let camera = CameraModel {
        intrinsics: Intrinsics {
            fx: 400.0,
            fy: 400.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        distortion: Distortion::default(),
        pose: Pose::look_at(
            Vector3::new(1.0, 3.0, 2.5),
            Vector3::new(6.0, 3.0, 0.85),
            Vector3::z(),
        )
        .unwrap(),
    };
    let sensor = OpticalSensor::new(7, &camera, &grid, &world, &params).unwrap();
    (world, grid, camera, sensor)
}

fn pd_at(grid: &Grid, sensor: &OpticalSensor, x: f64, y: f64) -> f64 {
    sensor.detection_probability()[grid.index_of(x, y).unwrap()]
}

#[test]
fn detection_probability_is_zero_behind_a_wall_outside_the_view_and_beyond_range() {
    let (_, grid, _, sensor) = setup(OpticalParams::default());
    // In view, in front, unoccluded.
    assert_eq!(pd_at(&grid, &sensor, 3.0, 3.0), 0.9);
    assert_eq!(pd_at(&grid, &sensor, 6.05, 4.45), 0.9);
    // Behind the wall: the line from (1, 3) to (6, 1.5) crosses x = 4 at y = 2.1 < 3.
    assert_eq!(pd_at(&grid, &sensor, 6.05, 1.55), 0.0);
    // Behind the camera, and far off to the side of its view.
    assert_eq!(pd_at(&grid, &sensor, 0.45, 3.05), 0.0);
    assert_eq!(pd_at(&grid, &sensor, 1.55, 0.25), 0.0);
    // Beyond a 4 m range.
    let (_, grid, _, near) = setup(OpticalParams {
        max_range_m: 4.0,
        ..OpticalParams::default()
    });
    assert_eq!(pd_at(&grid, &near, 3.0, 3.0), 0.9);
    assert_eq!(pd_at(&grid, &near, 6.05, 4.45), 0.0);
    // Every cell the camera sees really projects into the image, in front, unoccluded.
    let (world, grid, camera, sensor) = setup(OpticalParams::default());
    let pd = sensor.detection_probability();
    let centre = camera.pose.centre();
    for (k, p) in pd.iter().enumerate().filter(|(_, p)| **p > 0.0) {
        let [x, y] = grid.centre_of(k);
        let point = Vector3::new(x, y, 0.85);
        let px = camera.project(&point).expect("in front");
        assert!(
            px.x >= 0.0 && px.x < 640.0 && px.y >= 0.0 && px.y < 480.0,
            "cell {k} projects to {px:?}"
        );
        assert!(!world.occluded(&centre, &point));
        assert_eq!(*p, 0.9);
    }
    assert!(sensor.cells_seen() > 500);
}

/// With no detection the belief drops by (1 − P_d) exactly on the cells in view and rises by
/// the same normalisation everywhere else.
#[test]
fn no_detection_lowers_belief_exactly_in_view() {
    let (_, grid, _, sensor) = setup(OpticalParams::default());
    let mut belief = Belief::uniform(grid.clone());
    let mut lik = vec![1.0; grid.len()];
    assert_eq!(
        sensor.apply(Mode::Active, &[], &mut lik).unwrap(),
        OpticalOutcome::NoDetection
    );
    assert_eq!(belief.correct(&lik).unwrap(), Correction::Applied);
    let u = 1.0 / grid.free_count() as f64;
    let seen = sensor.cells_seen() as f64;
    let z = u * (grid.free_count() as f64 - 0.9 * seen);
    let pd = sensor.detection_probability();
    for k in (0..grid.len()).filter(|k| grid.is_free(*k)) {
        let want = if pd[k] > 0.0 { 0.1 * u / z } else { u / z };
        assert_abs_diff_eq!(belief.mass()[k], want, epsilon = 1e-15);
    }
}

#[test]
fn a_camera_that_is_not_capturing_says_nothing() {
    let (_, grid, _, sensor) = setup(OpticalParams::default());
    let det = [Detection {
        point: [0.0, 0.0],
        cov: [1e-4, 0.0, 1e-4],
    }];
    for mode in [Mode::CameraOff, Mode::Inactive] {
        let mut lik = vec![1.0; grid.len()];
        assert_eq!(
            sensor.apply(mode, &det, &mut lik).unwrap(),
            OpticalOutcome::Silent
        );
        assert!(lik.iter().all(|l| *l == 1.0));
    }
}

/// A detection of a target at (3, 4.2) puts the posterior's peak on the target's cell; cells
/// the camera does not see keep the clutter floor κ.
#[test]
fn a_detection_peaks_the_belief_at_the_target() {
    let (_, grid, camera, sensor) = setup(OpticalParams::default());
    let truth = Vector3::new(3.02, 4.23, 0.85);
    let (p, _) = camera.normalized(&truth);
    let cov = camera.normalized_covariance(&p, 2.0);
    let det = Detection {
        point: [p.x, p.y],
        cov: [cov[(0, 0)], cov[(0, 1)], cov[(1, 1)]],
    };
    let mut lik = vec![1.0; grid.len()];
    assert_eq!(
        sensor.apply(Mode::Active, &[det], &mut lik).unwrap(),
        OpticalOutcome::Detected(1)
    );
    let behind = grid.index_of(6.05, 1.55).unwrap();
    assert_eq!(lik[behind], 1e-3);
    let mut belief = Belief::uniform(grid.clone());
    belief.correct(&lik).unwrap();
    assert_eq!(belief.estimate().most_likely_cell, (30, 42));
    // From a uniform prior over 4,800 cells, κ = 10⁻³ leaves the clutter hypothesis most of
    // the mass; with κ = 10⁻⁶ the mean and spread are the detection's.
    let (_, grid, _, sharp) = setup(OpticalParams {
        clutter: 1e-6,
        ..OpticalParams::default()
    });
    let mut lik = vec![1.0; grid.len()];
    sharp.apply(Mode::Active, &[det], &mut lik).unwrap();
    let mut belief = Belief::uniform(grid.clone());
    belief.correct(&lik).unwrap();
    let e = belief.estimate();
    assert_eq!(e.most_likely_cell, (30, 42));
    assert!(
        (e.mean[0] - truth.x).abs() < 0.1 && (e.mean[1] - truth.y).abs() < 0.1,
        "{e:?}"
    );
    assert!(e.sigma_m() < 0.3, "{e:?}");
}

#[test]
fn bad_detections_are_refused_and_change_nothing() {
    let (_, grid, _, sensor) = setup(OpticalParams::default());
    let mut lik = vec![1.0; grid.len()];
    let nan = Detection {
        point: [f64::NAN, 0.0],
        cov: [1e-4, 0.0, 1e-4],
    };
    let singular = Detection {
        point: [0.0, 0.0],
        cov: [1e-4, 1e-4, 1e-4],
    };
    for d in [nan, singular] {
        let e = sensor.apply(Mode::Active, &[d], &mut lik).unwrap_err();
        assert!(e.to_string().starts_with("camera 7:"), "{e}");
    }
    assert!(sensor.apply(Mode::Active, &[], &mut [1.0; 3]).is_err());
    assert!(lik.iter().all(|l| *l == 1.0));
    assert!(
        OpticalParams {
            detection_probability: 1.5,
            ..OpticalParams::default()
        }
        .validate()
        .is_err()
    );
}
