//! A tiny measurement-level simulator for the head's tests: truth from the simulated world's
//! targets (`world::Target::truth_at`)
//! projected through the scenario's cameras with seeded pixel noise, undistorted, and turned
//! into `Contribution`s (or `Measurement`s for detections no prior gates) with `proto::models`
//! — what camera nodes do, minus the pixels. Synthetic RSSI is log-distance plus a smooth
//! per-node multipath bias and noise. Measurement-level: no ground truth reaches the head.

use nalgebra::{Matrix2, Vector2, Vector3};
use node_head::association::{Detection, distance2};
use node_head::{HeadConfig, HeadNode};
use proto::camera::CameraModel;
use proto::models::{camera_contribution, mat6_to_wire, vec6_to_wire};
use proto::msg::{
    Answers, ColourSignature, Contribution, Information, Measurement, PixelBox, Prior, Priors, RssiReading,
    TrackReport,
};
use proto::observation::{Kinds, Observation, ObservationKind, PinholePoint};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, Message, Mode, NodeId};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use world::Target;

pub const SERVER: u32 = 1;
pub const HEAD: u32 = 2;

/// A ring of `n` cameras around an 8 × 8 m room, all in head 2's cluster.
pub fn ring_scenario(
    n: usize,
    fusion: &str,
    activation: &str,
    energy_weight: f64,
    targets: &str,
) -> Scenario {
    let mut s = format!(
        r#"
name = "ring"
[world]
min = [0.0, 0.0, 0.0]
max = [8.0, 8.0, 3.0]
[method]
fusion = "{fusion}"
activation = "{activation}"
segmentation = "adaptive-background"
step-ms = 200
deadline-ms = 80
pixel-sigma = 4.0
rssi-window = 10
rssi-epsilon = 0.001
energy-weight = {energy_weight}
previous-point = false
track-timeout-ms = 1000
gate-chi2 = 13.8
motion = {{ accel-psd = [0.25, 0.25, 0.01] }}
rssi-default = {{ kind = "log-distance", a = -26.0, b = -48.0, variance = 16.0 }}
[[nodes]]
id = 1
role = "server"
[[nodes]]
id = 2
role = "head"
"#
    );
    for i in 0..n {
        let ang = i as f64 / n as f64 * std::f64::consts::TAU;
        let (x, y) = (4.0 + 5.5 * ang.cos(), 4.0 + 5.5 * ang.sin());
        s += &format!(
            r#"
[[nodes]]
id = {}
role = "camera"
head = 2
camera.intrinsics = {{ fx = 320.0, fy = 320.0, cx = 176.0, cy = 144.0, width = 352, height = 288 }}
camera.distortion = {{ k1 = -0.12, k2 = 0.02 }}
camera.pose = {{ position = [{x}, {y}, 2.8], look-at = [4.0, 4.0, 0.0] }}
"#,
            10 + i
        );
    }
    s += targets;
    Scenario::from_toml(&s, "ring").unwrap()
}

/// One target on a 1.5 m loop around the centre.
pub const ONE_TARGET: &str = r#"
[[targets]]
id = 1
size = [0.4, 0.4, 0.4]
colour = [255, 0, 0]
trajectory = { kind = "loop", speed = 0.5, waypoints = [[2.5, 2.5], [5.5, 2.5], [5.5, 5.5], [2.5, 5.5]] }
"#;

/// Two targets in opposite halves of the room.
pub const TWO_TARGETS: &str = r#"
[[targets]]
id = 1
size = [0.4, 0.4, 0.4]
colour = [255, 0, 0]
trajectory = { kind = "loop", speed = 0.4, waypoints = [[2.0, 2.0], [3.5, 2.0], [3.5, 3.0], [2.0, 3.0]] }
[[targets]]
id = 2
size = [0.4, 0.4, 0.4]
colour = [0, 0, 255]
trajectory = { kind = "loop", speed = 0.4, waypoints = [[5.0, 5.0], [6.0, 5.0], [6.0, 6.0], [5.0, 6.0]] }
"#;

