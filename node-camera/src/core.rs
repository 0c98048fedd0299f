//! The camera node's sans-IO state machine, a [`proto::node::Node`] whose sensors deliver
//! [`CameraInput`]s: frames, detections made elsewhere, a replay's measured frames, and tag
//! readings.
//!
//! In distributed mode it answers a step's `Priors` with one `Answers`: a `Contribution` for
//! every track the newest frame's detections, paired with the priors jointly, give one to (a
//! track it has nothing for is not listed), and the fresh tag readings once; detections gated
//! to no prior go out as `Measurement { target: None }` so heads can start tracks. In
//! centralized mode every detection goes out as a `Measurement`; in grid mode each processed
//! frame is also reported (`FrameReport`), so the head knows it looked. Modes
//! (Active, CameraOff, Inactive) follow the head's `Command`s; time in each, the runtime's
//! sync estimate and what it could not deliver are reported in a `NodeStatus` every status
//! period. In a logging run ([`crate::record_all`]) every frame is measured whatever the mode
//! and its measurements go to the server's recording. With `camera-tracker = "particle"` the
//! frames go through paper 004's particle filters and people leave as ground-plane
//! observations ([`ground`]).

use crate::config::CameraConfig;
use crate::ground_people::gate_distance2;
use crate::ground_people::track_colours::TrackColours;
use crate::ground_people::{GroundPeople, PeopleSender};
use crate::measure::{self, Measured};
use crate::previous::{Offer, previous_point};
use crate::record_all::RecordAll;
use crate::segment::Segmenter;
use proto::msg::{Answers, Message, Mode, NodeStatus, Prior, Priors};
use proto::node::{Input, Node, Outgoing};
use proto::observation::RssiReading;
use proto::sensor::{Detection, Frame, TagReading};
use proto::validate::Validate;
use proto::{ClusterTime, Envelope, NodeId, TagId, TargetId};
use std::collections::BTreeMap;
use tracing::{debug, warn};

/// What a camera's sensors deliver.
#[derive(Debug)]
pub enum CameraInput {
    /// A captured frame: segmented in Active mode (every frame in a logging run).
    Frame(Frame),
    /// Detections made elsewhere (the measurement-level simulation projects the truth and adds
    /// noise instead of rendering and segmenting), handled exactly as a segmented frame's.
    Detections {
        captured: ClusterTime,
        detections: Vec<Detection>,
    },
    /// Detections already segmented and undistorted: a replay of a logging run's recording.
    /// `segmented`: they came from this node's segmentation of frames, not from the
    /// measurement-level simulation's projection of the truth.
    Measured {
        captured: ClusterTime,
        measured: Vec<Measured>,
        segmented: bool,
    },
    /// A packet from a radio tag.
    Tag(TagReading),
}

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
    /// Messages of detections to the head: `Measurement`s (pin-hole points), `PeopleFrame`s.
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
    /// Regions the background model dropped as ghosts ([`crate::ghost`]).
    pub ghosts: u64,
    /// Moving pixels the background model took back because they showed the colour it had
    /// settled on there (`adaptive_background::settled`).
    pub revealed_pixels: u64,
    /// Tag readings refused as impossible.
    pub tag_readings: u64,
    /// Ground-plane people not sent because a number of theirs was not finite.
    pub people_unsendable: u64,
    /// The particle filters' counters (all zero without them, and at measurement level or in
    /// a replay, where the filters do not run).
    pub particle: crate::ground_people::ParticleCounters,
}

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
    /// The newest reading of each tag heard while the radio was on.
    tags: BTreeMap<TagId, RssiReading>,
    /// A logging run's measuring of every frame, whatever the mode.
    record_all: Option<RecordAll>,
    /// Paper 004's particle filters, when the scenario selects them, and what of their people
    /// is sent when.
    people: Option<GroundPeople>,
    people_out: PeopleSender,
    /// The colours of the person this camera last gave each track, which the pairing of
    /// priors with people weighs.
    track_colours: TrackColours,
    mode: Mode,
    mode_since: ClusterTime,
    time_in_mode_ns: [u64; 3],
    last_status: Option<ClusterTime>,
    /// The runtime's time-sync estimate: offset to the leader and sync error, ns (error −1:
    /// not synchronized yet).
    sync: (i64, i64),
    counters: Counters,
    /// Which rejections are logged (all are counted), and the time of the input being handled.
    log: proto::log_limit::LogLimiter,
    now: ClusterTime,
}

