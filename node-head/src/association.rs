//! Several targets: gated global-nearest-neighbour association of detections to tracks, and track
//! birth when unassociated detections from two or more cameras agree.
//!
//! Association: for every (detection, track) pair the innovation ν = p − h(μ̄) and its
//! covariance S = H Σ̄ Hᵀ + C give d² = νᵀ S⁻¹ ν; the optimal assignment over the pairs
//! inside the χ² gate gives each detection at most one track and each track at most one
//! detection per camera. Birth: the largest group of leftover detections from distinct cameras whose
//! triangulated point reprojects inside the gate for every member. Ground-plane people (paper
//! 004's cameras) gate in the floor plane (`models::ground_gate_distance2`) and are born from
//! groups of agreeing floor positions ([`ground_births`]).

mod ground;

use crate::init::{RayObservation, single_camera_prior, state_from_position, triangulate};
pub use ground::{GROUND_BIRTH_Z_SIGMA, ground_births};
use nalgebra::{Matrix2, Matrix6, Vector2};
use proto::camera::CameraModel;
use proto::models::{State, gate_distance2, ground_gate_distance2, pinhole};
use proto::{ClusterTime, NodeId, TargetId};

/// One detection as the head sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    pub node: NodeId,
    /// The node's index in the head's node table.
    pub slot: usize,
    /// Undistorted normalized point and covariance.
    pub point: Vector2<f64>,
    pub cov: Matrix2<f64>,
    pub prev_point: Option<Vector2<f64>>,
    /// The track the camera gated it to, if any.
    pub hint: Option<TargetId>,
    /// When the camera captured the frame.
    pub captured: ClusterTime,
    /// A ground-plane person's measured height, m: then `point` and `cov` are a floor position
    /// `[x, y]`, metres, and its covariance, not a normalized pin-hole point.
    pub ground: Option<f64>,
    /// The person's colour histogram, when the camera sent it with this detection (paper
    /// 004's particle cameras send it with a person's first message, then when it changed or
    /// every 10 s).
    pub appearance: Option<Vec<f32>>,
}

impl Detection {
    /// Seconds between the capture and `at` (the time of a track's mean); negative when the
    /// frame is newer.
    pub fn age_s(&self, at: ClusterTime) -> f64 {
        at.secs_since(self.captured)
    }
}

/// Squared Mahalanobis distance of a detection to a track predicted to `at`, compared with
/// where the track was when the frame was captured; `None` when the track projects onto the
/// camera plane or behind it.
pub fn distance2(
    camera: &CameraModel,
    det: &Detection,
    mean: &State,
    cov: &Matrix6<f64>,
    at: ClusterTime,
) -> Option<f64> {
    if det.ground.is_some() {
        return ground_gate_distance2(mean, cov, &det.point, &det.cov, det.age_s(at));
    }
    gate_distance2(camera, mean, cov, &det.point, &det.cov, det.age_s(at))
}

/// Assign detections to tracks (`tracks[t] = (μ̄, Σ̄, the time of μ̄)`); entry `i` is the track
/// of detection `i`, or `None`. Global nearest neighbour (`assign::gnn`) over
/// [`gated_costs`]: the optimal assignment, each detection to at most one track and each track
/// to at most one detection per camera, a detection left free costing the gate. Nearest-first,
/// the nearer track of two people side by side could take the wrong one and leave the other
/// with nothing.
pub fn associate(
    tracks: &[(State, Matrix6<f64>, ClusterTime)],
    dets: &[Detection],
    cameras: &[CameraModel],
    gate: f64,
) -> Vec<Option<usize>> {
    gated_costs(tracks, dets, cameras, gate).map_or_else(|| vec![None; dets.len()], |c| assign::assign(&c))
}

