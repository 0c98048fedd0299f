//! `ocelli bench head`: how fast the head's filter and activation are, as JSON.
//!
//! Measures, with medians over many repetitions (build with `--release`):
//! - `update_us[N]`: one EIF predict + the sum of N wire-form contributions + the update
//!   (Cholesky solve for the mean, covariance for the report), N = 3, 21, 100, 1000;
//! - `activation_us[N]`: one Algorithm 2 decision over N candidate nodes (three modes, expected
//!   camera and RSSI measurements of every node at the predicted mean);
//! - `ekf_update_us[N]`: the covariance-form EKF's stacked update on the same measurements, for
//!   comparison (N ≤ 100; its cost grows with the cube of the measurement size);
//! - `head_step_us[N]`: one whole step of the sans-IO `HeadNode` with N member cameras and one
//!   track — open (predict, N priors), N `Contribution` envelopes through `on_message` (step
//!   accounting), close (update, report) — with all-on activation so the population is stable;
//! - `head_step_rssi_us[N]`: the same with every node's radio on (full-node activation with no
//!   energy weight, so again no node is switched): each contribution also carries an RSSI
//!   reading, which the head linearizes with the node's model after re-running Algorithm 1's
//!   choice for every node, and trains on (the camera-only filter, N trainers).
//!
//! - `assign[D×T×C]`: the association's optimal assignment of D detections from C cameras to
//!   T tracks (`super::assign`), and how often and by how much the greedy nearest-first rule
//!   it replaced costs more on the same problems.
//!
//! Contributions are real ones: a ring of N cameras looking at the room centre, each linearized
//! with `proto::models::camera_contribution`. The timed loops allocate nothing.

use crate::Result;
use crate::error::OrFailed as _;
use nalgebra::{DMatrix, DVector, Matrix6, Vector2, Vector3, Vector6};
use node_head::activation::{Candidate, Expected, Planner, Variant};
use node_head::config::NodeInfo;
use node_head::eif::{Accumulator, Eif};
use node_head::ekf::{Block, Ekf};
use node_head::{HeadConfig, HeadNode};
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose};
use proto::models::{
    MotionModel, RssiModel, State, camera_contribution, mat6_to_wire, pinhole, vec6_to_wire,
};
use proto::msg::{Answers, Contribution, Handover, Information, RssiReading};
use proto::msg::{Mat6, Vec6};
use proto::observation::{Kinds, ObservationKind};
use proto::scenario::PowerFigures;
use proto::scenario::{Activation, Method};
use proto::{ClusterTime, Envelope, Message, TargetId};
use proto::{Mode, NodeId};
use serde_json::json;
use std::hint::black_box;
use std::time::Instant;

/// What to measure and how long.
#[derive(Clone, Debug)]
pub struct Options {
    /// Scale the repetition counts (1.0 = default).
    pub scale: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options { scale: 1.0 }
    }
}

const SIZES: [usize; 4] = [3, 21, 100, 1000];

fn ring(n: usize) -> Vec<CameraModel> {
    (0..n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            let r = 5.0 + 0.5 * ((i * 7) % 5) as f64;
            let pos = Vector3::new(6.0 + r * a.cos(), 4.0 + r * a.sin(), 2.5 + 0.1 * (i % 3) as f64);
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
                pose: Pose::look_at(pos, Vector3::new(6.0, 4.0, 0.0), Vector3::z())
                    .expect("ring cameras are never vertical"),
            }
        })
        .collect()
}

/// Median of `reps` timings of `f`, microseconds. Time is read here, in the bench runtime.
#[allow(clippy::disallowed_methods)]
fn median_us(reps: usize, mut f: impl FnMut()) -> f64 {
    for _ in 0..reps.div_ceil(10) {
        f();
    }
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let start = Instant::now();
        f();
        t.push(start.elapsed().as_secs_f64() * 1e6);
    }
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn reps_for(n: usize, scale: f64) -> usize {
    let base = match n {
        0..=21 => 20_000,
        22..=100 => 10_000,
        _ => 2_000,
    };
    ((base as f64 * scale) as usize).max(11)
}

