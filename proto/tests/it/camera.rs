//! The camera model: exact undistortion inverts distortion, `look_at` aims, Jacobians match
//! finite differences.

use approx::assert_relative_eq;
use nalgebra::{Matrix2, Vector2, Vector3};
use proptest::prelude::*;
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose, UndistortError};

pub fn intrinsics() -> impl Strategy<Value = Intrinsics> {
    (
        0.5..1.5f64,
        0.9..1.1f64,
        -20.0..20.0f64,
        -20.0..20.0f64,
        prop::sample::select(vec![(352u32, 288u32), (640, 480), (1920, 1080)]),
    )
        .prop_map(|(f, aspect, dx, dy, (width, height))| Intrinsics {
            // Horizontal field of view between 37° and 90°.
            fx: f * f64::from(width),
            fy: f * f64::from(width) * aspect,
            cx: f64::from(width) / 2.0 + dx,
            cy: f64::from(height) / 2.0 + dy,
            width,
            height,
        })
}

pub fn distortion() -> impl Strategy<Value = Distortion> {
    (
        -0.45..0.15f64,
        -0.1..0.25f64,
        -0.005..0.005f64,
        -0.005..0.005f64,
        -0.08..0.08f64,
    )
        .prop_map(|(k1, k2, p1, p2, k3)| Distortion { k1, k2, p1, p2, k3 })
}

/// Largest normalized radius of the image's corners, undistorted-side estimate.
fn corner_radius(k: &Intrinsics) -> f64 {
    let xs = [-k.cx / k.fx, (f64::from(k.width) - k.cx) / k.fx];
    let ys = [-k.cy / k.fy, (f64::from(k.height) - k.cy) / k.fy];
    xs.iter()
        .flat_map(|x| ys.iter().map(move |y| (x * x + y * y).sqrt()))
        .fold(0.0, f64::max)
}

