//! The camera's paper 004 mode (`[method] camera-tracker = "particle"`): each frame's
//! foreground regions feed the per-person colour particle filters ([`crate::tracker`]), and
//! every person tracked becomes a ground-plane [`GroundPoint`] — the mean state's position
//! (its box's lower edge where the frame's foreground puts it, [`crate::tracker::feet`]),
//! covariance from the sample spread through the ray geometry, width, height, the
//! maximum-likelihood state's floor position (its own box's) and confidence, and the colour
//! histogram.
//! Distributed fusion answers a prior with the one gated to it, quantised, in its
//! `Contribution` (the head folds it in, [`contribution`]); the others (all of them, in
//! centralized fusion) leave in one [`PeopleFrame`] per head step ([`PeopleSender`]): each
//! person quantised ([`GroundPerson`]), its histogram only when new, changed or due for a
//! refresh. A filter that lost its region at a border it was moving towards, or with a
//! quarter of its box outside the frame (its person walked out), is not reported until a
//! region supports it again, nor, with `report-unsupported = false` (the crowd and the hall),
//! any filter no region supports this frame, nor a person whose feet someone in front hides
//! (their lowest foreground is the other's feet, [`feet::anothers_feet`]). On a
//! [`proto::msg::SampleRequest`] the camera answers with every filter's sample set, reported
//! or not. With `hold-still-s`, the people standing still are kept out of the background
//! model ([`standing`]).
//!
//! The measurement-level simulation has no frames: its projected boxes are converted to the
//! ground plane directly ([`GroundPeople::from_boxes`]), with no spread and no histogram.

use crate::tracker::ground::{self, GroundObservation};
use crate::tracker::histogram::{BINS, ColourHistogram, KernelCounts};
use crate::tracker::manager::{
    Foreground, MultiTracker, PersonEstimate, TrackerCounters, TrackerError, TrackerInput,
};
use crate::tracker::params::{ParamsError, ParticleParams};
use crate::tracker::{boxes, feet};
use nalgebra::{Matrix2, Vector2};
use proto::camera::CameraModel;
use proto::models;
use proto::msg::{Contribution, ImageSample, MAX_SAMPLES, Mode, PeopleFrame, PixelBox, Prior, SampleSet};
use proto::observation::{
    GroundPerson, GroundPoint, HISTOGRAM_BINS, HISTOGRAM_HS_BINS, Kinds, RssiReading, dequantise_histogram,
};
use proto::sensor::{Detection, Frame};
use proto::{ClusterTime, TargetId};
use std::collections::{BTreeMap, BTreeSet};

pub mod standing;
pub mod track_colours;

/// Added to each axis of a ground position's variance, m²: the lower corners' rays meet the
/// floor at the person's near edge, the centre is up to half a body's depth behind it, and the
/// filter's mean box trails a moving person (model error the sample spread does not show).
pub const GROUND_POSITION_FLOOR_M2: f64 = 0.25 * 0.25;

// The tracker's histogram layout is the wire's.
const _: () = assert!(BINS == HISTOGRAM_BINS && crate::tracker::histogram::HS_BINS == HISTOGRAM_HS_BINS);

/// The particle filters and the newest frame's people on the ground.
#[derive(Debug)]
pub struct GroundPeople {
    tracker: MultiTracker,
    corner_sigma_px: f64,
    /// `ParticleParams::report_unsupported`.
    report_unsupported: bool,
    people: Vec<GroundPoint>,
    captured: Option<ClusterTime>,
    /// Who stands still, to be kept out of the background (`hold-still-s`).
    standing: standing::Standing,
    /// The filters whose person walked out of view ([`walked_out_of_view`]) and that no
    /// region has supported since: unreported until one does. Without it, a filter whose box
    /// diffused back inside the frame, or whose velocity decayed, would come back as a person
    /// who is not there for the rest of its `destroy-s`.
    walked_out: BTreeSet<u32>,
    /// The reports left out since the start, by why.
    withheld: Withheld,
}

/// Frames' reports the camera left out since the start, per person and frame, by why.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Withheld {
    /// The filter's person walked out of view and no region has supported it since
    /// ([`walked_out_of_view`]).
    pub walked_out: u64,
    /// No region supported the filter this frame (`report-unsupported = false`), and it had
    /// not walked out.
    pub unsupported: u64,
    /// Someone in front hid the person's feet ([`feet::anothers_feet`]).
    pub hidden_feet: u64,
    /// The box could not be put on the floor: a lower corner's ray (or a half-pixel
    /// neighbour's) misses it, above the horizon; a corner cannot be undistorted; the camera
    /// is not above the floor; or the height could not be found.
    pub off_the_floor: u64,
}

