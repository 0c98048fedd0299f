//! A track's life at the head: tentative → confirmed ⇄ coasting → deleted, by explicit rules.
//!
//! - **Tentative**: born from agreeing free detections. Filtered and merged, never reported.
//!   ([`birth_clear`], refusing a birth inside a live track's gate, is the rule's test; applied
//!   at the head it measured worse on four-people, docs/multi-target.md.) Deleted after
//!   [`TENTATIVE_MISSES`] steps in a row without a measurement.
//! - **Confirmed**: camera information in at least [`CONFIRM_HITS`] of its last
//!   [`CONFIRM_WINDOW`] steps, and moved from its anchor (`track::CONFIRM_DISTANCE_M`, the
//!   ghost rule of motion segmentation); handed-over tracks are confirmed at once. Reported.
//! - **Coasting**: a confirmed track whose last step brought no measurement: predicted only, its
//!   covariance growing with the motion model; still reported while its position σ stays under
//!   [`REPORT_SIGMA_M`], back to confirmed at its next measurement.
//! - **Deleted**: coasting longer than the scenario's `track-timeout-ms`, or its position σ
//!   above [`DELETE_SIGMA_M`] (a prediction that says nothing any more).
//!
//! Duplicates: two tracks whose positions stay within [`MERGE_DISTANCE_M`] and within the gate
//! of their summed covariances (and, both reported, whose velocities agree) for
//! [`MERGE_STEPS`] steps in a row are one target; the one the server knows, else the confirmed
//! one, else the older is kept ([`merge_rank`]).

use nalgebra::{Matrix3, Matrix6, Vector3};
use proto::models::State;

/// Steps of history the confirmation looks at.
pub const CONFIRM_WINDOW: u32 = 7;
/// Steps with camera information among the last [`CONFIRM_WINDOW`] a track needs to be
/// confirmed (M of N).
pub const CONFIRM_HITS: u32 = 5;
/// A tentative track with this many steps in a row without a measurement is deleted.
pub const TENTATIVE_MISSES: u32 = 3;
/// A coasting track is reported while its position σ (the root of the largest eigenvalue of
/// its position covariance) is under this, m.
pub const REPORT_SIGMA_M: f64 = 0.6;
/// A track whose position σ grows past this is deleted, m.
pub const DELETE_SIGMA_M: f64 = 1.2;
/// Two tracks closer than this (m) may be one target.
pub const MERGE_DISTANCE_M: f64 = 0.35;
/// Steps in a row two tracks must look like one target before they are merged: two people
/// crossing are that close for a step or two, a duplicate stays.
pub const MERGE_STEPS: u32 = 3;

/// Where a track is in its life (deleted tracks are removed from the head).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lifecycle {
    Tentative,
    Confirmed,
    Coasting,
}

/// The record of a track's recent steps the rules read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct History {
    /// Bit i: camera information i steps ago (bit 0: the last closed step).
    pub camera_bits: u32,
    /// Steps in a row, up to the last, that brought no measurement of any kind.
    pub missed: u32,
}

impl History {
    /// Record one closed step: whether cameras measured the track, whether anything did.
    pub fn record(&mut self, camera: bool, informed: bool) {
        self.camera_bits = (self.camera_bits << 1) | u32::from(camera);
        if informed || camera {
            self.missed = 0;
        } else {
            self.missed += 1;
        }
    }

    /// Steps with camera information among the last [`CONFIRM_WINDOW`].
    pub fn camera_hits(&self) -> u32 {
        (self.camera_bits & ((1 << CONFIRM_WINDOW) - 1)).count_ones()
    }

    /// The M-of-N confirmation rule.
    pub fn confirmable(&self) -> bool {
        self.camera_hits() >= CONFIRM_HITS
    }
}

/// A track's state from whether it is confirmed and its history.
pub fn state(confirmed: bool, history: &History) -> Lifecycle {
    match (confirmed, history.missed) {
        (false, _) => Lifecycle::Tentative,
        (true, 0) => Lifecycle::Confirmed,
        (true, _) => Lifecycle::Coasting,
    }
}

