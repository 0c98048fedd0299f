//! The server's sans-IO core, [`ServerNode`]: messages and ticks in, messages out, and a journal
//! of records for the recording.
//!
//! The runtime calls [`ServerNode::on_message`] with every decoded envelope,
//! [`ServerNode::on_rejected`] with every frame that did not decode, and [`ServerNode::tick`]
//! periodically; it sends the returned [`Outgoing`]s and appends [`ServerNode::take_records`]
//! (plus the envelopes it sent) to the recording.
//!
//! Replayability: the core is deterministic, and a tick is journaled exactly when it changed
//! state (it made a decision or sent beacons). Feeding a recording's `Received` and `Tick`
//! records back in ([`ServerNode::restore`]) therefore rebuilds the same membership, global ids
//! and last posteriors, and reproduces the recorded decisions.
//!
//! Handover messages: a [`Handover`] with `to_head` = the new head is sent to the new head (start
//! from this posterior: its own bound track's, when it has one) *and*, with the global's
//! posterior, to the old head if it is up (stop tracking it; a late report of the dropped track
//! is ignored, any other report of it is looked at afresh, as a track first seen). Assignments
//! are likewise sent to the camera, its new head and its previous head. When a head's track
//! gets a global id (new or merged) and its report carried none, the head is told with a
//! *naming* handover: `to_head` = that head, `from_head` = `None`, the report's own posterior —
//! the head adopts the id for the matching track.

use crate::decision::Decision;
use crate::membership::Membership;
use crate::record::{MeasuredFrame, Record, Stamped};
use crate::tracks::{GlobalTrack, TrackParams, Tracks};
use proto::log_limit::LogLimiter;
use proto::msg::{Assignment, Handover, HelloAck, Liveness, Message, NodeStatus, SyncBeacon, TagHomes};
use proto::node::{Input, Node, Outgoing};
use proto::scenario::Scenario;
use proto::{ClusterTime, Envelope, NodeId, PROTOCOL_VERSION, Role, TargetId};
use std::collections::BTreeMap;

mod viewers;
pub use viewers::MAX_VIEWERS;

/// Server configuration: the scenario plus the server's own tuning.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    pub id: NodeId,
    pub scenario: Scenario,
    pub tracks: TrackParams,
    /// Keep a journal for the recording (turn off when nobody drains it).
    pub journal: bool,
}

/// Below this blended Bhattacharyya coefficient two tracks' colours say they are different
/// people. Paper 004's particle filter itself weighs a sample at Bhattacharyya distance
/// √(1 − ρ) with σ = 0.2 (eq. 8): at ρ = 0.5 (distance 0.71) the weight is e^-6.3 of a perfect
/// match's, so such a pair is unmistakably two people; two people in similar colours stay
/// well above it and fall back on position alone.
pub const MIN_APPEARANCE_SIMILARITY: f32 = 0.5;

/// How long a head's second track on one of its globals waits for an id: longer than the
/// 0.2–2.4 s a failover survivor's duplicate lived in the end-to-end runs (see `tracks`).
pub const DUPLICATE_WAIT_NS: i64 = 3_000_000_000;

impl ServerConfig {
    /// Defaults from the scenario: merge gate 1 m, hysteresis 3 reports, handover margin
    /// 0.25 m, track timeout from `method.track-timeout-ms`, owner staleness three steps,
    /// appearance gate [`MIN_APPEARANCE_SIMILARITY`], duplicate wait [`DUPLICATE_WAIT_NS`].
    pub fn from_scenario(scenario: Scenario, id: NodeId) -> Self {
        let ms = |v: u64| i64::try_from(v).unwrap_or(i64::MAX / 1_000_000) * 1_000_000;
        let tracks = TrackParams {
            merge_gate_m: 1.0,
            hysteresis: 3,
            handover_margin_m: 0.25,
            track_timeout_ns: ms(scenario.method.track_timeout_ms),
            owner_stale_ns: ms(3 * scenario.method.step_ms),
            min_appearance_similarity: MIN_APPEARANCE_SIMILARITY,
            duplicate_wait_ns: DUPLICATE_WAIT_NS,
        };
        ServerConfig {
            id,
            scenario,
            tracks,
            journal: true,
        }
    }
}

