//! The sans-IO head core, [`HeadNode`]: messages and ticks in, messages out.
//!
//! Every `method.step_ms` a tick opens a step: tracks are predicted and their `Priors` go to
//! every member node that is up and not Inactive, one message per node (in parts of at most
//! `MAX_PRIORS` tracks). A node's `Answers` answer every track of a part. The step closes when
//! every expected node answered every track or the deadline passed; then the sums are applied,
//! RSSI is linearized with each node's (trained or default) model, a `TrackReport` per track
//! goes to the server, new tracks are born from agreeing unassociated detections, and
//! activation sends at most one `Command`.

use crate::activation::Planner;
use crate::association::Detection;
use crate::config::{HeadConfig, NodeInfo};
use crate::fusion::{self, Fusion};
use crate::lifecycle::{Ending, ending_at_open};
use crate::stats::{Counters, StepStats};
use crate::step::{Offer, StepWindow};
use crate::track::Track;
use nalgebra::{Matrix2, Matrix6, Vector2};
use proto::models::{State, mat6_from_wire, mat6_to_wire, vec6_from_wire, vec6_to_wire};
use proto::msg::{
    Answers, Contribution, Handover, MAX_PRIOR_PARTS, MAX_PRIORS, Measurement, NodeStatus, PeopleFrame,
    Prior, Priors, TagsHeard,
};
use proto::node::{Input, Node, Outgoing};
use proto::observation::{GroundPerson, ObservationKind};
use proto::scenario::Activation;
use proto::{ClusterTime, Envelope, Message, Mode, NodeId, TargetId};
use std::collections::{BTreeSet, HashMap};
use tracing::{debug, info, warn};

/// Most detections a head buffers per step; more are dropped and counted.
pub const MAX_DETECTIONS_PER_STEP: usize = 4096;
/// How far (metres, horizontally) a track may stray outside the world's box before it is
/// dropped: no target is there, and RSSI readings (which refresh a track without cameras)
/// kept one diverged track flying 30 m out of the room for seconds (Table I, pixel level).
pub const OUTSIDE_MARGIN_M: f64 = 1.0;
/// How often a head tells the server its sync estimate and failures in a `NodeStatus`, ms.
pub const STATUS_PERIOD_MS: i64 = 1000;
/// Shortest time between two of a head's words on its tags, ns (a claim that changes at
/// every step must not flood the server and its recording).
pub const TELL_TAGS_MIN_NS: i64 = 500_000_000;

#[derive(Clone, Debug)]
struct NodeState {
    info: NodeInfo,
    member: bool,
    up: bool,
    /// Whether this node is known to run: it sent something, its link came up, or the server
    /// said it is up. `launch` starts every process at once, so a node not heard is sent
    /// nothing and no step waits for it; it runs in its starting mode meanwhile. (Over shared
    /// memory, frames for an inbox nobody has read yet now wait in the transport, bounded, but
    /// a step's priors to a node still starting would only be stale when it reads them.)
    heard: bool,
    mode: Mode,
}

impl NodeState {
    /// A member that is up and has spoken: one the head sends priors and commands to.
    fn reachable(&self) -> bool {
        self.member && self.up && self.heard
    }
}

