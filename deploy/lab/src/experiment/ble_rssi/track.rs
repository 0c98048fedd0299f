//! Paper 002's RSSI machinery on one real trajectory: Algorithm 1
//! (`node_head::rssi_training::RssiTrainer`) predicting each sensor's next packet, and an
//! RSSI-only EIF (`node_head::eif::Eif`, `proto::models::rssi_contribution_aged`, the scenario's
//! motion model) stepping at a fixed rate over the packets received in each step, each at its own time.
//!
//! Algorithm 1 needs a distance from the cameras' auxiliary filter. The dataset has no cameras:
//! a **camera stand-in** — the ground-truth position plus seeded Gaussian noise of σ per axis,
//! independent per packet — takes that place. It is used only as the trainers' input (the
//! distance of a training pair, and the distance a model is evaluated at when predicting a
//! packet's RSSI); the tracked estimate never sees it or the truth, and trained models enter
//! the EIF only as trained on packets of earlier steps.

use super::data::{Packet, Sensor, Trajectory};
use super::law::distance;
use crate::experiment::runner::Sample;
use nalgebra::{Matrix6, SMatrix, SVector, Vector3};
use node_head::eif::{Accumulator, Eif};
use node_head::rssi_training::{Choice, MIN_PAIRS, RssiTrainer};
use proto::models::{
    MotionModel, RssiModel, State, back_in_time, information_contribution, rssi_contribution_aged,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Algorithm 1's parameters and the stand-in camera's noise.
#[derive(Clone, Copy, Debug)]
pub struct Training {
    /// Window M (pairs per sensor).
    pub window: usize,
    /// The 1/a guard ε.
    pub epsilon: f64,
    /// σ of the camera stand-in per axis, m.
    pub sigma_m: f64,
    pub seed: u64,
}

/// The camera stand-in's position for every packet of `traj`: truth plus N(0, σ²) per axis.
pub fn camera_standin(traj: &[Packet], sigma_m: f64, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let Ok(noise) = Normal::new(0.0, sigma_m.abs()) else {
        return traj.iter().map(|p| p.truth).collect();
    };
    traj.iter()
        .map(|p| p.truth + Vector3::from_fn(|_, _| noise.sample(&mut rng)))
        .collect()
}

/// Squared errors (dB²) of each-next-packet RSSI predictions, summed over the packets scored.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Prediction {
    /// Packets scored: those whose sensor already had a full window of M pairs.
    pub n: usize,
    pub scenario: f64,
    pub fitted: f64,
    /// The locally fitted line, always (σ²_D = ∞).
    pub local: f64,
    /// Algorithm 1: the local line when σ²_tm ≤ σ²_D of the fitted law, else the fitted law.
    pub algorithm1: f64,
    /// Scored packets where Algorithm 1 chose the trained model.
    pub trained: usize,
}

impl Prediction {
    pub fn add(&mut self, o: &Prediction) {
        self.n += o.n;
        self.scenario += o.scenario;
        self.fitted += o.fitted;
        self.local += o.local;
        self.algorithm1 += o.algorithm1;
        self.trained += o.trained;
    }

    /// RMSE of a sum of squares, dB.
    pub fn rmse(&self, sse: f64) -> Option<f64> {
        (self.n > 0).then(|| (sse / self.n as f64).sqrt())
    }
}

/// A trainer whose default is never preferred: the plain local line of eq. 4–5.
fn always_local(fitted: &RssiModel, tr: &Training) -> RssiTrainer {
    let never = match *fitted {
        RssiModel::LogDistance { a, b, .. } => RssiModel::LogDistance {
            a,
            b,
            variance: f64::INFINITY,
        },
        RssiModel::Linear { a, b, .. } => RssiModel::Linear {
            a,
            b,
            variance: f64::INFINITY,
        },
    };
    RssiTrainer::new(never, tr.window, tr.epsilon)
}

/// Predict every packet's RSSI from the packets before it, per sensor, with each model.
pub fn predict_next(
    sensors: &[Sensor],
    traj: &Trajectory,
    scenario: &RssiModel,
    fitted: &RssiModel,
    tr: &Training,
) -> Prediction {
    let cam = camera_standin(&traj.packets, tr.sigma_m, tr.seed);
    let mut alg1: Vec<RssiTrainer> = sensors
        .iter()
        .map(|_| RssiTrainer::new(*fitted, tr.window, tr.epsilon))
        .collect();
    let mut local: Vec<RssiTrainer> = sensors.iter().map(|_| always_local(fitted, tr)).collect();
    let mut out = Prediction::default();
    let su2 = tr.sigma_m * tr.sigma_m;
    for (p, c) in traj.packets.iter().zip(&cam) {
        let d = distance(&sensors[p.sensor].pos, c);
        let (a, l) = (&mut alg1[p.sensor], &mut local[p.sensor]);
        if a.pairs() >= tr.window.max(MIN_PAIRS) {
            let e = |m: RssiModel| (p.rssi - m.predict(d)).powi(2);
            out.n += 1;
            out.scenario += e(*scenario);
            out.fitted += e(*fitted);
            out.local += e(l.model());
            out.algorithm1 += e(a.model());
            if matches!(a.choice(), Choice::Trained { .. }) {
                out.trained += 1;
            }
        }
        a.push(d, p.rssi, su2);
        l.push(d, p.rssi, su2);
    }
    out
}