/// Whether `r ↦ r·d_r(r)` rises steeply enough up to `r_max` for the lens to be invertible there
/// (real lenses are over their image; random coefficients need not be).
fn radially_invertible(d: &Distortion, r_max: f64) -> bool {
    (0..=200).all(|i| {
        let r = r_max * 1.1 * f64::from(i) / 200.0;
        let r2 = r * r;
        1.0 + 3.0 * d.k1 * r2 + 5.0 * d.k2 * r2 * r2 + 7.0 * d.k3 * r2 * r2 * r2 > 0.3
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// distort ∘ exact undistort is the identity to ≤ 1e-9 (normalized) anywhere over the image,
    /// k3 included; and the pixel round trip through `CameraModel` agrees.
    #[test]
    fn exact_undistortion_inverts_distortion(k in intrinsics(), d in distortion(), fu in 0.0..1.0f64, fv in 0.0..1.0f64) {
        prop_assume!(radially_invertible(&d, corner_radius(&k)));
        let cam = CameraModel { intrinsics: k, distortion: d, pose: Pose::from_rvec_tvec([0.0; 3], [0.0; 3]) };
        // An undistorted point whose (undistorted) pixel lies on the image.
        let p = cam.pixel_to_distorted(&Vector2::new(fu * f64::from(k.width), fv * f64::from(k.height)));
        let back = d.undistort(&d.distort(&p)).expect("converges");
        prop_assert!((back - p).norm() <= 1e-9, "p {p:?} back {back:?}");
        let px = cam.normalized_to_pixel(&p);
        let via_pixel = cam.undistort(&px).unwrap();
        prop_assert!((via_pixel - p).norm() <= 1e-9);
    }

    /// `distort_jacobian` matches central finite differences.
    #[test]
    fn distortion_jacobian_matches_finite_differences(d in distortion(), x in -0.8..0.8f64, y in -0.6..0.6f64) {
        let p = Vector2::new(x, y);
        let h = 1e-6;
        let mut fd = Matrix2::zeros();
        for j in 0..2 {
            let mut e = Vector2::zeros();
            e[j] = h;
            fd.set_column(j, &((d.distort(&(p + e)) - d.distort(&(p - e))) / (2.0 * h)));
        }
        let jac = d.distort_jacobian(&p);
        prop_assert!((jac - fd).abs().max() <= 1e-7, "analytic {jac} fd {fd}");
    }

    /// `look_at` puts the target at the principal point, in front, with world up pointing to
    /// image up, and a proper rotation.
    #[test]
    fn look_at_centres_the_target(
        k in intrinsics(),
        d in distortion(),
        pos in prop::array::uniform3(-10.0..10.0f64),
        target in prop::array::uniform3(-10.0..10.0f64),
    ) {
        let (pos, target) = (Vector3::from(pos), Vector3::from(target));
        let dir = target - pos;
        prop_assume!(dir.norm() > 0.1 && dir.z.abs() < 0.99 * dir.norm());
        let pose = Pose::look_at(pos, target, Vector3::z()).unwrap();
        let cam = CameraModel { intrinsics: k, distortion: d, pose };
        let px = cam.project(&target).unwrap();
        prop_assert!((px - Vector2::new(k.cx, k.cy)).norm() <= 1e-9, "{px:?}");
        let (_, depth) = cam.normalized(&target);
        assert_relative_eq!(depth, dir.norm(), max_relative = 1e-12);
        assert_relative_eq!(pose.rotation.matrix().determinant(), 1.0, epsilon = 1e-12);
        assert_relative_eq!(pose.centre(), pos, epsilon = 1e-9);
        let above = cam.normalized(&(target + Vector3::z() * 0.01)).0;
        prop_assert!(above.y < 0.0, "up should map to image up (−y), got {above:?}");
        // The wire form carries the same pose.
        let back = Pose::from_wire(&pose.to_wire());
        assert_relative_eq!(back.rotation.matrix(), pose.rotation.matrix(), epsilon = 1e-9);
        assert_relative_eq!(back.translation, pose.translation, epsilon = 1e-12);
    }
}

#[test]
fn non_finite_pixels_are_rejected() {
    let cam = CameraModel {
        intrinsics: Intrinsics {
            fx: 400.0,
            fy: 400.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        distortion: Distortion {
            k1: -0.2,
            ..Distortion::default()
        },
        pose: Pose::from_rvec_tvec([0.0; 3], [0.0; 3]),
    };
    assert!(matches!(
        cam.undistort(&Vector2::new(f64::NAN, 1.0)),
        Err(UndistortError::NotFinite(..))
    ));
    assert!(matches!(
        cam.undistort(&Vector2::new(1.0, f64::INFINITY)),
        Err(UndistortError::NotFinite(..))
    ));
    // Behind the camera is not projected.
    assert!(cam.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
}

/// The normalized covariance of an undistorted point: σ²/f² without distortion, and the pixel
/// covariance pulled back through the distortion Jacobian with it.
#[test]
fn normalized_covariance_pulls_pixel_noise_back() {
    let mut cam = CameraModel {
        intrinsics: Intrinsics {
            fx: 400.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        distortion: Distortion::default(),
        pose: Pose::from_rvec_tvec([0.0; 3], [0.0; 3]),
    };
    let p = Vector2::new(0.3, -0.2);
    let c = cam.normalized_covariance(&p, 2.0);
    assert_relative_eq!(
        c,
        Matrix2::new(4.0 / 160_000.0, 0.0, 0.0, 4.0 / 250_000.0),
        epsilon = 1e-15
    );
    cam.distortion = Distortion {
        k1: -0.2,
        k2: 0.05,
        p1: 0.001,
        p2: -0.002,
        k3: 0.01,
    };
    let c = cam.normalized_covariance(&p, 2.0);
    // Push it forward again: J C Jᵀ scaled to pixels must give σ² I.
    let j = cam.distortion.distort_jacobian(&p);
    let px =
        Matrix2::new(400.0, 0.0, 0.0, 500.0) * j * c * j.transpose() * Matrix2::new(400.0, 0.0, 0.0, 500.0);
    assert_relative_eq!(px, Matrix2::identity() * 4.0, epsilon = 1e-9);
}

/// A strongly distorting lens far out (r = 2, beyond where proptest's cameras go): the exact
/// undistortion either finds the true point or reports failure — never the spurious preimage
/// on the far side of the polynomial's fold.
#[test]
fn undistortion_never_returns_a_folded_preimage() {
    let d = Distortion {
        k1: -0.088_539_096_460_452_97,
        k2: 0.245_884_464_660_282_2,
        p1: 0.0,
        p2: 0.0,
        k3: -0.029_237_533_396_607_07,
    };
    for p in [
        Vector2::new(1.511_345_300_705_675, -1.333_333_333_333_333_3),
        Vector2::new(0.5, 0.2),
        Vector2::new(-1.2, 0.9),
    ] {
        match d.undistort(&d.distort(&p)) {
            Some(back) => assert!((back - p).norm() < 1e-9, "p {p:?} came back as {back:?}"),
            None => eprintln!("p {p:?}: reported as not converging"),
        }
    }
    let near = Vector2::new(0.5, 0.2);
    assert!((d.undistort(&d.distort(&near)).unwrap() - near).norm() < 1e-9);
}