/// The head's state machine.
#[derive(Debug)]
pub struct HeadNode {
    cfg: HeadConfig,
    fusion: Box<dyn Fusion>,
    /// The step's sensor activity beyond detections: cameras that reported a frame, acoustic
    /// nodes' ILD vectors (`head/sensed.rs`).
    sensed: sensed::Sensed,
    nodes: Vec<NodeState>,
    slots: HashMap<NodeId, usize>,
    /// Other heads the server said are down (their floor is anybody's until they are back).
    heads_down: BTreeSet<NodeId>,
    cameras: Vec<proto::camera::CameraModel>,
    tracks: Vec<Track>,
    next_local: u32,
    window: StepWindow,
    /// The tracks each part of the open step's priors asked, by part.
    parts: Vec<Vec<TargetId>>,
    step: u64,
    step_time: ClusterTime,
    next_step_at: Option<ClusterTime>,
    detections: Vec<Detection>,
    /// The step's tag readings, the evidence of which tag is on which track, the bindings.
    tags: crate::tags::TagBook,
    /// Tags heard unbound, waiting for a radio track (`crate::unseen`).
    unseen: crate::unseen::UnseenTags,
    planner: Planner,
    expected: Vec<bool>,
    counters: Counters,
    /// Which rejections are logged (all are counted).
    log: proto::log_limit::LogLimiter,
    last: StepStats,
    history: Vec<StepStats>,
    keep_history: bool,
    /// When the head started, its last status, its sync estimate (offset, error ns; error −1:
    /// not synchronized) and what its runtime could not deliver.
    started: Option<ClusterTime>,
    last_status: Option<ClusterTime>,
    /// When the server was last told the tags (a changed claim is told at once, but at most
    /// every [`TELL_TAGS_MIN_NS`]).
    told_tags_at: Option<ClusterTime>,
    sync: (i64, i64),
    undelivered: u64,
}

impl HeadNode {
    pub fn new(cfg: HeadConfig) -> Self {
        let me = cfg.id;
        let radio_floor = cfg.nodes.iter().map(|n| [n.position.x, n.position.y]).collect();
        let nodes: Vec<NodeState> = cfg
            .nodes
            .iter()
            .map(|n| NodeState {
                info: n.clone(),
                member: n.member,
                up: true,
                heard: false,
                mode: Mode::Active,
            })
            .collect();
        let slots = nodes.iter().enumerate().map(|(i, n)| (n.info.id, i)).collect();
        // A reading repeated within the freshness bound must never be taken twice.
        let taken_memory_ns = i64::try_from(cfg.method.capture_max_age_ms())
            .unwrap_or(i64::MAX)
            .saturating_mul(2_000_000);
        let cameras = nodes.iter().map(|n| n.info.camera).collect();
        let planner = if cfg.method.drop_lost_cameras {
            Planner::watching_deliveries()
        } else {
            Planner::default()
        };
        HeadNode {
            fusion: fusion::build(&cfg),
            sensed: sensed::Sensed::new(&cfg),
            cfg,
            nodes,
            slots,
            heads_down: BTreeSet::new(),
            cameras,
            tracks: Vec::new(),
            next_local: 1,
            window: StepWindow::default(),
            parts: Vec::new(),
            step: 0,
            step_time: ClusterTime::ZERO,
            next_step_at: None,
            detections: Vec::new(),
            tags: crate::tags::TagBook::new(taken_memory_ns).for_head(me, radio_floor),
            unseen: crate::unseen::UnseenTags::default(),
            planner,
            expected: Vec::new(),
            counters: Counters::default(),
            log: proto::log_limit::LogLimiter::default(),
            last: StepStats::default(),
            history: Vec::new(),
            keep_history: false,
            started: None,
            last_status: None,
            told_tags_at: None,
            sync: (0, -1),
            undelivered: 0,
        }
    }

    /// Keep every step's stats (for experiments and tests).
    pub fn with_history(mut self) -> Self {
        self.keep_history = true;
        self
    }

