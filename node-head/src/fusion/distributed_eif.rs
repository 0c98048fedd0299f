//! The distributed EIF (paper 002 §III): every node linearizes its own measurement at the
//! broadcast μ̄ and sends Ω_i, ξ_i; the head only sums them (as they arrive, in
//! `HeadNode::on_answers`) and updates. A ground-plane person comes as itself (its model
//! is linear: the head's Ω_i, ξ_i from it are the node's, and far fewer bytes) and the head
//! folds it in as it arrives.

use super::{Fusion, Updated, eif_update};
use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::track::Track;
use proto::ClusterTime;

#[derive(Debug)]
pub(super) struct DistributedEif;

impl Fusion for DistributedEif {
    fn distributed(&self) -> bool {
        true
    }

    fn absorb(&mut self, _: &mut Track, _: &Detection, _: &NodeInfo, _: &HeadConfig) {}

    fn update(&mut self, track: &mut Track, _: ClusterTime) -> Updated {
        eif_update(track)
    }
}
