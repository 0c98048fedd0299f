//! The sans-IO head core, [`HeadNode`]: messages and ticks in, messages out.
//!
//! Every `method.step_ms` a tick opens a step: tracks are predicted and a `Prior` goes to every
//! member node that is up and not Inactive. The step closes when every expected node answered
//! every track or the deadline passed; then the sums are applied, RSSI is linearized with each
//! node's (trained or default) model, a `TrackReport` per track goes to the server, new tracks
//! are born from agreeing unassociated detections, and activation sends at most one `Command`.

use crate::activation::{Candidate, Expected, Planner, Variant};
use crate::association::{Detection, associate, births};
use crate::config::{HeadConfig, NodeInfo};
use crate::eif::Eif;
use crate::ml;
use crate::stats::{Counters, StepStats};
use crate::step::{Offer, StepWindow};
use crate::track::Track;
use nalgebra::{Matrix2, Matrix6, Vector2, Vector3};
use proto::models::{
    Info, State, camera_contribution, information_contribution, mat6_from_wire, mat6_to_wire,
    pinhole_previous, rssi_contribution, vec6_from_wire, vec6_to_wire,
};
use proto::msg::{Command, Contribution, Handover, Measurement, Prior, TrackReport};
use proto::node::Outgoing;
use proto::scenario::{Activation, Fusion};
use proto::{ClusterTime, Envelope, Message, Mode, NodeId, TargetId};
use std::collections::HashMap;
use tracing::{debug, info, warn};

/// Most detections a head buffers per step; more are dropped and counted.
pub const MAX_DETECTIONS_PER_STEP: usize = 4096;

#[derive(Clone, Debug)]
struct NodeState {
    info: NodeInfo,
    member: bool,
    up: bool,
    mode: Mode,
}

/// The head's state machine.
#[derive(Debug)]
pub struct HeadNode {
    cfg: HeadConfig,
    nodes: Vec<NodeState>,
    slots: HashMap<NodeId, usize>,
    cameras: Vec<proto::camera::CameraModel>,
    tracks: Vec<Track>,
    next_local: u32,
    window: StepWindow,
    step: u64,
    step_time: ClusterTime,
    next_step_at: Option<ClusterTime>,
    detections: Vec<Detection>,
    planner: Planner,
    expected: Vec<bool>,
    counters: Counters,
    last: StepStats,
    history: Vec<StepStats>,
    keep_history: bool,
}

impl HeadNode {
    pub fn new(cfg: HeadConfig) -> Self {
        let nodes: Vec<NodeState> = cfg
            .nodes
            .iter()
            .map(|n| NodeState {
                info: n.clone(),
                member: n.member,
                up: true,
                mode: Mode::Active,
            })
            .collect();
        let slots = nodes.iter().enumerate().map(|(i, n)| (n.info.id, i)).collect();
        let cameras = nodes.iter().map(|n| n.info.camera).collect();
        HeadNode {
            cfg,
            nodes,
            slots,
            cameras,
            tracks: Vec::new(),
            next_local: 1,
            window: StepWindow::default(),
            step: 0,
            step_time: ClusterTime::ZERO,
            next_step_at: None,
            detections: Vec::new(),
            planner: Planner::default(),
            expected: Vec::new(),
            counters: Counters::default(),
            last: StepStats::default(),
            history: Vec::new(),
            keep_history: false,
        }
    }

    /// Keep every step's stats (for experiments and tests).
    pub fn with_history(mut self) -> Self {
        self.keep_history = true;
        self
    }

