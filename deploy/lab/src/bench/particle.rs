//! Paper 004's camera path for `ocelli bench camera`: milliseconds per frame of the colour
//! particle filters (`node_camera::tracker::bench`: 1, 5 or 10 people × 100 particles at
//! 320×240 and 640×480, drawing excluded; and the people's lower edges in the mask,
//! `node_camera::tracker::feet`, in microseconds) and the adaptive background model's frames per
//! second at 320×240 on the same synthetic crowd. Keys are added to the camera bench's JSON.

use node_camera::adaptive_background::{AdaptiveBackground, AdaptiveBackgroundParams};
use node_camera::tracker::bench::bench_with;
use node_camera::tracker::params::ParticleParams;
use node_camera::tracker::scene::Scene;
use proto::ClusterTime;
use proto::sensor::Frame;
use serde_json::{Map, Value, json};
use std::time::Instant;

/// Sizes and crowds the particle filters are timed at.
const SIZES: [(u32, u32); 2] = [(320, 240), (640, 480)];
const PEOPLE: [usize; 3] = [1, 5, 10];
const PARTICLES: usize = 100;

/// `pf_ms_per_frame_{W}x{H}_{N}x100` and `feet_us_per_frame_{W}x{H}_{N}` for every size and
/// crowd (medians over `frames` frames).
pub fn particle_filter_keys(frames: usize) -> Map<String, Value> {
    let params = ParticleParams {
        particles: PARTICLES,
        ..ParticleParams::default()
    };
    let mut out = Map::new();
    for (w, h) in SIZES {
        for n in PEOPLE {
            let r = bench_with(&params, w, h, n, frames.max(5));
            out.insert(
                format!("pf_ms_per_frame_{w}x{h}_{n}x{PARTICLES}"),
                json!(r.median_ms),
            );
            out.insert(format!("feet_us_per_frame_{w}x{h}_{n}"), json!(r.feet_median_us));
        }
    }
    out
}

/// Frames per second of the adaptive background model alone at `width`×`height` (the median
/// frame's time), on a crowd of five drawn with noise; drawing is not timed.
#[allow(clippy::disallowed_methods)] // a bench reads the clock; the model it times does not
pub fn background_fps(width: u32, height: u32, frames: usize) -> f64 {
    let scene = Scene::crowd(width, height, 5);
    let mut model = AdaptiveBackground::new(AdaptiveBackgroundParams::default());
    let mut frame = Frame::new(scene.width, scene.height, ClusterTime::ZERO);
    let mut dets = Vec::new();
    let mut times = Vec::with_capacity(frames);
    let warmup = 25; // the ring buffer fills first (history 20)
    for t in 0..(warmup + frames.max(5)) as u32 {
        scene.render(t, &mut frame);
        scene.add_noise(t, &mut frame);
        let start = Instant::now();
        if model.process(&frame, &mut dets).is_err() {
            return f64::NAN;
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if t >= warmup as u32 {
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    if median > 0.0 { 1e3 / median } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_particle_key_is_a_finite_time_and_the_background_runs() {
        let keys = particle_filter_keys(1);
        assert_eq!(keys.len(), 12);
        assert!(keys.contains_key("pf_ms_per_frame_640x480_10x100"));
        assert!(keys.contains_key("feet_us_per_frame_640x480_10"));
        assert!(
            keys.values()
                .all(|v| v.as_f64().is_some_and(|x| x.is_finite() && x >= 0.0))
        );
        assert!(background_fps(64, 48, 5) > 0.0);
    }
}
