//! Authority follows regions: a head's estimate of a target in another head's area (or beyond
//! the room, nearer another head's region) never founds a global there, and ownership follows
//! the region that covers the target.

use super::*;

/// 200 ms steps `steps` in which each head reports its unnamed track `local` at rest at a
/// floor point.
fn reports_at_rest(
    s: &mut ServerNode,
    steps: std::ops::RangeInclusive<i64>,
    tracks: &[(NodeId, u32, [f64; 2])],
) {
    for k in steps {
        let t = ms(k * 200);
        for &(head, local, [x, y]) in tracks {
            s.on_message(t, report(head, local, None, t, x, y));
        }
    }
}

#[test]
fn a_track_started_in_another_clusters_area_is_not_pushed_onto_that_head() {
    let mut s = started_without_h2();
    // Head 3's cameras see a target deep in head 2's area while head 2 is down; head 2 comes
    // up: head 3 keeps it.
    s.on_message(ms(0), report(H3, 9, None, ms(0), 3.0, 4.0));
    s.on_message(ms(10), hello(H2, Role::Head));
    let out = s.on_message(ms(200), report(H3, 9, None, ms(200), 3.0, 4.0));
    assert!(handovers(&out).iter().all(|(_, h)| h.from_head.is_none()));
    assert_eq!(s.globals().next().unwrap().1.owner, H3);
}

#[test]
fn the_head_covering_a_target_it_already_tracks_takes_it_over() {
    let mut s = started_without_h2();
    let x = |k: i64| 1.0 + 0.2 * k as f64;
    // Head 3 started the track in head 2's area while head 2 was down; head 2 comes up and its
    // own track joins the global, and ownership follows the region.
    s.on_message(ms(0), report(H3, 9, None, ms(0), x(0), 4.0));
    let g = s.global_of(H3, TargetId(9)).unwrap();
    s.on_message(ms(10), hello(H2, Role::Head));
    for k in 1..5i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H3, 9, Some(g.0), t, x(k), 4.0));
        s.on_message(t, report(H2, 1, None, t, x(k) + 0.1, 4.0));
    }
    assert_eq!(s.global_of(H2, TargetId(1)), Some(g));
    assert_eq!(s.globals().next().unwrap().1.owner, H2);
    assert!(decisions(&mut s).contains(&Decision::OwnerChanged {
        global: g,
        from: H3,
        to: H2
    }));
}

/// Head 2 tracks the target in its own region; head 3 sees it from afar, badly.
#[test]
fn a_far_heads_poor_estimate_never_founds_a_second_global() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 3.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // Head 3's track sits 1.5 m off, inside head 2's region: it never gets an id of its own.
    for k in 1..=10i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 3.0, 4.0));
        s.on_message(t, report(H3, 9, None, t, 1.5, 4.0));
        assert_eq!(s.global_of(H3, TargetId(9)), None, "step {k}");
    }
    // Once it agrees it merges; when it drifts off again it loses the id instead of splitting.
    reports_at_rest(&mut s, 11..=13, &[(H2, 5, [3.0, 4.0]), (H3, 9, [3.2, 4.0])]);
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g));
    reports_at_rest(&mut s, 14..=20, &[(H2, 5, [3.0, 4.0]), (H3, 9, [1.2, 4.0])]);
    assert_eq!(s.global_of(H3, TargetId(9)), None);
    assert_eq!(s.globals().count(), 1);
    assert!(
        !decisions(&mut s)
            .iter()
            .any(|d| matches!(d, Decision::Split { .. } | Decision::NewGlobal { head: H3, .. }))
    );
}

/// Head 3 tracks the target near the far wall of its region (x 6–12 m); head 2's copy, seen by
/// its distant cameras, slides along their rays beyond the room, where no region reaches. Head
/// 3's region is still the nearest: the copy loses its id instead of splitting off one of its
/// own (four-people, seed 5: a second global at x = 12–12.8 m for 4 s).
#[test]
fn a_far_heads_track_beyond_every_region_never_founds_a_global() {
    let mut s = started();
    s.on_message(ms(0), report(H3, 2, None, ms(0), 9.0, 2.0));
    let g = s.global_of(H3, TargetId(2)).unwrap();
    reports_at_rest(&mut s, 1..=3, &[(H3, 2, [9.0, 2.0]), (H2, 4, [9.2, 2.0])]);
    assert_eq!(s.global_of(H2, TargetId(4)), Some(g));
    reports_at_rest(&mut s, 4..=20, &[(H3, 2, [9.0, 2.0]), (H2, 4, [12.5, 3.0])]);
    assert_eq!(s.global_of(H2, TargetId(4)), None);
    assert_eq!(s.globals().count(), 1);
    // Beyond the near wall, nearer head 2's own region than head 3's, the same track is head
    // 2's to found.
    reports_at_rest(&mut s, 21..=30, &[(H3, 2, [9.0, 2.0]), (H2, 4, [-0.8, 3.0])]);
    assert!(s.global_of(H2, TargetId(4)).is_some_and(|g2| g2 != g));
}

/// Three heads in a row (2: x 0–6, 3: 6–12, 4: 12–18); head 3 is down. A person in head 3's
/// floor, nearer head 4's region than head 2's, seen only by head 2's cameras: head 2 founds
/// their global, as it did before the rule for places beyond every region (the survivors share
/// a dead head's floor). Beyond the room past head 4's far wall, head 2's track does not.
#[test]
fn inside_a_dead_heads_region_any_head_may_found_a_global() {
    let toml = crate::testkit::TOML
        .replace("max = [12.0, 8.0, 3.0]", "max = [18.0, 8.0, 3.0]")
        .replace(
            "[[nodes]]\nid = 10",
            "[[nodes]]\nid = 4\nrole = \"head\"\nregion = [12.0, 0.0, 18.0, 8.0]\n[[nodes]]\nid = 10",
        );
    let sc = proto::scenario::Scenario::from_toml(&toml, "<three-heads>").unwrap();
    let mut s = ServerNode::new(ServerConfig::from_scenario(sc, NodeId(1)));
    let h4 = NodeId(4);
    s.on_message(ms(0), hello(H2, Role::Head));
    s.on_message(ms(0), hello(h4, Role::Head));
    assert!(!s.membership().is_up(H3));
    s.on_message(ms(0), report(H2, 1, None, ms(0), 10.0, 4.0));
    assert!(
        s.global_of(H2, TargetId(1)).is_some(),
        "head 3's floor, head 3 down"
    );
    s.on_message(ms(0), report(H2, 2, None, ms(0), 19.0, 4.0));
    assert_eq!(s.global_of(H2, TargetId(2)), None, "beyond head 4's far wall");
}