    /// Count every configured node as heard from, for harnesses that drive the head by hand
    /// (benches, tests) and never announce their nodes the way a running cluster's links do.
    pub fn with_nodes_heard(mut self) -> Self {
        for n in &mut self.nodes {
            n.heard = true;
        }
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
    /// The fusion method (for its per-track state: the grid estimator's beliefs).
    pub fn fusion(&self) -> &dyn Fusion {
        self.fusion.as_ref()
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

    /// Advance time: close a step past its deadline, open one when it is due, tell the server
    /// its status every [`STATUS_PERIOD_MS`].
    pub fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let mut out = Vec::new();
        self.status(now, &mut out);
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

    /// The head's `NodeStatus` for the server: always Active since it started, what its runtime
    /// could not deliver, the messages it rejected, and its sync estimate.
    fn status(&mut self, now: ClusterTime, out: &mut Vec<Outgoing>) {
        let started = *self.started.get_or_insert(now);
        let Some(server) = self.cfg.server else { return };
        if self
            .last_status
            .is_some_and(|t| now - t < STATUS_PERIOD_MS * 1_000_000)
        {
            return;
        }
        self.last_status = Some(now);
        out.push(Outgoing::new(
            server,
            Message::NodeStatus(NodeStatus {
                mode: Mode::Active,
                time_in_mode_ns: [u64::try_from(now - started).unwrap_or(0), 0, 0],
                frames: 0,
                detections: 0,
                dropped: self.undelivered,
                rejected: self.counters.rejected,
                sync_offset_ns: self.sync.0,
                sync_error_ns: self.sync.1,
                bytes_sent: 0,
            }),
        ));
        self.tell_tags(now, out);
    }

    /// Tell the server the tags the cluster hears, for it to name each one's home
    /// (`crate::tags`): with every status, and at once when a claim changed.
    pub(super) fn tell_tags(&mut self, now: ClusterTime, out: &mut Vec<Outgoing>) {
        let Some(server) = self.cfg.server else { return };
        if let Some(tags) = self.tags.tell(now) {
            self.told_tags_at = Some(now);
            out.push(Outgoing::new(server, Message::TagsHeard(TagsHeard { tags })));
        }
    }

    /// Handle one message. Messages from nodes not allowed to send them are counted and
    /// change no state.
    pub fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        let mut out = Vec::new();
        let src = env.source;
        if let Some(slot) = self.sensed.acoustic_slot(src) {
            self.on_acoustic(now, slot, env.body);
            return out;
        }
        let from_server = self.cfg.server == Some(src);
        let slot = self.slots.get(&src).copied();
        if let Some(slot) = slot {
            self.nodes[slot].heard = true;
        }
        let member = slot.filter(|&s| self.nodes[s].member);
        match env.body {
            Message::Answers(a) => match member {
                Some(slot) => self.on_answers(now, slot, a, &mut out),
                None => self.reject(now, src, "answers"),
            },
            Message::Measurement(m) => match member {
                Some(slot) => self.on_measurement(now, slot, m),
                None => self.reject(now, src, "measurement"),
            },
            Message::PeopleFrame(f) => match member {
                Some(slot) => self.on_people(now, slot, f),
                None => self.reject(now, src, "people_frame"),
            },
            Message::FrameReport(r) => match member {
                Some(slot) => self.on_frame_report(slot, &r),
                None => self.reject(now, src, "frame_report"),
            },
            Message::NodeStatus(s) => match member {
                Some(slot) => self.nodes[slot].mode = s.mode,
                None => self.reject(now, src, "node_status"),
            },
            Message::Handover(h) if from_server => self.on_handover(now, h),
            Message::TagHomes(h) if from_server => self.tags.set_homes(&h.homes, now),
            Message::Liveness(l) if from_server => out = self.node_liveness(now, l.node, l.up),
            Message::Assignment(a) if from_server => {
                // The server assigns cameras to live heads only.
                self.heads_down.remove(&a.head);
                self.sensed.assign(a.node, a.head == self.cfg.id);
                if let Some(&slot) = self.slots.get(&a.node) {
                    let mine = a.head == self.cfg.id;
                    // A node coming (back) into the cluster: what this head last heard of its
                    // liveness is stale — the server told its other head since (a "down" seen
                    // here and the "up" sent there left it down here for good, and a returning
                    // track lost its radio-only nodes). Up, unless the server's Liveness that
                    // follows the assignment says otherwise.
                    // Not yet heard, though: the server moves a down head's cameras whether
                    // they run or not; a live one's `Liveness` follows (or its link comes up,
                    // or it speaks).
                    if mine && !self.nodes[slot].member {
                        self.nodes[slot].up = true;
                    }
                    self.nodes[slot].member = mine;
                    if !mine {
                        self.window.release(slot);
                        if self.window.complete() {
                            self.close_step(now, &mut out);
                        }
                    }
                }
            }
            Message::Handover(_) | Message::Liveness(_) | Message::Assignment(_) | Message::TagHomes(_) => {
                self.reject(now, src, env.body.kind());
            }
            _ => {}
        }
        out
    }

    /// A node went down or came back (from the server's `Liveness`, or from the runtime when
    /// its link drops). A node down is not waited for and draws no power.
    pub fn node_liveness(&mut self, now: ClusterTime, node: NodeId, up: bool) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if self.cfg.other_regions.iter().any(|(h, _)| *h == node) {
            if up {
                self.heads_down.remove(&node);
            } else {
                info!(head = %node, "another head is down: its floor is anybody's");
                self.heads_down.insert(node);
            }
        }
        if let Some(&slot) = self.slots.get(&node) {
            if self.nodes[slot].up != up {
                info!(node = %node, up, "node liveness changed");
            }
            self.nodes[slot].up = up;
            // Up on a link, or in the server's word: the node is running and reads its inbox.
            self.nodes[slot].heard |= up;
            if !up {
                self.window.release(slot);
                if self.window.complete() {
                    self.close_step(now, &mut out);
                }
            }
        }
        out
    }

