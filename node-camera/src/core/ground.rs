//! The camera core in paper 004's mode (`camera-tracker = "particle"`): frames go through the
//! segmentation (regions and foreground mask) into the per-person particle filters, and people
//! leave as ground-plane observations ([`crate::ground_people`]) — the same split as the
//! pin-hole points: gated to a prior they go in the contribution to that prior in the node's
//! `Answers` (distributed; the person itself, which the head folds in: its model is linear) or
//! are sent naming it
//! (centralized); ungated ones are sent without a target so heads can start tracks. What is
//! sent goes in one `PeopleFrame` per head step.

use super::CameraNode;
use crate::ground_people;
use crate::segment::Segmenter;
use crate::tracker::manager::Foreground;
use proto::msg::{Message, Prior, SampleRequest};
use proto::node::Outgoing;
use proto::observation::GroundPoint;
use proto::sensor::{Detection, Frame};
use proto::{ClusterTime, NodeId, TargetId};

impl CameraNode {
    /// Whether the camera runs paper 004's particle filters.
    pub fn tracks_people(&self) -> bool {
        self.people.is_some()
    }

    /// The newest frame's people on the ground (empty unless [`Self::tracks_people`]).
    pub fn latest_people(&self) -> &[proto::observation::GroundPoint] {
        self.people.as_ref().map_or(&[], |p| p.latest())
    }

    /// A segmented frame's regions through the particle filters; the people are sent.
    pub(super) fn ground_frame(
        &mut self,
        now: ClusterTime,
        frame: &Frame,
        regions: &[Detection],
    ) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let Some(people) = self.people.as_mut() else {
            return out;
        };
        let foreground = match &self.segmenter {
            Segmenter::AdaptiveBackground(seg) => Foreground::of(seg),
            Segmenter::ColourDifference(_) => None,
        };
        let tracked = people
            .track(&self.cfg.camera, frame, regions, foreground)
            .map(|_| ());
        // The people standing still stay in the foreground at the next frame (`hold-still-s`;
        // none by default), and none after a frame the filters refused.
        if let Segmenter::AdaptiveBackground(seg) = &mut self.segmenter {
            seg.hold(if tracked.is_ok() { people.held() } else { &[] });
        }
        if let Err(e) = tracked {
            self.reject("frame", e.to_string());
            return out;
        }
        self.counters.frames += 1;
        self.counters.detections += regions.len() as u64;
        self.captured = Some(frame.captured);
        self.forget_stale(now);
        self.send_people(now, frame.captured, &mut out);
        out
    }

    /// The measurement-level simulation's boxes straight to the ground plane.
    pub(super) fn ground_boxes(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
    ) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let Some(people) = self.people.as_mut() else {
            return out;
        };
        people.from_boxes(&self.cfg.camera, detections, captured);
        self.counters.frames += 1;
        self.counters.detections += detections.len() as u64;
        self.captured = Some(captured);
        self.forget_stale(now);
        self.send_people(now, captured, &mut out);
        out
    }

    /// Gate the newest people against the known priors and send what the mode asks for, in
    /// one `PeopleFrame`, if this frame is the step's (see [`ground_people::PeopleSender`]).
    fn send_people(&mut self, now: ClusterTime, captured: ClusterTime, out: &mut Vec<Outgoing>) {
        let Some(people) = self.people.as_ref() else {
            return;
        };
        self.people_out.retain(&people.tracker().ids());
        if !self.people_out.due(captured) {
            return;
        }
        let priors: Vec<(&Prior, f64)> = self
            .priors
            .values()
            .filter(|(t, _)| self.fresh(captured, *t))
            .map(|(t, p)| (p, t.secs_since(captured)))
            .collect();
        let assoc = ground_people::associate(&priors, people.latest(), self.cfg.gate_chi2);
        let centralized = !self.cfg.fusion.distributed();
        let chosen: Vec<(&GroundPoint, Option<TargetId>)> = people
            .latest()
            .iter()
            .zip(assoc)
            .map(|(g, a)| (g, a.map(|i| priors[i].0.target)))
            .filter(|(_, target)| centralized || target.is_none())
            .collect();
        if chosen.is_empty() {
            return;
        }
        // Tag readings go with people gated to a track, as they go with a contribution.
        let rssi = if chosen.iter().any(|(_, t)| t.is_some()) {
            self.fresh_tags(now)
        } else {
            Vec::new()
        };
        let frame = self.people_out.frame(captured, self.mode, chosen, rssi);
        self.counters.people_unsendable = self.people_out.unsendable();
        if frame.people.is_empty() {
            return;
        }
        self.counters.measurements += 1;
        self.send_to_head(Message::PeopleFrame(frame), out);
    }

    /// A request for the filters' sample sets: one `SampleSet` per person to the asker (none
    /// when the camera tracks no one or runs no particle filters).
    pub(super) fn on_sample_request(&mut self, source: NodeId, req: &SampleRequest) -> Vec<Outgoing> {
        if req.node != self.cfg.id {
            self.reject("sample request", format!("addressed to {}", req.node));
            return Vec::new();
        }
        let Some(people) = self.people.as_ref() else {
            return Vec::new();
        };
        people
            .samples(req.local)
            .into_iter()
            .map(|s| Outgoing::new(source, Message::SampleSet(s)))
            .collect()
    }
}
