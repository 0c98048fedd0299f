//! The camera node's sans-IO state machine.
//!
//! Inputs: messages from its head and the server ([`CameraNode::on_message`]), frames
//! ([`CameraNode::on_frame`]), RSSI readings of target tags ([`CameraNode::on_rssi`]) and
//! ticks ([`CameraNode::tick`]), each with the current cluster time. Outputs: messages to
//! send. In distributed mode it answers every `Prior` with one `Contribution` built from the
//! newest frame's detection gated to that target (all-zero Ω when it has none); detections
//! gated to no prior go out as `Measurement { target: None }` so heads can start tracks. In
//! centralized mode every detection goes out as a `Measurement`. Modes (Active, CameraOff,
//! Inactive) follow the head's `Command`s; time in each is reported in `NodeStatus`.

use crate::config::CameraConfig;
use crate::detect::Detection;
use crate::frame::Frame;
use crate::measure::{self, Measured};
use crate::segment::Segmenter;
use proto::msg::{Message, Mode, NodeStatus, Prior, RssiReading};
use proto::node::Outgoing;
use proto::scenario::Fusion;
use proto::validate::Validate;
use proto::{ClusterTime, Envelope, TargetId};
use std::collections::BTreeMap;
use tracing::{debug, warn};

/// Counters of what the node did and refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    pub frames: u64,
    /// Frames not processed because the camera was off.
    pub frames_skipped: u64,
    pub detections: u64,
    /// Frames, messages and readings rejected as malformed or not for this node.
    pub rejected: u64,
    pub priors: u64,
    /// Priors received while inactive (radio asleep), not answered.
    pub priors_ignored: u64,
    pub contributions: u64,
    pub camera_contributions: u64,
    pub measurements: u64,
    /// Detections that could not be undistorted.
    pub undistort_failures: u64,
    /// Messages with nowhere to go (no head or server known).
    pub unsent: u64,
    /// Messages the runtime could not deliver, as it reports them.
    pub dropped: u64,
    /// Motion-segmented detections no prior gated that were not sent because they had not
    /// moved since the previous frame (or there was no recent previous frame to tell).
    pub still_unassociated: u64,
}

/// Pixels a motion-segmented region's centre must move between consecutive frames to be
/// offered for a new track (a region no prior gated). Paper 004's model only sees what moves,
/// so a region that stands still is where the model's background is wrong: the ghost a target
/// leaves where it stood when the model was (re)started. Two woken cameras' ghosts
/// triangulated into false tracks (Table I, pixel level: with the head's own guards,
/// ghost global ids in 7 of the proposed method's 40 runs, 2 with this). Not caught: a ghost while the target is still
/// uncovering it (it grows, so its centre moves), nor, probably, while the model absorbs it
/// (pixels go in the order they were uncovered, so it shrinks along the target's path). Also
/// held back: a target whose region moves less than this (e.g. one walking straight at the
/// camera) or more than its own size (no region of the previous frame within reach); another
/// camera or the next frame offers it. Regions that gate to a prior are always used, and only
/// the distributed filter holds any back (see `CameraNode::motion_check`).
pub const STILL_PX: f32 = 1.0;

/// The camera node core.
#[derive(Debug)]
pub struct CameraNode {
    cfg: CameraConfig,
    segmenter: Segmenter,
    scratch: Vec<Detection>,
    measured: Vec<Measured>,
    previous: Vec<Measured>,
    captured: Option<ClusterTime>,
    priors: BTreeMap<TargetId, (ClusterTime, Prior)>,
    rssi: BTreeMap<TargetId, RssiReading>,
    mode: Mode,
    mode_since: ClusterTime,
    time_in_mode_ns: [u64; 3],
    last_status: Option<ClusterTime>,
    /// The runtime's time-sync estimate: offset to the leader and sync error, ns (error −1:
    /// not synchronized yet).
    sync: (i64, i64),
    counters: Counters,
}

impl CameraNode {
    pub fn new(cfg: CameraConfig, now: ClusterTime) -> CameraNode {
        let segmenter = Segmenter::new(&cfg.segment);
        CameraNode {
            mode: cfg.initial_mode,
            cfg,
            segmenter,
            scratch: Vec::with_capacity(64),
            measured: Vec::with_capacity(64),
            previous: Vec::with_capacity(64),
            captured: None,
            priors: BTreeMap::new(),
            rssi: BTreeMap::new(),
            mode_since: now,
            time_in_mode_ns: [0; 3],
            last_status: None,
            sync: (0, -1),
            counters: Counters::default(),
        }
    }

