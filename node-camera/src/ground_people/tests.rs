use super::*;
use proto::models::State;
use proto::msg::PixelBox;
use proto::scenario::Scenario;

fn person(x: f64, y: f64) -> GroundPoint {
    GroundPoint {
        local: 0,
        position: [x, y],
        cov: [0.04, 0.0, 0.04],
        width_m: 0.5,
        height_m: 1.8,
        confidence: 0.5,
        histogram: Vec::new(),
        captured: ClusterTime::ZERO,
        ml_position: [x, y],
    }
}

fn prior(x: f64, y: f64) -> Prior {
    Prior {
        target: TargetId(1),
        step: 1,
        mean: models::vec6_to_wire(&State::new(x, y, 0.9, 0.0, 0.0, 0.0)),
        cov: models::mat6_to_wire(&(nalgebra::Matrix6::identity() * 0.05)),
        deadline: ClusterTime::ZERO,
        radio: false,
    }
}

#[test]
fn ground_points_gate_one_to_one_in_the_floor_plane() {
    let (a, b) = (prior(2.0, 2.0), prior(5.0, 3.0));
    let people = [person(5.1, 3.0), person(2.0, 2.1), person(9.0, 1.0)];
    let got = associate(&[(&a, 0.0), (&b, 0.0)], &people, 13.8);
    assert_eq!(got, vec![Some(1), Some(0), None]);
    let joint = |priors: &[(&Prior, f64)], of| {
        crate::measure::joint_choices(priors, &people, 13.8, gate_distance2)[of]
    };
    assert_eq!(joint(&[(&a, 0.0), (&b, 0.0)], 0), Some(&people[1]));
    let far = prior(7.0, 6.0);
    assert_eq!(joint(&[(&far, 0.0)], 0), None);
}

#[test]
fn joint_answers_give_two_close_tracks_two_people() {
    // Track a is nearer person 0 than person 1, but b gates only person 0: the nearest-first
    // answer would give a person 0 and b nobody.
    let (a, b) = (prior(2.0, 2.0), prior(2.9, 2.0));
    let people = [person(2.4, 2.0), person(1.5, 2.0)];
    let priors = [(&a, 0.0), (&b, 0.0)];
    let joint = |of: usize| crate::measure::joint_choices(&priors, &people, 13.8, gate_distance2)[of];
    assert!(gate_distance2(&a, &people[0], 0.0) < gate_distance2(&a, &people[1], 0.0));
    assert_eq!(gate_distance2(&b, &people[1], 0.0).filter(|d| *d <= 13.8), None);
    assert_eq!(joint(0), Some(&people[1]));
    assert_eq!(joint(1), Some(&people[0]));
}

#[test]
fn a_prior_the_pairing_leaves_without_a_person_gets_nothing() {
    // Two tracks, one person in view (the other hidden, or merged into this one's region): the
    // nearer track takes the person, the other coasts rather than take its neighbour's.
    let (a, b) = (prior(2.0, 2.0), prior(2.3, 2.0));
    let people = [person(2.1, 2.0)];
    let priors = [(&a, 0.0), (&b, 0.0)];
    let joint = |of: usize| crate::measure::joint_choices(&priors, &people, 13.8, gate_distance2)[of];
    assert!(
        gate_distance2(&b, &people[0], 0.0).is_some_and(|d| d <= 13.8),
        "b gates the person"
    );
    assert_eq!(joint(0), Some(&people[0]));
    assert_eq!(joint(1), None);
    // Alone, b takes the person.
    assert_eq!(
        crate::measure::joint_choices(&[(&b, 0.0)], &people, 13.8, gate_distance2)[0],
        Some(&people[0])
    );
}

