//! One track at the head: its filter, the auxiliary camera-only filter that feeds RSSI
//! training, this step's sums and readings, and one RSSI trainer per node.

use crate::association::Detection;
use crate::eif::{Accumulator, Eif, FilterError};
use crate::lifecycle::{ANCHOR_STEPS, Lifecycle, confirms};
use crate::rssi_noise::RssiNoise;
use crate::rssi_training::RssiTrainer;
use nalgebra::{Matrix3, Matrix6, Vector3};
use proto::models::{MotionModel, RssiModel, State};
use proto::msg::Contributor;
use proto::observation::Kinds;
use proto::{ClusterTime, TargetId};

/// How far a track's appearance moves towards each colour histogram a camera sends of it.
pub const APPEARANCE_RATE: f32 = 0.3;

/// A track.
#[derive(Clone, Debug)]
pub struct Track {
    pub local: TargetId,
    pub global: Option<TargetId>,
    pub filter: Eif,
    /// Camera-only EIF (paper 002 §IV): the distances RSSI training uses.
    pub aux: Eif,
    pub acc: Accumulator,
    pub aux_acc: Accumulator,
    /// RSSI readings of this step: (node slot, dBm, seconds from reception to the track's time).
    pub rssi: Vec<(usize, f64, f64)>,
    /// Detections associated this step (centralized and ML fusion).
    pub detections: Vec<Detection>,
    pub contributors: Vec<Contributor>,
    /// When the oldest camera frame fused this step was captured.
    pub captured: Option<ClusterTime>,
    /// One trainer per node slot.
    pub trainers: Vec<RssiTrainer>,
    /// How much wider than their models claim this track's RSSI readings are weighed.
    pub rssi_noise: RssiNoise,
    /// Per node slot: whether it ever read this target's tag (activation expects RSSI only
    /// from those).
    pub rssi_heard: Vec<bool>,
    /// Time of the filter's state.
    pub time: ClusterTime,
    /// Last time a measurement carried information about it.
    pub last_seen: ClusterTime,
    /// ML's lifted points of this step, and its previous fix (for its velocity).
    pub ml_points: Vec<(Vector3<f64>, Matrix3<f64>)>,
    pub ml_prev: Option<(Vector3<f64>, ClusterTime)>,
    /// Steps in which cameras measured it.
    pub camera_steps: u32,
    /// Position after [`ANCHOR_STEPS`] camera steps (tentative tracks only).
    pub anchor: Option<Vector3<f64>>,
    /// Where it is in its life (`crate::lifecycle`); set by [`Track::end_step`] and
    /// [`Track::confirm`] only.
    state: Lifecycle,
    /// The colour histogram the ground-plane observations fused into it carried, blended
    /// over time (empty until one came): its appearance for identity at the server.
    pub appearance: Vec<f32>,
    /// A radio track of a cluster with cameras (`crate::unseen`): cameras pair nothing with
    /// it (`Prior::radio`).
    pub radio: Option<Radio>,
}

/// Why a cluster with cameras holds a track no camera measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Radio {
    /// The cluster holds no other track: this one's priors ask the nodes for the tags they
    /// hear (a node answers priors, and sends its readings only then). Never reported; it
    /// times out like any unfed track, and another follows while the cluster has none.
    Search,
    /// Started for a tag no camera track held: it stands on its tag's readings alone and ends
    /// with its tag.
    Tag,
}