/// Which RSSI model the tracker linearizes with.
#[derive(Clone, Copy, Debug)]
pub enum Models {
    /// One log-distance model for every sensor.
    Fixed(RssiModel),
    /// Algorithm 1 per sensor, falling back to this default.
    Trained(RssiModel, Training),
}

/// The RSSI-only tracker's setup.
#[derive(Clone, Copy, Debug)]
pub struct Tracker {
    pub motion: MotionModel,
    /// Filter step, s.
    pub step_s: f64,
    /// The carrying height the estimate is held at, m, and the σ of that constraint.
    pub height_m: f64,
    pub height_sigma_m: f64,
    /// Starting mean (x, y), m, and the starting position σ, m.
    pub start_xy: [f64; 2],
    pub start_sigma_m: f64,
}

/// The known-height pseudo-measurement z = h as an information contribution.
fn height_contribution(t: &Tracker, mean: &State) -> Option<(Matrix6<f64>, State)> {
    let mut jac = SMatrix::<f64, 1, 6>::zeros();
    jac[(0, 2)] = 1.0;
    let z = SVector::<f64, 1>::new(t.height_m);
    let h = SVector::<f64, 1>::new(mean[2]);
    let q = SMatrix::<f64, 1, 1>::new(t.height_sigma_m * t.height_sigma_m);
    information_contribution(&z, &h, &jac, &q, mean)
}

