//! One entry of the server's recording: a message it received or sent, a tick that changed its
//! state, a decision, or the scenario it ran. Each entry is stamped with the server's cluster
//! time.
//!
//! Payload layout (inside the recording's length + CRC framing, see [`crate::recording`]):
//! `u8 kind | i64 LE at | body`, where the body is the scenario's TOML text, an encoded
//! envelope (`proto::wire::encode`), `u32 LE destination` + encoded envelope, nothing, a
//! decision as JSON, `u32 LE node` + `u8 up` for a link event, or a postcard-encoded
//! [`MeasuredFrame`] (a logging run's camera measurement, written by the simulation or mapped
//! from a camera process's `Message::MeasuredFrame`; kind 6, added later: recordings
//! without it read as before), or the run's [`Origin`] (`i64 LE t0 | u8 simulated`; kind 7,
//! added later still).

use crate::decision::Decision;
use proto::{ClusterTime, Envelope, NodeId, WireError};
use thiserror::Error;

/// What a recorded entry holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Record {
    /// The scenario the server ran, as TOML; the first entry of a new recording.
    Scenario(String),
    /// A frame the server received and decoded.
    Received(Envelope),
    /// A frame the server sent to `to`.
    Sent { to: NodeId, env: Envelope },
    /// A tick that changed the server's state (replaying it reproduces the change).
    Tick,
    /// A decision.
    Decision(Decision),
    /// The transport reported a link to `node` up or down.
    Link { node: NodeId, up: bool },
    /// One camera frame of a logging run: everything the camera measured, whatever its mode,
    /// so the run can be processed again offline with another method and policy.
    Measured(MeasuredFrame),
    /// Where the run's scenario clock starts and whether its world was simulated: written once,
    /// right after the scenario, by whoever starts a recording that knows it (`ocelli sim`,
    /// `ocelli launch`), so a report scores against truth only when there is truth.
    Origin(Origin),
}

/// The time origin of a run and whether it has a truth to score against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Origin {
    /// Cluster time of scenario time 0 (where the scenario's target trajectories start).
    pub t0: ClusterTime,
    /// The cameras sensed the simulated world, so the scenario's targets are the truth. A real
    /// deployment records `false`: nothing there knows where a target truly was.
    pub simulated: bool,
}

/// What one camera measured in one frame (paper 002 logged every camera's measurements once
/// and processed them offline with each method).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeasuredFrame {
    pub camera: NodeId,
    /// Capture time, the camera's cluster time.
    pub captured: ClusterTime,
    /// The tag readings the camera's radio received since its previous frame.
    pub rssi: Vec<proto::msg::RssiReading>,
    pub detections: Vec<MeasuredDetection>,
}

/// One undistorted detection of a [`MeasuredFrame`]: the camera's wire form, recorded as it
/// arrived (the sim records through the same form), so the replay gets back the numbers the
/// camera computed, bit for bit.
pub use proto::msg::MeasuredDetection;

impl MeasuredFrame {
    /// The record of a camera's `proto::msg::MeasuredFrame` (a logging run over real
    /// processes, or the sim's through the camera's wire form).
    pub fn from_wire(camera: NodeId, m: &proto::msg::MeasuredFrame) -> MeasuredFrame {
        MeasuredFrame {
            camera,
            captured: m.captured,
            rssi: m.rssi.clone(),
            detections: m.detections.clone(),
        }
    }

    /// Why the frame cannot be used, if it cannot: a non-finite number or a negative variance.
    pub fn problem(&self) -> Option<String> {
        if let Some(r) = self.rssi.iter().find(|r| !r.dbm.is_finite()) {
            return Some(format!(
                "camera {}: RSSI of tag {} is not finite",
                self.camera, r.tag
            ));
        }
        self.detections.iter().enumerate().find_map(|(i, d)| {
            let finite = d.point.iter().chain(&d.cov).all(|x| x.is_finite());
            (!finite || d.cov[0] < 0.0 || d.cov[2] < 0.0).then(|| {
                format!(
                    "camera {} detection {i}: point {:?} / covariance {:?} is not a finite \
                     symmetric covariance",
                    self.camera, d.point, d.cov
                )
            })
        })
    }
}

/// A record with the server's cluster time when it was made.
#[derive(Clone, Debug, PartialEq)]
pub struct Stamped {
    pub at: ClusterTime,
    pub record: Record,
}

impl Stamped {
    pub fn new(at: ClusterTime, record: Record) -> Self {
        Stamped { at, record }
    }
}

const KIND_SCENARIO: u8 = 0;
const KIND_RECEIVED: u8 = 1;
const KIND_SENT: u8 = 2;
const KIND_TICK: u8 = 3;
const KIND_DECISION: u8 = 4;
const KIND_LINK: u8 = 5;
const KIND_MEASURED: u8 = 6;
const KIND_ORIGIN: u8 = 7;

