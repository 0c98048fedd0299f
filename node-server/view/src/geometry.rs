//! What the views draw, computed once on the server side: a camera's field of view on the floor
//! (the wedge of the live map) and its frustum (the 3D view, Foxglove), and a track's 2σ
//! position ellipse.
//!
//! A camera's view is the cone of rays through its image border: [`BORDER_SAMPLES`] pixels per
//! edge, undistorted with the camera's lens model, turned into world rays. Each ray is followed
//! until it leaves the room (the world's box: floor, walls, ceiling). The frustum is the camera
//! centre and the four corner rays' end points; the wedge is the ring of every border ray's end
//! dropped onto the floor — the part of the floor the camera sees, bounded by the room's walls
//! where its view reaches them. (Interior walls are not taken into account.)

use nalgebra::{UnitQuaternion, Vector2, Vector3};
use proto::camera::CameraModel;
use serde::{Deserialize, Serialize};

/// Pixels sampled along each image edge for the floor wedge (corners included once).
pub const BORDER_SAMPLES: usize = 6;

/// A camera as the views draw it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraGeometry {
    /// Centre of projection, world metres.
    pub position: [f64; 3],
    /// Camera → world rotation as a quaternion `[x, y, z, w]` (the camera looks along its +z,
    /// image right is +x, image down is +y).
    pub orientation: [f64; 4],
    /// Unit viewing direction (the optical axis) in the world.
    pub forward: [f64; 3],
    /// Horizontal and vertical field of view of the undistorted pin-hole, degrees.
    pub fov_deg: [f64; 2],
    /// Ring of floor points `[x, y]` bounding what the camera sees (the map's wedge).
    pub footprint: Vec<[f64; 2]>,
    /// End points of the rays through the image corners (top-left, top-right, bottom-right,
    /// bottom-left), where they leave the room.
    pub frustum: [[f64; 3]; 4],
}

/// Where a ray from `c` along `d` leaves the box `min`–`max` (a camera outside it, or a ray
/// that never leaves, stops at 100 m).
fn ray_end(c: &Vector3<f64>, d: &Vector3<f64>, min: [f64; 3], max: [f64; 3]) -> Vector3<f64> {
    let d = d.normalize();
    let mut t = 100.0f64;
    for i in 0..3 {
        let exit = if d[i] > 1e-12 {
            (max[i] - c[i]) / d[i]
        } else if d[i] < -1e-12 {
            (min[i] - c[i]) / d[i]
        } else {
            continue;
        };
        if exit >= 0.0 {
            t = t.min(exit);
        }
    }
    c + d * t
}

/// The world ray through pixel `(u, v)`: exact undistortion, or the distorted point itself where
/// the lens model does not converge (far outside it, at a strongly distorted corner).
fn pixel_ray(cam: &CameraModel, u: f64, v: f64) -> Vector3<f64> {
    let px = Vector2::new(u, v);
    let p = cam.undistort(&px).unwrap_or_else(|_| cam.pixel_to_distorted(&px));
    cam.ray_world(&p)
}

/// Pixels around the image border, clockwise from the top-left corner.
fn border(width: f64, height: f64) -> Vec<(f64, f64)> {
    let n = BORDER_SAMPLES.max(2) - 1;
    let mut out = Vec::with_capacity(4 * n);
    let step = |a: f64, b: f64, i: usize| a + (b - a) * i as f64 / n as f64;
    for i in 0..n {
        out.push((step(0.0, width, i), 0.0));
    }
    for i in 0..n {
        out.push((width, step(0.0, height, i)));
    }
    for i in 0..n {
        out.push((step(width, 0.0, i), height));
    }
    for i in 0..n {
        out.push((0.0, step(height, 0.0, i)));
    }
    out
}

