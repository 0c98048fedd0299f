//! Sensor faults the simulation can inject, for the papers' experiments: measurement loss of
//! chosen cameras in a time window (paper 000 Table 1), random frame failures, extra
//! segmentation noise and camera yaw pointing errors (paper 002 §VI-B). Faults act on the
//! simulated *world* only — what a camera sees — never on what a node believes: a yawed camera's
//! node keeps its nominal pose, a noisier detection is still weighted with the scenario's
//! `pixel-sigma`. Every random draw comes from streams seeded by the run's seed.

use proto::scenario::{PoseSpec, Scenario};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Measurements of one camera lost in a time window: the camera stays on (and spends its
/// energy) but its frames yield no detection.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Blackout {
    pub camera: u32,
    /// Scenario seconds, inclusive start, exclusive end.
    pub from_s: f64,
    pub to_s: f64,
}

/// The faults of one run. `Faults::default()` injects none.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Faults {
    pub blackouts: Vec<Blackout>,
    /// Probability that one frame of one camera fails (yields nothing), independently per frame.
    pub frame_failure: f64,
    /// Extra pixel noise σ (px) on measurement-level detections: the total σ is
    /// √(pixel-sigma² + extra²). Nodes keep weighting with `pixel-sigma`.
    pub extra_pixel_sigma: f64,
    /// Standard deviation (rad) of each camera's yaw pointing error: the true camera is turned
    /// about the vertical through its centre; its node keeps the nominal pose.
    pub yaw_sigma_rad: f64,
}

impl Faults {
    /// Whether a blackout covers `camera` at `t_s`.
    pub fn blacked_out(&self, camera: u32, t_s: f64) -> bool {
        self.blackouts
            .iter()
            .any(|b| b.camera == camera && t_s >= b.from_s && t_s < b.to_s)
    }

    /// Whether one frame fails, drawing from `rng` only when failures are on (so a run without
    /// them draws nothing).
    pub fn frame_fails(&self, rng: &mut impl Rng) -> bool {
        self.frame_failure > 0.0 && rng.random::<f64>() < self.frame_failure
    }

    /// Total pixel σ of measurement-level detections given the scenario's.
    pub fn pixel_sigma(&self, scenario_sigma: f64) -> f64 {
        scenario_sigma.hypot(self.extra_pixel_sigma)
    }
}

/// The world as it truly is under `faults`: each camera's look-at pose turned by a yaw drawn
/// from N(0, yaw_sigma²) (seeded; one draw per camera in node order). Cameras posed by Rodrigues
/// vectors or OpenCV files are left as they are (the experiments pose cameras by look-at).
pub fn true_world(scenario: &Scenario, faults: &Faults, seed: u64) -> Scenario {
    let mut world = scenario.clone();
    if faults.yaw_sigma_rad <= 0.0 {
        return world;
    }
    let Ok(normal) = Normal::new(0.0, faults.yaw_sigma_rad) else {
        return world;
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x0079_6177_0000_0001);
    for node in &mut world.nodes {
        let Some(PoseSpec::LookAt { position, look_at }) = node.camera.as_mut().and_then(|c| c.pose.as_mut())
        else {
            continue;
        };
        let yaw: f64 = normal.sample(&mut rng);
        let (dx, dy) = (look_at[0] - position[0], look_at[1] - position[1]);
        let (s, c) = yaw.sin_cos();
        look_at[0] = position[0] + c * dx - s * dy;
        look_at[1] = position[1] + s * dx + c * dy;
    }
    world
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blackouts_cover_their_camera_and_window_only() {
        let f = Faults {
            blackouts: vec![Blackout {
                camera: 11,
                from_s: 10.0,
                to_s: 25.0,
            }],
            ..Faults::default()
        };
        assert!(f.blacked_out(11, 10.0) && f.blacked_out(11, 24.9));
        assert!(!f.blacked_out(11, 9.9) && !f.blacked_out(11, 25.0));
        assert!(!f.blacked_out(12, 15.0));
    }

    #[test]
    fn frame_failures_follow_their_probability_and_none_draws_nothing() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let f = Faults {
            frame_failure: 0.3,
            ..Faults::default()
        };
        let n = (0..10_000).filter(|_| f.frame_fails(&mut rng)).count();
        assert!((2_700..3_300).contains(&n), "{n} of 10000 failed at p = 0.3");
        let before = rng.clone();
        assert!(!Faults::default().frame_fails(&mut rng));
        assert_eq!(before.get_word_pos(), rng.get_word_pos());
        assert!((Faults::default().pixel_sigma(18.0) - 18.0).abs() < 1e-12);
        let noisy = Faults {
            extra_pixel_sigma: 24.0,
            ..Faults::default()
        };
        assert!((noisy.pixel_sigma(18.0) - 30.0).abs() < 1e-9);
    }

    #[test]
    fn yaw_turns_look_at_cameras_about_their_centre_deterministically() {
        let s = Scenario::default_scenario();
        assert_eq!(true_world(&s, &Faults::default(), 1), s);
        let f = Faults {
            yaw_sigma_rad: 0.1,
            ..Faults::default()
        };
        let (a, b) = (true_world(&s, &f, 1), true_world(&s, &f, 1));
        assert_eq!(a, b);
        assert_ne!(a, true_world(&s, &f, 2));
        let pose =
            |sc: &Scenario, i: usize| match sc.cameras().nth(i).and_then(|n| n.camera.as_ref()?.pose.clone())
            {
                Some(PoseSpec::LookAt { position, look_at }) => (position, look_at),
                other => panic!("camera {i} is not posed by look-at: {other:?}"),
            };
        let mut yaws = Vec::new();
        for i in 0..s.cameras().count() {
            let ((p0, l0), (p1, l1)) = (pose(&s, i), pose(&a, i));
            assert_eq!(p0, p1, "the centre stays");
            assert!((l0[2] - l1[2]).abs() < 1e-12, "the turn is about the vertical");
            let h0 = (l0[1] - p0[1]).atan2(l0[0] - p0[0]);
            let h1 = (l1[1] - p1[1]).atan2(l1[0] - p1[0]);
            let d = (h1 - h0 + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            yaws.push(d);
        }
        let rms = (yaws.iter().map(|y| y * y).sum::<f64>() / yaws.len() as f64).sqrt();
        assert!(
            (0.04..0.2).contains(&rms),
            "rms yaw {rms} rad for σ = 0.1 over 21 cameras"
        );
    }
}
