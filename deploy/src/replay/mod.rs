//! `ocelli replay`: re-run recorded or external detections through the heads' fusion methods.

pub mod detections;
pub mod multiviewx;
