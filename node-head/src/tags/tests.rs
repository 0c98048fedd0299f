//! Tests of the tag book: binding by evidence, and tags whose home is another head.

use super::*;
use nalgebra::{Matrix6, Vector3};
use proto::models::State;
use proto::msg::TagHome;

const MODEL: RssiModel = RssiModel::LogDistance {
    a: -22.0,
    b: -45.0,
    variance: 16.0,
};

fn track(local: u32, x: f64, y: f64) -> Track {
    let mut t = Track::new(
        TargetId(local),
        None,
        State::new(x, y, 1.0, 0.0, 0.0, 0.0),
        Matrix6::identity() * 0.01,
        ClusterTime::ZERO,
        4,
        MODEL,
        10,
        0.1,
    )
    .unwrap();
    t.camera_steps = 10;
    t.confirm();
    t
}

/// Four nodes at the room's corners.
fn node(slot: usize) -> Vector3<f64> {
    [
        Vector3::new(0.0, 0.0, 2.5),
        Vector3::new(10.0, 0.0, 2.5),
        Vector3::new(0.0, 10.0, 2.5),
        Vector3::new(10.0, 10.0, 2.5),
    ][slot]
}

/// One reading of `tag` at every node, as a tag at `at` would give them without noise,
/// received at `time`.
fn readings(book: &mut TagBook, tag: TagId, at: Vector3<f64>, time: ClusterTime) -> Vec<Heard> {
    for slot in 0..4 {
        let dbm = MODEL.predict((at - node(slot)).norm());
        book.offer(slot, RssiReading { tag, dbm, time }, time);
    }
    book.take_step(time)
}

/// Run `steps` steps of 0.2 s in which `tag` is heard at `at`; returns every change.
fn run(book: &mut TagBook, tracks: &[Track], tag: TagId, at: Vector3<f64>, steps: u32) -> Vec<Change> {
    let mut changes = Vec::new();
    for s in 0..steps {
        let time = ClusterTime::from_millis(200 * i64::from(s));
        let heard = readings(book, tag, at, time);
        book.weigh(&heard, tracks, time, |_, _| MODEL, node);
        changes.extend(book.decide(tracks, |t| t.past_tentative()));
    }
    changes
}

#[test]
fn a_tag_binds_to_the_track_it_moves_with_and_not_to_the_other() {
    let tracks = [track(1, 2.0, 3.0), track(2, 7.0, 6.0)];
    let mut book = TagBook::default();
    let tag = TagId(0xaa);
    let changes = run(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 10);
    assert_eq!(
        changes,
        vec![Change::Bound {
            tag,
            track: TargetId(2)
        }]
    );
    assert_eq!(book.tag_of(TargetId(2)), Some(tag));
    assert_eq!(book.tag_of(TargetId(1)), None);
    assert!(book.evidence(tag, TargetId(2)) - book.evidence(tag, TargetId(1)) >= BIND_LLR);
}

/// Steps of 0.2 s from `from_s` to `to_s` seconds in which `tag` is heard at `at`, the
/// server's word on homes taken as the head takes it; returns every change.
fn run_between(
    book: &mut TagBook,
    tracks: &[Track],
    tag: TagId,
    at: Vector3<f64>,
    from_s: f64,
    to_s: f64,
) -> Vec<Change> {
    let mut changes = Vec::new();
    let mut t = from_s;
    while t < to_s {
        let time = ClusterTime::from_millis((t * 1000.0).round() as i64);
        let heard = readings(book, tag, at, time);
        book.weigh(&heard, tracks, time, |_, _| MODEL, node);
        changes.extend(book.refresh_homes(time));
        changes.extend(book.decide(tracks, |t| t.past_tentative()));
        t += 0.2;
    }
    changes
}

#[test]
fn a_tag_whose_home_is_another_head_feeds_no_track_here_until_it_comes_back() {
    let tracks = [track(1, 7.0, 6.0)];
    let tag = TagId(0xaa);
    let at = Vector3::new(7.0, 6.0, 1.0);
    let mut book = TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
    run_between(&mut book, &tracks, tag, at, 0.0, 2.0);
    assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
    // The server names head 4 the tag's home: the track takes none of its readings while
    // the word holds; the binding stays (by the evidence), so the track still claims it.
    let home = [TagHome {
        tag,
        head: NodeId(4),
        shared: false,
    }];
    book.set_homes(&home, ClusterTime::from_millis(2000));
    let changes = run_between(&mut book, &tracks, tag, at, 2.0, 4.0);
    assert_eq!(
        changes,
        vec![Change::Away {
            tag,
            track: TargetId(1),
            home: NodeId(4)
        }]
    );
    assert!(book.away(tag));
    assert_eq!(book.fused_tag_of(TargetId(1)), None);
    assert_eq!(book.track_of(tag), Some(TargetId(1)));
    assert_eq!(
        book.loudest(ClusterTime::from_millis(4000))[0].track,
        Some(TargetId(1))
    );
    // Its own word does not hold it back; nor does a word older than HOME_TTL_NS.
    book.set_homes(
        &[TagHome {
            tag,
            head: NodeId(3),
            shared: false,
        }],
        ClusterTime::from_millis(4000),
    );
    run_between(&mut book, &tracks, tag, at, 4.0, 4.4);
    assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
    book.set_homes(&home, ClusterTime::from_millis(4400));
    run_between(&mut book, &tracks, tag, at, 4.4, 5.0);
    assert_eq!(book.fused_tag_of(TargetId(1)), None);
    let after = 4.4 + HOME_TTL_NS as f64 / 1e9;
    run_between(&mut book, &tracks, tag, at, 5.0, after + 0.4);
    assert!(!book.away(tag), "the server's word lapsed");
    assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
}