/// Counters the server keeps.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    pub received: u64,
    pub rejected: u64,
    /// Messages from ids that are neither members nor declared (also in `rejected`); they
    /// reach neither the state nor the recording.
    pub non_members: u64,
    pub handovers: u64,
    pub beacons: u64,
    /// Messages its runtime could not deliver.
    pub undelivered: u64,
    /// Times a tag's home moved from one head to another (`tag_homes`).
    pub tag_home_moves: u64,
    /// Tags given no home: the server's book of them was full (`tag_homes::MAX_TAGS`).
    pub tags_refused: u64,
}

/// The server core.
#[derive(Debug)]
pub struct ServerNode {
    cfg: ServerConfig,
    members: Membership,
    tracks: Tracks,
    round: u64,
    next_beacon: Option<ClusterTime>,
    beacon_ns: i64,
    status: BTreeMap<NodeId, NodeStatus>,
    journal: Vec<Stamped>,
    counters: Counters,
    /// Which rejections are logged (all are counted).
    log: LogLimiter,
    /// The visualization nodes' feed.
    viewers: viewers::ViewFeed,
    /// Which head's track takes each radio tag's readings.
    tag_homes: crate::tag_homes::TagHomes,
}

/// What restoring from a recording found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RestoreStats {
    /// Records fed back in (received envelopes and ticks).
    pub fed: u64,
    /// Recorded decisions the restore reproduced, and those it did not.
    pub decisions_matched: u64,
    pub decisions_mismatched: u64,
}

impl ServerNode {
    pub fn new(cfg: ServerConfig) -> Self {
        let members = Membership::new(&cfg.scenario);
        let tracks = Tracks::new(cfg.tracks.clone());
        let beacon_ns = i64::try_from(cfg.scenario.network.sync_beacon_ms.max(1))
            .unwrap_or(1000)
            .saturating_mul(1_000_000);
        ServerNode {
            cfg,
            members,
            tracks,
            round: 0,
            next_beacon: None,
            beacon_ns,
            status: BTreeMap::new(),
            journal: Vec::new(),
            counters: Counters::default(),
            log: LogLimiter::default(),
            viewers: viewers::ViewFeed::default(),
            tag_homes: crate::tag_homes::TagHomes::default(),
        }
    }

    pub fn id(&self) -> NodeId {
        self.cfg.id
    }

    pub fn config(&self) -> &ServerConfig {
        &self.cfg
    }

    pub fn membership(&self) -> &Membership {
        &self.members
    }

    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Global tracks with their owner and last posterior.
    pub fn globals(&self) -> impl Iterator<Item = (TargetId, &GlobalTrack)> {
        self.tracks.globals()
    }

    /// The global id of a head's local track, once bound.
    pub fn global_of(&self, head: NodeId, local: TargetId) -> Option<TargetId> {
        self.tracks.global_of(head, local)
    }

    /// Latest status each node sent (sync error, energy, drops).
    pub fn statuses(&self) -> &BTreeMap<NodeId, NodeStatus> {
        &self.status
    }

    /// Each node's visible sync error (the residual it last reported), ns.
    pub fn sync_errors(&self) -> Vec<(NodeId, i64)> {
        self.status.iter().map(|(n, s)| (*n, s.sync_error_ns)).collect()
    }

    /// Records made since the last call, in order.
    pub fn take_records(&mut self) -> Vec<Stamped> {
        std::mem::take(&mut self.journal)
    }

    fn journal(&mut self, now: ClusterTime, r: Record) {
        if self.cfg.journal {
            self.journal.push(Stamped::new(now, r));
        }
    }

    fn reject(&mut self, now: ClusterTime, source: Option<NodeId>, what: &str, reason: String) {
        self.counters.rejected += 1;
        let member = source.is_some_and(|s| self.members.member(s).is_some());
        self.viewers.rejected(source, member);
        if let Some(more) = self.log.admit(now.0, "message rejected") {
            tracing::warn!(source = %source.map_or_else(|| "unknown".to_string(), |s| s.to_string()), what, %reason, more, "message rejected");
        }
        self.decide(
            now,
            Decision::Rejected {
                source,
                what: what.into(),
                reason,
            },
            &mut Vec::new(),
        );
    }

    /// A frame that did not decode (the runtime knows the link it came on, if anything).
    pub fn on_rejected(&mut self, now: ClusterTime, source: Option<NodeId>, error: &str) {
        self.reject(now, source, "frame", error.into());
    }

