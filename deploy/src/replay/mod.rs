//! `ocelli replay`: re-run recorded or external detections through the heads' fusion methods.

pub mod cameras;
pub mod detections;
pub mod ml;
pub mod multiviewx;
pub mod rerun;
pub mod track;
