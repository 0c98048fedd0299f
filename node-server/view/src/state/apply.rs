//! [`ViewState::apply`]: one recording record into the view.

use super::{HandoverView, NodeKind, NodeView, RECENT_HANDOVERS, TrackView, ViewState};
use crate::geometry::Ellipse;
use node_server::{Decision, HandoverReason, Record, Stamped};
use proto::Envelope;
use proto::msg::{Message, NodeStatus, TrackReport};
use proto::scenario::Scenario;

/// What a record changed in the view (for exports that write only what changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Change {
    /// The site (a scenario record).
    Scenario,
    /// A node's liveness, mode, assignment or health.
    Node(u32),
    /// A track's position (a new track, or its owner's new report).
    Track(u32),
    /// A track is gone (lost, or absorbed into another).
    TrackRemoved(u32),
    /// A handover or owner change, by its sequence number.
    Handover(u64),
    /// A problem was noted.
    Problem,
}

impl ViewState {
    /// Apply one record of the server's recording; returns what changed.
    pub fn apply(&mut self, s: &Stamped) -> Vec<Change> {
        self.totals.records += 1;
        self.advance(s.at.0);
        let at = s.at.0;
        let mut out = Vec::new();
        match &s.record {
            Record::Scenario(toml) => match Scenario::from_toml(toml, "recorded scenario") {
                Ok(sc) => {
                    self.set_scenario(&sc);
                    out.push(Change::Scenario);
                }
                Err(e) => {
                    self.note_problem(at, e.to_string());
                    out.push(Change::Problem);
                }
            },
            Record::Received(env) => self.received(at, env, &mut out),
            Record::Decision(d) => {
                self.totals.decisions += 1;
                self.decision(at, d, &mut out);
            }
            Record::Sent { .. }
            | Record::Tick
            | Record::Link { .. }
            | Record::Measured(_)
            | Record::Origin(_) => {}
        }
        out
    }

    /// Count a record that could not be read, with why.
    pub fn undecodable(&mut self, at_ns: i64, why: String) {
        self.totals.undecodable += 1;
        self.note_problem(at_ns, why);
    }

    fn node_mut(&mut self, id: u32) -> &mut NodeView {
        self.nodes.entry(id).or_insert_with(|| NodeView {
            id,
            ..NodeView::default()
        })
    }

    fn received(&mut self, at: i64, env: &Envelope, out: &mut Vec<Change>) {
        self.totals.received += 1;
        let src = env.source.0;
        let last = self.book.last_seq.insert(src, env.seq);
        let node = self.node_mut(src);
        node.last_heard_ns = Some(at);
        node.stale = false;
        // A gap in a sender's sequence is frames lost on the way (a restarted sender starts
        // again from 0: no gap).
        if let Some(prev) = last
            && env.seq > prev + 1
        {
            node.health.lost += env.seq - prev - 1;
        }
        match &env.body {
            Message::NodeStatus(st) => {
                apply_status(node, st);
                out.push(Change::Node(src));
            }
            Message::TrackReport(r) => {
                if node.role == NodeKind::Unknown {
                    node.role = NodeKind::Head;
                }
                node.health.late = node.health.late.max(r.late);
                let more_steps = r.step.saturating_sub(node.health.steps);
                node.health.steps += more_steps;
                self.totals.steps += more_steps;
                let key = (src, r.target.0);
                self.book.latest.insert(key, (at, r.clone()));
                if let Some(&g) = self.book.bindings.get(&key)
                    && self.tracks.get(&g).is_none_or(|t| t.owner == src)
                {
                    self.update_track(g, src, at, r);
                    out.push(Change::Track(g));
                }
            }
            _ => {}
        }
    }

    /// Bind a local track to a global; if `owns`, the global is (now) that head's and takes its
    /// latest report.
    fn bind(&mut self, head: u32, local: u32, global: u32, owns: bool, out: &mut Vec<Change>) {
        self.book.bindings.insert((head, local), global);
        let exists = self.tracks.contains_key(&global);
        if owns || !exists {
            self.take_latest(global, head, out);
        }
    }

    /// Make `head` the owner of `global` and show its latest report of it, if it has one (a
    /// track no report was seen for yet, as in a view started mid-run, appears with the next).
    fn take_latest(&mut self, global: u32, head: u32, out: &mut Vec<Change>) {
        let latest = self
            .book
            .bindings
            .iter()
            .filter(|(k, g)| k.0 == head && **g == global)
            .filter_map(|(k, _)| self.book.latest.get(k))
            .max_by_key(|(_, r)| r.time)
            .cloned();
        if let Some((at, r)) = latest {
            self.update_track(global, head, at, &r);
        } else if let Some(t) = self.tracks.get_mut(&global) {
            t.owner = head;
        } else {
            return;
        }
        out.push(Change::Track(global));
    }

