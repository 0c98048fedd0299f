//! Track initialization from first detections: weighted least-squares triangulation of the
//! rays of two or more cameras, or a wide prior along the ray when only one camera sees the
//! target. Velocity starts at zero with a broad variance.

use nalgebra::{Cholesky, Matrix2, Matrix3, Matrix6, Vector2, Vector3};
use proto::camera::CameraModel;
use proto::models::State;

/// Standard deviation of the initial velocity, m/s.
pub const INIT_VELOCITY_SIGMA: f64 = 1.0;
/// Added to every triangulated position variance, m²: model error the rays do not show.
pub const INIT_POSITION_FLOOR: f64 = 0.02 * 0.02;
/// Standard deviation of a single-camera prior's position along every axis, m.
pub const SINGLE_CAMERA_SIGMA: f64 = 2.0;

/// One camera's view of the target: an undistorted normalized point and its covariance.
#[derive(Clone, Copy, Debug)]
pub struct RayObservation<'a> {
    pub camera: &'a CameraModel,
    pub point: Vector2<f64>,
    pub cov: Matrix2<f64>,
}

impl RayObservation<'_> {
    fn ray(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.camera.pose.centre(), self.camera.ray_world(&self.point))
    }

    /// Angular standard deviation of the ray, radians (normalized units ≈ radians near axis).
    fn angular_sigma(&self) -> f64 {
        self.cov.trace().max(1e-12).sqrt() / std::f64::consts::SQRT_2
    }
}

/// Least-squares point nearest to every ray, each ray weighted by its perpendicular variance
/// at the target's range, with the position covariance of that fit. `None` with fewer than two
/// rays, (nearly) parallel rays, or a point behind a camera.
pub fn triangulate(obs: &[RayObservation<'_>]) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    if obs.len() < 2 {
        return None;
    }
    let solve = |weights: &dyn Fn(usize) -> f64| {
        let (mut a, mut b) = (Matrix3::zeros(), Vector3::zeros());
        for (i, o) in obs.iter().enumerate() {
            let (c, d) = o.ray();
            let p = (Matrix3::identity() - d * d.transpose()) * weights(i);
            a += p;
            b += p * c;
        }
        let chol = Cholesky::new(a)?;
        Some((chol.solve(&b), chol.inverse()))
    };
    let (first, _) = solve(&|_| 1.0)?;
    // Reweight with the perpendicular variance at the first estimate's range.
    let weight = |i: usize| {
        let o = &obs[i];
        let range = (first - o.camera.pose.centre()).norm().max(0.1);
        1.0 / (o.angular_sigma() * range).powi(2)
    };
    let (point, cov) = solve(&weight)?;
    for o in obs {
        let (c, d) = o.ray();
        if (point - c).dot(&d) <= 0.0 {
            return None;
        }
    }
    Some((point, cov + Matrix3::identity() * INIT_POSITION_FLOOR))
}

/// Full 6-state Gaussian from a position and its covariance, zero velocity.
pub fn state_from_position(p: &Vector3<f64>, cov: &Matrix3<f64>) -> (State, Matrix6<f64>) {
    let mean = State::new(p.x, p.y, p.z, 0.0, 0.0, 0.0);
    let mut c = Matrix6::identity() * INIT_VELOCITY_SIGMA.powi(2);
    c.fixed_view_mut::<3, 3>(0, 0).copy_from(cov);
    (mean, c)
}

/// A wide prior from one camera: the ray's intersection with the plane `z = plane_z` (or a
/// point 3 m along the ray when it does not meet the plane in front), with
/// [`SINGLE_CAMERA_SIGMA`] on every position axis.
pub fn single_camera_prior(obs: &RayObservation<'_>, plane_z: f64) -> (State, Matrix6<f64>) {
    let (c, d) = obs.ray();
    let t = if d.z.abs() > 1e-6 {
        (plane_z - c.z) / d.z
    } else {
        -1.0
    };
    let t = if t > 0.0 && t < 50.0 { t } else { 3.0 };
    let p = c + d * t;
    state_from_position(&p, &(Matrix3::identity() * SINGLE_CAMERA_SIGMA.powi(2)))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proto::camera::{Distortion, Intrinsics, Pose};

    /// A 352×288 distortion-free camera at `pos` looking at `at` (shared by the head's tests).
    pub(crate) fn cam(pos: [f64; 3], at: [f64; 3]) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: 320.0,
                fy: 320.0,
                cx: 176.0,
                cy: 144.0,
                width: 352,
                height: 288,
            },
            distortion: Distortion::default(),
            pose: Pose::look_at(Vector3::from(pos), Vector3::from(at), Vector3::z()).unwrap(),
        }
    }

    #[test]
    fn two_exact_rays_meet_at_the_target() {
        let target = Vector3::new(3.0, 2.0, 0.2);
        let cams = [
            cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([6.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
        ];
        let obs: Vec<_> = cams
            .iter()
            .map(|c| RayObservation {
                camera: c,
                point: c.normalized(&target).0,
                cov: Matrix2::identity() * 1e-4,
            })
            .collect();
        let (p, cov) = triangulate(&obs).unwrap();
        assert!((p - target).norm() < 1e-9, "{p}");
        assert!(cov.trace() > 0.0);
        assert!(triangulate(&obs[..1]).is_none());
    }

    #[test]
    fn single_camera_prior_lies_on_the_ray_at_the_plane() {
        let c = cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]);
        let target = Vector3::new(3.0, 2.0, 0.2);
        let obs = RayObservation {
            camera: &c,
            point: c.normalized(&target).0,
            cov: Matrix2::identity() * 1e-4,
        };
        let (mean, cov) = single_camera_prior(&obs, 0.2);
        assert!((mean.fixed_rows::<3>(0) - target).norm() < 1e-9);
        assert!(cov[(0, 0)] >= SINGLE_CAMERA_SIGMA.powi(2));
    }
}