impl Track {
    /// A track from a Gaussian at `now`, with `nodes` RSSI trainers.
    ///
    /// # Errors
    /// The covariance is not positive definite.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        local: TargetId,
        global: Option<TargetId>,
        mean: State,
        cov: Matrix6<f64>,
        now: ClusterTime,
        nodes: usize,
        rssi_default: RssiModel,
        window: usize,
        epsilon: f64,
    ) -> Result<Self, FilterError> {
        let filter = Eif::from_gaussian(mean, cov)?;
        Ok(Track {
            local,
            global,
            aux: filter.clone(),
            filter,
            acc: Accumulator::default(),
            aux_acc: Accumulator::default(),
            rssi: Vec::new(),
            detections: Vec::new(),
            contributors: Vec::new(),
            captured: None,
            trainers: (0..nodes)
                .map(|_| RssiTrainer::new(rssi_default, window, epsilon))
                .collect(),
            rssi_noise: RssiNoise::default(),
            rssi_heard: vec![false; nodes],
            time: now,
            last_seen: now,
            ml_points: Vec::new(),
            ml_prev: None,
            camera_steps: 0,
            anchor: None,
            state: if global.is_some() {
                Lifecycle::Confirmed
            } else {
                Lifecycle::Tentative
            },
            appearance: Vec::new(),
            radio: None,
        })
    }

    /// Predict both filters to `now` and clear the step's sums.
    ///
    /// # Errors
    /// A prediction failed numerically; the filters are unchanged.
    pub fn begin_step(&mut self, motion: &MotionModel, now: ClusterTime) -> Result<(), FilterError> {
        let dt = now.secs_since(self.time);
        if dt > 0.0 {
            let f = self.filter.predicted(motion, dt)?;
            let a = self.aux.predicted(motion, dt)?;
            self.filter = f;
            self.aux = a;
            self.time = now;
        }
        self.acc.clear();
        self.aux_acc.clear();
        self.rssi.clear();
        self.detections.clear();
        self.ml_points.clear();
        self.contributors.clear();
        self.captured = None;
        Ok(())
    }

    /// Close a step: count it if cameras measured the track (`camera`), take its anchor after
    /// [`ANCHOR_STEPS`] of them, and move it along its life (`crate::lifecycle`): `measured`
    /// says whether any measurement (camera or RSSI) was fused this step.
    pub fn end_step(&mut self, camera: bool, measured: bool) {
        self.camera_steps += u32::from(camera);
        if self.state == Lifecycle::Tentative && camera && self.camera_steps == ANCHOR_STEPS {
            self.anchor = Some(self.position());
        }
        // Only a step with camera information can confirm (a tentative track takes no RSSI).
        let confirms = camera && confirms(self.camera_steps, self.anchor, self.position());
        self.state = self.state.after_step(measured, confirms);
    }

    /// Where the track is in its life.
    pub fn state(&self) -> Lifecycle {
        self.state
    }

    /// Confirmed or coasting: reported to the server, takes RSSI, may hold a tag.
    pub fn past_tentative(&self) -> bool {
        self.state.reported()
    }

    /// Confirm the track now: the server named it (its target is known), or it is a radio
    /// track (no camera can confirm it). A coasting track stays coasting.
    pub fn confirm(&mut self) {
        if self.state == Lifecycle::Tentative {
            self.state = Lifecycle::Confirmed;
        }
    }

    /// A radio track of a cluster with cameras (cameras never measure one: `Prior::radio`).
    pub fn is_radio(&self) -> bool {
        self.radio.is_some()
    }

    pub fn position(&self) -> Vector3<f64> {
        self.filter.mean().fixed_rows::<3>(0).into_owned()
    }

    /// Queue an RSSI reading of node `slot`, received `age_s` seconds before the track's time,
    /// for this step; returns whether it was taken.
    ///
    /// A tentative track takes none: the tag's readings say where the tag is, not that this
    /// track is its target, and a track born on a segmentation ghost that took them was pulled
    /// onto the tagged robot, "moved", and was confirmed as a second target (Table I, pixel
    /// level: a ghost global in 6 of the proposed method's first 20 runs, 1–1.4 m off for up
    /// to 2 s). Until it is confirmed a track stands on what cameras see.
    pub fn hear(&mut self, slot: usize, dbm: f64, age_s: f64) -> bool {
        if !self.past_tentative() {
            return false;
        }
        self.rssi.push((slot, dbm, age_s));
        if let Some(h) = self.rssi_heard.get_mut(slot) {
            *h = true;
        }
        true
    }

    /// A camera's colour histogram of the person this track follows (sent on the person's
    /// first frame and when it changed): the track's appearance moves [`APPEARANCE_RATE`] of
    /// the way towards it, so one odd frame (a partial occlusion) does not replace it.
    pub fn see_colours(&mut self, histogram: &[f32]) {
        if self.appearance.len() == histogram.len() {
            for (a, h) in self.appearance.iter_mut().zip(histogram) {
                *a += APPEARANCE_RATE * (h - *a);
            }
        } else {
            self.appearance = histogram.to_vec();
        }
    }

    /// A camera frame captured at `at` was fused this step.
    pub fn fused_frame(&mut self, at: ClusterTime) {
        self.captured = Some(self.captured.map_or(at, |c| c.min(at)));
    }

    /// Record one node's share in the report.
    pub fn note(&mut self, node: proto::NodeId, kinds: Kinds) {
        if let Some(c) = self.contributors.iter_mut().find(|c| c.node == node) {
            c.kinds = c.kinds.union(kinds);
        } else {
            self.contributors.push(Contributor { node, kinds });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(global: Option<TargetId>) -> Track {
        let model = RssiModel::LogDistance {
            a: -22.0,
            b: -45.0,
            variance: 16.0,
        };
        let mean = State::new(3.0, 4.0, 0.25, 0.5, 0.0, 0.0);
        Track::new(
            TargetId(1),
            global,
            mean,
            Matrix6::identity() * 0.04,
            ClusterTime::ZERO,
            3,
            model,
            20,
            0.1,
        )
        .unwrap()
    }

    #[test]
    fn appearance_starts_at_the_first_histogram_then_moves_part_of_the_way() {
        let mut t = track(None);
        assert!(t.appearance.is_empty());
        t.see_colours(&[1.0, 0.0]);
        assert_eq!(t.appearance, vec![1.0, 0.0]);
        t.see_colours(&[0.0, 1.0]);
        assert!(
            (t.appearance[0] - (1.0 - APPEARANCE_RATE)).abs() < 1e-6,
            "{:?}",
            t.appearance
        );
        assert!((t.appearance[1] - APPEARANCE_RATE).abs() < 1e-6);
    }

    #[test]
    fn a_tentative_track_takes_no_rssi_until_it_is_confirmed() {
        let mut t = track(None);
        assert!(!t.hear(1, -60.0, 0.0));
        assert!(
            t.rssi.is_empty() && !t.rssi_heard[1],
            "nothing queued or remembered"
        );
        t.confirm();
        assert!(t.hear(1, -60.0, 0.0));
        assert_eq!(t.rssi, vec![(1, -60.0, 0.0)]);
        assert!(t.rssi_heard[1]);
        // A handed-over track is confirmed from the start.
        assert!(track(Some(TargetId(7))).hear(0, -60.0, 0.0));
    }
}
