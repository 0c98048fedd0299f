//! Every parameter of paper 004's particle-filter tracker (§2.2–2.5, §3.2), with the paper's
//! values as defaults where it gives one, and ours (said so on each field) where it leaves the
//! value to the user: the scenario's `[method.particle]` table, used by cameras whose
//! `[method] camera-tracker` is `"particle"` (node-camera's `tracker`).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// How the samples' motion models are assigned (§2.2 (ii)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionMode {
    /// Every iteration the given shares of samples use the random position, zero velocity and
    /// constant velocity models, whatever their parent used.
    Fixed,
    /// The paper's combined mode: the random share is scattered anew every iteration; every
    /// other sample keeps its parent's model (zero or constant velocity), so the model that
    /// explains the target's motion multiplies.
    #[default]
    Combined,
}

/// The particle filter tracker's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct ParticleParams {
    /// Samples per person, N (paper: 100, §2.5.1 and §2.6.1).
    pub particles: usize,
    /// Share of the Bhattacharyya similarity taken from the HS histogram; the rest from V
    /// (paper: 70:30, §2.3).
    pub hs_weight: f32,
    /// σ of the Gaussian that maps the Bhattacharyya distance to a weight (eq. 8). The paper
    /// leaves it to the user (Fig. 3 shows several); ours: 0.15.
    pub sigma: f32,
    /// Most pixels read per sample histogram: a box with more is sub-sampled on a regular
    /// grid (the paper's "per particle subsampling size", §3.2.4; ours: 256).
    pub histogram_pixels: u32,
    /// Motion model assignment (paper: combined mode, §2.2 (ii)).
    pub motion: MotionMode,
    /// Share of samples scattered uniformly over the image each iteration (random position
    /// model). Ours: 0.05.
    pub random_fraction: f32,
    /// Of the remaining samples, the share that uses the zero velocity model; the others use
    /// constant velocity. Ours: 0.5.
    pub zero_velocity_fraction: f32,
    /// Gaussian diffusion of the position, pixels per iteration. Ours: 4.
    pub position_sigma_px: f32,
    /// Gaussian diffusion of the velocity (constant velocity model), pixels per iteration per
    /// iteration. Ours: 1.
    pub velocity_sigma_px: f32,
    /// Gaussian diffusion of the box size, relative (log-normal) per iteration. Ours: 0.03.
    pub size_sigma: f32,
    /// Smallest box side a sample may shrink to, pixels. Ours: 4.
    pub min_size_px: f32,
    /// How strongly the foreground region assigned to a person shapes the weights (§3.2.2
    /// (iii)): a sample's weight is multiplied by `exp(−(1 − IoU)² / 2σ²)` with its box's
    /// overlap with the region. 0 turns it off. Ours: 0.3.
    pub roi_sigma: f32,
    /// Adaptation rate α of the target histogram (eq. 9). With a background model the rate
    /// used is `alpha × ` the foreground share under the maximum-likelihood box (§3.2.2 (i)).
    /// Ours: 0.1.
    pub alpha: f32,
    /// No adaptation while the maximum-likelihood sample's colour similarity ρ is below this
    /// (§2.4, "adapt wisely": its eq. 8 weight, the paper's confidence, is a monotone function
    /// of ρ; a threshold on ρ does not move when σ does). Ours: 0.93.
    pub adapt_min_similarity: f32,
    /// No adaptation while the foreground share under the maximum-likelihood box is below
    /// this (when a background model is given, §3.2.2 (i)). Ours: 0.5.
    pub adapt_min_foreground: f32,
    /// Frames a new foreground region must be seen, unexplained by any filter, before a filter
    /// is started on it (§3.2.1 auto initialization). Ours: 2.
    pub init_frames: u32,
    /// Smallest region area, pixels, that starts a filter. Ours: 64.
    pub min_init_area: u32,
    /// Seconds without a supporting region after which a filter is destroyed (§3.2.1: "has
    /// not found a region of interest near enough over a certain amount of time"). A camera
    /// counts it in its own frames ([`ParticleParams::destroy_frames_at`]). Ours: 2/3 s, the
    /// 10 frames at 15 fps (where `ocelli experiment paper004` runs) the wait first was.
    pub destroy_s: f64,
    /// The destroy wait as a frame count at the camera's own rate, instead of `destroy-s`
    /// (scenarios written while the waits were frame counts; recordings keep those).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub destroy_frames: Option<u32>,
    /// Seconds two filters must share a region before one is eliminated — the younger, unless
    /// the older matched clearly worse meanwhile, or the smaller when one box lies inside (or
    /// is stacked on) the other (§3.2.1: "if the object does not split up again after a
    /// certain amount of time"). Counted in frames as `destroy-s` is. Ours: 2/3 s.
    pub duplicate_s: f64,
    /// The duplicate wait as a frame count, instead of `duplicate-s` (as `destroy-frames`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duplicate_frames: Option<u32>,
    /// Two filters sharing a region count as duplicates only when their boxes overlap at
    /// least this much (IoU), or one lies inside the other or above or below it in its columns
    /// (a filter on a part of another's person): two people side by side inside one merged
    /// region keep their filters (one right behind the other does not). 0 is the paper's
    /// literal rule (any shared region). Ours: 0.4.
    pub duplicate_iou: f32,
    /// A region supports (and explains) a filter when the filter's box centre lies inside it
    /// or their IoU is at least this. Ours: 0.2.
    pub support_iou: f32,
    /// Most filters at once. Ours: 32.
    pub max_people: usize,
    /// Floor of the pixel standard deviation of the box's lower corners used for the ground
    /// covariance (a sample set that collapsed still has pixel noise). Ours: 1.
    pub corner_sigma_px: f64,
    /// Whether a filter that no region supports this frame is still reported, at its own
    /// predicted box (paper 004's camera stands alone, and its filter carries a person
    /// through an occlusion; default). `false` reports only the filters a region supports
    /// this frame, while the others live on unreported until they find one again or are
    /// destroyed: a camera whose people a head fuses with other cameras' and with its own
    /// prediction. There an unsupported filter's box mostly stands where nobody is (its
    /// person walked on, out of its region's reach), and such reports fed false tracks
    /// (docs/multi-target.md, "On main since stop 38"). Sample sets, sent on request, still
    /// cover every filter.
    pub report_unsupported: bool,
    /// Ours, not the paper's (0, the default, is its model): while a filter that walked
    /// before has stood still, supported by a region, from 0.4 s to this many seconds, the
    /// background model does not take the moving pixels of its box that have the person's
    /// colours into the background (`node_camera::ground_people::standing`). Paper 004's model
    /// takes a person who stops into the background after its history and τ (about 2.5 s):
    /// their region fades and a camera that reports only supported filters loses them. A
    /// filter that never moved (one on a ghost, or on someone standing since the model
    /// started) is not held, and a person standing longer than this is taken in as before, so
    /// a parked object is not foreground for ever. The crowd sets 30; the hall, whose people do
    /// not stop, none (it held filters that had stopped on something else).
    pub hold_still_s: f64,
}

