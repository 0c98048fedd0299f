use super::*;
use proto::ClusterTime;

fn scene(t: usize, square_x: Option<usize>) -> Frame {
    let mut f = Frame::new(120, 90, ClusterTime::from_millis(t as i64 * 100));
    for y in 0..90 {
        for x in 0..120 {
            let i = (y * 120 + x) * 3;
            let n = ((x * 7 + y * 13 + t * 29) % 5) as u8; // small noise
            f.data[i] = 90 + n;
            f.data[i + 1] = 100 + n;
            f.data[i + 2] = 80 + n;
            if let Some(sx) = square_x
                && (sx..sx + 12).contains(&x)
                && (30..54).contains(&y)
            {
                f.data[i] = 200;
                f.data[i + 1] = 30;
                f.data[i + 2] = 40;
            }
        }
    }
    f
}

/// The model update as one per-pixel loop: what the row passes of `update` must equal.
/// Returns (background, ring, noise, confidence, mask).
#[allow(clippy::type_complexity)]
fn reference_update(
    seg: &AdaptiveBackground,
    frame: &Frame,
) -> (Vec<u8>, Vec<u8>, Vec<u8>, Vec<u8>, Vec<u8>) {
    let p = &seg.params;
    let g = seg.grid.unwrap();
    let (mut bg, mut ring, mut noise, mut conf, mut mask) = (
        seg.background.clone(),
        seg.ring.clone(),
        seg.noise.clone(),
        seg.confidence.clone(),
        seg.mask.clone(),
    );
    let n3 = g.len() * 3;
    let slot = &mut ring[seg.ring_head * n3..(seg.ring_head + 1) * n3];
    for gy in 0..g.height {
        for gx in 0..g.width {
            let k = gy * g.width + gx;
            let px = g.rgb(frame, gx, gy);
            let l1 = |q: &[u8]| {
                (0..3)
                    .map(|c| (px[c] as i32 - q[c] as i32).unsigned_abs())
                    .sum::<u32>()
            };
            let d_bg = l1(&bg[k * 3..k * 3 + 3]);
            let d_old = l1(&slot[k * 3..k * 3 + 3]);
            let eta = noise[k];
            let base = (seg.c1_q8 * eta as u32) >> 8;
            mask[k] = u8::from(d_bg > base + p.c2 as u32);
            let counted = (conf[k] + 1) * u8::from(d_old < base + p.c3 as u32);
            if counted >= p.tau {
                bg[k * 3..k * 3 + 3].copy_from_slice(&px);
                conf[k] = 0;
            } else {
                conf[k] = counted;
            }
            noise[k] = if d_old > eta as u32 {
                eta.saturating_add(p.noise_step).min(p.noise_max)
            } else {
                eta.saturating_sub(1).max(p.noise_min)
            };
            slot[k * 3..k * 3 + 3].copy_from_slice(&px);
        }
    }
    (bg, ring, noise, conf, mask)
}

#[test]
fn row_passes_equal_the_per_pixel_update() {
    for step in [1, 2] {
        let params = AdaptiveBackgroundParams {
            tau: 4,
            history: 3,
            step,
            // The reference is the paper's update alone.
            remove_ghosts: false,
            ..AdaptiveBackgroundParams::default()
        };
        let mut seg = AdaptiveBackground::new(params);
        let mut out = Vec::new();
        let mut updates = 0;
        for t in 0..30 {
            let mut f = scene(t, (t % 7 != 0).then_some(5 + 3 * t));
            // Strong noise in one corner drives the noise counters both ways.
            for (i, v) in f.data.iter_mut().enumerate().take(3 * 120 * 20) {
                *v = v.wrapping_add(((i * 31 + t * 17) % 61) as u8);
            }
            if seg.grid.is_none() {
                seg.process(&f, &mut out).unwrap();
                continue;
            }
            let want = reference_update(&seg, &f);
            updates += usize::from(want.0 != seg.background);
            seg.process(&f, &mut out).unwrap();
            let got = (
                seg.background.clone(),
                seg.ring.clone(),
                seg.noise.clone(),
                seg.confidence.clone(),
                seg.mask.clone(),
            );
            assert!(got == want, "step {step}, frame {t}");
        }
        assert!(updates > 0, "step {step}: the background never took a colour");
    }
}

