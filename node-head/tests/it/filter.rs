//! The information filter against a covariance-form EKF on the same inputs, and its
//! consistency (NEES) over many seeded runs.

use crate::sim::{ONE_TARGET, Sim, observe, ring_scenario};
use nalgebra::{DMatrix, DVector, Matrix6, Vector6};
use node_head::eif::{Accumulator, Eif};
use node_head::ekf::{Block, Ekf};
use proto::ClusterTime;
use proto::models::{MotionModel, State, camera_contribution, pinhole};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn rel(a: f64, b: f64, scale: f64) -> f64 {
    (a - b).abs() / scale.max(1e-12)
}

#[test]
fn eif_agrees_with_ekf_to_1e9() {
    let scenario = ring_scenario(8, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let mut sim = Sim::new(&scenario, 7);
    let motion = scenario.method.motion;
    let dt = 0.2;
    let t0 = sim.truth(0, ClusterTime::ZERO);
    let mean0 = t0 + Vector6::new(0.1, -0.1, 0.05, 0.0, 0.0, 0.0);
    let cov0 = Matrix6::from_diagonal(&Vector6::new(0.1, 0.1, 0.05, 0.5, 0.5, 0.05));
    let mut eif = Eif::from_gaussian(mean0, cov0).unwrap();
    let mut ekf = Ekf::new(mean0, cov0);
    let mut worst = 0.0f64;
    let mut updates = 0;
    for k in 1..100 {
        let t = ClusterTime::from_millis(k * 200);
        eif.predict(&motion, dt).unwrap();
        ekf.predict(&motion, dt);
        let mut acc = Accumulator::default();
        let mut blocks = Vec::new();
        for c in 0..sim.cams.len() {
            // Drop a camera now and then so the measurement set varies.
            if sim.coin(0.2) {
                continue;
            }
            let Some((point, cov)) = sim.detect(c, 0, t) else {
                continue;
            };
            let model = sim.cams[c].model;
            let (o, x) = camera_contribution(&model, &point, &cov, eif.mean()).unwrap();
            acc.add(&o, &x);
            let (h, jac) = pinhole(&model, &ekf.mean).unwrap();
            blocks.push(Block {
                z: DVector::from_column_slice(point.as_slice()),
                predicted: DVector::from_column_slice(h.as_slice()),
                jac: DMatrix::from_fn(2, 6, |i, j| jac[(i, j)]),
                noise: DMatrix::from_fn(2, 2, |i, j| cov[(i, j)]),
            });
        }
        updates += usize::from(!blocks.is_empty());
        eif.update(&acc).unwrap();
        ekf.update(&blocks).unwrap();
        let cov_scale = ekf.cov.abs().max();
        for i in 0..6 {
            worst = worst.max(rel(eif.mean()[i], ekf.mean[i], 1.0 + ekf.mean[i].abs()));
            for j in 0..6 {
                worst = worst.max(rel(eif.cov()[(i, j)], ekf.cov[(i, j)], cov_scale));
            }
        }
    }
    assert!(updates > 90, "only {updates} steps had measurements");
    assert!(worst <= 1e-9, "EIF and EKF differ by {worst:e}");
}

/// The consistency tests' world: six ring cameras, the motion model (the truth follows the
/// filter's own, so that consistency is what is tested), and the initial covariance the truth
/// is drawn from.
fn consistency_setup() -> (Vec<proto::camera::CameraModel>, MotionModel, Matrix6<f64>) {
    let scenario = ring_scenario(6, "distributed-eif", "all-on", 0.0, ONE_TARGET);
    let cams = Sim::new(&scenario, 0).cams.iter().map(|c| c.model).collect();
    let motion = MotionModel {
        accel_psd: [0.05, 0.05, 0.001],
    };
    let cov0 = Matrix6::from_diagonal(&Vector6::new(0.04, 0.04, 0.01, 0.04, 0.04, 0.001));
    (cams, motion, cov0)
}

/// χ² quantile by Wilson–Hilferty (accurate to a fraction of a percent for k ≥ 30).
fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

#[test]
fn nees_stays_in_the_95_percent_band() {
    let (cams, motion, cov0) = consistency_setup();
    let (runs, steps, dt, sigma_px) = (40usize, 60usize, 0.2, 4.0);
    let mut nees = vec![0.0; steps];
    let l0 = cov0.cholesky().unwrap().l();
    let lr = motion.process_noise(dt).cholesky().unwrap().l();
    for run in 0..runs {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + run as u64);
        let normal6 = |rng: &mut ChaCha8Rng| State::from_fn(|_, _| StandardNormal.sample(rng));
        let mean0 = State::new(4.0, 4.0, 0.3, 0.2, -0.1, 0.0);
        let mut truth = mean0 + l0 * normal6(&mut rng);
        let mut f = Eif::from_gaussian(mean0, cov0).unwrap();
        for e in nees.iter_mut() {
            truth = motion.transition(dt) * truth + lr * normal6(&mut rng);
            f.predict(&motion, dt).unwrap();
            let mut acc = Accumulator::default();
            for cam in &cams {
                let p = truth.fixed_rows::<3>(0).into_owned();
                if let Some((point, cov)) = observe(cam, &p, sigma_px, &mut rng)
                    && let Some((o, x)) = camera_contribution(cam, &point, &cov, f.mean())
                {
                    acc.add(&o, &x);
                }
            }
            f.update(&acc).unwrap();
            let err = truth - f.mean();
            *e += err.dot(&(f.omega() * err)) / runs as f64;
        }
    }
    let dof = 6.0 * runs as f64;
    let (lo, hi) = (
        chi2_quantile(dof, -1.96) / runs as f64,
        chi2_quantile(dof, 1.96) / runs as f64,
    );
    let inside = nees.iter().filter(|&&e| e >= lo && e <= hi).count();
    let mean_nees = nees.iter().sum::<f64>() / steps as f64;
    assert!(
        inside as f64 >= 0.9 * steps as f64,
        "only {inside}/{steps} steps inside [{lo:.2}, {hi:.2}]; mean NEES {mean_nees:.2}"
    );
}

