//! The association's assignment, for `ocelli bench head`: how long the optimal (global nearest
//! neighbour) assignment takes on crowd-like problems, and how much cost the greedy
//! nearest-first rule it replaced leaves on the table on the same problems.
//!
//! A problem: `tracks` people spread over a square of 2.25 m² each, `detections` split
//! round-robin over `cameras`, each a person seen with 0.3 m of Gaussian noise (one in ten is
//! clutter anywhere); d² is the squared distance over 0.3², gated at 9.21 (χ², 2 degrees of
//! freedom, 99%).

use assign::{GatedCosts, assign};
use rand::{Rng, SeedableRng};
use serde_json::json;
use std::hint::black_box;

/// A random crowd problem (see the module docs).
pub fn bench_costs(detections: usize, tracks: usize, cameras: usize, seed: u64) -> GatedCosts {
    const SIGMA: f64 = 0.3;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let side = 1.5 * (tracks.max(1) as f64).sqrt();
    let people: Vec<[f64; 2]> = (0..tracks)
        .map(|_| [rng.random_range(0.0..side), rng.random_range(0.0..side)])
        .collect();
    let mut costs = GatedCosts::new(tracks, 9.21).expect("a valid gate");
    let cameras = cameras.max(1);
    for i in 0..detections {
        let at = if tracks == 0 || rng.random_bool(0.1) {
            [rng.random_range(0.0..side), rng.random_range(0.0..side)]
        } else {
            let p = people[(i / cameras) % tracks];
            // Box–Muller.
            let (u, v): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
            let r = SIGMA * (-2.0 * u.ln()).sqrt();
            let a = std::f64::consts::TAU * v;
            [p[0] + r * a.cos(), p[1] + r * a.sin()]
        };
        let d2: Vec<Option<f64>> = people
            .iter()
            .map(|p| Some(((at[0] - p[0]).powi(2) + (at[1] - p[1]).powi(2)) / (SIGMA * SIGMA)))
            .collect();
        costs.push(i % cameras, &d2).expect("finite, non-negative costs");
    }
    costs
}

/// Greedy nearest-first: pairs inside the gate taken from the smallest d², each detection to
/// one track and each track to one detection per camera (what the camera and the head did
/// before the optimal assignment).
pub fn greedy(costs: &GatedCosts) -> Vec<Option<usize>> {
    let mut pairs = Vec::new();
    for d in 0..costs.detections() {
        for t in 0..costs.tracks() {
            if let Some(c) = costs.cost(d, t) {
                pairs.push((c, d, t));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = vec![None; costs.detections()];
    let mut taken = std::collections::HashSet::new();
    for (_, d, t) in pairs {
        let camera = costs.camera(d).unwrap_or(0);
        if out[d].is_none() && !taken.contains(&(camera, t)) {
            out[d] = Some(t);
            taken.insert((camera, t));
        }
    }
    out
}

/// Median timings of [`assign`] (µs) and the greedy rule's excess cost over the optimum, per
/// problem size `(detections, tracks, cameras)`, over `problems` seeds each.
pub fn run(problems: usize, median_us: impl Fn(usize, &mut dyn FnMut()) -> f64) -> serde_json::Value {
    let mut out = serde_json::Map::new();
    for (detections, tracks, cameras) in [(10, 10, 1), (40, 10, 4), (200, 50, 4), (1000, 100, 10)] {
        let (mut worse, mut excess) = (0usize, 0.0f64);
        for seed in 0..problems as u64 {
            let c = bench_costs(detections, tracks, cameras, seed);
            let best = c.total_cost(&assign(&c)).unwrap_or(f64::NAN);
            let g = c.total_cost(&greedy(&c)).unwrap_or(f64::NAN);
            if g > best + 1e-9 {
                worse += 1;
                excess += (g - best) / best.max(1e-9);
            }
        }
        let c = bench_costs(detections, tracks, cameras, 1);
        let us = median_us(200, &mut || {
            black_box(assign(black_box(&c)));
        });
        out.insert(
            format!("{detections}x{tracks}x{cameras}"),
            json!({
                "assign_us": us,
                "greedy_worse_share": worse as f64 / problems.max(1) as f64,
                "greedy_excess_cost_when_worse": if worse > 0 { excess / worse as f64 } else { 0.0 },
            }),
        );
    }
    serde_json::Value::Object(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_problems_have_the_requested_shape_and_real_choices() {
        let c = bench_costs(200, 50, 4, 1);
        assert_eq!((c.detections(), c.tracks()), (200, 50));
        assert_eq!((0..200).filter(|&i| c.camera(i) == Some(2)).count(), 50);
        // Most detections are inside the gate of their person; some compete for several tracks.
        let inside: Vec<usize> = (0..200)
            .map(|i| (0..50).filter(|&t| c.cost(i, t).is_some()).count())
            .collect();
        assert!(inside.iter().filter(|n| **n > 0).count() > 150, "{inside:?}");
        assert!(inside.iter().any(|n| *n > 1), "{inside:?}");
        assert_eq!(assign(&c), assign(&bench_costs(200, 50, 4, 1)));
        // The optimum is never worse than greedy, and on crowds greedy is sometimes worse.
        let mut worse = 0;
        for seed in 0..20 {
            let c = bench_costs(40, 10, 4, seed);
            let (a, g) = (
                c.total_cost(&assign(&c)).unwrap(),
                c.total_cost(&greedy(&c)).unwrap(),
            );
            assert!(a <= g + 1e-9, "seed {seed}: optimal {a} > greedy {g}");
            worse += usize::from(g > a + 1e-9);
        }
        assert!(worse > 0, "greedy was optimal on every crowd");
    }
}
