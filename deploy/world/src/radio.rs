//! The simulated radio world: RSSI of a target's tag at a node, as log-distance path loss plus
//! a smooth location-dependent multipath field, a constant per-node offset, wall attenuation and
//! per-reading noise
//! (`proto::scenario::RadioWorld`). The field differs per node and is fixed for a seed, so a
//! node that learns locally (paper 002 Algorithm 1) has real structure to learn, and the
//! paper's default `a log d + b` model is measurably worse. Pure functions of
//! (scenario, node, target position, t, seed).

use nalgebra::{Vector2, Vector3};
use proto::models::fit_log_distance;
use proto::scenario::{RadioWorld, Scenario, World};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Random Fourier components of the multipath field.
const COMPONENTS: usize = 48;

/// One node's multipath field over target floor positions: a stationary Gaussian field with
/// standard deviation `multipath_db` and correlation length `multipath_length_m`, drawn as a
/// sum of random cosines.
#[derive(Clone, Debug)]
pub struct MultipathField {
    waves: Vec<(Vector2<f64>, f64)>,
    amplitude: f64,
    /// The node's constant offset, dB.
    offset: f64,
}

impl MultipathField {
    pub fn new(radio: &RadioWorld, node: u32, seed: u64) -> MultipathField {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (0x5EED_0000_0000 | node as u64));
        let l = radio.multipath_length_m.max(1e-3);
        let k = Normal::new(0.0, 1.0 / l).expect("positive spread");
        let waves = (0..COMPONENTS)
            .map(|_| {
                let kv = Vector2::new(k.sample(&mut rng), k.sample(&mut rng));
                (kv, rng.random_range(0.0..std::f64::consts::TAU))
            })
            .collect();
        let offset = Normal::new(0.0, radio.node_offset_db.max(0.0))
            .map(|n| n.sample(&mut rng))
            .unwrap_or(0.0);
        MultipathField {
            waves,
            amplitude: radio.multipath_db * (2.0 / COMPONENTS as f64).sqrt(),
            offset,
        }
    }

    /// Field value at a floor position, including the node's offset, dB.
    pub fn at(&self, p: &Vector2<f64>) -> f64 {
        self.offset
            + self.amplitude
                * self
                    .waves
                    .iter()
                    .map(|(k, phi)| (k.dot(p) + phi).cos())
                    .sum::<f64>()
    }
}

/// Total attenuation of the walls the straight path crosses, dB.
pub fn wall_loss(world: &World, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    world
        .walls
        .iter()
        .filter(|w| w.crosses(a, b))
        .map(|w| w.attenuation_db)
        .sum()
}

/// The noiseless mean RSSI at `node` of a tag at `tag`, dBm.
pub fn mean_rssi(world: &World, field: &MultipathField, node: &Vector3<f64>, tag: &Vector3<f64>) -> f64 {
    let r = &world.radio;
    let d = (tag - node).norm().max(0.1);
    r.tx_power_dbm - 10.0 * r.path_loss_exponent * d.log10() + field.at(&Vector2::new(tag.x, tag.y))
        - wall_loss(world, node, tag)
}

/// One RSSI reading at `t` seconds: the mean plus seeded Gaussian noise (`noise_db`).
#[allow(clippy::too_many_arguments)]
pub fn reading(
    world: &World,
    field: &MultipathField,
    node_id: u32,
    node: &Vector3<f64>,
    target_id: u32,
    tag: &Vector3<f64>,
    t: f64,
    seed: u64,
) -> f64 {
    let tn = (t * 1e9).round() as i64 as u64;
    let mut rng = ChaCha8Rng::seed_from_u64(
        seed ^ tn.rotate_left(17) ^ ((node_id as u64) << 40) ^ ((target_id as u64) << 20),
    );
    let noise = Normal::new(0.0, world.radio.noise_db.max(0.0))
        .map(|n| n.sample(&mut rng))
        .unwrap_or(0.0);
    mean_rssi(world, field, node, tag) + noise
}

