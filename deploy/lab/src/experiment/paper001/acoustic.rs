//! Paper 001 §4.1 (Table 1, Fig. 10) in the simulated room: how well the acoustic observation
//! likelihood alone finds a sound source hidden behind one or two walls, as the nearer wall's
//! distance and the walls' length vary.
//!
//! Setup: the paper's bench (Table 1) scaled by 3, its 10 cm speaker spacing becoming our
//! 0.3 m lattice (our band is the paper's real-room 20–386 Hz, whose wavelengths are metres,
//! so the bench must grow with them). The two-microphone node stands next to the room's outer
//! wall at (0.3, 2.5) facing +x, as the paper's sensor does; the "speaker array" of 9 × 6 = 54
//! fingerprint positions 0.3 m apart covers x ∈ [1.8, 4.2], y ∈ [1.75, 3.25], its edge
//! L_m = 1.5 m from the node (the paper's 50 cm); the room is 5 × 5 m. Each position is
//! rendered for 0.5 s by `world::acoustics` and analysed as the node analyses its frames. A
//! wall across the line of sight, centred on y = 2.5, of length L_w ∈ {1.5, 1.8, 2.1} m (the
//! paper's 50–70 cm), at L_d ∈ {0, 0.3, 0.6, 0.9} m from the array's edge (0–30 cm); with two
//! walls the second stays 0.15 m in front of the array and only the nearer one moves (as in
//! the paper). Test sources at seeded random positions in the array's area, off the lattice;
//! for each, the likelihood (eq. 16–18) on a 5 cm grid over the array's area gives the
//! nearest-peak error (distance from the truth to the nearest local maximum above half the
//! highest one) and the differential entropy of the normalised likelihood. The error is
//! measured twice on the same test sound: with the correlations as the spline's control
//! points, as eq. 17 prints it, and with the spline interpolating them (the surface passes
//! through each fingerprint's correlation instead of smoothing it with its neighbours').

use crate::Result;
use crate::error::OrFailed;
use node_acoustic::ild::IldAnalyzer;
use node_head::grid::acoustic::{AcousticParams as Likelihood, AcousticSensor};
use node_head::grid::belief::Belief;
use node_head::grid::layout::Grid;
use proto::acoustic::{Fingerprint, FingerprintDb, SplineFit};
use proto::scenario::{RadioWorld, Wall, World, low_band};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use world::acoustics::{AcousticParams, TwoMicNode, render_stereo};

/// The array's area, `[xmin, ymin, xmax, ymax]`, m (lattice at its corners).
const ARRAY: [f64; 4] = [1.8, 1.75, 4.2, 3.25];
/// The node's centre: next to the outer wall, L_m = 1.5 m from the array's edge.
const NODE: [f64; 3] = [0.3, 2.5, 1.2];
/// The room's depth along x, m (the outline is [0, ROOM_X] × [0, 5]).
const ROOM_X: f64 = 5.0;
const SPACING_M: f64 = 0.3;
const SURVEY_S: f64 = 0.5;
const TEST_S: f64 = 0.5;
const GRID_CELL_M: f64 = 0.05;
/// The nearer wall's distance from the array's edge, m (single wall; two walls use the last three).
pub const DISTANCES_M: [f64; 4] = [0.0, 0.3, 0.6, 0.9];
/// The walls' length, m.
pub const LENGTHS_M: [f64; 3] = [1.5, 1.8, 2.1];
/// Where the second wall stays, in front of the array's edge, m.
const SECOND_WALL_M: f64 = 0.15;

/// One wall configuration's figures.
#[derive(Clone, Debug)]
pub struct Cell {
    pub walls: u32,
    pub distance_m: f64,
    pub length_m: f64,
    /// Nearest-peak error per test source with the paper's control-point spline, m.
    pub errors_m: Vec<f64>,
    /// The same with the interpolating spline, m.
    pub errors_interpolating_m: Vec<f64>,
    /// Differential entropy of the normalised likelihood per test source, nats.
    pub entropies: Vec<f64>,
}

