//! Shared models: Jacobians against central finite differences, the information form against
//! the covariance form, motion noise positive definite.

use approx::assert_relative_eq;
use nalgebra::{DMatrix, Matrix6, SMatrix, SVector, Vector3};
use proptest::prelude::*;
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose};
use proto::models::{self, MotionModel, RssiModel, State, information_contribution};

fn state() -> impl Strategy<Value = State> {
    (
        prop::array::uniform3(-5.0..5.0f64),
        prop::array::uniform3(-2.0..2.0f64),
    )
        .prop_map(|(p, v)| State::new(p[0], p[1], p[2], v[0], v[1], v[2]))
}

/// A camera 4–8 m from the origin looking at a point near it.
fn camera() -> impl Strategy<Value = CameraModel> {
    (
        prop::array::uniform3(-1.0..1.0f64),
        4.0..8.0f64,
        0.0..std::f64::consts::TAU,
        0.2..1.2f64,
    )
        .prop_map(|(aim, dist, az, el)| {
            let pos = Vector3::new(
                dist * el.cos() * az.cos(),
                dist * el.cos() * az.sin(),
                dist * el.sin(),
            );
            CameraModel {
                intrinsics: Intrinsics {
                    fx: 500.0,
                    fy: 500.0,
                    cx: 320.0,
                    cy: 240.0,
                    width: 640,
                    height: 480,
                },
                distortion: Distortion::default(),
                pose: Pose::look_at(pos, Vector3::from(aim), Vector3::z()).unwrap(),
            }
        })
}

/// Central differences of `f` at `x`, one state component at a time.
fn numeric_jacobian<const M: usize>(f: impl Fn(&State) -> SVector<f64, M>, x: &State) -> SMatrix<f64, M, 6> {
    let h = 1e-6;
    let mut j = SMatrix::<f64, M, 6>::zeros();
    for k in 0..6 {
        let mut e = State::zeros();
        e[k] = h;
        j.set_column(k, &((f(&(x + e)) - f(&(x - e))) / (2.0 * h)));
    }
    j
}