/// Track one trajectory from RSSI only; each packet is fused at its own time within the step.
/// One sample per step that received packets: the estimate at the time of the step's last
/// packet against the truth then; the error is horizontal. Stops early (shorter output) if the
/// filter fails numerically.
pub fn track(sensors: &[Sensor], traj: &Trajectory, models: &Models, t: &Tracker) -> Vec<Sample> {
    let mut mean = State::zeros();
    mean[0] = t.start_xy[0];
    mean[1] = t.start_xy[1];
    mean[2] = t.height_m;
    let s2 = t.start_sigma_m * t.start_sigma_m;
    let cov = Matrix6::from_diagonal(&State::from([
        s2,
        s2,
        t.height_sigma_m * t.height_sigma_m,
        1.0,
        1.0,
        0.01,
    ]));
    let Ok(mut eif) = Eif::from_gaussian(mean, cov) else {
        return Vec::new();
    };
    let (mut trainers, cam, su2) = match models {
        Models::Trained(default, tr) => (
            sensors
                .iter()
                .map(|_| RssiTrainer::new(*default, tr.window, tr.epsilon))
                .collect(),
            camera_standin(&traj.packets, tr.sigma_m, tr.seed),
            tr.sigma_m * tr.sigma_m,
        ),
        Models::Fixed(_) => (Vec::new(), Vec::new(), 0.0),
    };
    let mut out = Vec::new();
    let mut next = 0usize;
    let mut k = 0u32;
    while next < traj.packets.len() {
        k += 1;
        let t_end = f64::from(k) * t.step_s;
        if eif.predict(&t.motion, t.step_s).is_err() {
            break;
        }
        let first = next;
        while next < traj.packets.len() && traj.packets[next].t <= t_end {
            next += 1;
        }
        let step = &traj.packets[first..next];
        let prior = *eif.mean();
        let mut acc = Accumulator::default();
        for p in step {
            let model = match models {
                Models::Fixed(m) => *m,
                Models::Trained(..) => trainers[p.sensor].model(),
            };
            // Each packet at its own time within the step, as the head fuses them.
            let age_s = t_end - p.t;
            if let Some((o, xi)) =
                rssi_contribution_aged(&model, &sensors[p.sensor].pos, p.rssi, &prior, age_s)
            {
                acc.add(&o, &xi);
            }
        }
        let rssi = acc.count;
        if let Some((o, xi)) = height_contribution(t, &prior) {
            acc.add(&o, &xi);
        }
        if eif.update(&acc).is_err() {
            break;
        }
        // Training pairs of this step become usable from the next step on.
        if !trainers.is_empty() {
            for (i, p) in step.iter().enumerate() {
                let d = distance(&sensors[p.sensor].pos, &cam[first + i]);
                trainers[p.sensor].push(d, p.rssi, su2);
            }
        }
        let Some(last) = step.last() else {
            continue;
        };
        // The estimate where it puts the beacon when its last packet came, against the truth then.
        let e = back_in_time(eif.mean(), t_end - last.t);
        let est = [e[0], e[1], e[2]];
        let truth = [last.truth.x, last.truth.y, last.truth.z];
        let c = eif.cov();
        out.push(Sample {
            t: last.t,
            est,
            truth,
            sigma_m: (c[(0, 0)] + c[(1, 1)] + c[(2, 2)]).max(0.0).sqrt(),
            error_m: ((est[0] - truth[0]).powi(2) + (est[1] - truth[1]).powi(2)).sqrt(),
            cameras: 0,
            rssi_nodes: rssi as u32,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::ble_rssi::data::Sensor;

    fn sensors() -> Vec<Sensor> {
        [
            (0.0, 0.0),
            (8.0, 0.0),
            (0.0, 8.0),
            (8.0, 8.0),
            (4.0, -1.0),
            (4.0, 9.0),
        ]
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| Sensor {
            mac: format!("m{i}"),
            alias: format!("s{i}"),
            pos: Vector3::new(x, y, 2.0),
        })
        .collect()
    }

    /// A beacon walking a line at 0.5 m/s, every sensor hearing it 4 times a second with the
    /// exact law `law` (plus a per-sensor offset when `offset`).
    fn walk(sensors: &[Sensor], law: &RssiModel, offset: bool) -> Trajectory {
        let mut packets = Vec::new();
        for k in 0..160 {
            let t = f64::from(k) * 0.25;
            let truth = Vector3::new(1.0 + 0.15 * t, 2.0 + 0.1 * t, 1.5);
            for (i, s) in sensors.iter().enumerate() {
                let bias = if offset { 3.0 * (i as f64 - 2.5) } else { 0.0 };
                packets.push(Packet {
                    t: t + 0.01 * i as f64,
                    sensor: i,
                    rssi: law.predict(distance(&s.pos, &truth)) + bias,
                    truth,
                });
            }
        }
        Trajectory {
            name: "synthetic".into(),
            packets,
            skipped: Default::default(),
        }
    }

    const LAW: RssiModel = RssiModel::LogDistance {
        a: -25.0,
        b: -50.0,
        variance: 4.0,
    };

    fn tracker() -> Tracker {
        Tracker {
            motion: MotionModel::default(),
            step_s: 0.5,
            height_m: 1.5,
            height_sigma_m: 0.1,
            start_xy: [4.0, 4.0],
            start_sigma_m: 4.0,
        }
    }

    #[test]
    fn standin_noise_has_the_stated_sigma_and_is_seeded() {
        let s = sensors();
        let traj = walk(&s, &LAW, false);
        let a = camera_standin(&traj.packets, 0.1, 7);
        assert_eq!(a, camera_standin(&traj.packets, 0.1, 7));
        let errs: Vec<f64> = a
            .iter()
            .zip(&traj.packets)
            .flat_map(|(c, p)| (c - p.truth).iter().copied().collect::<Vec<_>>())
            .collect();
        let sd = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        assert!((sd - 0.1).abs() < 0.01, "{sd}");
    }

    #[test]
    fn local_training_learns_per_sensor_offsets_the_fixed_law_misses() {
        let s = sensors();
        let traj = walk(&s, &LAW, true);
        let tr = Training {
            window: 20,
            epsilon: 1e-3,
            sigma_m: 0.05,
            seed: 1,
        };
        let p = predict_next(&s, &traj, &RssiModel::default(), &LAW, &tr);
        assert!(p.n > 800, "{p:?}");
        let (fitted, local) = (
            p.rmse(p.fitted).unwrap_or(0.0),
            p.rmse(p.local).unwrap_or(f64::MAX),
        );
        assert!(fitted > 4.0, "offsets of up to 7.5 dB: {fitted}");
        assert!(local < 1.0, "the local line absorbs them: {local}");
    }

    #[test]
    fn the_rssi_only_filter_follows_a_beacon_under_its_own_law() {
        let s = sensors();
        let traj = walk(&s, &LAW, false);
        let out = track(&s, &traj, &Models::Fixed(LAW), &tracker());
        assert!(out.len() >= 75, "{}", out.len());
        let late: Vec<f64> = out[20..].iter().map(|x| x.error_m).collect();
        let mean = late.iter().sum::<f64>() / late.len() as f64;
        assert!(mean < 0.3, "noise-free law, converged: {mean}");
        // A badly wrong law (20 dB too strong) puts the estimate elsewhere.
        let wrong = RssiModel::LogDistance {
            a: -25.0,
            b: -30.0,
            variance: 4.0,
        };
        let bad = track(&s, &traj, &Models::Fixed(wrong), &tracker());
        let bad_mean = bad[20..].iter().map(|x| x.error_m).sum::<f64>() / (bad.len() - 20) as f64;
        assert!(bad_mean > 3.0 * mean.max(0.1), "{bad_mean} vs {mean}");
    }
}
