//! Region handovers: what each head is sent, and which of a head's tracks speaks for the
//! global after it moved away and back.

use super::*;

#[test]
fn leaving_a_region_hands_the_track_over_with_the_last_posterior() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.0, 4.0));
    // Inside the margin: no handover yet.
    let out = s.on_message(ms(200), report(H2, 5, None, ms(200), 6.2, 4.0));
    assert!(handovers(&out).is_empty());
    let out = s.on_message(ms(400), report(H2, 5, None, ms(400), 6.4, 4.1));
    let h: Vec<_> = handovers(&out)
        .into_iter()
        .filter(|(_, m)| m.from_head.is_some())
        .collect();
    assert_eq!(h.len(), 2, "sent to the new and the old head: {out:?}");
    assert!(h.iter().any(|(to, _)| *to == H3) && h.iter().any(|(to, _)| *to == H2));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    for (_, m) in &h {
        assert_eq!((m.global, m.to_head, m.from_head), (g, H3, Some(H2)));
        assert_eq!(m.mean[..2], [6.4, 4.1]);
        assert_eq!(m.time, ms(400));
    }
    // The new head continues the track under its own local id, carrying the global id.
    s.on_message(ms(600), report(H3, 1, Some(g.0), ms(600), 6.6, 4.1));
    assert_eq!(s.global_of(H3, TargetId(1)), Some(g));
    assert_eq!(s.globals().next().unwrap().1.owner, H3);
}

/// The new head already tracks the target (its track is bound to the global): the handover
/// gives it that track's posterior, so it takes it for the named track instead of starting a
/// second one beside it from the old head's estimate. The old head gets its own last word, by
/// which it finds the track to drop.
#[test]
fn a_handover_gives_the_new_head_its_own_track_of_the_target() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    for k in 1..=3i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 5, None, t, 5.5, 4.0));
        s.on_message(t, report(H3, 9, None, t, 5.9, 4.3));
    }
    assert_eq!(s.global_of(H3, TargetId(9)), Some(g));
    let out = s.on_message(ms(800), report(H2, 5, None, ms(800), 6.4, 4.0));
    let h = handovers(&out);
    let to_new = h.iter().find(|(to, _)| *to == H3).expect("sent to the new head");
    assert_eq!((&to_new.1.mean[..2], to_new.1.time), (&[5.9, 4.3][..], ms(600)));
    let to_old = h.iter().find(|(to, _)| *to == H2).expect("sent to the old head");
    assert_eq!((&to_old.1.mean[..2], to_old.1.time), (&[6.4, 4.0][..], ms(800)));
}

/// After a handover the old head drops its track; a track it starts again on the target (still
/// near the border) merges back into the global instead of founding a new one.
#[test]
fn the_old_heads_new_track_on_a_handed_over_target_merges_back() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 6.0, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    let out = s.on_message(ms(200), report(H2, 5, None, ms(200), 6.3, 4.0));
    assert_eq!(handovers(&out).len(), 2);
    for k in 2..=5i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H3, 1, Some(g.0), t, 6.3, 4.0));
        s.on_message(t, report(H2, 6, None, t, 6.2, 4.0));
    }
    assert_eq!(s.global_of(H2, TargetId(6)), Some(g));
    assert_eq!(s.globals().count(), 1);
}

/// A head that keeps a track of its own after the global it fed was handed away (here it was
/// told the name, but a head that adopted a handover beside its own unnamed track drops the
/// named one and keeps this) does not speak for the global when it comes back: its report is
/// looked at afresh. Taken as the owner's word, the kept track on the other head's floor
/// handed the global straight back, every report.
#[test]
fn a_kept_track_of_a_handed_away_global_never_hands_it_back() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.9, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    // H2's estimate crosses into H3's floor: handed over, H2's track 5 released.
    let out = s.on_message(ms(200), report(H2, 5, None, ms(200), 6.5, 4.0));
    assert_eq!(handovers(&out).len(), 2);
    // A report H2 made before it heard of the handover (its estimate is older), arriving late
    // and far from g: no word on anything (taken afresh, it founded a global and named a track
    // on H2, which may be a neighbour's).
    s.take_records();
    let out = s.on_message(ms(250), report(H2, 5, None, ms(200), 4.0, 4.0));
    assert!(out.is_empty(), "{out:?}");
    assert_eq!(decisions(&mut s), Vec::new());
    s.on_message(ms(400), report(H3, 1, Some(g.0), ms(400), 6.4, 4.0));
    // H3's track of g walks back onto H2's floor: handed to H2.
    let out = s.on_message(ms(600), report(H3, 1, Some(g.0), ms(600), 5.4, 4.0));
    assert!(handovers(&out).iter().any(|(to, h)| *to == H2 && h.to_head == H2));
    // H2 kept its track 5, still on H3's floor, 1.2 m from g.
    let out = s.on_message(ms(600), report(H2, 5, None, ms(600), 6.6, 4.0));
    assert!(handovers(&out).is_empty(), "{:?}", handovers(&out));
    assert_eq!(s.global_of(H2, TargetId(5)), None);
    // A late report of the very track H3 was told to drop is no word on g: no decision at all
    // (taken afresh, it would be claimed back).
    s.take_records();
    let out = s.on_message(ms(650), report(H3, 1, Some(g.0), ms(400), 6.9, 4.0));
    assert!(handovers(&out).is_empty(), "{:?}", handovers(&out));
    assert_eq!(decisions(&mut s), Vec::new());
    assert_eq!(
        s.globals().find(|(id, _)| *id == g).map(|(_, gt)| gt.owner),
        Some(H2)
    );
}

/// A global handed away and straight back to a head that kept its released track: the head
/// names that track by the handover back, and its reports are the owner's word again (they
/// were ignored as late reports, and the global was lost).
#[test]
fn a_released_track_named_by_a_handover_back_speaks_for_the_global() {
    let mut s = started();
    s.on_message(ms(0), report(H2, 5, None, ms(0), 5.9, 4.0));
    let g = s.global_of(H2, TargetId(5)).unwrap();
    s.on_message(ms(200), report(H2, 5, None, ms(200), 6.5, 4.0));
    let out = s.on_message(ms(400), report(H3, 1, Some(g.0), ms(400), 5.6, 4.0));
    assert!(handovers(&out).iter().any(|(to, h)| *to == H2 && h.to_head == H2));
    // H2 never dropped track 5 and names it g.
    s.on_message(ms(600), report(H2, 5, Some(g.0), ms(600), 5.2, 4.0));
    assert_eq!(s.global_of(H2, TargetId(5)), Some(g));
    let gt = s
        .globals()
        .find(|(id, _)| *id == g)
        .map(|(_, gt)| gt.clone())
        .unwrap();
    assert_eq!((gt.owner, gt.mean[0], gt.time), (H2, 5.2, ms(600)));
}
