//! One simulated camera: its core and what it senses of the simulated world at each of its
//! frame times — a rendered frame (pixel level) or the truth projected plus noise (measurement
//! level), and one reading of every tag its radio hears — or, in a replay, its recorded frame.
//! Everything reaches the core as `CameraInput`s through `Node::handle`, as in a process.

use crate::faults::Faults;
use crate::logged::{self, Recorded};
use node_camera::core::{CameraInput, CameraNode};
use proto::node::{Input, Node, Outgoing};
use proto::scenario::Scenario;
use proto::sensor::{Frame, TagReading};
use proto::{ClusterTime, NodeId};
use rand_chacha::ChaCha8Rng;
use world::render::Renderer;
use world::sources::SyntheticRadio;
use world::{Target, project};

/// A camera node and its sensors.
pub(crate) struct CameraSlot {
    pub core: CameraNode,
    /// Pixel level: what renders its frames.
    pub renderer: Option<Renderer>,
    pub radio: SyntheticRadio,
    pub period_ns: i64,
    /// The camera as it truly is (differs from the node's under a yaw fault).
    pub true_camera: proto::camera::CameraModel,
}

/// The world's shared state a camera senses with.
pub(crate) struct Senses<'a> {
    pub scenario: &'a Scenario,
    pub targets: &'a [Target],
    pub faults: &'a Faults,
    /// Pixel noise of measurement-level detections.
    pub noise: &'a mut ChaCha8Rng,
    /// Frame failures (a stream of its own, so faults leave the noise stream as it was).
    pub failures: &'a mut ChaCha8Rng,
    /// A logging run: sense every frame whatever the mode.
    pub record_all: bool,
}

impl CameraSlot {
    /// Hand the core what the radio hears at true time `t_s` (stamped with the node's `now`).
    fn hear(&mut self, t_s: f64, now: ClusterTime) -> Vec<Outgoing> {
        let mut heard = Vec::new();
        self.radio.readings(t_s, now, &mut heard);
        self.tags(now, heard)
    }

    fn tags(&mut self, now: ClusterTime, heard: Vec<TagReading>) -> Vec<Outgoing> {
        let mut out = Vec::new();
        for r in heard {
            out.extend(self.core.handle(now, Input::Sensor(CameraInput::Tag(r))));
        }
        out
    }

    /// One frame time: the radio reads, and the camera senses if it is capturing (and no
    /// fault swallows the frame). Returns the core's messages and whether a frame was rendered.
    pub fn sense(&mut self, t_ns: i64, now: ClusterTime, w: &mut Senses<'_>) -> (Vec<Outgoing>, bool) {
        let t_s = t_ns as f64 * 1e-9;
        let mut out = if self.core.mode().radio_on() || w.record_all {
            self.hear(t_s, now)
        } else {
            Vec::new()
        };
        if !self.core.capturing() {
            return (out, false);
        }
        let id = self.core.id();
        if !w.record_all && (w.faults.blacked_out(id.0, t_s) || w.faults.frame_fails(w.failures)) {
            return (out, false);
        }
        let input = match &self.renderer {
            Some(r) => {
                let mut frame = Frame::new(0, 0, now);
                r.render(w.targets, t_s, now, &mut frame);
                CameraInput::Frame(frame)
            }
            None => CameraInput::Detections {
                captured: now,
                detections: project::project_truth(
                    &self.true_camera,
                    &w.scenario.world,
                    w.targets,
                    t_s,
                    w.faults.pixel_sigma(w.scenario.method.pixel_sigma),
                    w.noise,
                ),
            },
        };
        let rendered = matches!(input, CameraInput::Frame(_));
        out.extend(self.core.handle(now, Input::Sensor(input)));
        (out, rendered)
    }

    /// A replay: the camera's recorded frame that is due at `t_ns`, if any, with the tag
    /// readings recorded with it (re-stamped with the node's `now`, as its frame is).
    pub fn replay(
        &mut self,
        id: NodeId,
        t_ns: i64,
        now: ClusterTime,
        recorded: &mut Recorded,
        segmented: bool,
    ) -> Vec<Outgoing> {
        let Some(f) = recorded.take_due(id, t_ns) else {
            return Vec::new();
        };
        let heard = f
            .rssi
            .iter()
            .map(|r| TagReading {
                tag: r.tag,
                dbm: r.dbm,
                time: now,
            })
            .collect();
        let mut out = self.tags(now, heard);
        let measured = f.detections.iter().map(logged::from_record).collect();
        out.extend(self.core.handle(
            now,
            Input::Sensor(CameraInput::Measured {
                captured: now,
                measured,
                segmented,
            }),
        ));
        out
    }
}