    /// The transport saw a link to `node` come up or go down. A closed link marks the node
    /// down at once (no need to wait for the liveness timeout); an opened one admits a declared
    /// node like any first message.
    ///
    /// While its link is up a member is up: liveness rests on the transport's heartbeats, not
    /// on what the node sends (a camera's status comes about once a second, no faster than
    /// the liveness timeout). A link event for a node that is neither a member nor declared
    /// changes nothing and is not recorded.
    pub fn on_link(&mut self, now: ClusterTime, node: NodeId, up: bool) -> Vec<Outgoing> {
        let declared = self.members.declared_role(node).filter(|r| *r != Role::Server);
        if self.members.member(node).is_none() && declared.is_none() {
            return Vec::new();
        }
        self.journal(now, Record::Link { node, up });
        let mut out = Vec::new();
        if up {
            let d = match (self.members.member(node), declared) {
                (Some(_), _) => self.members.seen(now, node),
                (None, Some(r)) => self.members.admit(now, node, r),
                (None, None) => None,
            };
            self.members.set_linked(node, true);
            if let Some(d) = d {
                self.decide(now, d, &mut out);
            }
        } else {
            self.members.set_linked(node, false);
            if let Some(d) = self.members.mark_down(now, node) {
                self.decide(now, d, &mut out);
                // Its tracks move on the next tick (failover), like any other dead head's.
            }
        }
        out
    }

    /// Handle one decoded envelope.
    pub fn on_message(&mut self, now: ClusterTime, env: Envelope) -> Vec<Outgoing> {
        if let Message::MeasuredFrame(m) = &env.body
            && self.members.declared_role(env.source) == Some(Role::Camera)
        {
            // A logging run's measurements are data for the recording, not an input: they
            // change no state (not even liveness), so restoring from `Received` records alone
            // stays exact. From anyone else they are an input, and rejected below.
            self.counters.received += 1;
            self.journal(now, Record::Measured(MeasuredFrame::from_wire(env.source, m)));
            return Vec::new();
        }
        let src = env.source;
        let kind = env.body.kind();
        // Tools and viewers are not in the scenario: their hello and a viewer's subscription
        // pass (the subscription admits a viewer, bounded by MAX_VIEWERS).
        let client_hello = matches!(&env.body, Message::Hello(h) if matches!(h.role, Role::Tool | Role::Viewer))
            || matches!(&env.body, Message::ViewSubscribe(_));
        let declared = self.members.declared_role(src).is_some_and(|r| r != Role::Server);
        if self.members.member(src).is_none() && !declared && !client_hello {
            // Not a member and not one the scenario declares: counted, logged rate-limited,
            // answered if it says hello — and kept out of the state and the recording, so a
            // stranger cannot fill either.
            self.counters.received += 1;
            self.counters.rejected += 1;
            self.counters.non_members += 1;
            if let Some(more) = self.log.admit(now.0, "non-member") {
                tracing::warn!(node = %src, kind, more, "message from a node that is not a member; ignored, not recorded");
            }
            return match &env.body {
                Message::Hello(h) => {
                    let reason = self
                        .hello_refusal(src, h)
                        .unwrap_or_else(|| format!("{src} is not in the scenario"));
                    vec![Outgoing::new(
                        src,
                        Message::HelloAck(HelloAck {
                            accepted: false,
                            reason,
                        }),
                    )]
                }
                _ => Vec::new(),
            };
        }
        self.journal(now, Record::Received(env.clone()));
        self.counters.received += 1;
        let mut out = Vec::new();
        if let Message::Hello(h) = &env.body {
            self.hello(now, src, h, &mut out);
            return out;
        }
        if let Message::ViewSubscribe(s) = &env.body {
            self.subscribe(now, src, env.seq, s, &mut out);
            return out;
        }
        // Anything else needs an admitted sender, or one the scenario declares (a node that
        // kept running while the server restarted need not say hello again).
        let role = match self.members.member(src).map(|m| m.role) {
            Some(r) => r,
            None => match self.members.declared_role(src) {
                Some(r) if r != Role::Server => {
                    if let Some(d) = self.members.admit(now, src, r) {
                        self.decide(now, d, &mut out);
                    }
                    r
                }
                _ => {
                    self.reject(now, Some(src), kind, "sender is not a member".into());
                    return out;
                }
            },
        };
        self.viewers.heard(src, env.seq);
        match env.body {
            Message::Heartbeat => {}
            Message::NodeStatus(s) => {
                self.status.insert(src, s);
            }
            Message::TagsHeard(t) if role == Role::Head => {
                let (homes, moved) = self.tag_homes.heard(now, src, &t.tags, &self.tracks);
                self.counters.tag_home_moves = self.tag_homes.moves;
                self.counters.tags_refused = self.tag_homes.refused;
                for m in &moved {
                    let Some(from) = m.from else { continue };
                    // Debug: a home moves in normal operation (tens of times a minute in the
                    // hall, counted in `tag_home_moves`), and every replay of a recording (the
                    // report, the rebuild) would log each move again.
                    tracing::debug!(tag = %m.tag, %from, to = %m.to, "a tag's home moved to the track nearer its loudest node");
                    // The former home holds the readings back now, not at its next word.
                    if from != src
                        && let Some(a) = self.tag_homes.answer(m.tag, from, &self.tracks)
                    {
                        out.push(Outgoing::new(
                            from,
                            Message::TagHomes(TagHomes { homes: vec![a] }),
                        ));
                    }
                }
                if !homes.is_empty() {
                    out.push(Outgoing::new(src, Message::TagHomes(TagHomes { homes })));
                }
            }
            Message::TrackReport(r) if role == Role::Head => {
                self.viewers.reported(src, &r);
                if let Some(d) = self.members.seen(now, src) {
                    self.decide(now, d, &mut out);
                }
                for d in self.tracks.observe(now, src, &r, &self.members) {
                    // Tell a head the global id of its track (it adopts it, so that a later
                    // handover away from it names a track it knows). Not after a split: the
                    // head already labels that track with the old id.
                    if let Decision::NewGlobal { global, .. } | Decision::Merged { global, .. } = d
                        && r.global.is_none()
                    {
                        out.push(Outgoing::new(
                            src,
                            Message::Handover(Handover {
                                global,
                                to_head: src,
                                from_head: None,
                                time: r.time,
                                mean: r.mean,
                                cov: r.cov,
                            }),
                        ));
                    }
                    self.decide(now, d, &mut out);
                }
                return out;
            }
            _ => {
                self.reject(
                    now,
                    Some(src),
                    kind,
                    format!("a server does not take {kind} from a {role}"),
                );
                return out;
            }
        }
        if let Some(d) = self.members.seen(now, src) {
            self.decide(now, d, &mut out);
        }
        out
    }

