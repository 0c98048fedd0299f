//! Every message Ocelli nodes exchange, grouped by direction.
//!
//! postcard is positional: the order of fields and variants below *is* the protocol. Append
//! new variants at the end and bump [`crate::PROTOCOL_VERSION`] on any other change; the golden
//! byte vectors in `wire`'s tests pin the current layout.

use crate::ids::{NodeId, Role, TagId, TargetId};
pub use crate::observation::{GroundPerson, Kinds, Observation, ObservationKind, RssiReading};
use crate::time::ClusterTime;
pub use crate::view::{ViewSubscribe, ViewUpdate};
use serde::{Deserialize, Serialize};

/// 6×6 matrix, row-major (information matrices, covariances of the state).
pub type Mat6 = [[f64; 6]; 6];
/// State-sized vector `[X Y Z Vx Vy Vz]`.
pub type Vec6 = [f64; 6];

/// Frame header + body. Every frame on every transport is one encoded `Envelope`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    /// The node that sent the frame.
    pub source: NodeId,
    /// Per-sender sequence number, +1 for every frame the sender emits on a link.
    pub seq: u64,
    /// Sender's cluster time when the frame was created.
    pub time: ClusterTime,
    pub body: Message,
}

/// Sensing mode of a camera node (paper 002 Fig. 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Mode {
    /// Camera and radio on: pixel measurements and RSSI.
    Active,
    /// Camera off, radio on: RSSI only, no capture, no segmentation.
    CameraOff,
    /// Low-power: nothing measured.
    Inactive,
}

impl Mode {
    pub const ALL: [Mode; 3] = [Mode::Active, Mode::CameraOff, Mode::Inactive];

    pub fn index(self) -> usize {
        match self {
            Mode::Active => 0,
            Mode::CameraOff => 1,
            Mode::Inactive => 2,
        }
    }

    pub fn camera_on(self) -> bool {
        self == Mode::Active
    }

    pub fn radio_on(self) -> bool {
        self != Mode::Inactive
    }
}

/// Axis-aligned pixel box `[xmin, ymin, xmax, ymax]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PixelBox {
    pub xmin: f32,
    pub ymin: f32,
    pub xmax: f32,
    pub ymax: f32,
}

/// Camera pose as sent in measurement packets (paper 000 §6.1.2): world → camera rotation as a
/// Rodrigues vector and translation, so `X_cam = R(rvec) · X_world + tvec`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWire {
    pub rvec: [f64; 3],
    pub tvec: [f64; 3],
}

/// A detection's colour signature: mean hue (rad), saturation and intensity in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ColourSignature {
    pub hue: f32,
    pub saturation: f32,
    pub intensity: f32,
}

// ---------------------------------------------------------------- camera → head

/// Observations the head models itself (paper 000's centralized mode, and detections no prior
/// gated, from which heads start tracks): one region's pin-hole point and the tag readings of
/// the same frame, or any other kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// Target the camera gated these observations to, or `None` when they matched no prior.
    pub target: Option<TargetId>,
    /// Filter step of the prior it was gated against (0 when none).
    pub step: u64,
    pub pose: PoseWire,
    pub mode: Mode,
    /// At most [`crate::observation::MAX_OBSERVATIONS`].
    pub observations: Vec<Observation>,
}

impl Measurement {
    /// The pin-hole point among the observations, if any (the first).
    pub fn pinhole(&self) -> Option<&crate::observation::PinholePoint> {
        self.observations.iter().find_map(|o| match o {
            Observation::Pinhole(p) => Some(p),
            _ => None,
        })
    }

    /// The tag readings among the observations.
    pub fn rssi(&self) -> impl Iterator<Item = &RssiReading> {
        self.observations.iter().filter_map(|o| match o {
            Observation::Rssi(r) => Some(r),
            _ => None,
        })
    }
}

/// Most tracks one [`Priors`] carries, and so most contributions one [`Answers`] carries: a
/// prior encodes to about 350 bytes, so 32 stay well inside [`crate::MAX_FRAME_BYTES`]. A head
/// with more tracks sends its step's priors in parts.
pub const MAX_PRIORS: usize = 32;

/// Most parts one step's priors come in: 128 × [`MAX_PRIORS`] = 4096 tracks in one cluster.
pub const MAX_PRIOR_PARTS: u16 = 128;

