use super::*;
use crate::adaptive_background::AdaptiveBackgroundParams;
use crate::tracker::scene::{Person as Drawn, Scene};
use proto::ClusterTime;
use proto::sensor::rgb_to_hsi;

/// The frame rate the tests' trackers are told: the waits' defaults are 10 frames at it.
const FPS: f64 = 15.0;

fn red() -> Drawn {
    Drawn {
        shirt: [210, 40, 50],
        trousers: [40, 60, 160],
        size: [20.0, 40.0],
        start: [20.0, 60.0],
        velocity: [1.5, 0.3],
    }
}

fn green() -> Drawn {
    Drawn {
        shirt: [40, 200, 60],
        trousers: [150, 120, 20],
        size: [18.0, 36.0],
        start: [150.0, 30.0],
        velocity: [-1.0, 0.5],
    }
}

fn scene(people: Vec<Drawn>) -> Scene {
    Scene {
        width: 220,
        height: 160,
        people,
        noise: 6,
        fps: 15.0,
    }
}

/// A region as the background model reports it: inclusive pixel indices.
fn detection(b: &PixelBox) -> Detection {
    let bbox = PixelBox {
        xmin: b.xmin.ceil(),
        ymin: b.ymin.ceil(),
        xmax: b.xmax.floor(),
        ymax: b.ymax.floor(),
    };
    let (w, h) = (bbox.xmax - bbox.xmin + 1.0, bbox.ymax - bbox.ymin + 1.0);
    let cx = 0.5 * (bbox.xmin + bbox.xmax);
    Detection {
        centre: [cx, 0.5 * (bbox.ymin + bbox.ymax)],
        foot: [cx, bbox.ymax],
        bbox,
        area: (w * h) as u32,
        colour: rgb_to_hsi(0.0, 0.0, 0.0),
    }
}

fn centre(b: &PixelBox) -> [f32; 2] {
    [0.5 * (b.xmin + b.xmax), 0.5 * (b.ymin + b.ymax)]
}

fn distance(e: &PersonEstimate, b: &PixelBox) -> f32 {
    let c = centre(b);
    (e.mean.x - c[0]).hypot(e.mean.y - c[1])
}

fn input<'a>(frame: &'a Frame, regions: &'a [Detection]) -> TrackerInput<'a> {
    TrackerInput {
        frame,
        regions,
        foreground: None,
        with_samples: false,
    }
}

/// Red walks through all `frames` frames; green walks in at frame 10 and out at frame 40. Per
/// frame, `seen` gets the frame's index, the scene with both and the tracker's output; the
/// ids tracked after each frame come back.
fn green_walks_in_and_out(
    tracker: &mut MultiTracker,
    frames: u32,
    mut seen: impl FnMut(u32, &Scene, &[PersonEstimate]),
) -> Vec<Vec<LocalId>> {
    let (both, only_red) = (scene(vec![red(), green()]), scene(vec![red()]));
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut ids_at = Vec::new();
    for t in 0..frames {
        let s = if (10..40).contains(&t) { &both } else { &only_red };
        s.render(t, &mut frame);
        let regions: Vec<Detection> = (0..s.people.len()).map(|i| detection(&s.box_at(i, t))).collect();
        let out = tracker.step(&input(&frame, &regions)).unwrap();
        ids_at.push(tracker.ids());
        seen(t, &both, &out);
    }
    ids_at
}

/// The default destroy wait is 2/3 s: 10 frames for a camera at 15 fps, 3 at 5 fps.
#[test]
fn the_destroy_wait_is_a_time_so_a_slower_camera_waits_fewer_frames() {
    for (fps, frames) in [(15.0, 10), (5.0, 3)] {
        let mut tracker = MultiTracker::new(ParticleParams::default(), fps, 1).unwrap();
        let ids_at = green_walks_in_and_out(&mut tracker, 60, |_, _, _| {});
        let last_kept = 40 + frames - 2;
        assert_eq!(
            ids_at[last_kept],
            vec![0, 1],
            "{fps} fps: kept {} frames without a region",
            frames - 1
        );
        assert_eq!(
            ids_at[last_kept + 1],
            vec![0],
            "{fps} fps: destroyed on frame {frames} without one"
        );
    }
}

