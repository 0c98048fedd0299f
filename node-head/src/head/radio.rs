//! Radio-only clusters: a head whose members are all radio-only nodes (no camera can start a
//! track there) keeps one *radio search* track while it has none, started wide at the centre of
//! its up members with Mode CameraOff, so its priors ask them for the tags they hear. The first
//! tag heard that no track holds is bound to it, and each further one gets a radio track of its
//! own (`crate::tags`: a tag's readings go into its own track only). A radio track takes its
//! tag's RSSI at once (it is confirmed: no camera can confirm it), is reported to the server
//! only once its tag was heard, and is dropped like any track when nothing was heard for
//! `track-timeout-ms`; the next step starts another search track if none is left. Clusters
//! with a camera start tracks from cameras only, as before, and their radio-only members add
//! RSSI to the tracks their tags are bound to.

use super::HeadNode;
use crate::tags::Heard;
use nalgebra::{Matrix6, Vector3};
use proto::models::State;
use proto::{ClusterTime, TargetId};
use tracing::{debug, info, warn};

/// Standard deviation of a radio search track's horizontal position at its start, metres (a
/// room's size: where the tag is is not known).
pub const RADIO_SEARCH_SIGMA_M: f64 = 5.0;
/// … of its height, and of the height a radio track is held at every step (the method's target
/// plane: RSSI alone hardly tells height), metres.
pub const RADIO_HEIGHT_SIGMA_M: f64 = 0.1;
/// … of its horizontal velocity, m/s.
const RADIO_SEARCH_SIGMA_V: f64 = 1.0;
/// … of its vertical velocity, m/s.
const RADIO_SEARCH_SIGMA_VZ: f64 = 0.1;
/// Most tracks a radio-only cluster holds; a further tag gets none (counted).
pub const MAX_RADIO_TRACKS: usize = 32;

impl HeadNode {
    /// Whether this head tracks from radio alone: it fuses RSSI and has members, every one of
    /// them radio-only.
    pub(super) fn radio_only_cluster(&self) -> bool {
        let mut members = self.nodes.iter().filter(|n| n.member).peekable();
        members.peek().is_some()
            && members.all(|n| n.info.radio_only)
            && self.uses_rssi()
            && self.fusion.fuses_rssi()
    }

    /// Start a radio search track if this is a radio-only cluster with no track and a member
    /// up.
    pub(super) fn radio_search(&mut self, now: ClusterTime) {
        if self.tracks.is_empty() && self.radio_only_cluster() {
            self.start_radio_track(now);
        }
    }

    /// In a radio-only cluster, give every tag heard this step that no track holds a track of
    /// its own: the search track while it holds none, else a new radio track. Several tags
    /// are several people, and a tag's readings go into its own track only (`crate::tags`).
    pub(super) fn radio_tracks_for(&mut self, heard: &[Heard], now: ClusterTime) {
        if !self.radio_only_cluster() {
            return;
        }
        for tag in self.tags.unbound_in(heard) {
            // The search track: started here, unnamed, holding no tag (a track handed over
            // from another head is that head's target, not a search).
            let search = self
                .tracks
                .iter()
                .find(|t| t.camera_steps == 0 && t.global.is_none() && self.tags.tag_of(t.local).is_none())
                .map(|t| t.local);
            if search.is_none() && self.tracks.len() >= MAX_RADIO_TRACKS {
                // Forged tag ids must not multiply the priors sent every step.
                self.counters.tag_readings_refused += 1;
                debug!(tag = %tag, tracks = self.tracks.len(), "no radio track for a tag: the cluster holds the most");
                continue;
            }
            if let Some(local) = search.or_else(|| self.start_radio_track(now)) {
                info!(tag = %tag, target = %local, "radio track holds a tag");
                self.tags.bind(tag, local);
            }
        }
    }

    /// Start a radio track, wide at the centre of the up members; returns its local id.
    fn start_radio_track(&mut self, now: ClusterTime) -> Option<TargetId> {
        let up: Vec<Vector3<f64>> = self
            .nodes
            .iter()
            .filter(|n| n.member && n.up)
            .map(|n| n.info.position)
            .collect();
        if up.is_empty() {
            return None;
        }
        let centre = up.iter().sum::<Vector3<f64>>() / up.len() as f64;
        let z = self.cfg.method.target_plane_z();
        let mean = State::new(centre.x, centre.y, z, 0.0, 0.0, 0.0);
        let (p, pz, v, vz) = (
            RADIO_SEARCH_SIGMA_M.powi(2),
            RADIO_HEIGHT_SIGMA_M.powi(2),
            RADIO_SEARCH_SIGMA_V.powi(2),
            RADIO_SEARCH_SIGMA_VZ.powi(2),
        );
        let cov = Matrix6::from_diagonal(&nalgebra::Vector6::new(p, p, pz, v, v, vz));
        let local = self.alloc_local();
        match self.new_track(local, None, mean, cov, now) {
            Ok(mut t) => {
                t.confirmed = true;
                info!(target = %local, x = centre.x, y = centre.y, nodes = up.len(), "radio search track");
                self.counters.births += 1;
                self.tracks.push(t);
                Some(local)
            }
            Err(e) => {
                self.counters.numeric_failures += 1;
                warn!(error = %e, "radio search track with an unusable covariance");
                None
            }
        }
    }

    /// In a radio-only cluster, hold track `t`'s height at the method's target plane (a
    /// pseudo-measurement of σ [`RADIO_HEIGHT_SIGMA_M`] in this step's sums), as the BLE
    /// experiment's RSSI-only filter does: ranges from sensors mounted at about one height
    /// hardly tell the tag's, and the filter would wander up and down.
    pub(super) fn hold_height(&mut self, t: usize) {
        if !self.radio_only_cluster() {
            return;
        }
        let w = RADIO_HEIGHT_SIGMA_M.powi(-2);
        let mut omega = Matrix6::zeros();
        omega[(2, 2)] = w;
        let mut xi = State::zeros();
        xi[2] = w * self.cfg.method.target_plane_z();
        self.tracks[t].acc.add(&omega, &xi);
    }
}
