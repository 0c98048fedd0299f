//! Logging runs and their replay: a recorded detection ([`node_server::MeasuredFrame`], written
//! through the camera's wire form) back as the camera core takes it, bit for bit, and the per-camera queues a replay
//! draws its frames from.

use node_camera::measure::Measured;
use node_server::{MeasuredDetection, MeasuredFrame};
use proto::sensor::Detection;
use proto::{ClusterTime, NodeId};
use std::collections::{BTreeMap, VecDeque};

/// A recorded detection as the camera core takes it.
pub fn from_record(d: &MeasuredDetection) -> Measured {
    Measured {
        detection: Detection {
            centre: d.centre,
            foot: d.foot,
            bbox: d.pixel_box,
            area: d.area,
            colour: d.colour,
        },
        point: nalgebra::Vector2::new(d.point[0], d.point[1]),
        cov: nalgebra::Matrix2::new(d.cov[0], d.cov[1], d.cov[1], d.cov[2]),
    }
}

/// Recorded frames per camera, in recording order, each with its simulation time (ns since
/// scenario time 0).
#[derive(Debug, Default)]
pub struct Recorded {
    frames: BTreeMap<NodeId, VecDeque<(i64, MeasuredFrame)>>,
    /// Frames passed over because a newer one was due at the same frame event.
    pub superseded: u64,
}

impl Recorded {
    /// Queue `frames` (recorded at `at`); `t0` is the cluster time of scenario time 0.
    pub fn new<'a>(
        frames: impl IntoIterator<Item = (ClusterTime, &'a MeasuredFrame)>,
        t0: ClusterTime,
    ) -> Self {
        let mut out = Recorded::default();
        for (at, f) in frames {
            out.frames
                .entry(f.camera)
                .or_default()
                .push_back((at.0 - t0.0, f.clone()));
        }
        out
    }

    /// Cameras with recorded frames.
    pub fn cameras(&self) -> impl Iterator<Item = NodeId> + '_ {
        self.frames.keys().copied()
    }

    /// Time of the last recorded frame, ns.
    pub fn last_ns(&self) -> Option<i64> {
        self.frames.values().filter_map(|q| q.back().map(|f| f.0)).max()
    }

    /// The newest frame of `camera` recorded at or before `t`, dropping older ones.
    pub fn take_due(&mut self, camera: NodeId, t: i64) -> Option<MeasuredFrame> {
        let q = self.frames.get_mut(&camera)?;
        let mut due = None;
        while q.front().is_some_and(|f| f.0 <= t) {
            if due.is_some() {
                self.superseded += 1;
            }
            due = q.pop_front().map(|f| f.1);
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_measured_detection_survives_the_record_bit_for_bit() {
        let m = Measured {
            detection: Detection {
                centre: [1.5, 2.25],
                foot: [1.5, 9.0],
                bbox: proto::msg::PixelBox {
                    xmin: 0.0,
                    ymin: 1.0,
                    xmax: 3.0,
                    ymax: 9.0,
                },
                area: 17,
                colour: proto::msg::ColourSignature {
                    hue: 0.3,
                    saturation: 0.2,
                    intensity: 0.1,
                },
            },
            point: nalgebra::Vector2::new(0.1 + 0.2, -1.0 / 3.0),
            cov: nalgebra::Matrix2::new(1e-6 / 3.0, 1e-9, 1e-9, 2e-6 / 7.0),
        };
        let wire = proto::msg::MeasuredFrame {
            captured: ClusterTime(5),
            rssi: Vec::new(),
            detections: vec![node_camera::record_all::to_wire(&m)],
        };
        let recorded = MeasuredFrame::from_wire(NodeId(3), &wire);
        assert_eq!(from_record(&recorded.detections[0]), m);
    }

    #[test]
    fn frames_are_taken_per_camera_when_due() {
        let f = |camera, captured| MeasuredFrame {
            camera: NodeId(camera),
            captured: ClusterTime(captured),
            rssi: Vec::new(),
            detections: Vec::new(),
        };
        let frames = [(100, f(1, 1)), (200, f(1, 2)), (150, f(2, 3)), (300, f(1, 4))];
        let mut r = Recorded::new(
            frames.iter().map(|(at, f)| (ClusterTime(*at + 50), f)),
            ClusterTime(50),
        );
        assert_eq!(r.last_ns(), Some(300));
        assert_eq!(r.take_due(NodeId(1), 99), None);
        assert_eq!(
            r.take_due(NodeId(1), 250).map(|f| f.captured),
            Some(ClusterTime(2))
        );
        assert_eq!(r.superseded, 1);
        assert_eq!(
            r.take_due(NodeId(2), 150).map(|f| f.captured),
            Some(ClusterTime(3))
        );
        assert_eq!(r.take_due(NodeId(3), 1000), None);
    }
}
