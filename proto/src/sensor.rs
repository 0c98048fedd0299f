//! The vocabulary between a node's sensors and its core: what a source delivers ([`Frame`]s,
//! [`Detection`]s) and the source interfaces ([`FrameSource`], [`RadioSource`]). Real devices and the simulated
//! world both implement them, so a node core cannot tell which one feeds it.

mod detection;
mod frame;
pub mod mbd;
mod source;

pub use detection::{Detection, ReferencePoint, hue_distance, rgb_to_hsi};
pub use frame::{Frame, FrameError, MAX_FRAME_SIDE};
pub use source::{FrameSource, RadioSource, SourceError, TagReading};
