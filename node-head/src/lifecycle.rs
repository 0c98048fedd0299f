//! A head track's life: its states and the rules that move a track between them, in one place.
//!
//! ```text
//!   born from detections ─► Tentative ─(confirmation rule)─► Confirmed ◄─(measured)─┐
//!   handed over, named by the server, a radio track ─────────► Confirmed ─(no measurement)─► Coasting
//!   any state ─(an ending rule)─► deleted: dropped from the head
//! ```
//!
//! - **Tentative**: born from detections, not yet shown to be a target. It is filtered, sent to
//!   cameras as a prior and may be merged, but never reported (so a short-lived duplicate never
//!   becomes a global id) and it takes no RSSI (a tag's readings say where the tag is, not that
//!   this track is its target).
//! - **Confirmed**: a target, measured in its last step (camera information or its tag's RSSI
//!   fused): reported.
//! - **Coasting**: confirmed, but its last step brought no measurement. Still reported, on its
//!   prediction, and back to Confirmed by the next measurement; a short occlusion keeps its id.
//! - **Deleted**: see [`Ending`]. Silence ends a track in any state after `track-timeout-ms`.
//!
//! The confirmation rule ([`confirms`]): [`CONFIRM_STEPS`] steps with camera information,
//! and [`CONFIRM_DISTANCE_M`] moved from where the track was after [`ANCHOR_STEPS`] of them.

use nalgebra::Vector3;

/// Steps with camera information a born track needs before it is confirmed (one second at the
/// default 200 ms step): a split region or the leftover of a segmentation ghost dies tentative.
pub const CONFIRM_STEPS: u32 = 5;
/// How far (metres) a born track must move, from where it was after its first
/// [`ANCHOR_STEPS`] camera steps (by then a new track has converged on its detections), to be
/// confirmed. Motion segmentation (paper 004) only sees what moves, so a target that does not
/// move is a ghost: the background where a target stood when a camera's model was started (or
/// last woken). A track born on a ghost settles there and is never reported; a target that
/// stands still from its birth is reported once it moves.
pub const CONFIRM_DISTANCE_M: f64 = 0.25;
/// Camera steps after which a born track's position is taken as its anchor.
pub const ANCHOR_STEPS: u32 = 2;

/// Where a track is in its life (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Lifecycle {
    #[default]
    Tentative,
    Confirmed,
    Coasting,
}

/// Why a track was deleted. Silence and leaving the world are checked when a step opens
/// ([`ending_at_open`]), a failed prediction then too; a duplicate is dropped when the step
/// closes, a handed-over track when the server's handover arrives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// No measurement for `track-timeout-ms`, in any state.
    Silent,
    /// Its estimate strayed outside the world's box (with a margin).
    LeftWorld,
    /// Its prediction failed numerically (a failed update at the close leaves the track on its
    /// prediction instead).
    NumericFailure,
    /// Another track on the same target was kept (`merge_duplicates`).
    Duplicate,
    /// The server handed its target to another head.
    HandedOver,
}

impl Lifecycle {
    /// Whether the server hears of the track: a target, confirmed or coasting.
    pub fn reported(self) -> bool {
        self != Lifecycle::Tentative
    }

    /// The state after a step closed. `measured`: a camera or RSSI measurement was fused this
    /// step; `confirms`: the confirmation rule holds now ([`confirms`]).
    #[must_use]
    pub fn after_step(self, measured: bool, confirms: bool) -> Lifecycle {
        match self {
            Lifecycle::Tentative if confirms => Lifecycle::Confirmed,
            Lifecycle::Tentative => Lifecycle::Tentative,
            Lifecycle::Confirmed | Lifecycle::Coasting if measured => Lifecycle::Confirmed,
            Lifecycle::Confirmed | Lifecycle::Coasting => Lifecycle::Coasting,
        }
    }
}

/// The confirmation rule: after `camera_steps` steps with camera information, with the track
/// at `position` and its anchor (where it was after [`ANCHOR_STEPS`] of them) at `anchor`.
pub fn confirms(camera_steps: u32, anchor: Option<Vector3<f64>>, position: Vector3<f64>) -> bool {
    camera_steps >= CONFIRM_STEPS && anchor.is_some_and(|a| (position - a).norm() >= CONFIRM_DISTANCE_M)
}

/// The ending a step's opening finds for a track silent for `silent_ns` (timeout
/// `timeout_ns`), whose position is `inside_world` or not: silence first (a silent track's
/// prediction may well have left the box).
pub fn ending_at_open(silent_ns: i64, timeout_ns: i64, inside_world: bool) -> Option<Ending> {
    if silent_ns > timeout_ns {
        Some(Ending::Silent)
    } else if !inside_world {
        Some(Ending::LeftWorld)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Lifecycle::*;

    #[test]
    fn a_tentative_track_is_confirmed_only_by_the_rule_and_is_never_reported() {
        assert_eq!(Tentative.after_step(true, false), Tentative);
        assert_eq!(Tentative.after_step(false, false), Tentative);
        assert_eq!(Tentative.after_step(true, true), Confirmed);
        assert!(!Tentative.reported());
        assert!(Confirmed.reported() && Coasting.reported());
        assert_eq!(Lifecycle::default(), Tentative);
    }

    #[test]
    fn a_confirmed_track_coasts_without_a_measurement_and_comes_back_with_one() {
        assert_eq!(Confirmed.after_step(true, false), Confirmed);
        assert_eq!(Confirmed.after_step(false, false), Coasting);
        assert_eq!(Coasting.after_step(false, true), Coasting);
        assert_eq!(Coasting.after_step(true, false), Confirmed);
    }

    #[test]
    fn confirmation_needs_the_steps_and_the_move_from_the_anchor() {
        let a = Some(Vector3::new(1.0, 1.0, 0.9));
        let moved = Vector3::new(1.0, 1.0 + CONFIRM_DISTANCE_M, 0.9);
        let still = Vector3::new(1.0, 1.0 + CONFIRM_DISTANCE_M * 0.9, 0.9);
        assert!(confirms(CONFIRM_STEPS, a, moved));
        assert!(!confirms(CONFIRM_STEPS - 1, a, moved), "too few steps");
        assert!(!confirms(CONFIRM_STEPS, a, still), "a ghost stays where it was");
        assert!(!confirms(CONFIRM_STEPS + 10, None, moved), "no anchor yet");
    }

    #[test]
    fn silence_ends_a_track_before_leaving_the_world_does() {
        assert_eq!(ending_at_open(3_000, 3_000, true), None);
        assert_eq!(ending_at_open(3_001, 3_000, true), Some(Ending::Silent));
        assert_eq!(ending_at_open(3_001, 3_000, false), Some(Ending::Silent));
        assert_eq!(ending_at_open(0, 3_000, false), Some(Ending::LeftWorld));
    }
}