/// Run the benchmark; its figures as JSON.
///
/// # Errors
/// A part of the system under test could not be set up.
pub fn run(args: &Options) -> Result<serde_json::Value> {
    let motion = MotionModel::default();
    let truth = State::new(6.2, 3.9, 0.3, 0.4, -0.2, 0.0);
    let prior_cov = Matrix6::from_diagonal(&Vector6::new(0.05, 0.05, 0.02, 0.1, 0.1, 0.01));
    let base = Eif::from_gaussian(truth, prior_cov).or_failed("prior")?;
    let sigma_px = 18.0;
    let mut update = serde_json::Map::new();
    let mut per_contribution = serde_json::Map::new();
    let mut activation = serde_json::Map::new();
    let mut ekf_update = serde_json::Map::new();
    for n in SIZES {
        let cams = ring(n);
        let predicted = base.predicted(&motion, 0.2).or_failed("predict")?;
        let mean_bar = *predicted.mean();
        // Real contributions, linearized at the predicted mean, in wire form.
        let mut wire: Vec<(Mat6, Vec6)> = Vec::with_capacity(n);
        let mut blocks = Vec::with_capacity(n);
        for cam in &cams {
            let (p, _) = cam.normalized(&truth.fixed_rows::<3>(0).into_owned());
            let p = p + Vector2::new(0.002, -0.001);
            let cov = cam.normalized_covariance(&p, sigma_px);
            let (o, x) = camera_contribution(cam, &p, &cov, &mean_bar).or_failed("contribution")?;
            wire.push((mat6_to_wire(&o), vec6_to_wire(&x)));
            let (h, jac) = pinhole(cam, &mean_bar).or_failed("pinhole")?;
            blocks.push(Block {
                z: DVector::from_column_slice(p.as_slice()),
                predicted: DVector::from_column_slice(h.as_slice()),
                jac: DMatrix::from_fn(2, 6, |i, j| jac[(i, j)]),
                noise: DMatrix::from_fn(2, 2, |i, j| cov[(i, j)]),
            });
        }
        let reps = reps_for(n, args.scale);
        let us = median_us(reps, || {
            let mut f = black_box(&base).clone();
            f.predict(&motion, 0.2).expect("prediction of a valid prior");
            let mut acc = Accumulator::default();
            for (o, x) in black_box(&wire) {
                acc.add_wire(o, x);
            }
            f.update(&acc).expect("update with valid contributions");
            black_box(f.mean());
        });
        update.insert(n.to_string(), json!(us));
        per_contribution.insert(n.to_string(), json!(us * 1e3 / n as f64));

        // Activation over n candidates, one track, three modes, RSSI on every node.
        let model = RssiModel::default();
        let positions: Vec<Vector3<f64>> = cams.iter().map(|c| c.pose.centre()).collect();
        let candidates: Vec<Candidate> = (0..n)
            .map(|i| Candidate {
                node: NodeId(10 + i as u32),
                mode: Mode::ALL[i % 3],
                power: PowerFigures::default(),
                cost_factor: 1.0,
            })
            .collect();
        let omega_bar = *predicted.omega();
        let mut planner = Planner::default();
        let act_reps = reps_for(n, args.scale) / 4 + 11;
        let us = median_us(act_reps, || {
            let d = planner.decide(Variant::ThreeMode, 1e-3, &candidates, &[omega_bar], |k, _| {
                Expected::at(
                    Some(&cams[k]),
                    &[],
                    sigma_px,
                    Some((&model, &positions[k])),
                    &mean_bar,
                )
            });
            black_box(d);
        });
        activation.insert(n.to_string(), json!(us));

        if n <= 100 {
            let ekf0 = Ekf::new(truth, prior_cov);
            let us = median_us(reps_for(n, args.scale) / 10 + 11, || {
                let mut f = black_box(&ekf0).clone();
                f.predict(&motion, 0.2);
                f.update(black_box(&blocks)).expect("EKF update");
                black_box(f.mean);
            });
            ekf_update.insert(n.to_string(), json!(us));
        }
    }
    let mut head_step = serde_json::Map::new();
    let mut head_step_rssi = serde_json::Map::new();
    for n in SIZES {
        head_step.insert(n.to_string(), json!(head_step_us(n, args.scale, false)?));
        head_step_rssi.insert(n.to_string(), json!(head_step_us(n, args.scale, true)?));
    }
    let out = json!({
        "bench": "head",
        "profile": if cfg!(debug_assertions) { "debug" } else { "release" },
        "update_us": update,
        "update_ns_per_contribution": per_contribution,
        "activation_us": activation,
        "ekf_update_us": ekf_update,
        "head_step_us": head_step,
        "head_step_rssi_us": head_step_rssi,
        "assign": super::assign::run(((200.0 * args.scale) as usize).max(10), |reps, f| median_us(reps, f)),
        "note": "medians; update = predict + sum of N wire contributions + update; activation = one Algorithm 2 decision over N nodes (three modes)",
    });
    Ok(out)
}