/// The scenario's RSSI nodes with their positions and their multipath fields for `seed`.
pub fn rssi_nodes(s: &Scenario, seed: u64) -> Vec<(u32, Vector3<f64>, MultipathField)> {
    s.cameras()
        .filter(|c| c.rssi)
        .filter_map(|c| {
            let pos = s.camera_model(c.id).ok()?.pose.centre();
            Some((c.id, pos, MultipathField::new(&s.world.radio, c.id, seed)))
        })
        .collect()
}

/// Readings each RSSI node takes of every other RSSI node's beacon (paper 002 §VI's survey
/// before tracking): `per_pair` readings per ordered pair, at 0.1 s intervals, as
/// (distance m, RSSI dBm). The beacon stands where the node is; the receiving node's multipath
/// field and offset, the walls and the noise apply as for a tag.
pub fn survey(s: &Scenario, seed: u64, per_pair: usize) -> Vec<(f64, f64)> {
    let nodes = rssi_nodes(s, seed);
    let mut out = Vec::new();
    for (rx, rx_pos, field) in &nodes {
        for (tx, tx_pos, _) in nodes.iter().filter(|n| n.0 != *rx) {
            for k in 0..per_pair {
                let t = k as f64 * 0.1;
                let dbm = reading(&s.world, field, *rx, rx_pos, *tx, tx_pos, t, seed);
                out.push(((tx_pos - rx_pos).norm(), dbm));
            }
        }
    }
    out
}

/// Readings per ordered node pair in [`surveyed`].
pub const SURVEY_READINGS_PER_PAIR: usize = 10;

