//! The grid estimator on the acoustic likelihood alone (`ocelli acoustic locate`): a random
//! walk predicted between frames, each frame's ILD vector as the correction, one fix per frame.
//!
//! The acoustic node's crate turns a WAV file into timed ILD vectors; this runs on those, so
//! the estimator exists once, here at the head, and no node crate depends on another. Its
//! default likelihood is sharpened (see [`LocateParams::default`]); fusion at the head keeps
//! the paper's.

use super::GridError;
use super::acoustic::{AcousticParams, AcousticSensor};
use super::belief::{Belief, Correction, RandomWalk};
use super::layout::Grid;
use proto::acoustic::{FingerprintDb, IldVector};
use proto::scenario::{RadioWorld, World};
use serde::Serialize;
use std::sync::Arc;

/// How `locate` runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocateParams {
    /// Grid cell, m.
    pub cell_m: f64,
    pub motion: RandomWalk,
    pub acoustic: AcousticParams,
}

impl Default for LocateParams {
    /// 10 cm cells, a 0.5 m/√s walk, and the acoustic likelihood sharpened to X^20. Alone,
    /// without the optical prior the paper fuses it with, the paper's X (a correlation that
    /// rarely leaves [0.5, 1]) hardly narrows the belief: in the simulated room (0.25 m survey,
    /// 10 s of half-second frames) a still source was 0.5 m off with σ 1 m at X¹, about 0.13 m
    /// off with σ 0.15 m at X¹⁰–X³⁰. The exponent counts each frame as that many looks.
    fn default() -> Self {
        LocateParams {
            cell_m: 0.1,
            motion: RandomWalk {
                sigma_per_sqrt_s: 0.5,
            },
            acoustic: AcousticParams {
                sharpness: 20.0,
                ..AcousticParams::default()
            },
        }
    }
}

/// One frame's estimate: `{"t", "x", "y", "sigma_m"}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Fix {
    /// Seconds from the start of the recording.
    pub t: f64,
    /// The belief's mean, m.
    pub x: f64,
    pub y: f64,
    /// √(trace Σ), m.
    pub sigma_m: f64,
    /// Whether the frame corrected the belief (false: skipped, prediction only).
    #[serde(skip)]
    pub corrected: bool,
    #[serde(skip)]
    pub correction: Option<Correction>,
}

/// The world `locate` uses without a scenario: the survey's region, no walls.
pub fn survey_world(db: &FingerprintDb) -> World {
    let [x0, y0, x1, y1] = db.region();
    World {
        min: [x0, y0, 0.0],
        max: [x1, y1, 3.0],
        walls: Vec::new(),
        radio: RadioWorld::default(),
        geo: None,
    }
}

/// The running estimator.
#[derive(Clone, Debug)]
pub struct Locator {
    belief: Belief,
    sensor: AcousticSensor,
    motion: RandomWalk,
    last_t: Option<f64>,
    likelihood: Vec<f64>,
}

impl Locator {
    /// Start uniform over `world`'s free cells.
    ///
    /// # Errors
    /// A grid that cannot be built, or invalid parameters.
    pub fn new(world: &World, db: FingerprintDb, params: &LocateParams) -> Result<Self, GridError> {
        let grid = Arc::new(Grid::new(world, params.cell_m)?);
        let sensor = AcousticSensor::new(&grid, db, params.acoustic)?;
        Ok(Locator {
            likelihood: vec![1.0; grid.len()],
            belief: Belief::uniform(grid),
            sensor,
            motion: params.motion,
            last_t: None,
        })
    }

    pub fn belief(&self) -> &Belief {
        &self.belief
    }

    /// Predict to `t` and correct with the frame's ILD vector (`None`: a frame that was
    /// skipped — silent or clipped — predicts only).
    ///
    /// # Errors
    /// A time before the previous frame's or not finite, or an ILD vector the fingerprints
    /// cannot read; the estimator is unchanged.
    pub fn step(&mut self, t: f64, ild: Option<&IldVector>) -> Result<Fix, GridError> {
        let dt = match self.last_t {
            _ if !t.is_finite() => return Err(GridError::Invalid(format!("frame time {t} s"))),
            Some(last) if t < last => {
                return Err(GridError::Invalid(format!("frame time {t} s is before {last} s")));
            }
            Some(last) => t - last,
            None => 0.0,
        };
        let correction = match ild {
            Some(ild) => {
                self.likelihood.fill(1.0);
                self.sensor.apply(ild, &mut self.likelihood)?;
                self.belief.predict(&self.motion, dt)?;
                Some(self.belief.correct(&self.likelihood)?)
            }
            None => {
                self.belief.predict(&self.motion, dt)?;
                None
            }
        };
        self.last_t = Some(t);
        let e = self.belief.estimate();
        Ok(Fix {
            t,
            x: e.mean[0],
            y: e.mean[1],
            sigma_m: e.sigma_m(),
            corrected: correction.is_some(),
            correction,
        })
    }
}

