//! Appearance in the server's identity: people of other colours standing or walking together
//! keep their ids, and without colours position alone decides.

use super::*;

/// A colour histogram (HS 10×10 then V 10 bins) with all its mass in one HS and one V bin.
fn colours(hs_bin: usize, v_bin: usize) -> Vec<f32> {
    let mut h = vec![0.0; proto::observation::HISTOGRAM_BINS];
    h[hs_bin] = 0.5;
    h[proto::observation::HISTOGRAM_HS_BINS + v_bin] = 0.5;
    h
}

fn looking(mut e: Envelope, appearance: &[f32]) -> Envelope {
    if let Message::TrackReport(r) = &mut e.body {
        r.appearance = appearance.to_vec();
    }
    e
}

#[test]
fn two_people_of_other_colours_standing_together_stay_two() {
    let (red, blue) = (colours(3, 2), colours(60, 8));
    let mut s = started();
    let x = |k: i64| 1.0 + 0.2 * k as f64;
    s.on_message(ms(0), looking(report(H2, 1, None, ms(0), x(0), 2.0), &red));
    s.on_message(ms(0), looking(report(H2, 2, None, ms(0), x(0), 3.5), &blue));
    // They meet and walk together, as close as the same-coloured pair that became one above.
    for k in 1..8i64 {
        let t = ms(k * 200);
        s.on_message(t, looking(report(H2, 1, None, t, x(k), 2.0), &red));
        s.on_message(t, looking(report(H2, 2, None, t, x(k), 2.1), &blue));
    }
    assert_eq!(s.globals().count(), 2);
    assert_ne!(s.global_of(H2, TargetId(1)), s.global_of(H2, TargetId(2)));
}

#[test]
fn side_by_side_across_a_cluster_boundary_each_keeps_their_id_by_colour() {
    let (red, blue) = (colours(3, 2), colours(60, 8));
    let mut s = started();
    // Head 2 tracks two people 0.6 m apart near the border, red at y = 4.0, blue at y = 4.6.
    s.on_message(ms(0), looking(report(H2, 1, None, ms(0), 5.0, 4.0), &red));
    s.on_message(ms(0), looking(report(H2, 2, None, ms(0), 5.0, 4.6), &blue));
    let (r, b) = (
        s.global_of(H2, TargetId(1)).unwrap(),
        s.global_of(H2, TargetId(2)).unwrap(),
    );
    assert_ne!(r, b);
    // Head 3's cameras see them from afar, each estimate nearer the other person.
    for k in 1..=4i64 {
        let t = ms(k * 200);
        let dx = 0.1 * k as f64;
        s.on_message(t, looking(report(H2, 1, None, t, 5.0 + dx, 4.0), &red));
        s.on_message(t, looking(report(H2, 2, None, t, 5.0 + dx, 4.6), &blue));
        s.on_message(t, looking(report(H3, 9, None, t, 5.0 + dx, 4.45), &red));
        s.on_message(t, looking(report(H3, 8, None, t, 5.0 + dx, 4.15), &blue));
    }
    assert_eq!(
        s.global_of(H3, TargetId(9)),
        Some(r),
        "the red one by colour, not by distance"
    );
    assert_eq!(s.global_of(H3, TargetId(8)), Some(b));
    assert_eq!(s.globals().count(), 2, "no id flickered into existence");
}

#[test]
fn without_colours_a_second_person_beside_the_first_waits_for_an_id() {
    // The same start without histograms: head 2's second track lies within the gate of the
    // global it already feeds, so it is taken for the head's duplicate of the first person and
    // waits without an id until they part (what the colours above overrule).
    let mut s = started();
    for k in 0..=4i64 {
        let t = ms(k * 200);
        s.on_message(t, report(H2, 1, None, t, 5.0 + 0.1 * k as f64, 4.0));
        s.on_message(t, report(H2, 2, None, t, 5.0 + 0.1 * k as f64, 4.6));
    }
    assert!(s.global_of(H2, TargetId(1)).is_some());
    assert_eq!(s.global_of(H2, TargetId(2)), None);
}