#[test]
fn finds_a_moving_square_and_not_the_noise() {
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams::default());
    let mut out = Vec::new();
    for t in 0..10 {
        seg.process(&scene(t, None), &mut out).unwrap();
        assert!(out.is_empty(), "frame {t}: static noise detected: {out:?}");
    }
    for t in 10..20 {
        let x = 10 + (t - 10) * 5;
        seg.process(&scene(t, Some(x)), &mut out).unwrap();
        assert_eq!(out.len(), 1, "frame {t}: {out:?}");
        let d = out[0];
        assert!((d.centre[0] - (x as f32 + 5.5)).abs() < 1.5, "{d:?}");
        assert!((d.centre[1] - 41.5).abs() < 1.5, "{d:?}");
        assert!(d.area > 200 && d.area <= 288, "{d:?}");
        assert!(d.colour.hue < 0.3 || d.colour.hue > 6.0, "{d:?}");
    }
}

/// Regions per frame while the red square stands at x = 50 from frame 1 on, in a model of
/// short memory (history 4, τ 8), with `holds` handed over before every frame.
fn parked(holds: &[Hold]) -> Vec<usize> {
    let params = AdaptiveBackgroundParams {
        tau: 8,
        history: 4,
        ..AdaptiveBackgroundParams::default()
    };
    let mut seg = AdaptiveBackground::new(params);
    let mut out = Vec::new();
    seg.process(&scene(0, None), &mut out).unwrap();
    (1..40)
        .map(|t| {
            seg.hold(holds);
            seg.process(&scene(t, Some(50)), &mut out).unwrap();
            out.len()
        })
        .collect()
}

#[test]
fn a_parked_object_joins_the_background_after_tau() {
    let seen = parked(&[]);
    assert_eq!(seen[0], 1, "the new object is moving at first");
    assert_eq!(*seen.last().unwrap(), 0, "and parked later: {seen:?}");
}

#[test]
fn a_held_box_keeps_a_parked_object_of_its_colours_out_of_the_background() {
    let bbox = PixelBox {
        xmin: 48.0,
        ymin: 28.0,
        xmax: 64.0,
        ymax: 56.0,
    };
    let red = 1u128 << hsv_bins(table_colour([200, 30, 40])).0;
    let held = parked(&[Hold { bbox, hs_bins: red }]);
    assert!(held.iter().all(|&n| n == 1), "held: {held:?}");
    // Holding other colours than the object's is holding nothing.
    let other = parked(&[Hold { bbox, hs_bins: !red }]);
    assert_eq!(*other.last().unwrap(), 0, "{other:?}");
}

#[test]
fn frame_counts_keep_the_papers_times_at_other_rates() {
    let p = AdaptiveBackgroundParams::default();
    let at20 = p.clone().scaled_to_fps(PAPER_FPS);
    assert_eq!((at20.history, at20.tau), (p.history, p.tau));
    assert_eq!(at20.restart_gap_ms, 2500);
    let at5 = p.clone().scaled_to_fps(5.0);
    assert_eq!((at5.history, at5.tau), (5, 8));
    let at1 = p.clone().scaled_to_fps(1.0);
    assert_eq!((at1.history, at1.tau), (2, 2));
    assert_eq!(p.clone().scaled_to_fps(f64::NAN), p);
}

/// Frames (of `total`) on which something is still detected where an object stood in the
/// first frame and left on the second.
fn ghost_frames(params: AdaptiveBackgroundParams, total: usize) -> usize {
    let mut seg = AdaptiveBackground::new(params);
    let mut out = Vec::new();
    seg.process(&scene(0, Some(20)), &mut out).unwrap();
    (1..total)
        .filter(|&t| {
            seg.process(&scene(t, None), &mut out).unwrap();
            out.iter().any(|d| (d.centre[0] - 25.5).abs() < 6.0)
        })
        .count()
}

/// The paper's model alone, without the ghost test.
fn keeping_ghosts() -> AdaptiveBackgroundParams {
    AdaptiveBackgroundParams {
        remove_ghosts: false,
        ..AdaptiveBackgroundParams::default()
    }
}

#[test]
fn the_first_frames_ghost_lasts_the_papers_time_at_5_fps() {
    // At 5 fps, 3 s is 15 frames: the scaled model (1 s history + 1.5 s) absorbs the ghost
    // within them; the paper's frame counts taken literally would keep it for 10 s.
    let fps = 5.0;
    let scaled = ghost_frames(keeping_ghosts().scaled_to_fps(fps), 25);
    assert!(scaled > 0 && scaled <= 15, "scaled: {scaled} frames");
    let literal = ghost_frames(keeping_ghosts(), 25);
    assert_eq!(literal, 24, "literal counts keep the ghost for the whole 5 s");
}