    pub fn config(&self) -> &CameraConfig {
        &self.cfg
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Detections of the newest processed frame, undistorted.
    pub fn latest(&self) -> &[Measured] {
        &self.measured
    }

    /// Cumulative time in Active, CameraOff, Inactive up to `now`, ns.
    pub fn time_in_mode_ns(&self, now: ClusterTime) -> [u64; 3] {
        let mut t = self.time_in_mode_ns;
        t[self.mode.index()] += (now - self.mode_since).max(0) as u64;
        t
    }

    /// The runtime's time-sync estimate (`proto::sync::SyncEstimator`), reported in the next
    /// `NodeStatus`: offset to the leader and sync error, ns; a negative error means unknown.
    pub fn set_sync(&mut self, offset_ns: i64, error_ns: i64) {
        self.sync = (offset_ns, error_ns);
    }

    /// The runtime reports messages it could not deliver.
    pub fn record_dropped(&mut self, n: u64) {
        self.counters.dropped += n;
    }

    fn switch_mode(&mut self, now: ClusterTime, mode: Mode) {
        if mode == self.mode {
            return;
        }
        self.time_in_mode_ns = self.time_in_mode_ns(now);
        self.mode_since = now;
        debug!(node = %self.cfg.id, from = ?self.mode, to = ?mode, "mode switch");
        self.mode = mode;
        if !mode.camera_on() {
            self.measured.clear();
            self.previous.clear();
            self.captured = None;
        }
        if !mode.radio_on() {
            self.rssi.clear();
        }
    }

    /// Within `max_age_ms` of now, either way: frames are fused at their capture time, so one
    /// stamped in the future (a source clock that is off) must not count as fresh either.
    fn fresh(&self, t: ClusterTime, now: ClusterTime) -> bool {
        (now - t).abs() <= self.cfg.max_age_ms as i64 * 1_000_000
    }

    fn reject(&mut self, what: &'static str, problem: String) {
        self.counters.rejected += 1;
        warn!(node = %self.cfg.id, what, %problem, "rejected input");
    }

    fn send_to_head(&mut self, body: Message, out: &mut Vec<Outgoing>) {
        match self.cfg.head {
            Some(h) => out.push(Outgoing::new(h, body)),
            None => self.counters.unsent += 1,
        }
    }

    /// A message from the head or the server.
    pub fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if let Err(e) = env.validate() {
            self.reject("message", e.to_string());
            return out;
        }
        match env.body {
            Message::Prior(p) => {
                if !self.mode.radio_on() {
                    self.counters.priors_ignored += 1;
                    return out;
                }
                self.counters.priors += 1;
                if self.cfg.fusion == Fusion::DistributedEif {
                    let c = self.answer(now, &p);
                    self.counters.contributions += 1;
                    self.counters.camera_contributions += u64::from(c.camera);
                    out.push(Outgoing::new(env.source, Message::Contribution(c)));
                }
                self.priors.insert(p.target, (now, p));
            }
            Message::Command(c) => {
                if c.node != self.cfg.id {
                    self.reject("command", format!("addressed to {}", c.node));
                } else {
                    self.switch_mode(now, c.mode);
                }
            }
            Message::Assignment(a) => {
                if a.node != self.cfg.id {
                    self.reject("assignment", format!("addressed to {}", a.node));
                } else {
                    self.cfg.head = Some(a.head);
                }
            }
            Message::Heartbeat
            | Message::Hello(_)
            | Message::HelloAck(_)
            | Message::SyncBeacon(_)
            | Message::Liveness(_) => {}
            other => self.reject("message", format!("a camera does not take {}", other.kind())),
        }
        out
    }