    fn reject(&mut self, now: ClusterTime, src: NodeId, kind: &'static str) {
        self.counters.rejected += 1;
        if let Some(more) = self.log.admit(now.0, "not allowed") {
            warn!(node = %src, kind, more, "message from a node not allowed to send it; ignored");
        }
    }

    /// A node's answers to one part of the step's priors: every track of the part is
    /// answered, those it lists with their contribution, the others with nothing.
    fn on_answers(&mut self, now: ClusterTime, slot: usize, a: Answers, out: &mut Vec<Outgoing>) {
        if a.contributions.iter().any(|c| {
            c.info
                .as_ref()
                .is_some_and(|i| i.matrix.iter().flatten().chain(&i.vector).any(|x| !x.is_finite()))
        }) {
            self.counters.rejected += 1;
            if let Some(more) = self.log.admit(now.0, "non-finite contribution") {
                warn!(node = %self.nodes[slot].info.id, more, "contribution with non-finite numbers; ignored");
            }
            return;
        }
        // The part's tracks, each with the window's slot it had when the step opened (parts
        // are the open step's tracks in order, `MAX_PRIORS` a part) and its index now, if it
        // is still there (a handover may release a track mid-step).
        let first = usize::from(a.part) * MAX_PRIORS;
        let asked: Vec<(usize, Option<usize>, Option<&Contribution>)> =
            match self.parts.get(usize::from(a.part)) {
                Some(targets) if a.step == self.step => targets
                    .iter()
                    .enumerate()
                    .map(|(i, target)| {
                        let now_at = self.tracks.iter().position(|tr| tr.local == *target);
                        (
                            first + i,
                            now_at,
                            a.contributions.iter().find(|c| c.target == *target),
                        )
                    })
                    .collect(),
                _ => Vec::new(),
            };
        let offers: Vec<Offer> = if asked.is_empty() {
            // Not a part of this step: by its step alone, late or confused.
            vec![self.window.classify(a.step, now)]
        } else {
            let targets = &self.parts[usize::from(a.part)];
            for c in a.contributions.iter().filter(|c| !targets.contains(&c.target)) {
                self.counters.unknown_target += 1;
                let node = self.nodes[slot].info.id;
                let target = c.target;
                debug!(%node, %target, part = a.part, "contribution to a track the part did not ask");
            }
            asked
                .iter()
                .map(|&(at_open, _, _)| self.window.offer(slot, at_open, a.step, now))
                .collect()
        };
        let applied = offers.iter().filter(|&&o| o == Offer::Apply).count();
        self.counters.applied += applied as u64;
        if applied > 0 {
            self.offer_readings(now, slot, &a.rssi);
            self.nodes[slot].mode = a.mode;
        }
        for (&(_, t, c), offer) in asked.iter().zip(&offers) {
            if *offer == Offer::Apply
                && let (Some(t), Some(c)) = (t, c)
            {
                self.apply_contribution(now, slot, t, c, a.captured);
            }
        }
        // One count per answer, however many tracks it covers.
        let node = self.nodes[slot].info.id;
        if offers.contains(&Offer::Late) {
            self.counters.late += 1;
            debug!(%node, step = a.step, current = self.step, "late answers");
        } else if offers.contains(&Offer::Duplicate) {
            self.counters.duplicate += 1;
            debug!(%node, step = a.step, "duplicate answers");
        } else if offers.contains(&Offer::Future) {
            self.counters.future += 1;
            if let Some(more) = self.log.admit(now.0, "future answers") {
                warn!(%node, step = a.step, current = self.step, more, "answers for a future step");
            }
        }
        if self.window.complete() {
            self.close_step(now, out);
        }
    }

