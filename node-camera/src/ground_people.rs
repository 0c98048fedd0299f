//! The camera's paper 004 mode (`[method] camera-tracker = "particle"`): each frame's
//! foreground regions feed the per-person colour particle filters ([`crate::tracker`]), and
//! every person tracked leaves as a ground-plane [`GroundPoint`] — the mean state's position,
//! covariance from the sample spread through the ray geometry, width, height, the
//! maximum-likelihood state's floor position and confidence, and the colour histogram (sent
//! with a person's first observation and then at most once per [`HISTOGRAM_PERIOD_NS`], to keep
//! the bytes per person small). Centralized fusion gets them in `Measurement`s; distributed
//! fusion folds the one gated to a prior into the `Contribution` with
//! [`models::ground_contribution_aged`]. On a [`SampleRequest`] the camera answers with the
//! filters' sample sets.
//!
//! The measurement-level simulation has no frames: its projected boxes are converted to the
//! ground plane directly ([`GroundPeople::from_boxes`]), with no spread and no histogram.

use crate::tracker::ground::{self, GroundObservation};
use crate::tracker::histogram::{BINS, ColourHistogram, KernelCounts};
use crate::tracker::manager::{Foreground, MultiTracker, PersonEstimate, TrackerError, TrackerInput};
use crate::tracker::params::{ParamsError, ParticleParams};
use nalgebra::{Matrix2, Vector2};
use proto::camera::CameraModel;
use proto::models::{self, State};
use proto::msg::{Contribution, ImageSample, MAX_SAMPLES, Measurement, Mode, Prior, SampleSet};
use proto::observation::{GroundPoint, Observation, ObservationKind, RssiReading};
use proto::sensor::{Detection, Frame};
use proto::{ClusterTime, TargetId};
use std::collections::BTreeMap;

/// Added to each axis of a ground position's variance, m²: the lower corners' rays meet the
/// floor at the person's near edge, the centre is up to half a body's depth behind it, and the
/// filter's mean box trails a moving person (model error the sample spread does not show).
pub const GROUND_POSITION_FLOOR_M2: f64 = 0.25 * 0.25;

/// A person's histogram goes out again after this long, ns.
pub const HISTOGRAM_PERIOD_NS: i64 = 1_000_000_000;

/// The particle filters and the newest frame's people on the ground.
#[derive(Debug)]
pub struct GroundPeople {
    tracker: MultiTracker,
    corner_sigma_px: f64,
    people: Vec<GroundPoint>,
    captured: Option<ClusterTime>,
    /// When each person's histogram last went out.
    histogram_sent: BTreeMap<u32, ClusterTime>,
}

impl GroundPeople {
    /// Filters with `params`, their randomness seeded with `seed`.
    ///
    /// # Errors
    /// A parameter out of range.
    pub fn new(params: &ParticleParams, seed: u64) -> Result<GroundPeople, ParamsError> {
        Ok(GroundPeople {
            tracker: MultiTracker::new(params.clone(), seed)?,
            corner_sigma_px: params.corner_sigma_px,
            people: Vec::new(),
            captured: None,
            histogram_sent: BTreeMap::new(),
        })
    }

    pub fn tracker(&self) -> &MultiTracker {
        &self.tracker
    }

    /// The newest frame's people.
    pub fn latest(&self) -> &[GroundPoint] {
        &self.people
    }

    /// Forget the people (the camera went off): the next frame starts afresh.
    pub fn clear(&mut self) {
        self.people.clear();
        self.captured = None;
    }

    /// Track one frame with its foreground `regions` (and the background model's mask) and
    /// convert each person to the ground plane; people whose box is above the horizon are
    /// dropped.
    ///
    /// # Errors
    /// The tracker refused the frame or a region; nothing changes then.
    pub fn track(
        &mut self,
        camera: &CameraModel,
        frame: &Frame,
        regions: &[Detection],
        foreground: Option<Foreground<'_>>,
    ) -> Result<&[GroundPoint], TrackerError> {
        let estimates = self.tracker.step(&TrackerInput {
            frame,
            regions,
            foreground,
            with_samples: false,
        })?;
        let captured = frame.captured;
        self.people.clear();
        for person in &estimates {
            if let Some(obs) = ground::observe(camera, person, 1.0, self.corner_sigma_px, captured) {
                let ml = ml_position(camera, person).unwrap_or(obs.position);
                let g = self.ground_point(person.id, person.ml_confidence, obs, ml);
                self.people.push(g);
            }
        }
        let live = self.tracker.ids();
        self.histogram_sent.retain(|id, _| live.contains(id));
        self.captured = Some(captured);
        Ok(&self.people)
    }

    /// The measurement-level simulation's projected boxes as ground points (no sample spread:
    /// the corner floor alone; no histogram; confidence 1). `local` is the detection's index.
    pub fn from_boxes(&mut self, camera: &CameraModel, detections: &[Detection], captured: ClusterTime) {
        self.people.clear();
        let spread = [[0.0; 4]; 4];
        let counts = KernelCounts {
            bins: [0.0; BINS],
            total: 1.0,
        };
        let Some(empty) = ColourHistogram::from_counts(&counts) else {
            return;
        };
        for (i, d) in detections.iter().enumerate() {
            let hist = empty.clone();
            if let Some(obs) =
                ground::to_ground(camera, &d.bbox, &spread, self.corner_sigma_px, captured, hist)
            {
                let position = obs.position;
                let mut g = to_point(i as u32, 1.0, obs, position);
                g.histogram.clear();
                self.people.push(g);
            }
        }
        self.captured = Some(captured);
    }

