//! What sensors observe, as typed kinds. A measurement carries a list of observations (a
//! contribution at most one ground person, a node's answers their tag readings); the head chooses the model for each kind in one place. A new sensor is a new
//! kind here (appended: variant order is the wire format), its model in [`crate::models`] and
//! its source in [`crate::sensor`]. Ground-plane people travel quantised ([`GroundPerson`];
//! [`GroundPoint`] is their floating-point form), a frame's together in a camera's
//! [`crate::msg::PeopleFrame`].

use crate::ids::{TagId, TargetId};
use crate::msg::{ColourSignature, PixelBox};
use crate::time::ClusterTime;
use serde::{Deserialize, Serialize};

/// Most observations one measurement may carry (and tag readings one answer or people frame).
pub const MAX_OBSERVATIONS: usize = 64;

/// Most bins a colour histogram or an ILD vector may carry.
pub const MAX_BINS: usize = 256;

/// One observation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Observation {
    /// A camera's undistorted normalized pin-hole point (papers 000, 002).
    Pinhole(PinholePoint),
    /// The received signal strength of a radio tag (paper 002).
    Rssi(RssiReading),
    /// A person on the ground plane a camera's per-person tracker sees (paper 004 §3.2.3),
    /// quantised; its capture time is its message's. In a `Contribution`, the person gated
    /// to the prior; a frame's people travel together in a [`crate::msg::PeopleFrame`].
    Ground(GroundPerson),
    /// The interaural level differences of a two-microphone node (paper 001 §3.3).
    Acoustic(IldVector),
}

/// The kind of an [`Observation`], for accounting and bitsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ObservationKind {
    Pinhole,
    Rssi,
    Ground,
    Acoustic,
}

impl ObservationKind {
    pub const ALL: [ObservationKind; 4] = [
        ObservationKind::Pinhole,
        ObservationKind::Rssi,
        ObservationKind::Ground,
        ObservationKind::Acoustic,
    ];

    /// Short name for logs and reports.
    pub fn name(self) -> &'static str {
        match self {
            ObservationKind::Pinhole => "pinhole",
            ObservationKind::Rssi => "rssi",
            ObservationKind::Ground => "ground",
            ObservationKind::Acoustic => "acoustic",
        }
    }

    /// Whether a camera made it (a pin-hole point or a ground-plane person).
    pub fn is_camera(self) -> bool {
        matches!(self, ObservationKind::Pinhole | ObservationKind::Ground)
    }
}

impl Observation {
    pub fn kind(&self) -> ObservationKind {
        match self {
            Observation::Pinhole(_) => ObservationKind::Pinhole,
            Observation::Rssi(_) => ObservationKind::Rssi,
            Observation::Ground(_) => ObservationKind::Ground,
            Observation::Acoustic(_) => ObservationKind::Acoustic,
        }
    }
}

/// A set of observation kinds, one bit each (what a contribution folded in, what a node
/// contributed to a step).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Kinds(pub u8);

impl Kinds {
    pub const NONE: Kinds = Kinds(0);

    pub fn of(kind: ObservationKind) -> Kinds {
        Kinds(1 << kind as u8)
    }

    pub fn contains(self, kind: ObservationKind) -> bool {
        self.0 & (1 << kind as u8) != 0
    }

    pub fn insert(&mut self, kind: ObservationKind) {
        self.0 |= 1 << kind as u8;
    }

    pub fn union(self, other: Kinds) -> Kinds {
        Kinds(self.0 | other.0)
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Whether a camera observation is among them.
    pub fn camera(self) -> bool {
        self.contains(ObservationKind::Pinhole) || self.contains(ObservationKind::Ground)
    }

    pub fn iter(self) -> impl Iterator<Item = ObservationKind> {
        ObservationKind::ALL
            .into_iter()
            .filter(move |k| self.contains(*k))
    }
}

impl FromIterator<ObservationKind> for Kinds {
    fn from_iter<I: IntoIterator<Item = ObservationKind>>(it: I) -> Kinds {
        let mut k = Kinds::NONE;
        for kind in it {
            k.insert(kind);
        }
        k
    }
}

/// An undistorted normalized pin-hole point of one segmented region.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PinholePoint {
    /// Normalized pin-hole point `[x, y]` (undistorted).
    pub point: [f64; 2],
    /// Covariance of `point`, `[σxx, σxy, σyy]` in normalized units².
    pub cov: [f64; 3],
    /// Previous-frame normalized point of the same region, if tracked (paper 000 eq. 13).
    pub prev_point: Option<[f64; 2]>,
    pub pixel_box: PixelBox,
    /// Region area in pixels.
    pub area: u32,
    pub colour: ColourSignature,
    /// When the frame was captured, the camera's cluster time.
    pub captured: ClusterTime,
}

