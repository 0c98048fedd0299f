//! Logging runs (`ocelli camera --record-measurements`, `ocelli sim --record-measurements`):
//! every captured frame is segmented and undistorted whatever the node's mode, the frame's
//! measurements and the tag readings heard since the previous frame go to the server as a
//! `proto::msg::MeasuredFrame` for its recording, and the core uses the same measurements as
//! it would its own (only while its camera is on), so tracking is what it would have been.
//! Paper 002 logged every measurement once this way and processed the log offline with each
//! method (`ocelli replay`).

use crate::config::CameraConfig;
use crate::core::CameraNode;
use crate::measure::{self, Measured};
use crate::segment::Segmenter;
use proto::msg::{MeasuredDetection, MeasuredFrame, Message};
use proto::node::Outgoing;
use proto::observation::{MAX_OBSERVATIONS, RssiReading};
use proto::sensor::{Detection, Frame};
use proto::{ClusterTime, MAX_MEASURED_DETECTIONS};
use tracing::warn;

/// What a logging run measured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LogCounters {
    /// Frames measured and addressed to the server.
    pub frames: u64,
    /// Frames the segmenter refused (wrong size, malformed); nothing was sent or fed.
    pub rejected: u64,
    /// Detections past [`MAX_MEASURED_DETECTIONS`] (and tag readings past
    /// [`MAX_OBSERVATIONS`]) left out of a frame's message (the core still got them).
    pub truncated: u64,
    /// Detections that could not be undistorted.
    pub undistort_failures: u64,
    /// Frames with no server to send them to.
    pub unsent: u64,
}

/// A camera's own measuring of every frame for a logging run, whatever the mode.
#[derive(Debug)]
pub struct RecordAll {
    segmenter: Segmenter,
    scratch: Vec<Detection>,
    measured: Vec<Measured>,
    heard: Vec<RssiReading>,
    counters: LogCounters,
}

/// The wire form of a measured detection (the covariance's upper triangle).
pub fn to_wire(m: &Measured) -> MeasuredDetection {
    let d = &m.detection;
    MeasuredDetection {
        centre: d.centre,
        foot: d.foot,
        pixel_box: d.bbox,
        area: d.area,
        colour: d.colour,
        point: [m.point.x, m.point.y],
        cov: [m.cov[(0, 0)], m.cov[(0, 1)], m.cov[(1, 1)]],
    }
}

impl RecordAll {
    pub fn new(cfg: &CameraConfig) -> RecordAll {
        RecordAll {
            segmenter: Segmenter::new(&cfg.segment),
            scratch: Vec::with_capacity(64),
            measured: Vec::with_capacity(64),
            heard: Vec::new(),
            counters: LogCounters::default(),
        }
    }

    pub fn counters(&self) -> LogCounters {
        self.counters
    }

    /// A tag reading for the next frame's record.
    pub(crate) fn heard(&mut self, r: RssiReading) {
        if self.heard.len() >= MAX_OBSERVATIONS {
            self.heard.remove(0);
            self.counters.truncated += 1;
        }
        self.heard.push(r);
    }

    /// Segment and measure `frame` whatever `node`'s mode: the `MeasuredFrame` for the server,
    /// followed by what the core answers to the same measurements. A frame of another size
    /// than the camera's, or malformed, is refused and counted; nothing is sent or fed.
    pub(crate) fn frame(&mut self, node: &mut CameraNode, now: ClusterTime, frame: &Frame) -> Vec<Outgoing> {
        let k = &node.config().camera.intrinsics;
        let refused = if (frame.width, frame.height) != (k.width, k.height) {
            Some(format!(
                "{}x{} frame, camera is {}x{}",
                frame.width, frame.height, k.width, k.height
            ))
        } else {
            self.segmenter
                .process(frame, &mut self.scratch)
                .err()
                .map(|e| e.to_string())
        };
        if let Some(problem) = refused {
            self.counters.rejected += 1;
            warn!(node = %node.config().id, %problem, "logging run: frame refused");
            return Vec::new();
        }
        let detections = std::mem::take(&mut self.scratch);
        let out = self.measure(node, now, frame.captured, &detections, true);
        self.scratch = detections;
        out
    }

    /// Detections already made (the measurement-level simulation projects the truth instead
    /// of rendering and segmenting), handled exactly as a segmented frame's otherwise.
    pub(crate) fn detections(
        &mut self,
        node: &mut CameraNode,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
    ) -> Vec<Outgoing> {
        self.measure(node, now, captured, detections, false)
    }