/// Median time of one whole `HeadNode` step with `n` cameras answering one track, with an
/// RSSI reading in every contribution when `rssi`.
fn head_step_us(n: usize, scale: f64, rssi: bool) -> Result<f64> {
    let cams = ring(n);
    let server = NodeId(1);
    let method = Method {
        activation: if rssi {
            Activation::FullNode
        } else {
            Activation::AllOn
        },
        energy_weight: 0.0,
        ..Method::default()
    };
    let model = method.rssi_default;
    let nodes = cams
        .iter()
        .enumerate()
        .map(|(i, c)| NodeInfo {
            id: NodeId(10 + i as u32),
            camera: *c,
            position: c.pose.centre(),
            rssi,
            power: PowerFigures::default(),
            cost_factor: 1.0,
            fps: 5.0,
            member: true,
            radio_only: false,
        })
        .collect();
    let cfg = HeadConfig {
        id: NodeId(2),
        server: Some(server),
        method,
        nodes,
        bounds: ([0.0, 0.0, 0.0], [12.0, 8.0, 3.0]),
        walls: Vec::new(),
        birth_min_cameras: 2,
        region: None,
        other_regions: Vec::new(),
        target_plane_z: 0.3,
        ml_depth: node_head::fusion::ml::DepthHandling::default(),
        acoustic: Vec::new(),
    };
    let mut head = HeadNode::new(cfg).with_nodes_heard();
    let truth = State::new(6.2, 3.9, 0.3, 0.0, 0.0, 0.0);
    let cov = Matrix6::from_diagonal(&Vector6::new(0.05, 0.05, 0.02, 0.1, 0.1, 0.01));
    head.on_message(
        ClusterTime::ZERO,
        Envelope {
            source: server,
            seq: 0,
            time: ClusterTime::ZERO,
            body: Message::Handover(Handover {
                global: TargetId(1),
                to_head: NodeId(2),
                from_head: None,
                time: ClusterTime::ZERO,
                mean: vec6_to_wire(&truth),
                cov: mat6_to_wire(&cov),
            }),
        },
    );
    let target = head.tracks().first().or_failed("handover made no track")?.local;
    // Contributions linearized at the truth (close to every prior): realistic numbers.
    let envs: Vec<Envelope> = cams
        .iter()
        .enumerate()
        .map(|(i, cam)| {
            let (p, _) = cam.normalized(&truth.fixed_rows::<3>(0).into_owned());
            let c = cam.normalized_covariance(&p, 18.0);
            let (o, x) = camera_contribution(cam, &p, &c, &truth).or_failed("contribution")?;
            Ok(Envelope {
                source: NodeId(10 + i as u32),
                seq: 0,
                time: ClusterTime::ZERO,
                body: Message::Answers(Answers {
                    step: 0,
                    part: 0,
                    captured: ClusterTime::ZERO,
                    mode: Mode::Active,
                    rssi: rssi
                        .then(|| RssiReading {
                            tag: proto::TagId::simulated(1),
                            dbm: model.predict((truth.fixed_rows::<3>(0) - cam.pose.centre()).norm()),
                            time: ClusterTime::ZERO,
                        })
                        .into_iter()
                        .collect(),
                    contributions: vec![Contribution {
                        target,
                        info: Some(Information {
                            matrix: mat6_to_wire(&o),
                            vector: vec6_to_wire(&x),
                        }),
                        folded: Kinds::of(ObservationKind::Pinhole),
                        ground: None,
                    }],
                }),
            })
        })
        .collect::<Result<_>>()?;
    let mut k: i64 = 0;
    let mut step: u64 = 0;
    let reps = (reps_for(n, scale) / 20).max(11);
    let us = median_us(reps, || {
        k += 1;
        step += 1;
        let now = ClusterTime::from_millis(k * 200);
        black_box(head.tick(now));
        for e in &envs {
            let mut e = e.clone();
            if let Message::Answers(a) = &mut e.body {
                a.step = step;
                for r in &mut a.rssi {
                    r.time = now;
                }
            }
            black_box(head.on_message(now, e));
        }
    });
    let c = head.counters();
    if !(c.applied as usize >= n * reps && c.late == 0 && c.duplicate == 0) {
        return Err(crate::LabError::failed(
            "head bench",
            format!("bench steps did not apply every contribution: {c:?}"),
        ));
    }
    // The closing tick fuses the last step's readings.
    head.tick(ClusterTime::from_millis((k + 1) * 200));
    let c = head.counters();
    if !(c.commands == 0
        && c.stale_measurements == 0
        && head.last_step().rssi_nodes == if rssi { n } else { 0 })
    {
        return Err(crate::LabError::failed(
            "head bench",
            format!(
                "bench steps switched nodes or did not fuse every reading: {c:?}, {} RSSI nodes",
                head.last_step().rssi_nodes
            ),
        ));
    }
    Ok(us)
}
