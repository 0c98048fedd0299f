//! Maximum-likelihood fusion (paper 000 §3, eq. 4–7): every camera's normalized point is
//! lifted to a world point at a depth, with a covariance, and the points are averaged with
//! inverse-covariance weights. The depth the method needs comes from a known target plane
//! (`z = h`) or from a mean depth with an inflated variance along the optical axis. As a
//! head's [`Fusion`], each step's fix replaces the track's state (velocity from the previous
//! fix); tag readings have no place in it.

use super::{Fusion, Updated};
use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::eif::Eif;
use crate::track::Track;
use nalgebra::{Cholesky, Matrix2, Matrix3, Matrix6, Vector2, Vector3};
use proto::ClusterTime;
use proto::camera::CameraModel;
use proto::models::State;
use serde::{Deserialize, Serialize};

/// Maximum-likelihood fusion as a head's method.
#[derive(Debug)]
pub(super) struct Ml;

impl Fusion for Ml {
    fn distributed(&self) -> bool {
        false
    }

    fn fuses_rssi(&self) -> bool {
        false
    }

    fn absorb(&mut self, track: &mut Track, det: &Detection, node: &NodeInfo, cfg: &HeadConfig) {
        let lifted = if det.ground.is_some() {
            lift_ground(det, cfg.ml_depth, track.filter.mean()[2])
        } else {
            lift(&node.camera, &det.point, &det.cov, cfg.ml_depth)
        };
        if let Some(p) = lifted {
            track.ml_points.push(p);
        }
    }

    fn update(&mut self, track: &mut Track, now: ClusterTime) -> Updated {
        let points = std::mem::take(&mut track.ml_points);
        let Some((p, c)) = fuse(&points) else {
            return Updated::default();
        };
        let dt_prev = track.ml_prev.map(|(_, t0)| now.secs_since(t0));
        let mut mean = State::zeros();
        mean.fixed_rows_mut::<3>(0).copy_from(&p);
        let mut cov = Matrix6::identity() * crate::init::INIT_VELOCITY_SIGMA.powi(2);
        cov.fixed_view_mut::<3, 3>(0, 0).copy_from(&c);
        if let (Some((p0, _)), Some(dt)) = (track.ml_prev, dt_prev)
            && dt > 0.0
        {
            mean.fixed_rows_mut::<3>(3).copy_from(&((p - p0) / dt));
            cov.fixed_view_mut::<3, 3>(3, 3)
                .copy_from(&(c * (2.0 / (dt * dt))));
        }
        match Eif::from_gaussian(mean, cov) {
            Ok(f) => {
                track.filter = f;
                track.ml_prev = Some((p, now));
                Updated {
                    informed: true,
                    failure: None,
                }
            }
            Err(e) => Updated {
                informed: true,
                failure: Some(e),
            },
        }
    }
}

/// How ML chooses the depth Z_i of eq. 6.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum DepthHandling {
    /// The target moves on the plane `z`: intersect the ray; `sigma` (m) is the plane's
    /// thickness, the variance left along the world z axis.
    KnownPlane { z: f64, sigma: f64 },
    /// Z_i = `depth` (m) along each optical axis, with standard deviation `sigma` (m): the
    /// paper's "average value … with a high value for the variance".
    MeanDepth { depth: f64, sigma: f64 },
}

impl Default for DepthHandling {
    fn default() -> Self {
        DepthHandling::KnownPlane { z: 0.5, sigma: 0.05 }
    }
}

/// One camera's world point P_i^G (eq. 6–7) and its covariance Σ_i. `None` when the ray does
/// not meet the plane in front of the camera, or the depth is not positive.
pub fn lift(
    camera: &CameraModel,
    point: &Vector2<f64>,
    cov: &Matrix2<f64>,
    depth: DepthHandling,
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let rt = camera.pose.rotation.inverse();
    let centre = camera.pose.centre();
    match depth {
        DepthHandling::KnownPlane { z, sigma } => {
            let d = rt * Vector3::new(point.x, point.y, 1.0);
            if d.z.abs() < 1e-9 {
                return None;
            }
            let s = (z - centre.z) / d.z;
            if s <= 0.0 {
                return None;
            }
            let p = centre + d * s;
            // ∂P/∂x_k = s (r_k − d r_k,z / d_z), r_k the k-th column of Rᵀ.
            let mut jac = nalgebra::Matrix3x2::zeros();
            for k in 0..2 {
                let r = rt * Vector3::ith(k, 1.0);
                jac.set_column(k, &((r - d * (r.z / d.z)) * s));
            }
            let sigma_p =
                jac * cov * jac.transpose() + Matrix3::from_diagonal(&Vector3::new(0.0, 0.0, sigma * sigma));
            Some((p, sigma_p))
        }
        DepthHandling::MeanDepth { depth, sigma } => {
            if depth <= 0.0 {
                return None;
            }
            let pc = Vector3::new(point.x * depth, point.y * depth, depth);
            let p = rt * (pc - camera.pose.translation);
            let mut local = Matrix3::zeros();
            local
                .fixed_view_mut::<2, 2>(0, 0)
                .copy_from(&(cov * depth * depth));
            local[(2, 2)] = sigma * sigma;
            let r = rt.matrix();
            Some((p, r * local * r.transpose()))
        }
    }
}

