//! What a head counts: per step (active cameras, RSSI nodes, contributions applied / late /
//! duplicate, cluster power) and cumulative, so that reports and experiments can show every
//! dropped, late or rejected input.

use crate::activation::Decision;
use proto::ClusterTime;

/// One closed step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    pub step: u64,
    /// When the step opened (the time of its prior).
    pub time: ClusterTime,
    pub tracks: usize,
    /// Of those tracks, the ones still tentative and the ones coasting (`crate::lifecycle`);
    /// like `tracks`, counted before the step's births.
    pub tentative: usize,
    pub coasting: usize,
    /// Member nodes up and in `Active`.
    pub active_cameras: usize,
    /// Member nodes up and in `CameraOff`.
    pub camera_off: usize,
    /// Nodes whose RSSI reading was fused this step.
    pub rssi_nodes: usize,
    /// (Node, track) answers (or, centralized, measurements) applied this step.
    pub applied: u64,
    /// (Node, track) answers for an earlier step or past the deadline, counted while this step
    /// was open.
    pub late: u64,
    pub duplicate: u64,
    /// Tracks that had no measurement and were prediction only.
    pub prediction_only: usize,
    /// The cluster's power draw with the power figures and current modes, mW.
    pub power_mw: f64,
    /// The activation decision taken at the end of the step.
    pub decision: Option<Decision>,
    /// Whether the step closed early because every expected node answered.
    pub complete: bool,
}

/// Cumulative counters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counters {
    pub steps: u64,
    /// (Node, track) answers applied: a node's `Answers` answer every track of its part.
    pub applied: u64,
    /// Nodes' `Answers` that came late, came twice, or for a step that has not started (or a
    /// part the step never had): one count per message.
    pub late: u64,
    pub duplicate: u64,
    pub future: u64,
    /// Contributions for a track the part did not ask (dropped or never existed).
    pub unknown_target: u64,
    /// Messages from a node not allowed to send them (not a member, not the server).
    pub rejected: u64,
    /// Measurements beyond the per-step limit.
    pub overflow: u64,
    /// Observations of kinds this head's fusion does not use (ground-plane people, acoustic
    /// ILD vectors under an EIF), counted and ignored.
    pub unfused_observations: u64,
    /// Measurements and RSSI packets stamped too far from the head's time to fuse (a clock
    /// that is off), refused.
    pub stale_measurements: u64,
    /// Tag readings refused because the head already keeps evidence of
    /// [`crate::tags::MAX_TAGS`] other tags (a flood of tag ids).
    pub tag_readings_refused: u64,
    pub births: u64,
    /// Births refused because they lay on a live head's floor, more than
    /// `config::BIRTH_REGION_MARGIN_M` from this head's region.
    pub births_elsewhere: u64,
    pub deaths: u64,
    /// Of the deaths, tracks dropped for straying outside the world's box.
    pub left_world: u64,
    /// Tracks dropped as duplicates of another on the same target.
    pub merges: u64,
    pub handovers: u64,
    pub commands: u64,
    /// Filter updates that failed numerically and fell back to prediction only.
    pub numeric_failures: u64,
    /// Frames cameras reported processing (grid fusion: each says whether they looked).
    pub frame_reports: u64,
    /// ILD vectors acoustic nodes delivered, and those refused (stale, malformed, beyond the
    /// per-step limit).
    pub ild_vectors: u64,
    pub ild_refused: u64,
    /// Sums over steps, for averages.
    pub sum_active_cameras: u64,
    pub sum_rssi_nodes: u64,
    /// Tentative and coasting tracks summed over steps (`crate::lifecycle`).
    pub sum_tentative: u64,
    pub sum_coasting: u64,
    pub sum_power_mw: f64,
}

impl Counters {
    pub fn mean_active_cameras(&self) -> f64 {
        self.sum_active_cameras as f64 / self.steps.max(1) as f64
    }
    pub fn mean_rssi_nodes(&self) -> f64 {
        self.sum_rssi_nodes as f64 / self.steps.max(1) as f64
    }
    /// Tracks per step still tentative, and coasting.
    pub fn mean_tentative(&self) -> f64 {
        self.sum_tentative as f64 / self.steps.max(1) as f64
    }
    pub fn mean_coasting(&self) -> f64 {
        self.sum_coasting as f64 / self.steps.max(1) as f64
    }
    pub fn mean_power_mw(&self) -> f64 {
        self.sum_power_mw / self.steps.max(1) as f64
    }
}
