//! Standard multi-target tracking metrics: CLEAR MOT, the identity measures (IDF1) and GOSPA,
//! computed from per-frame ground truth and hypotheses, per run and per target.
//!
//! Pure functions of their input: no scenario, recording or clock. A truth and a hypothesis
//! may match when their Euclidean distance is at most a threshold in metres (1 m is the usual
//! choice for multi-camera 3D trackers on WildTrack and MultiviewX).
//!
//! - `clear`: CLEAR MOT (Bernardin & Stiefelhagen 2008) exactly as py-motmetrics 1.4 computes
//!   it: per frame, previous matches still within the threshold are kept, the rest are paired
//!   by an optimal assignment (most pairs, then least total distance); an id switch is a truth
//!   matched to another hypothesis than at its last match; a fragmentation is a tracked truth
//!   becoming untracked and tracked again.
//! - `identity`: IDF1, IDP, IDR (Ristani et al. 2016): one optimal truth ↔ hypothesis id
//!   matching over whole trajectories maximising the frames in which the pair is within the
//!   threshold (IDTP).
//! - `gospa`: GOSPA as Stone Soup's `GOSPAMetric` computes it (α = 2, exponent p, cutoff c),
//!   averaged over the frames in which anything is present.
//!
//! The reference values the tests are pinned to come from `reference.py` beside this file
//! (py-motmetrics 1.4.0 and Stone Soup 1.9.1 on the inputs in `scenarios.json`).

mod clear;
mod gospa;
mod identity;
#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};
use std::collections::HashSet;

/// One frame: the true targets and the tracker's hypotheses, each `(id, position in metres)`.
/// `D` is 2 (ground plane) or 3. Ids are unique within a frame on each side.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame<const D: usize> {
    /// Seconds; strictly increasing over the frames of a run.
    pub t: f64,
    pub truth: Vec<(u32, [f64; D])>,
    pub hyps: Vec<(u32, [f64; D])>,
}

/// What CLEAR MOT counted in one frame (py-motmetrics' `mot_events`, grouped by frame): the
/// pairs it made, each a match or an identity switch, the truths it missed and the hypotheses
/// it counted as false positives. Summed over a run they give [`MotMetrics`]' `matches` plus
/// `id_switches` (the pairs), `misses` and `false_positives`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameEvents {
    pub t: f64,
    /// Sorted by truth id.
    pub pairs: Vec<Pair>,
    pub misses: Vec<u32>,
    pub false_positives: Vec<u32>,
}

/// A truth and the hypothesis CLEAR MOT paired it with in a frame: a match, or an identity
/// switch.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pair {
    pub truth: u32,
    pub hypothesis: u32,
    pub distance_m: f64,
    /// The truth was last paired with another hypothesis: an identity switch.
    pub switch: bool,
}

/// How pairs are scored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricsConfig {
    /// A truth and a hypothesis may match when at most this far apart (CLEAR MOT and IDF1).
    pub threshold_m: f64,
    /// GOSPA's cutoff c: a pair farther apart counts as a miss plus a false track.
    pub gospa_c_m: f64,
    /// GOSPA's exponent p (≥ 1).
    pub gospa_p: f64,
}

impl Default for MetricsConfig {
    /// 1 m matching threshold; GOSPA with c = 2 m and p = 1, so that a missed or false target
    /// costs c/2 = 1 m (α = 2) and the components add up to the total in metres.
    fn default() -> Self {
        MetricsConfig {
            threshold_m: 1.0,
            gospa_c_m: 2.0,
            gospa_p: 1.0,
        }
    }
}