/// A received-signal-strength reading of a tag.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RssiReading {
    /// The tag heard (its BLE MAC).
    pub tag: TagId,
    /// Received power, dBm.
    pub dbm: f64,
    /// When the packet was received, cluster time.
    pub time: ClusterTime,
}

/// Bins of a ground-plane person's colour histogram: paper 004's 10 × 10 hue-saturation bins
/// (hue-major), then 10 value bins. Each part sums to 1.
pub const HISTOGRAM_HS_BINS: usize = 100;
pub const HISTOGRAM_V_BINS: usize = 10;
pub const HISTOGRAM_BINS: usize = HISTOGRAM_HS_BINS + HISTOGRAM_V_BINS;

/// A [`GroundPerson`]'s position step, m: positions travel in centimetres (at most 5 mm off,
/// against the 0.25 m a camera adds to every position's standard deviation).
pub const POSITION_STEP_M: f64 = 0.01;
/// A [`GroundPerson`]'s standard deviation step, m (millimetres).
pub const SIGMA_STEP_M: f64 = 0.001;
/// A [`GroundPerson`]'s correlation travels in 128ths, in −127..=127: `|ρ| ≤ 127/128`, so the
/// covariance it gives back is positive definite.
pub const CORRELATION_STEPS: f64 = 128.0;
/// A [`GroundPerson`]'s width and height step, m (centimetres).
pub const SIZE_STEP_M: f64 = 0.01;

/// A person on the ground plane, as a camera's per-person tracker converts its box (paper 004
/// §3.2.3), in floating point: where the rays of the box's lower corners meet the floor, with
/// the covariance the tracker's spread gives, the width and height, and the colour histogram.
/// Paper 004 §2.5.1's output: the mean state (`position`, `width_m`, `height_m`), the
/// maximum-likelihood state with its confidence (`ml_position`, `confidence`); the sample set
/// goes only on request ([`crate::msg::SampleSet`]). It is not sent as it is: a
/// [`GroundPerson`] quantises it for the wire and gives it back ([`GroundPerson::point`]).
#[derive(Clone, Debug, PartialEq)]
pub struct GroundPoint {
    /// The camera's own id for the person (its tracker's).
    pub local: u32,
    /// Floor position `[x, y]`, metres, world frame.
    pub position: [f64; 2],
    /// Covariance of `position`, `[σxx, σxy, σyy]`, m².
    pub cov: [f64; 3],
    pub width_m: f64,
    pub height_m: f64,
    /// The tracker's confidence in `[0, 1]`.
    pub confidence: f64,
    /// Colour histogram ([`HISTOGRAM_BINS`] bins, HS then V, each part summing to 1); empty
    /// when there is none.
    pub histogram: Vec<f32>,
    pub captured: ClusterTime,
    /// Where the tracker's maximum-likelihood state puts the person on the floor, metres
    /// (`position` comes from its mean state; `confidence` is the ML state's).
    pub ml_position: [f64; 2],
}

/// One person of a [`crate::msg::PeopleFrame`]: a [`GroundPoint`] quantised to small integers
/// (postcard writes them as varints: about 18 bytes without the histogram, 129 with it). The
/// capture time is the frame's.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct GroundPerson {
    /// The camera's own id for the person (its tracker's); once per frame.
    pub local: u32,
    /// The prior the camera gated the person to, if any (its tag readings then apply).
    pub target: Option<TargetId>,
    /// Floor position `[x, y]`, centimetres ([`POSITION_STEP_M`]), world frame.
    pub position_cm: [i32; 2],
    /// Standard deviations of the position along x and y, millimetres, at least 1.
    pub sigma_mm: [u16; 2],
    /// Correlation of x and y in 128ths, −127..=127 ([`CORRELATION_STEPS`]).
    pub correlation: i8,
    pub width_cm: u16,
    pub height_cm: u16,
    /// The tracker's confidence in 255ths.
    pub confidence: u8,
    /// The maximum-likelihood state's floor position minus `position`, centimetres.
    pub ml_offset_cm: [i16; 2],
    /// The colour histogram, each part's square roots scaled so its fullest bin is 255
    /// ([`quantise_histogram`]); only when the camera sends it (a person's first frame, then
    /// when it changed).
    pub histogram: Option<Vec<u8>>,
}