#[test]
fn the_ghost_test_drops_the_first_frames_ghost_at_once_and_the_model_takes_the_frame() {
    let params = AdaptiveBackgroundParams::default().scaled_to_fps(5.0);
    assert_eq!(ghost_frames(params.clone(), 25), 0);
    let mut seg = AdaptiveBackground::new(params);
    let mut out = Vec::new();
    seg.process(&scene(0, Some(20)), &mut out).unwrap();
    let empty = scene(1, None);
    seg.process(&empty, &mut out).unwrap();
    assert!(out.is_empty(), "{out:?}");
    assert_eq!(seg.ghosts(), 1);
    // The model holds the floor where the object stood (its moving pixels took the frame).
    let g = seg.grid().unwrap();
    let k = 40 * g.width + 25;
    assert_eq!(&seg.background()[k * 3..k * 3 + 3], &g.rgb(&empty, 25, 40));
    assert_eq!(seg.mask()[k], 0, "the moving mask agrees with the detections");
    // Nothing is left to detect, and an object that comes back is seen.
    seg.process(&scene(2, None), &mut out).unwrap();
    assert!(out.is_empty(), "{out:?}");
    seg.process(&scene(3, Some(60)), &mut out).unwrap();
    assert_eq!(out.len(), 1, "{out:?}");
    assert_eq!(seg.ghosts(), 1);
}

#[test]
fn an_object_moving_at_5_fps_stays_detected_with_scaled_counts() {
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams::default().scaled_to_fps(5.0));
    let mut out = Vec::new();
    for t in 0..5 {
        seg.process(&scene(t, None), &mut out).unwrap();
    }
    // 4 px per frame across a 12 px wide object: each pixel is covered for 3 frames.
    for t in 5..30 {
        let x = 4 + (t - 5) * 4;
        seg.process(&scene(t, Some(x)), &mut out).unwrap();
        assert_eq!(out.len(), 1, "frame {t}: {out:?}");
        assert!(
            (out[0].centre[0] - (x as f32 + 5.5)).abs() < 1.5,
            "frame {t}: {:?}",
            out[0]
        );
    }
}

#[test]
fn a_model_woken_after_a_long_gap_restarts_instead_of_showing_old_ghosts() {
    let params = keeping_ghosts().scaled_to_fps(5.0);
    assert_eq!(params.restart_gap_ms, 2600);
    let woken = |params: AdaptiveBackgroundParams| {
        let mut seg = AdaptiveBackground::new(params);
        let mut out = Vec::new();
        // The object stands at x = 20 when the camera starts, and it stops capturing.
        seg.process(&scene(0, Some(20)), &mut out).unwrap();
        seg.process(&scene(1, Some(22)), &mut out).unwrap();
        // Woken 10 s later: the object is gone from there.
        seg.process(&scene(100, None), &mut out).unwrap();
        (out.len(), seg.restarts())
    };
    assert_eq!(woken(params.clone()), (0, 1));
    let never = AdaptiveBackgroundParams {
        restart_gap_ms: 0,
        ..params
    };
    assert_eq!(
        woken(never),
        (1, 0),
        "without the restart the stale model shows a ghost"
    );
}

/// A model of short memory (history 4, τ 8) with settled colours after `settled` frames,
/// without the ghost test (its verdicts are not what these tests are about).
fn settling(settled_frames: u32) -> AdaptiveBackgroundParams {
    AdaptiveBackgroundParams {
        tau: 8,
        history: 4,
        settled_frames,
        ..keeping_ghosts()
    }
}

/// `scene` with a blue square (not the red one's colours) at x = 50.
fn blue_at_50(t: usize) -> Frame {
    let mut f = scene(t, None);
    for y in 30..54 {
        for x in 50..62 {
            let i = (y * 120 + x) * 3;
            f.data[i..i + 3].copy_from_slice(&[30, 40, 210]);
        }
    }
    f
}

