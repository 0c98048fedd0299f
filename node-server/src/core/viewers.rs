//! The server's side of the visualization node (paper 004 §3.1): viewers subscribe, and every
//! period (the filter's step by default) each gets one round of [`ViewUpdate`]s — every global
//! track with its owner and posterior, every node's liveness, status and health, the latest
//! handovers and the server's counts.
//!
//! A viewer has no say: its [`ViewSubscribe`] admits it (as [`Role::Viewer`], with an id the
//! scenario does not declare) and it is sent updates, nothing else changes. Updates are
//! droppable, so a viewer that cannot keep up loses updates (counted as undelivered by the
//! runtime) and never holds the server up; a viewer marked down gets nothing until it speaks
//! again. At most [`MAX_VIEWERS`] subscribe at once.
//!
//! What the updates carry beyond the core's own state is kept here from the inputs: each
//! member's sequence gaps (frames lost on the way) and rejected messages, each head's latest
//! step and late contributions, each local track's latest contributors, and the recent
//! handovers. It is all derived from recorded inputs, so a restored server rebuilds it.

use super::ServerNode;
use crate::decision::{Decision, HandoverReason};
use proto::msg::{Contributor, Message, TrackReport, ViewSubscribe, ViewUpdate};
use proto::node::Outgoing;
use proto::view::{
    HandoverCause, MAX_VIEW_CONTRIBUTORS, MAX_VIEW_HANDOVERS, MAX_VIEW_NODES, MAX_VIEW_PARTS,
    MAX_VIEW_TRACKS, MIN_VIEW_PERIOD_MS, ViewCounters, ViewHandover, ViewNode, ViewTrack,
};
use proto::{ClusterTime, NodeId, Role, TargetId};
use std::collections::{BTreeMap, BTreeSet, VecDeque};

/// Viewers subscribed at once, at most.
pub const MAX_VIEWERS: usize = 16;

/// What the feed keeps.
#[derive(Clone, Debug, Default)]
pub(crate) struct ViewFeed {
    subscribers: BTreeMap<NodeId, Subscriber>,
    heard: BTreeMap<NodeId, Heard>,
    /// Each head's local track: its latest report's time and contributors.
    locals: BTreeMap<(NodeId, TargetId), (ClusterTime, Vec<Contributor>)>,
    handovers: VecDeque<ViewHandover>,
    handover_seq: u64,
}

#[derive(Clone, Debug)]
struct Subscriber {
    period_ns: i64,
    next: ClusterTime,
    round: u64,
}

/// What the server noticed about one member's messages.
#[derive(Clone, Debug, Default)]
struct Heard {
    last_seq: Option<u64>,
    lost: u64,
    rejected: u64,
    steps: u64,
    late: u64,
}

impl ViewFeed {
    /// A message from member `src` with sequence number `seq`: a gap is frames lost on the way
    /// (a restarted sender starts again from 0: no gap).
    pub(crate) fn heard(&mut self, src: NodeId, seq: u64) {
        let h = self.heard.entry(src).or_default();
        if let Some(prev) = h.last_seq
            && seq > prev + 1
        {
            h.lost += seq - prev - 1;
        }
        h.last_seq = Some(seq);
    }

    /// A head's report: its step, its late count and the track's contributors.
    pub(crate) fn reported(&mut self, head: NodeId, r: &TrackReport) {
        let h = self.heard.entry(head).or_default();
        h.steps = h.steps.max(r.step);
        h.late = h.late.max(r.late);
        let mut who = r.contributors.clone();
        who.truncate(MAX_VIEW_CONTRIBUTORS);
        self.locals.insert((head, r.target), (r.time, who));
    }

    /// A message of `source` (a member) was rejected.
    pub(crate) fn rejected(&mut self, source: Option<NodeId>, member: bool) {
        if let Some(s) = source
            && member
        {
            self.heard.entry(s).or_default().rejected += 1;
        }
    }

