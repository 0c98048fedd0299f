//! How a head turns a step's observations into each track's posterior, behind one interface:
//! the distributed EIF (paper 002: nodes contribute Ω_i, ξ_i), the centralized EIF and
//! maximum-likelihood fusion (paper 000: nodes send measurements the head models). The head's
//! step, association, births, RSSI and activation are the same for all of them.
//!
//! A new estimator is a new module implementing [`Fusion`] plus one line in [`build`].

mod centralized_eif;
mod distributed_eif;
pub mod ml;

use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::eif::FilterError;
use crate::track::Track;
use proto::ClusterTime;

/// What one track's update made of its step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Updated {
    /// The step carried information about the track (otherwise it is prediction only).
    pub informed: bool,
    /// The update failed numerically; the track keeps its prediction.
    pub failure: Option<FilterError>,
}

/// A fusion method.
pub trait Fusion: std::fmt::Debug + Send {
    /// Nodes answer each prior with their information contribution Ω_i, ξ_i and the head waits
    /// for them; otherwise nodes send measurements and the head models them ([`Fusion::absorb`]).
    fn distributed(&self) -> bool;

    /// Whether tag readings enter the estimate.
    fn fuses_rssi(&self) -> bool {
        true
    }

    /// Fold one camera detection the head associated with `track` this step (at the head:
    /// centralized methods; the distributed filter's cameras already contributed theirs).
    fn absorb(&self, track: &mut Track, det: &Detection, node: &NodeInfo, cfg: &HeadConfig);

    /// The track's posterior from its step's information.
    fn update(&self, track: &mut Track, now: ClusterTime) -> Updated;
}

/// The fusion a scenario's `method.fusion` names.
pub fn build(kind: proto::scenario::Fusion) -> Box<dyn Fusion> {
    use proto::scenario::Fusion as Kind;
    match kind {
        Kind::DistributedEif => Box::new(distributed_eif::DistributedEif),
        Kind::CentralizedEif => Box::new(centralized_eif::CentralizedEif),
        Kind::Ml => Box::new(ml::Ml),
    }
}

/// The information-form update shared by both EIFs: the step's summed information.
fn eif_update(track: &mut Track) -> Updated {
    Updated {
        informed: track.acc.count > 0,
        failure: track.filter.update(&track.acc).err(),
    }
}