    /// Why a hello is refused, if it is.
    fn hello_refusal(&self, src: NodeId, h: &proto::msg::Hello) -> Option<String> {
        if h.node != src {
            Some(format!("hello names node {} but came from {src}", h.node))
        } else if h.version != PROTOCOL_VERSION {
            Some(format!(
                "protocol version {} (server speaks {PROTOCOL_VERSION})",
                h.version
            ))
        } else {
            match (self.members.declared_role(src), h.role) {
                (_, Role::Server) => Some("a second server".to_string()),
                (None, Role::Tool | Role::Viewer) => None,
                (Some(d), r) if d == r => None,
                (Some(d), r) => Some(format!("scenario declares {src} as {d}, not {r}")),
                (None, r) => Some(format!("{src} is not in the scenario (as {r})")),
            }
        }
    }

    fn hello(&mut self, now: ClusterTime, src: NodeId, h: &proto::msg::Hello, out: &mut Vec<Outgoing>) {
        if let Some(reason) = self.hello_refusal(src, h) {
            self.counters.rejected += 1;
            if let Some(more) = self.log.admit(now.0, "hello refused") {
                tracing::warn!(node = %src, %reason, more, "hello refused");
            }
            out.push(Outgoing::new(
                src,
                Message::HelloAck(HelloAck {
                    accepted: false,
                    reason: reason.clone(),
                }),
            ));
            self.decide(now, Decision::Refused { node: src, reason }, out);
            return;
        }
        out.push(Outgoing::new(
            src,
            Message::HelloAck(HelloAck {
                accepted: true,
                reason: String::new(),
            }),
        ));
        match self.members.admit(now, src, h.role) {
            Some(d) => self.decide(now, d, out),
            // Already up: a reconnect. Repeat what it needs to know.
            None => self.welcome(src, out),
        }
    }

