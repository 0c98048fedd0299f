//! Paper 004 §3.2.3, the 2D → 3D conversion unit: a person's box in the image becomes a
//! position, width and height in the world. The view rays through the box's two lower corners
//! meet the ground plane `z = 0`: their midpoint is the position, their distance the width.
//! The ray through the top-centre pixel meets the vertical plane through those two points: its
//! height is the person's. A box whose lower corners' rays do not meet the ground in front of
//! the camera (above the horizon) is dropped. Pixels are undistorted with `proto::camera`
//! first. The position's covariance is the lower corners' pixel covariance (from the sample
//! set's spread, plus a floor) pushed through the Jacobian of the ray geometry, taken by
//! central differences.
//!
//! Boxes are in the camera model's pixels: a tracker running on a half-resolution Bayer frame
//! scales its boxes by 2 first ([`crate::tracker::motion::State::scaled`]).

use crate::tracker::histogram::ColourHistogram;
use crate::tracker::manager::PersonEstimate;
use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};
use proto::ClusterTime;
use proto::camera::CameraModel;
use proto::msg::PixelBox;

/// Pixel step of the central differences, pixels.
const JACOBIAN_STEP_PX: f64 = 0.5;
/// A ray must fall at least this steeply (its direction's z) to meet the ground.
const MIN_DESCENT: f64 = 1e-9;

/// One person as the camera reports them on the ground plane.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundObservation {
    /// Midpoint of the lower corners' ground points, metres (world x, y).
    pub position: [f64; 2],
    /// Covariance of `position`: xx, xy, yy, m².
    pub cov: [f64; 3],
    pub width_m: f64,
    pub height_m: f64,
    pub captured: ClusterTime,
    pub histogram: ColourHistogram,
}

/// Where the view ray through a (distorted) pixel meets the ground plane `z = 0`; `None` when
/// the pixel cannot be undistorted or its ray does not descend to the ground in front of the
/// camera.
pub fn ground_point(camera: &CameraModel, px: [f64; 2]) -> Option<Vector3<f64>> {
    let p = camera.undistort(&Vector2::new(px[0], px[1])).ok()?;
    let d = camera.ray_world(&p);
    let c = camera.pose.centre();
    if d.z > -MIN_DESCENT || c.z <= 0.0 {
        return None;
    }
    let s = -c.z / d.z;
    Some(c + d * s)
}

/// 2×2 Jacobian of [`ground_point`]'s (x, y) with respect to the pixel, by central
/// differences; `None` when a neighbouring pixel is above the horizon.
fn ground_jacobian(camera: &CameraModel, px: [f64; 2]) -> Option<Matrix2<f64>> {
    let h = JACOBIAN_STEP_PX;
    let mut j = Matrix2::zeros();
    for axis in 0..2 {
        let (mut a, mut b) = (px, px);
        a[axis] += h;
        b[axis] -= h;
        let d = (ground_point(camera, a)? - ground_point(camera, b)?) / (2.0 * h);
        j[(0, axis)] = d.x;
        j[(1, axis)] = d.y;
    }
    Some(j)
}

/// The height where the ray through `px` meets the vertical plane through `left` and `right`.
fn height_on_plane(
    camera: &CameraModel,
    px: [f64; 2],
    left: &Vector3<f64>,
    right: &Vector3<f64>,
) -> Option<f64> {
    let c = camera.pose.centre();
    let along = right - left;
    // The plane's horizontal normal; for a zero-width box, the plane faces the camera.
    let normal = if along.norm() > 1e-9 {
        along.cross(&Vector3::z())
    } else {
        let towards = 0.5 * (left + right) - c;
        Vector3::new(towards.x, towards.y, 0.0)
    }
    .try_normalize(1e-12)?;
    let p = camera.undistort(&Vector2::new(px[0], px[1])).ok()?;
    let d = camera.ray_world(&p);
    let denom = normal.dot(&d);
    if denom.abs() < 1e-12 {
        return None;
    }
    let s = normal.dot(&(left - c)) / denom;
    (s > 0.0).then(|| (c + d * s).z).filter(|z| z.is_finite())
}

