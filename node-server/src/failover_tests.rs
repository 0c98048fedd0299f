//! Failover keeps the global id, whatever order the surviving head's reports and the failover
//! tick reach the server in.
//!
//! The sequence is the one an end-to-end run (`tests` crate, `cluster::killing_the_owning_head…`)
//! recorded when it failed: head 3 founds the target while head 2 is not up yet, head 2 merges
//! and takes the track over (its region), the two heads then disagree by about a metre, head 2
//! dies, and head 3's track — demoted to pending by the disagreement with head 2's last estimate
//! — used to found a second global id once head 2 was gone.

use crate::core::{ServerConfig, ServerNode};
use crate::decision::{Decision, HandoverReason};
use crate::record::Record;
use proto::msg::{Hello, Message, TrackReport};
use proto::{ClusterTime, Envelope, NodeId, PROTOCOL_VERSION, Role, TargetId};

const H2: NodeId = NodeId(2);
const H3: NodeId = NodeId(3);
const CAM: NodeId = NodeId(10);

fn ms(v: i64) -> ClusterTime {
    ClusterTime::from_millis(v)
}

fn env(source: NodeId, body: Message) -> Envelope {
    Envelope {
        source,
        seq: 0,
        time: ClusterTime::ZERO,
        body,
    }
}

fn hello(node: NodeId, role: Role) -> Envelope {
    env(
        node,
        Message::Hello(Hello {
            version: PROTOCOL_VERSION,
            role,
            node,
        }),
    )
}

/// A head's report of its local track at rest at `(x, 4)`.
fn report(head: NodeId, local: u32, global: Option<TargetId>, t: i64, x: f64) -> Envelope {
    let mut cov = [[0.0; 6]; 6];
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] = 0.04;
    }
    env(
        head,
        Message::TrackReport(TrackReport {
            target: TargetId(local),
            global,
            step: 0,
            time: ms(t),
            mean: [x, 4.0, 0.9, 0.0, 0.0, 0.0],
            cov,
            contributors: vec![],
            power_mw: 100.0,
            late: 0,
            appearance: Vec::new(),
            grid: None,
            captured: None,
        }),
    )
}

fn decisions(s: &mut ServerNode) -> Vec<Decision> {
    s.take_records()
        .into_iter()
        .filter_map(|r| match r.record {
            Record::Decision(d) => Some(d),
            _ => None,
        })
        .collect()
}

/// Up to head 2's death at 1400 ms: returns the server and the target's global id. Head 3's
/// last reports disagree with head 2's (1.2 m apart) while head 2 is still fresh, so head 3's
/// track is pending, not bound, when head 2 dies.
fn owner_dies_while_the_other_head_disagrees() -> (ServerNode, TargetId) {
    let mut s = ServerNode::new(ServerConfig::from_scenario(crate::testkit::scenario(), NodeId(1)));
    s.on_message(ms(0), hello(H3, Role::Head));
    s.on_message(ms(0), hello(CAM, Role::Camera));
    // Head 3 sees the target first, in head 2's area while head 2 is not up: it founds it.
    s.on_message(ms(0), report(H3, 1, None, 0, 2.4));
    let g = s.global_of(H3, TargetId(1)).expect("head 3 founds the target");
    s.on_message(ms(100), hello(H2, Role::Head));
    // Head 2 merges after the hysteresis, then takes the track over (it is in its region).
    for t in (200..=800).step_by(200) {
        s.on_message(ms(t), report(H3, 1, Some(g), t, 2.6));
        s.on_message(ms(t + 5), report(H2, 1, None, t, 2.8));
    }
    assert_eq!(s.global_of(H2, TargetId(1)), Some(g));
    assert_eq!(s.globals().next().map(|(_, gt)| gt.owner), Some(H2));
    // Head 2 stays at 2.8 m, head 3 sees the target at 4.0 m: three disagreeing reports.
    for t in (1000..=1400).step_by(200) {
        s.on_message(ms(t + 5), report(H2, 1, Some(g), t, 2.8));
        s.on_message(ms(t + 10), report(H3, 1, Some(g), t + 10, 4.0));
    }
    // Head 2 dies right after its last report.
    assert_eq!(s.global_of(H3, TargetId(1)), None, "head 3's track is pending");
    let founded = decisions(&mut s)
        .into_iter()
        .filter(|d| matches!(d, Decision::NewGlobal { .. }))
        .count();
    assert_eq!(founded, 1);
    (s, g)
}

fn assert_kept(s: &mut ServerNode, g: TargetId) {
    assert_eq!(
        s.global_of(H3, TargetId(1)),
        Some(g),
        "head 3's track lost the global id"
    );
    let globals: Vec<_> = s.globals().map(|(id, gt)| (id, gt.owner, gt.mean[0])).collect();
    assert!(
        matches!(globals[..], [(id, owner, x)] if id == g && owner == H3 && (x - 4.8).abs() < 1e-9),
        "want one global {g}, owned by head 3, at its last estimate: {globals:?}"
    );
    let founded: Vec<Decision> = decisions(s)
        .into_iter()
        .filter(|d| matches!(d, Decision::NewGlobal { .. } | Decision::Split { .. }))
        .collect();
    assert!(founded.is_empty(), "a second id was founded: {founded:?}");
}