    fn ground_point(
        &mut self,
        local: u32,
        confidence: f32,
        obs: GroundObservation,
        ml: [f64; 2],
    ) -> GroundPoint {
        let captured = obs.captured;
        let mut g = to_point(local, confidence, obs, ml);
        let due = self
            .histogram_sent
            .get(&local)
            .is_none_or(|&t| (captured - t).abs() >= HISTOGRAM_PERIOD_NS);
        if due {
            self.histogram_sent.insert(local, captured);
        } else {
            g.histogram.clear();
        }
        g
    }

    /// The sample sets of the newest frame: of person `local`, or of everyone. A filter with
    /// more than [`MAX_SAMPLES`] samples sends its heaviest.
    pub fn samples(&self, local: Option<u32>) -> Vec<SampleSet> {
        let Some(captured) = self.captured else {
            return Vec::new();
        };
        self.tracker
            .ids()
            .into_iter()
            .filter(|id| local.is_none_or(|l| l == *id))
            .filter_map(|id| {
                let f = self.tracker.filter(id)?;
                let mut samples: Vec<ImageSample> = f
                    .samples()
                    .map(|s| ImageSample {
                        state: s.state.to_array(),
                        weight: s.weight,
                    })
                    .collect();
                if samples.len() > MAX_SAMPLES {
                    samples.sort_by(|a, b| b.weight.total_cmp(&a.weight));
                    samples.truncate(MAX_SAMPLES);
                }
                Some(SampleSet {
                    local: id,
                    captured,
                    samples,
                })
            })
            .collect()
    }
}

fn to_point(local: u32, confidence: f32, obs: GroundObservation, ml: [f64; 2]) -> GroundPoint {
    let c = obs.cov;
    GroundPoint {
        local,
        position: obs.position,
        cov: [
            c[0] + GROUND_POSITION_FLOOR_M2,
            c[1],
            c[2] + GROUND_POSITION_FLOOR_M2,
        ],
        width_m: obs.width_m as f32,
        height_m: obs.height_m as f32,
        confidence: confidence.clamp(0.0, 1.0),
        histogram: obs.histogram.bins().to_vec(),
        captured: obs.captured,
        ml_position: [ml[0] as f32, ml[1] as f32],
    }
}

/// Where the maximum-likelihood state's box stands on the floor (its bottom centre).
fn ml_position(camera: &CameraModel, person: &PersonEstimate) -> Option<[f64; 2]> {
    let b = person.ml.bbox();
    let p = ground::ground_point(camera, [0.5 * (b.xmin + b.xmax) as f64, b.ymax as f64])?;
    Some([p.x, p.y])
}

fn position_and_cov(g: &GroundPoint) -> (Vector2<f64>, Matrix2<f64>) {
    (
        Vector2::from(g.position),
        Matrix2::new(g.cov[0], g.cov[1], g.cov[1], g.cov[2]),
    )
}

/// [`models::ground_gate_distance2`] of a ground point seen `age_s` seconds before the prior's
/// time (negative: after).
pub fn gate_distance2(prior: &Prior, g: &GroundPoint, age_s: f64) -> Option<f64> {
    let mean = models::vec6_from_wire(&prior.mean);
    let cov = models::mat6_from_wire(&prior.cov);
    let (p, c) = position_and_cov(g);
    models::ground_gate_distance2(&mean, &cov, &p, &c, age_s)
}

/// Assign ground points to priors, nearest pairs first, one to one, within `gate_chi2` (each
/// prior with the points' age relative to it, s). Returns, per point, its prior's index.
pub fn associate(priors: &[(&Prior, f64)], people: &[GroundPoint], gate_chi2: f64) -> Vec<Option<usize>> {
    crate::measure::nearest_pairs(priors, people, gate_chi2, gate_distance2)
}

/// The nearest ground point within the gate of one prior.
pub fn nearest<'a>(
    prior: &Prior,
    people: &'a [GroundPoint],
    age_s: f64,
    gate_chi2: f64,
) -> Option<&'a GroundPoint> {
    people
        .iter()
        .filter_map(|g| gate_distance2(prior, g, age_s).map(|d2| (d2, g)))
        .filter(|(d2, _)| *d2 <= gate_chi2)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, g)| g)
}

/// The contribution Ω_i, ξ_i of one ground point at the prior's mean — its floor position and
/// the centre height its measured height gives (all zero, nothing folded,
/// when there is none or it cannot be linearized); tag readings go along raw.
pub fn contribution(
    prior: &Prior,
    person: Option<&GroundPoint>,
    captured: ClusterTime,
    age_s: f64,
    mode: Mode,
    rssi: &[RssiReading],
) -> Contribution {
    let mean: State = models::vec6_from_wire(&prior.mean);
    let info = person.and_then(|g| {
        let (p, c) = position_and_cov(g);
        let (mut omega, mut xi) = models::ground_contribution_aged(&p, &c, &mean, age_s)?;
        if let Some((o, x)) = models::ground_height_contribution(f64::from(g.height_m), &mean) {
            omega += o;
            xi += x;
        }
        Some((omega, xi))
    });
    crate::measure::folded_contribution(prior, info, ObservationKind::Ground, captured, mode, rssi)
}

/// A measurement carrying one ground point (and the tag readings of its frame).
pub fn measurement(
    camera: &CameraModel,
    person: GroundPoint,
    target: Option<(TargetId, u64)>,
    mode: Mode,
    rssi: &[RssiReading],
) -> Measurement {
    Measurement {
        target: target.map(|t| t.0),
        step: target.map_or(0, |t| t.1),
        pose: camera.pose.to_wire(),
        mode,
        observations: std::iter::once(Observation::Ground(person))
            .chain(rssi.iter().copied().map(Observation::Rssi))
            .collect(),
    }
}

#[cfg(test)]
mod tests;