impl CameraGeometry {
    /// The geometry of a calibrated camera in a room with corners `min` and `max`.
    pub fn new(cam: &CameraModel, min: [f64; 3], max: [f64; 3]) -> CameraGeometry {
        let k = &cam.intrinsics;
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        let c = cam.pose.centre();
        let footprint = border(w, h)
            .into_iter()
            .map(|(u, v)| {
                let e = ray_end(&c, &pixel_ray(cam, u, v), min, max);
                [e.x, e.y]
            })
            .collect();
        let corner = |u: f64, v: f64| {
            let e = ray_end(&c, &pixel_ray(cam, u, v), min, max);
            [e.x, e.y, e.z]
        };
        let frustum = [corner(0.0, 0.0), corner(w, 0.0), corner(w, h), corner(0.0, h)];
        let to_world = cam.pose.rotation.inverse();
        let q = UnitQuaternion::from_rotation_matrix(&to_world);
        let forward = to_world * Vector3::z();
        let fov = |size: f64, f: f64| 2.0 * (size / (2.0 * f)).atan().to_degrees();
        CameraGeometry {
            position: [c.x, c.y, c.z],
            orientation: [q.i, q.j, q.k, q.w],
            forward: [forward.x, forward.y, forward.z],
            fov_deg: [fov(w, k.fx), fov(h, k.fy)],
            footprint,
            frustum,
        }
    }
}

/// A 2σ position ellipse on the floor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ellipse {
    /// Semi-axes, metres (2σ along each principal direction), major first.
    pub semi_major: f64,
    pub semi_minor: f64,
    /// Angle of the major axis from world +x towards +y, radians.
    pub angle: f64,
}