/// Log-distance RSSI with a smooth per-node multipath bias.
#[derive(Clone, Copy, Debug)]
pub struct Radio {
    pub tx_dbm: f64,
    pub exponent: f64,
    pub multipath_db: f64,
    pub noise_db: f64,
}

impl Radio {
    /// The noise-free reading of node `k` (at `node`) for a tag at `p`.
    pub fn mean(&self, k: usize, node: &Vector3<f64>, p: &Vector3<f64>) -> f64 {
        let d = (p - node).norm().max(0.1);
        let phase = k as f64 * 1.7;
        let bias = self.multipath_db * ((0.9 * p.x + phase).sin() * (0.7 * p.y - phase).cos());
        self.tx_dbm - 10.0 * self.exponent * d.log10() + bias
    }
}

pub struct SimCam {
    pub id: NodeId,
    pub model: CameraModel,
    pub mode: Mode,
    /// When false the camera sees nothing (failure, occlusion).
    pub working: bool,
}

pub struct Sim {
    pub head: HeadNode,
    pub cams: Vec<SimCam>,
    pub targets: Vec<Target>,
    /// Whether each target is still in the scene.
    pub present: Vec<bool>,
    pub rng: ChaCha8Rng,
    pub sigma_px: f64,
    pub radio: Option<Radio>,
    pub step_ms: i64,
    pub deadline_ms: i64,
    pub k: i64,
    /// Centralized or ML fusion: cameras send every detection as a `Measurement`.
    pub centralized: bool,
    /// Include p_{i,t−1} (one frame earlier) in measurements.
    pub previous_point: bool,
    pub reports: Vec<TrackReport>,
    seq: u64,
}

impl Sim {
    pub fn new(scenario: &Scenario, seed: u64) -> Sim {
        // What the method must know of the targets (the plane they move on), as every
        // simulated run prepares it.
        let scenario = &world::prepare(scenario, seed).unwrap();
        let targets = world::targets(scenario).unwrap();
        let cfg = HeadConfig::from_scenario(scenario, HEAD).unwrap();
        let cams = cfg
            .nodes
            .iter()
            .map(|n| SimCam {
                id: n.id,
                model: n.camera,
                mode: Mode::Active,
                working: true,
            })
            .collect();
        Sim {
            head: HeadNode::new(cfg).with_history().with_nodes_heard(),
            cams,
            present: vec![true; targets.len()],
            targets,
            rng: ChaCha8Rng::seed_from_u64(seed),
            sigma_px: scenario.method.pixel_sigma,
            radio: None,
            step_ms: scenario.method.step_ms as i64,
            deadline_ms: scenario.method.deadline_ms as i64,
            k: 0,
            centralized: !scenario.method.fusion.distributed(),
            previous_point: scenario.method.previous_point,
            reports: Vec::new(),
            seq: 0,
        }
    }

    pub fn now(&self) -> ClusterTime {
        ClusterTime::from_millis(self.k * self.step_ms)
    }

    pub fn truth(&self, target: usize, t: ClusterTime) -> proto::models::State {
        self.targets[target].truth_at(t.as_secs_f64())
    }

    fn envelope(&mut self, source: NodeId, time: ClusterTime, body: Message) -> Envelope {
        self.seq += 1;
        Envelope {
            source,
            seq: self.seq,
            time,
            body,
        }
    }

    /// A noisy detection of target `i` by camera `c` at `t`, if in view.
    pub fn detect(&mut self, c: usize, i: usize, t: ClusterTime) -> Option<(Vector2<f64>, Matrix2<f64>)> {
        if !self.cams[c].working || !self.present[i] {
            return None;
        }
        let p = self.targets[i]
            .truth_at(t.as_secs_f64())
            .fixed_rows::<3>(0)
            .into_owned();
        observe(&self.cams[c].model, &p, self.sigma_px, &mut self.rng)
    }

    fn rssi(&mut self, c: usize, i: usize, t: ClusterTime) -> Option<RssiReading> {
        let radio = self.radio?;
        if !self.present[i] {
            return None;
        }
        let p = self.targets[i]
            .truth_at(t.as_secs_f64())
            .fixed_rows::<3>(0)
            .into_owned();
        let n: f64 = StandardNormal.sample(&mut self.rng);
        let dbm = radio.mean(c, &self.cams[c].model.pose.centre(), &p) + n * radio.noise_db;
        Some(RssiReading {
            tag: proto::TagId::simulated(i as u32 + 1),
            dbm,
            time: t,
        })
    }