/// A node's answer to one [`Priors`] (paper 002 §III): its information contributions to the
/// part's tracks, one message per node per step and part, whatever the number of tracks. A
/// track of the part it does not list gets nothing from the node (Ω_i = 0, ξ_i = 0); the
/// message still tells the head that the node answered it, so the step can close early.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Answers {
    pub step: u64,
    /// The [`Priors::part`] answered.
    pub part: u16,
    /// When the frame the contributions come from was captured (the node's newest fresh
    /// frame), or the answer's time when there is none.
    pub captured: ClusterTime,
    pub mode: Mode,
    /// The node's fresh tag readings, raw (the head models them itself and binds each tag to
    /// one track), at most [`crate::observation::MAX_OBSERVATIONS`].
    pub rssi: Vec<RssiReading>,
    /// The part's tracks the node has something for, each at most once, at most
    /// [`MAX_PRIORS`]; each brings exactly one of information and a ground-plane person.
    pub contributions: Vec<Contribution>,
}

/// A node's information contribution to one track of a distributed EIF step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contribution {
    pub target: TargetId,
    /// Ω_i, ξ_i of what the node folded in, linearized at the track's prior.
    pub info: Option<Information>,
    /// The kinds of observation the node folded into `info`.
    pub folded: Kinds,
    /// A ground-plane person the node gated to the prior, captured at the answer's
    /// `captured`, for the head to model (its model is linear, so the head gets the same Ω_i,
    /// ξ_i from it, exactly but for the quantisation, from a twentieth of the bytes).
    pub ground: Option<GroundPerson>,
}

/// Ω_i = Hᵀ Q⁻¹ H, symmetric positive semi-definite, and ξ_i = Hᵀ Q⁻¹ (z − h(μ̄) + H μ̄), with
/// H and h taken where μ̄ puts the target at the frame's capture time
/// (`models::camera_contribution_aged`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Information {
    pub matrix: Mat6,
    pub vector: Vec6,
}

impl Contribution {
    /// Whether it brings camera information: folded in, or a ground-plane person.
    pub fn camera(&self) -> bool {
        self.folded.camera() || self.ground.is_some()
    }
}

/// Camera node health and energy accounting, sent periodically to its head and the server.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeStatus {
    pub mode: Mode,
    /// Cumulative nanoseconds spent in Active, CameraOff, Inactive.
    pub time_in_mode_ns: [u64; 3],
    pub frames: u64,
    pub detections: u64,
    /// Messages this node could not deliver (queue full, link down).
    pub dropped: u64,
    /// Frames it received and rejected.
    pub rejected: u64,
    /// Estimated offset to the leader's clock, ns, and the residual of the fit, ns.
    pub sync_offset_ns: i64,
    pub sync_error_ns: i64,
    /// Bytes this node put on the wire so far: the encoded frames its transport took. Only
    /// the runtime knows it, so the runtime fills it in as the status goes out (a core
    /// leaves 0).
    pub bytes_sent: u64,
}

/// What a camera in grid mode (`[method] fusion = "grid"`) says after every frame it
/// processed, detections or not: that it looked, so the head can use its silence (paper 001's
/// no-detection likelihood). Its detections travel as `Measurement`s before it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// When the frame was captured, the camera's cluster time.
    pub captured: ClusterTime,
    pub mode: Mode,
    /// Detections the frame had (each sent as a `Measurement`).
    pub detections: u32,
}

/// Every person a camera's particle filters track in one frame (paper 004's mode, `[method]
/// camera-tracker = "particle"`), in one message: the capture time, the mode and the tag
/// readings once, then each person quantised ([`GroundPerson`]). No camera pose: the positions
/// are already on the world's floor, and heads take each camera's geometry from the scenario.
/// A camera sends at most one per head step (`[method] step-ms`), the newest frame's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PeopleFrame {
    /// When the frame was captured, the camera's cluster time.
    pub captured: ClusterTime,
    pub mode: Mode,
    /// The node's fresh tag readings when a person is gated to a prior (they go with the
    /// people gated to a track, as they go with a contribution); at most
    /// [`crate::observation::MAX_OBSERVATIONS`].
    pub rssi: Vec<RssiReading>,
    /// At most [`crate::observation::MAX_OBSERVATIONS`], each `local` once.
    pub people: Vec<GroundPerson>,
}