/// The position σ of a covariance: the root of its position block's largest eigenvalue, m.
pub fn position_sigma(cov: &Matrix6<f64>) -> f64 {
    let p: Matrix3<f64> = cov.fixed_view::<3, 3>(0, 0).into_owned();
    p.symmetric_eigenvalues().max().max(0.0).sqrt()
}

/// Whether a track is deleted: a tentative track missed [`TENTATIVE_MISSES`] steps in a row;
/// any track coasted more than `coast_steps` steps or its position σ passed
/// [`DELETE_SIGMA_M`].
pub fn deleted(confirmed: bool, history: &History, cov: &Matrix6<f64>, coast_steps: u32) -> bool {
    let missed_too_long = if confirmed {
        history.missed > coast_steps
    } else {
        history.missed >= TENTATIVE_MISSES
    };
    missed_too_long || position_sigma(cov) > DELETE_SIGMA_M
}

/// Whether a track in `state` with covariance `cov` is reported to the server.
pub fn reported(state: Lifecycle, cov: &Matrix6<f64>) -> bool {
    match state {
        Lifecycle::Tentative => false,
        Lifecycle::Confirmed => true,
        Lifecycle::Coasting => position_sigma(cov) < REPORT_SIGMA_M,
    }
}

/// Whether a birth at `at` (with its own position covariance `birth_cov`) is clear of a live
/// track (mean, covariance): outside the gate of their summed position covariances. A birth
/// inside it is that track seen again, never a second track.
pub fn birth_clear(
    at: &Vector3<f64>,
    birth_cov: &Matrix3<f64>,
    track: (&State, &Matrix6<f64>),
    gate_chi2: f64,
) -> bool {
    let d = at - track.0.fixed_rows::<3>(0);
    let s = birth_cov + track.1.fixed_view::<3, 3>(0, 0);
    !s.cholesky().is_some_and(|c| d.dot(&c.solve(&d)) <= gate_chi2)
}

/// Whether two tracks look like one target this step: positions within [`MERGE_DISTANCE_M`]
/// and within the gate of the summed position covariances; when `with_velocity`, their full
/// states within the gate too (two people crossing are near but move apart).
pub fn look_alike(
    a: (&State, &Matrix6<f64>),
    b: (&State, &Matrix6<f64>),
    gate_chi2: f64,
    with_velocity: bool,
) -> bool {
    let d = a.0 - b.0;
    let s = a.1 + b.1;
    let dp = d.fixed_rows::<3>(0).into_owned();
    if dp.norm() > MERGE_DISTANCE_M {
        return false;
    }
    let sp = s.fixed_view::<3, 3>(0, 0).into_owned();
    if !sp.cholesky().is_some_and(|c| dp.dot(&c.solve(&dp)) <= gate_chi2) {
        return false;
    }
    !with_velocity || s.cholesky().is_some_and(|c| d.dot(&c.solve(&d)) <= gate_chi2)
}

