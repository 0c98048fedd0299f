//! Paper 001's grid estimator as a head's fusion: one belief over the floor's cells per track,
//! predicted by a random walk and corrected each step by the product of the likelihoods of
//! everything the cluster sensed (eq. 12):
//!
//! - every camera of the cluster that processed a frame this step (it sends a `FrameReport`
//!   after each frame in grid mode): the detections the head associated with the track, or,
//!   if it had none for the track, its no-detection likelihood 1 − P_d (eq. 6); a camera that
//!   did not capture (CameraOff, Inactive, silent) says nothing;
//! - every acoustic node's ILD vector of the step, correlated with its fingerprints (eq. 16–18);
//! - the track's tag readings, each through its node's current RSSI model.
//!
//! The rest of the head (association, gating, births, merging, activation, reports) sees the
//! belief's mean and covariance as the track's Gaussian (at the method's target height, no
//! velocity); the report also carries the belief itself, down-sampled.

use super::{Fusion, StepSensors, Updated};
use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::eif::Eif;
use crate::grid::acoustic::{AcousticParams, AcousticSensor};
use crate::grid::optical::{self, OpticalOutcome, OpticalParams, OpticalSensor};
use crate::grid::{Belief, Grid, GridError, RandomWalk, report, rssi};
use crate::track::Track;
use nalgebra::{Matrix6, Vector3};
use proto::acoustic::IldVector;
use proto::models::State;
use proto::msg::GridPosterior;
use proto::{ClusterTime, Mode, TargetId};
use std::collections::HashMap;
use std::sync::Arc;
use tracing::warn;

/// Velocity standard deviation the track's Gaussian is given (the random walk has none), m/s.
const VELOCITY_SIGMA: f64 = 0.5;
/// Height standard deviation of the track's Gaussian, m.
const HEIGHT_SIGMA: f64 = 0.1;

/// One track's belief and what the step associated with it.
#[derive(Clone, Debug)]
struct TrackGrid {
    belief: Belief,
    /// Time of the belief.
    time: ClusterTime,
    /// `(camera slot, detection)` of this step.
    detections: Vec<(usize, optical::Detection)>,
}

/// The grid estimator of one head.
#[derive(Debug)]
pub struct GridFusion {
    grid: Arc<Grid>,
    motion: RandomWalk,
    /// Per camera slot (the head's node table).
    optical: Vec<OpticalSensor>,
    /// Per camera slot: where its radio is.
    radios: Vec<Vector3<f64>>,
    /// Per acoustic slot; `None` without fingerprints.
    acoustic: Vec<Option<AcousticSensor>>,
    target_z: f64,
    report_side: u16,
    tracks: HashMap<TargetId, TrackGrid>,
    looked: Vec<bool>,
    modes: Vec<Mode>,
    ilds: Vec<(usize, IldVector)>,
    likelihood: Vec<f64>,
    refused: u64,
}