/// The red square parks at x = 50 (frames 30–49) until the model takes it in, then leaves.
/// Returns the frames of the next ten that still detect something, and the model.
fn parked_then_gone(params: AdaptiveBackgroundParams) -> (usize, AdaptiveBackground) {
    let mut seg = AdaptiveBackground::new(params);
    let mut out = Vec::new();
    for t in 0..30 {
        seg.process(&scene(t, None), &mut out).unwrap();
    }
    for t in 30..50 {
        seg.process(&scene(t, Some(50)), &mut out).unwrap();
    }
    assert!(out.is_empty(), "the parked square is background: {out:?}");
    let ghost = (50..60)
        .filter(|&t| {
            seg.process(&scene(t, None), &mut out).unwrap();
            !out.is_empty()
        })
        .count();
    (ghost, seg)
}

#[test]
fn a_parked_object_that_leaves_shows_the_settled_floor_at_once() {
    let (ghost, seg) = parked_then_gone(settling(20));
    assert_eq!(ghost, 0, "the floor it uncovers is the settled one");
    assert!(seg.revealed() > 200, "{} pixels", seg.revealed());
    let (ghost, seg) = parked_then_gone(settling(0));
    assert!(
        ghost >= 5,
        "without settled colours the ghost lasts τ: {ghost} frames"
    );
    assert_eq!(seg.revealed(), 0);
}

#[test]
fn an_object_where_the_model_is_young_is_still_seen() {
    let (_, mut seg) = parked_then_gone(settling(20));
    let mut out = Vec::new();
    // Another object, of other colours, parks where the red one stood, while the model's
    // floor there is a few frames old: it is not the settled floor, so it moves.
    for t in 60..65 {
        seg.process(&blue_at_50(t), &mut out).unwrap();
        assert_eq!(out.len(), 1, "frame {t}: {out:?}");
    }
}

#[test]
fn nothing_settles_before_it_has_held_long_enough() {
    // The floor has held about 40 frames when the model takes the square in (it parks at
    // frame 30): with 60 needed, the floor is not settled.
    let (ghost, seg) = parked_then_gone(settling(60));
    assert!(ghost >= 5, "{ghost} frames");
    assert_eq!(seg.revealed(), 0);
}

#[test]
fn a_restarted_model_knows_the_floor_under_the_object_in_view() {
    let params = AdaptiveBackgroundParams {
        restart_gap_ms: 1000,
        ..settling(20)
    };
    let ghost = |params: AdaptiveBackgroundParams| {
        let mut seg = AdaptiveBackground::new(params);
        let mut out = Vec::new();
        for t in 0..30 {
            seg.process(&scene(t, None), &mut out).unwrap();
        }
        // Woken 5 s later with the square in view: the restarted model holds it.
        seg.process(&scene(80, Some(50)), &mut out).unwrap();
        assert_eq!(seg.restarts(), 1);
        // It walks off.
        (81..90)
            .filter(|&t| {
                seg.process(&scene(t, Some(90)), &mut out).unwrap();
                out.iter().any(|d| (d.centre[0] - 55.5).abs() < 6.0)
            })
            .count()
    };
    assert_eq!(ghost(params.clone()), 0);
    let without = AdaptiveBackgroundParams {
        settled_frames: 0,
        ..params
    };
    assert!(
        ghost(without) >= 5,
        "the restart's ghost lasts τ without settled colours"
    );
}

#[test]
fn wrong_size_frame_is_rejected_without_change() {
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams::default());
    let mut out = Vec::new();
    seg.process(&scene(0, None), &mut out).unwrap();
    let bg = seg.background().to_vec();
    let other = Frame::new(60, 40, ClusterTime::ZERO);
    assert!(matches!(
        seg.process(&other, &mut out),
        Err(FrameError::Mismatch { .. })
    ));
    assert_eq!(seg.background(), &bg[..]);
    assert_eq!(seg.frames(), 1);
}

#[test]
fn subsampled_processing_reports_full_resolution_coordinates() {
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams {
        step: 2,
        min_pixels: 4,
        ..AdaptiveBackgroundParams::default()
    });
    let mut out = Vec::new();
    seg.process(&scene(0, None), &mut out).unwrap();
    seg.process(&scene(1, Some(60)), &mut out).unwrap();
    assert_eq!(out.len(), 1, "{out:?}");
    assert!((out[0].centre[0] - 65.5).abs() < 2.0, "{:?}", out[0]);
    assert!(
        out[0].bbox.xmin >= 58.0 && out[0].bbox.xmax <= 73.0,
        "{:?}",
        out[0]
    );
}