/// A ground-plane person's floor position as a world point: on the known plane (with its σ),
/// or at the track's height `track_z` with [`crate::association::ground::GROUND_BIRTH_Z_SIGMA`]
/// when the depth is a mean depth.
pub fn lift_ground(
    det: &Detection,
    depth: DepthHandling,
    track_z: f64,
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let (z, sigma) = match depth {
        DepthHandling::KnownPlane { z, sigma } => (z, sigma),
        DepthHandling::MeanDepth { .. } => (track_z, crate::association::GROUND_BIRTH_Z_SIGMA),
    };
    let mut cov = Matrix3::zeros();
    cov.fixed_view_mut::<2, 2>(0, 0).copy_from(&det.cov);
    cov[(2, 2)] = sigma * sigma;
    let p = Vector3::new(det.point.x, det.point.y, z);
    (p.iter().all(|v| v.is_finite()) && cov.iter().all(|v| v.is_finite())).then_some((p, cov))
}

/// Fuse lifted points (eq. 4–5): x = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ z_i, Σ_x = (Σ Σ_i⁻¹)⁻¹. `None` with no
/// points or a singular sum.
pub fn fuse(points: &[(Vector3<f64>, Matrix3<f64>)]) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let (mut info, mut vec) = (Matrix3::zeros(), Vector3::zeros());
    for (p, c) in points {
        let ci = Cholesky::new(*c)?;
        info += ci.inverse();
        vec += ci.solve(p);
    }
    let chol = Cholesky::new(info)?;
    Some((chol.solve(&vec), chol.inverse()))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::init::tests::cam;

    #[test]
    fn known_plane_recovers_exact_points_and_fuses() {
        let target = Vector3::new(3.0, 2.0, 0.3);
        let cams = [
            cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]),
            cam([6.0, 0.5, 2.5], [3.0, 3.0, 0.0]),
        ];
        let cov = Matrix2::identity() * 3e-3_f64.powi(2);
        let lifted: Vec<_> = cams
            .iter()
            .map(|c| {
                lift(
                    c,
                    &c.normalized(&target).0,
                    &cov,
                    DepthHandling::KnownPlane { z: 0.3, sigma: 0.01 },
                )
                .unwrap()
            })
            .collect();
        for (p, _) in &lifted {
            assert!((p - target).norm() < 1e-9);
        }
        let (x, sx) = fuse(&lifted).unwrap();
        assert!((x - target).norm() < 1e-9);
        // eq. 5: the fused variance is below every single one.
        for (_, c) in &lifted {
            assert!(sx.trace() < c.trace());
        }
    }

    #[test]
    fn mean_depth_is_exact_at_the_true_depth_and_wrong_elsewhere() {
        let c = cam([0.0, 0.0, 2.5], [3.0, 3.0, 0.0]);
        let target = Vector3::new(3.0, 2.0, 0.3);
        let (p, z) = c.normalized(&target);
        let cov = Matrix2::identity() * 1e-6;
        let (at, _) = lift(&c, &p, &cov, DepthHandling::MeanDepth { depth: z, sigma: 1.0 }).unwrap();
        assert!((at - target).norm() < 1e-9);
        let (off, sc) = lift(
            &c,
            &p,
            &cov,
            DepthHandling::MeanDepth {
                depth: z + 1.0,
                sigma: 1.0,
            },
        )
        .unwrap();
        assert!((off - target).norm() > 0.9);
        assert!(sc.trace() > 0.99);
        assert!(lift(&c, &p, &cov, DepthHandling::KnownPlane { z: 3.0, sigma: 0.1 }).is_none());
    }
}