/// What a camera's particle filters did since the start: the tracker's filters, and the
/// reports left out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ParticleCounters {
    /// Filters started, destroyed, eliminated as duplicates; births refused.
    pub tracker: TrackerCounters,
    /// Reports left out, by why.
    pub withheld: Withheld,
}

impl GroundPeople {
    /// Filters with `params` for a camera at `fps`, their randomness seeded with `seed`.
    ///
    /// # Errors
    /// A parameter out of range.
    pub fn new(params: &ParticleParams, fps: f64, seed: u64) -> Result<GroundPeople, ParamsError> {
        Ok(GroundPeople {
            tracker: MultiTracker::new(params.clone(), fps, seed)?,
            corner_sigma_px: params.corner_sigma_px,
            report_unsupported: params.report_unsupported,
            people: Vec::new(),
            captured: None,
            standing: standing::Standing::new(params.hold_still_s),
            walked_out: BTreeSet::new(),
            withheld: Withheld::default(),
        })
    }

    pub fn tracker(&self) -> &MultiTracker {
        &self.tracker
    }

    /// The tracker's counters and the reports left out since the start, by why.
    pub fn counters(&self) -> ParticleCounters {
        ParticleCounters {
            tracker: self.tracker.counters(),
            withheld: self.withheld,
        }
    }

    /// The newest frame's people.
    pub fn latest(&self) -> &[GroundPoint] {
        &self.people
    }

    /// Forget the people (the camera went off): the next frame starts afresh.
    pub fn clear(&mut self) {
        self.people.clear();
        self.captured = None;
        self.standing.clear();
        // `walked_out` stays: the filters it names live on in the tracker.
    }

    /// The standing people the background model is to keep out of the background at the next
    /// frame ([`standing`]; none with `hold-still-s = 0`, the default).
    pub fn held(&self) -> &[crate::adaptive_background::Hold] {
        self.standing.held()
    }

    /// Track one frame with its foreground `regions` (and the background model's mask) and
    /// convert each person to the ground plane; people whose box is above the horizon, who
    /// walked out of view, whose feet someone in front hides, or (without
    /// `report-unsupported`) whom no region supports this frame are not reported.
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
        self.standing.update(&estimates, captured);
        self.walked_out
            .retain(|id| estimates.iter().any(|p| p.id == *id && p.unsupported_frames > 0));
        let edges = feet::lower_edges(&estimates, regions, foreground.as_ref());
        for (i, (person, edge)) in estimates.iter().zip(edges).enumerate() {
            if walked_out_of_view(person, frame) {
                self.walked_out.insert(person.id);
            }
            if self.walked_out.contains(&person.id) {
                self.withheld.walked_out += 1;
                continue;
            }
            if !self.report_unsupported && person.unsupported_frames > 0 {
                self.withheld.unsupported += 1;
                continue;
            }
            // Hidden from the knees down by someone in front: this frame does not measure
            // where they stand, and their feet would be the other's (`feet::anothers_feet`).
            if edge.is_some_and(|e| feet::anothers_feet(&estimates, i, e)) {
                self.withheld.hidden_feet += 1;
                continue;
            }
            match ground::observe(camera, person, edge, 1.0, self.corner_sigma_px, captured) {
                Some(obs) => {
                    let ml = ml_position(camera, person).unwrap_or(obs.position);
                    self.people
                        .push(to_point(person.id, person.ml_confidence, obs, ml));
                }
                None => self.withheld.off_the_floor += 1,
            }
        }
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
        width_m: obs.width_m,
        height_m: obs.height_m,
        confidence: f64::from(confidence.clamp(0.0, 1.0)),
        histogram: obs.histogram.bins().to_vec(),
        captured: obs.captured,
        ml_position: ml,
    }
}

/// Within this many pixels of the frame's border a box touches it.
const BORDER_PX: f32 = 1.0;
/// Slowest speed towards a border, pixels per frame, that counts as walking out through it.
const OUTWARD_PX_PER_FRAME: f32 = 0.25;

/// Share of a box outside the frame from which a filter that lost its region counts as walked
/// out whatever its velocity: its person was stepping out through a border (the filter's
/// velocity is often near zero there, its box held by the shrinking part still in view). At
/// the top border too: someone near the camera, hidden or faded, with a quarter of their box
/// above the image is no longer reported (nothing measures them there either).
const OUTSIDE_SHARE: f32 = 0.25;

