//! The vocabulary between a node's sensors and its core: what a source delivers ([`Frame`]s,
//! [`Detection`]s, [`AudioFrame`]s) and the source interfaces ([`FrameSource`], [`RadioSource`],
//! [`AudioSource`]). Real devices and the simulated world both implement them, so a node core
//! cannot tell which one feeds it.

mod audio;
mod detection;
mod frame;
pub mod mbd;
mod source;

pub use audio::{AudioFrame, AudioSource};
pub use detection::{Detection, ReferencePoint, hue_distance, rgb_to_hsi};
pub use frame::{Frame, FrameError, MAX_FRAME_SIDE};
pub use source::{FrameSource, RadioSource, SourceError, TagReading};