/// The rank of a track when two merge (the higher kept): known to the server, confirmed, older
/// (a lower local id).
pub fn merge_rank(global: bool, confirmed: bool, local: u64) -> (bool, bool, std::cmp::Reverse<u64>) {
    (global, confirmed, std::cmp::Reverse(local))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cov(pos_var: f64) -> Matrix6<f64> {
        let mut c = Matrix6::identity() * 0.01;
        for i in 0..3 {
            c[(i, i)] = pos_var;
        }
        c
    }

    #[test]
    fn confirmation_needs_m_of_n_camera_steps() {
        let mut h = History::default();
        for _ in 0..CONFIRM_HITS - 1 {
            h.record(true, true);
        }
        assert!(!h.confirmable());
        h.record(false, false);
        assert!(!h.confirmable(), "a miss is not a hit");
        h.record(true, true);
        assert!(h.confirmable(), "{} of the last {}", CONFIRM_HITS, CONFIRM_WINDOW);
        // Hits older than the window do not count.
        let mut old = History::default();
        for _ in 0..CONFIRM_HITS {
            old.record(true, true);
        }
        for _ in 0..CONFIRM_WINDOW {
            old.record(false, true);
        }
        assert!(!old.confirmable());
    }

    #[test]
    fn a_confirmed_track_coasts_while_unobserved_and_comes_back() {
        let mut h = History::default();
        h.record(true, true);
        assert_eq!(state(true, &h), Lifecycle::Confirmed);
        h.record(false, false);
        assert_eq!(state(true, &h), Lifecycle::Coasting);
        assert!(reported(Lifecycle::Coasting, &cov(0.04)));
        assert!(!reported(Lifecycle::Coasting, &cov(1.0)), "σ 1 m is not reported");
        h.record(false, true);
        assert_eq!(
            state(true, &h),
            Lifecycle::Confirmed,
            "RSSI alone is a measurement"
        );
        assert_eq!(state(false, &h), Lifecycle::Tentative);
        assert!(!reported(Lifecycle::Tentative, &cov(0.01)));
    }

    #[test]
    fn deletion_after_the_coast_time_or_the_sigma_bound() {
        let mut h = History::default();
        for _ in 0..5 {
            h.record(false, false);
        }
        assert!(!deleted(true, &h, &cov(0.04), 15));
        assert!(deleted(true, &h, &cov(0.04), 4), "coasted past its limit");
        assert!(
            deleted(true, &h, &cov(DELETE_SIGMA_M.powi(2) * 1.1), 15),
            "σ bound"
        );
        let mut t = History::default();
        for _ in 0..TENTATIVE_MISSES - 1 {
            t.record(false, false);
        }
        assert!(!deleted(false, &t, &cov(0.04), 15));
        t.record(false, false);
        assert!(
            deleted(false, &t, &cov(0.04), 15),
            "a tentative track goes sooner"
        );
    }

    #[test]
    fn a_birth_inside_a_live_tracks_gate_is_refused() {
        let track = State::new(3.0, 4.0, 0.8, 0.5, 0.0, 0.0);
        let c = cov(0.01);
        let birth_cov = Matrix3::identity() * 0.01;
        assert!(!birth_clear(
            &Vector3::new(3.2, 4.0, 0.8),
            &birth_cov,
            (&track, &c),
            13.8
        ));
        assert!(birth_clear(
            &Vector3::new(4.5, 4.0, 0.8),
            &birth_cov,
            (&track, &c),
            13.8
        ));
    }

    #[test]
    fn duplicates_look_alike_crossers_do_not() {
        let a = State::new(3.0, 4.0, 0.8, 0.5, 0.0, 0.0);
        let b = State::new(3.1, 4.05, 0.8, 0.5, 0.0, 0.0);
        let crossing = State::new(3.1, 4.05, 0.8, -0.5, 0.0, 0.0);
        let far = State::new(3.8, 4.0, 0.8, 0.5, 0.0, 0.0);
        let c = cov(0.02);
        assert!(look_alike((&a, &c), (&b, &c), 13.8, true));
        assert!(
            !look_alike((&a, &c), (&crossing, &c), 13.8, true),
            "opposite velocities"
        );
        assert!(
            look_alike((&a, &c), (&crossing, &c), 13.8, false),
            "position only"
        );
        // Far apart, however wide the covariances.
        assert!(!look_alike((&a, &cov(4.0)), (&far, &cov(4.0)), 13.8, false));
        // The server's track, then the confirmed one, then the older is kept.
        assert!(merge_rank(true, false, 9) > merge_rank(false, true, 1));
        assert!(merge_rank(false, true, 9) > merge_rank(false, false, 1));
        assert!(merge_rank(false, true, 1) > merge_rank(false, true, 9));
    }
}
