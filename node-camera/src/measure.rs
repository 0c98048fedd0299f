//! From detection to measurement: undistort a region's reference point to normalized pin-hole
//! coordinates with its covariance, gate it against a head's prior, and build the messages —
//! a [`Measurement`] (centralized, paper 000) or a [`Contribution`] Ω_i, ξ_i linearized at the
//! broadcast μ̄ (distributed, paper 002 §III). All models come from `proto`.

use nalgebra::{Matrix2, Vector2};
use proto::camera::{CameraModel, UndistortError};
use proto::models::{self, State};
use proto::msg::{Contribution, Information, Measurement, Mode, Prior};
use proto::observation::{Kinds, Observation, ObservationKind, PinholePoint, RssiReading};
use proto::sensor::{Detection, ReferencePoint};
use proto::{ClusterTime, TargetId};

/// A detection with its undistorted normalized point and covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    pub detection: Detection,
    /// Undistorted normalized pin-hole point of the reference point.
    pub point: Vector2<f64>,
    /// Its covariance from the pixel σ, normalized units².
    pub cov: Matrix2<f64>,
}

/// Undistort a detection's reference point.
///
/// # Errors
/// The point is not finite or outside the lens model's invertible range.
pub fn measure(
    camera: &CameraModel,
    detection: &Detection,
    reference: ReferencePoint,
    sigma_px: f64,
) -> Result<Measured, UndistortError> {
    let [u, v] = detection.reference(reference);
    let point = camera.undistort(&Vector2::new(u as f64, v as f64))?;
    Ok(Measured {
        detection: *detection,
        point,
        cov: camera.normalized_covariance(&point, sigma_px),
    })
}

/// [`models::gate_distance2`] of a measured point seen `age_s` seconds before the prior's time
/// (negative: after).
pub fn mahalanobis2(camera: &CameraModel, prior: &Prior, m: &Measured, age_s: f64) -> Option<f64> {
    let mean = models::vec6_from_wire(&prior.mean);
    let cov = models::mat6_from_wire(&prior.cov);
    models::gate_distance2(camera, &mean, &cov, &m.point, &m.cov, age_s)
}

/// Assign measured detections to priors: each prior takes at most one detection and each
/// detection at most one prior, nearest pairs first, only within `gate_chi2`. Each prior comes
/// with the detections' age relative to it, s (see [`mahalanobis2`]). Returns, per detection,
/// the index of its prior.
pub fn associate(
    camera: &CameraModel,
    priors: &[(&Prior, f64)],
    measured: &[Measured],
    gate_chi2: f64,
) -> Vec<Option<usize>> {
    nearest_pairs(priors, measured, gate_chi2, |p, m, age_s| {
        mahalanobis2(camera, p, m, age_s)
    })
}

/// The optimal one-to-one assignment of `items` to `priors` (global nearest neighbour,
/// `assign::gnn`): the pairs minimising the summed squared gate distance `distance2` (for the
/// prior, the item and the item's age relative to the prior, s), an item left free costing the
/// gate, and no pair outside `gate_chi2`. Returns, per item, the index of its prior. Shared by
/// the pin-hole detections and the ground-plane people.
///
/// Optimal rather than nearest-first: two people close together in a view, each with a track,
/// are a common sight in a crowd, and a greedy pass that gives the nearer track the wrong
/// person leaves the other track with nobody.
pub fn nearest_pairs<T>(
    priors: &[(&Prior, f64)],
    items: &[T],
    gate_chi2: f64,
    distance2: impl Fn(&Prior, &T, f64) -> Option<f64>,
) -> Vec<Option<usize>> {
    let Ok(mut costs) = assign::GatedCosts::new(priors.len(), gate_chi2) else {
        return vec![None; items.len()];
    };
    for item in items {
        let row: Vec<Option<f64>> = priors
            .iter()
            .map(|&(p, age_s)| distance2(p, item, age_s).filter(|d2| d2.is_finite() && *d2 >= 0.0))
            .collect();
        // Every cost is finite and non-negative, so the row is always taken.
        let _ = costs.push(0, &row);
    }
    assign::assign(&costs)
}