// ---------------------------------------------------------------- head → camera

/// The predicted state of one track at the start of a step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prior {
    pub target: TargetId,
    pub step: u64,
    /// μ̄, the predicted mean; cameras linearize at it.
    pub mean: Vec6,
    /// Σ̄, the predicted covariance; cameras gate with it.
    pub cov: Mat6,
    /// Contributions arriving after this cluster time are late.
    pub deadline: ClusterTime,
    /// A radio track: a tag no camera sees, placed by RSSI alone (`node_head::unseen`). Its
    /// covariance is as wide as the fix, so a camera pairs no region with it (it would take
    /// whoever walks by); the node answers it with its tag readings only.
    pub radio: bool,
}

/// A step's priors, broadcast to every node at the start of the step: one message per node
/// with every track (in parts of at most [`MAX_PRIORS`] when there are more), so that a node
/// answers them all at once and jointly ([`Answers`]). Every prior of it has the same step and
/// deadline, and names a different track.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Priors {
    /// Which part of the step's priors this is, from 0, of `parts`.
    pub part: u16,
    /// How many parts the step's priors come in (1 up to [`MAX_PRIOR_PARTS`]): a node that has
    /// every part of a step knows every track of it, and with one part, this message alone.
    pub parts: u16,
    pub tracks: Vec<Prior>,
}

/// Switch a node's sensing mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Command {
    pub node: NodeId,
    pub mode: Mode,
}

// ---------------------------------------------------------------- head → server

/// One node's share in a step: the kinds of observation of it that were fused.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contributor {
    pub node: NodeId,
    pub kinds: Kinds,
}

impl Contributor {
    /// Whether a camera observation of this node was fused.
    pub fn camera(&self) -> bool {
        self.kinds.camera()
    }

    /// Whether a tag reading of this node was fused.
    pub fn rssi(&self) -> bool {
        self.kinds.contains(ObservationKind::Rssi)
    }
}

/// The posterior of one track after a step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackReport {
    pub target: TargetId,
    /// Global id, once the server gave one.
    pub global: Option<TargetId>,
    pub step: u64,
    pub time: ClusterTime,
    pub mean: Vec6,
    pub cov: Mat6,
    pub contributors: Vec<Contributor>,
    /// The cluster's power draw this step with the scenario's power figures, mW.
    pub power_mw: f64,
    /// Nodes' answers that arrived after the deadline of their step, cumulative.
    pub late: u64,
    /// The track's colour histogram (paper 004's HS 10×10 then V 10 bins, summing to 1), from
    /// the ground-plane observations fused into it, for identity at the server; empty when no
    /// camera sent one.
    pub appearance: Vec<f32>,
    /// The grid estimator's posterior, down-sampled (`[method] fusion = "grid"` only).
    pub grid: Option<GridPosterior>,
    /// When the oldest camera frame fused into this estimate was captured; `None` when no
    /// camera's frame was (tag readings only, or a coasting step). With the server's receipt
    /// time it gives the end-to-end latency from frame capture to the fused estimate.
    pub captured: Option<ClusterTime>,
}

/// Most cells per side of a [`GridPosterior`] (a report carries at most 64 × 64 bytes of it).
pub const MAX_GRID_POSTERIOR_SIDE: u16 = 64;

/// A grid estimator's belief in a compact form (paper 001): the floor's cells summed into at
/// most [`MAX_GRID_POSTERIOR_SIDE`] per side, each cell's probability mass quantized to a byte
/// relative to the largest (`255` = `peak_mass`), row-major with x fastest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridPosterior {
    /// World `[x, y]` of the first cell's corner, m.
    pub origin: [f32; 2],
    /// Side of one (down-sampled) cell, m.
    pub cell_m: f32,
    pub nx: u16,
    pub ny: u16,
    /// Probability mass of the fullest cell.
    pub peak_mass: f32,
    /// `nx × ny` values, `round(255 · mass / peak_mass)`.
    pub cells: Vec<u8>,
}

impl GridPosterior {
    /// Probability mass of cell `(i, j)` (to the quantization's precision).
    pub fn mass(&self, i: usize, j: usize) -> f32 {
        let k = j * usize::from(self.nx) + i;
        self.cells
            .get(k)
            .map_or(0.0, |v| f32::from(*v) / 255.0 * self.peak_mass)
    }
}