/// Head 3's reports are held up until the failover tick has given the track to head 3.
#[test]
fn failover_tick_before_the_survivors_report_keeps_the_global_id() {
    let (mut s, g) = owner_dies_while_the_other_head_disagrees();
    let mut failover = None;
    for t in (1450..3000).step_by(50) {
        s.on_message(ms(t), env(H3, Message::Heartbeat));
        s.on_message(ms(t), env(CAM, Message::Heartbeat));
        s.tick(ms(t));
        if s.globals().any(|(_, gt)| gt.owner == H3) {
            failover = Some(t);
            break;
        }
    }
    let t = failover.expect("the track failed over to head 3");
    assert!(decisions(&mut s).contains(&Decision::Handover {
        global: g,
        from: Some(H2),
        to: H3,
        reason: HandoverReason::Failover,
    }));
    for k in 1..=4 {
        let at = t + 200 * k;
        s.on_message(ms(at), report(H3, 1, Some(g), at, 4.0 + 0.2 * k as f64));
    }
    assert_kept(&mut s, g);
}

/// The link to head 2 closes (TCP): head 2 is down at once, and head 3's reports reach the
/// server before any tick runs the failover.
#[test]
fn survivors_report_before_the_failover_tick_keeps_the_global_id() {
    let (mut s, g) = owner_dies_while_the_other_head_disagrees();
    s.on_link(ms(1450), H2, false);
    for k in 1..=4 {
        let at = 1400 + 200 * k;
        s.on_message(ms(at), report(H3, 1, Some(g), at, 4.0 + 0.2 * k as f64));
    }
    s.tick(ms(2300));
    assert_kept(&mut s, g);
}

/// Head 2 only falls silent (no link event): head 3's reports keep coming while the server still
/// counts head 2 as up, then the liveness timeout and the failover tick follow.
#[test]
fn survivors_reports_while_the_owner_is_silent_keep_the_global_id() {
    let (mut s, g) = owner_dies_while_the_other_head_disagrees();
    for k in 1..=4 {
        let at = 1400 + 200 * k;
        s.on_message(ms(at), env(CAM, Message::Heartbeat));
        s.on_message(ms(at), report(H3, 1, Some(g), at, 4.0 + 0.2 * k as f64));
        s.tick(ms(at));
    }
    for t in (2300..3000).step_by(50) {
        s.on_message(ms(t), env(H3, Message::Heartbeat));
        s.on_message(ms(t), env(CAM, Message::Heartbeat));
        s.tick(ms(t));
    }
    assert!(!s.membership().is_up(H2));
    assert_kept(&mut s, g);
}

/// The failover tick comes while head 3's track still follows the target: the track goes to
/// head 3, which continues from its own estimate (newer than the dead owner's), bound at once.
#[test]
fn failover_to_the_following_head_starts_from_its_own_estimate() {
    let (mut s, g) = owner_dies_while_the_other_head_disagrees();
    s.on_link(ms(1450), H2, false);
    let out = s.tick(ms(1460));
    let sent: Vec<_> = out
        .iter()
        .filter_map(|o| match &o.body {
            Message::Handover(h) => Some((o.to, h.global, h.mean[0])),
            _ => None,
        })
        .collect();
    assert_eq!(
        sent,
        vec![(H3, g, 4.0)],
        "handover to head 3 with its own last estimate"
    );
    assert_eq!(s.global_of(H3, TargetId(1)), Some(g));
    let d = decisions(&mut s);
    assert!(d.contains(&Decision::Merged {
        head: H3,
        local: TargetId(1),
        global: g
    }));
    for k in 1..=4 {
        let at = 1400 + 200 * k;
        s.on_message(ms(at), report(H3, 1, Some(g), at, 4.0 + 0.2 * k as f64));
    }
    assert_kept(&mut s, g);
}

/// After the failover the survivor briefly holds two confirmed tracks of the one target (a
/// duplicate born on detections its bound track's gate missed, seen in the e2e recordings
/// 0.2–1.1 m from the bound track, dropped by the head's duplicate merge within about a
/// second). The duplicate is reported without a global id, well inside the merge gate of the
/// global the same head already feeds: it must not be given a second global id.
#[test]
fn survivors_duplicate_track_after_failover_gets_no_second_global_id() {
    let (mut s, g) = owner_dies_while_the_other_head_disagrees();
    s.on_link(ms(1450), H2, false);
    s.tick(ms(1460));
    assert_eq!(s.global_of(H3, TargetId(1)), Some(g));
    decisions(&mut s);
    let mut minted = Vec::new();
    for k in 1..=8 {
        let at = 1400 + 200 * k;
        let x = 4.0 + 0.2 * k as f64;
        s.on_message(ms(at), report(H3, 1, Some(g), at, x));
        // The duplicate lives for four reports, half a metre off the bound track.
        if (3..=6).contains(&k) {
            let out = s.on_message(ms(at + 1), report(H3, 2, None, at, x - 0.5));
            minted.extend(out.into_iter().filter_map(|o| match o.body {
                Message::Handover(h) if h.from_head.is_none() && h.global != g => Some(h.global),
                _ => None,
            }));
        }
    }
    let founded: Vec<Decision> = decisions(&mut s)
        .into_iter()
        .filter(|d| matches!(d, Decision::NewGlobal { .. } | Decision::Split { .. }))
        .collect();
    assert!(
        founded.is_empty() && minted.is_empty(),
        "a second global id was minted for the survivor's duplicate of {g}: {founded:?}, named {minted:?}"
    );
    assert_eq!(s.globals().count(), 1, "one target, one global");
}