    /// Tell a node its place: a camera its head, a head its cameras.
    fn welcome(&self, node: NodeId, out: &mut Vec<Outgoing>) {
        match self.members.member(node).map(|m| m.role) {
            Some(Role::Camera) => {
                if let Some(head) = self.members.head_of(node) {
                    let a = Message::Assignment(Assignment { node, head });
                    out.push(Outgoing::new(node, a.clone()));
                    if self.members.is_up(head) {
                        out.push(Outgoing::new(head, a));
                    }
                }
            }
            Some(Role::Head) => {
                for c in self.members.cameras_of(node) {
                    out.push(Outgoing::new(
                        node,
                        Message::Assignment(Assignment { node: c, head: node }),
                    ));
                }
            }
            _ => {}
        }
    }

    /// Journal a decision, apply its follow-ups and emit the messages it implies.
    fn decide(&mut self, now: ClusterTime, d: Decision, out: &mut Vec<Outgoing>) {
        tracing::debug!(decision = ?d, "decision");
        self.journal(now, Record::Decision(d.clone()));
        self.viewers.decided(now, &d);
        match d {
            Decision::Admitted { node, .. } | Decision::Up { node } => {
                if matches!(d, Decision::Up { .. })
                    && let Some(head) = self.members.head_of(node)
                    && self.members.is_up(head)
                {
                    out.push(Outgoing::new(
                        head,
                        Message::Liveness(Liveness { node, up: true }),
                    ));
                }
                if self.members.member(node).map(|m| m.role) == Some(Role::Head) {
                    // Back after a "down" every live head was told: they leave its floor to it
                    // again (a head starts no track on a live head's floor).
                    if matches!(d, Decision::Up { .. }) {
                        for h in self.members.live_heads().into_iter().filter(|&h| h != node) {
                            out.push(Outgoing::new(h, Message::Liveness(Liveness { node, up: true })));
                        }
                    }
                    for a in self.members.rebalance() {
                        self.decide(now, a, out);
                    }
                }
                self.welcome(node, out);
            }
            Decision::Down { node, .. } => match self.members.member(node).map(|m| m.role) {
                Some(Role::Camera) => {
                    if let Some(head) = self.members.head_of(node)
                        && self.members.is_up(head)
                    {
                        out.push(Outgoing::new(
                            head,
                            Message::Liveness(Liveness { node, up: false }),
                        ));
                    }
                }
                Some(Role::Head) => {
                    for h in self.members.live_heads() {
                        out.push(Outgoing::new(h, Message::Liveness(Liveness { node, up: false })));
                    }
                    for a in self.members.rebalance() {
                        self.decide(now, a, out);
                    }
                }
                _ => {}
            },
            Decision::Assigned { camera, head, from } => {
                let a = Message::Assignment(Assignment { node: camera, head });
                for to in [Some(camera), Some(head), from].into_iter().flatten() {
                    if self.members.is_up(to) && !out.iter().any(|o| o.to == to && o.body == a) {
                        out.push(Outgoing::new(to, a.clone()));
                    }
                }
                // The new head learns the camera's liveness with it: what it heard of that
                // camera before it left is stale (its ups and downs since went to the other
                // head).
                if self.members.is_up(head)
                    && let Some(m) = self.members.member(camera)
                {
                    let up = m.up;
                    out.push(Outgoing::new(
                        head,
                        Message::Liveness(Liveness { node: camera, up }),
                    ));
                }
            }
            Decision::Handover { global, from, to, .. } => {
                self.counters.handovers += 1;
                // The old head drops its track nearest the global's posterior (the owner's last
                // word, its own in a region handover); the new head adopts the track nearest
                // the posterior it is given.
                if let Some(gt) = self.tracks.global(global) {
                    let (time, mean, cov) = self
                        .tracks
                        .handover_posterior(now, global, to)
                        .unwrap_or((gt.time, gt.mean, gt.cov));
                    let handover = |time, mean, cov| {
                        Message::Handover(Handover {
                            global,
                            to_head: to,
                            from_head: from,
                            time,
                            mean,
                            cov,
                        })
                    };
                    out.push(Outgoing::new(to, handover(time, mean, cov)));
                    if let Some(f) = from
                        && f != to
                        && self.members.is_up(f)
                    {
                        out.push(Outgoing::new(f, handover(gt.time, gt.mean, gt.cov)));
                    }
                }
            }
            _ => {}
        }
    }