    /// Run one whole step: tick, answer every prior, detections no prior gates go up as
    /// measurements, close at the deadline, apply commands. Returns this step's reports.
    pub fn step(&mut self) -> Vec<TrackReport> {
        self.step_with(|_| 1)
    }

    /// As [`Sim::step`]; `copies(cam)` says how many times camera `cam` sends its answers to
    /// the step's priors (0 drops them, 2 duplicates them).
    pub fn step_with(&mut self, mut copies: impl FnMut(usize) -> usize) -> Vec<TrackReport> {
        let now = self.now();
        let mut out = self.head.tick(now);
        let answer_at = now + 1_000_000;
        let mut inbox = Vec::new();
        for c in 0..self.cams.len() {
            let id = self.cams[c].id;
            let centralized = self.centralized;
            let asked: Vec<Priors> = out
                .iter()
                .filter(|o| o.to == id && !centralized)
                .filter_map(|o| match &o.body {
                    Message::Priors(p) => Some(p.clone()),
                    _ => None,
                })
                .collect();
            let priors: Vec<Prior> = asked.iter().flat_map(|p| p.tracks.clone()).collect();
            let mode = self.cams[c].mode;
            if mode == Mode::Inactive {
                continue;
            }
            // Detections of every target this camera sees (camera on only).
            let mut dets = Vec::new();
            if mode == Mode::Active {
                for i in 0..self.targets.len() {
                    if let Some(d) = self.detect(c, i, now) {
                        dets.push((i, d));
                    }
                }
            }
            // Gate each detection to the nearest prior (as a camera node does).
            let mut used = vec![false; dets.len()];
            let mut contributions = Vec::new();
            let mut readings: Vec<RssiReading> = Vec::new();
            for p in &priors {
                let mean = proto::models::vec6_from_wire(&p.mean);
                let cov = proto::models::mat6_from_wire(&p.cov);
                let mut best: Option<(f64, usize)> = None;
                for (j, (_, (pt, cv))) in dets.iter().enumerate() {
                    if used[j] {
                        continue;
                    }
                    let det = Detection {
                        node: id,
                        slot: c,
                        point: *pt,
                        cov: *cv,
                        prev_point: None,
                        hint: None,
                        captured: ClusterTime::ZERO,
                        ground: None,
                        appearance: None,
                    };
                    if let Some(d2) = distance2(&self.cams[c].model, &det, &mean, &cov, ClusterTime::ZERO)
                        && d2 <= 13.8
                        && best.is_none_or(|b| d2 < b.0)
                    {
                        best = Some((d2, j));
                    }
                }
                let mut info = (nalgebra::Matrix6::zeros(), proto::models::State::zeros());
                let mut camera = false;
                let mut rssi_target = None;
                if let Some((_, j)) = best {
                    used[j] = true;
                    let (pt, cv) = dets[j].1;
                    if let Some(ix) = camera_contribution(&self.cams[c].model, &pt, &cv, &mean) {
                        info = ix;
                        camera = true;
                    }
                    rssi_target = Some(dets[j].0);
                }
                // RSSI of the tag nearest this prior (one target in RSSI tests).
                let rssi = match (rssi_target, self.targets.len()) {
                    (Some(i), _) => self.rssi(c, i, now),
                    (None, 1) => self.rssi(c, 0, now),
                    _ => None,
                };
                if camera {
                    contributions.push(Contribution {
                        target: p.target,
                        info: Some(Information {
                            matrix: mat6_to_wire(&info.0),
                            vector: vec6_to_wire(&info.1),
                        }),
                        folded: Kinds::of(ObservationKind::Pinhole),
                        ground: None,
                    });
                }
                if let Some(r) = rssi.filter(|r| !readings.iter().any(|q| q.tag == r.tag)) {
                    readings.push(r);
                }
            }
            // One answer per part asked (one part: the tests' heads hold few tracks).
            for part in &asked {
                let body = Message::Answers(Answers {
                    step: part.tracks[0].step,
                    part: part.part,
                    captured: now,
                    mode,
                    rssi: readings.clone(),
                    contributions: contributions
                        .iter()
                        .filter(|c| part.tracks.iter().any(|p| p.target == c.target))
                        .cloned()
                        .collect(),
                });
                for _ in 0..copies(c) {
                    let env = self.envelope(id, answer_at, body.clone());
                    inbox.push(env);
                }
            }
            for (j, &(i, (pt, cv))) in dets.iter().enumerate() {
                if used[j] {
                    continue;
                }
                // One frame (0.2 s) earlier, for paper 000's p_{i,t−1}.
                let prev_point = if self.previous_point {
                    self.detect(c, i, now + -200_000_000).map(|(p, _)| [p.x, p.y])
                } else {
                    None
                };
                let rssi = if centralized { self.rssi(c, i, now) } else { None };
                let point = PinholePoint {
                    point: [pt.x, pt.y],
                    prev_point,
                    cov: [cv[(0, 0)], cv[(0, 1)], cv[(1, 1)]],
                    pixel_box: PixelBox {
                        xmin: 0.0,
                        ymin: 0.0,
                        xmax: 1.0,
                        ymax: 1.0,
                    },
                    area: 100,
                    colour: ColourSignature {
                        hue: 0.0,
                        saturation: 1.0,
                        intensity: 0.5,
                    },
                    captured: now,
                };
                let m = Measurement {
                    target: None,
                    step: 0,
                    pose: self.cams[c].model.pose.to_wire(),
                    mode,
                    observations: std::iter::once(Observation::Pinhole(point))
                        .chain(rssi.map(Observation::Rssi))
                        .collect(),
                };
                // Measurements first: they must reach the head before the step closes.
                let env = self.envelope(id, answer_at, Message::Measurement(m));
                inbox.insert(0, env);
            }
        }
        for env in inbox {
            out.extend(self.head.on_message(answer_at, env));
        }
        if self.head.step_open() {
            let close = now + (self.deadline_ms + 1) * 1_000_000;
            out.extend(self.head.tick(close));
        }
        let mut reports = Vec::new();
        for o in out {
            match o.body {
                Message::Command(cmd) => {
                    if let Some(c) = self.cams.iter_mut().find(|c| c.id == cmd.node) {
                        c.mode = cmd.mode;
                    }
                }
                Message::TrackReport(r) => reports.push(r),
                _ => {}
            }
        }
        self.reports.extend(reports.iter().cloned());
        self.k += 1;
        reports
    }