impl Cell {
    pub fn mean_error(&self) -> f64 {
        mean(&self.errors_m)
    }
    pub fn mean_entropy(&self) -> f64 {
        mean(&self.entropies)
    }
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn wall_at(x: f64, length: f64) -> Wall {
    Wall {
        from: [x, 2.5 - 0.5 * length],
        to: [x, 2.5 + 0.5 * length],
        height: 3.0,
        attenuation_db: 20.0,
    }
}

/// The room with `walls` walls, the nearer at `distance` from the array's edge.
pub fn room(walls: u32, distance: f64, length: f64) -> World {
    let near_x = ARRAY[0] - distance;
    let mut w = vec![wall_at(near_x, length)];
    if walls == 2 {
        // The distances swept with two walls are all larger than the second wall's.
        w.push(wall_at(ARRAY[0] - SECOND_WALL_M, length));
    }
    World {
        min: [0.0, 0.0, 0.0],
        max: [ROOM_X, 5.0, 3.0],
        walls: w,
        radio: RadioWorld::default(),
        geo: None,
    }
}

fn array_world() -> World {
    World {
        min: [ARRAY[0], ARRAY[1], 0.0],
        max: [ARRAY[2], ARRAY[3], 3.0],
        walls: Vec::new(),
        radio: RadioWorld::default(),
        geo: None,
    }
}

/// Nearest local maximum (8-neighbour, at least half the highest value) of `map` to `truth`, m.
pub fn nearest_peak_error(grid: &Grid, map: &[f64], truth: [f64; 2]) -> f64 {
    let (nx, ny) = grid.shape();
    let top = map.iter().copied().fold(0.0, f64::max);
    let mut best = f64::INFINITY;
    for j in 0..ny {
        for i in 0..nx {
            let v = map[j * nx + i];
            if v < 0.5 * top || v <= 0.0 {
                continue;
            }
            let peak = (-1i64..=1).all(|dj| {
                (-1i64..=1).all(|di| {
                    let (a, b) = (i as i64 + di, j as i64 + dj);
                    if (di, dj) == (0, 0) || a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                        return true;
                    }
                    map[b as usize * nx + a as usize] <= v
                })
            });
            if peak {
                let c = grid.centre(i, j);
                best = best.min((c[0] - truth[0]).hypot(c[1] - truth[1]));
            }
        }
    }
    best
}

/// Evaluate one wall configuration with `sources` test positions.
///
/// # Errors
/// A survey or analysis the acoustic code refuses.
pub fn evaluate(walls: u32, distance: f64, length: f64, sources: usize, seed: u64) -> Result<Cell> {
    let room = room(walls, distance, length);
    let settings = low_band();
    let node = TwoMicNode::ears(NODE, 0.0, 0.2);
    let params = AcousticParams::default();
    let mut analyzer = IldAnalyzer::new(&settings).or_failed("paper001")?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rate = settings.sample_rate;
    let listen = |p: [f64; 2], secs: f64, rng: &mut ChaCha8Rng, a: &mut IldAnalyzer| {
        let n = (secs * f64::from(rate)).round() as usize;
        let (l, r) = render_stereo(&room, &params, &node, p, n, rate, rng);
        a.analyze(&l, &r)
    };
    let (nx, ny) = (
        ((ARRAY[2] - ARRAY[0]) / SPACING_M).round() as usize + 1,
        ((ARRAY[3] - ARRAY[1]) / SPACING_M).round() as usize + 1,
    );
    let mut fingerprints = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let p = [ARRAY[0] + SPACING_M * i as f64, ARRAY[1] + SPACING_M * j as f64];
            let values = listen(p, SURVEY_S, &mut rng, &mut analyzer)
                .or_failed("paper001")?
                .values;
            fingerprints.push(Fingerprint { position: p, values });
        }
    }
    let area = array_world();
    let db = FingerprintDb::new(&area, settings, fingerprints).or_failed("fingerprints")?;
    let grid = Arc::new(Grid::new(&area, GRID_CELL_M).or_failed("paper001")?);
    let interpolating = Likelihood {
        fit: SplineFit::Interpolating,
        ..Likelihood::default()
    };
    let sensor = AcousticSensor::new(&grid, db.clone(), Likelihood::default()).or_failed("paper001")?;
    let through = AcousticSensor::new(&grid, db, interpolating).or_failed("paper001")?;
    let mut cell = Cell {
        walls,
        distance_m: distance,
        length_m: length,
        errors_m: Vec::with_capacity(sources),
        errors_interpolating_m: Vec::with_capacity(sources),
        entropies: Vec::with_capacity(sources),
    };
    for _ in 0..sources {
        let p = [
            rng.random_range(ARRAY[0] + 0.05..ARRAY[2] - 0.05),
            rng.random_range(ARRAY[1] + 0.05..ARRAY[3] - 0.05),
        ];
        let ild = listen(p, TEST_S, &mut rng, &mut analyzer).or_failed("paper001")?;
        let map = sensor.likelihood_map(&ild).or_failed("paper001")?;
        cell.errors_m.push(nearest_peak_error(&grid, &map, p));
        let map_through = through.likelihood_map(&ild).or_failed("paper001")?;
        cell.errors_interpolating_m
            .push(nearest_peak_error(&grid, &map_through, p));
        let mut b = Belief::uniform(grid.clone());
        b.correct(&map).or_failed("paper001")?;
        cell.entropies.push(b.differential_entropy());
    }
    Ok(cell)
}