/// A random symmetric positive-definite n×n matrix `A Aᵀ + εI`.
fn spd(n: usize) -> impl Strategy<Value = DMatrix<f64>> {
    prop::collection::vec(-2.0..2.0f64, n * n).prop_map(move |a| {
        let a = DMatrix::from_vec(n, n, a);
        &a * a.transpose() + DMatrix::identity(n, n) * 0.05
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn pinhole_jacobian_matches_finite_differences(cam in camera(), x in state()) {
        let (_, depth) = cam.normalized(&models::position(&x));
        prop_assume!(depth > 0.5);
        let (h, jac) = models::pinhole(&cam, &x).unwrap();
        let (want, _) = cam.normalized(&models::position(&x));
        assert_relative_eq!(h, want, epsilon = 1e-12);
        let fd = numeric_jacobian(|s| models::pinhole(&cam, s).unwrap().0, &x);
        prop_assert!((jac - fd).abs().max() <= 1e-6 * (1.0 + fd.abs().max()), "analytic {jac} fd {fd}");
        // Position only: the velocity columns are zero.
        prop_assert!(jac.fixed_view::<2, 3>(0, 3).iter().all(|v| *v == 0.0));
    }

    #[test]
    fn pinhole_previous_jacobian_matches_finite_differences(cam in camera(), x in state(), dt in 0.01..0.5f64) {
        let back = models::position(&x) - Vector3::new(x[3], x[4], x[5]) * dt;
        prop_assume!(cam.normalized(&back).1 > 0.5);
        let (h, jac) = models::pinhole_previous(&cam, &x, dt).unwrap();
        assert_relative_eq!(h, cam.normalized(&back).0, epsilon = 1e-12);
        let fd = numeric_jacobian(|s| models::pinhole_previous(&cam, s, dt).unwrap().0, &x);
        prop_assert!((jac - fd).abs().max() <= 1e-6 * (1.0 + fd.abs().max()), "analytic {jac} fd {fd}");
    }

    #[test]
    fn rssi_jacobian_matches_finite_differences(
        node in prop::array::uniform3(-5.0..5.0f64),
        x in state(),
        a in -40.0..-5.0f64,
        b in -70.0..-30.0f64,
        linear in any::<bool>(),
    ) {
        let node = Vector3::from(node);
        prop_assume!((models::position(&x) - node).norm() > 0.3);
        let model = if linear {
            RssiModel::Linear { a: a / 10.0, b, variance: 9.0 }
        } else {
            RssiModel::LogDistance { a, b, variance: 16.0 }
        };
        let (h, jac) = model.measurement(&node, &x);
        assert_relative_eq!(h, model.predict((models::position(&x) - node).norm()), epsilon = 1e-12);
        let fd = numeric_jacobian(|s| SVector::<f64, 1>::new(model.measurement(&node, s).0), &x);
        prop_assert!((jac - fd).abs().max() <= 1e-6 * (1.0 + fd.abs().max()), "analytic {jac} fd {fd}");
    }

    #[test]
    fn ground_model_is_where_the_target_stood_and_its_jacobian_matches(x in state(), age in -0.5..0.5f64) {
        let (h, jac) = models::ground_aged(&x, age);
        assert_relative_eq!(h[0], x[0] - age * x[3], epsilon = 1e-12);
        assert_relative_eq!(h[1], x[1] - age * x[4], epsilon = 1e-12);
        let fd = numeric_jacobian(|s| models::ground_aged(s, age).0, &x);
        prop_assert!((jac - fd).abs().max() <= 1e-6, "analytic {jac} fd {fd}");
        // The height is not observed.
        prop_assert!(jac.column(2).iter().chain(jac.column(5).iter()).all(|v| *v == 0.0));
    }

    /// A ground observation folded in information form moves the mean by the Kalman gain and
    /// the gate is the innovation's Mahalanobis distance.
    #[test]
    fn ground_information_is_the_kalman_update(
        sigma in spd(6),
        r in spd(2),
        x in state(),
        z in prop::array::uniform2(-5.0..5.0f64),
        age in 0.0..0.3f64,
    ) {
        let p = Matrix6::from_iterator(sigma.iter().copied());
        let r = nalgebra::Matrix2::from_iterator(r.iter().copied());
        let z = nalgebra::Vector2::from(z);
        let (omega, xi) = models::ground_contribution_aged(&z, &r, &x, age).unwrap();
        let info = p.try_inverse().unwrap();
        let post_cov = (info + omega).try_inverse().unwrap();
        let post_mean = post_cov * (info * x + xi);
        let (h, jac) = models::ground_aged(&x, age);
        let s = jac * p * jac.transpose() + r;
        let k = p * jac.transpose() * s.try_inverse().unwrap();
        let want = x + k * (z - h);
        prop_assert!((post_mean - want).abs().max() <= 1e-6 * (1.0 + want.abs().max()), "{post_mean} vs {want}");
        let d2 = models::ground_gate_distance2(&x, &p, &z, &r, age).unwrap();
        let nu = z - h;
        assert_relative_eq!(d2, nu.dot(&(s.try_inverse().unwrap() * nu)), max_relative = 1e-6);
    }

    /// Folding one measurement in information form (Ω̄ + Hᵀ Q⁻¹ H, ξ̄ + ξ_i) gives the same
    /// posterior as the covariance-form (Kalman) update with the same linearization.
    #[test]
    fn information_form_equals_covariance_form(
        sigma in spd(6),
        q in spd(2),
        h in prop::collection::vec(-3.0..3.0f64, 12),
        mean in state(),
        z in prop::array::uniform2(-1.0..1.0f64),
        predicted in prop::array::uniform2(-1.0..1.0f64),
    ) {
        let sigma = Matrix6::from_iterator(sigma.iter().copied());
        let q = SMatrix::<f64, 2, 2>::from_iterator(q.iter().copied());
        let h = SMatrix::<f64, 2, 6>::from_row_slice(&h);
        let (z, predicted) = (SVector::<f64, 2>::from(z), SVector::<f64, 2>::from(predicted));
        let (omega_i, xi_i) = information_contribution(&z, &predicted, &h, &q, &mean).unwrap();
        // Ω_i is Hᵀ Q⁻¹ H.
        let qinv = q.try_inverse().unwrap();
        assert_relative_eq!(omega_i, h.transpose() * qinv * h, epsilon = 1e-8, max_relative = 1e-8);
        // Covariance form.
        let s = h * sigma * h.transpose() + q;
        let k = sigma * h.transpose() * s.try_inverse().unwrap();
        let mean_cov = mean + k * (z - predicted);
        let sigma_cov = (Matrix6::identity() - k * h) * sigma;
        // Information form.
        let omega_prior = sigma.try_inverse().unwrap();
        let omega = omega_prior + omega_i;
        let xi = omega_prior * mean + xi_i;
        let sigma_info = omega.try_inverse().unwrap();
        let mean_info = sigma_info * xi;
        let scale = sigma.abs().max();
        prop_assert!((sigma_info - sigma_cov).abs().max() <= 1e-7 * scale, "Σ differs");
        prop_assert!((mean_info - mean_cov).norm() <= 1e-7 * (1.0 + mean_cov.norm()) * (1.0 + scale));
    }

    /// The RSSI half, scalar: the same agreement through `rssi_contribution`.
    #[test]
    fn rssi_contribution_equals_covariance_form(sigma in spd(6), x in state(), dbm in -90.0..-40.0f64) {
        let sigma = Matrix6::from_iterator(sigma.iter().copied());
        let node = Vector3::new(6.0, -1.0, 2.5);
        let model = RssiModel::default();
        let (omega_i, xi_i) = models::rssi_contribution(&model, &node, dbm, &x).unwrap();
        let (h, jac) = model.measurement(&node, &x);
        let s = (jac * sigma * jac.transpose())[(0, 0)] + model.variance();
        let k = sigma * jac.transpose() / s;
        let mean_cov = x + k * (dbm - h);
        let omega = sigma.try_inverse().unwrap() + omega_i;
        let mean_info = omega.try_inverse().unwrap() * (sigma.try_inverse().unwrap() * x + xi_i);
        prop_assert!((mean_info - mean_cov).norm() <= 1e-7 * (1.0 + mean_cov.norm()) * (1.0 + sigma.abs().max()));
    }

    #[test]
    fn process_noise_is_spd(q in prop::array::uniform3(1e-4..10.0f64), dt in 1e-3..5.0f64) {
        let r = MotionModel { accel_psd: q }.process_noise(dt);
        prop_assert_eq!(r, r.transpose());
        let eig = r.symmetric_eigenvalues();
        prop_assert!(eig.min() > 0.0, "eigenvalues {eig}");
        prop_assert!(r.cholesky().is_some());
    }
}

/// A noise matrix that is not positive definite gives `None`, not a panic.
#[test]
fn non_spd_noise_is_refused() {
    let h = SMatrix::<f64, 1, 6>::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let z = SVector::<f64, 1>::new(1.0);
    assert!(
        information_contribution(&z, &z, &h, &SMatrix::<f64, 1, 1>::new(-1.0), &State::zeros()).is_none()
    );
}

/// Constant velocity: one step moves the position by v·dt and keeps the velocity.
#[test]
fn transition_moves_position_by_velocity() {
    let m = MotionModel::default();
    let x = State::new(1.0, 2.0, 0.5, 0.4, -0.2, 0.0);
    assert_relative_eq!(
        m.predict_mean(&x, 0.5),
        State::new(1.2, 1.9, 0.5, 0.4, -0.2, 0.0),
        epsilon = 1e-15
    );
    // The process noise is the integral of white acceleration: Var(pos) = q dt³/3.
    let r = m.process_noise(2.0);
    assert_relative_eq!(r[(0, 0)], 0.25 * 8.0 / 3.0, epsilon = 1e-15);
    assert_relative_eq!(r[(0, 3)], 0.25 * 4.0 / 2.0, epsilon = 1e-15);
    assert_relative_eq!(r[(3, 3)], 0.25 * 2.0, epsilon = 1e-15);
}

/// The survey fit recovers a known law from noisy pairs, estimates the noise as its variance,
/// and refuses what cannot determine a line.
#[test]
fn log_distance_fit_recovers_a_law_and_its_variance() {
    use proto::models::fit_log_distance;
    // A deterministic ±2 dB alternation: variance 4 (times n/(n−2)).
    let pairs: Vec<(f64, f64)> = (0..200)
        .map(|k| {
            let d = 1.0 + 0.05 * k as f64;
            let e = if k % 2 == 0 { 2.0 } else { -2.0 };
            (d, -26.0 * d.log10() - 48.0 + e)
        })
        .collect();
    let Some(RssiModel::LogDistance { a, b, variance }) = fit_log_distance(&pairs) else {
        panic!("no log-distance fit");
    };
    assert!((a + 26.0).abs() < 0.5, "a = {a}");
    assert!((b + 48.0).abs() < 0.3, "b = {b}");
    assert!((variance - 4.0).abs() < 0.2, "variance = {variance}");
    assert!(fit_log_distance(&pairs[..2]).is_none());
    assert!(fit_log_distance(&[(3.0, -60.0); 10]).is_none());
    assert!(fit_log_distance(&[(f64::NAN, -60.0), (2.0, f64::INFINITY), (1.0, -50.0)]).is_none());
}

/// An RSSI packet received 0.3 s before the mean's time, from a target moving at 1 m/s, is
/// read as the range to where the target was then: fused alone into a prior that is right, it
/// moves nothing; taken as current, it drags the position.
#[test]
fn an_aged_rssi_packet_is_the_range_to_where_the_target_was() {
    let model = RssiModel::LogDistance {
        a: -25.0,
        b: -48.0,
        variance: 1.0,
    };
    let node = Vector3::new(0.0, 0.0, 2.5);
    let mean = State::new(3.0, 1.0, 0.25, 1.0, 0.0, 0.0);
    let back = models::back_in_time(&mean, 0.3);
    assert_relative_eq!(models::position(&back), Vector3::new(2.7, 1.0, 0.25));
    let dbm = model.predict((models::position(&back) - node).norm());
    let prior_info = Matrix6::identity() * 100.0;
    let fuse = |age: f64| {
        let (o, x) = models::rssi_contribution_aged(&model, &node, dbm, &mean, age).unwrap();
        (prior_info + o)
            .cholesky()
            .unwrap()
            .solve(&(prior_info * mean + x))
    };
    let aged = fuse(0.3);
    assert!((aged - mean).norm() < 1e-9, "{aged}");
    let as_current = fuse(0.0);
    assert!(
        (as_current - mean).fixed_rows::<3>(0).norm() > 0.01,
        "{as_current}"
    );
    assert_eq!(
        models::rssi_contribution_aged(&model, &node, dbm, &mean, 0.0),
        models::rssi_contribution(&model, &node, dbm, &mean)
    );
}