impl CameraNode {
    pub fn new(cfg: CameraConfig, now: ClusterTime) -> CameraNode {
        let segmenter = Segmenter::new(&cfg.segment);
        let record_all = cfg.record_all.then(|| RecordAll::new(&cfg));
        let people = (cfg.tracker == proto::scenario::CameraTracker::Particle)
            .then(|| GroundPeople::new(&cfg.particle, cfg.fps, u64::from(cfg.id.0)))
            .and_then(|r| {
                // The scenario's check refuses bad parameters; a hand-made config falls back.
                r.map_err(|e| warn!(node = %cfg.id, error = %e, "particle tracker refused; segmentation"))
                    .ok()
            });
        CameraNode {
            people_out: PeopleSender::new(cfg.step_ms, f64::from(cfg.particle.hs_weight)),
            track_colours: TrackColours::default(),
            mode: cfg.initial_mode,
            cfg,
            segmenter,
            scratch: Vec::with_capacity(64),
            measured: Vec::with_capacity(64),
            previous: Vec::with_capacity(64),
            captured: None,
            priors: BTreeMap::new(),
            tags: BTreeMap::new(),
            record_all,
            people,
            mode_since: now,
            time_in_mode_ns: [0; 3],
            last_status: None,
            sync: (0, -1),
            counters: Counters::default(),
            log: proto::log_limit::LogLimiter::default(),
            now,
        }
    }