#[test]
fn a_track_the_server_says_is_the_homes_person_takes_an_away_tag() {
    let tracks = [track(1, 7.0, 6.0)];
    let tag = TagId(0xaa);
    let mut book = TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
    run_between(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 0.0, 2.0);
    let home = |shared| TagHome {
        tag,
        head: NodeId(4),
        shared,
    };
    book.set_homes(&[home(true)], ClusterTime::from_millis(2000));
    book.refresh_homes(ClusterTime::from_millis(2000));
    assert!(book.away(tag));
    assert_eq!(book.fused_tag_of(TargetId(1)), Some(tag));
    book.set_homes(&[home(false)], ClusterTime::from_millis(2200));
    book.refresh_homes(ClusterTime::from_millis(2200));
    assert_eq!(book.fused_tag_of(TargetId(1)), None);
}

#[test]
fn the_server_is_told_each_tags_claim_and_an_empty_list_once() {
    let tracks = [track(1, 7.0, 6.0)];
    let tag = TagId(0xaa);
    let mut book = TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
    assert_eq!(book.tell(ClusterTime::ZERO), None, "nothing heard, nothing told");
    run_between(&mut book, &tracks, tag, Vector3::new(7.0, 6.0, 1.0), 0.0, 2.0);
    assert!(book.claims_changed(ClusterTime::from_millis(2000)));
    let told = book.tell(ClusterTime::from_millis(2000)).unwrap();
    assert_eq!(told[0].track, Some(TargetId(1)));
    assert_eq!(told[0].near, [10.0, 10.0], "the node nearest (7, 6)");
    assert!(!book.claims_changed(ClusterTime::from_millis(2000)));
    // Silence past the window: the list empties, told once.
    let later = ClusterTime::from_millis(2000) + LOUD_WINDOW_NS + 1;
    assert_eq!(book.tell(later), Some(Vec::new()));
    assert_eq!(book.tell(later), None);
}

#[test]
fn an_away_tag_gets_no_radio_track() {
    let mut book = TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
    let tag = TagId(0xbb);
    let heard = readings(&mut book, tag, Vector3::new(5.0, 5.0, 1.0), ClusterTime::ZERO);
    assert_eq!(book.unbound_in(&heard), vec![tag]);
    book.set_homes(
        &[TagHome {
            tag,
            head: NodeId(4),
            shared: false,
        }],
        ClusterTime::ZERO,
    );
    book.refresh_homes(ClusterTime::ZERO);
    assert!(book.unbound_in(&heard).is_empty());
}

#[test]
fn the_cluster_hears_a_tag_as_loud_as_its_loudest_node_lately() {
    let mut book = TagBook::default().for_head(NodeId(3), (0..4).map(|s| [node(s).x, node(s).y]).collect());
    let tag = TagId(5);
    let at = Vector3::new(1.0, 1.0, 1.0);
    for s in 0..5 {
        readings(&mut book, tag, at, ClusterTime::from_millis(200 * s));
    }
    let heard = book.loudest(ClusterTime::from_millis(800));
    let nearest = MODEL.predict((at - node(0)).norm()) as f32;
    assert_eq!(heard.len(), 1);
    assert_eq!(heard[0].tag, tag);
    assert!(
        (heard[0].dbm - nearest).abs() < 1e-3,
        "{} vs {nearest}",
        heard[0].dbm
    );
    // One loud reading moves the smoothed loudness by a quarter of the difference.
    book.offer(
        0,
        RssiReading {
            tag,
            dbm: f64::from(nearest) + 20.0,
            time: ClusterTime::from_millis(1000),
        },
        ClusterTime::from_millis(1000),
    );
    let heard = book.loudest(ClusterTime::from_millis(1000));
    assert!((heard[0].dbm - (nearest + 5.0)).abs() < 1e-3, "{}", heard[0].dbm);
    // Nothing heard in the window: the cluster does not hear it.
    assert!(
        book.loudest(ClusterTime::from_millis(1000) + LOUD_WINDOW_NS + 1)
            .is_empty()
    );
}