impl GridFusion {
    /// The grid over the head's world and each sensor's precomputed view of it.
    ///
    /// # Errors
    /// A grid that cannot be built, or parameters out of range.
    pub fn new(cfg: &HeadConfig) -> Result<GridFusion, GridError> {
        let g = &cfg.method.grid;
        let world = cfg.world();
        let grid = Arc::new(Grid::new(&world, g.cell_m)?);
        let params = OpticalParams {
            detection_probability: g.detection_probability,
            max_range_m: g.max_range_m,
            target_height_m: cfg.target_plane_z,
            clutter: g.clutter,
        };
        let optical = cfg
            .nodes
            .iter()
            .map(|n| OpticalSensor::new(n.id.0, &n.camera, &grid, &world, &params))
            .collect::<Result<Vec<_>, _>>()?;
        let acoustic_params = AcousticParams {
            sharpness: g.acoustic_sharpness,
            ..AcousticParams::default()
        };
        let acoustic = cfg
            .acoustic
            .iter()
            .map(|a| {
                a.fingerprints
                    .clone()
                    .map(|db| AcousticSensor::new(&grid, db, acoustic_params))
                    .transpose()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(GridFusion {
            likelihood: vec![1.0; grid.len()],
            motion: RandomWalk {
                sigma_per_sqrt_s: g.diffusion,
            },
            optical,
            radios: cfg.nodes.iter().map(|n| n.position).collect(),
            acoustic,
            target_z: cfg.target_plane_z,
            report_side: g.report_side,
            tracks: HashMap::new(),
            looked: vec![false; cfg.nodes.len()],
            modes: vec![Mode::Active; cfg.nodes.len()],
            ilds: Vec::new(),
            grid,
            refused: 0,
        })
    }

    /// The belief of a track, if it has one yet.
    pub fn belief(&self, track: TargetId) -> Option<&Belief> {
        self.tracks.get(&track).map(|t| &t.belief)
    }

    fn entry(&mut self, track: &Track) -> &mut TrackGrid {
        let grid = &self.grid;
        self.tracks.entry(track.local).or_insert_with(|| {
            let p = track.position();
            let c = track.filter.cov();
            let sigma = c[(0, 0)].max(c[(1, 1)]).max(0.0).sqrt().clamp(grid.cell(), 2.0);
            TrackGrid {
                belief: Belief::gaussian(grid.clone(), [p.x, p.y], sigma),
                time: track.time,
                detections: Vec::new(),
            }
        })
    }

    fn refuse(&mut self, what: &'static str, e: &GridError) {
        self.refused += 1;
        warn!(what, error = %e, "observation refused by the grid estimator");
    }

    /// The step's joint likelihood for `track` into `self.likelihood`; whether anything was
    /// fused.
    fn joint_likelihood(&mut self, track: &Track, detections: &[(usize, optical::Detection)]) -> bool {
        let mut likelihood = std::mem::take(&mut self.likelihood);
        likelihood.fill(1.0);
        let mut informed = false;
        let mut mine = Vec::new();
        for (slot, sensor) in self.optical.iter().enumerate() {
            if !self.looked[slot] {
                continue;
            }
            mine.clear();
            mine.extend(detections.iter().filter(|(s, _)| *s == slot).map(|(_, d)| *d));
            match sensor.apply(self.modes[slot], &mine, &mut likelihood) {
                Ok(OpticalOutcome::Silent) => {}
                Ok(_) => informed = true,
                Err(e) => {
                    self.refused += 1;
                    warn!(error = %e, "camera observation refused by the grid estimator");
                }
            }
        }
        for (slot, ild) in &self.ilds {
            match self.acoustic.get(*slot).and_then(Option::as_ref) {
                Some(sensor) => match sensor.apply(ild, &mut likelihood) {
                    Ok(()) => informed = true,
                    Err(e) => {
                        self.refused += 1;
                        warn!(error = %e, "acoustic observation refused by the grid estimator");
                    }
                },
                None => self.refused += 1,
            }
        }
        for &(slot, dbm, _) in &track.rssi {
            let model = track.rssi_noise.weighed(&track.trainers[slot].model());
            match rssi::apply(
                &self.grid,
                &self.radios[slot],
                &model,
                dbm,
                self.target_z,
                &mut likelihood,
            ) {
                Ok(()) => informed = true,
                Err(e) => self.refuse("rssi", &e),
            }
        }
        self.likelihood = likelihood;
        informed
    }
}

impl Fusion for GridFusion {
    fn distributed(&self) -> bool {
        false
    }

    fn wants_frame_reports(&self) -> bool {
        true
    }

    fn fuses_acoustic(&self) -> bool {
        true
    }

    fn sensed(&mut self, sensors: &StepSensors<'_>) {
        self.looked.clear();
        self.looked.extend_from_slice(sensors.looked);
        self.looked.resize(self.optical.len(), false);
        self.modes.clear();
        self.modes.extend_from_slice(sensors.modes);
        self.modes.resize(self.optical.len(), Mode::Inactive);
        self.ilds.clear();
        self.ilds.extend_from_slice(sensors.ilds);
    }

    fn absorb(&mut self, track: &mut Track, det: &Detection, _: &NodeInfo, _: &HeadConfig) {
        // The grid's optical model takes pin-hole points; ground-plane people are not in it.
        if det.ground.is_some() {
            return;
        }
        let d = optical::Detection {
            point: [det.point.x, det.point.y],
            cov: [det.cov[(0, 0)], det.cov[(0, 1)], det.cov[(1, 1)]],
        };
        let slot = det.slot;
        self.entry(track).detections.push((slot, d));
    }

    fn update(&mut self, track: &mut Track, _: ClusterTime) -> Updated {
        let (time, detections) = {
            let e = self.entry(track);
            (e.time, std::mem::take(&mut e.detections))
        };
        let dt = track.time.secs_since(time).max(0.0);
        let informed = self.joint_likelihood(track, &detections);
        let motion = self.motion;
        let Some(e) = self.tracks.get_mut(&track.local) else {
            return Updated::default();
        };
        if let Err(err) = e.belief.predict(&motion, dt) {
            warn!(error = %err, "grid prediction refused");
        }
        e.time = track.time;
        if let Err(err) = e.belief.correct(&self.likelihood) {
            self.refused += 1;
            warn!(error = %err, "grid correction refused");
        }
        let est = e.belief.estimate();
        let mean = State::new(est.mean[0], est.mean[1], self.target_z, 0.0, 0.0, 0.0);
        let mut cov = Matrix6::identity() * VELOCITY_SIGMA.powi(2);
        for a in 0..2 {
            for b in 0..2 {
                cov[(a, b)] = est.covariance[a][b];
            }
        }
        cov[(2, 2)] = HEIGHT_SIGMA.powi(2);
        match Eif::from_gaussian(mean, cov) {
            Ok(f) => {
                track.filter = f;
                track.aux = track.filter.clone();
                Updated {
                    informed,
                    failure: None,
                }
            }
            Err(failure) => Updated {
                informed,
                failure: Some(failure),
            },
        }
    }

    fn posterior(&self, track: TargetId) -> Option<GridPosterior> {
        self.tracks
            .get(&track)
            .map(|t| report::posterior(&t.belief, self.report_side))
    }

    fn retain(&mut self, live: &[TargetId]) {
        self.tracks.retain(|id, _| live.contains(id));
    }

    fn refused(&self) -> u64 {
        self.refused
    }
}
