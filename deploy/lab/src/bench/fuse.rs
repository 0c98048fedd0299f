//! `ocelli bench fuse`: what fusing external detections costs as more of them share one time
//! stamp, as JSON — the grouping's cost grows with the pairs of detections within the gate,
//! not with the square of the detections.
//!
//! Measures (build with `--release`): `ms[N]`, one `replay_ml` over N detections at one time
//! stamp (N = 1000, 2000, 4000, 8000 times `scale`): people at seeded random places on the
//! default scenario's floor, each seen by the cameras whose image it falls in, with the plane
//! and gate of `ocelli fuse --plane-z 0`.

use crate::Result;
use crate::replay::cameras::Cameras;
use crate::replay::detections::ExternalDetection;
use crate::replay::ml::{MlOptions, replay_ml};
use nalgebra::Vector3;
use proto::scenario::Scenario;
use rand::{Rng, SeedableRng};
use serde_json::json;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scale the detection counts (1.0 = default).
    pub scale: f64,
}

/// `n` detections at t = 0 of people scattered over the scenario's floor.
fn crowd(scenario: &Scenario, cameras: &Cameras, n: usize) -> Vec<ExternalDetection> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (lo, hi) = (scenario.world.min, scenario.world.max);
    let mut out = Vec::with_capacity(n + cameras.models.len());
    while out.len() < n {
        let p = Vector3::new(rng.random_range(lo[0]..hi[0]), rng.random_range(lo[1]..hi[1]), 0.0);
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
    }
    out.truncate(n);
    out
}

/// # Errors
/// The default scenario's cameras cannot be built.
pub fn run(opts: &Options) -> Result<serde_json::Value> {
    let scenario = Scenario::default_scenario();
    let cameras = Cameras::from_scenario(&scenario).map_err(|e| crate::LabError::failed("fuse bench", e.to_string()))?;
    let options = MlOptions {
        plane_z: Some(0.0),
        ..MlOptions::default()
    };
    let mut ms = serde_json::Map::new();
    let mut estimates = serde_json::Map::new();
    for base in [1000usize, 2000, 4000, 8000] {
        let n = ((base as f64 * opts.scale).round() as usize).max(1);
        let detections = crowd(&scenario, &cameras, n);
        #[allow(clippy::disallowed_methods)] // a benchmark times itself
        let start = Instant::now();
        let (est, _) = replay_ml(&detections, &cameras, &options);
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        ms.insert(n.to_string(), json!(elapsed));
        estimates.insert(n.to_string(), json!(est.len()));
    }
    Ok(json!({
        "bench": "fuse",
        "detections_per_stamp_ms": ms,
        "estimates": estimates,
    }))
}
