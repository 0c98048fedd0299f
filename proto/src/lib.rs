//! `proto` is the contract every Ocelli node shares.
//!
//! What two nodes must agree on lives here and nowhere else: the messages and their wire
//! encoding ([`msg`], [`observation`], [`wire`]), what sensors deliver to a node core and the
//! core's contract ([`sensor`], [`node`]), units and frames ([`ids`],
//! [`time`], [`geo`]), the camera model ([`camera`], [`opencv`]), the state layout, motion and
//! measurement models ([`models`]), the scenario file ([`scenario`]) and the visualization
//! node's feed ([`view`]).
//!
//! Units: metres, seconds (nanoseconds on the wire), radians, dBm, milliwatts. The world frame
//! is right-handed with z up; camera frames follow OpenCV (x right, y down, z forward).

pub mod acoustic;
pub mod appearance;
pub mod camera;
pub mod examples;
pub mod geo;
pub mod ids;
pub mod log_limit;
pub mod models;
pub mod msg;
pub mod node;
pub mod observation;
pub mod opencv;
pub mod region;
pub mod scenario;
pub mod sensor;
pub mod sync;
pub mod time;
pub mod validate;
pub mod view;
pub mod wire;

pub use ids::{NodeId, Role, TagId, TargetId};
pub use msg::{Envelope, Message, Mode};
pub use time::ClusterTime;
pub use wire::{WireError, decode, encode};

/// Version of the wire protocol. Carried in every frame header and in the handshake; a
/// mismatch is rejected before the body is decoded.
pub const PROTOCOL_VERSION: u16 = 7;

/// Largest encoded frame any transport accepts, in bytes.
pub const MAX_FRAME_BYTES: usize = 16 * 1024;

/// Most node ids a single `TrackReport` may name.
pub const MAX_CONTRIBUTORS: usize = 1024;

/// Most detections one `MeasuredFrame` may carry (segmenters keep at most 32 regions; 64 of
/// them encode to about 6 KiB, well inside [`MAX_FRAME_BYTES`]).
pub const MAX_MEASURED_DETECTIONS: usize = 64;

/// Most nodes a scenario may declare.
pub const MAX_NODES: usize = 4096;
