//! Timing of the grid estimator's hot path, for `ocelli bench grid`: one step of prediction
//! plus correction by one camera's detection likelihood.

use super::belief::{Belief, RandomWalk};
use super::layout::Grid;
use super::optical::{Detection, OpticalParams, OpticalSensor};
use nalgebra::Vector3;
use proto::Mode;
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose};
use proto::scenario::{RadioWorld, Wall, World};
use std::sync::Arc;
use std::time::Instant;

/// Median wall-clock milliseconds of one predict + correct on an `nx`×`ny` grid (10 cm
/// cells, a wall across half the room, 0.2 s steps of a 1 m/√s random walk, a camera whose
/// likelihood covers about a third of the grid), over `iters` steps after a few warm-up
/// steps. The likelihood's per-step part (the detection term) is included; the P_d map is
/// built once, as in the estimator.
#[allow(clippy::disallowed_methods)] // a bench owns its clock; the estimator it times does not
pub fn bench_update(nx: usize, ny: usize, iters: usize) -> f64 {
    let cell = 0.1;
    let (w, h) = (nx as f64 * cell, ny as f64 * cell);
    let world = World {
        min: [0.0, 0.0, 0.0],
        max: [w, h, 3.0],
        walls: vec![Wall {
            from: [0.5 * w, 0.0],
            to: [0.5 * w, 0.5 * h],
            height: 2.5,
            attenuation_db: 6.0,
        }],
        radio: RadioWorld::default(),
        geo: None,
    };
    let grid = Arc::new(Grid::new(&world, cell).expect("the bench grid is valid"));
    let camera = CameraModel {
        intrinsics: Intrinsics {
            fx: 320.0,
            fy: 320.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        distortion: Distortion::default(),
        pose: Pose::look_at(
            Vector3::new(0.0, 0.5 * h, 2.5),
            Vector3::new(0.5 * w, 0.5 * h, 0.85),
            Vector3::z(),
        )
        .expect("the bench camera is not vertical"),
    };
    let params = OpticalParams {
        max_range_m: 1e3,
        ..OpticalParams::default()
    };
    let sensor = OpticalSensor::new(1, &camera, &grid, &world, &params).expect("valid parameters");
    let target = Vector3::new(0.3 * w, 0.6 * h, 0.85);
    let (p, _) = camera.normalized(&target);
    let cov = camera.normalized_covariance(&p, 4.0);
    let detection = Detection {
        point: [p.x, p.y],
        cov: [cov[(0, 0)], cov[(0, 1)], cov[(1, 1)]],
    };
    let motion = RandomWalk {
        sigma_per_sqrt_s: 1.0,
    };
    let mut belief = Belief::gaussian(grid.clone(), [target.x, target.y], 0.5);
    let mut likelihood = vec![1.0; grid.len()];
    let mut step = |belief: &mut Belief| {
        belief.predict(&motion, 0.2).expect("valid step");
        likelihood.fill(1.0);
        sensor
            .apply(Mode::Active, &[detection], &mut likelihood)
            .expect("valid detection");
        belief.correct(&likelihood).expect("valid likelihood");
    };
    for _ in 0..iters.div_ceil(10).max(2) {
        step(&mut belief);
    }
    let mut times: Vec<f64> = (0..iters.max(1))
        .map(|_| {
            let start = Instant::now();
            step(&mut belief);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bench runs and reports a finite, positive time (its value is measured, not asserted).
    #[test]
    fn bench_update_runs() {
        let ms = bench_update(20, 16, 3);
        assert!(ms.is_finite() && ms > 0.0);
    }
}