/// The metrics of one run. Ratios are `None` when their denominator is zero (no truth for
/// MOTA, no match for MOTP, nothing at all for the identity measures).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotMetrics {
    /// The matching threshold used, metres.
    pub threshold_m: f64,
    pub frames: usize,
    /// 1 − (misses + id switches + false positives) / objects.
    pub mota: Option<f64>,
    /// Mean distance of the matched pairs (matches and switches), metres.
    pub motp_m: Option<f64>,
    /// 2 IDTP / (objects + predictions).
    pub idf1: Option<f64>,
    /// IDTP / predictions.
    pub idp: Option<f64>,
    /// IDTP / objects.
    pub idr: Option<f64>,
    pub idtp: usize,
    pub idfp: usize,
    pub idfn: usize,
    pub id_switches: usize,
    pub fragmentations: usize,
    /// Targets tracked in at least 80% of the frames they are present in.
    pub mostly_tracked: usize,
    /// Targets tracked in 20% to 80% of their frames.
    pub partially_tracked: usize,
    /// Targets tracked in less than 20% of their frames.
    pub mostly_lost: usize,
    pub false_positives: usize,
    pub misses: usize,
    /// Matched pairs that are not id switches (py-motmetrics' `num_matches`); true positives
    /// are `matches + id_switches`.
    pub matches: usize,
    /// Truth instances, summed over frames (py-motmetrics' `num_objects`).
    pub objects: usize,
    /// Hypothesis instances, summed over frames (`num_predictions`).
    pub predictions: usize,
    /// Distinct truth ids.
    pub unique_objects: usize,
    /// Distinct hypothesis ids (the tracker's identities).
    pub unique_hypotheses: usize,
    /// Mean GOSPA over the frames in which anything is present (0 when none is).
    pub gospa_m: f64,
    /// GOSPA's three parts, averaged the same way, in Stone Soup's units (metres to the p):
    /// the sum of matched distances to the p, and c^p/2 per missed and per false target.
    pub gospa_localisation: f64,
    pub gospa_missed: f64,
    pub gospa_false: f64,
    pub gospa_c_m: f64,
    pub gospa_p: f64,
    /// Frames averaged into GOSPA.
    pub gospa_frames: usize,
    /// One entry per truth id, in increasing id order.
    pub targets: Vec<TargetMetrics>,
}

/// How one true target was tracked.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetMetrics {
    pub id: u32,
    /// Frames the target is present in.
    pub frames: usize,
    /// Frames it was matched to a hypothesis in.
    pub tracked: usize,
    /// `tracked / frames`.
    pub coverage: f64,
    pub id_switches: usize,
    pub fragmentations: usize,
    /// The hypothesis ids it was matched to, in order of first match.
    pub hyp_ids: Vec<u32>,
    /// The hypothesis the identity measures gave it (the global id matching), if any.
    pub identity: Option<u32>,
    /// Mean distance of its matched pairs, metres (`None` when never matched).
    pub motp_m: Option<f64>,
    /// 2 × the frames it shares with its identity over its frames plus that identity's.
    pub idf1: f64,
}

/// Why metrics could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricsError {
    #[error("{name} = {value}: expected {expected}")]
    Parameter {
        name: &'static str,
        value: f64,
        expected: &'static str,
    },
    #[error("frame {frame}: time {t} is not finite or not after the previous frame's {previous}")]
    Time { frame: usize, t: f64, previous: f64 },
    #[error("frame {frame}: {side} id {id} appears twice")]
    DuplicateId { frame: usize, side: Side, id: u32 },
    #[error("frame {frame}: {side} id {id} has a non-finite position")]
    NonFinite { frame: usize, side: Side, id: u32 },
}

/// Which list of a frame an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Truth,
    Hypothesis,
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Side::Truth => "truth",
            Side::Hypothesis => "hypothesis",
        })
    }
}

/// CLEAR MOT's events of every frame of a run: where [`evaluate`]'s counts come from.
///
/// # Errors
/// As [`evaluate`].
pub fn events<const D: usize>(
    frames: &[Frame<D>],
    config: &MetricsConfig,
) -> Result<Vec<FrameEvents>, MetricsError> {
    validate(frames, config)?;
    let mut clear = clear::Clear::default();
    Ok(frames
        .iter()
        .map(|frame| clear.frame(frame, &distances(frame), config.threshold_m))
        .collect())
}