impl Default for ParticleParams {
    fn default() -> Self {
        ParticleParams {
            particles: 100,
            hs_weight: 0.7,
            sigma: 0.15,
            histogram_pixels: 256,
            motion: MotionMode::Combined,
            random_fraction: 0.05,
            zero_velocity_fraction: 0.5,
            position_sigma_px: 4.0,
            velocity_sigma_px: 1.0,
            size_sigma: 0.03,
            min_size_px: 4.0,
            roi_sigma: 0.3,
            alpha: 0.1,
            adapt_min_similarity: 0.93,
            adapt_min_foreground: 0.5,
            init_frames: 2,
            min_init_area: 64,
            destroy_s: DEFAULT_WAIT_S,
            destroy_frames: None,
            duplicate_s: DEFAULT_WAIT_S,
            duplicate_frames: None,
            duplicate_iou: 0.4,
            support_iou: 0.2,
            max_people: 32,
            corner_sigma_px: 1.0,
            report_unsupported: true,
            hold_still_s: 0.0,
        }
    }
}

/// The default destroy and duplicate waits: 10 frames at 15 fps.
pub const DEFAULT_WAIT_S: f64 = 10.0 / 15.0;

/// Most samples per filter accepted.
pub const MAX_PARTICLES: usize = 100_000;