/// Convert a box (camera pixels) to a ground observation. `spread` is the covariance of the
/// box's (x, y, w, h) — centre and size, pixels² — from the sample set
/// ([`crate::tracker::filter::ParticleFilter::box_covariance`]); `corner_sigma_px` a floor added
/// to each lower-corner coordinate. `None` when the box is above the horizon.
pub fn to_ground(
    camera: &CameraModel,
    bbox: &PixelBox,
    spread: &[[f64; 4]; 4],
    corner_sigma_px: f64,
    captured: ClusterTime,
    histogram: ColourHistogram,
) -> Option<GroundObservation> {
    let (xmin, xmax) = (bbox.xmin as f64, bbox.xmax as f64);
    let (ymin, ymax) = (bbox.ymin as f64, bbox.ymax as f64);
    let (left_px, right_px) = ([xmin, ymax], [xmax, ymax]);
    let left = ground_point(camera, left_px)?;
    let right = ground_point(camera, right_px)?;
    let height = height_on_plane(camera, [0.5 * (xmin + xmax), ymin], &left, &right)?;
    // Lower corners (u_left, u_right, v) = A · (x, y, w, h).
    let a = nalgebra::Matrix3x4::new(1.0, 0.0, -0.5, 0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.5);
    let s = nalgebra::Matrix4::from_fn(|i, j| spread[i][j]);
    let corners = a * s * a.transpose() + Matrix3::identity() * corner_sigma_px.powi(2);
    // position = ½ (G(u_left, v) + G(u_right, v)).
    let (jl, jr) = (
        ground_jacobian(camera, left_px)?,
        ground_jacobian(camera, right_px)?,
    );
    let j = 0.5
        * Matrix2x3::new(
            jl[(0, 0)],
            jr[(0, 0)],
            jl[(0, 1)] + jr[(0, 1)],
            jl[(1, 0)],
            jr[(1, 0)],
            jl[(1, 1)] + jr[(1, 1)],
        );
    let cov = j * corners * j.transpose();
    let mid = 0.5 * (left + right);
    Some(GroundObservation {
        position: [mid.x, mid.y],
        cov: [cov[(0, 0)], 0.5 * (cov[(0, 1)] + cov[(1, 0)]), cov[(1, 1)]],
        width_m: (right - left).norm(),
        height_m: height,
        captured,
        histogram,
    })
}

/// [`to_ground`] for a tracked person's mean box, its sample spread and target histogram.
/// `lower_edge` is where the frame's foreground says the person's box ends
/// ([`crate::tracker::feet`]); it replaces the mean box's lower edge when it lies below the box's
/// top (the sample spread stays as it is: wider than the measured edge's, so on the safe side).
/// `scale` maps the tracker's pixels to the camera model's (2 for a half-resolution Bayer
/// frame, else 1).
pub fn observe(
    camera: &CameraModel,
    person: &PersonEstimate,
    lower_edge: Option<f32>,
    scale: f32,
    corner_sigma_px: f64,
    captured: ClusterTime,
) -> Option<GroundObservation> {
    let mut own = person.mean.bbox();
    if let Some(edge) = lower_edge.filter(|&e| e > own.ymin) {
        own.ymax = edge;
    }
    let bbox = PixelBox {
        xmin: own.xmin * scale,
        ymin: own.ymin * scale,
        xmax: own.xmax * scale,
        ymax: own.ymax * scale,
    };
    let s2 = (scale as f64).powi(2);
    let spread = person.box_covariance.map(|row| row.map(|v| v * s2));
    to_ground(
        camera,
        &bbox,
        &spread,
        corner_sigma_px,
        captured,
        person.histogram.clone(),
    )
}

#[cfg(test)]
mod tests;
