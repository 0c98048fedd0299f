//! The camera node: what runs on each Pi-class smart camera. It turns frames into small
//! results — detections, undistorted measurements, information contributions — and sends
//! nothing else (papers 000 §2.2 and §6.1, 002 §II, 004 §2.6 and §3.2).
//!
//! A sans-IO core plus its process: [`source`] reads frames from files (and devices), [`colour_difference`]
//! and [`adaptive_background`] segment them ([`segment`] selects; [`ghost`] drops the regions
//! the background model left behind), [`measure`] undistorts, gates and
//! linearizes, [`core`] is the node's state machine, [`record_all`] makes its logging runs
//! (every frame measured and sent to the server's recording), [`process`] runs a camera as an
//! OS process on the sources it is given. [`radio`] holds what real radio sources share,
//! [`radio_file`] replays recorded BLE readings and `ble` (feature) hears real tags through
//! BlueZ. The camera never sees the simulated world: `ocelli launch` injects it as sources.

pub mod adaptive_background;
#[cfg(feature = "ble")]
pub mod ble;
pub mod colour_difference;
pub mod config;
pub mod core;
pub mod detect;
pub mod ghost;
pub mod ground_people;
#[cfg(feature = "gstreamer")]
pub mod gst;
pub mod measure;
pub mod previous;
pub mod process;
pub mod radio;
pub mod radio_file;
pub mod record_all;
pub mod region;
pub mod segment;
pub mod source;
pub mod source_spec;
pub mod tracker;
#[cfg(feature = "v4l2")]
pub mod v4l2;