/// A parameter out of its range.
#[derive(Debug, Error, PartialEq)]
#[error("particle filter parameter `{field}` = {value}: {expected}")]
pub struct ParamsError {
    pub field: &'static str,
    pub value: String,
    pub expected: &'static str,
}

impl ParticleParams {
    /// Check every parameter's range.
    ///
    /// # Errors
    /// The first parameter out of range, named as in the scenario file.
    pub fn validate(&self) -> Result<(), ParamsError> {
        let fail = |field, value: &dyn std::fmt::Display, expected| {
            Err(ParamsError {
                field,
                value: value.to_string(),
                expected,
            })
        };
        let unit = |v: f32| v.is_finite() && (0.0..=1.0).contains(&v);
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        if !(1..=MAX_PARTICLES).contains(&self.particles) {
            return fail("particles", &self.particles, "1 to 100000");
        }
        if self.max_people == 0 {
            return fail("max-people", &self.max_people, "at least 1");
        }
        if self.histogram_pixels == 0 {
            return fail("histogram-pixels", &self.histogram_pixels, "at least 1");
        }
        let units = [
            ("hs-weight", self.hs_weight),
            ("random-fraction", self.random_fraction),
            ("zero-velocity-fraction", self.zero_velocity_fraction),
            ("alpha", self.alpha),
            ("adapt-min-similarity", self.adapt_min_similarity),
            ("adapt-min-foreground", self.adapt_min_foreground),
            ("duplicate-iou", self.duplicate_iou),
            ("support-iou", self.support_iou),
        ];
        for (field, v) in units {
            if !unit(v) {
                return fail(field, &v, "a number in [0, 1]");
            }
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return fail("sigma", &self.sigma, "a positive number");
        }
        let spreads = [
            ("position-sigma-px", self.position_sigma_px),
            ("velocity-sigma-px", self.velocity_sigma_px),
            ("size-sigma", self.size_sigma),
            ("roi-sigma", self.roi_sigma),
        ];
        for (field, v) in spreads {
            if !non_negative(v) {
                return fail(field, &v, "a non-negative number");
            }
        }
        if !(self.min_size_px.is_finite() && self.min_size_px >= 1.0) {
            return fail("min-size-px", &self.min_size_px, "at least 1");
        }
        if !(self.corner_sigma_px.is_finite() && self.corner_sigma_px >= 0.0) {
            return fail("corner-sigma-px", &self.corner_sigma_px, "a non-negative number");
        }
        if self.init_frames == 0 {
            return fail("init-frames", &self.init_frames, "at least 1");
        }
        let waits = [("destroy-s", self.destroy_s), ("duplicate-s", self.duplicate_s)];
        for (field, v) in waits {
            if !(v.is_finite() && v > 0.0) {
                return fail(field, &v, "a positive number of seconds");
            }
        }
        if !(self.hold_still_s.is_finite() && self.hold_still_s >= 0.0) {
            return fail(
                "hold-still-s",
                &self.hold_still_s,
                "a non-negative number of seconds",
            );
        }
        if self.destroy_frames == Some(0) {
            return fail("destroy-frames", &0, "at least 1");
        }
        if self.duplicate_frames == Some(0) {
            return fail("duplicate-frames", &0, "at least 1");
        }
        Ok(())
    }

    /// Frames without a supporting region before a filter is destroyed, for a camera at `fps`:
    /// `destroy-frames` when given, else `destroy-s` in frames (rounded, at least one).
    pub fn destroy_frames_at(&self, fps: f64) -> u32 {
        self.destroy_frames
            .unwrap_or_else(|| frames_of(self.destroy_s, fps))
    }

    /// Frames two filters share a region before one is eliminated, for a camera at `fps`
    /// (as [`Self::destroy_frames_at`]).
    pub fn duplicate_frames_at(&self, fps: f64) -> u32 {
        self.duplicate_frames
            .unwrap_or_else(|| frames_of(self.duplicate_s, fps))
    }
}