    /// Sum one node's contribution to track `t` (its frame captured at `captured`).
    fn apply_contribution(
        &mut self,
        now: ClusterTime,
        slot: usize,
        t: usize,
        c: &Contribution,
        captured: ClusterTime,
    ) {
        // A ground-plane person the camera gated to the prior, folded in here (at the capture
        // time, by the same linear model the camera would use).
        let ground = c
            .ground
            .as_ref()
            .filter(|_| self.fresh(now, captured, slot, "ground person"))
            .map(|p| self.ground_detection(slot, p, captured));
        let camera = c.folded.camera() || ground.is_some();
        if !camera {
            return;
        }
        let node = &self.nodes[slot];
        let track = &mut self.tracks[t];
        self.planner.camera_delivered(node.info.id);
        if let Some(info) = c.info.as_ref().filter(|_| c.folded.camera()) {
            track.acc.add_wire(&info.matrix, &info.vector);
            track.aux_acc.add_wire(&info.matrix, &info.vector);
        }
        if let Some(d) = &ground {
            crate::observe::ground(track, d);
        }
        if let Some(h) = c
            .ground
            .as_ref()
            .and_then(|p| p.histogram.as_deref())
            .filter(|_| ground.is_some())
        {
            track.see_colours(&proto::observation::dequantise_histogram(h));
        }
        track.last_seen = now;
        track.fused_frame(captured);
        let mut kinds = c.folded;
        if ground.is_some() {
            kinds.insert(ObservationKind::Ground);
        }
        track.contributors.push(proto::msg::Contributor {
            node: node.info.id,
            kinds,
        });
    }

    /// Whether a capture stamped `t` may be fused at `now`. Frames and packets are fused at
    /// their capture time, so one stamped far from now (a clock that is off) would carry the
    /// track seconds along its velocity: it is refused and counted, by the bound the cameras
    /// apply to their own frames.
    fn fresh(&mut self, now: ClusterTime, t: ClusterTime, slot: usize, what: &'static str) -> bool {
        let off_ns = now - t;
        if off_ns.abs() <= self.cfg.method.capture_max_age_ms() as i64 * 1_000_000 {
            return true;
        }
        self.counters.stale_measurements += 1;
        if let Some(more) = self.log.admit(now.0, "stale capture") {
            warn!(
                node = %self.nodes[slot].info.id,
                what,
                off_ms = off_ns / 1_000_000,
                more,
                "stamped too far from now (clock off?); ignored"
            );
        }
        false
    }

    fn on_measurement(&mut self, now: ClusterTime, slot: usize, m: Measurement) {
        self.nodes[slot].mode = m.mode;
        let Some(p) = m.pinhole() else {
            // Only camera detections start or feed tracks here.
            self.counters.unfused_observations += m.observations.len() as u64;
            return;
        };
        let (point, cov, prev_point, captured) =
            (p.point, p.cov, p.prev_point.map(Vector2::from), p.captured);
        if !self.fresh(now, captured, slot, "measurement") {
            return;
        }
        self.offer_readings(now, slot, m.rssi());
        self.planner.camera_delivered(self.nodes[slot].info.id);
        self.detect(Detection {
            node: self.nodes[slot].info.id,
            slot,
            point: Vector2::from(point),
            cov: Matrix2::new(cov[0], cov[1], cov[1], cov[2]),
            prev_point,
            hint: m.target,
            captured,
            ground: None,
            appearance: None,
        });
    }

