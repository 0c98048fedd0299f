//! What sensors observe, as typed kinds. A measurement or contribution carries a list of
//! observations; the head chooses the model for each kind in one place. A new sensor is a new
//! kind here (appended: variant order is the wire format), its model in [`crate::models`] and
//! its source in [`crate::sensor`].

use crate::ids::TagId;
use crate::msg::{ColourSignature, PixelBox};
use crate::time::ClusterTime;
use serde::{Deserialize, Serialize};

/// Most observations one measurement or contribution may carry.
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
    /// A person on the ground plane with size and colour, from a camera's per-person tracker
    /// (paper 004 §3.2.3).
    Ground(GroundPoint),
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

/// A person on the ground plane, as a camera's per-person tracker converts its box (paper 004
/// §3.2.3): where the rays of the box's lower corners meet the floor, with the covariance the
/// tracker's spread gives, the width and height, and the colour histogram. Paper 004 §2.5.1's
/// output: the mean state (`position`, `width_m`, `height_m`), the maximum-likelihood state
/// with its confidence (`ml_position`, `confidence`); the sample set goes only on request
/// ([`crate::msg::SampleSet`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundPoint {
    /// The camera's own id for the person (its tracker's).
    pub local: u32,
    /// Floor position `[x, y]`, metres, world frame.
    pub position: [f64; 2],
    /// Covariance of `position`, `[σxx, σxy, σyy]`, m².
    pub cov: [f64; 3],
    pub width_m: f32,
    pub height_m: f32,
    /// The tracker's confidence in `[0, 1]`.
    pub confidence: f32,
    /// Colour histogram (HS 10×10 then V 10 bins, normalized to sum 1; empty when not sent).
    pub histogram: Vec<f32>,
    pub captured: ClusterTime,
    /// Where the tracker's maximum-likelihood state puts the person on the floor, metres
    /// (`position` comes from its mean state; `confidence` is the ML state's). f32: a
    /// millimetre is plenty, and every byte a person costs goes out every frame.
    pub ml_position: [f32; 2],
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
}