    /// A decision: handovers and owner changes are kept for the viewers; a forgotten local
    /// track's contributors go.
    pub(crate) fn decided(&mut self, now: ClusterTime, d: &Decision) {
        let (global, from, to, cause) = match d {
            Decision::Handover {
                global,
                from,
                to,
                reason,
            } => {
                let cause = match reason {
                    HandoverReason::Region => HandoverCause::Region,
                    HandoverReason::Failover => HandoverCause::Failover,
                };
                (*global, *from, *to, cause)
            }
            Decision::OwnerChanged { global, from, to } => {
                (*global, Some(*from), *to, HandoverCause::OwnerChanged)
            }
            Decision::Forgotten { head, local } => {
                self.locals.remove(&(*head, *local));
                return;
            }
            _ => return,
        };
        self.handover_seq += 1;
        if self.handovers.len() >= MAX_VIEW_HANDOVERS {
            self.handovers.pop_front();
        }
        self.handovers.push_back(ViewHandover {
            seq: self.handover_seq,
            time: now,
            global,
            from,
            to,
            cause,
        });
    }

    /// The local id and contributors of `owner`'s latest report bound to `global`.
    fn owner_local(
        &self,
        node: &ServerNode,
        owner: NodeId,
        global: TargetId,
    ) -> (Option<TargetId>, Vec<Contributor>) {
        self.locals
            .range((owner, TargetId(0))..=(owner, TargetId(u32::MAX)))
            .filter(|((h, l), _)| node.tracks.global_of(*h, *l) == Some(global))
            .max_by_key(|(_, (t, _))| *t)
            .map_or((None, Vec::new()), |((_, l), (_, who))| (Some(*l), who.clone()))
    }
}

/// The slice `[from, to)` of `len` items that part `part` carries, `max` per part.
fn part_range(len: usize, max: usize, part: usize) -> (usize, usize) {
    let from = (part * max).min(len);
    (from, (from + max).min(len))
}

/// `[xx, xy, xz, yy, yz, zz]` of a 6×6 covariance's position block.
fn position_block(c: &proto::msg::Mat6) -> [f64; 6] {
    [c[0][0], c[0][1], c[0][2], c[1][1], c[1][2], c[2][2]]
}

impl ServerNode {
    /// A viewer's subscription (or its renewal): admit it as a viewer and send it updates
    /// from the next tick on.
    pub(super) fn subscribe(
        &mut self,
        now: ClusterTime,
        src: NodeId,
        seq: u64,
        s: &ViewSubscribe,
        out: &mut Vec<Outgoing>,
    ) {
        let refuse = match (
            self.members.declared_role(src),
            self.members.member(src).map(|m| m.role),
        ) {
            (Some(r), _) => Some(format!(
                "{src} is the scenario's {r}; a viewer needs an id the scenario does not use"
            )),
            (None, Some(r)) if r != Role::Viewer => Some(format!("{src} joined as a {r}, not a viewer")),
            _ if !self.viewers.subscribers.contains_key(&src)
                && self.viewers.subscribers.len() >= MAX_VIEWERS =>
            {
                Some(format!("{MAX_VIEWERS} viewers are subscribed already"))
            }
            _ => None,
        };
        if let Some(reason) = refuse {
            self.reject(now, Some(src), "view_subscribe", reason);
            return;
        }
        if let Some(d) = self.members.admit(now, src, Role::Viewer) {
            self.decide(now, d, out);
        }
        self.viewers.heard(src, seq);
        let step_ms = u32::try_from(self.cfg.scenario.method.step_ms).unwrap_or(u32::MAX);
        let period_ms = if s.period_ms == 0 { step_ms } else { s.period_ms }.max(MIN_VIEW_PERIOD_MS);
        let period_ns = i64::from(period_ms) * 1_000_000;
        let sub = self.viewers.subscribers.entry(src).or_insert(Subscriber {
            period_ns,
            next: now,
            round: 0,
        });
        sub.period_ns = period_ns;
    }

