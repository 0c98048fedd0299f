//! The centralized EIF (paper 000 §4): cameras send undistorted points and the head linearizes
//! each one at μ̄ with the camera's model, at the frame's capture time as the cameras do in the
//! distributed filter, plus the previous frame's point when the method asks (eq. 13).

use super::{Fusion, Updated, eif_update};
use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::observe;
use crate::track::Track;
use proto::ClusterTime;

#[derive(Debug)]
pub(super) struct CentralizedEif;

impl Fusion for CentralizedEif {
    fn distributed(&self) -> bool {
        false
    }

    fn absorb(&mut self, track: &mut Track, det: &Detection, node: &NodeInfo, cfg: &HeadConfig) {
        observe::camera(track, det, node, cfg.method.previous_point);
    }

    fn update(&mut self, track: &mut Track, _: ClusterTime) -> Updated {
        eif_update(track)
    }
}
