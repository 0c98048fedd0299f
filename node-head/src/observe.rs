//! The head's one place that turns an observation into information about a track, per kind:
//! a pin-hole point through the camera's model at the frame's capture time (and the previous
//! frame's point, paper 000 eq. 13), a tag's reading through the node's trained RSSI model
//! (paper 002 Algorithm 1) weighed by the errors this track's readings have made, a
//! ground-plane person (paper 004) as a floor position at the frame's capture time. Acoustic
//! ILD vectors are not fused by the EIFs.

use crate::association::Detection;
use crate::config::NodeInfo;
use crate::eif::Accumulator;
use crate::track::Track;
use nalgebra::Matrix6;
use proto::models::{
    State, camera_contribution_aged, ground_contribution_aged, ground_height_contribution,
    information_contribution, pinhole_previous, rssi_aged, rssi_information,
};
use proto::observation::ObservationKind;

/// Fold a camera's detection into `track`'s step sums by its kind: a ground-plane person or a
/// pin-hole point.
pub fn camera(track: &mut Track, det: &Detection, node: &NodeInfo, previous_point: bool) {
    if det.ground.is_some() {
        ground(track, det);
    } else {
        pinhole(track, det, node, previous_point);
    }
}

/// Fold a camera's ground-plane person (floor position and covariance) into `track`'s step
/// sums, both filters', linearized at the predicted mean at the frame's capture time, with the
/// centre height its measured height gives.
pub fn ground(track: &mut Track, det: &Detection) {
    let mean_bar = *track.filter.mean();
    let age_s = det.age_s(track.time);
    let height = det.ground.and_then(|h| ground_height_contribution(h, &mean_bar));
    if let Some((o, x)) = ground_contribution_aged(&det.point, &det.cov, &mean_bar, age_s) {
        track.acc.add(&o, &x);
        track.aux_acc.add(&o, &x);
        if let Some((o, x)) = height {
            track.acc.add(&o, &x);
            track.aux_acc.add(&o, &x);
        }
    }
}

/// Fold a camera's pin-hole detection into `track`'s step sums (both the filter's and the
/// camera-only auxiliary filter's), linearized at the track's predicted mean.
pub fn pinhole(track: &mut Track, det: &Detection, node: &NodeInfo, previous_point: bool) {
    let cam = &node.camera;
    // The time of μ̄: the step's, or a track handed over during the step its own.
    let mean_bar = *track.filter.mean();
    let age_s = det.age_s(track.time);
    if let Some((o, x)) = camera_contribution_aged(cam, &det.point, &det.cov, &mean_bar, age_s) {
        track.acc.add(&o, &x);
        track.aux_acc.add(&o, &x);
    }
    if previous_point
        && let Some(prev) = det.prev_point
        && let Some((h, jac)) = pinhole_previous(cam, &mean_bar, age_s + 1.0 / node.fps)
        && let Some((o, x)) = information_contribution(&prev, &h, &jac, &det.cov, &mean_bar)
    {
        track.acc.add(&o, &x);
        track.aux_acc.add(&o, &x);
    }
}

/// Fold the step's queued tag readings into `track`'s sums, each linearized at the predicted
/// mean `mean_bar` (covariance `cov_bar`) with the reading node's current model, weighed with
/// what this track's readings erred before the step (so the order packets came in does not
/// matter), then counted. Returns the node slots whose readings were fused.
pub fn rssi(track: &mut Track, nodes: &[NodeInfo], mean_bar: &State, cov_bar: &Matrix6<f64>) -> Vec<usize> {
    let erred = track.rssi_noise;
    let mut fused = Vec::new();
    for &(slot, dbm, age_s) in &track.rssi {
        let node = &nodes[slot];
        let claimed = track.trainers[slot].model();
        let (h, jac) = rssi_aged(&claimed, &node.position, mean_bar, age_s);
        let hph = (jac * cov_bar * jac.transpose())[(0, 0)];
        track.rssi_noise.observe(&claimed, dbm - h, hph);
        let variance = erred.weighed(&claimed).variance();
        if let Some((o, x)) = rssi_information(dbm, h, &jac, variance, mean_bar) {
            track.acc.add(&o, &x);
            fused.push(slot);
        }
    }
    fused
}

/// Spread of a camera track's height about the method's target plane (`target-plane-z`, which
/// a deployment states for its targets; the simulation takes half its first target's height),
/// metres: people's mid-heights differ by ±0.1 m (1.5–1.9 m tall) and a region's centre falls
/// higher or lower on them, and a deployment that left the plane at its 0.5 m default while
/// tracking people (mid-height about 0.85 m) is not pulled hard.
/// Cameras looking steeply down hardly tell a target's height, and a track whose height drifted
/// (the generated hall: a tenth of its tracks more than 2 m below the floor) sits elsewhere on
/// the floor along an oblique camera's ray, and a second track was born where the person is.
pub const HEIGHT_PRIOR_SIGMA_M: f64 = 0.5;

/// Hold a camera track's height near `plane_z` (σ [`HEIGHT_PRIOR_SIGMA_M`]) in the step sums
/// `acc` when the step brought them observations: a pseudo-measurement, not counted as one, so
/// a step without observations stays prediction only.
pub fn height_prior(acc: &mut Accumulator, plane_z: f64) {
    if acc.count == 0 {
        return;
    }
    let w = HEIGHT_PRIOR_SIGMA_M.powi(-2);
    let mut omega = Matrix6::zeros();
    omega[(2, 2)] = w;
    let mut xi = State::zeros();
    xi[2] = w * plane_z;
    acc.add_prior(&omega, &xi);
}

/// Whether the EIFs can fuse an observation of `kind` (the others are counted and ignored).
pub fn fused_by_eif(kind: ObservationKind) -> bool {
    matches!(
        kind,
        ObservationKind::Pinhole | ObservationKind::Rssi | ObservationKind::Ground
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The height prior adds information on the height only, only to a step that had
    /// observations, and is not counted as one.
    #[test]
    fn the_height_prior_holds_only_informed_steps_and_is_not_an_observation() {
        let mut acc = Accumulator::default();
        height_prior(&mut acc, 0.85);
        assert_eq!(
            acc,
            Accumulator::default(),
            "a step without observations stays prediction only"
        );
        acc.add(&Matrix6::identity(), &State::zeros());
        height_prior(&mut acc, 0.85);
        let w = HEIGHT_PRIOR_SIGMA_M.powi(-2);
        assert_eq!(acc.count, 1);
        assert!((acc.omega[(2, 2)] - (1.0 + w)).abs() < 1e-12);
        assert!((acc.xi[2] - w * 0.85).abs() < 1e-12);
        assert_eq!(acc.omega[(0, 0)], 1.0);
        assert_eq!(acc.xi[0], 0.0);
    }
}