    /// A camera's ground-plane people of one frame: each a detection on the floor (its
    /// position, covariance and measured height), the frame's tag readings with the people
    /// the camera gated to a track.
    fn on_people(&mut self, now: ClusterTime, slot: usize, f: PeopleFrame) {
        self.nodes[slot].mode = f.mode;
        if !self.fresh(now, f.captured, slot, "people frame") {
            return;
        }
        self.offer_readings(now, slot, &f.rssi);
        if !f.people.is_empty() {
            self.planner.camera_delivered(self.nodes[slot].info.id);
        }
        for p in &f.people {
            let cov = p.cov();
            self.detect(Detection {
                node: self.nodes[slot].info.id,
                slot,
                point: Vector2::from(p.position()),
                cov: Matrix2::new(cov[0], cov[1], cov[1], cov[2]),
                prev_point: None,
                hint: p.target,
                captured: f.captured,
                ground: Some(p.height_m()),
                appearance: p
                    .histogram
                    .as_deref()
                    .map(proto::observation::dequantise_histogram),
            });
        }
    }

    /// A camera's ground-plane person as a detection on the floor, captured at `captured`.
    fn ground_detection(&self, slot: usize, p: &GroundPerson, captured: ClusterTime) -> Detection {
        let cov = p.cov();
        Detection {
            node: self.nodes[slot].info.id,
            slot,
            point: Vector2::from(p.position()),
            cov: Matrix2::new(cov[0], cov[1], cov[1], cov[2]),
            prev_point: None,
            hint: p.target,
            captured,
            ground: Some(p.height_m()),
            appearance: None,
        }
    }

    /// Buffer a detection for the step's association, within the per-step limit.
    fn detect(&mut self, d: Detection) {
        if self.detections.len() >= MAX_DETECTIONS_PER_STEP {
            self.counters.overflow += 1;
            return;
        }
        self.detections.push(d);
    }