/// The association problem: each detection's [`distance2`] to every track, by camera (`None`
/// when the gate is not a finite number > 0).
pub fn gated_costs(
    tracks: &[(State, Matrix6<f64>, ClusterTime)],
    dets: &[Detection],
    cameras: &[CameraModel],
    gate: f64,
) -> Option<assign::GatedCosts> {
    let mut costs = assign::GatedCosts::new(tracks.len(), gate).ok()?;
    for d in dets {
        let row: Vec<Option<f64>> = match cameras.get(d.slot) {
            Some(cam) => tracks
                .iter()
                .map(|(mean, cov, at)| {
                    distance2(cam, d, mean, cov, *at).filter(|x| x.is_finite() && *x >= 0.0)
                })
                .collect(),
            None => vec![None; tracks.len()],
        };
        // Finite, non-negative costs of the right width: always taken.
        let _ = costs.push(d.slot, &row);
    }
    Some(costs)
}

/// A new track to start.
#[derive(Clone, Debug, PartialEq)]
pub struct Birth {
    pub mean: State,
    pub cov: Matrix6<f64>,
    /// Indices of the detections that made it.
    pub members: Vec<usize>,
}

fn reprojection_chi2(camera: &CameraModel, det: &Detection, p: &nalgebra::Vector3<f64>) -> Option<f64> {
    let x = State::new(p.x, p.y, p.z, 0.0, 0.0, 0.0);
    let (h, _) = pinhole(camera, &x)?;
    if camera.pose.world_to_camera(p).z <= 0.0 {
        return None;
    }
    let nu = det.point - h;
    Some(nu.dot(&det.cov.cholesky()?.solve(&nu)))
}

/// A candidate birth: members, summed reprojection χ², point and its covariance.
type Group = (Vec<usize>, f64, nalgebra::Vector3<f64>, nalgebra::Matrix3<f64>);

/// Slack around the world box a born track may lie in, metres.
pub const BIRTH_BOUNDS_MARGIN: f64 = 0.5;

/// Whether the first `axes` coordinates of `p` lie within `bounds` widened by `margin` (false
/// for a NaN).
pub fn within(p: &nalgebra::Vector3<f64>, bounds: ([f64; 3], [f64; 3]), margin: f64, axes: usize) -> bool {
    (0..axes).all(|a| (bounds.0[a] - margin..=bounds.1[a] + margin).contains(&p[a]))
}