    pub fn id(&self) -> NodeId {
        self.cfg.id
    }
    pub fn config(&self) -> &HeadConfig {
        &self.cfg
    }
    pub fn counters(&self) -> &Counters {
        &self.counters
    }
    pub fn last_step(&self) -> &StepStats {
        &self.last
    }
    pub fn history(&self) -> &[StepStats] {
        &self.history
    }
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }
    /// The head's belief of a node's mode.
    pub fn mode_of(&self, node: NodeId) -> Option<Mode> {
        self.slots.get(&node).map(|&s| self.nodes[s].mode)
    }
    /// Whether a step is waiting for contributions.
    pub fn step_open(&self) -> bool {
        self.window.is_open()
    }

    fn uses_rssi(&self) -> bool {
        matches!(
            self.cfg.method.activation,
            Activation::FullNode | Activation::ThreeMode
        )
    }

    /// Advance time: close a step past its deadline, open one when it is due.
    pub fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if self.window.past_deadline(now) {
            self.close_step(now, &mut out);
        }
        let due = self.next_step_at.is_none_or(|t| now >= t);
        if due {
            if self.window.is_open() {
                self.close_step(now, &mut out);
            }
            self.open_step(now, &mut out);
            let period = (self.cfg.method.step_ms as i64).saturating_mul(1_000_000);
            let next = self.next_step_at.map_or(now + period, |t| t + period);
            self.next_step_at = Some(if next <= now { now + period } else { next });
        }
        out
    }

    /// Handle one message. Messages from nodes not allowed to send them are counted and
    /// change no state.
    pub fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let src = env.source;
        let from_server = self.cfg.server == Some(src);
        let member = self.slots.get(&src).copied().filter(|&s| self.nodes[s].member);
        match env.body {
            Message::Contribution(c) => match member {
                Some(slot) => self.on_contribution(now, slot, c, &mut out),
                None => self.reject(src, "contribution"),
            },
            Message::Measurement(m) => match member {
                Some(slot) => self.on_measurement(slot, m),
                None => self.reject(src, "measurement"),
            },
            Message::NodeStatus(s) => match member {
                Some(slot) => self.nodes[slot].mode = s.mode,
                None => self.reject(src, "node_status"),
            },
            Message::Handover(h) if from_server => self.on_handover(now, h),
            Message::Liveness(l) if from_server => {
                if let Some(&slot) = self.slots.get(&l.node) {
                    self.nodes[slot].up = l.up;
                    if !l.up {
                        info!(node = %l.node, "node down; not waiting for it");
                        self.window.release(slot);
                        if self.window.complete() {
                            self.close_step(now, &mut out);
                        }
                    }
                }
            }
            Message::Assignment(a) if from_server => {
                if let Some(&slot) = self.slots.get(&a.node) {
                    let mine = a.head == self.cfg.id;
                    self.nodes[slot].member = mine;
                    if !mine {
                        self.window.release(slot);
                        if self.window.complete() {
                            self.close_step(now, &mut out);
                        }
                    }
                }
            }
            Message::Handover(_) | Message::Liveness(_) | Message::Assignment(_) => {
                self.reject(src, env.body.kind());
            }
            _ => {}
        }
        out
    }

    fn reject(&mut self, src: NodeId, kind: &'static str) {
        self.counters.rejected += 1;
        warn!(node = %src, kind, "message from a node not allowed to send it; ignored");
    }

    fn on_contribution(&mut self, now: ClusterTime, slot: usize, c: Contribution, out: &mut Vec<Outgoing>) {
        let Some(t) = self.tracks.iter().position(|tr| tr.local == c.target) else {
            self.counters.unknown_target += 1;
            debug!(node = %self.nodes[slot].info.id, target = %c.target, "contribution for an unknown track");
            return;
        };
        match self.window.offer(slot, t, c.step, now) {
            Offer::Apply => {
                self.counters.applied += 1;
                let node = &mut self.nodes[slot];
                node.mode = c.mode;
                let rssi = c.rssi.filter(|_| node.info.rssi).map(|r| r.dbm);
                let track = &mut self.tracks[t];
                if c.camera {
                    track.acc.add_wire(&c.info_matrix, &c.info_vector);
                    track.aux_acc.add_wire(&c.info_matrix, &c.info_vector);
                    track.last_seen = now;
                }
                if let Some(dbm) = rssi {
                    track.rssi.push((slot, dbm));
                }
                if c.camera || rssi.is_some() {
                    track.contributors.push(proto::msg::Contributor {
                        node: node.info.id,
                        camera: c.camera,
                        rssi: rssi.is_some(),
                    });
                }
            }
            Offer::Late => {
                self.counters.late += 1;
                debug!(node = %self.nodes[slot].info.id, step = c.step, current = self.step, "late contribution");
            }
            Offer::Duplicate => {
                self.counters.duplicate += 1;
                debug!(node = %self.nodes[slot].info.id, step = c.step, "duplicate contribution");
            }
            Offer::Future => {
                self.counters.future += 1;
                warn!(node = %self.nodes[slot].info.id, step = c.step, current = self.step, "contribution for a future step");
            }
        }
        if self.window.complete() {
            self.close_step(now, out);
        }
    }

    fn on_measurement(&mut self, slot: usize, m: Measurement) {
        self.nodes[slot].mode = m.mode;
        if self.detections.len() >= MAX_DETECTIONS_PER_STEP {
            self.counters.overflow += 1;
            return;
        }
        self.detections.push(Detection {
            node: self.nodes[slot].info.id,
            slot,
            point: Vector2::from(m.point),
            cov: Matrix2::new(m.cov[0], m.cov[1], m.cov[1], m.cov[2]),
            prev_point: m.prev_point.map(Vector2::from),
            rssi: m.rssi,
            hint: m.target,
        });
    }

    fn on_handover(&mut self, now: ClusterTime, h: Handover) {
        if h.to_head != self.cfg.id {
            if h.from_head == Some(self.cfg.id) {
                self.tracks.retain(|t| t.global != Some(h.global));
            }
            return;
        }
        if self.tracks.iter().any(|t| t.global == Some(h.global)) {
            return;
        }
        let mean = vec6_from_wire(&h.mean);
        let cov = mat6_from_wire(&h.cov);
        // The server naming one of our tracks: adopt the global id.
        let gate = self.cfg.method.gate_chi2;
        if let Some(t) = self.tracks.iter_mut().filter(|t| t.global.is_none()).find(|t| {
            let d = t.position() - mean.fixed_rows::<3>(0);
            let s = t.filter.cov().fixed_view::<3, 3>(0, 0) + cov.fixed_view::<3, 3>(0, 0);
            s.cholesky().is_some_and(|c| d.dot(&c.solve(&d)) <= gate)
        }) {
            t.global = Some(h.global);
            return;
        }
        let local = self.alloc_local();
        match self.new_track(local, Some(h.global), mean, cov, h.time.min(now)) {
            Ok(t) => {
                self.counters.handovers += 1;
                info!(global = %h.global, local = %local, "track handed over");
                self.tracks.push(t);
            }
            Err(e) => {
                self.counters.rejected += 1;
                warn!(global = %h.global, error = %e, "handover with an unusable posterior");
            }
        }
    }

    fn alloc_local(&mut self) -> TargetId {
        let id = TargetId(self.next_local);
        self.next_local = self.next_local.wrapping_add(1).max(1);
        id
    }

    fn new_track(
        &self,
        local: TargetId,
        global: Option<TargetId>,
        mean: State,
        cov: Matrix6<f64>,
        now: ClusterTime,
    ) -> Result<Track, crate::eif::FilterError> {
        let m = &self.cfg.method;
        Track::new(
            local,
            global,
            mean,
            cov,
            now,
            self.nodes.len(),
            m.rssi_default,
            m.rssi_window,
            m.rssi_epsilon,
        )
    }

    fn open_step(&mut self, now: ClusterTime, out: &mut Vec<Outgoing>) {
        let timeout = (self.cfg.method.track_timeout_ms as i64).saturating_mul(1_000_000);
        let before = self.tracks.len();
        self.tracks.retain(|t| {
            let keep = now - t.last_seen <= timeout;
            if !keep {
                info!(target = %t.local, "track silent too long; dropped");
            }
            keep
        });
        self.counters.deaths += (before - self.tracks.len()) as u64;
        let motion = self.cfg.method.motion;
        let mut failed = 0;
        self.tracks.retain_mut(|t| {
            let ok = t.begin_step(&motion, now).is_ok();
            failed += u64::from(!ok);
            ok
        });
        self.counters.numeric_failures += failed;
        self.counters.deaths += failed;
        self.step += 1;
        self.step_time = now;
        // Detections are kept: those that arrived between steps are associated at the close.
        let distributed = self.cfg.method.fusion == Fusion::DistributedEif;
        self.expected.clear();
        self.expected.extend(
            self.nodes
                .iter()
                .map(|n| distributed && n.member && n.up && n.mode != Mode::Inactive),
        );
        let deadline = now + (self.cfg.method.deadline_ms as i64).saturating_mul(1_000_000);
        self.window
            .open(self.step, deadline, self.tracks.len(), &self.expected);
        for t in &self.tracks {
            let prior = Prior {
                target: t.local,
                step: self.step,
                mean: vec6_to_wire(t.filter.mean()),
                cov: mat6_to_wire(t.filter.cov()),
                deadline,
            };
            for n in self
                .nodes
                .iter()
                .filter(|n| n.member && n.up && n.mode != Mode::Inactive)
            {
                out.push(Outgoing::new(n.info.id, Message::Prior(prior.clone())));
            }
        }
    }

    fn close_step(&mut self, now: ClusterTime, out: &mut Vec<Outgoing>) {
        let complete = self.window.complete();
        self.window.close();
        let counts = self.window.counts();
        let fusion = self.cfg.method.fusion;
        // Associate detections; leftovers may start tracks.
        let dets = std::mem::take(&mut self.detections);
        let priors: Vec<(State, Matrix6<f64>)> = self
            .tracks
            .iter()
            .map(|t| (*t.filter.mean(), *t.filter.cov()))
            .collect();
        let assigned = associate(&priors, &dets, &self.cameras, self.cfg.method.gate_chi2);
        let mut free = Vec::new();
        for (d, a) in dets.into_iter().zip(assigned) {
            match a {
                Some(t) if fusion != Fusion::DistributedEif => {
                    self.tracks[t].last_seen = now;
                    self.tracks[t].detections.push(d);
                }
                Some(_) => {}
                None => free.push(d),
            }
        }
        let mut stats = StepStats {
            step: self.step,
            time: self.step_time,
            tracks: self.tracks.len(),
            applied: counts.applied,
            late: counts.late,
            duplicate: counts.duplicate,
            complete,
            ..StepStats::default()
        };
        let mut rssi_nodes = vec![false; self.nodes.len()];
        for t in 0..self.tracks.len() {
            self.fuse_track(t, now, &mut stats, &mut rssi_nodes);
        }
        stats.rssi_nodes = rssi_nodes.iter().filter(|&&b| b).count();
        for t in &self.tracks {
            if let Some(server) = self.cfg.server {
                out.push(Outgoing::new(
                    server,
                    Message::TrackReport(TrackReport {
                        target: t.local,
                        global: t.global,
                        step: self.step,
                        time: t.time,
                        mean: vec6_to_wire(t.filter.mean()),
                        cov: mat6_to_wire(t.filter.cov()),
                        contributors: t.contributors.clone(),
                        power_mw: self.power_mw(),
                        late: self.counters.late,
                    }),
                ));
            }
        }
        self.birth(&free, now);
        stats.decision = self.activate(out);
        stats.power_mw = self.power_mw();
        for n in self.nodes.iter().filter(|n| n.member && n.up) {
            stats.active_cameras += usize::from(n.mode == Mode::Active);
            stats.camera_off += usize::from(n.mode == Mode::CameraOff);
        }
        let c = &mut self.counters;
        c.steps += 1;
        c.sum_active_cameras += stats.active_cameras as u64;
        c.sum_rssi_nodes += stats.rssi_nodes as u64;
        c.sum_power_mw += stats.power_mw;
        self.last = stats;
        if self.keep_history {
            self.history.push(stats);
        }
    }

    /// Apply one track's step: sums (or measurements), RSSI, update, training.
    fn fuse_track(&mut self, t: usize, now: ClusterTime, stats: &mut StepStats, rssi_nodes: &mut [bool]) {
        let uses_rssi = self.uses_rssi();
        let method = &self.cfg.method;
        let track = &mut self.tracks[t];
        let mean_bar = *track.filter.mean();
        // Centralized and ML: the head linearizes.
        let dets = std::mem::take(&mut track.detections);
        let mut ml_points = Vec::new();
        for d in &dets {
            let node = &self.nodes[d.slot].info;
            let cam = &node.camera;
            match method.fusion {
                Fusion::CentralizedEif => {
                    if let Some((o, x)) = camera_contribution(cam, &d.point, &d.cov, &mean_bar) {
                        track.acc.add(&o, &x);
                        track.aux_acc.add(&o, &x);
                    }
                    if method.previous_point
                        && let Some(prev) = d.prev_point
                        && let Some((h, jac)) = pinhole_previous(cam, &mean_bar, 1.0 / node.fps)
                        && let Some((o, x)) = information_contribution(&prev, &h, &jac, &d.cov, &mean_bar)
                    {
                        track.acc.add(&o, &x);
                        track.aux_acc.add(&o, &x);
                    }
                }
                Fusion::Ml => {
                    if let Some(p) = ml::lift(cam, &d.point, &d.cov, self.cfg.ml_depth) {
                        ml_points.push(p);
                    }
                }
                Fusion::DistributedEif => {}
            }
            if let Some(r) = d.rssi.filter(|_| node.rssi) {
                track.rssi.push((d.slot, r.dbm));
            }
            track.note(node.id, true, d.rssi.is_some() && node.rssi);
        }
        stats.applied += if method.fusion == Fusion::DistributedEif {
            0
        } else {
            dets.len() as u64
        };
        // RSSI, linearized here with the node's current model.
        if uses_rssi && method.fusion != Fusion::Ml {
            for &(slot, dbm) in &track.rssi {
                let node = &self.nodes[slot].info;
                let model = track.trainers[slot].model();
                if let Some((o, x)) = rssi_contribution(&model, &node.position, dbm, &mean_bar) {
                    track.acc.add(&o, &x);
                    rssi_nodes[slot] = true;
                    track.last_seen = now;
                }
            }
        }
        if method.fusion == Fusion::Ml {
            if let Some((p, c)) = ml::fuse(&ml_points) {
                let dt_prev = track.ml_prev.map(|(_, t0)| now.secs_since(t0));
                let mut mean = State::zeros();
                mean.fixed_rows_mut::<3>(0).copy_from(&p);
                let mut cov = Matrix6::identity() * crate::init::INIT_VELOCITY_SIGMA.powi(2);
                cov.fixed_view_mut::<3, 3>(0, 0).copy_from(&c);
                if let (Some((p0, _)), Some(dt)) = (track.ml_prev, dt_prev)
                    && dt > 0.0
                {
                    mean.fixed_rows_mut::<3>(3).copy_from(&((p - p0) / dt));
                    cov.fixed_view_mut::<3, 3>(3, 3)
                        .copy_from(&(c * (2.0 / (dt * dt))));
                }
                match Eif::from_gaussian(mean, cov) {
                    Ok(f) => {
                        track.filter = f;
                        track.ml_prev = Some((p, now));
                    }
                    Err(_) => self.counters.numeric_failures += 1,
                }
            } else {
                stats.prediction_only += 1;
            }
        } else {
            if track.acc.count == 0 {
                stats.prediction_only += 1;
            }
            if let Err(e) = track.filter.update(&track.acc) {
                self.counters.numeric_failures += 1;
                warn!(target = %track.local, error = %e, "update failed; prediction only");
            }
        }
        let trained_from_cameras = track.aux_acc.count > 0;
        if track.aux.update(&track.aux_acc).is_err() {
            self.counters.numeric_failures += 1;
        }
        // Algorithm 1: pairs (distance from the camera-only filter, RSSI).
        if trained_from_cameras {
            let aux_pos: Vector3<f64> = track.aux.mean().fixed_rows::<3>(0).into_owned();
            let aux_cov = track.aux.cov().fixed_view::<3, 3>(0, 0).into_owned();
            for &(slot, dbm) in &track.rssi {
                let diff = aux_pos - self.nodes[slot].info.position;
                let d = diff.norm();
                if d > 1e-6 {
                    let u = diff / d;
                    track.trainers[slot].push(d, dbm, u.dot(&(aux_cov * u)));
                }
            }
        }
        track.detections = dets;
        track.detections.clear();
    }

    fn birth(&mut self, free: &[Detection], now: ClusterTime) {
        if free.is_empty() {
            return;
        }
        let found = births(
            free,
            &self.cameras,
            self.cfg.method.gate_chi2,
            self.cfg.birth_min_cameras,
            self.cfg.target_plane_z,
            self.cfg.bounds,
        );
        for b in found {
            let local = self.alloc_local();
            match self.new_track(local, None, b.mean, b.cov, now) {
                Ok(t) => {
                    info!(target = %local, cameras = b.members.len(), "new track");
                    self.counters.births += 1;
                    self.tracks.push(t);
                }
                Err(e) => {
                    self.counters.numeric_failures += 1;
                    warn!(error = %e, "birth with an unusable covariance");
                }
            }
        }
    }

    /// The cluster's power with the current modes (nodes down draw nothing we can count).
    pub fn power_mw(&self) -> f64 {
        self.nodes
            .iter()
            .filter(|n| n.member && n.up)
            .map(|n| n.info.power.in_mode(n.mode))
            .sum()
    }

    fn command(&mut self, slot: usize, mode: Mode, out: &mut Vec<Outgoing>) {
        let id = self.nodes[slot].info.id;
        self.nodes[slot].mode = mode;
        self.counters.commands += 1;
        out.push(Outgoing::new(id, Message::Command(Command { node: id, mode })));
    }

    /// Algorithm 2 (or all-on). Returns the greedy decision taken, if any.
    fn activate(&mut self, out: &mut Vec<Outgoing>) -> Option<crate::activation::Decision> {
        let variant = match self.cfg.method.activation {
            Activation::AllOn => None,
            Activation::CameraEntropy => Some(Variant::CameraOnly),
            Activation::FullNode => Some(Variant::FullNode),
            Activation::ThreeMode => Some(Variant::ThreeMode),
        };
        // All on, or no track to look for: wake every member (search).
        if variant.is_none() || self.tracks.is_empty() {
            for s in 0..self.nodes.len() {
                let n = &self.nodes[s];
                if n.member && n.up && n.mode != Mode::Active {
                    self.command(s, Mode::Active, out);
                }
            }
            return None;
        }
        let variant = variant?;
        let dt = self.cfg.method.step_ms as f64 * 1e-3;
        let motion = self.cfg.method.motion;
        let mut predicted: Vec<Info> = Vec::with_capacity(self.tracks.len());
        let mut means: Vec<State> = Vec::with_capacity(self.tracks.len());
        for t in &self.tracks {
            let p = t.filter.predicted(&motion, dt).ok()?;
            predicted.push(*p.omega());
            means.push(*p.mean());
        }
        let slots: Vec<usize> = (0..self.nodes.len())
            .filter(|&s| self.nodes[s].member && self.nodes[s].up)
            .collect();
        let candidates: Vec<Candidate> = slots
            .iter()
            .map(|&s| Candidate {
                node: self.nodes[s].info.id,
                mode: self.nodes[s].mode,
                power: self.nodes[s].info.power,
                cost_factor: self.nodes[s].info.cost_factor,
            })
            .collect();
        let sigma = self.cfg.method.pixel_sigma;
        let (nodes, tracks) = (&self.nodes, &self.tracks);
        let decision = self.planner.decide(
            variant,
            self.cfg.method.energy_weight,
            &candidates,
            &predicted,
            |n, t| {
                let node = &nodes[slots[n]].info;
                let model = tracks[t].trainers[slots[n]].model();
                let rssi = node.rssi.then_some((&model, &node.position));
                Expected::at(Some(&node.camera), sigma, rssi, &means[t])
            },
        )?;
        let slot = self.slots[&decision.node];
        info!(node = %decision.node, from = ?decision.from, to = ?decision.to, reward = decision.reward, cost = decision.cost, "activation");
        self.command(slot, decision.to, out);
        Some(decision)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::scenario::Scenario;

    fn env(source: u32, body: Message) -> Envelope {
        Envelope {
            source: NodeId(source),
            seq: 0,
            time: ClusterTime::ZERO,
            body,
        }
    }

    #[test]
    fn a_step_without_tracks_sends_nothing_and_strangers_are_rejected() {
        let s = Scenario::default_scenario();
        let mut h = HeadNode::new(HeadConfig::from_scenario(&s, 2).unwrap());
        let out = h.tick(ClusterTime::ZERO);
        assert!(out.is_empty(), "{out:?}");
        assert!(h.step_open());
        // Node 13 belongs to head 3.
        let c = Contribution {
            target: TargetId(1),
            step: 1,
            info_matrix: [[0.0; 6]; 6],
            info_vector: [0.0; 6],
            camera: false,
            captured: ClusterTime::ZERO,
            mode: Mode::Active,
            rssi: None,
        };
        h.on_message(ClusterTime::ZERO, env(13, Message::Contribution(c.clone())));
        assert_eq!(h.counters().rejected, 1);
        h.on_message(ClusterTime::ZERO, env(10, Message::Contribution(c)));
        assert_eq!(h.counters().unknown_target, 1);
        // Liveness only from the server.
        h.on_message(
            ClusterTime::ZERO,
            env(
                10,
                Message::Liveness(proto::msg::Liveness {
                    node: NodeId(11),
                    up: false,
                }),
            ),
        );
        assert_eq!(h.counters().rejected, 2);
        assert_eq!(h.mode_of(NodeId(11)), Some(Mode::Active));
    }
}
