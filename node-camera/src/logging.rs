//! Logging runs in the camera process (`ocelli camera --record-measurements`): every captured
//! frame is segmented and undistorted whatever the node's mode, the frame's measurements go to
//! the server as a `proto::msg::MeasuredFrame` for its recording, and the core is fed the same
//! measurements through [`CameraNode::on_measured`] (used only while its camera is on), so
//! tracking is what it would have been. Paper 002 logged every measurement once this way and
//! processed the log offline with each method (`ocelli replay`).

use crate::config::CameraConfig;
use crate::core::CameraNode;
use crate::measure::{self, Measured};
use crate::segment::Segmenter;
use proto::msg::{MeasuredDetection, MeasuredFrame, Message};
use proto::node::Outgoing;
use proto::sensor::Detection;
use proto::sensor::{Frame, FrameError};
use proto::{ClusterTime, MAX_MEASURED_DETECTIONS};

/// What the logger did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LogCounters {
    /// Frames measured and addressed to the server.
    pub frames: u64,
    /// Frames the segmenter refused (wrong size, malformed); nothing was sent or fed.
    pub rejected: u64,
    /// Detections past [`MAX_MEASURED_DETECTIONS`] left out of a frame's message (the core
    /// still got them).
    pub truncated: u64,
    /// Detections that could not be undistorted.
    pub undistort_failures: u64,
    /// Frames with no server to send them to.
    pub unsent: u64,
}

/// A camera's own segmenter for logging runs: it measures every frame, whatever the mode.
#[derive(Debug)]
pub struct FrameLogger {
    segmenter: Segmenter,
    scratch: Vec<Detection>,
    measured: Vec<Measured>,
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

impl FrameLogger {
    pub fn new(cfg: &CameraConfig) -> FrameLogger {
        FrameLogger {
            segmenter: Segmenter::new(&cfg.segment),
            scratch: Vec::with_capacity(64),
            measured: Vec::with_capacity(64),
            counters: LogCounters::default(),
        }
    }

    pub fn counters(&self) -> LogCounters {
        self.counters
    }

    /// Measure `frame` whatever `node`'s mode: the `MeasuredFrame` for the server (with the
    /// tag's RSSI at capture time, if known) followed by what the core answers to the same
    /// measurements.
    ///
    /// # Errors
    /// A frame the segmenter refuses (another size than the camera's, malformed); it is
    /// counted and nothing is sent or fed.
    pub fn log(
        &mut self,
        node: &mut CameraNode,
        now: ClusterTime,
        frame: &Frame,
        rssi_dbm: Option<f64>,
    ) -> Result<Vec<Outgoing>, FrameError> {
        let (measured, answers) = self.measure(node, now, frame, rssi_dbm)?;
        let mut out = Vec::with_capacity(answers.len() + 1);
        match node.config().server {
            Some(s) => out.push(Outgoing::new(s, Message::MeasuredFrame(measured))),
            None => self.counters.unsent += 1,
        }
        out.extend(answers);
        Ok(out)
    }

    /// [`FrameLogger::log`] without the sending: the frame's `MeasuredFrame` and what the core
    /// answers. The simulation records the frame itself.
    ///
    /// # Errors
    /// As [`FrameLogger::log`].
    pub fn measure(
        &mut self,
        node: &mut CameraNode,
        now: ClusterTime,
        frame: &Frame,
        rssi_dbm: Option<f64>,
    ) -> Result<(MeasuredFrame, Vec<Outgoing>), FrameError> {
        let k = &node.config().camera.intrinsics;
        if (frame.width, frame.height) != (k.width, k.height) {
            self.counters.rejected += 1;
            return Err(FrameError::Mismatch {
                got_w: frame.width,
                got_h: frame.height,
                want_w: k.width,
                want_h: k.height,
            });
        }
        if let Err(e) = self.segmenter.process(frame, &mut self.scratch) {
            self.counters.rejected += 1;
            return Err(e);
        }
        let detections = std::mem::take(&mut self.scratch);
        let out = self.measure_detections(node, now, frame.captured, &detections, rssi_dbm, true);
        self.scratch = detections;
        Ok(out)
    }

    /// [`FrameLogger::measure`] for detections already made: `segmented` by this logger, or
    /// elsewhere (the measurement-level simulation projects the truth instead of rendering and
    /// segmenting), handled exactly as a segmented frame's otherwise.
    pub fn measure_detections(
        &mut self,
        node: &mut CameraNode,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
        rssi_dbm: Option<f64>,
        segmented: bool,
    ) -> (MeasuredFrame, Vec<Outgoing>) {
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
        let frame = MeasuredFrame {
            captured,
            rssi_dbm: rssi_dbm.filter(|d| d.is_finite() && (-200.0..=30.0).contains(d)),
            detections: self.measured[..kept].iter().map(to_wire).collect(),
        };
        (frame, node.on_measured(now, captured, &self.measured, segmented))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use proto::Mode;
    use proto::msg::Command;
    use proto::scenario::Scenario;

    fn camera(scenario: &Scenario) -> (u32, CameraNode, Renderer) {
        let id = scenario.cameras().next().expect("a camera").id;
        let node = CameraNode::new(
            CameraConfig::from_scenario(scenario, id).unwrap(),
            ClusterTime::ZERO,
        );
        (id, node, Renderer::for_node(scenario, id, 1).unwrap())
    }

    /// A frame that shows the target is measured and sent to the server whatever the mode;
    /// the core uses it only while its camera is on.
    #[test]
    fn every_frame_is_measured_and_sent_whatever_the_mode() {
        let scenario = Scenario::default_scenario();
        let (id, mut node, renderer) = camera(&scenario);
        let server = node.config().server.unwrap();
        let mut logger = FrameLogger::new(node.config());
        let k = node.config().camera.intrinsics;
        let mut frame = Frame::new(k.width, k.height, ClusterTime::ZERO);
        let mut seen = 0;
        for (i, mode) in [Mode::Active, Mode::Inactive, Mode::CameraOff, Mode::Active]
            .into_iter()
            .cycle()
            .take(40)
            .enumerate()
        {
            let now = ClusterTime::from_millis(200 * i as i64);
            node.on_message(
                now,
                proto::Envelope {
                    source: node.config().head.unwrap(),
                    seq: i as u64,
                    time: now,
                    body: Message::Command(Command {
                        node: proto::NodeId(id),
                        mode,
                    }),
                },
            );
            renderer.render(&scenario.targets, now.as_secs_f64(), now, &mut frame);
            let frames_before = node.counters().frames;
            let out = logger.log(&mut node, now, &frame, Some(-61.0)).unwrap();
            let Some(Message::MeasuredFrame(m)) = out.iter().find(|o| o.to == server).map(|o| &o.body) else {
                panic!("no measured frame for the server: {out:?}")
            };
            assert_eq!(m.captured, now);
            assert_eq!(m.rssi_dbm, Some(-61.0));
            assert!(proto::validate::Validate::validate(&out[0].body).is_ok());
            seen += usize::from(!m.detections.is_empty());
            assert_eq!(
                node.counters().frames - frames_before,
                u64::from(mode == Mode::Active)
            );
        }
        assert_eq!(logger.counters().frames, 40);
        assert!(seen > 0, "the target was never in view of camera {id}");
        // A frame of another size is refused and counted; nothing is sent.
        let small = Frame::new(8, 8, ClusterTime::ZERO);
        assert!(logger.log(&mut node, ClusterTime::ZERO, &small, None).is_err());
        assert_eq!(logger.counters().rejected, 1);
    }
}