/// `s` with its default RSSI model fitted to the survey of its simulated room when the scenario
/// asks for it (`method.rssi-survey`), otherwise unchanged. The result no longer asks: it
/// carries the model it was given, so a recording of it says what was used and a replay does not
/// survey again. Too few RSSI nodes to fit leave the scenario as it is.
pub fn surveyed(s: &Scenario, seed: u64) -> Scenario {
    let mut out = s.clone();
    if s.method.rssi_survey
        && let Some(m) = fit_log_distance(&survey(s, seed, SURVEY_READINGS_PER_PAIR))
    {
        out.method.rssi_default = m;
        out.method.rssi_survey = false;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::models::RssiModel;
    use proto::scenario::{Scenario, Wall};

    fn fit_linear(xs: &[f64], ys: &[f64]) -> (f64, f64) {
        let n = xs.len() as f64;
        let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
        let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
        let a = sxy / sxx;
        (a, my - a * mx)
    }

    /// Over windows of M = 20 consecutive readings of a moving tag (paper 002 Algorithm 1),
    /// a local linear fit `a d + b` predicts the next readings better than the default
    /// `a log d + b`: the multipath field is local structure worth learning.
    #[test]
    fn local_linear_model_beats_the_default_log_model() {
        // The default fitted to the room itself (paper 002's), not a literature one.
        let s = surveyed(&Scenario::default_scenario(), 42);
        let world = &s.world;
        let default = s.method.rssi_default;
        let all = crate::targets(&s).unwrap();
        let tg = &all[0];
        let (mut err_local, mut err_default, mut count) = (0.0, 0.0, 0);
        for node in s.cameras().take(8) {
            let pos = s.camera_model(node.id).unwrap().pose.centre();
            let field = MultipathField::new(&world.radio, node.id, 42);
            let samples: Vec<(f64, f64)> = (0..400)
                .map(|k| {
                    let t = k as f64 * 0.2;
                    let x = tg.truth_at(t);
                    let tag = Vector3::new(x[0], x[1], x[2]);
                    let r = reading(world, &field, node.id, &pos, tg.id, &tag, t, 42);
                    ((tag - pos).norm(), r)
                })
                .collect();
            for w in samples.windows(25).step_by(5) {
                let (train, test) = w.split_at(20);
                let xs: Vec<f64> = train.iter().map(|p| p.0).collect();
                let ys: Vec<f64> = train.iter().map(|p| p.1).collect();
                let (a, b) = fit_linear(&xs, &ys);
                let local = RssiModel::Linear { a, b, variance: 1.0 };
                for (d, r) in test {
                    err_local += (local.predict(*d) - r).powi(2);
                    err_default += (default.predict(*d) - r).powi(2);
                    count += 1;
                }
            }
        }
        let (rl, rd) = (
            (err_local / count as f64).sqrt(),
            (err_default / count as f64).sqrt(),
        );
        eprintln!("rms error: local linear {rl:.2} dB, default log {rd:.2} dB");
        assert!(rl < 0.7 * rd, "local {rl:.2} dB vs default {rd:.2} dB");
        assert!(
            rl > 1.0,
            "noise ({} dB) cannot be learned away: {rl:.2}",
            world.radio.noise_db
        );
    }

    /// The survey of the default room recovers the simulated law (the default model the paper
    /// fitted between nodes), with the field and noise as its variance, and only when asked.
    #[test]
    fn survey_fits_the_rooms_law_when_the_scenario_asks() {
        let mut s = Scenario::default_scenario();
        let r = s.world.radio.clone();
        let pairs = survey(&s, 3, 4);
        let n = s.cameras().filter(|c| c.rssi).count();
        assert_eq!(pairs.len(), n * (n - 1) * 4);
        s.method.rssi_survey = true;
        let done = surveyed(&s, 3);
        assert!(!done.method.rssi_survey, "a surveyed scenario does not ask again");
        assert_eq!(surveyed(&done, 4), done, "surveying twice changes nothing");
        let RssiModel::LogDistance { a, b, variance } = done.method.rssi_default else {
            panic!("the survey fits the log-distance form");
        };
        let (a0, b0) = (-10.0 * r.path_loss_exponent, r.tx_power_dbm);
        assert!(
            (a - a0).abs() < 4.0 && (b - b0).abs() < 4.0,
            "fit {a} log d + {b}"
        );
        let expected = r.multipath_db.powi(2) + r.noise_db.powi(2);
        assert!(
            variance > 0.5 * expected && variance < 2.0 * expected,
            "variance {variance} vs {expected}"
        );
        s.method.rssi_survey = false;
        assert_eq!(surveyed(&s, 3).method.rssi_default, s.method.rssi_default);
    }

    /// Each node's constant offset is drawn with the configured spread and is the same
    /// everywhere on the floor.
    #[test]
    fn node_offsets_have_the_configured_spread() {
        let radio = RadioWorld {
            multipath_db: 0.0,
            node_offset_db: 3.0,
            ..RadioWorld::default()
        };
        let offsets: Vec<f64> = (0..400)
            .map(|id| {
                let f = MultipathField::new(&radio, id, 5);
                assert_eq!(f.at(&Vector2::new(1.0, 2.0)), f.at(&Vector2::new(7.0, -3.0)));
                f.at(&Vector2::zeros())
            })
            .collect();
        let sd = (offsets.iter().map(|v| v * v).sum::<f64>() / offsets.len() as f64).sqrt();
        assert!((sd - 3.0).abs() < 0.5, "offset sd {sd}");
    }

    #[test]
    fn field_statistics_walls_and_determinism() {
        let s = Scenario::default_scenario();
        let mut world = s.world.clone();
        let f = MultipathField::new(&world.radio, 10, 1);
        let vals: Vec<f64> = (0..2000)
            .map(|k| f.at(&Vector2::new((k % 50) as f64 * 0.9, (k / 50) as f64 * 0.7)))
            .collect();
        let sd = (vals.iter().map(|v| v * v).sum::<f64>() / vals.len() as f64).sqrt();
        assert!((sd - world.radio.multipath_db).abs() < 2.0, "field sd {sd}");
        let node = Vector3::new(1.0, 1.0, 2.5);
        let tag = Vector3::new(6.0, 4.0, 0.25);
        let open = mean_rssi(&world, &f, &node, &tag);
        world.walls.push(Wall {
            from: [3.0, 0.0],
            to: [3.0, 8.0],
            height: 3.0,
            attenuation_db: 6.0,
        });
        let walled = mean_rssi(&world, &f, &node, &tag);
        assert!((open - walled - 6.0).abs() < 1e-9);
        let a = reading(&world, &f, 10, &node, 1, &tag, 2.0, 9);
        assert_eq!(a, reading(&world, &f, 10, &node, 1, &tag, 2.0, 9));
        assert_ne!(a, reading(&world, &f, 10, &node, 1, &tag, 2.2, 9));
    }
}