#[test]
fn a_contribution_carries_the_gated_person_for_the_head_to_fold_in() {
    let p = prior(2.0, 2.0);
    let g = person(2.1, 2.0);
    let c = contribution(&p, Some(&g), false).expect("a contribution");
    assert!(c.folded.is_empty() && c.info.is_none(), "nothing folded here");
    assert!(c.camera());
    let q = c.ground.as_ref().expect("the person");
    assert_eq!((q.local, q.target), (g.local, None));
    // The information the head gets from it is what folding it here gave, to the quantisation.
    let mean = models::vec6_from_wire(&p.mean);
    let fold = |position: [f64; 2], cov: [f64; 3]| {
        let (p, c) = (
            Vector2::from(position),
            Matrix2::new(cov[0], cov[1], cov[1], cov[2]),
        );
        models::ground_contribution_aged(&p, &c, &mean, 0.1).unwrap()
    };
    let back = q.point(ClusterTime::ZERO);
    let (o, x) = fold(g.position, g.cov);
    let (oq, xq) = fold(back.position, back.cov);
    assert!((o - oq).norm() <= 1e-2 * o.norm(), "{o} vs {oq}");
    assert!((x - xq).norm() <= 1e-2 * x.norm(), "{x} vs {xq}");
    assert!((back.height_m - g.height_m).abs() <= 0.005);
    assert_eq!(contribution(&p, None, false), None, "nothing to send");
    // An impossible person is not sent either.
    let mut bad = g.clone();
    bad.position[0] = f64::NAN;
    assert_eq!(contribution(&p, Some(&bad), false), None);
}

#[test]
fn projected_boxes_become_ground_points_and_boxes_above_the_horizon_are_dropped() {
    let cam = Scenario::default_scenario().camera_model(10).unwrap();
    let mut people = GroundPeople::new(&ParticleParams::default(), 15.0, 1).unwrap();
    let det = |ymin: f32, ymax: f32| Detection {
        centre: [176.0, 0.5 * (ymin + ymax)],
        foot: [176.0, ymax],
        bbox: PixelBox {
            xmin: 160.0,
            ymin,
            xmax: 192.0,
            ymax,
        },
        area: 1000,
        colour: proto::msg::ColourSignature {
            hue: 0.0,
            saturation: 0.0,
            intensity: 0.5,
        },
    };
    people.from_boxes(&cam, &[det(120.0, 200.0), det(-400.0, -300.0)], ClusterTime::ZERO);
    assert_eq!(people.latest().len(), 1);
    let g = &people.latest()[0];
    assert!(g.histogram.is_empty() && g.width_m > 0.0 && g.height_m > 0.0);
    assert!(g.cov[0] >= GROUND_POSITION_FLOOR_M2);
    assert!(
        people.samples(None).is_empty(),
        "no filters run on projected boxes"
    );
}

fn at_ms(ms: i64) -> ClusterTime {
    ClusterTime(ms * 1_000_000)
}

/// Frames at `fps` for `seconds`: the capture times the sender lets through, ms.
fn sent_frames(fps: f64, seconds: f64, step_ms: u64) -> Vec<i64> {
    let mut s = PeopleSender::new(step_ms, 0.7);
    let n = (fps * seconds).round() as usize;
    (0..n)
        .map(|k| (k as f64 * 1000.0 / fps).round() as i64)
        .filter(|&ms| s.due(at_ms(ms)))
        .collect()
}

#[test]
fn people_go_out_once_per_head_step_whatever_the_frame_rate() {
    // As fast as the steps: every frame; three times faster: every third, on the steps.
    assert_eq!(sent_frames(5.0, 2.0, 200).len(), 10);
    let fast = sent_frames(15.0, 2.0, 200);
    assert_eq!(fast.len(), 10, "{fast:?}");
    assert!(
        fast.windows(2).all(|w| (w[1] - w[0] - 200).abs() <= 1),
        "{fast:?}"
    );
    // Between the two: still one per step on average, never two within half a step.
    let seven = sent_frames(7.0, 10.0, 200);
    assert!((49..=51).contains(&seven.len()), "{} frames in 10 s", seven.len());
    assert!(seven.windows(2).all(|w| w[1] - w[0] >= 100), "{seven:?}");
    // Slower than the steps: every frame.
    assert_eq!(sent_frames(2.0, 5.0, 200).len(), 10);
    // After a gap (the camera was off) the next frame goes at once and the cadence restarts.
    let mut s = PeopleSender::new(200, 0.7);
    assert!(s.due(at_ms(0)));
    assert!(!s.due(at_ms(67)));
    assert!(s.due(at_ms(5_000)));
    assert!(!s.due(at_ms(5_067)) && !s.due(at_ms(5_133)) && s.due(at_ms(5_200)));
}