    pub fn config(&self) -> &CameraConfig {
        &self.cfg
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn counters(&self) -> Counters {
        Counters {
            // The segmenter keeps the count; read, not copied every frame.
            ghosts: self.segmenter.ghosts(),
            revealed_pixels: self.segmenter.revealed_pixels(),
            particle: self
                .people
                .as_ref()
                .map(GroundPeople::counters)
                .unwrap_or_default(),
            ..self.counters
        }
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

    /// Whether the camera should capture now: in Active mode, or always in a logging run.
    pub fn capturing(&self) -> bool {
        self.record_all.is_some() || self.mode.camera_on()
    }

    /// What a logging run measured, if this is one.
    pub fn record_all(&self) -> Option<&RecordAll> {
        self.record_all.as_ref()
    }

    fn switch_mode(&mut self, now: ClusterTime, mode: Mode) {
        // A radio-only node has no camera to switch on: Active is CameraOff for it.
        let mode = if self.cfg.radio_only && mode == Mode::Active {
            Mode::CameraOff
        } else {
            mode
        };
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
            if let Some(p) = self.people.as_mut() {
                p.clear();
            }
            if let Segmenter::AdaptiveBackground(seg) = &mut self.segmenter {
                seg.hold(&[]);
            }
        }
        if !mode.radio_on() {
            self.tags.clear();
        }
    }

    /// Within `max_age_ms` of now, either way: frames are fused at their capture time, so one
    /// stamped in the future (a source clock that is off) must not count as fresh either.
    fn fresh(&self, t: ClusterTime, now: ClusterTime) -> bool {
        (now - t).abs() <= self.cfg.max_age_ms as i64 * 1_000_000
    }

    fn reject(&mut self, what: &'static str, problem: String) {
        self.counters.rejected += 1;
        if let Some(more) = self.log.admit(self.now.0, what) {
            warn!(node = %self.cfg.id, what, %problem, more, "rejected input");
        }
    }

    pub(crate) fn server(&self) -> Option<NodeId> {
        self.cfg.server
    }

    fn send_to_head(&mut self, body: Message, out: &mut Vec<Outgoing>) {
        match self.cfg.head {
            Some(h) => out.push(Outgoing::new(h, body)),
            None => self.counters.unsent += 1,
        }
    }

    /// A message from the head or the server.
    pub(crate) fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        let mut out = Vec::new();
        if let Err(e) = env.validate() {
            self.reject("message", e.to_string());
            return out;
        }
        match env.body {
            Message::Priors(p) => {
                if !self.mode.radio_on() {
                    self.counters.priors_ignored += p.tracks.len() as u64;
                    return out;
                }
                self.counters.priors += p.tracks.len() as u64;
                // A radio track's prior is no camera's to pair (`Prior::radio`): it is answered
                // with the tag readings only.
                for prior in p.tracks.iter().filter(|p| !p.radio) {
                    self.priors.insert(prior.target, (now, prior.clone()));
                }
                if self.cfg.fusion.distributed() {
                    let a = self.answers(now, &p);
                    self.counters.contributions += a.contributions.len() as u64;
                    self.counters.camera_contributions +=
                        a.contributions.iter().filter(|c| c.camera()).count() as u64;
                    out.push(Outgoing::new(env.source, Message::Answers(a)));
                }
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
            Message::SampleRequest(r) => return self.on_sample_request(env.source, &r),
            Message::Heartbeat
            | Message::Hello(_)
            | Message::HelloAck(_)
            | Message::SyncBeacon(_)
            | Message::Liveness(_) => {}
            other => self.reject("message", format!("a camera does not take {}", other.kind())),
        }
        out
    }

    /// The answers to a step's priors (already among `self.priors`) from the newest frame: the
    /// priors are paired with its detections (or, with particle filters, its people) jointly,
    /// and only those given one are listed; the fresh tag readings go once.
    fn answers(&mut self, now: ClusterTime, priors: &Priors) -> Answers {
        let captured = self.captured.filter(|&t| self.fresh(t, now));
        // The priors' means are for the step the head opened as it sent them; their arrival
        // here stands for that time on this node's own clock (the link's latency is small
        // against a frame period), so the frame's age needs no clock shared with the head.
        let age_s = captured.map_or(0.0, |t| now.secs_since(t));
        // Radio tracks' priors get no camera contribution (`Prior::radio`); copied only when a
        // step has any (this runs for every prior message).
        let asked: std::borrow::Cow<[Prior]> = if priors.tracks.iter().any(|p| p.radio) {
            priors.tracks.iter().filter(|p| !p.radio).cloned().collect()
        } else {
            std::borrow::Cow::Borrowed(&priors.tracks)
        };
        let contributions = match captured {
            None => Vec::new(),
            Some(c) => {
                let joint = self.answering(&asked, priors.parts == 1, age_s, c);
                let gate = self.cfg.gate_chi2;
                match &self.people {
                    Some(people) => {
                        let colours = &self.track_colours;
                        let chosen = measure::joint_choices(&joint, people.latest(), gate, |p, g, age| {
                            // Colours never widen the gate: a person in other colours near its
                            // edge falls out of it (keeping such pairs in was measured worse).
                            gate_distance2(p, g, age).map(|d2| colours.cost(p.target, g, d2))
                        });
                        let targets = asked.iter().map(|p| p.target);
                        self.track_colours.note(now, targets.zip(chosen.iter().copied()));
                        // A person's colours go with the contribution as they would with a
                        // people frame (new, changed or 10 s old: `PeopleSender`): the head's
                        // track takes them for identity at the server.
                        let out = &self.people_out;
                        asked
                            .iter()
                            .zip(chosen)
                            .filter_map(|(p, g)| {
                                let with = g.is_some_and(|g| out.histogram_due(c, g));
                                crate::ground_people::contribution(p, g, with)
                            })
                            .collect()
                    }
                    None => {
                        let cam = &self.cfg.camera;
                        let chosen = measure::joint_choices(&joint, &self.measured, gate, |p, m, age| {
                            measure::mahalanobis2(cam, p, m, age)
                        });
                        asked
                            .iter()
                            .zip(chosen)
                            .filter_map(|(p, m)| measure::contribution(cam, p, m, age_s))
                            .collect()
                    }
                }
            }
        };
        if let Some(c) = captured {
            for g in contributions.iter().filter_map(|k| k.ground.as_ref()) {
                if let Some(h) = &g.histogram {
                    self.people_out.sent(g.local, c, h);
                }
            }
        }
        Answers {
            step: priors.tracks.first().map_or(0, |p| p.step),
            part: priors.part,
            captured: captured.unwrap_or(now),
            mode: self.mode,
            rssi: self.fresh_tags(now),
            contributions,
        }
    }

    /// The priors `asked` (first, in order, their frame `age_s` old) with the priors they are
    /// answered jointly with. When `whole` (the step's priors came in one part) that is all
    /// of them: a track not among them the head has dropped. Else the other tracks' newest,
    /// of the same step (another part) or the one before (a part not here yet), each with the
    /// frame's age relative to its arrival.
    pub(crate) fn answering<'a>(
        &'a self,
        asked: &'a [Prior],
        whole: bool,
        age_s: f64,
        captured: ClusterTime,
    ) -> Vec<(&'a Prior, f64)> {
        let Some(step) = asked.first().map(|p| p.step) else {
            return Vec::new();
        };
        let mut out: Vec<_> = asked.iter().map(|p| (p, age_s)).collect();
        if whole {
            return out;
        }
        out.extend(
            self.priors
                .values()
                .filter(|(t, p)| {
                    !asked.iter().any(|a| a.target == p.target)
                        && p.step + 1 >= step
                        && p.step <= step
                        && self.fresh(captured, *t)
                })
                .map(|(t, p)| (p, t.secs_since(captured))),
        );
        out
    }