#[test]
fn people_who_enter_get_a_filter_and_one_who_leaves_loses_it_after_n_frames() {
    let params = ParticleParams {
        init_frames: 2,
        destroy_frames: Some(10),
        ..ParticleParams::default()
    };
    let mut tracker = MultiTracker::new(params, FPS, 1).unwrap();
    let ids_at = green_walks_in_and_out(&mut tracker, 70, |t, both, out| {
        // Identities stay on their people.
        if let Some(e) = out.iter().find(|e| e.id == 0) {
            assert!(
                distance(e, &both.box_at(0, t)) < 4.0,
                "frame {t}: red's filter off: {e:?}"
            );
        }
        if (13..40).contains(&t) {
            let e = out.iter().find(|e| e.id == 1).expect("green's filter");
            assert!(
                distance(e, &both.box_at(1, t)) < 4.0,
                "frame {t}: green's filter off"
            );
        }
    });
    assert!(
        ids_at[0].is_empty(),
        "a region must be seen init-frames = 2 frames"
    );
    assert_eq!(ids_at[1], vec![0]);
    assert_eq!(ids_at[10], vec![0]);
    assert_eq!(ids_at[11], vec![0, 1], "two people, two filters");
    assert_eq!(
        ids_at[48],
        vec![0, 1],
        "green left at 40: 9 frames without a region"
    );
    assert_eq!(
        ids_at[49],
        vec![0],
        "destroyed on the 10th frame without a region"
    );
    assert_eq!(ids_at[69], vec![0]);
    let c = tracker.counters();
    assert_eq!((c.started, c.destroyed, c.duplicates_eliminated), (2, 1, 0));
}

#[test]
fn a_duplicate_filter_on_one_region_is_eliminated_and_the_older_id_stays() {
    let params = ParticleParams {
        duplicate_frames: Some(10),
        ..ParticleParams::default()
    };
    let mut tracker = MultiTracker::new(params, FPS, 2).unwrap();
    let s = scene(vec![red()]);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    for t in 0..30u32 {
        s.render(t, &mut frame);
        let regions = [detection(&s.box_at(0, t))];
        let out = tracker.step(&input(&frame, &regions)).unwrap();
        if t == 5 {
            assert_eq!(tracker.ids(), vec![0]);
            let second = tracker.start(&frame, &s.box_at(0, t)).unwrap();
            assert_eq!(second, 1);
        }
        match t {
            6..=14 => assert_eq!(tracker.ids(), vec![0, 1], "frame {t}"),
            15.. => {
                assert_eq!(tracker.ids(), vec![0], "frame {t}: the younger is eliminated");
                assert!(distance(&out[0], &s.box_at(0, t)) < 4.0);
            }
            _ => {}
        }
    }
    let c = tracker.counters();
    assert_eq!((c.started, c.duplicates_eliminated, c.destroyed), (2, 1, 0));
}

/// Red alone in one region, a filter started on `fragment` (a box on part of red) and then
/// one on all of red, with `duplicate-frames` 5, tracked for 14 frames: the two filters' ids
/// and the ids alive after each frame.
fn a_fragment_then_the_person(
    fragment: impl Fn(PixelBox) -> PixelBox,
) -> (LocalId, LocalId, Vec<Vec<LocalId>>) {
    let s = scene(vec![red()]);
    let params = ParticleParams {
        duplicate_frames: Some(5),
        ..ParticleParams::default()
    };
    let mut tracker = MultiTracker::new(params, FPS, 7).unwrap();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    s.render(0, &mut frame);
    let whole = s.box_at(0, 0);
    let first = tracker.start(&frame, &fragment(whole)).unwrap();
    let person = tracker.start(&frame, &whole).unwrap();
    let mut alive = Vec::new();
    for t in 1..15u32 {
        s.render(t, &mut frame);
        tracker
            .step(&input(&frame, &[detection(&s.box_at(0, t))]))
            .unwrap();
        alive.push(tracker.ids());
    }
    assert_eq!(tracker.counters().duplicates_eliminated, 1);
    (first, person, alive)
}