fn coloured(local: u32, hue_bin: usize) -> GroundPoint {
    let mut h = vec![0.0f32; HISTOGRAM_BINS];
    h[hue_bin] = 0.8;
    h[hue_bin + 1] = 0.2;
    h[HISTOGRAM_HS_BINS + 5] = 1.0;
    GroundPoint {
        local,
        histogram: h,
        ..person(2.0, 3.0)
    }
}

fn histograms_sent(s: &mut PeopleSender, ms: i64, people: &[GroundPoint]) -> Vec<u32> {
    s.frame(
        at_ms(ms),
        Mode::Active,
        people.iter().map(|p| (p, None)),
        Vec::new(),
    )
    .people
    .iter()
    .filter(|p| p.histogram.is_some())
    .map(|p| p.local)
    .collect()
}

#[test]
fn a_histogram_goes_with_a_new_person_then_when_it_changed_or_is_old() {
    let mut s = PeopleSender::new(200, 0.7);
    let (a, b) = (coloured(1, 20), coloured(2, 50));
    assert_eq!(
        histograms_sent(&mut s, 0, std::slice::from_ref(&a)),
        vec![1],
        "new"
    );
    assert!(histograms_sent(&mut s, 200, std::slice::from_ref(&a)).is_empty());
    assert_eq!(
        histograms_sent(&mut s, 400, &[a.clone(), b.clone()]),
        vec![2],
        "new"
    );
    // Person 1 changes colour: not again before two seconds, then at once.
    let a2 = coloured(1, 60);
    assert!(histogram_distance(&a.histogram, &a2.histogram, 0.7) > HISTOGRAM_CHANGE);
    assert!(histograms_sent(&mut s, 1_800, &[a2.clone(), b.clone()]).is_empty());
    assert_eq!(histograms_sent(&mut s, 2_000, &[a2.clone(), b.clone()]), vec![1]);
    // Unchanged: again only after the refresh period.
    assert!(histograms_sent(&mut s, 10_200, &[a2.clone(), b.clone()]).is_empty());
    assert_eq!(
        histograms_sent(&mut s, 10_400, &[a2.clone(), b.clone()]),
        vec![2],
        "refresh"
    );
    // A person no longer tracked is forgotten: back, it is new.
    s.retain(&[2]);
    assert_eq!(histograms_sent(&mut s, 10_600, &[a2.clone(), b.clone()]), vec![1]);
    // A person without a histogram (projected boxes) goes without one.
    assert!(histograms_sent(&mut s, 10_800, &[person(1.0, 1.0)]).is_empty());
}

#[test]
fn a_frame_carries_every_person_quantised_and_leaves_out_impossible_ones() {
    let mut s = PeopleSender::new(200, 0.7);
    let mut bad = person(1.0, 1.0);
    bad.position[0] = f64::NAN;
    bad.local = 7;
    let good = coloured(3, 20);
    let mut broken_colour = coloured(4, 30);
    broken_colour.histogram[0] = f32::NAN;
    let frame = s.frame(
        at_ms(40),
        Mode::Active,
        [(&good, Some(TargetId(9))), (&bad, None), (&broken_colour, None)],
        Vec::new(),
    );
    assert_eq!(frame.captured, at_ms(40));
    let locals: Vec<u32> = frame.people.iter().map(|p| p.local).collect();
    assert_eq!(locals, vec![3, 4], "the NaN position left out");
    assert_eq!(frame.people[0].target, Some(TargetId(9)));
    assert!(frame.people[0].histogram.is_some());
    assert!(
        frame.people[1].histogram.is_none(),
        "sent without its broken histogram"
    );
    assert_eq!(s.unsendable(), 1);
    let back = frame.people[0].point(frame.captured);
    assert!((back.position[0] - good.position[0]).abs() <= 0.005);
    assert!(histogram_distance(&back.histogram, &good.histogram, 0.7) < 0.03);
    // What the camera builds is what the wire takes.
    let env = proto::Envelope {
        source: proto::NodeId(10),
        seq: 1,
        time: at_ms(41),
        body: proto::Message::PeopleFrame(frame),
    };
    assert_eq!(proto::decode(&proto::encode(&env).unwrap()).unwrap(), env);
}