#[test]
fn a_tag_between_two_tracks_binds_to_neither() {
    // Two people 0.3 m apart: RSSI cannot tell them apart.
    let tracks = [track(1, 5.0, 5.0), track(2, 5.3, 5.0)];
    let mut book = TagBook::default();
    let changes = run(&mut book, &tracks, TagId(1), Vector3::new(5.15, 5.0, 1.0), 50);
    assert!(changes.is_empty(), "{changes:?}");
}

#[test]
fn a_tag_on_no_track_stays_unbound_and_a_bound_tag_that_leaves_is_unbound() {
    let tracks = [track(1, 1.0, 1.0)];
    let mut book = TagBook::default();
    let tag = TagId(3);
    assert!(run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30).is_empty());
    let mut book = TagBook::default();
    run(&mut book, &tracks, tag, Vector3::new(1.0, 1.0, 1.0), 10);
    assert_eq!(book.track_of(tag), Some(TargetId(1)));
    let changes = run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30);
    assert_eq!(
        changes,
        vec![Change::Unbound {
            tag,
            track: TargetId(1)
        }]
    );
}

#[test]
fn a_tag_moves_to_the_track_that_explains_it_and_a_track_holds_one_tag() {
    let mut tracks = vec![track(1, 2.0, 2.0), track(2, 8.0, 8.0)];
    let mut book = TagBook::default();
    let (a, b) = (TagId(1), TagId(2));
    run(&mut book, &tracks, a, Vector3::new(2.0, 2.0, 1.0), 10);
    assert_eq!(book.track_of(a), Some(TargetId(1)));
    // The camera tracks swap places (an identity switch): the tag follows its person.
    tracks[0] = track(1, 8.0, 2.0);
    tracks[1] = track(2, 2.0, 2.0);
    let changes = run(&mut book, &tracks, a, Vector3::new(2.0, 2.0, 1.0), 40);
    assert!(changes.contains(&Change::Moved {
        tag: a,
        from: TargetId(1),
        to: TargetId(2)
    }));
    // A second tag where track 2 is cannot take it while `a` holds it.
    run(&mut book, &tracks, b, Vector3::new(2.0, 2.0, 1.0), 20);
    assert_eq!(book.track_of(a), Some(TargetId(2)));
    assert_ne!(book.track_of(b), Some(TargetId(2)));
}

#[test]
fn a_reading_counts_once_and_a_flood_of_tags_is_bounded() {
    let mut book = TagBook::default();
    let r = RssiReading {
        tag: TagId(1),
        dbm: -60.0,
        time: ClusterTime::ZERO,
    };
    assert!(book.offer(0, r, ClusterTime::ZERO));
    assert!(!book.offer(0, r, ClusterTime::ZERO), "the same reading again");
    assert!(book.offer(1, r, ClusterTime::ZERO), "another node's");
    for g in 0..2 * MAX_TAGS as u64 {
        book.offer(
            0,
            RssiReading {
                tag: TagId(100 + g),
                ..r
            },
            ClusterTime::ZERO,
        );
    }
    assert_eq!(book.tags.len(), MAX_TAGS);
    assert_eq!(book.refused, MAX_TAGS as u64 + 1);
}

#[test]
fn a_tag_taken_over_in_a_merge_answers_to_the_evidence_and_a_step_of_readings_is_bounded() {
    let tracks = [track(1, 1.0, 1.0)];
    let mut book = TagBook::default();
    let tag = TagId(4);
    readings(&mut book, tag, Vector3::new(1.0, 1.0, 1.0), ClusterTime::ZERO);
    book.bind(tag, TargetId(2));
    book.merged(TargetId(2), TargetId(1));
    let changes = run(&mut book, &tracks, tag, Vector3::new(9.0, 9.0, 1.0), 30);
    assert!(
        changes.contains(&Change::Unbound {
            tag,
            track: TargetId(1)
        }),
        "a merge's binding is not for good: {changes:?}"
    );
    let mut book = TagBook::default();
    let n = MAX_READINGS_PER_STEP as i64 + 10;
    for k in 0..n {
        let r = RssiReading {
            tag,
            dbm: -60.0,
            time: ClusterTime(k),
        };
        book.offer(0, r, ClusterTime(n));
    }
    assert_eq!(book.queued().len(), MAX_READINGS_PER_STEP);
    assert_eq!(book.refused, 10);
}

#[test]
fn a_track_merged_away_hands_its_tag_to_the_kept_one() {
    let mut book = TagBook::default();
    let tag = TagId(9);
    readings(&mut book, tag, Vector3::new(2.0, 3.0, 1.0), ClusterTime::ZERO);
    book.bind(tag, TargetId(2));
    book.merged(TargetId(2), TargetId(1));
    assert_eq!(book.track_of(tag), Some(TargetId(1)));
}