/// `x / step` rounded, if finite and within `min..=max`.
fn steps(x: f64, step: f64, min: i64, max: i64) -> Option<i64> {
    let q = (x / step).round();
    (q.is_finite() && (min as f64..=max as f64).contains(&q)).then_some(q as i64)
}

/// `x / step` rounded and clamped into `min..=max` (`None` if not finite).
fn clamped_steps(x: f64, step: f64, min: i64, max: i64) -> Option<i64> {
    let q = (x / step).round();
    q.is_finite().then(|| q.clamp(min as f64, max as f64) as i64)
}

impl GroundPerson {
    /// `point` quantised (its `captured` goes once per frame), gated to `target`, with its
    /// histogram if `with_histogram` and it has one. Sizes, standard deviations and the
    /// ML position's offset saturate at their type's range, `|ρ|` at 127/128. `None` when a
    /// number is not finite, a size negative, the covariance not positive definite, the
    /// position beyond ±21 000 km, or a histogram asked for is not one
    /// ([`quantise_histogram`]): such a point is not sent.
    pub fn quantise(
        point: &GroundPoint,
        target: Option<TargetId>,
        with_histogram: bool,
    ) -> Option<GroundPerson> {
        let [xx, xy, yy] = point.cov;
        if !(xx > 0.0 && yy > 0.0 && xx * yy - xy * xy > 0.0) || point.width_m < 0.0 || point.height_m < 0.0 {
            return None;
        }
        let (i32min, i32max) = (i64::from(i32::MIN), i64::from(i32::MAX));
        let position_cm = [
            steps(point.position[0], POSITION_STEP_M, i32min, i32max)? as i32,
            steps(point.position[1], POSITION_STEP_M, i32min, i32max)? as i32,
        ];
        let sigma = |v: f64| clamped_steps(v.sqrt(), SIGMA_STEP_M, 1, i64::from(u16::MAX)).map(|q| q as u16);
        let rho = xy / (xx * yy).sqrt();
        let size = |v: f64| clamped_steps(v, SIZE_STEP_M, 0, i64::from(u16::MAX)).map(|q| q as u16);
        let offset = |i: usize| {
            clamped_steps(
                point.ml_position[i] - f64::from(position_cm[i]) * POSITION_STEP_M,
                POSITION_STEP_M,
                i64::from(i16::MIN),
                i64::from(i16::MAX),
            )
            .map(|q| q as i16)
        };
        let histogram = if with_histogram && !point.histogram.is_empty() {
            Some(quantise_histogram(&point.histogram)?)
        } else {
            None
        };
        Some(GroundPerson {
            local: point.local,
            target,
            position_cm,
            sigma_mm: [sigma(xx)?, sigma(yy)?],
            correlation: clamped_steps(rho, 1.0 / CORRELATION_STEPS, -127, 127)? as i8,
            width_cm: size(point.width_m)?,
            height_cm: size(point.height_m)?,
            confidence: clamped_steps(point.confidence, 1.0 / 255.0, 0, 255)? as u8,
            ml_offset_cm: [offset(0)?, offset(1)?],
            histogram,
        })
    }

    /// Floor position, m.
    pub fn position(&self) -> [f64; 2] {
        self.position_cm.map(|c| f64::from(c) * POSITION_STEP_M)
    }

    /// Covariance of the position, `[σxx, σxy, σyy]`, m² (positive definite for a valid
    /// person).
    pub fn cov(&self) -> [f64; 3] {
        let [sx, sy] = self.sigma_mm.map(|s| f64::from(s) * SIGMA_STEP_M);
        let rho = f64::from(self.correlation) / CORRELATION_STEPS;
        [sx * sx, rho * sx * sy, sy * sy]
    }