/// Every configuration: one wall at each distance and length, two walls at the last three
/// distances and each length (the paper's 12 and 9 cases).
///
/// # Errors
/// As [`evaluate`].
pub fn study(sources: usize, seed: u64) -> Result<Vec<Cell>> {
    let mut out = Vec::new();
    for walls in [1u32, 2] {
        let distances: &[f64] = if walls == 1 {
            &DISTANCES_M
        } else {
            &DISTANCES_M[1..]
        };
        for &d in distances {
            for &l in &LENGTHS_M {
                out.push(evaluate(walls, d, l, sources, seed)?);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_peak_finds_the_closest_of_two_peaks() {
        let area = array_world();
        let grid = Grid::new(&area, 0.1).unwrap();
        let (nx, ny) = grid.shape();
        let bump = |c: [f64; 2], p: [f64; 2]| (-((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2)) / 0.02).exp();
        let map: Vec<f64> = (0..nx * ny)
            .map(|k| {
                let c = grid.centre_of(k);
                bump(c, [ARRAY[0] + 0.5, 2.0]) + 0.8 * bump(c, [ARRAY[0] + 2.0, 3.0])
            })
            .collect();
        let e = nearest_peak_error(&grid, &map, [ARRAY[0] + 1.9, 3.0]);
        assert!(e < 0.15, "the second peak is the nearest: {e}");
    }

    /// One configuration end to end (render, survey, likelihood): finite errors inside the
    /// array's area and entropies no larger than a uniform density's over it.
    #[test]
    fn one_configuration_gives_bounded_errors_and_entropies() {
        let c = evaluate(1, DISTANCES_M[1], LENGTHS_M[0], 2, 7).unwrap();
        let diagonal = (ARRAY[2] - ARRAY[0]).hypot(ARRAY[3] - ARRAY[1]);
        let uniform = ((ARRAY[2] - ARRAY[0]) * (ARRAY[3] - ARRAY[1])).ln();
        assert_eq!(c.errors_m.len(), 2);
        assert_eq!(c.errors_interpolating_m.len(), 2);
        for e in &c.errors_interpolating_m {
            assert!(e.is_finite() && *e >= 0.0 && *e <= diagonal, "error {e}");
        }
        for (e, h) in c.errors_m.iter().zip(&c.entropies) {
            assert!(e.is_finite() && *e >= 0.0 && *e <= diagonal, "error {e}");
            assert!(
                h.is_finite() && *h <= uniform + 1e-6,
                "entropy {h} above uniform {uniform}"
            );
        }
    }

    #[test]
    fn two_walls_put_the_moving_one_nearer_the_node() {
        let w = room(2, DISTANCES_M[2], LENGTHS_M[1]).walls;
        assert_eq!(w.len(), 2);
        assert!(w[0].from[0] < w[1].from[0], "{w:?}");
        assert!((w[1].from[0] - (ARRAY[0] - SECOND_WALL_M)).abs() < 1e-12);
    }
}