    /// The newest reading of every tag heard within the freshness bound.
    fn fresh_tags(&self, now: ClusterTime) -> Vec<RssiReading> {
        self.tags
            .values()
            .filter(|r| self.fresh(r.time, now))
            .copied()
            .collect()
    }

    /// A captured frame. Segmented only in Active mode; in a logging run every frame is
    /// measured for the recording first.
    pub(crate) fn on_frame(&mut self, now: ClusterTime, frame: &Frame) -> Vec<Outgoing> {
        if let Some(mut all) = self.record_all.take() {
            let out = all.frame(self, now, frame);
            self.record_all = Some(all);
            return out;
        }
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
        if self.people.is_some() {
            let regions = std::mem::take(&mut self.scratch);
            let out = self.ground_frame(now, frame, &regions);
            self.scratch = regions;
            return out;
        }
        self.counters.frames += 1;
        let detections = std::mem::take(&mut self.scratch);
        let offer = self.offer(frame.captured);
        self.apply_detections(now, frame.captured, &detections, offer, &mut out);
        self.scratch = detections;
        out
    }

    /// Detections made elsewhere (the measurement-level simulation projects the truth and adds
    /// noise instead of rendering and segmenting). Handled exactly as a segmented frame's.
    pub(crate) fn on_detections(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
    ) -> Vec<Outgoing> {
        if let Some(mut all) = self.record_all.take() {
            let out = all.detections(self, now, captured, detections);
            self.record_all = Some(all);
            return out;
        }
        let mut out = Vec::new();
        if !self.mode.camera_on() {
            self.counters.frames_skipped += 1;
            return out;
        }
        if self.people.is_some() {
            return self.ground_boxes(now, captured, detections);
        }
        self.counters.frames += 1;
        self.apply_detections(now, captured, detections, Offer::All, &mut out);
        out
    }

    /// Detections already segmented and undistorted elsewhere: a logging run measures every
    /// frame whatever the mode, and a replay feeds a recording's measurements back. Handled
    /// exactly as a frame's detections after undistortion (`segmented`: they came from this
    /// node's segmentation of frames, not from the measurement-level simulation's projection
    /// of the truth); ignored when the camera is off. Non-finite points or covariances reject
    /// the whole frame and change no state.
    pub(crate) fn on_measured(
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
        let offer = if segmented {
            self.offer(captured)
        } else {
            Offer::All
        };
        std::mem::swap(&mut self.previous, &mut self.measured);
        self.measured.clear();
        self.measured.extend_from_slice(measured);
        self.captured = Some(captured);
        self.forget_stale(now);
        self.send_measurements(now, captured, offer, &mut out);
        out
    }

    /// Which ungated regions of the frame captured at `captured`, segmented by this node, may
    /// start tracks: only moving ones for motion segmentation (paper 004) in the distributed
    /// filter, if the previous frame can tell what moved (it exists and the model did not
    /// restart since: a gap longer than its memory, as after a sleep).
    fn offer(&self, captured: ClusterTime) -> Offer {
        let Segmenter::AdaptiveBackground(seg) = &self.segmenter else {
            return Offer::All;
        };
        if !self.cfg.fusion.distributed() {
            return Offer::All;
        }
        let memory_s = seg.params().restart_gap_ms as f64 / 1e3;
        match self.captured {
            Some(t) if memory_s <= 0.0 || captured.secs_since(t) <= memory_s => Offer::Moving,
            _ => Offer::Nothing,
        }
    }

