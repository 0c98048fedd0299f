use super::*;
use crate::adaptive_background::{AdaptiveBackground, AdaptiveBackgroundParams};
use crate::tracker::histogram::BinImage;
use crate::tracker::scene::{Person, Scene, fill_box};
use proto::ClusterTime;
use proto::sensor::Frame;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn one_person(velocity: [f32; 2]) -> Scene {
    Scene {
        width: 200,
        height: 150,
        people: vec![Person {
            shirt: [210, 40, 50],
            trousers: [40, 60, 160],
            size: [20.0, 40.0],
            start: [20.0, 50.0],
            velocity,
        }],
        noise: 6,
        fps: 15.0,
    }
}

fn centre(b: &PixelBox) -> [f32; 2] {
    [0.5 * (b.xmin + b.xmax), 0.5 * (b.ymin + b.ymax)]
}

/// Runs a filter started on the person's true box at frame 0 over `frames` frames, with
/// `draw` changing each rendered frame; returns per frame (mean error px, ML likelihood).
fn track(
    scene: &Scene,
    frames: u32,
    p: &ParticleParams,
    adapt: bool,
    draw: impl Fn(u32, &mut Frame),
) -> Vec<(f32, f32)> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut image = BinImage::new();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    scene.render(0, &mut frame);
    draw(0, &mut frame);
    let mut bins = image.bind(&frame).unwrap();
    let mut filter = ParticleFilter::new(&mut bins, &scene.box_at(0, 0), p, &mut rng).unwrap();
    let mut out = Vec::new();
    for t in 1..frames {
        scene.render(t, &mut frame);
        draw(t, &mut frame);
        let mut bins = image.bind(&frame).unwrap();
        filter.step(&mut bins, None, p, &mut rng);
        if adapt {
            filter.adapt(adaptation_rate(p, filter.ml_similarity(), None));
        }
        let truth = centre(&scene.box_at(0, t));
        let m = filter.mean();
        out.push(((m.x - truth[0]).hypot(m.y - truth[1]), filter.ml_likelihood()));
    }
    out
}

#[test]
fn follows_a_coloured_box_across_the_frame() {
    let scene = one_person([2.5, 0.6]);
    let p = ParticleParams::default();
    let run = track(&scene, 60, &p, true, |_, _| {});
    let worst = run.iter().map(|r| r.0).fold(0.0, f32::max);
    assert!(worst < 4.0, "worst mean error {worst:.2} px: {run:?}");
    assert!(run.iter().all(|r| r.1 > 0.3), "confidence fell: {run:?}");
}