/// A record payload that could not be encoded or decoded.
#[derive(Debug, Error)]
pub enum RecordError {
    #[error("record payload of {0} bytes is shorter than its 9-byte header")]
    Short(usize),
    #[error("unknown record kind {0}")]
    UnknownKind(u8),
    #[error("recorded envelope: {0}")]
    Wire(#[from] WireError),
    #[error("recorded decision: {0}")]
    Json(#[from] serde_json::Error),
    #[error("recorded scenario is not UTF-8")]
    Utf8,
    #[error("recorded measurement: {0}")]
    Measured(String),
}

impl Stamped {
    /// Encode into a payload.
    ///
    /// # Errors
    /// An envelope the wire encoding refuses (invalid or oversized).
    pub fn encode(&self) -> Result<Vec<u8>, RecordError> {
        let mut out = Vec::with_capacity(64);
        let kind = match &self.record {
            Record::Scenario(_) => KIND_SCENARIO,
            Record::Received(_) => KIND_RECEIVED,
            Record::Sent { .. } => KIND_SENT,
            Record::Tick => KIND_TICK,
            Record::Decision(_) => KIND_DECISION,
            Record::Link { .. } => KIND_LINK,
            Record::Measured(_) => KIND_MEASURED,
            Record::Origin(_) => KIND_ORIGIN,
        };
        out.push(kind);
        out.extend_from_slice(&self.at.0.to_le_bytes());
        match &self.record {
            Record::Scenario(toml) => out.extend_from_slice(toml.as_bytes()),
            Record::Received(env) => out.extend_from_slice(&proto::encode(env)?),
            Record::Sent { to, env } => {
                out.extend_from_slice(&to.0.to_le_bytes());
                out.extend_from_slice(&proto::encode(env)?);
            }
            Record::Tick => {}
            Record::Decision(d) => out.extend_from_slice(&serde_json::to_vec(d)?),
            Record::Link { node, up } => {
                out.extend_from_slice(&node.0.to_le_bytes());
                out.push(u8::from(*up));
            }
            Record::Measured(m) => {
                if let Some(p) = m.problem() {
                    return Err(RecordError::Measured(p));
                }
                out = postcard::to_extend(m, out).map_err(|e| RecordError::Measured(e.to_string()))?;
            }
            Record::Origin(o) => {
                out.extend_from_slice(&o.t0.0.to_le_bytes());
                out.push(u8::from(o.simulated));
            }
        }
        Ok(out)
    }

    /// Decode a payload.
    ///
    /// # Errors
    /// A short payload, an unknown kind, or a body that does not decode.
    pub fn decode(payload: &[u8]) -> Result<Stamped, RecordError> {
        if payload.len() < 9 {
            return Err(RecordError::Short(payload.len()));
        }
        let kind = payload[0];
        let mut at = [0u8; 8];
        at.copy_from_slice(&payload[1..9]);
        let at = ClusterTime(i64::from_le_bytes(at));
        let body = &payload[9..];
        let record = match kind {
            KIND_SCENARIO => {
                Record::Scenario(String::from_utf8(body.to_vec()).map_err(|_| RecordError::Utf8)?)
            }
            KIND_RECEIVED => Record::Received(proto::decode(body)?),
            KIND_SENT => {
                if body.len() < 4 {
                    return Err(RecordError::Short(payload.len()));
                }
                let to = NodeId(u32::from_le_bytes([body[0], body[1], body[2], body[3]]));
                Record::Sent {
                    to,
                    env: proto::decode(&body[4..])?,
                }
            }
            KIND_TICK => Record::Tick,
            KIND_DECISION => Record::Decision(serde_json::from_slice(body)?),
            KIND_LINK => {
                if body.len() != 5 {
                    return Err(RecordError::Short(payload.len()));
                }
                Record::Link {
                    node: NodeId(u32::from_le_bytes([body[0], body[1], body[2], body[3]])),
                    up: body[4] != 0,
                }
            }
            KIND_MEASURED => {
                let m: MeasuredFrame =
                    postcard::from_bytes(body).map_err(|e| RecordError::Measured(e.to_string()))?;
                if let Some(p) = m.problem() {
                    return Err(RecordError::Measured(p));
                }
                Record::Measured(m)
            }
            KIND_ORIGIN => {
                let Ok(bytes) = <[u8; 9]>::try_from(body) else {
                    return Err(RecordError::Short(payload.len()));
                };
                let mut t0 = [0u8; 8];
                t0.copy_from_slice(&bytes[..8]);
                Record::Origin(Origin {
                    t0: ClusterTime(i64::from_le_bytes(t0)),
                    simulated: bytes[8] != 0,
                })
            }
            k => return Err(RecordError::UnknownKind(k)),
        };
        Ok(Stamped { at, record })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::msg::{Message, SyncBeacon};

    fn env() -> Envelope {
        Envelope {
            source: NodeId(1),
            seq: 9,
            time: ClusterTime(5),
            body: Message::SyncBeacon(SyncBeacon {
                leader: NodeId(1),
                round: 2,
                leader_time: ClusterTime(5),
            }),
        }
    }

    #[test]
    fn every_kind_round_trips() {
        let all = [
            Record::Scenario("name = \"x\"".into()),
            Record::Received(env()),
            Record::Sent {
                to: NodeId(4),
                env: env(),
            },
            Record::Tick,
            Record::Decision(Decision::Up { node: NodeId(3) }),
            Record::Link {
                node: NodeId(7),
                up: false,
            },
            Record::Measured(frame()),
            Record::Measured(MeasuredFrame {
                detections: Vec::new(),
                rssi: Vec::new(),
                ..frame()
            }),
            Record::Origin(Origin {
                t0: ClusterTime(1_700_000_000_123_456_789),
                simulated: true,
            }),
            Record::Origin(Origin {
                t0: ClusterTime(0),
                simulated: false,
            }),
        ];
        for r in all {
            let s = Stamped::new(ClusterTime(-17), r);
            assert_eq!(Stamped::decode(&s.encode().unwrap()).unwrap(), s);
        }
    }

    fn frame() -> MeasuredFrame {
        MeasuredFrame {
            camera: NodeId(12),
            captured: ClusterTime(1_234_567_891),
            rssi: vec![proto::msg::RssiReading {
                tag: proto::TagId(0x0200_0000_0001),
                dbm: -61.25,
                time: ClusterTime(1_234_500_000),
            }],
            detections: vec![MeasuredDetection {
                centre: [320.5, 240.25],
                foot: [320.5, 300.0],
                pixel_box: proto::msg::PixelBox {
                    xmin: 300.0,
                    ymin: 200.0,
                    xmax: 340.0,
                    ymax: 300.0,
                },
                area: 3200,
                colour: proto::msg::ColourSignature {
                    hue: 1.0,
                    saturation: 0.5,
                    intensity: 0.25,
                },
                point: [0.1 + 0.2, -1.0 / 3.0],
                cov: [1e-6 / 3.0, 1e-9, 2e-6 / 7.0],
            }],
        }
    }

    /// A camera's wire frame becomes a record with the same numbers, and survives the recording.
    #[test]
    fn a_wire_frame_maps_to_the_same_record() {
        let want = frame();
        let wire = proto::msg::MeasuredFrame {
            captured: want.captured,
            rssi: want.rssi.clone(),
            detections: want.detections.clone(),
        };
        let got = MeasuredFrame::from_wire(want.camera, &wire);
        assert_eq!(got, want);
        let s = Stamped::new(ClusterTime(3), Record::Measured(got));
        assert_eq!(Stamped::decode(&s.encode().unwrap()).unwrap(), s);
    }

    #[test]
    fn bad_measured_frames_are_refused_both_ways() {
        let mut bad = frame();
        bad.detections[0].point[1] = f64::NAN;
        let s = Stamped::new(ClusterTime(0), Record::Measured(bad.clone()));
        assert!(matches!(s.encode(), Err(RecordError::Measured(_))));
        let mut p = vec![KIND_MEASURED];
        p.extend_from_slice(&[0; 8]);
        p.extend_from_slice(&postcard::to_stdvec(&bad).unwrap());
        let e = Stamped::decode(&p).unwrap_err().to_string();
        assert!(e.contains("camera n12 detection 0"), "{e}");
        let mut p = vec![KIND_MEASURED];
        p.extend_from_slice(&[0; 8]);
        p.extend_from_slice(&[1, 2, 3]);
        assert!(matches!(Stamped::decode(&p), Err(RecordError::Measured(_))));
    }

    #[test]
    fn bad_payloads_are_errors() {
        assert!(matches!(Stamped::decode(&[1, 2]), Err(RecordError::Short(2))));
        let mut p = vec![99];
        p.extend_from_slice(&[0; 8]);
        assert!(matches!(Stamped::decode(&p), Err(RecordError::UnknownKind(99))));
        let mut p = vec![KIND_RECEIVED];
        p.extend_from_slice(&[0; 8]);
        p.extend_from_slice(&[1, 2, 3]);
        assert!(matches!(Stamped::decode(&p), Err(RecordError::Wire(_))));
    }
}