/// Cameras that are not frame-synchronized with the steps: each answers with a frame a fixed
/// age old. Fused as current, the frames make the estimate trail the target; aged
/// (`camera_contribution_aged`), they do not, the error falls, and the filter stays consistent.
#[test]
fn aged_frames_remove_the_lag_and_keep_the_filter_consistent() {
    use proto::models::camera_contribution_aged;
    let (cams, motion, cov0) = consistency_setup();
    let (runs, steps, sub, dt, sigma_px) = (40usize, 60usize, 10usize, 0.2, 4.0);
    let h = dt / sub as f64;
    let lr = motion.process_noise(h).cholesky().unwrap().l();
    let l0 = cov0.cholesky().unwrap().l();
    // Camera c's frame is (c × 3) mod 10 sub-steps old.
    let age_of = |c: usize| ((c * 3) % sub) as f64 * h;
    let run = |aged: bool| -> (f64, f64, f64) {
        let (mut sq, mut along, mut nees, mut n) = (0.0, 0.0, 0.0, 0.0);
        for run in 0..runs {
            let mut rng = ChaCha8Rng::seed_from_u64(2000 + run as u64);
            let normal6 = |rng: &mut ChaCha8Rng| State::from_fn(|_, _| StandardNormal.sample(rng));
            let mean0 = State::new(4.0, 4.0, 0.3, 0.3, -0.15, 0.0);
            let mut truth = mean0 + l0 * normal6(&mut rng);
            let mut path = vec![truth];
            let mut f = Eif::from_gaussian(mean0, cov0).unwrap();
            for _ in 0..steps {
                for _ in 0..sub {
                    truth = motion.transition(h) * truth + lr * normal6(&mut rng);
                    path.push(truth);
                }
                f.predict(&motion, dt).unwrap();
                let mut acc = Accumulator::default();
                for (c, cam) in cams.iter().enumerate() {
                    let back = ((c * 3) % sub).min(path.len() - 1);
                    let was = path[path.len() - 1 - back];
                    let p = was.fixed_rows::<3>(0).into_owned();
                    let age = if aged { age_of(c) } else { 0.0 };
                    if let Some((point, cov)) = observe(cam, &p, sigma_px, &mut rng)
                        && let Some((o, x)) = camera_contribution_aged(cam, &point, &cov, f.mean(), age)
                    {
                        acc.add(&o, &x);
                    }
                }
                f.update(&acc).unwrap();
                let err = truth - f.mean();
                let v = truth.fixed_rows::<2>(3).into_owned();
                sq += err.fixed_rows::<3>(0).norm_squared();
                // Estimate minus truth along the motion: negative when the estimate trails.
                along -= err.fixed_rows::<2>(0).dot(&v) / v.norm().max(1e-9);
                nees += err.dot(&(f.omega() * err));
                n += 1.0;
            }
        }
        ((sq / n).sqrt(), along / n, nees / n)
    };
    let (rmse_current, along_current, _) = run(false);
    let (rmse_aged, along_aged, nees_aged) = run(true);
    assert!(
        along_current < -0.02,
        "fused as current the estimate trails: {along_current}"
    );
    assert!(
        along_aged.abs() < 0.3 * along_current.abs(),
        "aged: {along_aged} vs {along_current}"
    );
    assert!(
        rmse_aged < rmse_current,
        "rmse aged {rmse_aged} vs as current {rmse_current}"
    );
    assert!(
        (4.5..7.5).contains(&nees_aged),
        "mean NEES {nees_aged} (6 is consistent)"
    );
}
