//! The camera node: what runs on each Pi-class smart camera. It turns frames into small
//! results — detections, undistorted measurements, information contributions — and sends
//! nothing else (papers 000 §2.2 and §6.1, 002 §II, 004 §2.6 and §3.2).
//!
//! A sans-IO core plus its process: [`frame`] and [`source`] produce frames, [`seg000`] and
//! [`seg004`] segment them ([`segment`] selects), [`measure`] undistorts, gates and linearizes,
//! [`core`] is the node's state machine, [`render`] and [`radio`] are the synthetic world,
//! [`process`] runs a camera as an OS process over a `proto::transport`, [`logging`] makes its
//! logging runs (every frame measured and sent to the server's recording).

pub mod config;
pub mod core;
pub mod detect;
pub mod frame;
#[cfg(feature = "gstreamer")]
pub mod gst;
pub mod logging;
pub mod measure;
pub mod previous;
pub mod process;
pub mod radio;
pub mod region;
pub mod render;
pub mod seg000;
pub mod seg004;
pub mod segment;
pub mod source;
pub mod source_spec;
pub mod synthetic;
#[cfg(feature = "v4l2")]
pub mod v4l2;