#[test]
fn a_filter_that_lost_its_region_leaving_through_a_border_walked_out() {
    let frame = Frame::new(352, 288, ClusterTime::ZERO);
    let at = |id: u32, xmin: f32, xmax: f32, ymax: f32, v: [f32; 2], region: Option<usize>| {
        let mut p = PersonEstimate::at_box(
            id,
            PixelBox {
                xmin,
                ymin: 100.0,
                xmax,
                ymax,
            },
            region,
        );
        (p.mean.vx, p.mean.vy) = (v[0], v[1]);
        p
    };
    let walked = [
        at(0, 330.0, 352.0, 200.0, [2.0, 0.0], None),
        at(1, -3.0, 20.0, 200.0, [-1.0, 0.5], None),
        at(2, 150.0, 180.0, 288.0, [0.0, 1.5], None),
        // A quarter or more of the box past the border, whatever the velocity (held there by
        // the part of its person still in view while they stepped out).
        at(7, 330.0, 370.0, 200.0, [0.0, 0.0], None),
        at(8, -12.0, 28.0, 200.0, [0.5, 0.0], None),
    ];
    for p in &walked {
        assert!(walked_out_of_view(p, &frame), "{}: no region, moving out", p.id);
    }
    let stayed = [
        // Still supported at the border: walking out, but measured.
        at(3, 330.0, 352.0, 200.0, [2.0, 0.0], Some(0)),
        // No region inside the frame: hidden (behind a pillar), still reported.
        at(4, 150.0, 180.0, 200.0, [2.0, 0.0], None),
        // No region at the bottom border, standing (faded into the background) or walking in.
        at(5, 150.0, 180.0, 288.0, [0.0, 0.1], None),
        at(6, 330.0, 352.0, 200.0, [-1.0, 0.0], None),
        // Less than a quarter past the border, standing: someone at the edge of the view.
        at(9, 320.0, 360.0, 200.0, [0.0, 0.0], None),
        // Past the border but still supported.
        at(10, 330.0, 370.0, 200.0, [0.0, 0.0], Some(0)),
    ];
    for p in &stayed {
        assert!(!walked_out_of_view(p, &frame), "{}", p.id);
    }
}

/// A distributed camera answers a prior with the person gated to it: the person's colours go
/// with that contribution by the same policy as with a people frame (new, then changed or
/// old), so the head's track has an appearance for the server's identity.
#[test]
fn a_contribution_carries_the_colours_by_the_people_frames_policy() {
    let mut s = PeopleSender::new(200, 0.7);
    let a = coloured(1, 20);
    let p = prior(2.0, 3.0);
    let answer = |s: &mut PeopleSender, ms: i64| {
        let with = s.histogram_due(at_ms(ms), &a);
        let c = contribution(&p, Some(&a), with).expect("a contribution");
        let g = c.ground.expect("a ground person");
        if let Some(h) = &g.histogram {
            s.sent(g.local, at_ms(ms), h);
        }
        g.histogram.is_some()
    };
    assert!(answer(&mut s, 0), "new");
    assert!(!answer(&mut s, 200), "sent already");
    // The contribution counted as sent: a people frame that carries the person does not send
    // the colours again.
    assert!(histograms_sent(&mut s, 400, std::slice::from_ref(&a)).is_empty());
    assert!(answer(&mut s, 10_000), "refresh");
    // Without a histogram (projected boxes) or not due: the person goes without one.
    assert!(
        contribution(&p, Some(&person(2.0, 3.0)), true)
            .unwrap()
            .ground
            .unwrap()
            .histogram
            .is_none()
    );
    assert!(
        contribution(&p, Some(&a), false)
            .unwrap()
            .ground
            .unwrap()
            .histogram
            .is_none()
    );
}