    pub fn height_m(&self) -> f64 {
        f64::from(self.height_cm) * SIZE_STEP_M
    }

    /// The floating-point person it stands for, captured at `captured` (its frame's time).
    pub fn point(&self, captured: ClusterTime) -> GroundPoint {
        let position = self.position();
        GroundPoint {
            local: self.local,
            position,
            cov: self.cov(),
            width_m: f64::from(self.width_cm) * SIZE_STEP_M,
            height_m: self.height_m(),
            confidence: f64::from(self.confidence) / 255.0,
            histogram: self
                .histogram
                .as_deref()
                .map(dequantise_histogram)
                .unwrap_or_default(),
            captured,
            ml_position: [0, 1].map(|i| position[i] + f64::from(self.ml_offset_cm[i]) * POSITION_STEP_M),
        }
    }
}

/// A histogram's bytes on the wire: in each part (HS, V) the square root of every bin, scaled
/// so that the fullest bin is 255 and rounded. Square roots because the Bhattacharyya
/// coefficient that compares histograms is a sum of them (paper 004 eq. 6): a bin's root is off
/// by at most 1/510 of its part's largest, so a part's Bhattacharyya distance to the original
/// stays below √(2 · bins) / 510 (0.028 for HS, 0.009 for V), and small bins do not vanish.
/// `None` unless it has [`HISTOGRAM_BINS`] finite, non-negative bins and weight in both parts.
pub fn quantise_histogram(bins: &[f32]) -> Option<Vec<u8>> {
    if bins.len() != HISTOGRAM_BINS || bins.iter().any(|b| !(b.is_finite() && *b >= 0.0)) {
        return None;
    }
    fn part(p: &[f32], out: &mut Vec<u8>) -> Option<()> {
        let max = p.iter().fold(0.0f32, |a, b| a.max(*b));
        (max > 0.0).then(|| out.extend(p.iter().map(|b| (255.0 * (b / max).sqrt()).round() as u8)))
    }
    let (hs, v) = bins.split_at(HISTOGRAM_HS_BINS);
    let mut out = Vec::with_capacity(HISTOGRAM_BINS);
    part(hs, &mut out)?;
    part(v, &mut out)?;
    Some(out)
}

/// The histogram a quantised one stands for: each part's squared bytes renormalized to sum 1
/// (a part without weight stays zero; a valid message has none).
pub fn dequantise_histogram(q: &[u8]) -> Vec<f32> {
    fn part(p: &[u8], out: &mut Vec<f32>) {
        let sum: f32 = p.iter().map(|b| f32::from(*b).powi(2)).sum();
        let f = if sum > 0.0 { 1.0 / sum } else { 0.0 };
        out.extend(p.iter().map(|b| f32::from(*b).powi(2) * f));
    }
    let (hs, v) = q.split_at(HISTOGRAM_HS_BINS.min(q.len()));
    let mut out = Vec::with_capacity(q.len());
    part(hs, &mut out);
    part(v, &mut out);
    out
}

