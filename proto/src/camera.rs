//! The camera model: intrinsics, lens distortion (Heikkilä / OpenCV: k1 k2 p1 p2 k3, the
//! papers' a b c d plus k3) and 6-DoF pose.
//!
//! Pipeline, world → pixel: `X_c = R X_w + t`, normalized `p = [X_c/Z_c, Y_c/Z_c]`, distorted
//! `p_d = d_r p + d_t` (paper 000 eq. 17–18), pixel `u = fx x_d + cx, v = fy y_d + cy` (eq. 19).
//! Undistortion inverts the last two steps: [`CameraModel::undistort`] exactly (Newton
//! iteration), [`CameraModel::undistort_one_step`] as the paper approximates it.

use crate::msg::PoseWire;
use nalgebra::{Matrix2, Matrix3, Rotation3, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Pin-hole intrinsics in pixels, and the sensor size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
}

/// Lens distortion, OpenCV order. `k1 k2 p1 p2` are paper 000's `a b c d`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Distortion {
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub p1: f64,
    #[serde(default)]
    pub p2: f64,
    #[serde(default)]
    pub k3: f64,
}

/// World → camera rigid transform: `X_c = rotation · X_w + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub rotation: Rotation3<f64>,
    pub translation: Vector3<f64>,
}

impl Pose {
    /// From a Rodrigues vector and translation (OpenCV `rvec`, `tvec`).
    pub fn from_rvec_tvec(rvec: [f64; 3], tvec: [f64; 3]) -> Self {
        Pose {
            rotation: Rotation3::from_scaled_axis(Vector3::from(rvec)),
            translation: Vector3::from(tvec),
        }
    }

    /// A camera at `position` (world) looking at `target`, with world `up` (z up by default)
    /// mapping to image-up (camera −y).
    pub fn look_at(position: Vector3<f64>, target: Vector3<f64>, up: Vector3<f64>) -> Option<Self> {
        let z = (target - position).try_normalize(1e-12)?;
        let x = z.cross(&up).try_normalize(1e-12)?; // image right
        let y = z.cross(&x); // image down
        // Rows of R are the camera axes expressed in the world frame.
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        let rotation = Rotation3::from_matrix_unchecked(r);
        Some(Pose {
            rotation,
            translation: -(rotation * position),
        })
    }

    /// Camera centre in world coordinates.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation.inverse() * self.translation)
    }

    pub fn to_wire(&self) -> PoseWire {
        let r = self.rotation.scaled_axis();
        PoseWire {
            rvec: [r.x, r.y, r.z],
            tvec: [self.translation.x, self.translation.y, self.translation.z],
        }
    }

    pub fn from_wire(w: &PoseWire) -> Self {
        Pose::from_rvec_tvec(w.rvec, w.tvec)
    }

    pub fn world_to_camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }
}

/// Why a pixel could not be undistorted.
#[derive(Debug, Error, PartialEq)]
pub enum UndistortError {
    #[error("pixel ({0}, {1}) is not finite")]
    NotFinite(f64, f64),
    #[error("undistortion did not converge for pixel ({u}, {v}) (residual {residual:e})")]
    NoConvergence { u: f64, v: f64, residual: f64 },
}

/// Convergence threshold of [`CameraModel::undistort`], normalized units.
pub const UNDISTORT_TOLERANCE: f64 = 1e-12;
const UNDISTORT_MAX_ITERATIONS: usize = 50;

/// A calibrated camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraModel {
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
    pub pose: Pose,
}

impl CameraModel {
    /// Normalized pin-hole projection of a world point, with the camera-frame depth. Depth may
    /// be negative (behind the camera); the caller decides whether that matters.
    pub fn normalized(&self, world: &Vector3<f64>) -> (Vector2<f64>, f64) {
        let c = self.pose.world_to_camera(world);
        (Vector2::new(c.x / c.z, c.y / c.z), c.z)
    }