#[test]
fn a_filter_on_part_of_anothers_person_is_eliminated_whatever_its_age() {
    // A filter on red's upper third (a fragment the region split off), then one on all of
    // red: their boxes are not alike (IoU a third, under the default 0.4), but one lies inside
    // the other in red's one region. The smaller goes, though it is the older.
    let (fragment, person, alive) = a_fragment_then_the_person(|whole| PixelBox {
        ymax: whole.ymin + (whole.ymax - whole.ymin) / 3.0,
        ..whole
    });
    assert_eq!(
        alive.last(),
        Some(&vec![person]),
        "fragment {fragment} eliminated"
    );
}

#[test]
fn a_filter_stacked_on_anothers_person_is_eliminated_whatever_its_age() {
    // A filter on red's legs and the floor below them (a fragment), then one on all of red:
    // their boxes share their columns but are not alike (IoU under the default 0.4) and
    // neither lies inside the other, so only the stacking rule finds them: both live until the
    // fifth frame, when the smaller goes (so they were stacked from the first).
    let legs = |whole: PixelBox| {
        let h = whole.ymax - whole.ymin;
        PixelBox {
            ymin: whole.ymin + 0.65 * h,
            ymax: whole.ymax + 0.35 * h,
            ..whole
        }
    };
    let whole = scene(vec![red()]).box_at(0, 0);
    assert!(overlap_of_smaller(&legs(whole), &whole) < NESTED_OVERLAP && iou(&legs(whole), &whole) < 0.4);
    let (fragment, person, alive) = a_fragment_then_the_person(legs);
    for (t, ids) in alive.iter().enumerate().take(4) {
        assert_eq!(ids, &vec![fragment, person], "frame {}", t + 1);
    }
    assert_eq!(
        alive.last(),
        Some(&vec![person]),
        "fragment {fragment} eliminated"
    );
}

#[test]
fn two_people_in_one_merged_region_keep_their_filters_unless_the_rule_is_literal() {
    // Red and green walk side by side, green `gap` px to the right of red's left edge; the
    // background model sees one region around both.
    let run = |duplicate_iou: f32, gap: f32| {
        let mut a = red();
        let mut b = green();
        a.start = [40.0, 60.0];
        b.start = [40.0 + gap, 62.0];
        a.velocity = [1.0, 0.0];
        b.velocity = [1.0, 0.0];
        let s = scene(vec![a, b]);
        let (p, q) = (s.box_at(0, 0), s.box_at(1, 0));
        assert!(column_overlap(&p, &q) < STACKED_COLUMNS);
        let params = ParticleParams {
            duplicate_iou,
            duplicate_frames: Some(10),
            ..ParticleParams::default()
        };
        let mut tracker = MultiTracker::new(params, FPS, 3).unwrap();
        let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
        s.render(0, &mut frame);
        tracker.start(&frame, &s.box_at(0, 0)).unwrap();
        tracker.start(&frame, &s.box_at(1, 0)).unwrap();
        for t in 1..25u32 {
            s.render(t, &mut frame);
            let (p, q) = (s.box_at(0, t), s.box_at(1, t));
            let merged = PixelBox {
                xmin: p.xmin.min(q.xmin),
                ymin: p.ymin.min(q.ymin),
                xmax: p.xmax.max(q.xmax),
                ymax: p.ymax.max(q.ymax),
            };
            tracker.step(&input(&frame, &[detection(&merged)])).unwrap();
        }
        tracker.ids()
    };
    assert_eq!(
        run(0.4, 21.0),
        vec![0, 1],
        "their boxes do not overlap: two people"
    );
    assert_eq!(
        run(0.4, 14.0),
        vec![0, 1],
        "green hides a third of red's columns (below the stacking rule's share): still two people"
    );
    assert_eq!(
        run(0.0, 21.0),
        vec![0],
        "the paper's literal rule keeps one filter per region"
    );
}