    fn apply_detections(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        detections: &[Detection],
        offer: Offer,
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
        self.send_measurements(now, captured, offer, out);
    }

    /// Gate the newest detections against the known priors and send what the mode asks for.
    /// A detection no prior gated is sent only if `offer` offers it (see [`Self::offer`]).
    fn send_measurements(
        &mut self,
        now: ClusterTime,
        captured: ClusterTime,
        offer: Offer,
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
        let centralized = !self.cfg.fusion.distributed();
        let mut msgs = Vec::new();
        for (m, target) in self.measured.iter().zip(targets) {
            if target.is_some() && !centralized {
                continue;
            }
            if target.is_none() && !offer.offers(&self.previous, m) {
                self.counters.still_unassociated += 1;
                continue;
            }
            // Tag readings go with a detection gated to a track, as they go with a contribution.
            let rssi = if target.is_some() {
                self.fresh_tags(now)
            } else {
                Vec::new()
            };
            let prev = self
                .cfg
                .previous_point
                .then(|| previous_point(&self.previous, m))
                .flatten();
            msgs.push(Message::Measurement(measure::measurement(
                &self.cfg.camera,
                measure::pinhole(m, prev, captured),
                target,
                self.mode,
                &rssi,
            )));
        }
        for body in msgs {
            self.counters.measurements += 1;
            self.send_to_head(body, out);
        }
        // The grid estimator uses a camera's silence too (paper 001 eq. 6): say that it looked.
        if self.cfg.fusion == proto::scenario::Fusion::Grid {
            let report = proto::msg::FrameReport {
                captured,
                mode: self.mode,
                detections: u32::try_from(self.measured.len()).unwrap_or(u32::MAX),
            };
            self.send_to_head(Message::FrameReport(report), out);
        }
    }

    fn forget_stale(&mut self, now: ClusterTime) {
        let timeout = self.cfg.prior_timeout_ms as i64 * 1_000_000;
        self.priors.retain(|_, (t, _)| now - *t <= timeout);
    }

    /// A packet from a radio tag: kept as the tag's newest reading while the radio is on (and
    /// for a logging run's recording whatever the mode).
    pub(crate) fn on_tag(&mut self, reading: TagReading) {
        let TagReading { tag, dbm, time } = reading;
        if !(dbm.is_finite() && (-200.0..=30.0).contains(&dbm)) {
            self.counters.tag_readings += 1;
            self.reject(
                "rssi",
                format!("tag {tag}: {dbm} dBm is not a finite reading in -200..30"),
            );
            return;
        }
        let r = RssiReading { tag, dbm, time };
        if let Some(all) = self.record_all.as_mut() {
            all.heard(r);
        }
        if !self.cfg.rssi || !self.mode.radio_on() {
            return;
        }
        self.tags.insert(tag, r);
    }

    /// Periodic work: forget stale priors, send `NodeStatus` every status period.
    pub(crate) fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
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
            bytes_sent: 0,
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

impl Node for CameraNode {
    type Sensor = CameraInput;

    fn id(&self) -> NodeId {
        self.cfg.id
    }

    fn handle(&mut self, now: ClusterTime, input: Input<CameraInput>) -> Vec<Outgoing> {
        self.now = now;
        match input {
            Input::Message(env) => self.on_message(now, env),
            Input::Tick => self.tick(now),
            Input::Sensor(CameraInput::Frame(f)) => self.on_frame(now, &f),
            Input::Sensor(CameraInput::Detections { captured, detections }) => {
                self.on_detections(now, captured, &detections)
            }
            Input::Sensor(CameraInput::Measured {
                captured,
                measured,
                segmented,
            }) => self.on_measured(now, captured, &measured, segmented),
            Input::Sensor(CameraInput::Tag(r)) => {
                self.on_tag(r);
                Vec::new()
            }
            Input::Sync { offset_ns, error_ns } => {
                self.sync = (offset_ns, error_ns);
                Vec::new()
            }
            Input::Undelivered(n) => {
                self.counters.dropped += n;
                Vec::new()
            }
            // The head's or the server's link: what cannot reach them is counted as undelivered.
            Input::Link { .. } => Vec::new(),
        }
    }
}

mod ground;
#[cfg(test)]
mod ground_tests;
#[cfg(test)]
mod tests;