/// A filter that lost its region with its box at a border it was moving towards, or with a
/// quarter or more of its box outside the frame ([`OUTSIDE_SHARE`]): its person walked out of
/// view. The filter lives on for `destroy-s` (they may step back in), but nothing measures where it
/// stands any more, and reported it would be a person at the border who is not there: it
/// stays unreported until a region supports it again ([`GroundPeople::track`]). A filter that
/// lost its region inside the frame (a person hidden), or at a border it was not moving
/// towards and not past (someone standing at the edge of the view, faded into the
/// background), is still reported with `report-unsupported` (the default).
fn walked_out_of_view(person: &PersonEstimate, frame: &Frame) -> bool {
    let m = &person.mean;
    let b = m.bbox();
    let (w, h) = (frame.width as f32, frame.height as f32);
    let v = OUTWARD_PX_PER_FRAME;
    let whole = PixelBox {
        xmin: 0.0,
        ymin: 0.0,
        xmax: w,
        ymax: h,
    };
    let area = boxes::area(&b);
    let outside = if area > 0.0 {
        1.0 - boxes::intersection(&b, &whole) / area
    } else {
        0.0
    };
    person.unsupported_frames > 0
        && (outside >= OUTSIDE_SHARE
            || (b.xmin <= BORDER_PX && m.vx < -v)
            || (b.ymin <= BORDER_PX && m.vy < -v)
            || (b.xmax >= w - BORDER_PX && m.vx > v)
            || (b.ymax >= h - BORDER_PX && m.vy > v))
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

/// The answer to `prior` with one ground point gated to it: the person itself, quantised, for
/// the head to model (the floor position aged to the prior's time and the centre height its
/// measured height gives are linear in the state, so the head computes from it the Ω_i, ξ_i
/// [`models::ground_contribution_aged`] would give here, from a twentieth of the bytes); none
/// when there is no person or it cannot be quantised. Its histogram goes with it when
/// `with_histogram` (the [`PeopleSender`]'s policy says it is due).
pub fn contribution(
    prior: &Prior,
    person: Option<&GroundPoint>,
    with_histogram: bool,
) -> Option<Contribution> {
    let person = person.and_then(|g| quantised(g, None, with_histogram))?;
    Some(Contribution {
        target: prior.target,
        info: None,
        folded: Kinds::NONE,
        ground: Some(person),
    })
}

/// `g` quantised for the wire, gated to `target`, with its histogram when `with_histogram`
/// and that quantises, else without it; `None` when the person itself cannot be quantised.
fn quantised(g: &GroundPoint, target: Option<TargetId>, with_histogram: bool) -> Option<GroundPerson> {
    GroundPerson::quantise(g, target, with_histogram).or_else(|| GroundPerson::quantise(g, target, false))
}

/// A person's histogram goes out again when it has drifted this far (Bhattacharyya distance,
/// blended HS:V as the filters weigh it) from the one last sent: a change the filters' colour
/// likelihood (σ = 0.15 by default) tells apart.
pub const HISTOGRAM_CHANGE: f64 = 0.1;
/// ... but not sooner than this after the last, ns,
pub const HISTOGRAM_MIN_PERIOD_NS: i64 = 2_000_000_000;
/// ... and, changed or not, at least this often, so a head that lost one (people frames may be
/// dropped) or took the camera over gets it, ns.
pub const HISTOGRAM_REFRESH_NS: i64 = 10_000_000_000;

/// What of the people leaves the camera and when: one [`PeopleFrame`] per head step at most
/// (the head fuses at its steps, and the distributed filter's contributions answer each step
/// from the newest frame alone), each person quantised, and each person's histogram with the
/// first message that carries the person (a people frame or, in distributed fusion, a
/// contribution), then only when it changed by [`HISTOGRAM_CHANGE`] (at most every
/// [`HISTOGRAM_MIN_PERIOD_NS`]) or is [`HISTOGRAM_REFRESH_NS`] old. A histogram counts as sent
/// when its message is built: one the head drops (a late answer, a region that starts no
/// track) is sent again at the next change or refresh.
#[derive(Debug)]
pub struct PeopleSender {
    period_ns: i64,
    hs_weight: f64,
    /// When the next frame is due, and the previous frame's capture time.
    next: Option<ClusterTime>,
    previous: Option<ClusterTime>,
    /// Per person: when its histogram last went out, and the histogram the head got.
    histograms: BTreeMap<u32, (ClusterTime, Vec<f32>)>,
    /// People left out of a frame because a number of theirs was not finite.
    unsendable: u64,
}

impl PeopleSender {
    /// At most one frame per `step_ms` (a head's step); histograms compared with `hs_weight`
    /// (the filters' HS share of the similarity).
    pub fn new(step_ms: u64, hs_weight: f64) -> PeopleSender {
        PeopleSender {
            period_ns: i64::try_from(step_ms.saturating_mul(1_000_000)).unwrap_or(i64::MAX),
            hs_weight,
            next: None,
            previous: None,
            histograms: BTreeMap::new(),
            unsendable: 0,
        }
    }

    /// People left out so far because a number of theirs was not finite.
    pub fn unsendable(&self) -> u64 {
        self.unsendable
    }

    /// Whether the frame captured at `captured` goes out: the first, then one per period, the
    /// frame nearest each period's end (a frame counts as due half its interval early, so a
    /// camera as fast as the steps sends every frame and a faster one every n-th).
    pub fn due(&mut self, captured: ClusterTime) -> bool {
        let interval = self.previous.map_or(0, |p| (captured - p).max(0));
        self.previous = Some(captured);
        if self.next.is_some_and(|next| captured + interval / 2 < next) {
            return false;
        }
        // Keep the cadence, unless the camera fell a whole period behind (it was off).
        let base = self
            .next
            .filter(|&next| captured - next < self.period_ns)
            .unwrap_or(captured);
        self.next = Some(base + self.period_ns);
        true
    }

    /// The message of one frame captured at `captured`: `people` with the prior each was gated
    /// to, `rssi` the tag readings that go with the gated ones. People whose numbers cannot be
    /// quantised are left out (counted); histograms go as the policy says.
    pub fn frame<'a>(
        &mut self,
        captured: ClusterTime,
        mode: Mode,
        people: impl IntoIterator<Item = (&'a GroundPoint, Option<TargetId>)>,
        rssi: Vec<RssiReading>,
    ) -> PeopleFrame {
        let mut out = Vec::new();
        for (p, target) in people {
            let with_histogram = self.histogram_due(captured, p);
            let person = quantised(p, target, with_histogram);
            let Some(person) = person else {
                self.unsendable += 1;
                continue;
            };
            if let Some(h) = &person.histogram {
                self.sent(p.local, captured, h);
            }
            out.push(person);
        }
        PeopleFrame {
            captured,
            mode,
            rssi,
            people: out,
        }
    }

    /// Whether person `p`'s histogram goes out with a message of the frame captured at
    /// `captured` (the policy above; a person without one never).
    pub fn histogram_due(&self, captured: ClusterTime, p: &GroundPoint) -> bool {
        !p.histogram.is_empty() && self.histogram_changed_or_old(captured, p)
    }

    /// Person `local`'s histogram `h` (quantised) went out with a message of the frame
    /// captured at `captured`: the next is due by the policy from now.
    pub fn sent(&mut self, local: u32, captured: ClusterTime, h: &[u8]) {
        self.histograms.insert(local, (captured, dequantise_histogram(h)));
    }

    fn histogram_changed_or_old(&self, captured: ClusterTime, p: &GroundPoint) -> bool {
        let Some((sent_at, sent)) = self.histograms.get(&p.local) else {
            return true;
        };
        let age = captured - *sent_at;
        age >= HISTOGRAM_REFRESH_NS
            || (age >= HISTOGRAM_MIN_PERIOD_NS
                && histogram_distance(sent, &p.histogram, self.hs_weight) > HISTOGRAM_CHANGE)
    }

    /// Forget the histograms of people no longer tracked (a returning id is new).
    pub fn retain(&mut self, live: &[u32]) {
        self.histograms.retain(|id, _| live.contains(id));
    }
}

/// Bhattacharyya distance of two histograms (HS then V bins), the parts' coefficients blended
/// `hs_weight : 1 − hs_weight` as the filters blend them (paper 004 eq. 6–7).
pub fn histogram_distance(a: &[f32], b: &[f32], hs_weight: f64) -> f64 {
    let rho = |x: &[f32], y: &[f32]| -> f64 { x.iter().zip(y).map(|(p, q)| f64::from(p * q).sqrt()).sum() };
    let (ah, av) = a.split_at(HISTOGRAM_HS_BINS.min(a.len()));
    let (bh, bv) = b.split_at(HISTOGRAM_HS_BINS.min(b.len()));
    let r = hs_weight * rho(ah, bh) + (1.0 - hs_weight) * rho(av, bv);
    (1.0 - r).max(0.0).sqrt()
}

#[cfg(test)]
mod tests;