#[test]
fn with_the_background_model_it_tracks_two_people_and_reports_their_foreground() {
    let s = scene(vec![red(), green()]);
    let empty = scene(vec![]);
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams::default());
    let mut tracker = MultiTracker::new(ParticleParams::default(), FPS, 4).unwrap();
    let (mut frame, mut regions) = (Frame::new(1, 1, ClusterTime::ZERO), Vec::new());
    empty.render(0, &mut frame);
    seg.process(&frame, &mut regions).unwrap();
    let mut last = Vec::new();
    for t in 1..40u32 {
        s.render(t, &mut frame);
        seg.process(&frame, &mut regions).unwrap();
        let inp = TrackerInput {
            frame: &frame,
            regions: &regions,
            foreground: Foreground::of(&seg),
            with_samples: false,
        };
        last = tracker.step(&inp).unwrap();
    }
    assert_eq!(tracker.ids(), vec![0, 1], "{last:?}");
    // Each person has one filter on them (ids in the order the regions were found).
    for i in 0..2 {
        let truth = s.box_at(i, 39);
        let e = last
            .iter()
            .min_by(|a, b| distance(a, &truth).total_cmp(&distance(b, &truth)))
            .unwrap();
        let d = distance(e, &truth);
        assert!(d < 4.0, "person {i}: {d:.1} px off");
        let fg = e.foreground.unwrap();
        assert!(fg > 0.6, "person {i}: foreground under the box {fg}");
        let h = truth.ymax - truth.ymin;
        assert!(
            (e.mean.h - h).abs() < 0.2 * h,
            "person {i}: height {} of {h}",
            e.mean.h
        );
    }
}

#[test]
fn samples_only_on_request() {
    let s = scene(vec![red()]);
    let mut tracker = MultiTracker::new(ParticleParams::default(), FPS, 5).unwrap();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    for t in 0..3u32 {
        s.render(t, &mut frame);
        let regions = [detection(&s.box_at(0, t))];
        let out = tracker
            .step(&TrackerInput {
                with_samples: t == 2,
                ..input(&frame, &regions)
            })
            .unwrap();
        if t == 1 {
            assert!(out[0].samples.is_empty());
        }
        if t == 2 {
            assert_eq!(out[0].samples.len(), 100);
            let total: f32 = out[0].samples.iter().map(|x| x.weight).sum();
            assert!((total - 1.0).abs() < 1e-4);
        }
    }
}

#[test]
fn bad_input_is_rejected_and_changes_nothing() {
    let s = scene(vec![red(), green()]);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut clean = MultiTracker::new(ParticleParams::default(), FPS, 6).unwrap();
    let mut poked = MultiTracker::new(ParticleParams::default(), FPS, 6).unwrap();
    for t in 0..12u32 {
        s.render(t, &mut frame);
        let regions: Vec<Detection> = (0..2).map(|i| detection(&s.box_at(i, t))).collect();
        if t == 6 {
            let mut bad = regions.clone();
            bad[1].bbox.xmax = f32::NAN;
            let err = poked.step(&input(&frame, &bad)).unwrap_err();
            assert!(matches!(err, TrackerError::Region { index: 1, .. }), "{err}");
            let small = Frame::new(100, 80, frame.captured);
            let err = poked.step(&input(&small, &regions)).unwrap_err();
            assert!(
                matches!(err, TrackerError::Frame(FrameError::Mismatch { .. })),
                "{err}"
            );
            let mask = vec![0u8; 50 * 40];
            let grid = Grid::new(100, 80, 2);
            let fg = Foreground::new(&mask, grid).unwrap();
            let err = poked
                .step(&TrackerInput {
                    foreground: Some(fg),
                    ..input(&frame, &regions)
                })
                .unwrap_err();
            assert!(matches!(err, TrackerError::MaskGrid { .. }), "{err}");
            let err = poked.start(
                &frame,
                &PixelBox {
                    xmin: -50.0,
                    ymin: -50.0,
                    xmax: -10.0,
                    ymax: -10.0,
                },
            );
            assert!(matches!(err, Err(TrackerError::EmptyBox(_))));
        }
        let a = clean.step(&input(&frame, &regions)).unwrap();
        let b = poked.step(&input(&frame, &regions)).unwrap();
        assert_eq!(a, b, "frame {t}");
    }
    assert_eq!(clean.counters(), poked.counters());
}