    fn measure(
        &mut self,
        node: &mut CameraNode,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
        segmented: bool,
    ) -> Vec<Outgoing> {
        let cfg = node.config();
        self.measured.clear();
        for d in detections {
            match measure::measure(&cfg.camera, d, cfg.reference, cfg.pixel_sigma) {
                Ok(m) => self.measured.push(m),
                Err(_) => self.counters.undistort_failures += 1,
            }
        }
        let kept = self.measured.len().min(MAX_MEASURED_DETECTIONS);
        self.counters.truncated += (self.measured.len() - kept) as u64;
        self.counters.frames += 1;
        let record = MeasuredFrame {
            captured,
            rssi: std::mem::take(&mut self.heard),
            detections: self.measured[..kept].iter().map(to_wire).collect(),
        };
        let mut out = Vec::new();
        match node.server() {
            Some(s) => out.push(Outgoing::new(s, Message::MeasuredFrame(record))),
            None => self.counters.unsent += 1,
        }
        out.extend(node.on_measured(now, captured, &self.measured, segmented));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::CameraInput;
    use proto::msg::Command;
    use proto::node::{Input, Node};
    use proto::scenario::Scenario;
    use proto::sensor::TagReading;
    use proto::{Mode, TagId};
    use world::render::Renderer;

    /// A frame that shows the target is measured and sent to the server whatever the mode,
    /// with the tag readings heard since the previous frame; the core uses it only while its
    /// camera is on.
    #[test]
    fn every_frame_is_measured_and_sent_whatever_the_mode() {
        let scenario = Scenario::default_scenario();
        let targets = world::targets(&scenario).unwrap();
        let id = scenario.cameras().next().expect("a camera").id;
        let mut cfg = CameraConfig::from_scenario(&scenario, id).unwrap();
        cfg.record_all = true;
        let mut node = CameraNode::new(cfg, ClusterTime::ZERO);
        let renderer = Renderer::for_node(&scenario, id, 1).unwrap();
        let server = node.config().server.unwrap();
        let k = node.config().camera.intrinsics;
        let mut seen = 0;
        for (i, mode) in [Mode::Active, Mode::Inactive, Mode::CameraOff, Mode::Active]
            .into_iter()
            .cycle()
            .take(40)
            .enumerate()
        {
            let now = ClusterTime::from_millis(200 * i as i64);
            node.handle(
                now,
                Input::Message(proto::Envelope {
                    source: node.config().head.unwrap(),
                    seq: i as u64,
                    time: now,
                    body: Message::Command(Command {
                        node: proto::NodeId(id),
                        mode,
                    }),
                }),
            );
            let tag = TagReading {
                tag: TagId::simulated(1),
                dbm: -61.0,
                time: now,
            };
            node.handle(now, Input::Sensor(CameraInput::Tag(tag)));
            let mut frame = Frame::new(k.width, k.height, ClusterTime::ZERO);
            renderer.render(&targets, now.as_secs_f64(), now, &mut frame);
            let frames_before = node.counters().frames;
            assert!(node.capturing(), "a logging run captures whatever the mode");
            let out = node.handle(now, Input::Sensor(CameraInput::Frame(frame)));
            let Some(Message::MeasuredFrame(m)) = out.iter().find(|o| o.to == server).map(|o| &o.body) else {
                panic!("no measured frame for the server: {out:?}")
            };
            assert_eq!(m.captured, now);
            assert_eq!(m.rssi.len(), 1, "the reading heard since the previous frame");
            assert_eq!((m.rssi[0].tag, m.rssi[0].dbm), (tag.tag, -61.0));
            assert!(proto::validate::Validate::validate(&out[0].body).is_ok());
            seen += usize::from(!m.detections.is_empty());
            assert_eq!(
                node.counters().frames - frames_before,
                u64::from(mode == Mode::Active)
            );
        }
        let counters = node.record_all().unwrap().counters();
        assert_eq!(counters.frames, 40);
        assert!(seen > 0, "the target was never in view of camera {id}");
        // A frame of another size is refused and counted; nothing is sent.
        let small = Frame::new(8, 8, ClusterTime::ZERO);
        assert!(
            node.handle(ClusterTime::ZERO, Input::Sensor(CameraInput::Frame(small)))
                .is_empty()
        );
        assert_eq!(node.record_all().unwrap().counters().rejected, 1);
    }
}