/// How loud a head's cluster hears one tag, and whether one of its tracks explains it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagHeard {
    pub tag: TagId,
    /// The loudest node's readings of the tag over the last few seconds, smoothed, dBm.
    pub dbm: f32,
    /// Where that node's radio is on the floor, `[x, y]` metres: near the tag.
    pub near: [f32; 2],
    /// The head's track the tag is bound to, if any: the one that *claims* it (bound by the
    /// head's own evidence, whether or not the tag's home lets it take the readings).
    pub track: Option<TargetId>,
}

/// head → server, with its status and whenever a claim changes: every tag its cluster hears
/// (a complete list: a tag left out is no longer heard), how loud, where, and which track
/// claims it, each tag once, in increasing order, at most [`MAX_TAGS_HEARD`]. The server
/// names each tag's home ([`TagHomes`], `node_server::tag_homes` has the rule).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagsHeard {
    pub tags: Vec<TagHeard>,
}

/// Most tags one [`TagsHeard`] or [`TagHomes`] names (a head keeps evidence of at most this
/// many tags).
pub const MAX_TAGS_HEARD: usize = 256;

// ---------------------------------------------------------------- server → nodes

/// Which head a camera belongs to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Assignment {
    pub node: NodeId,
    pub head: NodeId,
}

/// Move a track to a head, starting from its last posterior (handover and failover).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Handover {
    pub global: TargetId,
    pub to_head: NodeId,
    pub from_head: Option<NodeId>,
    pub time: ClusterTime,
    pub mean: Vec6,
    pub cov: Mat6,
}

/// One tag's home: the head whose track takes its readings; and whether the asking head's
/// claiming track is the same person (one global, by the server's books) and takes them too.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagHome {
    pub tag: TagId,
    pub head: NodeId,
    pub shared: bool,
}

/// server → head, in answer to its [`TagsHeard`] (and to a head that just lost a home): the
/// homes of the tags it named, each once, in increasing order. A head fuses the readings of a
/// tag whose home is another head into none of its tracks, unless told they are shared.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TagHomes {
    pub homes: Vec<TagHome>,
}

/// Time-sync beacon (FTSP): the leader's cluster time when it sent the beacon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SyncBeacon {
    pub leader: NodeId,
    pub round: u64,
    pub leader_time: ClusterTime,
}

/// Liveness change of a node, told to its head.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Liveness {
    pub node: NodeId,
    pub up: bool,
}

// ---------------------------------------------------------------- camera → server

/// One undistorted detection of a [`MeasuredFrame`]: the segmented region and its normalized
/// pin-hole point with covariance, as the camera computed them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasuredDetection {
    /// Region centroid and foot point, pixels.
    pub centre: [f32; 2],
    pub foot: [f32; 2],
    pub pixel_box: PixelBox,
    /// Region area in pixels.
    pub area: u32,
    pub colour: ColourSignature,
    /// Undistorted normalized point of the camera's reference point.
    pub point: [f64; 2],
    /// Covariance of `point`, `[σxx, σxy, σyy]` in normalized units².
    pub cov: [f64; 3],
}

/// Everything a camera measured in one frame of a *logging run*, whatever its mode (paper 002
/// logged every measurement once and processed it offline with each method). Sent to the
/// server, which records it; at most [`crate::MAX_MEASURED_DETECTIONS`] detections.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasuredFrame {
    /// Capture time, the camera's cluster time.
    pub captured: ClusterTime,
    /// The tag readings the node's radio received since its previous frame, at most
    /// [`crate::observation::MAX_OBSERVATIONS`].
    pub rssi: Vec<RssiReading>,
    pub detections: Vec<MeasuredDetection>,
}

// ---------------------------------------------------------------- particle filter samples

/// Most samples one [`SampleSet`] carries.
pub const MAX_SAMPLES: usize = 512;

/// Ask a camera for the sample sets of its per-person particle filters (paper 004 §2.5.1 (i):
/// the pdf itself, sent only on request). Answered once, from the newest frame, with one
/// [`SampleSet`] per person to the node that asked.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleRequest {
    /// The camera asked.
    pub node: NodeId,
    /// The camera's id of the person, or `None` for everyone it tracks.
    pub local: Option<u32>,
}