/// A two-microphone node's weighted interaural level differences over frequency (paper 001
/// eq. 13–15) for one audio frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IldVector {
    /// Frequency of the first band and the spacing of the bands, Hz.
    pub first_hz: f32,
    pub step_hz: f32,
    /// Weighted level difference per band, dB.
    pub ild_db: Vec<f32>,
    /// When the frame ended, the node's cluster time.
    pub captured: ClusterTime,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kind_sets_hold_what_is_inserted() {
        let mut k = Kinds::NONE;
        assert!(k.is_empty() && !k.camera());
        k.insert(ObservationKind::Rssi);
        assert!(k.contains(ObservationKind::Rssi) && !k.camera());
        k.insert(ObservationKind::Ground);
        assert!(k.camera());
        assert_eq!(
            k.iter().collect::<Vec<_>>(),
            vec![ObservationKind::Rssi, ObservationKind::Ground]
        );
        let all: Kinds = ObservationKind::ALL.into_iter().collect();
        assert_eq!(all, Kinds(0b1111));
        assert_eq!(
            Kinds::of(ObservationKind::Pinhole)
                .union(Kinds::of(ObservationKind::Acoustic))
                .0,
            0b1001
        );
    }

    use proptest::prelude::*;

    fn point(position: [f64; 2], cov: [f64; 3]) -> GroundPoint {
        GroundPoint {
            local: 3,
            position,
            cov,
            width_m: 0.5,
            height_m: 1.7,
            confidence: 0.8,
            histogram: Vec::new(),
            captured: ClusterTime(77),
            ml_position: position,
        }
    }

    /// A histogram of `HISTOGRAM_BINS` bins from raw weights (each part normalized to 1).
    fn normalized(raw: &[f32]) -> Vec<f32> {
        let (hs, v) = raw.split_at(HISTOGRAM_HS_BINS);
        let part = |p: &[f32]| {
            let s: f32 = p.iter().sum();
            p.iter().map(|x| x / s).collect::<Vec<_>>()
        };
        [part(hs), part(v)].concat()
    }

    /// Bhattacharyya distance of two histograms' parts.
    fn distance(a: &[f32], b: &[f32]) -> f64 {
        let rho: f64 = a.iter().zip(b).map(|(p, q)| f64::from(p * q).sqrt()).sum();
        (1.0 - rho).max(0.0).sqrt()
    }

    fn weights() -> impl Strategy<Value = Vec<f32>> {
        // Peaked (many empty bins, a few full ones) as well as spread histograms.
        prop::collection::vec(
            prop_oneof![3 => Just(0.0f32), 1 => 0.0..1e-3f32, 1 => 0.0..1.0f32],
            HISTOGRAM_BINS,
        )
        .prop_map(|mut w| {
            w[17] += 0.5;
            w[HISTOGRAM_HS_BINS + 4] += 0.5;
            w
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// Every field comes back within half its step (sizes, σ and the ML position's offset
        /// inside their range), and the covariance is positive definite.
        #[test]
        fn a_person_comes_back_within_its_steps(
            x in -500.0..500.0f64, y in -500.0..500.0f64,
            sx in 0.01..20.0f64, sy in 0.01..20.0f64, rho in -0.99..0.99f64,
            (w, h, c) in (0.0..5.0f64, 0.0..5.0f64, 0.0..=1.0f64),
            (dx, dy) in (-50.0..50.0f64, -50.0..50.0f64),
            target in prop::option::of(any::<u32>()),
        ) {
            let mut p = point([x, y], [sx * sx, rho * sx * sy, sy * sy]);
            (p.width_m, p.height_m, p.confidence) = (w, h, c);
            p.ml_position = [x + dx, y + dy];
            let q = GroundPerson::quantise(&p, target.map(TargetId), true).unwrap();
            prop_assert_eq!(q.target, target.map(TargetId));
            prop_assert!(q.histogram.is_none(), "no histogram to send");
            let back = q.point(p.captured);
            let half = |step: f64| 0.5 * step + 1e-9;
            prop_assert!((back.position[0] - x).abs() <= half(POSITION_STEP_M));
            prop_assert!((back.position[1] - y).abs() <= half(POSITION_STEP_M));
            prop_assert!((back.cov[0].sqrt() - sx).abs() <= half(SIGMA_STEP_M));
            prop_assert!((back.cov[2].sqrt() - sy).abs() <= half(SIGMA_STEP_M));
            let back_rho = back.cov[1] / (back.cov[0] * back.cov[2]).sqrt();
            prop_assert!((back_rho - rho).abs() <= half(1.0 / CORRELATION_STEPS));
            prop_assert!(back.cov[0] * back.cov[2] - back.cov[1] * back.cov[1] > 0.0);
            prop_assert!((back.width_m - w).abs() <= half(SIZE_STEP_M));
            prop_assert!((back.height_m - h).abs() <= half(SIZE_STEP_M));
            prop_assert!((back.confidence - c).abs() <= half(1.0 / 255.0));
            // The offset is taken from the quantised position: one step in all.
            prop_assert!((back.ml_position[0] - x - dx).abs() <= half(POSITION_STEP_M));
            prop_assert!((back.ml_position[1] - y - dy).abs() <= half(POSITION_STEP_M));
            prop_assert_eq!(back.captured, p.captured);
            prop_assert_eq!(back.local, p.local);
        }

        /// A quantised histogram comes back with each part summing to 1, within the
        /// Bhattacharyya distance its square-root steps allow (√(2 · bins) / 510 per part).
        #[test]
        fn a_histogram_comes_back_within_its_bhattacharyya_bound(raw in weights()) {
            let h = normalized(&raw);
            let q = quantise_histogram(&h).unwrap();
            prop_assert_eq!(q.len(), HISTOGRAM_BINS);
            let back = dequantise_histogram(&q);
            let (hs, v) = h.split_at(HISTOGRAM_HS_BINS);
            let (bhs, bv) = back.split_at(HISTOGRAM_HS_BINS);
            for (part, bpart) in [(hs, bhs), (v, bv)] {
                prop_assert!((bpart.iter().sum::<f32>() - 1.0).abs() < 1e-5);
                let bound = (2.0 * part.len() as f64).sqrt() / 510.0;
                let d = distance(part, bpart);
                prop_assert!(d <= bound, "distance {} > {}", d, bound);
            }
            // Quantised again, it is the same bytes: what a head gets back is stable.
            prop_assert_eq!(quantise_histogram(&back).unwrap(), q);
        }
    }

    #[test]
    fn a_histogram_travels_only_when_asked_and_when_it_is_one() {
        let mut p = point([1.0, 2.0], [0.1, 0.0, 0.1]);
        let q = GroundPerson::quantise(&p, None, true).unwrap();
        assert_eq!(q.histogram, None, "none to send");
        p.histogram = normalized(&[1.0; HISTOGRAM_BINS]);
        assert_eq!(GroundPerson::quantise(&p, None, false).unwrap().histogram, None);
        let q = GroundPerson::quantise(&p, None, true).unwrap();
        assert_eq!(
            q.histogram,
            Some(vec![255; HISTOGRAM_BINS]),
            "flat: every root is the largest"
        );
        assert_eq!(q.point(p.captured).histogram, p.histogram);
        // Not a histogram: a person with it is not sent at all.
        for bad in [vec![0.5; 3], vec![0.0; HISTOGRAM_BINS], {
            let mut h = p.histogram.clone();
            h[5] = f32::NAN;
            h
        }] {
            p.histogram = bad;
            assert_eq!(GroundPerson::quantise(&p, None, true), None);
        }
    }

    #[test]
    fn impossible_points_are_not_quantised_and_big_values_saturate() {
        let ok = point([1.0, 2.0], [0.1, 0.0, 0.1]);
        assert!(GroundPerson::quantise(&ok, None, false).is_some());
        let mut bad = Vec::new();
        for (i, v) in [f64::NAN, f64::INFINITY, 3e7].into_iter().enumerate() {
            let mut p = ok.clone();
            p.position[i % 2] = v;
            bad.push(p);
        }
        for cov in [
            [0.0, 0.0, 0.1],
            [0.1, 0.1, 0.1],
            [f64::NAN, 0.0, 0.1],
            [-0.1, 0.0, 0.1],
        ] {
            bad.push(point([1.0, 2.0], cov));
        }
        let mut p = ok.clone();
        p.height_m = -0.1;
        bad.push(p);
        let mut p = ok.clone();
        p.ml_position[1] = f64::NAN;
        bad.push(p);
        for p in &bad {
            assert_eq!(GroundPerson::quantise(p, None, false), None, "{p:?}");
        }
        // Out of range, but finite and proper: saturated, never wrapped.
        let mut p = point([1.0, 2.0], [1e4, 1e4 * 0.99999, 1e4]);
        p.width_m = 1e6;
        p.ml_position = [1e6, -1e6];
        p.confidence = 7.0;
        let q = GroundPerson::quantise(&p, None, false).unwrap();
        assert_eq!(q.sigma_mm, [65_535, 65_535]);
        assert_eq!(q.correlation, 127);
        assert_eq!(q.width_cm, u16::MAX);
        assert_eq!(q.ml_offset_cm, [i16::MAX, i16::MIN]);
        assert_eq!(q.confidence, 255);
        let q = GroundPerson::quantise(&point([0.0, 0.0], [1e-12, 0.0, 1e-12]), None, false).unwrap();
        assert_eq!(q.sigma_mm, [1, 1], "at least a millimetre");
    }
}