    /// The contribution for one prior from the newest frame.
    fn answer(&self, now: ClusterTime, prior: &Prior) -> proto::msg::Contribution {
        let rssi = self
            .rssi
            .get(&prior.target)
            .copied()
            .filter(|r| self.fresh(r.time, now));
        let captured = self.captured.filter(|&t| self.fresh(t, now));
        // The prior's mean is for the step the head opened as it sent it; its arrival here
        // stands for that time on this node's own clock (the link's latency is small against a
        // frame period), so the frame's age needs no clock shared with the head.
        let age_s = captured.map_or(0.0, |t| now.secs_since(t));
        let cam = &self.cfg.camera;
        let chosen = captured.and_then(|_| {
            self.measured
                .iter()
                .filter_map(|m| measure::mahalanobis2(cam, prior, m, age_s).map(|d2| (d2, m)))
                .filter(|(d2, _)| *d2 <= self.cfg.gate_chi2)
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, m)| m)
        });
        measure::contribution(
            cam,
            prior,
            chosen,
            captured.unwrap_or(now),
            age_s,
            self.mode,
            rssi,
        )
    }

    /// A captured frame. Segmented only in Active mode.
    pub fn on_frame(&mut self, now: ClusterTime, frame: &Frame) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if !self.mode.camera_on() {
            self.counters.frames_skipped += 1;
            return out;
        }
        let k = &self.cfg.camera.intrinsics;
        if (frame.width, frame.height) != (k.width, k.height) {
            self.reject(
                "frame",
                format!(
                    "{}x{} frame, camera is {}x{}",
                    frame.width, frame.height, k.width, k.height
                ),
            );
            return out;
        }
        if let Err(e) = self.segmenter.process(frame, &mut self.scratch) {
            self.reject("frame", e.to_string());
            return out;
        }
        self.counters.frames += 1;
        let detections = std::mem::take(&mut self.scratch);
        let moving_only = self.motion_check(frame.captured);
        self.apply_detections(now, frame.captured, &detections, moving_only, &mut out);
        self.scratch = detections;
        out
    }

    /// Detections made elsewhere (the measurement-level simulation projects the truth and adds
    /// noise instead of rendering and segmenting). Handled exactly as a segmented frame's.
    pub fn on_detections(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
    ) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if !self.mode.camera_on() {
            self.counters.frames_skipped += 1;
            return out;
        }
        self.counters.frames += 1;
        self.apply_detections(now, captured, detections, None, &mut out);
        out
    }

    /// Detections already segmented and undistorted elsewhere: a logging run measures every
    /// frame whatever the mode, and a replay feeds a recording's measurements back. Handled
    /// exactly as a frame's detections after undistortion (`segmented`: they came from this
    /// node's segmentation of frames, not from the measurement-level simulation's projection
    /// of the truth); ignored when the camera is off. Non-finite points or covariances reject
    /// the whole frame and change no state.
    pub fn on_measured(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        measured: &[Measured],
        segmented: bool,
    ) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if !self.mode.camera_on() {
            self.counters.frames_skipped += 1;
            return out;
        }
        if let Some(m) = measured
            .iter()
            .find(|m| !(m.point.iter().chain(m.cov.iter()).all(|x| x.is_finite())))
        {
            self.reject(
                "measured",
                format!("point {:?} or its covariance is not finite", m.point),
            );
            return out;
        }
        self.counters.frames += 1;
        self.counters.detections += measured.len() as u64;
        let moving_only = if segmented {
            self.motion_check(captured)
        } else {
            None
        };
        std::mem::swap(&mut self.previous, &mut self.measured);
        self.measured.clear();
        self.measured.extend_from_slice(measured);
        self.captured = Some(captured);
        self.forget_stale(now);
        self.send_measurements(now, captured, moving_only, &mut out);
        out
    }

    /// For motion-segmented detections (paper 004) in the distributed filter, whether the frame
    /// before `captured` can tell what moved: it exists and the model did not restart since
    /// (a gap longer than its memory, as after a sleep). `None` where still regions may be
    /// targets: colour segmentation sees targets that stand still, and in centralized fusion
    /// the head associates every measurement itself, so one the camera could not gate may
    /// still update a track.
    fn motion_check(&self, captured: ClusterTime) -> Option<bool> {
        let Segmenter::Paper004(seg) = &self.segmenter else {
            return None;
        };
        if self.cfg.fusion != Fusion::DistributedEif {
            return None;
        }
        let memory_s = seg.params().restart_gap_ms as f64 / 1e3;
        Some(
            self.captured
                .is_some_and(|t| memory_s <= 0.0 || captured.secs_since(t) <= memory_s),
        )
    }

    fn apply_detections(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
        moving_only: Option<bool>,
        out: &mut Vec<Outgoing>,
    ) {
        self.counters.detections += detections.len() as u64;
        std::mem::swap(&mut self.previous, &mut self.measured);
        self.measured.clear();
        for d in detections {
            match measure::measure(&self.cfg.camera, d, self.cfg.reference, self.cfg.pixel_sigma) {
                Ok(m) => self.measured.push(m),
                Err(_) => self.counters.undistort_failures += 1,
            }
        }
        self.captured = Some(captured);
        self.forget_stale(now);
        self.send_measurements(now, captured, moving_only, out);
    }

    /// Gate the newest detections against the known priors and send what the mode asks for.
    /// `moving_only` (see [`Self::motion_check`]): a detection no prior gated is sent only if
    /// it moved ([`STILL_PX`]) since a recent previous frame.
    fn send_measurements(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        moving_only: Option<bool>,
        out: &mut Vec<Outgoing>,
    ) {
        // A prior's time is when it arrived (see `answer`); frames newer than it have a
        // negative age. A prior kept from longer ago than a frame may be old gates nothing.
        let priors: Vec<(&Prior, f64)> = self
            .priors
            .values()
            .filter(|(t, _)| self.fresh(captured, *t))
            .map(|(t, p)| (p, t.secs_since(captured)))
            .collect();
        let assoc = measure::associate(&self.cfg.camera, &priors, &self.measured, self.cfg.gate_chi2);
        let targets: Vec<Option<(TargetId, u64)>> = assoc
            .iter()
            .map(|a| a.map(|i| (priors[i].0.target, priors[i].0.step)))
            .collect();
        let centralized = self.cfg.fusion != Fusion::DistributedEif;
        let mut msgs = Vec::new();
        for (m, target) in self.measured.iter().zip(targets) {
            if target.is_some() && !centralized {
                continue;
            }
            if target.is_none()
                && let Some(recent) = moving_only
                && !(recent && moved_px(&self.previous, m).is_some_and(|d| d >= STILL_PX))
            {
                self.counters.still_unassociated += 1;
                continue;
            }
            let rssi = target
                .and_then(|(t, _)| self.rssi.get(&t).copied())
                .filter(|r| self.fresh(r.time, now));
            let prev = self
                .cfg
                .previous_point
                .then(|| nearest(&self.previous, m))
                .flatten();
            msgs.push(Message::Measurement(measure::measurement(
                &self.cfg.camera,
                m,
                target,
                prev,
                captured,
                self.mode,
                rssi,
            )));
        }
        for body in msgs {
            self.counters.measurements += 1;
            self.send_to_head(body, out);
        }
    }

    fn forget_stale(&mut self, now: ClusterTime) {
        let timeout = self.cfg.prior_timeout_ms as i64 * 1_000_000;
        self.priors.retain(|_, (t, _)| now - *t <= timeout);
    }

    /// An RSSI reading of `target`'s tag, dBm.
    pub fn on_rssi(&mut self, now: ClusterTime, target: TargetId, dbm: f64) {
        if !(dbm.is_finite() && (-200.0..=30.0).contains(&dbm)) {
            self.reject("rssi", format!("{dbm} dBm is not a finite reading in -200..30"));
            return;
        }
        if !self.cfg.rssi || !self.mode.radio_on() {
            return;
        }
        self.rssi.insert(target, RssiReading { dbm, time: now });
    }

    /// Periodic work: forget stale priors, send `NodeStatus` every status period.
    pub fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let mut out = Vec::new();
        self.forget_stale(now);
        let period = self.cfg.status_period_ms as i64 * 1_000_000;
        if self.last_status.is_some_and(|t| now - t < period) {
            return out;
        }
        self.last_status = Some(now);
        let c = self.counters;
        let status = NodeStatus {
            mode: self.mode,
            time_in_mode_ns: self.time_in_mode_ns(now),
            frames: c.frames,
            detections: c.detections,
            dropped: c.dropped + c.unsent,
            rejected: c.rejected,
            sync_offset_ns: self.sync.0,
            sync_error_ns: self.sync.1,
        };
        self.send_to_head(Message::NodeStatus(status.clone()), &mut out);
        match self.cfg.server {
            Some(s) if Some(s) != self.cfg.head => out.push(Outgoing::new(s, Message::NodeStatus(status))),
            Some(_) => {}
            None => self.counters.unsent += 1,
        }
        out
    }
}