/// Per prior, the item the optimal pairing of every prior with the items gives it
/// ([`nearest_pairs`]), or none. A camera answers all of a step's priors at once; pairing
/// jointly keeps two people side by side from both being given to the nearer track (a crowd's
/// tracks then lost their people and swapped).
///
/// A prior the pairing leaves empty gets nothing: its person is hidden or merged into a
/// neighbour's region, and the track coasts. Until the background model dropped its ghosts
/// (`crate::ghost`), the camera gave such a prior its nearest detection in the gate all the same,
/// because the robot's head held ghost tracks and lagging duplicates that had to be pulled onto
/// the robot and merged; that fallback also gave a crowd's track its neighbour's person and
/// merged two people into one track. Without ghosts the robot has one track and the fallback
/// does nothing for it (default scenario, seeds 1–5, identical errors with and without it),
/// and without the fallback four people, the crowd and the hall keep their tracks apart
/// (`docs/multi-target.md`). Giving such a prior the merged region that holds its projection,
/// with the box's extent as its uncertainty, was measured and not kept (same document).
pub fn joint_choices<'a, T>(
    priors: &[(&Prior, f64)],
    items: &'a [T],
    gate_chi2: f64,
    distance2: impl Fn(&Prior, &T, f64) -> Option<f64>,
) -> Vec<Option<&'a T>> {
    let mut out = vec![None; priors.len()];
    for (item, p) in nearest_pairs(priors, items, gate_chi2, distance2)
        .into_iter()
        .enumerate()
    {
        if let Some(p) = p {
            out[p] = Some(&items[item]);
        }
    }
    out
}

/// The contribution Ω_i, ξ_i of one measured point at the prior's mean, or none when there is
/// no point or it cannot be linearized. The point was captured `age_s` seconds before the
/// prior's time ([`models::camera_contribution_aged`]).
pub fn contribution(
    camera: &CameraModel,
    prior: &Prior,
    measured: Option<&Measured>,
    age_s: f64,
) -> Option<Contribution> {
    let mean: State = models::vec6_from_wire(&prior.mean);
    let (omega, xi) =
        measured.and_then(|m| models::camera_contribution_aged(camera, &m.point, &m.cov, &mean, age_s))?;
    Some(Contribution {
        target: prior.target,
        info: Some(Information {
            matrix: models::mat6_to_wire(&omega),
            vector: models::vec6_to_wire(&xi),
        }),
        folded: Kinds::of(ObservationKind::Pinhole),
        ground: None,
    })
}

/// The pin-hole observation of one measured detection.
pub fn pinhole(m: &Measured, prev_point: Option<Vector2<f64>>, captured: ClusterTime) -> PinholePoint {
    let d = &m.detection;
    PinholePoint {
        point: [m.point.x, m.point.y],
        cov: [m.cov[(0, 0)], m.cov[(0, 1)], m.cov[(1, 1)]],
        prev_point: prev_point.map(|p| [p.x, p.y]),
        pixel_box: d.bbox,
        area: d.area,
        colour: d.colour,
        captured,
    }
}

