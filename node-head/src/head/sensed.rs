//! What the head's sensors did in a step besides the detections it associates: which cameras
//! reported processing a frame (`FrameReport`, grid fusion), and the ILD vectors of its
//! acoustic nodes. Kept until the step closes, handed to the fusion there, then cleared.

use super::HeadNode;
use crate::config::HeadConfig;
use crate::fusion::StepSensors;
use proto::acoustic::IldVector;
use proto::msg::FrameReport;
use proto::observation::Observation;
use proto::{ClusterTime, Message, Mode, NodeId};
use tracing::warn;

/// Most ILD vectors a head keeps per step; more are refused and counted.
pub const MAX_ILDS_PER_STEP: usize = 64;

/// The step's sensor activity.
#[derive(Clone, Debug)]
pub(super) struct Sensed {
    /// Acoustic nodes: id and whether it reports to this head.
    acoustic: Vec<(NodeId, bool)>,
    /// Per camera slot: reported a processed frame since the last close.
    looked: Vec<bool>,
    ilds: Vec<(usize, IldVector)>,
}

impl Sensed {
    pub fn new(cfg: &HeadConfig) -> Sensed {
        Sensed {
            acoustic: cfg.acoustic.iter().map(|a| (a.id, a.member)).collect(),
            looked: vec![false; cfg.nodes.len()],
            ilds: Vec::new(),
        }
    }

    /// The acoustic slot of `node`, if it is one of the scenario's acoustic nodes.
    pub fn acoustic_slot(&self, node: NodeId) -> Option<usize> {
        self.acoustic.iter().position(|(id, _)| *id == node)
    }

    /// The server moved `node` to this head (`mine`) or away.
    pub fn assign(&mut self, node: NodeId, mine: bool) {
        if let Some(a) = self.acoustic.iter_mut().find(|(id, _)| *id == node) {
            a.1 = mine;
        }
    }
}

impl HeadNode {
    /// A camera processed a frame.
    pub(super) fn on_frame_report(&mut self, slot: usize, r: &FrameReport) {
        self.counters.frame_reports += 1;
        self.nodes[slot].mode = r.mode;
        if let Some(l) = self.sensed.looked.get_mut(slot) {
            *l = true;
        }
    }

    /// A message from an acoustic node: its ILD vectors are kept for the step (fused by a
    /// method that can, counted otherwise); its status is noted; anything else is refused.
    pub(super) fn on_acoustic(&mut self, now: ClusterTime, slot: usize, body: Message) {
        let (id, member) = self.sensed.acoustic[slot];
        if !member {
            self.reject(now, id, "acoustic");
            return;
        }
        let observations = match body {
            Message::Measurement(m) => m.observations,
            Message::NodeStatus(_) | Message::Heartbeat => return,
            other => {
                self.reject(now, id, other.kind());
                return;
            }
        };
        let max_age_ns = self.cfg.method.capture_max_age_ms() as i64 * 1_000_000;
        for o in observations {
            let Observation::Acoustic(wire) = o else {
                self.counters.unfused_observations += 1;
                continue;
            };
            self.counters.ild_vectors += 1;
            if !self.fusion.fuses_acoustic() {
                self.counters.unfused_observations += 1;
                continue;
            }
            let refuse = |problem: String| {
                warn!(node = %id, problem, "ILD vector refused");
            };
            if (now - wire.captured).abs() > max_age_ns {
                self.counters.ild_refused += 1;
                self.counters.stale_measurements += 1;
                refuse(format!(
                    "captured {} ms from now",
                    (now - wire.captured) / 1_000_000
                ));
                continue;
            }
            if self.sensed.ilds.len() >= MAX_ILDS_PER_STEP {
                self.counters.ild_refused += 1;
                self.counters.overflow += 1;
                continue;
            }
            match IldVector::from_observation(&wire) {
                Ok(v) => self.sensed.ilds.push((slot, v)),
                Err(e) => {
                    self.counters.ild_refused += 1;
                    refuse(e.to_string());
                }
            }
        }
    }

    /// Hand the step's sensor activity to the fusion and start the next step's afresh.
    pub(super) fn hand_sensed_to_fusion(&mut self) {
        let modes: Vec<Mode> = self
            .nodes
            .iter()
            .map(|n| if n.member && n.up { n.mode } else { Mode::Inactive })
            .collect();
        self.fusion.sensed(&StepSensors {
            looked: &self.sensed.looked,
            modes: &modes,
            ilds: &self.sensed.ilds,
        });
        self.sensed.looked.fill(false);
        self.sensed.ilds.clear();
    }
}