#[test]
fn foreground_share_under_a_box() {
    // A 20×20 frame on a step-2 grid (10×10); a 2×2 grid block set.
    let grid = Grid::new(20, 20, 2);
    let mut mask = vec![0u8; 100];
    for (x, y) in [(2, 2), (3, 2), (2, 3), (3, 3)] {
        mask[y * 10 + x] = 1;
    }
    let fg = Foreground::new(&mask, grid).unwrap();
    // Frame pixels 4..=10 cover grid columns and rows 2..=5: 4 of 16 set.
    let b = PixelBox {
        xmin: 4.0,
        ymin: 4.0,
        xmax: 10.0,
        ymax: 10.0,
    };
    assert!((fg.fraction(&b) - 0.25).abs() < 1e-6);
    let outside = PixelBox {
        xmin: 30.0,
        ymin: 0.0,
        xmax: 40.0,
        ymax: 5.0,
    };
    assert_eq!(fg.fraction(&outside), 0.0);
    assert!(matches!(
        Foreground::new(&mask[..99], grid),
        Err(TrackerError::Mask {
            got: 99,
            want: 100,
            ..
        })
    ));
}

#[test]
fn max_people_refuses_and_counts_the_rest() {
    let params = ParticleParams {
        max_people: 1,
        init_frames: 1,
        ..ParticleParams::default()
    };
    let mut tracker = MultiTracker::new(params, FPS, 7).unwrap();
    let s = scene(vec![red(), green()]);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    s.render(0, &mut frame);
    let regions: Vec<Detection> = (0..2).map(|i| detection(&s.box_at(i, 0))).collect();
    tracker.step(&input(&frame, &regions)).unwrap();
    assert_eq!(tracker.ids().len(), 1);
    assert_eq!(tracker.counters().refused_full, 1);
    assert!(matches!(
        tracker.start(&frame, &s.box_at(1, 0)),
        Err(TrackerError::Full(1))
    ));
    let bad = ParticleParams {
        particles: 0,
        ..ParticleParams::default()
    };
    assert_eq!(MultiTracker::new(bad, FPS, 0).unwrap_err().field, "particles");
}

#[test]
fn reset_accepts_a_new_resolution_and_never_reuses_an_id() {
    let mut tracker = MultiTracker::new(ParticleParams::default(), FPS, 8).unwrap();
    let s = scene(vec![red()]);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    for t in 0..3u32 {
        s.render(t, &mut frame);
        tracker
            .step(&input(&frame, &[detection(&s.box_at(0, t))]))
            .unwrap();
    }
    assert_eq!(tracker.ids(), vec![0]);
    let smaller = Scene {
        width: 160,
        height: 120,
        ..s.clone()
    };
    smaller.render(3, &mut frame);
    let regions = [detection(&smaller.box_at(0, 3))];
    assert!(tracker.step(&input(&frame, &regions)).is_err());
    tracker.reset();
    assert!(tracker.ids().is_empty());
    for t in 3..6u32 {
        smaller.render(t, &mut frame);
        tracker
            .step(&input(&frame, &[detection(&smaller.box_at(0, t))]))
            .unwrap();
    }
    assert_eq!(tracker.ids(), vec![1]);
}