impl Ellipse {
    /// The 2σ ellipse of a 2×2 covariance `[σxx, σxy, σyy]` (m²); `None` unless it is finite
    /// and positive semi-definite (within rounding).
    pub fn two_sigma(cov: [f64; 3]) -> Option<Ellipse> {
        let [a, b, c] = cov;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            return None;
        }
        let mean = 0.5 * (a + c);
        let r = (0.25 * (a - c) * (a - c) + b * b).sqrt();
        let (l1, l2) = (mean + r, mean - r);
        let tol = 1e-12 * (1.0 + a.abs() + c.abs());
        if l2 < -tol {
            return None;
        }
        Some(Ellipse {
            semi_major: 2.0 * l1.max(0.0).sqrt(),
            semi_minor: 2.0 * l2.max(0.0).sqrt(),
            angle: 0.5 * (2.0 * b).atan2(a - c),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proto::camera::{Distortion, Intrinsics, Pose};
    use std::f64::consts::FRAC_PI_4;

    #[test]
    fn ellipses_of_hand_covariances() {
        let e = Ellipse::two_sigma([4.0, 0.0, 1.0]).unwrap();
        assert_relative_eq!(e.semi_major, 4.0);
        assert_relative_eq!(e.semi_minor, 2.0);
        assert_relative_eq!(e.angle, 0.0);
        // [[2, 1], [1, 2]]: eigenvalues 3 and 1, major axis along (1, 1).
        let e = Ellipse::two_sigma([2.0, 1.0, 2.0]).unwrap();
        assert_relative_eq!(e.semi_major, 2.0 * 3f64.sqrt(), epsilon = 1e-12);
        assert_relative_eq!(e.semi_minor, 2.0, epsilon = 1e-12);
        assert_relative_eq!(e.angle, FRAC_PI_4, epsilon = 1e-12);
        // Major axis along y.
        let e = Ellipse::two_sigma([1.0, 0.0, 9.0]).unwrap();
        assert_relative_eq!(e.semi_major, 6.0);
        assert_relative_eq!(e.angle.abs(), std::f64::consts::FRAC_PI_2, epsilon = 1e-12);
        assert_eq!(Ellipse::two_sigma([1.0, 2.0, 1.0]), None); // indefinite
        assert_eq!(Ellipse::two_sigma([f64::NAN, 0.0, 1.0]), None);
    }

    fn camera(position: [f64; 3], look_at: [f64; 3]) -> CameraModel {
        CameraModel {
            intrinsics: Intrinsics {
                fx: 100.0,
                fy: 100.0,
                cx: 100.0,
                cy: 50.0,
                width: 200,
                height: 100,
            },
            distortion: Distortion::default(),
            pose: Pose::look_at(Vector3::from(position), Vector3::from(look_at), Vector3::z()).unwrap(),
        }
    }

    /// A camera 2 m up looking straight down (image right = world ... any): with fx = 100 and a
    /// 200 × 100 image the half-widths on the floor are 2 m × 100/100 = 2 m and 2 m × 50/100 = 1 m.
    #[test]
    fn a_downward_camera_sees_a_rectangle() {
        let cam = CameraModel {
            pose: Pose::look_at(
                Vector3::new(5.0, 5.0, 2.0),
                Vector3::new(5.0, 5.0, 0.0),
                Vector3::y(), // z is the view direction; y names image-up
            )
            .unwrap(),
            ..camera([0.0; 3], [1.0, 0.0, 0.0])
        };
        let g = CameraGeometry::new(&cam, [0.0; 3], [10.0, 10.0, 3.0]);
        assert_relative_eq!(g.forward[2], -1.0, epsilon = 1e-12);
        assert_relative_eq!(g.fov_deg[0], 90.0, epsilon = 1e-9);
        for p in &g.frustum {
            assert_relative_eq!(p[2], 0.0, epsilon = 1e-9);
            assert_relative_eq!((p[0] - 5.0).abs(), 2.0, epsilon = 1e-9);
            assert_relative_eq!((p[1] - 5.0).abs(), 1.0, epsilon = 1e-9);
        }
        assert_eq!(g.footprint.len(), 4 * (BORDER_SAMPLES - 1));
        for p in &g.footprint {
            assert!(
                (p[0] - 5.0).abs() <= 2.0 + 1e-9 && (p[1] - 5.0).abs() <= 1.0 + 1e-9,
                "{p:?}"
            );
        }
    }

    /// A horizontal camera 1 m up: its upper corners look above the horizon and end on the
    /// ceiling (3 m); its lower corners meet the floor at height / depression.
    #[test]
    fn rays_end_where_they_leave_the_room() {
        let g = CameraGeometry::new(
            &camera([0.0, 0.0, 1.0], [10.0, 0.0, 1.0]),
            [-1.0, -10.0, 0.0],
            [19.0, 10.0, 3.0],
        );
        let [tl, tr, br, bl] = g.frustum;
        // Upper corners: normalized (±1, −0.5) is direction (1, ±1, 0.5): the ceiling at t = 4.
        for top in [tl, tr] {
            assert_relative_eq!(top[2], 3.0, epsilon = 1e-9);
            assert_relative_eq!(top[0], 4.0, epsilon = 1e-9);
            assert_relative_eq!(top[1].abs(), 4.0, epsilon = 1e-9);
        }
        // Bottom corners: normalized y = 0.5 below the axis, so the floor is 1 m / 0.5 = 2 m ahead.
        for bottom in [br, bl] {
            assert_relative_eq!(bottom[2], 0.0, epsilon = 1e-9);
            assert_relative_eq!(bottom[0], 2.0, epsilon = 1e-9);
            assert_relative_eq!(bottom[1].abs(), 2.0, epsilon = 1e-9);
        }
        // The wedge stays inside the room.
        for p in &g.footprint {
            assert!(
                p[0] >= -1.0 - 1e-9 && p[0] <= 19.0 + 1e-9 && p[1].abs() <= 10.0 + 1e-9,
                "{p:?}"
            );
        }
        // The camera's +x is image right: looking along +x with z up, right is −y.
        assert!(tr[1] < 0.0 && tl[1] > 0.0);
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            g.orientation[3],
            g.orientation[0],
            g.orientation[1],
            g.orientation[2],
        ));
        let fwd = q * Vector3::z();
        assert_relative_eq!(fwd.x, 1.0, epsilon = 1e-12);
    }
}
