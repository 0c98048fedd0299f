//! How a head turns a step's observations into each track's posterior, behind one interface:
//! the distributed EIF (paper 002: nodes contribute Ω_i, ξ_i), the centralized EIF and
//! maximum-likelihood fusion (paper 000: nodes send measurements the head models), and paper
//! 001's grid estimator (detections, non-detections, acoustic fingerprints and RSSI as
//! likelihoods over the floor). The head's step, association, births, RSSI queueing and
//! activation are the same for all of them.
//!
//! A new estimator is a new module implementing [`Fusion`] plus one line in [`build`]. A
//! fusion may keep state of its own per track (keyed by the track's local id): the head tells
//! it which tracks are still alive after every step ([`Fusion::retain`]).

mod centralized_eif;
mod distributed_eif;
pub mod grid;
pub mod ml;

use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::eif::FilterError;
use crate::track::Track;
use proto::acoustic::IldVector;
use proto::msg::GridPosterior;
use proto::{ClusterTime, Mode, TargetId};

/// What one track's update made of its step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Updated {
    /// The step carried information about the track (otherwise it is prediction only).
    pub informed: bool,
    /// The update failed numerically; the track keeps its prediction.
    pub failure: Option<FilterError>,
}

/// What the head's sensors did in a step besides the detections associated with tracks: which
/// cameras processed a frame (one that looked and saw nothing is evidence too) in which mode,
/// and the acoustic nodes' ILD vectors.
#[derive(Clone, Copy, Debug)]
pub struct StepSensors<'a> {
    /// Per camera slot: whether it reported at least one processed frame since the last step.
    pub looked: &'a [bool],
    /// Per camera slot: its mode as the head knows it.
    pub modes: &'a [Mode],
    /// `(acoustic slot, ILD vector)` received since the last step.
    pub ilds: &'a [(usize, IldVector)],
}

/// A fusion method.
pub trait Fusion: std::fmt::Debug + Send {
    /// Nodes answer the step's priors with their information contributions Ω_i, ξ_i and the
    /// head waits for them; otherwise nodes send measurements and the head models them ([`Fusion::absorb`]).
    fn distributed(&self) -> bool;

    /// Whether tag readings enter the estimate.
    fn fuses_rssi(&self) -> bool {
        true
    }

    /// Whether acoustic ILD vectors enter the estimate.
    fn fuses_acoustic(&self) -> bool {
        false
    }

    /// Whether cameras report every processed frame, detections or not (`FrameReport`).
    fn wants_frame_reports(&self) -> bool {
        false
    }

    /// The step's sensor activity, before any track of the step is updated.
    fn sensed(&mut self, sensors: &StepSensors<'_>) {
        let _ = sensors;
    }

    /// Fold one camera detection the head associated with `track` this step (at the head:
    /// centralized methods; the distributed filter's cameras already contributed theirs).
    fn absorb(&mut self, track: &mut Track, det: &Detection, node: &NodeInfo, cfg: &HeadConfig);

    /// The track's posterior from its step's information.
    fn update(&mut self, track: &mut Track, now: ClusterTime) -> Updated;

    /// A compact form of the track's posterior for its report, if the method has one beyond
    /// the mean and covariance.
    fn posterior(&self, track: TargetId) -> Option<GridPosterior> {
        let _ = track;
        None
    }

    /// Forget per-track state of every track not in `live`.
    fn retain(&mut self, live: &[TargetId]) {
        let _ = live;
    }

    /// Observations refused so far (another grid's, frequencies no fingerprint has, …).
    fn refused(&self) -> u64 {
        0
    }
}

/// The fusion a head's configuration names (`method.fusion`). A grid that cannot be built
/// (checked before, by [`HeadConfig::from_scenario`]) is logged and falls back to the
/// centralized EIF, so the head keeps tracking.
pub fn build(cfg: &HeadConfig) -> Box<dyn Fusion> {
    use proto::scenario::Fusion as Kind;
    match cfg.method.fusion {
        Kind::DistributedEif => Box::new(distributed_eif::DistributedEif),
        Kind::CentralizedEif => Box::new(centralized_eif::CentralizedEif),
        Kind::Ml => Box::new(ml::Ml),
        Kind::Grid => match grid::GridFusion::new(cfg) {
            Ok(g) => Box::new(g),
            Err(e) => {
                tracing::error!(error = %e, "grid fusion cannot be built; centralized EIF instead");
                Box::new(centralized_eif::CentralizedEif)
            }
        },
    }
}

/// The information-form update shared by both EIFs: the step's summed information.
fn eif_update(track: &mut Track) -> Updated {
    Updated {
        informed: track.acc.count > 0,
        failure: track.filter.update(&track.acc).err(),
    }
}