/// `seconds` in frames at `fps`, rounded, at least one; one for a rate that is not a positive
/// number (the scenario checks rates; this only keeps a wait from being zero).
fn frames_of(seconds: f64, fps: f64) -> u32 {
    let n = (seconds * fps).round();
    if n.is_finite() && n >= 1.0 {
        n.min(f64::from(u32::MAX)) as u32
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let p = ParticleParams::default();
        assert_eq!(p.particles, 100);
        assert_eq!(p.hs_weight, 0.7);
        assert_eq!(p.motion, MotionMode::Combined);
        assert_eq!(p.validate(), Ok(()));
    }

    #[test]
    fn kebab_case_keys_with_defaults_and_unknown_keys_rejected() {
        let p: ParticleParams =
            serde_json::from_str(r#"{"particles": 50, "hs-weight": 0.6, "motion": "fixed"}"#).unwrap();
        assert_eq!((p.particles, p.hs_weight, p.motion), (50, 0.6, MotionMode::Fixed));
        assert_eq!(p.sigma, ParticleParams::default().sigma);
        let err = serde_json::from_str::<ParticleParams>(r#"{"particle": 50}"#).unwrap_err();
        assert!(err.to_string().contains("unknown field `particle`"), "{err}");
        let back: ParticleParams = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn out_of_range_values_name_the_field() {
        let bad = ParticleParams {
            hs_weight: 1.5,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "hs-weight");
        let bad = ParticleParams {
            sigma: 0.0,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "sigma");
        let bad = ParticleParams {
            particles: 0,
            ..ParticleParams::default()
        };
        let err = bad.validate().unwrap_err();
        assert_eq!(err.field, "particles");
        assert!(err.to_string().contains("1 to 100000"), "{err}");
        let bad = ParticleParams {
            position_sigma_px: f32::NAN,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "position-sigma-px");
        let bad = ParticleParams {
            destroy_s: 0.0,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "destroy-s");
        let bad = ParticleParams {
            duplicate_s: f64::INFINITY,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "duplicate-s");
        let bad = ParticleParams {
            hold_still_s: -1.0,
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "hold-still-s");
        let bad = ParticleParams {
            duplicate_frames: Some(0),
            ..ParticleParams::default()
        };
        assert_eq!(bad.validate().unwrap_err().field, "duplicate-frames");
    }

    #[test]
    fn waits_are_times_counted_in_each_cameras_frames() {
        let p = ParticleParams::default();
        // 2/3 s: 10 frames at 15 fps, 3.33 → 3 at 5 fps, 20 at 30 fps, never none.
        let at = |fps| (p.destroy_frames_at(fps), p.duplicate_frames_at(fps));
        assert_eq!(at(15.0), (10, 10));
        assert_eq!(at(5.0), (3, 3));
        assert_eq!(at(30.0), (20, 20));
        assert_eq!(at(1.0), (1, 1));
        assert_eq!(at(0.5), (1, 1));
        assert_eq!(at(f64::NAN), (1, 1));
        let two_s = ParticleParams {
            destroy_s: 2.0,
            duplicate_s: 0.5,
            ..ParticleParams::default()
        };
        assert_eq!(
            (two_s.destroy_frames_at(5.0), two_s.duplicate_frames_at(5.0)),
            (10, 3)
        );
    }

    #[test]
    fn a_frame_count_written_before_the_waits_were_times_still_reads_as_frames() {
        let old: ParticleParams =
            serde_json::from_str(r#"{"destroy-frames": 3, "duplicate-frames": 4}"#).unwrap();
        assert_eq!(old.validate(), Ok(()));
        assert_eq!(
            (old.destroy_frames_at(15.0), old.duplicate_frames_at(5.0)),
            (3, 4)
        );
        let back: ParticleParams = serde_json::from_str(&serde_json::to_string(&old).unwrap()).unwrap();
        assert_eq!(back, old);
        // Without them, none is written and the seconds rule.
        let text = serde_json::to_string(&ParticleParams::default()).unwrap();
        assert!(
            !text.contains("destroy-frames")
                && !text.contains("duplicate-frames")
                && text.contains("destroy-s"),
            "{text}"
        );
    }
}