    /// Periodic work: liveness, failover, lost tracks, sync beacons.
    pub fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let mark = self.journal.len();
        self.journal(now, Record::Tick);
        let mut out = Vec::new();
        let mut changed = false;
        for d in self.members.expire(now) {
            changed = true;
            self.decide(now, d, &mut out);
        }
        for d in self.tracks.tick(now, &self.members) {
            changed = true;
            self.decide(now, d, &mut out);
        }
        if self.next_beacon.is_none_or(|t| now >= t) {
            changed = true;
            self.round += 1;
            self.next_beacon = Some(now + self.beacon_ns);
            let beacon = Message::SyncBeacon(SyncBeacon {
                leader: self.cfg.id,
                round: self.round,
                leader_time: now,
            });
            let up: Vec<NodeId> = self
                .members
                .members()
                .filter(|(_, m)| m.up)
                .map(|(id, _)| id)
                .collect();
            for node in up {
                self.counters.beacons += 1;
                out.push(Outgoing::new(node, beacon.clone()));
            }
        }
        if !changed && self.cfg.journal {
            self.journal.truncate(mark);
        }
        // What the viewers are sent follows from the state: it changes nothing to replay.
        out.extend(self.view_updates(now));
        out
    }

    /// After a restart: give every known node and track a fresh grace period from `now` so
    /// nodes can reconnect before anything is declared down or lost.
    pub fn resume(&mut self, now: ClusterTime, records: u64, skipped_bytes: u64) {
        self.members.refresh_all(now);
        self.tracks.refresh_all(now);
        self.next_beacon = None;
        self.journal(
            now,
            Record::Decision(Decision::Resumed {
                records,
                skipped_bytes,
            }),
        );
    }

    /// Feed one recorded input back in (received envelopes, state-changing ticks, link events,
    /// restarts, undecodable frames), discarding the messages it would send. Returns whether
    /// the record was an input.
    pub fn feed(&mut self, s: &Stamped) -> bool {
        match &s.record {
            Record::Received(env) => {
                self.on_message(s.at, env.clone());
            }
            Record::Tick => {
                self.tick(s.at);
            }
            Record::Link { node, up } => {
                self.on_link(s.at, *node, *up);
            }
            Record::Decision(Decision::Resumed {
                records,
                skipped_bytes,
            }) => self.resume(s.at, *records, *skipped_bytes),
            // Undecodable frames leave only their decision behind.
            Record::Decision(d @ Decision::Rejected { what, .. }) if what == "frame" => {
                self.counters.rejected += 1;
                self.journal(s.at, Record::Decision(d.clone()));
            }
            Record::Decision(_)
            | Record::Scenario(_)
            | Record::Sent { .. }
            | Record::Measured(_)
            | Record::Origin(_) => {
                return false;
            }
        }
        true
    }

    /// Rebuild a server from the records of a previous run by feeding its inputs back in, and
    /// check that the restore reproduces the recorded decisions.
    pub fn restore(cfg: ServerConfig, records: &[Stamped]) -> (ServerNode, RestoreStats) {
        let mut cfg = cfg;
        cfg.journal = true;
        let mut node = ServerNode::new(cfg);
        let mut stats = RestoreStats::default();
        let mut recorded = Vec::new();
        for s in records {
            if let Record::Decision(d) = &s.record {
                recorded.push(d.clone());
            }
            if node.feed(s) && !matches!(s.record, Record::Decision(_)) {
                stats.fed += 1;
            }
        }
        let rebuilt: Vec<Decision> = node
            .take_records()
            .into_iter()
            .filter_map(|s| match s.record {
                Record::Decision(d) => Some(d),
                _ => None,
            })
            .collect();
        for (i, d) in recorded.iter().enumerate() {
            if rebuilt.get(i) == Some(d) {
                stats.decisions_matched += 1;
            } else {
                stats.decisions_mismatched += 1;
            }
        }
        stats.decisions_mismatched += rebuilt.len().saturating_sub(recorded.len()) as u64;
        (node, stats)
    }
}

impl Node for ServerNode {
    type Sensor = std::convert::Infallible;

    fn id(&self) -> NodeId {
        self.cfg.id
    }

    fn handle(&mut self, now: ClusterTime, input: Input<Self::Sensor>) -> Vec<Outgoing> {
        match input {
            Input::Message(env) => self.on_message(now, env),
            Input::Link { peer, up } => self.on_link(now, peer, up),
            Input::Tick => self.tick(now),
            Input::Undelivered(n) => {
                self.counters.undelivered += n;
                Vec::new()
            }
            // The server leads time sync: it follows nobody.
            Input::Sync { .. } => Vec::new(),
            Input::Sensor(never) => match never {},
        }
    }
}