#[test]
fn weights_are_normalized_and_the_set_has_the_configured_size() {
    let scene = one_person([2.0, 0.0]);
    let p = ParticleParams {
        particles: 37,
        ..ParticleParams::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut image = BinImage::new();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    scene.render(0, &mut frame);
    let mut bins = image.bind(&frame).unwrap();
    let mut filter = ParticleFilter::new(&mut bins, &scene.box_at(0, 0), &p, &mut rng).unwrap();
    scene.render(1, &mut frame);
    let mut bins = image.bind(&frame).unwrap();
    filter.step(&mut bins, None, &p, &mut rng);
    let samples: Vec<Sample> = filter.samples().collect();
    assert_eq!(samples.len(), 37);
    let total: f32 = samples.iter().map(|s| s.weight).sum();
    assert!((total - 1.0).abs() < 1e-5, "{total}");
    let best = samples.iter().map(|s| s.weight).fold(0.0, f32::max);
    assert_eq!(filter.peak_weight(), best);
    assert_eq!(
        filter.ml_state(),
        samples.iter().find(|s| s.weight == best).unwrap().state
    );
    // The mean is the weighted mean of the set.
    let mx: f32 = samples.iter().map(|s| s.weight * s.state.x).sum();
    assert!((filter.mean().x - mx).abs() < 1e-3);
    let cov = filter.box_covariance();
    assert!(cov[0][0] > 0.0 && (cov[0][1] - cov[1][0]).abs() < 1e-9);
}

/// The occluder of the occlusion tests: a grey box over the person's right half, reaching
/// 30 px beyond it, frames 20–31 (another person in grey walking alongside).
fn occluder(scene: &Scene, t: u32) -> Option<PixelBox> {
    (20..32).contains(&t).then(|| {
        let b = scene.box_at(0, t);
        PixelBox {
            xmin: 0.5 * (b.xmin + b.xmax),
            xmax: b.xmax + 30.0,
            ..b
        }
    })
}

#[test]
fn keeps_the_person_through_a_partial_occlusion_that_segmentation_merges() {
    let scene = one_person([2.0, 0.0]);
    let grey = [185, 185, 185];
    let draw = |t: u32, f: &mut Frame| {
        if let Some(b) = occluder(&scene, t) {
            fill_box(f, &b, grey);
        }
    };
    let run = track(&scene, 45, &ParticleParams::default(), true, draw);
    // Frame t is run[t - 1].
    let during = run[19..31].iter().map(|r| r.0).fold(0.0, f32::max);
    let after = run[34..].iter().map(|r| r.0).fold(0.0, f32::max);
    // The person is 20 px wide: a mean within 8 px stays on them (it leans towards the
    // visible half, whose centre is 5 px away).
    assert!(during < 8.0, "lost during the occlusion: {during:.1} px, {run:?}");
    assert!(
        after < 4.0,
        "not recovered 3 frames later: {after:.1} px {:?}",
        &run[19..]
    );
    // It did not learn the occluder: after the occlusion the person matches its target well.
    assert!(run[40..].iter().all(|r| r.1 > 0.3), "{:?}", &run[40..]);

    // Segmentation alone: the background model sees person and occluder as one region whose
    // centre is more than half the person's width away from the person.
    let mut seg = AdaptiveBackground::new(AdaptiveBackgroundParams::default());
    let (mut frame, mut regions) = (Frame::new(1, 1, ClusterTime::ZERO), Vec::new());
    let empty = Scene {
        people: vec![],
        ..scene.clone()
    };
    empty.render(0, &mut frame);
    seg.process(&frame, &mut regions).unwrap();
    let mut worst_region_error = 0.0f32;
    for t in 1..32 {
        scene.render(t, &mut frame);
        draw(t, &mut frame);
        seg.process(&frame, &mut regions).unwrap();
        if t >= 20 {
            let truth = centre(&scene.box_at(0, t));
            let nearest = regions
                .iter()
                .map(|r| (r.centre[0] - truth[0]).hypot(r.centre[1] - truth[1]))
                .fold(f32::INFINITY, f32::min);
            worst_region_error = worst_region_error.max(nearest);
        }
    }
    assert!(
        worst_region_error > 10.0,
        "segmentation kept it: {worst_region_error:.1} px"
    );
}

#[test]
fn self_adaptation_follows_a_slow_brightness_change() {
    // The person's colours dim to half over 400 frames (27 s at 15 fps); hue and saturation
    // stay.
    let scene = one_person([1.0, 0.2]);
    let dim = |t: u32, f: &mut Frame| {
        let gain = 1.0 - 0.5 * (t as f32 / 400.0).min(1.0);
        let b = scene.box_at(0, t);
        let p = &scene.people[0];
        let mid = b.ymin + 0.55 * (b.ymax - b.ymin);
        let scale = |c: [u8; 3]| c.map(|v| (v as f32 * gain) as u8);
        fill_box(f, &PixelBox { ymax: mid, ..b }, scale(p.shirt));
        fill_box(f, &PixelBox { ymin: mid, ..b }, scale(p.trousers));
        scene.add_noise(t + 1000, f);
    };
    let p = ParticleParams::default();
    let adapted = track(&scene, 410, &p, true, dim);
    let fixed = track(&scene, 410, &p, false, dim);
    let end = |run: &[(f32, f32)]| {
        let tail = &run[run.len() - 10..];
        let n = tail.len() as f32;
        (
            tail.iter().map(|r| r.0).sum::<f32>() / n,
            tail.iter().map(|r| r.1).sum::<f32>() / n,
        )
    };
    let (err_on, conf_on) = end(&adapted);
    let (_, conf_off) = end(&fixed);
    assert!(err_on < 4.0, "adapting filter lost the person: {err_on:.1} px");
    assert!(conf_on > 0.4, "adapting filter's confidence {conf_on:.3}");
    assert!(
        conf_off < 0.5 * conf_on,
        "without adaptation the confidence should drop: {conf_off:.3} vs {conf_on:.3}"
    );
}

#[test]
fn the_adaptation_rate_is_gated_by_confidence() {
    let p = ParticleParams {
        alpha: 0.2,
        adapt_min_similarity: 0.9,
        adapt_min_foreground: 0.5,
        ..ParticleParams::default()
    };
    assert_eq!(adaptation_rate(&p, 0.89, None), 0.0);
    assert_eq!(adaptation_rate(&p, 0.95, None), 0.2);
    assert_eq!(adaptation_rate(&p, 0.95, Some(0.49)), 0.0);
    assert!((adaptation_rate(&p, 0.95, Some(0.5)) - 0.1).abs() < 1e-7);
    assert_eq!(
        adaptation_rate(&p, 0.85, Some(1.0)),
        0.0,
        "a poor match never adapts"
    );
    assert_eq!(adaptation_rate(&p, f32::NAN, None), 0.0);
}

#[test]
fn a_region_shapes_the_box_size() {
    // A filter started on a box half the person's height grows towards the region.
    let scene = one_person([0.0, 0.0]);
    let p = ParticleParams::default();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut image = BinImage::new();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    scene.render(0, &mut frame);
    let truth = scene.box_at(0, 0);
    let small = PixelBox {
        ymax: truth.ymin + 20.0,
        ..truth
    };
    let target = {
        let mut bins = image.bind(&frame).unwrap();
        let mut c = KernelCounts::default();
        let s = State::from_box(&truth);
        bins.kernel_counts(s.centre(), s.half(), 1, &mut c);
        ColourHistogram::from_counts(&c).unwrap()
    };
    let mut with_roi = ParticleFilter::with_target(target.clone(), &small, &p, &mut rng);
    let mut without = ParticleFilter::with_target(target, &small, &p, &mut rng);
    for t in 1..40 {
        scene.render(t, &mut frame);
        let mut bins = image.bind(&frame).unwrap();
        with_roi.step(&mut bins, Some(&truth), &p, &mut rng);
        without.step(&mut bins, None, &p, &mut rng);
    }
    let (h_roi, h_none) = (with_roi.mean().h, without.mean().h);
    assert!((h_roi - 40.0).abs() < 5.0, "with the region: h = {h_roi:.1}");
    assert!(
        (h_roi - 40.0).abs() < (h_none - 40.0).abs(),
        "{h_roi} vs {h_none}"
    );
}