    /// World point → pixel, `None` when the point is not in front of the camera.
    pub fn project(&self, world: &Vector3<f64>) -> Option<Vector2<f64>> {
        let (p, depth) = self.normalized(world);
        (depth > 1e-9).then(|| self.normalized_to_pixel(&p))
    }

    /// Undistorted normalized point → distorted → pixel.
    pub fn normalized_to_pixel(&self, p: &Vector2<f64>) -> Vector2<f64> {
        self.distorted_to_pixel(&self.distortion.distort(p))
    }

    pub fn distorted_to_pixel(&self, d: &Vector2<f64>) -> Vector2<f64> {
        let k = &self.intrinsics;
        Vector2::new(k.fx * d.x + k.cx, k.fy * d.y + k.cy)
    }

    pub fn pixel_to_distorted(&self, px: &Vector2<f64>) -> Vector2<f64> {
        let k = &self.intrinsics;
        Vector2::new((px.x - k.cx) / k.fx, (px.y - k.cy) / k.fy)
    }

    /// Exact undistortion: the normalized point whose distorted projection is `px`.
    ///
    /// # Errors
    /// Non-finite input, or a pixel so far outside the lens model that Newton's method does not
    /// converge.
    pub fn undistort(&self, px: &Vector2<f64>) -> Result<Vector2<f64>, UndistortError> {
        if !(px.x.is_finite() && px.y.is_finite()) {
            return Err(UndistortError::NotFinite(px.x, px.y));
        }
        let target = self.pixel_to_distorted(px);
        self.distortion
            .undistort(&target)
            .ok_or_else(|| UndistortError::NoConvergence {
                u: px.x,
                v: px.y,
                residual: (self.distortion.distort(&target) - target).norm(),
            })
    }

    /// Paper 000 §6.1.2's approximation: the distortion terms evaluated at the distorted
    /// point, `p ≈ (p_d − d_t(p_d)) / d_r(p_d)`. Kept for comparison only.
    pub fn undistort_one_step(&self, px: &Vector2<f64>) -> Vector2<f64> {
        let d = self.pixel_to_distorted(px);
        let (radial, tangential) = self.distortion.terms(&d);
        (d - tangential) / radial
    }

    /// Unit ray direction in world coordinates through an undistorted normalized point.
    pub fn ray_world(&self, p: &Vector2<f64>) -> Vector3<f64> {
        (self.pose.rotation.inverse() * Vector3::new(p.x, p.y, 1.0)).normalize()
    }
}

impl Distortion {
    pub fn is_zero(&self) -> bool {
        *self == Distortion::default()
    }

    /// Radial factor d_r and tangential offset d_t at a normalized point (eq. 18 + k3).
    pub fn terms(&self, p: &Vector2<f64>) -> (f64, Vector2<f64>) {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let tangential = Vector2::new(
            2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        );
        (radial, tangential)
    }

    /// Distort a normalized point (eq. 17).
    pub fn distort(&self, p: &Vector2<f64>) -> Vector2<f64> {
        let (radial, tangential) = self.terms(p);
        p * radial + tangential
    }

    /// Jacobian of [`Distortion::distort`] at `p`.
    pub fn distort_jacobian(&self, p: &Vector2<f64>) -> Matrix2<f64> {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r2
        let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let (drx, dry) = (2.0 * x * dr, 2.0 * y * dr);
        Matrix2::new(
            radial + x * drx + 2.0 * self.p1 * y + 6.0 * self.p2 * x,
            x * dry + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            y * drx + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            radial + y * dry + 6.0 * self.p1 * y + 2.0 * self.p2 * x,
        )
    }