/// One weighted sample of a camera's particle filter, in the camera's pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageSample {
    /// `[x, y, vx, vy, w, h]`: box centre, velocity (pixels per frame) and size, pixels.
    pub state: [f32; 6],
    /// Normalized weight π.
    pub weight: f32,
}

/// One person's sample set of a camera's newest frame, the answer to a [`SampleRequest`]. A
/// filter with more than [`MAX_SAMPLES`] samples sends its heaviest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleSet {
    /// The camera's id of the person.
    pub local: u32,
    pub captured: ClusterTime,
    pub samples: Vec<ImageSample>,
}

// ---------------------------------------------------------------- every link

/// First frame on every link.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    pub version: u16,
    pub role: Role,
    pub node: NodeId,
}

/// Answer to a [`Hello`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HelloAck {
    pub accepted: bool,
    pub reason: String,
}

/// Every message kind. Variant order is part of the wire format.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    Hello(Hello),
    HelloAck(HelloAck),
    Heartbeat,
    Measurement(Measurement),
    /// node → head: the answers to a step's priors (distributed EIF).
    Answers(Answers),
    NodeStatus(NodeStatus),
    /// head → node: a step's priors (distributed EIF).
    Priors(Priors),
    Command(Command),
    TrackReport(TrackReport),
    Assignment(Assignment),
    Handover(Handover),
    SyncBeacon(SyncBeacon),
    Liveness(Liveness),
    MeasuredFrame(MeasuredFrame),
    SampleRequest(SampleRequest),
    SampleSet(SampleSet),
    FrameReport(FrameReport),
    /// viewer → server: send me the view feed (renewed every second).
    ViewSubscribe(ViewSubscribe),
    /// server → viewer: the tracks, nodes and handovers, every step.
    ViewUpdate(ViewUpdate),
    /// camera → head: a frame's ground-plane people (paper 004's cameras).
    PeopleFrame(PeopleFrame),
    /// head → server: the tags its cluster hears, and how loud.
    TagsHeard(TagsHeard),
    /// server → head: which head's track takes each of those tags' readings.
    TagHomes(TagHomes),
}

impl Message {
    /// Short kind name for logs, counters and benchmarks.
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Hello(_) => "hello",
            Message::HelloAck(_) => "hello_ack",
            Message::Heartbeat => "heartbeat",
            Message::Measurement(_) => "measurement",
            Message::Answers(_) => "answers",
            Message::NodeStatus(_) => "node_status",
            Message::Priors(_) => "priors",
            Message::Command(_) => "command",
            Message::TrackReport(_) => "track_report",
            Message::Assignment(_) => "assignment",
            Message::Handover(_) => "handover",
            Message::SyncBeacon(_) => "sync_beacon",
            Message::Liveness(_) => "liveness",
            Message::MeasuredFrame(_) => "measured_frame",
            Message::SampleRequest(_) => "sample_request",
            Message::SampleSet(_) => "sample_set",
            Message::FrameReport(_) => "frame_report",
            Message::ViewSubscribe(_) => "view_subscribe",
            Message::ViewUpdate(_) => "view_update",
            Message::PeopleFrame(_) => "people_frame",
            Message::TagsHeard(_) => "tags_heard",
            Message::TagHomes(_) => "tag_homes",
        }
    }

    /// Whether a transport may drop this message when a queue is full. Measurements and
    /// reports are superseded by the next step (a logging run's dropped frames are counted
    /// by the camera), and so are a viewer's subscription (renewed every second) and its
    /// updates, and a head's tags and their homes (both sent every second); control messages
    /// never are.
    pub fn droppable(&self) -> bool {
        matches!(
            self,
            Message::Measurement(_)
                | Message::Answers(_)
                | Message::NodeStatus(_)
                | Message::TrackReport(_)
                | Message::Heartbeat
                | Message::MeasuredFrame(_)
                | Message::SampleSet(_)
                | Message::FrameReport(_)
                | Message::ViewSubscribe(_)
                | Message::ViewUpdate(_)
                | Message::PeopleFrame(_)
                | Message::TagsHeard(_)
                | Message::TagHomes(_)
        )
    }
}
