//! Radio-only clusters: a head whose members are all radio-only nodes (no camera can start a
//! track there) keeps one *radio search* track while it has none, started wide at the centre of
//! its up members with Mode CameraOff, so its priors ask them for the tags they hear. The first
//! tag heard that no track holds is bound to it, and each further one gets a radio track of its
//! own (`crate::tags`: a tag's readings go into its own track only). A radio track takes its
//! tag's RSSI at once (it is confirmed: no camera can confirm it), is reported to the server
//! only once its tag was heard, and is dropped like any track when nothing was heard for
//! `track-timeout-ms`; the next step starts another search track if none is left. Clusters
//! with a camera start tracks from cameras, and their radio-only members add RSSI to the
//! tracks their tags are bound to; a tag no camera track claims for a while gets a radio track
//! there too (`crate::unseen`, [`HeadNode::unseen_tag_tracks`]).

use super::HeadNode;
use crate::tags::Heard;
use crate::track::Radio;
use nalgebra::{Matrix2, Matrix6, Vector2, Vector3};
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
/// Most tracks a radio-only cluster holds, and most radio tracks a cluster with cameras holds;
/// a further tag gets none (counted).
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

    /// Start a radio search track if the cluster holds no track and a member is up (and drop
    /// a [`Radio::Search`] track once it holds another): in a radio-only cluster the track the
    /// first tag heard is bound to, in one with cameras a [`Radio::Search`] track whose priors
    /// ask the radio nodes for the tags they hear (for `crate::unseen`; without a prior to
    /// answer a node sends none).
    pub(super) fn radio_search(&mut self, now: ClusterTime) {
        // A search track is needed only while the cluster holds no other.
        if self.tracks.iter().any(|t| t.radio != Some(Radio::Search)) {
            let before = self.tracks.len();
            self.tracks.retain(|t| t.radio != Some(Radio::Search));
            self.counters.deaths += (before - self.tracks.len()) as u64;
        }
        if !self.tracks.is_empty() {
            return;
        }
        if self.radio_only_cluster() {
            self.start_radio_track(now, None);
        } else if self.tracks_unseen_tags() {
            self.start_radio_track(now, Some(Radio::Search));
        }
    }

    /// Whether this cluster (one with cameras) tracks tags no camera sees: the method asks for
    /// it (`unseen-tags`), it fuses tag readings and has a member radio to hear them.
    pub(super) fn tracks_unseen_tags(&self) -> bool {
        self.cfg.method.unseen_tags
            && !self.radio_only_cluster()
            && self.uses_rssi()
            && self.fusion.fuses_rssi()
            && self.nodes.iter().any(|n| n.member && n.info.rssi)
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
            if let Some(local) = search.or_else(|| self.start_radio_track(now, None)) {
                info!(tag = %tag, target = %local, "radio track holds a tag");
                self.tags.bind(tag, local);
            }
        }
    }

    /// In a cluster with cameras that tracks unseen tags ([`Self::tracks_unseen_tags`]), give
    /// each tag that waited unbound and unclaimed (`crate::unseen`) a radio track at its RSSI
    /// fix, bound to it by evidence's rules. None on another live head's floor (that head's
    /// tracks may hold the tag) or past [`MAX_RADIO_TRACKS`] radio tracks.
    pub(super) fn unseen_tag_tracks(&mut self, heard: &[Heard], now: ClusterTime) {
        if !self.tracks_unseen_tags() {
            // (Members reassigned away may end it: no search is left waking radios.)
            self.unseen = crate::unseen::UnseenTags::default();
            return;
        }
        self.unseen.note(heard, &self.tags, now);
        for (tag, means) in self.unseen.due(&self.tags, now) {
            let radio_tracks = self.tracks.iter().filter(|t| t.is_radio()).count();
            if radio_tracks >= MAX_RADIO_TRACKS {
                self.unseen.done(tag);
                self.counters.tag_readings_refused += 1;
                debug!(tag = %tag, "no radio track for an unseen tag: the cluster holds the most");
                continue;
            }
            let readings: Vec<(Vector3<f64>, f64)> = means
                .iter()
                .map(|&(slot, dbm)| (self.nodes[slot].info.position, dbm))
                .collect();
            let Some((p, c)) = crate::unseen::fix(
                self.cfg.bounds,
                &self.cfg.walls,
                &self.cfg.method.rssi_default,
                self.cfg.target_plane_z,
                &readings,
            )
            .filter(|(_, c)| c.trace().sqrt() <= crate::unseen::MAX_FIX_SIGMA_M) else {
                debug!(tag = %tag, nodes = readings.len(), "no usable RSSI fix for an unseen tag yet: searching");
                self.unseen.search(tag, now);
                continue;
            };
            self.unseen.done(tag);
            if self.on_another_heads_floor(p.x, p.y) {
                self.counters.births_elsewhere += 1;
                debug!(tag = %tag, x = p.x, y = p.y, "an unseen tag on another head's floor: left to it");
                continue;
            }
            let Some(local) = self.push_radio_track(now, Some(Radio::Tag), p, c) else {
                continue;
            };
            info!(tag = %tag, target = %local, x = p.x, y = p.y, sigma_m = c.trace().sqrt(), nodes = readings.len(), "radio track for a tag no camera track holds");
            // The planner counts on these nodes' readings of it (they heard the tag).
            if let Some(t) = self.tracks.last_mut() {
                for &(slot, _) in &means {
                    if let Some(h) = t.rssi_heard.get_mut(slot) {
                        *h = true;
                    }
                }
            }
            self.tags.give(tag, local);
        }
    }

    /// Drop the radio tracks whose tag is gone or claimed: the evidence moved the tag to a
    /// camera track or turned against this one, or a camera track's evidence for it reached
    /// [`crate::unseen::UNSEEN_LLR`] (the person is seen after all: binding follows by the
    /// evidence's rules once the radio track is gone).
    pub(super) fn drop_superseded_radio_tracks(&mut self) {
        let before = self.tracks.len();
        let gone: Vec<TargetId> = self
            .tracks
            .iter()
            .filter(|t| t.radio == Some(Radio::Tag))
            .filter(|t| match self.tags.tag_of(t.local) {
                None => true,
                Some(tag) => self.tracks.iter().any(|k| {
                    k.camera_steps > 0 && self.tags.evidence(tag, k.local) >= crate::unseen::UNSEEN_LLR
                }),
            })
            .map(|t| t.local)
            .collect();
        for local in &gone {
            info!(target = %local, "radio track's tag is gone or a camera track claims it; dropped");
        }
        self.tracks.retain(|t| !gone.contains(&t.local));
        self.counters.deaths += (before - self.tracks.len()) as u64;
    }

    /// Start a radio track, wide at the centre of the up members; returns its local id.
    fn start_radio_track(&mut self, now: ClusterTime, radio: Option<Radio>) -> Option<TargetId> {
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
        let local = self.push_radio_track(
            now,
            radio,
            centre.xy(),
            Matrix2::identity() * RADIO_SEARCH_SIGMA_M.powi(2),
        )?;
        // A camera cluster's search track comes and goes every few seconds while the cluster
        // is empty: not news.
        if radio.is_none() {
            info!(target = %local, x = centre.x, y = centre.y, nodes = up.len(), "radio search track");
        } else {
            debug!(target = %local, x = centre.x, y = centre.y, nodes = up.len(), "radio search track");
        }
        Some(local)
    }

    /// Push a confirmed track standing on radio alone at floor point `at` (covariance `floor`)
    /// on the target plane, still, with the radio tracks' height and velocity spreads; its
    /// local id, or `None` (counted) for a covariance the filter refuses.
    fn push_radio_track(
        &mut self,
        now: ClusterTime,
        radio: Option<Radio>,
        at: Vector2<f64>,
        floor: Matrix2<f64>,
    ) -> Option<TargetId> {
        let mut cov = Matrix6::from_diagonal(&nalgebra::Vector6::new(
            0.0,
            0.0,
            RADIO_HEIGHT_SIGMA_M.powi(2),
            RADIO_SEARCH_SIGMA_V.powi(2),
            RADIO_SEARCH_SIGMA_V.powi(2),
            RADIO_SEARCH_SIGMA_VZ.powi(2),
        ));
        cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&floor);
        let mean = State::new(at.x, at.y, self.cfg.target_plane_z, 0.0, 0.0, 0.0);
        let local = self.alloc_local();
        match self.new_track(local, None, mean, cov, now) {
            Ok(mut t) => {
                t.confirm();
                t.radio = radio;
                self.counters.births += 1;
                self.tracks.push(t);
                Some(local)
            }
            Err(e) => {
                self.counters.numeric_failures += 1;
                warn!(error = %e, "radio track with an unusable covariance");
                None
            }
        }
    }

    /// In a radio-only cluster, and for a radio track in any, hold track `t`'s height at the
    /// method's target plane (a pseudo-measurement of σ [`RADIO_HEIGHT_SIGMA_M`] in this
    /// step's sums), as the BLE experiment's RSSI-only filter does: ranges from sensors
    /// mounted at about one height hardly tell the tag's, and the filter would wander up and
    /// down.
    pub(super) fn hold_height(&mut self, t: usize) {
        if !(self.radio_only_cluster() || self.tracks[t].is_radio()) {
            return;
        }
        let w = RADIO_HEIGHT_SIGMA_M.powi(-2);
        let mut omega = Matrix6::zeros();
        omega[(2, 2)] = w;
        let mut xi = State::zeros();
        xi[2] = w * self.cfg.target_plane_z;
        self.tracks[t].acc.add(&omega, &xi);
    }
}