#[test]
fn of_two_duplicates_the_one_that_drifted_onto_someone_else_gives_way() {
    // Filter 0 learned a green person; it sits on the red person's region, where filter 1
    // (red's own) also is. Filter 0 matches clearly worse there, so it goes, though older.
    let params = ParticleParams {
        duplicate_frames: Some(8),
        ..ParticleParams::default()
    };
    let mut tracker = MultiTracker::new(params, FPS, 9).unwrap();
    let still = Drawn {
        velocity: [0.0, 0.0],
        ..red()
    };
    let s = scene(vec![still.clone()]);
    let in_green = scene(vec![Drawn {
        shirt: [40, 200, 60],
        trousers: [150, 120, 20],
        ..still
    }]);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let b = s.box_at(0, 0);
    in_green.render(0, &mut frame);
    assert_eq!(tracker.start(&frame, &b).unwrap(), 0);
    s.render(1, &mut frame);
    tracker.step(&input(&frame, &[detection(&b)])).unwrap();
    assert_eq!(tracker.start(&frame, &b).unwrap(), 1);
    for t in 2..20u32 {
        s.render(t, &mut frame);
        tracker.step(&input(&frame, &[detection(&b)])).unwrap();
    }
    assert_eq!(tracker.ids(), vec![1]);
    assert_eq!(tracker.counters().duplicates_eliminated, 1);
}

/// A grey pillar over columns `columns` of every frame.
fn pillar(frame: &mut Frame, columns: (f32, f32)) {
    let full = PixelBox {
        xmin: columns.0,
        ymin: 0.0,
        xmax: columns.1,
        ymax: frame.height as f32,
    };
    crate::tracker::scene::fill_box(frame, &full, [128, 128, 128]);
}

/// The visible parts of `b` on either side of a pillar over `columns`, as regions.
fn beside_pillar(b: &PixelBox, columns: (f32, f32)) -> Vec<Detection> {
    let left = PixelBox {
        xmax: b.xmax.min(columns.0 - 1.0),
        ..*b
    };
    let right = PixelBox {
        xmin: b.xmin.max(columns.1 + 1.0),
        ..*b
    };
    [left, right]
        .iter()
        .filter(|p| p.xmax - p.xmin >= 1.0)
        .map(detection)
        .collect()
}

#[test]
fn a_person_a_pillar_splits_in_two_keeps_one_filter_on_their_whole_outline() {
    // Red (20 px wide) walks behind an 8 px pillar from frame 14 to 32: first a strip of them
    // shows on its far side, then two strips, then one on its near side.
    const PILLAR: (f32, f32) = (60.0, 68.0);
    let s = scene(vec![red()]);
    let mut tracker = MultiTracker::new(ParticleParams::default(), FPS, 11).unwrap();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut split = 0;
    for t in 0..45u32 {
        s.render(t, &mut frame);
        pillar(&mut frame, PILLAR);
        let truth = s.box_at(0, t);
        let regions = beside_pillar(&truth, PILLAR);
        split += usize::from(regions.len() == 2);
        let out = tracker.step(&input(&frame, &regions)).unwrap();
        if t >= 1 {
            assert_eq!(tracker.ids(), vec![0], "frame {t}: one person, one filter");
        }
        // A filter's region is known from its first step after the one that started it.
        if t >= 2 {
            let e = &out[0];
            // Within 0.4 of red's width: on them, though the pillar hides up to 0.4 of them.
            assert!(
                distance(e, &truth) < 8.0,
                "frame {t}: the filter left its person: {e:?}"
            );
            assert!(
                e.region.is_some(),
                "frame {t}: its parts no longer support the filter"
            );
        }
    }
    assert!(split >= 5, "the pillar split red in {split} frames");
    assert!(
        tracker.counters().refused_fragments > 0,
        "no strip was taken for a new person"
    );
}