/// The previous frame's point nearest to `m` in the image, if within a box width.
fn nearest(previous: &[Measured], m: &Measured) -> Option<nalgebra::Vector2<f64>> {
    nearest_with_shift(previous, m).map(|(_, p)| p.point)
}

/// How far (pixels) a region's centre moved from the nearest region of the previous frame,
/// if one lies within the region's extent.
fn moved_px(previous: &[Measured], m: &Measured) -> Option<f32> {
    nearest_with_shift(previous, m).map(|(d, _)| d)
}

fn nearest_with_shift<'a>(previous: &'a [Measured], m: &Measured) -> Option<(f32, &'a Measured)> {
    let b = m.detection.bbox;
    let reach = (b.xmax - b.xmin).max(b.ymax - b.ymin);
    let c = m.detection.centre;
    previous
        .iter()
        .map(|p| {
            let pc = p.detection.centre;
            (((pc[0] - c[0]).powi(2) + (pc[1] - c[1]).powi(2)).sqrt(), p)
        })
        .filter(|(d, _)| *d <= reach)
        .min_by(|a, b| a.0.total_cmp(&b.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use nalgebra::{Matrix6, Vector3};
    use proto::NodeId;
    use proto::models;
    use proto::msg::{Command, Prior};
    use proto::scenario::Scenario;

    const CAM: u32 = 10;

    fn setup(fusion: Fusion) -> (Scenario, CameraNode, Renderer) {
        let mut s = Scenario::default_scenario();
        s.method.fusion = fusion;
        let cfg = CameraConfig::from_scenario(&s, CAM).unwrap();
        let r = Renderer::for_node(&s, CAM, 3).unwrap();
        (s, CameraNode::new(cfg, ClusterTime::ZERO), r)
    }

    fn env(body: Message) -> Envelope {
        Envelope {
            source: NodeId(2),
            seq: 1,
            time: ClusterTime::ZERO,
            body,
        }
    }

    fn prior(s: &Scenario, t: f64, offset: f64, step: u64) -> Prior {
        let mut mean = s.targets[0].truth_at(t);
        mean[0] += offset;
        Prior {
            target: TargetId(1),
            step,
            mean: models::vec6_to_wire(&mean),
            cov: models::mat6_to_wire(&(Matrix6::identity() * 0.04)),
            deadline: ClusterTime::from_secs_f64(t + 0.08),
        }
    }

    /// Feed rendered frames from `t0` to `t1` at 5 fps; returns all outputs.
    fn run(node: &mut CameraNode, s: &Scenario, r: &Renderer, t0: f64, t1: f64) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let mut f = Frame::new(0, 0, ClusterTime::ZERO);
        let mut t = t0;
        while t <= t1 + 1e-9 {
            let now = ClusterTime::from_secs_f64(t);
            r.render(&s.targets, t, now, &mut f);
            out.extend(node.on_frame(now, &f));
            t += 0.2;
        }
        out
    }

    /// Centralized mode gates a frame against the priors at the frame's time: a target moving
    /// at 10 m/s whose prior came 0.1 s before the frame is 1 m behind in that prior, and the
    /// detection is still gated to it (as current, it would be far outside the gate).
    #[test]
    fn a_frame_is_gated_against_where_the_prior_puts_the_target_then() {
        let (s, mut node, r) = setup(Fusion::CentralizedEif);
        run(&mut node, &s, &r, 0.0, 5.8);
        let truth = s.targets[0].truth_at(6.0);
        let mut mean = truth;
        mean[3] = 10.0;
        mean[4] = 0.0;
        mean[0] -= 1.0;
        let p = Prior {
            target: TargetId(1),
            step: 30,
            mean: models::vec6_to_wire(&mean),
            cov: models::mat6_to_wire(&(Matrix6::identity() * 0.0025)),
            deadline: ClusterTime::from_secs_f64(5.98),
        };
        node.on_message(ClusterTime::from_secs_f64(5.9), env(Message::Prior(p)));
        let mut f = Frame::new(0, 0, ClusterTime::ZERO);
        let now = ClusterTime::from_secs_f64(6.0);
        r.render(&s.targets, 6.0, now, &mut f);
        let out = node.on_frame(now, &f);
        let gated: Vec<_> = out
            .iter()
            .filter_map(|o| match &o.body {
                Message::Measurement(m) => Some(m.target),
                _ => None,
            })
            .collect();
        assert!(gated.contains(&Some(TargetId(1))), "{gated:?}");
    }

    /// A frame far from the prior's arrival, older or (a source clock that is off) newer, is
    /// not used: frames are fused at their capture time.
    #[test]
    fn a_frame_far_from_the_prior_is_not_used_either_way() {
        for arrival in [16.0, -4.0] {
            let (s, mut node, r) = setup(Fusion::DistributedEif);
            run(&mut node, &s, &r, 0.0, 6.0);
            let now = ClusterTime::from_secs_f64(arrival);
            let got = node.on_message(now, env(Message::Prior(prior(&s, 6.0, 0.15, 31))));
            let Message::Contribution(c) = &got[0].body else {
                panic!("expected a contribution, got {:?}", got[0].body)
            };
            assert!(
                !c.camera,
                "a frame 10 s from the prior was used (arrival {arrival} s)"
            );
        }
    }

    #[test]
    fn answers_a_prior_with_the_gated_detection() {
        let (s, mut node, r) = setup(Fusion::DistributedEif);
        let cam = s.camera_model(CAM).unwrap();
        let outs = run(&mut node, &s, &r, 0.0, 6.0);
        // No prior yet: whatever it sees goes out as a track-starting measurement.
        assert!(
            outs.iter()
                .any(|o| matches!(&o.body, Message::Measurement(m) if m.target.is_none()))
        );
        assert!(outs.iter().all(|o| o.to == NodeId(2)));
        let t = 6.0;
        let now = ClusterTime::from_secs_f64(t + 0.01);
        let got = node.on_message(now, env(Message::Prior(prior(&s, t, 0.15, 31))));
        assert_eq!(got.len(), 1);
        let Message::Contribution(c) = &got[0].body else {
            panic!("expected a contribution, got {:?}", got[0].body)
        };
        assert_eq!(
            (c.target, c.step, c.camera, c.mode),
            (TargetId(1), 31, true, Mode::Active)
        );
        assert_eq!(got[0].to, NodeId(2), "answers the head that asked");
        // Recover the measured point from ξ and Ω: the measurement the camera used lies
        // within a few pixels of the true centre's projection.
        let truth = s.targets[0].truth_at(t);
        let m = node
            .latest()
            .iter()
            .min_by(|a, b| {
                let (p, _) = cam.normalized(&models::position(&truth));
                (a.point - p).norm().total_cmp(&(b.point - p).norm())
            })
            .unwrap();
        let (p, _) = cam.normalized(&models::position(&truth));
        let px_err = (m.point - p).norm() * cam.intrinsics.fx;
        assert!(px_err < 12.0, "centre off by {px_err:.1} px");
        let expected = measure::contribution(
            &cam,
            &prior(&s, t, 0.15, 31),
            Some(m),
            c.captured,
            now.secs_since(c.captured),
            Mode::Active,
            None,
        );
        assert_eq!(
            c.info_vector, expected.info_vector,
            "built from the nearest detection"
        );
    }

    /// A frame of the camera's size: a textured floor and, at column `x`, a 30×40 block.
    fn block_frame(s: &Scenario, t: f64, x: Option<usize>) -> Frame {
        let k = s.camera_model(CAM).unwrap().intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let mut f = Frame::new(k.width, k.height, ClusterTime::from_secs_f64(t));
        let tick = (t * 10.0).round() as usize;
        for y in 0..h {
            for c in 0..w {
                let i = (y * w + c) * 3;
                let n = ((c * 7 + y * 13 + tick * 29) % 5) as u8;
                let block = x.is_some_and(|x| (x..x + 30).contains(&c) && (120..160).contains(&y));
                let rgb = if block {
                    [200, 30, 40]
                } else {
                    [90 + n, 100 + n, 80 + n]
                };
                f.data[i..i + 3].copy_from_slice(&rgb);
            }
        }
        f
    }

    /// A camera woken after a gap restarts its model from its first frame, block included:
    /// once the block moves on, the place it stood shows as a still region (a ghost) until
    /// the model absorbs it. Only regions that moved since the previous frame are offered for
    /// new tracks: the ghost once it stands still is not, the block is.
    #[test]
    fn still_regions_are_not_offered_for_new_tracks() {
        let (s, mut node, _) = setup(Fusion::DistributedEif);
        let mut offered = Vec::new();
        let mut t = 0.0;
        for x in (0..10).map(|_| None).chain((0..8).map(|k| Some(40 + 12 * k))) {
            // Frames 0–1.8 s without the block, then a 5 s gap, then the block moving.
            let now = ClusterTime::from_secs_f64(t);
            for o in node.on_frame(now, &block_frame(&s, t, x)) {
                if let Message::Measurement(m) = o.body {
                    offered.push((x, m.pixel_box));
                }
            }
            t += if t > 1.7 && t < 2.0 { 5.0 } else { 0.2 };
        }
        // While the block uncovers where it stood, that region grows and its centre moves, so
        // it is offered; from the frame after the block has left it (x ≥ 70), it stands still
        // and is not.
        let uncovered: Vec<_> = offered
            .iter()
            .filter(|(x, _)| x.is_some_and(|x| x >= 82))
            .collect();
        assert!(uncovered.len() >= 3, "the moving block is offered: {offered:?}");
        for (x, b) in uncovered {
            let x = x.unwrap() as f32;
            let centre = (b.xmin + b.xmax) / 2.0;
            assert!(
                (centre - (x + 15.0)).abs() < 4.0,
                "offered a region at {centre}, block at {x}: {b:?}"
            );
        }
        assert!(
            offered.iter().all(|(x, _)| x.is_some()),
            "nothing before the block: {offered:?}"
        );
        assert!(node.counters().still_unassociated >= 3, "{:?}", node.counters());
    }

    #[test]
    fn empty_answer_when_nothing_matches_and_bad_input_changes_nothing() {
        let (s, mut node, r) = setup(Fusion::DistributedEif);
        run(&mut node, &s, &r, 0.0, 2.0);
        let now = ClusterTime::from_secs_f64(2.05);
        // A prior 4 m away from anything the camera sees.
        let got = node.on_message(now, env(Message::Prior(prior(&s, 2.0, 4.0, 5))));
        let Message::Contribution(c) = &got[0].body else {
            panic!()
        };
        assert!(!c.camera);
        assert!(c.info_matrix.iter().flatten().all(|&v| v == 0.0));
        let before = node.counters();
        let mut bad = prior(&s, 2.0, 0.0, 6);
        bad.mean[0] = f64::NAN;
        assert!(node.on_message(now, env(Message::Prior(bad))).is_empty());
        let other = Command {
            node: NodeId(99),
            mode: Mode::Inactive,
        };
        assert!(node.on_message(now, env(Message::Command(other))).is_empty());
        assert_eq!(node.mode(), Mode::Active);
        assert_eq!(node.counters().rejected, before.rejected + 2);
        assert_eq!(node.counters().priors, before.priors);
        let wrong = Frame::new(100, 100, now);
        assert!(node.on_frame(now, &wrong).is_empty());
        assert_eq!(node.counters().rejected, before.rejected + 3);
        node.on_rssi(now, TargetId(1), f64::INFINITY);
        assert_eq!(node.counters().rejected, before.rejected + 4);
    }

    #[test]
    fn modes_gate_capture_and_radio_and_time_is_accounted() {
        let (s, mut node, r) = setup(Fusion::DistributedEif);
        run(&mut node, &s, &r, 0.0, 1.0);
        let frames = node.counters().frames;
        let cmd = |m| {
            env(Message::Command(Command {
                node: NodeId(CAM),
                mode: m,
            }))
        };
        node.on_message(ClusterTime::from_secs_f64(1.0), cmd(Mode::CameraOff));
        run(&mut node, &s, &r, 1.2, 3.0);
        assert_eq!(
            node.counters().frames,
            frames,
            "no capture when the camera is off"
        );
        assert_eq!(node.counters().frames_skipped, 10);
        node.on_rssi(ClusterTime::from_secs_f64(3.0), TargetId(1), -60.0);
        let got = node.on_message(
            ClusterTime::from_secs_f64(3.05),
            env(Message::Prior(prior(&s, 3.0, 0.0, 9))),
        );
        let Message::Contribution(c) = &got[0].body else {
            panic!()
        };
        assert!(!c.camera && c.mode == Mode::CameraOff);
        assert_eq!(c.rssi.map(|r| r.dbm), Some(-60.0), "CameraOff still reports RSSI");
        node.on_message(ClusterTime::from_secs_f64(4.0), cmd(Mode::Inactive));
        node.on_rssi(ClusterTime::from_secs_f64(4.5), TargetId(1), -61.0);
        assert!(
            node.on_message(
                ClusterTime::from_secs_f64(4.6),
                env(Message::Prior(prior(&s, 4.6, 0.0, 10)))
            )
            .is_empty()
        );
        assert_eq!(node.counters().priors_ignored, 1);
        node.on_message(ClusterTime::from_secs_f64(7.0), cmd(Mode::Active));
        let t = node.time_in_mode_ns(ClusterTime::from_secs_f64(8.0));
        assert_eq!(t, [2_000_000_000, 3_000_000_000, 3_000_000_000]);
        let status = node.tick(ClusterTime::from_secs_f64(8.0));
        assert_eq!(status.len(), 2, "to the head and the server");
        let Message::NodeStatus(st) = &status[0].body else {
            panic!()
        };
        assert_eq!(st.time_in_mode_ns, t);
        assert_eq!(st.mode, Mode::Active);
        assert_eq!(
            (st.sync_offset_ns, st.sync_error_ns),
            (0, -1),
            "not synchronized yet"
        );
        assert!(
            node.tick(ClusterTime::from_secs_f64(8.5)).is_empty(),
            "once per period"
        );
        node.set_sync(-1_500_000, 40_000);
        let status = node.tick(ClusterTime::from_secs_f64(9.0));
        assert_eq!(status.len(), 2);
        let Message::NodeStatus(st) = &status[1].body else {
            panic!()
        };
        assert_eq!((st.sync_offset_ns, st.sync_error_ns), (-1_500_000, 40_000));
    }

    #[test]
    fn centralized_mode_sends_gated_measurements_with_pose() {
        let (s, mut node, r) = setup(Fusion::CentralizedEif);
        run(&mut node, &s, &r, 0.0, 5.8);
        let t = 6.0;
        let got = node.on_message(
            ClusterTime::from_secs_f64(5.9),
            env(Message::Prior(prior(&s, t, 0.1, 40))),
        );
        assert!(
            got.is_empty(),
            "centralized nodes do not answer priors with contributions"
        );
        let outs = run(&mut node, &s, &r, t, t);
        let gated: Vec<_> = outs
            .iter()
            .filter_map(|o| match &o.body {
                Message::Measurement(m) if m.target == Some(TargetId(1)) => Some(m),
                _ => None,
            })
            .collect();
        assert_eq!(gated.len(), 1, "{outs:?}");
        let cam = s.camera_model(CAM).unwrap();
        assert_eq!(gated[0].pose, cam.pose.to_wire());
        assert_eq!(gated[0].step, 40);
        let (p, _) = cam.normalized(&Vector3::new(
            s.targets[0].truth_at(t)[0],
            s.targets[0].truth_at(t)[1],
            s.targets[0].truth_at(t)[2],
        ));
        let err = ((gated[0].point[0] - p.x).powi(2) + (gated[0].point[1] - p.y).powi(2)).sqrt();
        assert!(err * cam.intrinsics.fx < 12.0, "{err}");
    }

    #[test]
    fn measured_input_answers_like_the_frame_it_came_from() {
        let (s, mut a, r) = setup(Fusion::DistributedEif);
        let (_, mut b, _) = setup(Fusion::DistributedEif);
        let mut f = Frame::new(0, 0, ClusterTime::ZERO);
        let mut t = 0.0;
        while t <= 6.0 {
            let now = ClusterTime::from_secs_f64(t);
            r.render(&s.targets, t, now, &mut f);
            let from_frame = a.on_frame(now, &f);
            let logged = a.latest().to_vec();
            assert_eq!(b.on_measured(now, now, &logged, true), from_frame);
            t += 0.2;
        }
        let now = ClusterTime::from_secs_f64(6.01);
        let p = || env(Message::Prior(prior(&s, 6.0, 0.1, 31)));
        let (ca, cb) = (a.on_message(now, p()), b.on_message(now, p()));
        assert!(matches!(&ca[0].body, Message::Contribution(c) if c.camera));
        assert_eq!(ca, cb, "the same contribution from the same measurements");
        assert_eq!(a.counters().frames, b.counters().frames);

        let mut bad = a.latest().to_vec();
        bad[0].cov[(0, 0)] = f64::NAN;
        let before = b.counters();
        assert!(b.on_measured(now, now, &bad, true).is_empty());
        assert_eq!(b.counters().rejected, before.rejected + 1);
        assert_eq!(b.counters().frames, before.frames);
        assert_eq!(b.latest(), a.latest(), "a rejected frame changes nothing");

        let off = env(Message::Command(Command {
            node: NodeId(CAM),
            mode: Mode::CameraOff,
        }));
        b.on_message(now, off);
        assert!(b.on_measured(now, now, a.latest(), true).is_empty());
        assert_eq!(b.counters().frames_skipped, before.frames_skipped + 1);
    }
}
