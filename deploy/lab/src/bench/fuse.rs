//! `ocelli bench fuse`: what fusing external detections costs as more of them share one time
//! stamp, as JSON. The grouping's cost grows with the pairs of detections within the gate of
//! each other, not with the square of all detections: at a fixed crowd density (more people
//! over a larger floor) it grows near-linearly; packing ever more people into one room grows
//! the pairs, and the cost, with the square of the density.
//!
//! Measures (build with `--release` for absolute figures): one `replay_ml` over N detections at
//! one time stamp (N = 1000, 2000, 4000, 8000 times `scale`), with the plane and gate of
//! `ocelli fuse --plane-z 0`, for people at seeded random places
//! - `spread_ms[N]`: on a row of copies of the default scenario's room, each with its own
//!   cameras, at [`PEOPLE_PER_M2`] — N grows with the floor;
//! - `one_room_ms[N]`: all in the default scenario's room — N grows with the density.

use crate::Result;
use crate::replay::cameras::Cameras;
use crate::replay::detections::ExternalDetection;
use crate::replay::ml::{MlOptions, replay_ml};
use nalgebra::Vector3;
use proto::camera::CameraModel;
use proto::scenario::Scenario;
use rand::{Rng, SeedableRng};
use serde_json::json;
use std::collections::BTreeMap;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scale the detection counts (1.0 = default).
    pub scale: f64,
}

/// The crowd density of the `spread` series: a busy hall, people a metre apart.
pub const PEOPLE_PER_M2: f64 = 1.0;

/// `rooms` copies of the scenario's room side by side along x, each with its own cameras
/// (ids `r<room>-<camera>`).
fn rooms(scenario: &Scenario, base: &Cameras, rooms: usize) -> Cameras {
    let width = scenario.world.max[0] - scenario.world.min[0];
    let mut models = BTreeMap::new();
    for r in 0..rooms {
        let shift = Vector3::new(width * r as f64, 0.0, 0.0);
        for (id, m) in &base.models {
            let mut shifted: CameraModel = *m;
            // p_c = R p + t for the original; the copy sees p + shift as the original sees p.
            shifted.pose.translation -= shifted.pose.rotation * shift;
            models.insert(format!("r{r}-{id}"), shifted);
        }
    }
    Cameras { models, mirror: None }
}

/// `n` detections at t = 0 of people at random places on `[x0, x1] × [y0, y1]`, each seen by
/// every camera whose image it falls in, and how many people were seen.
fn crowd(cameras: &Cameras, floor: ([f64; 2], [f64; 2]), n: usize) -> (Vec<ExternalDetection>, usize) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let ([x0, y0], [x1, y1]) = floor;
    let mut out = Vec::with_capacity(n + cameras.models.len());
    let mut people = 0;
    while out.len() < n {
        let before = out.len();
        let p = Vector3::new(rng.random_range(x0..x1), rng.random_range(y0..y1), 0.0);
        for (id, m) in &cameras.models {
            let k = &m.intrinsics;
            if let Some(px) = m.project(&p)
                && px.x >= 0.0
                && px.y >= 0.0
                && px.x < f64::from(k.width)
                && px.y < f64::from(k.height)
            {
                out.push(ExternalDetection {
                    t: 0.0,
                    camera: id.clone(),
                    u: px.x,
                    v: px.y,
                    pixel_box: None,
                    rssi: None,
                });
            }
        }
        people += usize::from(out.len() > before);
    }
    out.truncate(n);
    (out, people)
}

/// Milliseconds of one fusion of `detections`, and its estimates.
fn time_fusion(detections: &[ExternalDetection], cameras: &Cameras) -> (f64, usize) {
    let options = MlOptions {
        plane_z: Some(0.0),
        ..MlOptions::default()
    };
    #[allow(clippy::disallowed_methods)] // a benchmark times itself
    let start = Instant::now();
    let (est, _) = replay_ml(detections, cameras, &options);
    (start.elapsed().as_secs_f64() * 1e3, est.len())
}

/// # Errors
/// The default scenario's cameras cannot be built.
pub fn run(opts: &Options) -> Result<serde_json::Value> {
    let scenario = Scenario::default_scenario();
    let one = Cameras::from_scenario(&scenario)
        .map_err(|e| crate::LabError::failed("fuse bench", e.to_string()))?;
    let (lo, hi) = (scenario.world.min, scenario.world.max);
    let room_area = (hi[0] - lo[0]) * (hi[1] - lo[1]);
    // Detections per person in one room: how many rooms a count needs at the set density.
    let (sample, seen) = crowd(&one, ([lo[0], lo[1]], [hi[0], hi[1]]), 1000);
    let per_person = sample.len() as f64 / seen.max(1) as f64;
    let mut spread = serde_json::Map::new();
    let mut one_room = serde_json::Map::new();
    let mut estimates = serde_json::Map::new();
    for base in [1000usize, 2000, 4000, 8000] {
        let n = ((base as f64 * opts.scale).round() as usize).max(1);
        let people = n as f64 / per_person;
        let count = ((people / (PEOPLE_PER_M2 * room_area)).ceil() as usize).max(1);
        let row = rooms(&scenario, &one, count);
        let x1 = lo[0] + (hi[0] - lo[0]) * count as f64;
        let (ms, est) = time_fusion(&crowd(&row, ([lo[0], lo[1]], [x1, hi[1]]), n).0, &row);
        spread.insert(n.to_string(), json!(ms));
        estimates.insert(n.to_string(), json!(est));
        let (ms, _) = time_fusion(&crowd(&one, ([lo[0], lo[1]], [hi[0], hi[1]]), n).0, &one);
        one_room.insert(n.to_string(), json!(ms));
    }
    Ok(json!({
        "bench": "fuse",
        "people_per_m2": PEOPLE_PER_M2,
        "spread_ms": spread,
        "spread_estimates": estimates,
        "one_room_ms": one_room,
    }))
}