/// The measurement of one detection for the head to model (centralized mode, or no prior
/// gated it), with the tag readings of its frame.
pub fn measurement(
    camera: &CameraModel,
    point: PinholePoint,
    target: Option<(TargetId, u64)>,
    mode: Mode,
    rssi: &[RssiReading],
) -> Measurement {
    Measurement {
        target: target.map(|t| t.0),
        step: target.map_or(0, |t| t.1),
        pose: camera.pose.to_wire(),
        mode,
        observations: std::iter::once(Observation::Pinhole(point))
            .chain(rssi.iter().copied().map(Observation::Rssi))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix6, Vector3};
    use proto::msg::{ColourSignature, PixelBox};
    use proto::scenario::Scenario;

    fn cam() -> CameraModel {
        Scenario::default_scenario().camera_model(10).unwrap()
    }

    fn detection_at(px: Vector2<f64>) -> Detection {
        Detection {
            centre: [px.x as f32, px.y as f32],
            foot: [px.x as f32, px.y as f32 + 20.0],
            bbox: PixelBox {
                xmin: px.x as f32 - 10.0,
                ymin: px.y as f32 - 20.0,
                xmax: px.x as f32 + 10.0,
                ymax: px.y as f32 + 20.0,
            },
            area: 800,
            colour: ColourSignature {
                hue: 0.0,
                saturation: 0.8,
                intensity: 0.4,
            },
        }
    }

    /// The measured centre of a detection of the world point `x`, weighed with `sigma_px`.
    fn measured_at(c: &CameraModel, x: &Vector3<f64>, sigma_px: f64) -> Measured {
        measure(
            c,
            &detection_at(c.project(x).unwrap()),
            ReferencePoint::Centre,
            sigma_px,
        )
        .unwrap()
    }

    fn prior(target: u32, pos: Vector3<f64>, sd: f64) -> Prior {
        let mean = State::new(pos.x, pos.y, pos.z, 0.0, 0.0, 0.0);
        Prior {
            target: TargetId(target),
            step: 7,
            mean: models::vec6_to_wire(&mean),
            cov: models::mat6_to_wire(&(Matrix6::identity() * sd * sd)),
            deadline: ClusterTime::ZERO,
            radio: false,
        }
    }

    #[test]
    fn undistorted_point_is_the_pinhole_projection() {
        let c = cam();
        let world = Vector3::new(3.5, 2.2, 0.25);
        let px = c.project(&world).unwrap();
        let m = measure(&c, &detection_at(px), ReferencePoint::Centre, 18.0).unwrap();
        let (p, _) = c.normalized(&world);
        // Detections hold f32 pixels: ~1e-5 px of rounding.
        assert!((m.point - p).norm() < 1e-6, "{} vs {p}", m.point);
        // 18 px through fx ≈ 320: σ ≈ 0.056 in normalized units, more where distortion compresses.
        let sd = m.cov[(0, 0)].sqrt();
        assert!(sd > 18.0 / 320.0 * 0.9 && sd < 18.0 / 320.0 * 1.6, "{sd}");
        let foot = measure(&c, &detection_at(px), ReferencePoint::Foot, 18.0).unwrap();
        assert!(foot.point.y > m.point.y);
    }

    #[test]
    fn gating_picks_the_right_target_and_rejects_far_ones() {
        let c = cam();
        let a = Vector3::new(3.5, 2.2, 0.25);
        let b = Vector3::new(2.6, 3.4, 0.25);
        let pb_px = c.project(&b).unwrap();
        let pa_px = c.project(&a).unwrap();
        assert!((pb_px - pa_px).norm() > 100.0, "{pa_px} {pb_px}");
        assert!(
            pb_px.x > 0.0 && pb_px.x < 352.0 && pb_px.y > 0.0 && pb_px.y < 288.0,
            "{pb_px}"
        );
        let ma = measured_at(&c, &a, 18.0);
        let mb = measured_at(&c, &b, 18.0);
        let pa = prior(1, a + Vector3::new(0.1, -0.05, 0.0), 0.1);
        let pb = prior(2, b, 0.1);
        let far = prior(3, Vector3::new(9.0, 7.0, 0.25), 0.2);
        assert!(mahalanobis2(&c, &pa, &ma, 0.0).unwrap() < 13.8);
        assert!(mahalanobis2(&c, &pa, &mb, 0.0).unwrap() > 13.8);
        let got = associate(&c, &[(&pb, 0.0), (&far, 0.0), (&pa, 0.0)], &[ma, mb], 13.8);
        assert_eq!(got, vec![Some(2), Some(0)]);
        let behind = prior(4, Vector3::new(0.5, -3.0, 0.25), 0.2);
        assert_eq!(mahalanobis2(&c, &behind, &ma, 0.0), None);
    }

    /// A prior of a target moving at 2 m/s and a frame of where it was 0.2 s earlier.
    fn moving_prior_and_old_frame() -> (CameraModel, Prior, Measured) {
        let c = cam();
        let now = Vector3::new(3.5, 2.2, 0.25);
        let mut p = prior(1, now, 0.05);
        p.mean[3] = 2.0;
        let was = now - Vector3::new(0.4, 0.0, 0.0);
        let m = measured_at(&c, &was, 2.0);
        (c, p, m)
    }

    #[test]
    fn an_old_frame_is_compared_with_where_the_prior_puts_the_target_then() {
        let (c, p, m) = moving_prior_and_old_frame();
        let aged = mahalanobis2(&c, &p, &m, 0.2).unwrap();
        let as_current = mahalanobis2(&c, &p, &m, 0.0).unwrap();
        assert!(aged < 1e-6, "{aged}");
        assert!(as_current > 13.8, "{as_current}");
    }

    #[test]
    fn an_old_frame_contributes_at_its_own_time() {
        let (c, p, m) = moving_prior_and_old_frame();
        let mean = models::vec6_from_wire(&p.mean);
        let got = contribution(&c, &p, Some(&m), 0.2).unwrap();
        let (omega, xi) = models::camera_contribution_aged(&c, &m.point, &m.cov, &mean, 0.2).unwrap();
        let info = got.info.unwrap();
        assert_eq!(info.matrix, models::mat6_to_wire(&omega));
        assert_eq!(info.vector, models::vec6_to_wire(&xi));
        // Fused alone into the prior, the old frame moves the mean nowhere (it agrees with the
        // prior once aged) and it observes velocity.
        let prior_info = models::mat6_from_wire(&p.cov).try_inverse().unwrap();
        let post_info = prior_info + omega;
        let post = post_info.cholesky().unwrap().solve(&(prior_info * mean + xi));
        assert!((post - mean).norm() < 1e-6, "{post}");
        assert!(omega[(3, 3)] > 0.0);
        let (omega0, xi0) = models::camera_contribution(&c, &m.point, &m.cov, &mean).unwrap();
        let post0 = (prior_info + omega0)
            .cholesky()
            .unwrap()
            .solve(&(prior_info * mean + xi0));
        assert!(
            (post0 - mean).fixed_rows::<3>(0).norm() > 0.05,
            "as current, it drags the mean back"
        );
    }

    #[test]
    fn contribution_matches_proto_and_none_when_empty() {
        let c = cam();
        let a = Vector3::new(3.5, 2.2, 0.25);
        let m = measured_at(&c, &a, 18.0);
        let p = prior(1, a, 0.3);
        let got = contribution(&c, &p, Some(&m), 0.0).unwrap();
        assert_eq!(got.folded, Kinds::of(ObservationKind::Pinhole));
        let (omega, xi) =
            models::camera_contribution(&c, &m.point, &m.cov, &models::vec6_from_wire(&p.mean)).unwrap();
        let info = got.info.clone().unwrap();
        assert_eq!(info.matrix, models::mat6_to_wire(&omega));
        assert_eq!(info.vector, models::vec6_to_wire(&xi));
        assert_eq!((got.target, got.ground), (TargetId(1), None));
        assert_eq!(contribution(&c, &p, None, 0.0), None, "nothing to send");
        let tag = RssiReading {
            tag: proto::TagId(9),
            dbm: -60.0,
            time: ClusterTime(4),
        };
        let meas = measurement(
            &c,
            pinhole(&m, None, ClusterTime(5)),
            Some((TargetId(1), 7)),
            Mode::Active,
            &[tag],
        );
        assert_eq!(meas.target, Some(TargetId(1)));
        assert_eq!(meas.observations.len(), 2);
        assert!(matches!(&meas.observations[0], Observation::Pinhole(p) if p.captured == ClusterTime(5)));
        assert_eq!(meas.observations[1], Observation::Rssi(tag));
        assert_eq!(meas.pose, c.pose.to_wire());
    }
}
