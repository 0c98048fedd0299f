//! Paper 001 §4.1 (Table 1, Fig. 10) in the simulated room: how well the acoustic observation
//! likelihood alone finds a sound source hidden behind one or two walls, as the nearer wall's
//! distance and the walls' length vary.
//!
//! Setup, scaled from the paper's 90 × 50 cm bench to a room (our band is the paper's real-room
//! 20–386 Hz, whose wavelengths are metres): an 8 × 5 m room, the two-microphone node at
//! (0.3, 2.5) facing +x, a "speaker array" of 9 × 6 = 54 fingerprint positions 0.3 m apart over
//! x ∈ [5.0, 7.4], y ∈ [1.75, 3.25] (the paper's 54 speakers), each rendered for 0.5 s by
//! `world::acoustics` and analysed as the node analyses its frames. A wall across the line of
//! sight, centred on y = 2.5, of length L_w, at L_d from the array's edge; with two walls the
//! second is fixed 0.3 m in front of the array and only the nearer one moves (as in the paper).
//! Test sources at seeded random positions in the array's area, off the lattice; for each the
//! likelihood (eq. 16–18) on a 5 cm grid over the array's area gives the nearest-peak error
//! (distance from the truth to the nearest local maximum above half the highest one) and the
//! differential entropy of the normalised likelihood.

use crate::Result;
use crate::error::OrFailed;
use node_acoustic::ild::IldAnalyzer;
use node_head::grid::acoustic::{AcousticParams as Likelihood, AcousticSensor};
use node_head::grid::belief::Belief;
use node_head::grid::layout::Grid;
use proto::acoustic::{Fingerprint, FingerprintDb};
use proto::scenario::{RadioWorld, Wall, World, low_band};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use world::acoustics::{AcousticParams, TwoMicNode, render_stereo};

/// The array's area, `[xmin, ymin, xmax, ymax]`, m (lattice at its corners).
const ARRAY: [f64; 4] = [5.0, 1.75, 7.4, 3.25];
const SPACING_M: f64 = 0.3;
const SURVEY_S: f64 = 0.5;
const TEST_S: f64 = 0.5;
const GRID_CELL_M: f64 = 0.05;
/// The nearer wall's distance from the array's edge, m (single wall; two walls use the last three).
pub const DISTANCES_M: [f64; 4] = [0.0, 0.5, 1.0, 1.5];
/// The walls' length, m.
pub const LENGTHS_M: [f64; 3] = [1.0, 2.0, 3.0];

/// One wall configuration's figures.
#[derive(Clone, Debug)]
pub struct Cell {
    pub walls: u32,
    pub distance_m: f64,
    pub length_m: f64,
    /// Nearest-peak error per test source, m.
    pub errors_m: Vec<f64>,
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
        // The second wall stays 0.3 m in front of the array; the distances swept with two
        // walls are all larger.
        w.push(wall_at(ARRAY[0] - 0.3, length));
    }
    World {
        min: [0.0, 0.0, 0.0],
        max: [8.0, 5.0, 3.0],
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
    let node = TwoMicNode::ears([0.3, 2.5, 1.2], 0.0, 0.2);
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
    let sensor = AcousticSensor::new(&grid, db, Likelihood::default()).or_failed("paper001")?;
    let mut cell = Cell {
        walls,
        distance_m: distance,
        length_m: length,
        errors_m: Vec::with_capacity(sources),
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
                bump(c, [5.5, 2.0]) + 0.8 * bump(c, [7.0, 3.0])
            })
            .collect();
        let e = nearest_peak_error(&grid, &map, [6.9, 3.0]);
        assert!(e < 0.15, "the second peak is the nearest: {e}");
    }

    /// One configuration end to end (render, survey, likelihood): finite errors inside the
    /// array's area and entropies no larger than a uniform density's over it.
    #[test]
    fn one_configuration_gives_bounded_errors_and_entropies() {
        let c = evaluate(1, 0.5, 1.0, 2, 7).unwrap();
        let diagonal = (ARRAY[2] - ARRAY[0]).hypot(ARRAY[3] - ARRAY[1]);
        let uniform = ((ARRAY[2] - ARRAY[0]) * (ARRAY[3] - ARRAY[1])).ln();
        assert_eq!(c.errors_m.len(), 2);
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
        let w = room(2, 1.0, 2.0).walls;
        assert_eq!(w.len(), 2);
        assert!(w[0].from[0] < w[1].from[0], "{w:?}");
        assert!((w[1].from[0] - (ARRAY[0] - 0.3)).abs() < 1e-12);
    }
}