/// Computes every metric of a run.
///
/// # Errors
/// A [`MetricsError`] naming the parameter or the frame and id when a parameter is out of range
/// (threshold and cutoff finite and positive, p finite and ≥ 1), a frame's time is not finite
/// or not after the previous one, an id appears twice on one side of a frame, or a position is
/// not finite.
pub fn evaluate<const D: usize>(
    frames: &[Frame<D>],
    config: &MetricsConfig,
) -> Result<MotMetrics, MetricsError> {
    validate(frames, config)?;
    let mut clear = clear::Clear::default();
    let mut identity = identity::Identity::default();
    let mut gospa = gospa::Gospa::new(config.gospa_c_m, config.gospa_p);
    for frame in frames {
        let d = distances(frame);
        let _ = clear.frame(frame, &d, config.threshold_m);
        identity.frame(frame, &d, config.threshold_m);
        gospa.frame(frame.truth.len(), frame.hyps.len(), &d);
    }
    let ids = identity.finish();
    let g = gospa.finish();
    let c = clear;
    let objects = c.objects;
    let predictions = c.predictions;
    let targets: Vec<TargetMetrics> = c
        .targets
        .into_iter()
        .map(|(id, t)| TargetMetrics {
            id,
            frames: t.frames,
            tracked: t.tracked,
            coverage: ratio(t.tracked as f64, t.frames as f64).unwrap_or(0.0),
            id_switches: t.switches,
            fragmentations: t.fragmentations,
            motp_m: ratio(t.distance_sum, (t.tracked) as f64),
            hyp_ids: t.hyp_ids,
            identity: ids.identity.get(&id).copied(),
            idf1: ids.idf1.get(&id).copied().unwrap_or(0.0),
        })
        .collect();
    let class = |lo: f64, hi: f64| {
        targets
            .iter()
            .filter(|t| t.coverage >= lo && t.coverage < hi)
            .count()
    };
    Ok(MotMetrics {
        threshold_m: config.threshold_m,
        frames: frames.len(),
        mota: ratio((c.misses + c.switches + c.false_positives) as f64, objects as f64).map(|r| 1.0 - r),
        motp_m: ratio(c.distance_sum, (c.matches + c.switches) as f64),
        idf1: ratio(2.0 * ids.idtp as f64, (objects + predictions) as f64),
        idp: ratio(ids.idtp as f64, predictions as f64),
        idr: ratio(ids.idtp as f64, objects as f64),
        idtp: ids.idtp,
        idfp: predictions - ids.idtp,
        idfn: objects - ids.idtp,
        id_switches: c.switches,
        fragmentations: targets.iter().map(|t| t.fragmentations).sum(),
        mostly_tracked: class(0.8, f64::INFINITY),
        partially_tracked: class(0.2, 0.8),
        mostly_lost: class(f64::NEG_INFINITY, 0.2),
        false_positives: c.false_positives,
        misses: c.misses,
        matches: c.matches,
        objects,
        predictions,
        unique_objects: targets.len(),
        unique_hypotheses: ids.unique_hypotheses,
        gospa_m: g.distance,
        gospa_localisation: g.localisation,
        gospa_missed: g.missed,
        gospa_false: g.false_,
        gospa_c_m: config.gospa_c_m,
        gospa_p: config.gospa_p,
        gospa_frames: g.frames,
        targets,
    })
}

fn ratio(num: f64, den: f64) -> Option<f64> {
    (den > 0.0).then(|| num / den)
}

/// Euclidean distances, truth-major: entry `i * hyps + j`.
fn distances<const D: usize>(frame: &Frame<D>) -> Vec<f64> {
    let mut d = Vec::with_capacity(frame.truth.len() * frame.hyps.len());
    for (_, p) in &frame.truth {
        for (_, q) in &frame.hyps {
            d.push(
                p.iter()
                    .zip(q)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt(),
            );
        }
    }
    d
}

fn validate<const D: usize>(frames: &[Frame<D>], config: &MetricsConfig) -> Result<(), MetricsError> {
    let positive = |name, value: f64| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(MetricsError::Parameter {
                name,
                value,
                expected: "a finite number > 0",
            })
        }
    };
    positive("threshold_m", config.threshold_m)?;
    positive("gospa_c_m", config.gospa_c_m)?;
    if !(config.gospa_p.is_finite() && config.gospa_p >= 1.0) {
        return Err(MetricsError::Parameter {
            name: "gospa_p",
            value: config.gospa_p,
            expected: "a finite number >= 1",
        });
    }
    let mut previous = f64::NEG_INFINITY;
    for (k, frame) in frames.iter().enumerate() {
        if !(frame.t.is_finite() && frame.t > previous) {
            return Err(MetricsError::Time {
                frame: k,
                t: frame.t,
                previous,
            });
        }
        previous = frame.t;
        for (side, list) in [(Side::Truth, &frame.truth), (Side::Hypothesis, &frame.hyps)] {
            let mut seen = HashSet::with_capacity(list.len());
            for (id, p) in list {
                if !seen.insert(*id) {
                    return Err(MetricsError::DuplicateId {
                        frame: k,
                        side,
                        id: *id,
                    });
                }
                if !p.iter().all(|x| x.is_finite()) {
                    return Err(MetricsError::NonFinite {
                        frame: k,
                        side,
                        id: *id,
                    });
                }
            }
        }
    }
    Ok(())
}