    /// Invert [`Distortion::distort`] by damped Newton iteration from the one-step estimate,
    /// then (if that fails) from `d` itself. A solution is accepted only where the lens map is
    /// orientation-preserving (`det J > 0`): beyond the fold of a strongly distorting polynomial
    /// a second, spurious preimage exists, and returning it would be silently wrong.
    /// `None` if no start converges to [`UNDISTORT_TOLERANCE`] on the unfolded branch.
    pub fn undistort(&self, d: &Vector2<f64>) -> Option<Vector2<f64>> {
        if self.is_zero() {
            return Some(*d);
        }
        let (radial, tangential) = self.terms(d);
        let one_step = if radial.abs() > 1e-6 {
            (d - tangential) / radial
        } else {
            *d
        };
        [one_step, *d]
            .into_iter()
            .filter_map(|start| self.newton(d, start))
            .find(|p| self.distort_jacobian(p).determinant() > 0.0)
    }

    fn newton(&self, d: &Vector2<f64>, start: Vector2<f64>) -> Option<Vector2<f64>> {
        let mut p = start;
        for _ in 0..UNDISTORT_MAX_ITERATIONS {
            let residual = self.distort(&p) - d;
            if residual.norm() <= UNDISTORT_TOLERANCE {
                return Some(p);
            }
            let step = self.distort_jacobian(&p).lu().solve(&residual)?;
            // Halve the step while it does not reduce the residual (fish-eye corners).
            let mut scale = 1.0;
            let mut next = p - step;
            while (self.distort(&next) - d).norm() > residual.norm() && scale > 1e-4 {
                scale *= 0.5;
                next = p - step * scale;
            }
            p = next;
        }
        ((self.distort(&p) - d).norm() <= 1e-9).then_some(p)
    }
}

impl CameraModel {
    /// Covariance of an undistorted normalized point given isotropic pixel noise `sigma_px`:
    /// the pixel covariance pushed through the inverse of the distortion Jacobian.
    pub fn normalized_covariance(&self, p: &Vector2<f64>, sigma_px: f64) -> Matrix2<f64> {
        let k = &self.intrinsics;
        let pix_to_dist = Matrix2::new(1.0 / k.fx, 0.0, 0.0, 1.0 / k.fy);
        let jac = self
            .distortion
            .distort_jacobian(p)
            .try_inverse()
            .unwrap_or_else(Matrix2::identity)
            * pix_to_dist;
        let c = jac * jac.transpose() * (sigma_px * sigma_px);
        0.5 * (c + c.transpose())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vectors_path() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/vectors/undistort_opencv.csv")
    }

    /// Every row of OpenCV's vectors is reproduced to ≤ 1e-7 by the exact undistortion, and
    /// the paper's one-step approximation is measurably worse.
    #[test]
    fn exact_undistortion_matches_opencv_vectors() {
        let path = vectors_path();
        let Ok(text) = std::fs::read_to_string(&path) else {
            panic!(
                "reference vectors missing at {} (shared/ must sit beside the repo)",
                path.display()
            );
        };
        let (mut rows, mut worst, mut worst_one_step) = (0, 0.0f64, 0.0f64);
        for line in text.lines().skip(1) {
            let f: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
            let cam = CameraModel {
                intrinsics: Intrinsics {
                    fx: f[3],
                    fy: f[3],
                    cx: f[4],
                    cy: f[5],
                    width: f[1] as u32,
                    height: f[2] as u32,
                },
                distortion: Distortion {
                    k1: f[6],
                    k2: f[7],
                    p1: f[8],
                    p2: f[9],
                    k3: 0.0,
                },
                pose: Pose::from_rvec_tvec([0.0; 3], [0.0; 3]),
            };
            let px = Vector2::new(f[10], f[11]);
            let want = Vector2::new(f[12], f[13]);
            let got = cam.undistort(&px).unwrap();
            worst = worst.max((got - want).norm());
            worst_one_step = worst_one_step.max((cam.undistort_one_step(&px) - want).norm());
            rows += 1;
        }
        assert!(rows > 10, "only {rows} rows read");
        assert!(worst <= 1e-7, "worst exact error {worst:e}");
        assert!(
            worst_one_step > 1e-4,
            "one-step approximation unexpectedly exact ({worst_one_step:e})"
        );
    }
}