    /// On a tick: a round of updates to every subscribed viewer that is up and due.
    pub(super) fn view_updates(&mut self, now: ClusterTime) -> Vec<Outgoing> {
        let due: Vec<NodeId> = self
            .viewers
            .subscribers
            .iter()
            .filter(|(id, s)| now >= s.next && self.members.is_up(**id))
            .map(|(id, _)| *id)
            .collect();
        if due.is_empty() {
            return Vec::new();
        }
        let tracks = self.view_tracks();
        let nodes = self.view_nodes(now);
        let parts = tracks
            .len()
            .div_ceil(MAX_VIEW_TRACKS)
            .max(nodes.len().div_ceil(MAX_VIEW_NODES))
            .clamp(1, usize::from(MAX_VIEW_PARTS));
        let counters = ViewCounters {
            received: self.counters.received,
            rejected: self.counters.rejected,
            handovers: self.counters.handovers,
            undelivered: self.counters.undelivered,
        };
        let handovers: Vec<ViewHandover> = self.viewers.handovers.iter().cloned().collect();
        let mut out = Vec::new();
        for id in due {
            let Some(sub) = self.viewers.subscribers.get_mut(&id) else {
                continue;
            };
            sub.round += 1;
            sub.next = if now - sub.next > sub.period_ns {
                now + sub.period_ns
            } else {
                sub.next + sub.period_ns
            };
            for part in 0..parts {
                let (t0, t1) = part_range(tracks.len(), MAX_VIEW_TRACKS, part);
                let (n0, n1) = part_range(nodes.len(), MAX_VIEW_NODES, part);
                let update = ViewUpdate {
                    round: sub.round,
                    part: u16::try_from(part).unwrap_or(u16::MAX),
                    parts: u16::try_from(parts).unwrap_or(u16::MAX),
                    time: now,
                    tracks: tracks[t0..t1].to_vec(),
                    tracks_total: u32::try_from(tracks.len()).unwrap_or(u32::MAX),
                    nodes: nodes[n0..n1].to_vec(),
                    nodes_total: u32::try_from(nodes.len()).unwrap_or(u32::MAX),
                    handovers: handovers.clone(),
                    counters: counters.clone(),
                };
                out.push(Outgoing::new(id, Message::ViewUpdate(update)));
            }
        }
        out
    }

    fn view_tracks(&self) -> Vec<ViewTrack> {
        self.tracks
            .globals()
            .map(|(global, gt)| {
                let (local, contributors) = self.viewers.owner_local(self, gt.owner, global);
                ViewTrack {
                    global,
                    owner: gt.owner,
                    local,
                    time: gt.time,
                    mean: gt.mean,
                    cov_pos: position_block(&gt.cov),
                    contributors,
                }
            })
            .collect()
    }

    /// Every node the scenario declares and every member, in id order.
    fn view_nodes(&self, now: ClusterTime) -> Vec<ViewNode> {
        let ids: BTreeSet<NodeId> = self
            .cfg
            .scenario
            .nodes
            .iter()
            .map(|n| NodeId(n.id))
            .chain(self.members.members().map(|(id, _)| id))
            .collect();
        ids.into_iter()
            .filter_map(|id| {
                let member = self.members.member(id);
                let role = member
                    .map(|m| m.role)
                    .or_else(|| self.members.declared_role(id))?;
                let me = id == self.cfg.id;
                let silent_ms = match member {
                    _ if me => 0,
                    Some(m) => u64::try_from((now - m.last_seen).max(0) / 1_000_000).unwrap_or(0),
                    None => u64::MAX,
                };
                let heard = self.viewers.heard.get(&id).cloned().unwrap_or_default();
                Some(ViewNode {
                    node: id,
                    role,
                    up: me || member.is_some_and(|m| m.up),
                    silent_ms,
                    head: (role == Role::Camera).then(|| self.members.head_of(id)).flatten(),
                    status: self.status.get(&id).cloned(),
                    steps: heard.steps,
                    late: heard.late,
                    rejected: heard.rejected,
                    lost: heard.lost,
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
