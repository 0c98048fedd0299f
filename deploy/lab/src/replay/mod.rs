//! Re-running a logging run's recording through the heads with another method ([`rerun`]),
//! and fusing external detections from any detector ([`fuse`]).

pub mod cameras;
pub mod detections;
pub mod fuse;
pub mod ml;
pub mod multiviewx;
pub mod rerun;
pub mod track;