/// Run a whole recording's frames `(t, ILD or None)`.
///
/// # Errors
/// As [`Locator::new`] and [`Locator::step`].
pub fn locate(
    world: &World,
    db: FingerprintDb,
    frames: impl IntoIterator<Item = (f64, Option<IldVector>)>,
    params: &LocateParams,
) -> Result<Vec<Fix>, GridError> {
    let mut locator = Locator::new(world, db, params)?;
    frames
        .into_iter()
        .map(|(t, ild)| locator.step(t, ild.as_ref()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::acoustic::{Fingerprint, IldSettings};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// An analytic ILD field: each frequency a plane wave across the room with its own
    /// direction and wavelength, so every position has its own vector.
    fn analytic_ild(freqs: usize, x: f64, y: f64) -> Vec<f64> {
        (0..freqs)
            .map(|j| {
                let a = j as f64 * 2.399; // golden angle: directions spread evenly
                let k = 1.5 + 0.15 * j as f64;
                3.0 * (k * (a.cos() * x + a.sin() * y) + 0.7 * j as f64).sin()
            })
            .collect()
    }

    /// A source between the survey's knots is found within two cells from ILDs with noise.
    #[test]
    fn locate_recovers_a_source_from_analytic_fingerprints() {
        let world: World = toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [4.0, 3.0, 2.5]").unwrap();
        let settings = IldSettings {
            f_min_hz: 200.0,
            f_max_hz: 4000.0,
            frequencies: 24,
            ..IldSettings::default()
        };
        let n = settings.frequencies;
        let mut fps = Vec::new();
        for j in 0..7 {
            for i in 0..9 {
                let (x, y) = (0.25 + 0.45 * i as f64, 0.2 + 0.45 * j as f64);
                fps.push(Fingerprint {
                    position: [x, y],
                    values: analytic_ild(n, x, y),
                });
            }
        }
        let db = FingerprintDb::new(&world, settings, fps).unwrap();
        let freqs = db.frequencies().to_vec();
        let truth = [1.63, 2.07];
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let noise = Normal::new(0.0, 0.3).unwrap();
        let frames = (0..24).map(|f| {
            let t = 0.25 * f as f64;
            // Every fourth frame silent (skipped).
            let ild = (f % 4 != 3).then(|| {
                let v = analytic_ild(n, truth[0], truth[1])
                    .into_iter()
                    .map(|v| v + noise.sample(&mut rng))
                    .collect();
                IldVector::new(freqs.clone(), v).unwrap()
            });
            (t, ild)
        });
        let frames: Vec<_> = frames.collect();
        let fixes = locate(&world, db.clone(), frames.clone(), &LocateParams::default()).unwrap();
        assert_eq!(fixes.len(), 24);
        assert!(!fixes[3].corrected && fixes[4].corrected);
        let last = fixes.last().unwrap();
        let err = ((last.x - truth[0]).powi(2) + (last.y - truth[1]).powi(2)).sqrt();
        assert!(err <= 0.2, "fix {last:?} is {err} m from the source");
        assert!(last.sigma_m < 0.5, "{last:?}");
        // The paper's own likelihood (X¹) is weak per frame: the belief narrows only as frames
        // accumulate.
        let paper = LocateParams {
            acoustic: AcousticParams::default(),
            ..LocateParams::default()
        };
        let fixes = locate(&world, db.clone(), frames.clone(), &paper).unwrap();
        assert!(
            fixes[22].sigma_m < 0.8 * fixes[0].sigma_m,
            "{:?} vs {:?}",
            fixes[22],
            fixes[0]
        );
        assert!((last.t - 5.75).abs() < 1e-12);
    }

    #[test]
    fn frames_out_of_order_are_refused() {
        let world: World = toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [2.0, 2.0, 2.5]").unwrap();
        let settings = IldSettings {
            frequencies: 2,
            ..IldSettings::default()
        };
        let fps = vec![Fingerprint {
            position: [1.0, 1.0],
            values: vec![1.0, 0.0],
        }];
        let db = FingerprintDb::new(&world, settings, fps).unwrap();
        let mut l = Locator::new(&survey_world(&db), db, &LocateParams::default()).unwrap();
        l.step(1.0, None).unwrap();
        let e = l.step(0.5, None).unwrap_err();
        assert!(e.to_string().contains("before"), "{e}");
        assert!(l.step(f64::NAN, None).is_err());
    }
}