    fn on_handover(&mut self, now: ClusterTime, h: Handover) {
        if h.to_head != self.cfg.id {
            if h.from_head == Some(self.cfg.id) {
                self.release(&h);
            }
            return;
        }
        if self.tracks.iter().any(|t| t.global == Some(h.global)) {
            return;
        }
        let mean = vec6_from_wire(&h.mean);
        let cov = mat6_from_wire(&h.cov);
        // The server naming one of our tracks: adopt the global id. The nearest of our unnamed
        // tracks within the gate: in a crowd the first one within it may be the neighbour. A
        // radio track is named (its own report came back), never adopted for another head's
        // target: that is a camera track to start.
        let naming = h.from_head.is_none();
        if let Some(i) = self.nearest_unnamed(&mean, &cov, naming) {
            let t = &mut self.tracks[i];
            t.global = Some(h.global);
            t.confirm();
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

    /// The server handed one of our targets to another head: stop tracking it. The track is the
    /// one carrying the global id, or, for a track we started (the server named it without
    /// telling us), the one nearest the handed-over posterior (our own last report of it)
    /// within the gate.
    fn release(&mut self, h: &Handover) {
        let before = self.tracks.len();
        self.tracks.retain(|t| t.global != Some(h.global));
        if self.tracks.len() == before
            && let Some(i) = self.nearest_unnamed(&vec6_from_wire(&h.mean), &mat6_from_wire(&h.cov), true)
        {
            self.tracks.remove(i);
        }
        if self.tracks.len() < before {
            info!(global = %h.global, to = %h.to_head, ending = ?Ending::HandedOver, "track handed to another head; dropped");
        }
    }

    /// Our track without a global id nearest (Mahalanobis, positions, summed covariances) to a
    /// posterior the server sent, within the gate. Never a radio search track (it is nobody);
    /// a tag's radio track (`crate::unseen`) only with `radio`.
    fn nearest_unnamed(&self, mean: &State, cov: &Matrix6<f64>, radio: bool) -> Option<usize> {
        let gate = self.cfg.method.gate_chi2;
        self.tracks
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                t.global.is_none() && t.radio != Some(crate::track::Radio::Search) && (radio || !t.is_radio())
            })
            .filter_map(|(i, t)| {
                let d = t.position() - mean.fixed_rows::<3>(0);
                let s = t.filter.cov().fixed_view::<3, 3>(0, 0) + cov.fixed_view::<3, 3>(0, 0);
                let d2 = d.dot(&s.cholesky()?.solve(&d));
                (d2 <= gate).then_some((i, d2))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
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
        let bounds = self.cfg.bounds;
        let mut left = 0;
        self.tracks.retain(|t| {
            let p = t.position();
            let inside = crate::association::within(&p, bounds, OUTSIDE_MARGIN_M, 2);
            match ending_at_open(now - t.last_seen, timeout, inside) {
                None => return true,
                Some(Ending::Silent) if t.radio == Some(crate::track::Radio::Search) => {
                    debug!(target = %t.local, "radio search track timed out");
                }
                Some(Ending::Silent) => {
                    info!(target = %t.local, state = ?t.state(), ending = ?Ending::Silent, "track silent too long; dropped")
                }
                Some(ending) => {
                    left += 1;
                    info!(target = %t.local, x = p[0], y = p[1], ?ending, "track left the world; dropped");
                }
            }
            false
        });
        self.counters.left_world += left;
        self.counters.deaths += (before - self.tracks.len()) as u64;
        let motion = self.cfg.method.motion;
        let mut failed = 0;
        self.tracks.retain_mut(|t| {
            let ok = t.begin_step(&motion, now).is_ok();
            if !ok {
                failed += 1;
                warn!(target = %t.local, ending = ?Ending::NumericFailure, "prediction failed numerically; track dropped");
            }
            ok
        });
        self.counters.numeric_failures += failed;
        self.counters.deaths += failed;
        self.radio_search(now);
        self.step += 1;
        self.step_time = now;
        // Detections are kept: those that arrived between steps are associated at the close.
        let distributed = self.fusion.distributed();
        self.expected.clear();
        self.expected.extend(
            self.nodes
                .iter()
                .map(|n| distributed && n.reachable() && n.mode != Mode::Inactive),
        );
        let deadline = now + (self.cfg.method.deadline_ms as i64).saturating_mul(1_000_000);
        self.window
            .open(self.step, deadline, self.tracks.len(), &self.expected);
        // One message per node for the step's priors (in parts when there are many), so each
        // node answers them all at once and jointly.
        // (A cluster past MAX_PRIOR_PARTS × MAX_PRIORS tracks sends the first ones' only; the
        // step then closes at its deadline.)
        self.parts.clear();
        let parts = self
            .tracks
            .len()
            .div_ceil(MAX_PRIORS)
            .min(usize::from(MAX_PRIOR_PARTS)) as u16;
        for (part, tracks) in self
            .tracks
            .chunks(MAX_PRIORS)
            .take(usize::from(parts))
            .enumerate()
        {
            self.parts.push(tracks.iter().map(|t| t.local).collect());
            let priors = Priors {
                part: part as u16,
                parts,
                tracks: tracks
                    .iter()
                    .map(|t| Prior {
                        target: t.local,
                        step: self.step,
                        mean: vec6_to_wire(t.filter.mean()),
                        cov: mat6_to_wire(t.filter.cov()),
                        deadline,
                        radio: t.is_radio(),
                    })
                    .collect(),
            };
            for n in self
                .nodes
                .iter()
                .filter(|n| n.reachable() && n.mode != Mode::Inactive)
            {
                out.push(Outgoing::new(n.info.id, Message::Priors(priors.clone())));
            }
        }
    }
}

impl Node for HeadNode {
    type Sensor = std::convert::Infallible;

    fn id(&self) -> NodeId {
        self.cfg.id
    }

    fn handle(&mut self, now: ClusterTime, input: Input<Self::Sensor>) -> Vec<Outgoing> {
        match input {
            Input::Message(env) => self.on_message(now, env),
            Input::Tick => self.tick(now),
            // A link to a camera that drops means the camera is down until it comes back.
            Input::Link { peer, up } => self.node_liveness(now, peer, up),
            Input::Sync { offset_ns, error_ns } => {
                self.sync = (offset_ns, error_ns);
                Vec::new()
            }
            Input::Undelivered(n) => {
                self.undelivered += n;
                Vec::new()
            }
            Input::Sensor(never) => match never {},
        }
    }
}

mod close;
mod radio;
mod sensed;
mod tagged;
#[cfg(test)]
mod tests;
