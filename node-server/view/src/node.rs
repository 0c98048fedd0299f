//! The visualization node's core (paper 004 §3.1): a [`Node`] that subscribes to the server's
//! view feed and builds the [`ViewState`] the pages show. Sans-IO like every core: the runtime
//! gives it ticks, links and messages; [`crate::live`] runs it as a process and publishes the
//! view after each step it changed.
//!
//! It renews its subscription every `renew` (well inside the server's liveness timeout, so the
//! server keeps it up), at once when the link to the server comes up, and says on the page
//! when the server has gone quiet. It sends nothing else: a viewer has no say in tracking.

use crate::state::ViewState;
use proto::msg::{Message, ViewSubscribe};
use proto::node::{Input, Node, Outgoing};
use proto::scenario::Scenario;
use proto::{ClusterTime, NodeId};
use std::convert::Infallible;

/// How a viewer core runs.
#[derive(Clone, Debug)]
pub struct ViewerConfig {
    pub id: NodeId,
    pub server: NodeId,
    /// The update period asked of the server, ms (0: the filter's step).
    pub period_ms: u32,
    /// How often the subscription is renewed, ns.
    pub renew_ns: i64,
    /// The server is called quiet after this long without an update, ns.
    pub quiet_ns: i64,
}

impl ViewerConfig {
    /// A viewer `id` of `scenario`'s server: updates every step, the subscription renewed three
    /// times per liveness timeout (at most every second), quiet after two timeouts.
    ///
    /// # Errors
    /// The scenario declares no server.
    pub fn for_scenario(scenario: &Scenario, id: NodeId) -> Result<ViewerConfig, NoServer> {
        let server = scenario.server().ok_or(NoServer)?;
        let timeout_ms = i64::try_from(scenario.network.liveness_timeout_ms)
            .unwrap_or(1000)
            .max(1);
        Ok(ViewerConfig {
            id,
            server: NodeId(server.id),
            period_ms: 0,
            renew_ns: (timeout_ms / 3).clamp(50, 1000) * 1_000_000,
            quiet_ns: (2 * timeout_ms).max(1000) * 1_000_000,
        })
    }
}

/// The first id from 900 up that `scenario` does not give a node: a viewer's default.
pub fn free_id(scenario: &Scenario) -> NodeId {
    (900u32..)
        .find(|id| scenario.node(*id).is_none())
        .map_or(NodeId(u32::MAX), NodeId)
}

/// The scenario has no server to subscribe to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the scenario declares no server for the viewer to subscribe to")]
pub struct NoServer;

/// What the viewer counted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ViewerCounters {
    /// Updates applied.
    pub updates: u64,
    /// Updates lost on the way (gaps in the server's sequence numbers).
    pub lost: u64,
    /// Messages that were not for a viewer (counted, ignored).
    pub ignored: u64,
    /// Subscriptions the runtime could not deliver.
    pub undelivered: u64,
}

/// The viewer core.
#[derive(Debug)]
pub struct ViewerNode {
    cfg: ViewerConfig,
    state: ViewState,
    next_renew: Option<ClusterTime>,
    last_update: Option<ClusterTime>,
    last_seq: Option<u64>,
    quiet_noted: bool,
    changed: bool,
    counters: ViewerCounters,
}

impl ViewerNode {
    /// A viewer starting from `initial` (the site from the scenario).
    pub fn new(cfg: ViewerConfig, initial: ViewState) -> Self {
        ViewerNode {
            cfg,
            state: initial,
            next_renew: None,
            last_update: None,
            last_seq: None,
            quiet_noted: false,
            changed: true,
            counters: ViewerCounters::default(),
        }
    }

    pub fn state(&self) -> &ViewState {
        &self.state
    }

    pub fn counters(&self) -> &ViewerCounters {
        &self.counters
    }

    /// The view, if it changed since the last call.
    pub fn take_changed(&mut self) -> Option<&ViewState> {
        std::mem::take(&mut self.changed).then_some(&self.state)
    }

    fn subscribe(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        self.next_renew = Some(now + self.cfg.renew_ns);
        let s = ViewSubscribe {
            period_ms: self.cfg.period_ms,
        };
        vec![Outgoing::new(self.cfg.server, Message::ViewSubscribe(s))]
    }

    /// A gap in the server's sequence numbers is frames lost on the way (a restarted server
    /// starts again from 0: no gap).
    fn heard_seq(&mut self, seq: u64) {
        if let Some(prev) = self.last_seq
            && seq > prev + 1
        {
            self.counters.lost += seq - prev - 1;
        }
        self.last_seq = Some(seq);
    }

    fn message(&mut self, now: ClusterTime, env: proto::Envelope) -> Vec<Outgoing> {
        match env.body {
            Message::ViewUpdate(u) if env.source == self.cfg.server => {
                self.last_update = Some(now);
                self.quiet_noted = false;
                self.counters.updates += 1;
                self.state.apply_update(&u);
                self.changed = true;
            }
            // Beacons, heartbeats, anything else: a viewer does nothing with them.
            _ => self.counters.ignored += 1,
        }
        Vec::new()
    }

    fn tick(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let quiet = self.last_update.is_none_or(|t| now - t > self.cfg.quiet_ns);
        if quiet && !self.quiet_noted && self.last_update.is_some() {
            let text = format!(
                "no update from the server {} for over {} s",
                self.cfg.server,
                self.cfg.quiet_ns / 1_000_000_000
            );
            self.state.note_problem(now.0, text);
            self.quiet_noted = true;
            self.changed = true;
        }
        if self.next_renew.is_none_or(|t| now >= t) {
            return self.subscribe(now);
        }
        Vec::new()
    }
}

impl Node for ViewerNode {
    type Sensor = Infallible;

    fn id(&self) -> NodeId {
        self.cfg.id
    }

    fn handle(&mut self, now: ClusterTime, input: Input<Infallible>) -> Vec<Outgoing> {
        match input {
            Input::Tick => self.tick(now),
            Input::Link { peer, up } if peer == self.cfg.server => {
                if up {
                    return self.subscribe(now);
                }
                self.state
                    .note_problem(now.0, format!("the link to the server {peer} went down"));
                self.changed = true;
                Vec::new()
            }
            Input::Message(env) => {
                if env.source == self.cfg.server {
                    self.heard_seq(env.seq);
                }
                self.message(now, env)
            }
            Input::Undelivered(n) => {
                self.counters.undelivered += n;
                Vec::new()
            }
            Input::Link { .. } | Input::Sync { .. } => Vec::new(),
            Input::Sensor(never) => match never {},
        }
    }
}

#[cfg(test)]
mod tests;
