//! [`ViewState::apply_update`]: the server's view feed into the view (the live viewer; a
//! recording goes through [`ViewState::apply`] instead).
//!
//! An update is one part of a round (see [`proto::view`]). Nodes and tracks are taken as they
//! come; a track the server no longer holds is removed once every part of a round arrived
//! without it (a round with a lost part removes nothing, the next complete one does).
//! Handovers are shown once each, by their sequence number; a server that started afresh
//! numbers them anew, which the view notices when the numbers go back.

use super::{Change, HandoverView, NodeKind, NodeView, RECENT_HANDOVERS, STALE_NS, ViewState};
use proto::msg::{TrackReport, ViewUpdate};
use proto::view::{HandoverCause, ViewNode, ViewTrack};
use proto::{ClusterTime, Role, TargetId};
use std::collections::BTreeSet;

/// The parts of the round being received.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Round {
    round: u64,
    parts: u16,
    seen: u64,
    tracks: BTreeSet<u32>,
}

/// The view's kind of a wire role.
pub fn kind_of(role: Role) -> NodeKind {
    match role {
        Role::Camera => NodeKind::Camera,
        Role::Head => NodeKind::Head,
        Role::Server => NodeKind::Server,
        Role::Viewer => NodeKind::Viewer,
        Role::Acoustic => NodeKind::Acoustic,
        Role::Tool => NodeKind::Unknown,
    }
}

/// A view track as the report the recording path applies (the velocity block of the
/// covariance is not sent: zero).
fn as_report(t: &ViewTrack) -> TrackReport {
    let c = t.cov_pos;
    let mut cov = [[0.0; 6]; 6];
    cov[0][..3].copy_from_slice(&[c[0], c[1], c[2]]);
    cov[1][..3].copy_from_slice(&[c[1], c[3], c[4]]);
    cov[2][..3].copy_from_slice(&[c[2], c[4], c[5]]);
    TrackReport {
        target: t.local.unwrap_or(TargetId(0)),
        global: Some(t.global),
        step: 0,
        time: t.time,
        mean: t.mean,
        cov,
        contributors: t.contributors.clone(),
        power_mw: 0.0,
        late: 0,
        appearance: Vec::new(),
        grid: None,
        captured: None,
    }
}

impl ViewState {
    /// Apply one part of the server's view feed; returns what changed.
    pub fn apply_update(&mut self, u: &ViewUpdate) -> Vec<Change> {
        self.totals.records += 1;
        let at = u.time.0;
        self.advance(at);
        let mut out = Vec::new();
        for n in &u.nodes {
            self.apply_node(u.time, n);
            out.push(Change::Node(n.node.0));
        }
        for t in &u.tracks {
            self.update_track(t.global.0, t.owner.0, at, &as_report(t));
            out.push(Change::Track(t.global.0));
        }
        self.round_part(u, &mut out);
        self.apply_handovers(u, &mut out);
        let c = &u.counters;
        self.totals.received = c.received;
        self.totals.rejected = c.rejected;
        self.totals.handovers = c.handovers;
        self.totals.steps = self.nodes_of(NodeKind::Head).map(|n| n.health.steps).sum();
        out
    }

    fn apply_node(&mut self, time: ClusterTime, n: &ViewNode) {
        let node = self.nodes.entry(n.node.0).or_insert_with(|| NodeView {
            id: n.node.0,
            ..NodeView::default()
        });
        node.role = kind_of(n.role);
        node.up = n.up;
        let silent_ns = i64::try_from(n.silent_ms)
            .ok()
            .and_then(|ms| ms.checked_mul(1_000_000));
        node.last_heard_ns = silent_ns.map(|s| time.0.saturating_sub(s));
        node.stale = n.up && n.role != Role::Server && silent_ns.is_none_or(|s| s > STALE_NS);
        node.head = n.head.map(|h| h.0);
        let h = &mut node.health;
        if let Some(st) = &n.status {
            if n.role != Role::Head {
                node.mode = Some(st.mode);
            }
            h.sync_error_ms = (st.sync_error_ns >= 0).then_some(st.sync_error_ns as f64 * 1e-6);
            h.sync_offset_ms = (st.sync_error_ns >= 0).then_some(st.sync_offset_ns as f64 * 1e-6);
            h.dropped = st.dropped;
            h.rejected = st.rejected;
            h.frames = st.frames;
            h.detections = st.detections;
        }
        h.rejected_by_server = n.rejected;
        h.late = n.late;
        h.lost = n.lost;
        h.steps = n.steps;
    }

    /// Note this part of its round; once every part arrived, tracks the round did not carry
    /// are gone.
    fn round_part(&mut self, u: &ViewUpdate, out: &mut Vec<Change>) {
        let r = &mut self.book.round;
        if r.round != u.round || r.parts != u.parts {
            *r = Round {
                round: u.round,
                parts: u.parts,
                ..Round::default()
            };
        }
        r.seen |= 1u64 << u.part.min(63);
        r.tracks.extend(u.tracks.iter().map(|t| t.global.0));
        let all = if u.parts >= 64 {
            u64::MAX
        } else {
            (1u64 << u.parts) - 1
        };
        if r.seen & all != all {
            return;
        }
        let keep = std::mem::take(&mut r.tracks);
        r.seen = 0;
        let gone: Vec<u32> = self
            .tracks
            .keys()
            .filter(|g| !keep.contains(g))
            .copied()
            .collect();
        for g in gone {
            self.tracks.remove(&g);
            out.push(Change::TrackRemoved(g));
        }
    }

    fn apply_handovers(&mut self, u: &ViewUpdate, out: &mut Vec<Change>) {
        if u.handovers
            .iter()
            .map(|h| h.seq)
            .max()
            .is_some_and(|m| m < self.book.handover_seq)
        {
            self.book.handover_seq = 0; // the server numbers afresh
        }
        let shown = self.book.handover_seq;
        for h in u.handovers.iter().filter(|h| h.seq > shown) {
            self.book.handover_seq = h.seq;
            let position = self
                .tracks
                .get(&h.global.0)
                .map(|t| [t.position[0], t.position[1]]);
            if self.handovers.len() >= RECENT_HANDOVERS {
                self.handovers.pop_front();
            }
            self.handovers.push_back(HandoverView {
                seq: h.seq,
                time: h.time.as_secs_f64(),
                global: h.global.0,
                from: h.from.map(|f| f.0),
                to: h.to.0,
                reason: match h.cause {
                    HandoverCause::Region => "region",
                    HandoverCause::Failover => "failover",
                    HandoverCause::OwnerChanged => "owner_changed",
                }
                .into(),
                position,
            });
            out.push(Change::Handover(h.seq));
        }
    }
}