    /// Random bits for tests that need them.
    pub fn coin(&mut self, p: f64) -> bool {
        self.rng.random_bool(p)
    }
}

/// What a camera measures of a world point: the pixel with isotropic Gaussian noise
/// `sigma_px`, undistorted exactly, with its normalized covariance. `None` out of view.
pub fn observe(
    model: &CameraModel,
    p: &Vector3<f64>,
    sigma_px: f64,
    rng: &mut ChaCha8Rng,
) -> Option<(Vector2<f64>, Matrix2<f64>)> {
    let px = model.project(p)?;
    let k = &model.intrinsics;
    if px.x < 0.0 || px.y < 0.0 || px.x >= k.width as f64 || px.y >= k.height as f64 {
        return None;
    }
    let nx: f64 = StandardNormal.sample(rng);
    let ny: f64 = StandardNormal.sample(rng);
    let noisy = px + Vector2::new(nx, ny) * sigma_px;
    let point = model.undistort(&noisy).ok()?;
    Some((point, model.normalized_covariance(&point, sigma_px)))
}

/// Position error of a report against target `i`'s truth at the report's time.
pub fn error(sim: &Sim, r: &TrackReport, i: usize) -> f64 {
    let truth = sim.truth(i, r.time);
    let m = Vector3::new(r.mean[0], r.mean[1], r.mean[2]);
    (m - truth.fixed_rows::<3>(0)).norm()
}