/// A red person on a grey floor, with the region the background model would give them, then
/// the region gone (they walked on out of its reach, or the model took them in): with
/// `report-unsupported` (paper 004, the default) the filter is still reported where it stands;
/// without it, it lives on unreported, and is reported again once a region supports it.
#[test]
fn a_filter_no_region_supports_is_reported_only_with_report_unsupported() {
    let cam = Scenario::default_scenario().camera_model(10).unwrap();
    let bbox = PixelBox {
        xmin: 160.0,
        ymin: 120.0,
        xmax: 192.0,
        ymax: 200.0,
    };
    let mut frame = Frame::new(352, 288, ClusterTime::ZERO);
    for y in 0..288u32 {
        for x in 0..352u32 {
            let inside = (160..=192).contains(&x) && (120..=200).contains(&y);
            let i = 3 * (y * 352 + x) as usize;
            frame.data[i..i + 3].copy_from_slice(if inside { &[200, 30, 30] } else { &[110, 110, 110] });
        }
    }
    let region = Detection {
        centre: [176.0, 160.0],
        foot: [176.0, 200.0],
        bbox,
        area: 33 * 81,
        colour: proto::msg::ColourSignature {
            hue: 0.0,
            saturation: 0.8,
            intensity: 0.5,
        },
    };
    let mut reported = |report_unsupported: bool| -> Vec<usize> {
        let params = ParticleParams {
            report_unsupported,
            ..ParticleParams::default()
        };
        let mut people = GroundPeople::new(&params, 15.0, 1).unwrap();
        let mut counts = Vec::new();
        for k in 0..8 {
            // Frames 0–3 with the region, 4–5 without (fewer than the destroy wait), 6–7 with.
            let regions: &[Detection] = if (4..6).contains(&k) {
                &[]
            } else {
                std::slice::from_ref(&region)
            };
            frame.captured = at_ms(k * 67);
            counts.push(people.track(&cam, &frame, regions, None).unwrap().len());
        }
        assert_eq!(people.tracker().ids().len(), 1, "one filter throughout");
        let withheld = people.counters().withheld;
        assert_eq!(withheld.unsupported, if report_unsupported { 0 } else { 2 });
        assert_eq!(people.counters().tracker.started, 1);
        counts
    };
    assert_eq!(reported(true), vec![0, 1, 1, 1, 1, 1, 1, 1]);
    assert_eq!(reported(false), vec![0, 1, 1, 1, 0, 0, 1, 1]);
}

/// A red person walks out through the right border: their region shrinks to the part still in
/// view, then goes. Their filter is not reported after it lost the region, though it lives on
/// for `destroy-s` and its box, held by nothing, drifts; when the person stands back in view,
/// a filter is reported once a region supports it.
#[test]
fn a_filter_whose_person_walked_out_stays_unreported_until_a_region_supports_it() {
    let cam = Scenario::default_scenario().camera_model(10).unwrap();
    let (w, h) = (352u32, 288u32);
    // Out at 5 px per frame (gone from frame 20), 9 frames gone (under the 10-frame destroy
    // wait), then standing at the right of the view.
    let left_edge = |k: i64| if k < 29 { 250.0 + 5.0 * k as f32 } else { 300.0 };
    for seed in 0..8 {
        let mut people = GroundPeople::new(&ParticleParams::default(), 15.0, seed).unwrap();
        let mut frame = Frame::new(w, h, ClusterTime::ZERO);
        let mut reported_back = false;
        for k in 0..45i64 {
            let xmin = left_edge(k);
            let visible = PixelBox {
                xmin,
                ymin: 120.0,
                xmax: (xmin + 36.0).min(w as f32 - 1.0),
                ymax: 220.0,
            };
            for y in 0..h {
                for x in 0..w {
                    let inside =
                        x as f32 >= visible.xmin && x as f32 <= visible.xmax && (120..=220).contains(&y);
                    let i = 3 * (y * w + x) as usize;
                    frame.data[i..i + 3].copy_from_slice(if inside {
                        &[200, 30, 30]
                    } else {
                        &[110, 110, 110]
                    });
                }
            }
            let in_view = visible.xmax - visible.xmin >= 4.0;
            let region = in_view.then_some(Detection {
                centre: [0.5 * (visible.xmin + visible.xmax), 170.0],
                foot: [0.5 * (visible.xmin + visible.xmax), 220.0],
                bbox: visible,
                area: ((visible.xmax - visible.xmin + 1.0) * 101.0) as u32,
                colour: proto::msg::ColourSignature {
                    hue: 0.0,
                    saturation: 0.8,
                    intensity: 0.5,
                },
            });
            frame.captured = at_ms(k * 67);
            let reported: Vec<u32> = people
                .track(&cam, &frame, region.as_slice(), None)
                .unwrap()
                .iter()
                .map(|p| p.local)
                .collect();
            match k {
                1..20 => assert_eq!(reported.len(), 1, "seed {seed}, frame {k}: in view"),
                20..29 => assert!(reported.is_empty(), "seed {seed}, frame {k}: walked out"),
                _ => reported_back |= !reported.is_empty(),
            }
        }
        assert!(reported_back, "seed {seed}: reported once back in view");
        let withheld = people.counters().withheld;
        assert!(withheld.walked_out >= 9, "seed {seed}: {withheld:?}");
        assert_eq!(
            (withheld.unsupported, withheld.hidden_feet, withheld.off_the_floor),
            (0, 0, 0),
            "seed {seed}"
        );
    }
}