#[test]
fn a_strip_beside_a_person_starts_a_filter_only_in_other_colours() {
    // Red stands left of a pillar; someone stands behind it, a 7 px strip of them showing
    // between the two. In green, that is a second person; in red's colours, a part of red.
    const PILLAR: (f32, f32) = (69.0, 90.0);
    let still = |p: Drawn, x: f32| Drawn {
        start: [x, 60.0],
        velocity: [0.0, 0.0],
        size: [20.0, 40.0],
        ..p
    };
    for (behind, people) in [(green(), 2), (red(), 1)] {
        let s = scene(vec![still(red(), 40.0), still(behind, 62.0)]);
        let mut tracker = MultiTracker::new(ParticleParams::default(), FPS, 12).unwrap();
        let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
        for t in 0..6u32 {
            s.render(t, &mut frame);
            pillar(&mut frame, PILLAR);
            // The strip first: births are tried largest first, whatever the regions' order.
            let mut regions = beside_pillar(&s.box_at(1, t), PILLAR);
            regions.push(detection(&s.box_at(0, t)));
            tracker.step(&input(&frame, &regions)).unwrap();
        }
        assert_eq!(tracker.ids().len(), people, "{people} filter(s)");
        assert_eq!(tracker.counters().refused_fragments > 0, people == 1);
    }
}

#[test]
fn a_person_whose_middle_a_pillar_hides_is_their_two_strips_together() {
    // Red at rest, 20 px wide; a 16 px pillar leaves 2 px of them on either side, too little
    // for either strip alone to support their box.
    let s = scene(vec![Drawn {
        velocity: [0.0, 0.0],
        ..red()
    }]);
    let person = s.box_at(0, 0);
    let columns = (person.xmin + 2.0, person.xmin + 18.0);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    s.render(0, &mut frame);
    let p = ParticleParams::default();
    let mut image = BinImage::new();
    let target = box_histogram(&mut image.bind(&frame).unwrap(), &person, &p).unwrap();
    pillar(&mut frame, columns);
    let regions: Vec<PixelBox> = beside_pillar(&person, columns).iter().map(region_box).collect();
    assert_eq!(regions.len(), 2);
    assert_eq!(best_region(&person, &regions, p.support_iou), None);
    let mut bins = image.bind(&frame).unwrap();
    let (i, roi) = parts_beside(&person, &regions, &target, &mut bins, &p).expect("a region");
    assert_eq!(roi, union(&regions[0], &regions[1]));
    // Equal overlaps with the box: the first part stands for them.
    assert_eq!(i, 0);
    assert!(supports(&roi, &person, p.support_iou));
    // Two whole people in red's colours either side of a lost filter's box are not its parts.
    let side = |dx: f32| PixelBox {
        xmin: person.xmin + dx,
        xmax: person.xmax + dx,
        ..person
    };
    let people = [side(-21.0), side(21.0)];
    let at = |b: &PixelBox| Drawn {
        velocity: [0.0, 0.0],
        start: [b.xmin, b.ymin],
        ..red()
    };
    let mut two = Frame::new(1, 1, ClusterTime::ZERO);
    scene(people.iter().map(at).collect()).render(0, &mut two);
    assert_eq!(best_region(&person, &people, p.support_iou), None);
    let mut bins = image.bind(&two).unwrap();
    assert_eq!(parts_beside(&person, &people, &target, &mut bins, &p), None);
    // Strips of other colours are no part of them.
    let mut green_frame = Frame::new(1, 1, ClusterTime::ZERO);
    let green_there = Drawn {
        velocity: [0.0, 0.0],
        start: red().start,
        size: red().size,
        ..green()
    };
    scene(vec![green_there]).render(0, &mut green_frame);
    let green = box_histogram(&mut BinImage::new().bind(&green_frame).unwrap(), &person, &p).unwrap();
    assert_eq!(parts_beside(&person, &regions, &green, &mut bins, &p), None);
}