    pub(super) fn update_track(&mut self, global: u32, head: u32, at: i64, r: &TrackReport) {
        let t = self.tracks.entry(global).or_insert_with(|| TrackView {
            global,
            owner: head,
            ..TrackView::default()
        });
        t.owner = head;
        if t.updated_ns != 0 && r.time.0 < t.time_ns {
            return; // an older estimate than the one shown
        }
        let m = &r.mean;
        t.local = r.target.0;
        t.time_ns = r.time.0;
        t.updated_ns = at;
        t.position = [m[0], m[1], m[2]];
        t.velocity = [m[3], m[4], m[5]];
        t.cov_xy = [r.cov[0][0], r.cov[0][1], r.cov[1][1]];
        t.sigma_m = (r.cov[0][0] + r.cov[1][1] + r.cov[2][2]).max(0.0).sqrt();
        t.ellipse = Ellipse::two_sigma(t.cov_xy);
        t.height_m = (m[2] > 0.05 && m[2] < 1.5).then(|| 2.0 * m[2]);
        t.cameras = r
            .contributors
            .iter()
            .filter(|c| c.camera())
            .map(|c| c.node.0)
            .collect();
        t.rssi = r
            .contributors
            .iter()
            .filter(|c| c.rssi())
            .map(|c| c.node.0)
            .collect();
        let secs = at as f64 * 1e-9;
        match t.trail.back_mut() {
            Some(last) if last[0] >= secs => *last = [last[0], m[0], m[1]],
            _ => t.trail.push_back([secs, m[0], m[1]]),
        }
    }

    fn handover(&mut self, at: i64, global: u32, from: Option<u32>, to: u32, reason: &str) -> u64 {
        self.totals.handovers += 1;
        self.book.handover_seq += 1;
        let position = self.tracks.get(&global).map(|t| [t.position[0], t.position[1]]);
        if self.handovers.len() >= RECENT_HANDOVERS {
            self.handovers.pop_front();
        }
        self.handovers.push_back(HandoverView {
            seq: self.book.handover_seq,
            time: at as f64 * 1e-9,
            global,
            from,
            to,
            reason: reason.into(),
            position,
        });
        self.book.handover_seq
    }

    fn decision(&mut self, at: i64, d: &Decision, out: &mut Vec<Change>) {
        match d {
            Decision::Admitted { node, role } => {
                let n = self.node_mut(node.0);
                n.up = true;
                n.stale = false;
                n.last_heard_ns.get_or_insert(at);
                if n.role == NodeKind::Unknown {
                    n.role = super::live::kind_of(*role);
                }
                out.push(Change::Node(node.0));
            }
            Decision::Up { node } => {
                let n = self.node_mut(node.0);
                n.up = true;
                n.stale = false;
                out.push(Change::Node(node.0));
            }
            Decision::Down { node, .. } => {
                let n = self.node_mut(node.0);
                n.up = false;
                n.stale = false;
                out.push(Change::Node(node.0));
            }
            Decision::Refused { node, reason } => {
                self.note_problem(at, format!("{node} refused: {reason}"));
                out.push(Change::Problem);
            }
            Decision::Rejected { source, what, reason } => {
                self.totals.rejected += 1;
                if let Some(n) = source {
                    self.node_mut(n.0).health.rejected_by_server += 1;
                    out.push(Change::Node(n.0));
                }
                let from = source.map_or_else(|| "an unknown sender".to_string(), |n| n.to_string());
                self.note_problem(at, format!("server rejected {what} from {from}: {reason}"));
            }
            Decision::Assigned { camera, head, .. } => {
                self.node_mut(camera.0).head = Some(head.0);
                out.push(Change::Node(camera.0));
            }
            Decision::NewGlobal { head, local, global }
            | Decision::Split {
                head, local, global, ..
            } => {
                self.bind(head.0, local.0, global.0, true, out);
            }
            Decision::Claimed { head, local, global } | Decision::Merged { head, local, global } => {
                let owns = self.tracks.get(&global.0).is_some_and(|t| t.owner == head.0);
                self.bind(head.0, local.0, global.0, owns, out);
            }
            Decision::Handover {
                global,
                from,
                to,
                reason,
            } => {
                let reason = match reason {
                    HandoverReason::Region => "region",
                    HandoverReason::Failover => "failover",
                };
                let seq = self.handover(at, global.0, from.map(|f| f.0), to.0, reason);
                out.push(Change::Handover(seq));
                if let Some(t) = self.tracks.get_mut(&global.0) {
                    t.owner = to.0;
                    out.push(Change::Track(global.0));
                }
            }
            Decision::OwnerChanged { global, from, to } => {
                let seq = self.handover(at, global.0, Some(from.0), to.0, "owner_changed");
                out.push(Change::Handover(seq));
                self.take_latest(global.0, to.0, out);
            }
            Decision::Absorbed { global, into } => {
                for g in self.book.bindings.values_mut() {
                    if *g == global.0 {
                        *g = into.0;
                    }
                }
                if self.tracks.remove(&global.0).is_some() {
                    out.push(Change::TrackRemoved(global.0));
                }
            }
            Decision::Lost { global } => {
                self.book.bindings.retain(|_, g| *g != global.0);
                if self.tracks.remove(&global.0).is_some() {
                    out.push(Change::TrackRemoved(global.0));
                }
            }
            Decision::Forgotten { head, local } => {
                self.book.bindings.remove(&(head.0, local.0));
                self.book.latest.remove(&(head.0, local.0));
            }
            Decision::Resumed {
                records,
                skipped_bytes,
            } => {
                let text = format!(
                    "server restarted: resumed from {records} records, {skipped_bytes} torn bytes skipped"
                );
                self.note_problem(at, text);
                out.push(Change::Problem);
            }
        }
    }
}

fn apply_status(node: &mut NodeView, st: &NodeStatus) {
    if node.role != NodeKind::Head {
        node.mode = Some(st.mode);
    }
    let h = &mut node.health;
    h.sync_error_ms = (st.sync_error_ns >= 0).then_some(st.sync_error_ns as f64 * 1e-6);
    h.sync_offset_ms = (st.sync_error_ns >= 0).then_some(st.sync_offset_ns as f64 * 1e-6);
    h.dropped = st.dropped;
    h.rejected = st.rejected;
    h.frames = st.frames;
    h.detections = st.detections;
}