/// A far person's blue legs at the top of the view, a red person near the camera below them:
/// apart, each is reported; once the near one's head reaches the legs, their foreground is
/// one region and the lowest foreground under the legs is the near person's feet. The legs'
/// filter lives on, unreported (nothing measures where the far person stands), and the near
/// person is still reported where they stand.
#[test]
fn a_person_whose_feet_someone_in_front_hides_is_not_reported() {
    let cam = Scenario::default_scenario().camera_model(10).unwrap();
    let (w, h) = (352u32, 288u32);
    let b = |xmin: f32, ymin: f32, xmax: f32, ymax: f32| PixelBox {
        xmin,
        ymin,
        xmax,
        ymax,
    };
    let near = b(140.0, 110.0, 180.0, 250.0);
    let grid = crate::region::Grid::new(w, h, 1);
    let mut people = GroundPeople::new(&ParticleParams::default(), 15.0, 3).unwrap();
    let mut frame = Frame::new(w, h, ClusterTime::ZERO);
    let mut near_alone = None;
    for k in 0..12i64 {
        // Frames 0–5 the legs end at row 60, then at row 112, inside the near person's head.
        let legs = b(150.0, 0.0, 166.0, if k < 6 { 60.0 } else { 112.0 });
        let mut mask = vec![0u8; grid.len()];
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32, y as f32);
                let inside = |r: &PixelBox| xf >= r.xmin && xf <= r.xmax && yf >= r.ymin && yf <= r.ymax;
                let i = (y * w + x) as usize;
                let colour: &[u8; 3] = if inside(&near) {
                    &[200, 30, 30]
                } else if inside(&legs) {
                    &[30, 40, 200]
                } else {
                    &[110, 110, 110]
                };
                frame.data[3 * i..3 * i + 3].copy_from_slice(colour);
                mask[i] = u8::from(inside(&near) || inside(&legs));
            }
        }
        let regions = if k < 6 {
            vec![
                crate::tracker::feet::tests::region(near),
                crate::tracker::feet::tests::region(legs),
            ]
        } else {
            vec![crate::tracker::feet::tests::region(b(140.0, 0.0, 180.0, 250.0))]
        };
        frame.captured = at_ms(k * 67);
        let fg = Foreground::new(&mask, grid).unwrap();
        let reported = people.track(&cam, &frame, &regions, Some(fg)).unwrap().to_vec();
        match k {
            0 => assert!(reported.is_empty(), "filters start on a region's second frame"),
            1..6 => {
                assert_eq!(reported.len(), 2, "frame {k}: two people apart");
                near_alone = reported
                    .iter()
                    .max_by(|a, c| a.height_m.total_cmp(&c.height_m))
                    .cloned();
            }
            _ => {
                assert_eq!(people.tracker().ids().len(), 2, "frame {k}: both filters live on");
                assert_eq!(reported.len(), 1, "frame {k}: only the near person is measured");
                let near = near_alone.as_ref().unwrap();
                let d = (reported[0].position[0] - near.position[0])
                    .hypot(reported[0].position[1] - near.position[1]);
                assert!(
                    d < 0.3,
                    "frame {k}: the near person stands where they stood, {d:.2} m off"
                );
            }
        }
    }
    assert_eq!(
        people.counters().withheld.hidden_feet,
        6,
        "one report left out per merged frame"
    );
}