/// Start tracks from unassociated detections: groups of at least `min_cameras` distinct
/// cameras whose triangulated point lies in the world box `bounds` (never fewer than two,
/// unless `min_cameras` is 1, when a lone detection gets a wide single-camera prior on the
/// plane `plane_z`). The box rejects the ghost intersections two skew rays always have.
pub fn births(
    dets: &[Detection],
    cameras: &[CameraModel],
    gate: f64,
    min_cameras: usize,
    plane_z: f64,
    bounds: ([f64; 3], [f64; 3]),
) -> Vec<Birth> {
    let inside = |p: &nalgebra::Vector3<f64>| within(p, bounds, BIRTH_BOUNDS_MARGIN, 3);
    let mut left: Vec<usize> = (0..dets.len())
        .filter(|&i| cameras.get(dets[i].slot).is_some() && dets[i].ground.is_none())
        .collect();
    let mut out = ground_births(dets, gate, min_cameras, plane_z, bounds);
    let obs = |i: usize| RayObservation {
        camera: &cameras[dets[i].slot],
        point: dets[i].point,
        cov: dets[i].cov,
    };
    loop {
        let mut best: Option<Group> = None;
        for (a, &i) in left.iter().enumerate() {
            for &j in &left[a + 1..] {
                if dets[i].slot == dets[j].slot {
                    continue;
                }
                let Some((p, _)) = triangulate(&[obs(i), obs(j)]) else {
                    continue;
                };
                if !inside(&p) {
                    continue;
                }
                let mut group = vec![i, j];
                for &k in &left {
                    if group.iter().any(|&g| dets[g].slot == dets[k].slot) {
                        continue;
                    }
                    if reprojection_chi2(&cameras[dets[k].slot], &dets[k], &p).is_some_and(|c| c <= gate) {
                        group.push(k);
                    }
                }
                let Some((p, cov)) = triangulate(&group.iter().map(|&g| obs(g)).collect::<Vec<_>>()) else {
                    continue;
                };
                let chis: Option<Vec<f64>> = group
                    .iter()
                    .map(|&g| reprojection_chi2(&cameras[dets[g].slot], &dets[g], &p))
                    .collect();
                let Some(chis) = chis else { continue };
                if !inside(&p) || chis.iter().any(|&c| c > gate) {
                    continue;
                }
                let score: f64 = chis.iter().sum();
                let better = match &best {
                    None => true,
                    Some((g, s, _, _)) => group.len() > g.len() || (group.len() == g.len() && score < *s),
                };
                if better {
                    best = Some((group, score, p, cov));
                }
            }
        }
        match best {
            Some((group, _, p, cov)) if group.len() >= min_cameras.max(2) || min_cameras <= 1 => {
                let (mean, cov6) = state_from_position(&p, &cov);
                left.retain(|i| !group.contains(i));
                out.push(Birth {
                    mean,
                    cov: cov6,
                    members: group,
                });
            }
            _ => break,
        }
    }
    if min_cameras <= 1 {
        for i in left {
            let (mean, cov) = single_camera_prior(&obs(i), plane_z);
            out.push(Birth {
                mean,
                cov,
                members: vec![i],
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    use crate::init::tests::cam;

    fn det(cams: &[CameraModel], slot: usize, p: Vector3<f64>) -> Detection {
        Detection {
            node: NodeId(slot as u32),
            slot,
            point: cams[slot].normalized(&p).0,
            cov: Matrix2::identity() * (18.0f64 / 320.0).powi(2),
            prev_point: None,
            hint: None,
            captured: ClusterTime::ZERO,
            ground: None,
            appearance: None,
        }
    }

    const ROOM: ([f64; 3], [f64; 3]) = ([0.0, 0.0, 0.0], [12.0, 8.0, 3.0]);

    fn cams() -> Vec<CameraModel> {
        vec![
            cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([6.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([3.0, 7.0, 2.5], [3.0, 3.0, 0.0]),
        ]
    }

    #[test]
    fn nearest_track_wins_and_far_detections_stay_free() {
        let cams = cams();
        let a = Vector3::new(2.0, 2.0, 0.2);
        let b = Vector3::new(4.5, 4.0, 0.2);
        let cov = Matrix6::identity() * 0.05;
        let tracks = [
            (State::new(a.x, a.y, a.z, 0.0, 0.0, 0.0), cov, ClusterTime::ZERO),
            (State::new(b.x, b.y, b.z, 0.0, 0.0, 0.0), cov, ClusterTime::ZERO),
        ];
        let dets = vec![
            det(&cams, 0, b),
            det(&cams, 0, a),
            det(&cams, 1, Vector3::new(5.5, 0.8, 0.2)),
        ];
        let got = associate(&tracks, &dets, &cams, 13.8);
        assert_eq!(got, vec![Some(1), Some(0), None]);
    }

    #[test]
    fn birth_needs_two_agreeing_cameras() {
        let cams = cams();
        let a = Vector3::new(2.0, 2.0, 0.2);
        let b = Vector3::new(4.5, 4.0, 0.2);
        // Two cameras agree on `a`; a third sees `b` alone.
        let dets = vec![det(&cams, 0, a), det(&cams, 1, a), det(&cams, 2, b)];
        let got = births(&dets, &cams, 13.8, 2, 0.2, ROOM);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].members.len(), 2);
        assert!((got[0].mean.fixed_rows::<3>(0) - a).norm() < 1e-6);
        // Disagreeing rays (different points) give no birth.
        let dets = vec![det(&cams, 0, a), det(&cams, 1, b)];
        let ghost = births(&dets, &cams, 13.8, 2, 0.2, ROOM);
        assert!(ghost.is_empty(), "{:?}", ghost.first().map(|b| b.mean));
        // One camera alone with min_cameras = 1 gets a wide prior.
        let one = births(&dets[..1], &cams, 13.8, 1, 0.2, ROOM);
        assert_eq!(one.len(), 1);
        assert!(one[0].cov[(0, 0)] > 1.0);
    }
}
