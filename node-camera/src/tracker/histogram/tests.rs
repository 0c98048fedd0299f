use super::*;
use proto::ClusterTime;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn filled(w: u32, h: u32, rgb: [u8; 3]) -> Frame {
    let mut f = Frame::new(w, h, ClusterTime::ZERO);
    for px in f.data.chunks_exact_mut(3) {
        px.copy_from_slice(&rgb);
    }
    f
}

fn put(f: &mut Frame, x: u32, y: u32, rgb: [u8; 3]) {
    let i = (y as usize * f.width as usize + x as usize) * 3;
    f.data[i..i + 3].copy_from_slice(&rgb);
}

fn histogram(f: &Frame, centre: [f32; 2], half: [f32; 2], step: usize) -> ColourHistogram {
    let mut image = BinImage::new();
    let mut bins = image.bind(f).unwrap();
    let mut counts = KernelCounts::default();
    bins.kernel_counts(centre, half, step, &mut counts);
    ColourHistogram::from_counts(&counts).unwrap()
}

#[test]
fn primaries_fall_in_their_hue_sectors() {
    // Hue bins are 36° wide: red 0° → 0, yellow 60° → 1, green 120° → 3, blue 240° → 6,
    // magenta 300° → 8; full saturation → saturation bin 9; value 255 → bin 9.
    assert_eq!(hsv_bins([255, 0, 0]), (9, 9));
    assert_eq!(hsv_bins([255, 255, 0]), (19, 9));
    assert_eq!(hsv_bins([0, 255, 0]), (39, 9));
    assert_eq!(hsv_bins([0, 0, 255]), (69, 9));
    assert_eq!(hsv_bins([255, 0, 255]), (89, 9));
    // Grey: no hue, no saturation; value 100/256 → bin 3.
    assert_eq!(hsv_bins([100, 100, 100]), (0, 3));
    assert_eq!(hsv_bins([0, 0, 0]), (0, 0));
    // Half-saturated dark red: saturation 0.5 → bin 5, value 128 → bin 5.
    assert_eq!(hsv_bins([128, 64, 64]), (5, 5));
}

#[test]
fn the_quantized_table_agrees_with_the_exact_bins() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let f = Frame {
        width: 64,
        height: 64,
        data: (0..64 * 64 * 3).map(|_| rng.random()).collect(),
        captured: ClusterTime::ZERO,
    };
    let mut image = BinImage::new();
    let mut bins = image.bind(&f).unwrap();
    bins.ensure(0, 0, 63, 63);
    let agree = (0..64 * 64)
        .filter(|&i| {
            let exact = hsv_bins([f.data[3 * i], f.data[3 * i + 1], f.data[3 * i + 2]]);
            let [hs, v] = bins.image.bins[i];
            (hs as usize, v as usize - HS_BINS) == exact
        })
        .count();
    // 5-bit quantization moves only colours near a bin border.
    assert!(agree as f64 / 4096.0 > 0.8, "only {agree} of 4096 agree");
}

#[test]
fn a_uniform_box_puts_all_mass_in_one_bin() {
    let f = filled(40, 30, [30, 60, 200]);
    let (hs, v) = hsv_bins([30, 60, 200]);
    for step in [1, 3] {
        let hist = histogram(&f, [20.0, 15.0], [8.0, 10.0], step);
        assert!((hist.hs()[hs] - 1.0).abs() < 1e-6, "step {step}: {:?}", hist.hs());
        assert!((hist.value()[v] - 1.0).abs() < 1e-6);
        assert_eq!(hist.bins().iter().filter(|&&b| b > 0.0).count(), 2);
    }
}

#[test]
fn kernel_weights_are_one_minus_r_squared_and_sum_to_one() {
    // A 3×3 box (half sizes 1.5, a² = 4.5) on a blue frame with one red pixel in the middle:
    // weights 1 (centre), 1 − 1/4.5 (edges), 1 − 2/4.5 (corners); total 6⅓.
    let mut f = filled(9, 9, [0, 0, 255]);
    put(&mut f, 4, 4, [255, 0, 0]);
    let hist = histogram(&f, [4.0, 4.0], [1.5, 1.5], 1);
    let total = 1.0 + 4.0 * (1.0 - 1.0 / 4.5) + 4.0 * (1.0 - 2.0 / 4.5);
    let (red, _) = hsv_bins([255, 0, 0]);
    let (blue, _) = hsv_bins([0, 0, 255]);
    assert!((hist.hs()[red] - 1.0 / total).abs() < 1e-6, "{}", hist.hs()[red]);
    assert!((hist.hs()[blue] - (total - 1.0) / total).abs() < 1e-6);

    // Any box on a random image: HS and V each sum to 1.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let f = Frame {
        width: 80,
        height: 60,
        data: (0..80 * 60 * 3).map(|_| rng.random()).collect(),
        captured: ClusterTime::ZERO,
    };
    for _ in 0..20 {
        let c = [rng.random_range(0.0..80.0), rng.random_range(0.0..60.0)];
        let half = [rng.random_range(1.0..30.0), rng.random_range(1.0..30.0)];
        let hist = histogram(&f, c, half, rng.random_range(1..4));
        let (hs, v): (f32, f32) = (hist.hs().iter().sum(), hist.value().iter().sum());
        assert!((hs - 1.0).abs() < 1e-4 && (v - 1.0).abs() < 1e-4, "{hs} {v}");
    }
}

#[test]
fn a_box_outside_the_frame_has_no_histogram() {
    let f = filled(20, 20, [10, 20, 30]);
    let mut image = BinImage::new();
    let mut bins = image.bind(&f).unwrap();
    let mut counts = KernelCounts::default();
    bins.kernel_counts([-30.0, 5.0], [5.0, 5.0], 1, &mut counts);
    assert_eq!(counts.total, 0.0);
    assert!(ColourHistogram::from_counts(&counts).is_none());
    // Half inside: only the inside pixels count.
    bins.kernel_counts([0.0, 10.0], [4.0, 4.0], 1, &mut counts);
    let full = {
        let mut c = KernelCounts::default();
        bins.kernel_counts([10.0, 10.0], [4.0, 4.0], 1, &mut c);
        c.total
    };
    assert!(
        counts.total > 0.4 * full && counts.total < 0.7 * full,
        "{} of {full}",
        counts.total
    );
}

#[test]
fn a_new_frame_replaces_the_bins_of_the_last() {
    let (a, b) = (filled(40, 40, [200, 0, 0]), filled(40, 40, [0, 200, 0]));
    let mut image = BinImage::new();
    let mut counts = KernelCounts::default();
    image
        .bind(&a)
        .unwrap()
        .kernel_counts([20.0, 20.0], [5.0, 5.0], 1, &mut counts);
    assert!(counts.bins[hsv_bins([200, 0, 0]).0] > 0.0);
    image
        .bind(&b)
        .unwrap()
        .kernel_counts([20.0, 20.0], [5.0, 5.0], 1, &mut counts);
    assert_eq!(counts.bins[hsv_bins([200, 0, 0]).0], 0.0);
    assert!(counts.bins[hsv_bins([0, 200, 0]).0] > 0.0);
    let bad = Frame {
        data: vec![0; 5],
        ..b.clone()
    };
    assert!(image.bind(&bad).is_err());
}

fn two_colour(w: u32, split: u32, left: [u8; 3], right: [u8; 3]) -> ColourHistogram {
    let mut f = filled(w, 10, left);
    for y in 0..10 {
        for x in split..w {
            put(&mut f, x, y, right);
        }
    }
    histogram(&f, [(w as f32 - 1.0) / 2.0, 4.5], [w as f32 / 2.0, 5.0], 1)
}

#[test]
fn bhattacharyya_is_one_for_identical_zero_for_disjoint_and_blends_70_30() {
    let a = two_colour(20, 10, [200, 30, 30], [30, 30, 200]);
    assert!((a.similarity(&a, 0.7) - 1.0).abs() < 1e-5);
    // Disjoint in HS and in V: bright red vs dark green.
    let red = two_colour(20, 20, [250, 0, 0], [250, 0, 0]);
    let green = two_colour(20, 20, [0, 60, 0], [0, 60, 0]);
    assert!(red.similarity(&green, 0.7).abs() < 1e-6);
    // Same hue and saturation, disjoint value: only the HS part (70%) matches.
    let dark_red = two_colour(20, 20, [100, 0, 0], [100, 0, 0]);
    assert!((red.similarity(&dark_red, 0.7) - 0.7).abs() < 1e-5);
    // Same value, disjoint hue: only V (30%).
    let blue = two_colour(20, 20, [0, 0, 250], [0, 0, 250]);
    assert!((red.similarity(&blue, 0.7) - 0.3).abs() < 1e-5);
    // Half red, half green (symmetric under the kernel), same value: ρ_HS = √(½·1), ρ_V = 1.
    let half = two_colour(20, 10, [250, 0, 0], [0, 250, 0]);
    let got = half.similarity(&red, 0.7);
    assert!((got - (0.7 * 0.5f32.sqrt() + 0.3)).abs() < 1e-5, "{got}");
}

#[test]
fn target_similarity_from_counts_equals_the_histogram_formula() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for _ in 0..50 {
        let mut counts = KernelCounts::default();
        for _ in 0..rng.random_range(1..40) {
            let (hs, v) = (rng.random_range(0..HS_BINS), rng.random_range(HS_BINS..BINS));
            let k: f32 = rng.random_range(0.0..1.0);
            counts.bins[hs] += k;
            counts.bins[v] += k;
            counts.total += k;
        }
        let other = {
            let mut c = counts.clone();
            c.bins[rng.random_range(0..HS_BINS)] += 0.5;
            c.bins[rng.random_range(HS_BINS..BINS)] += 0.5;
            c.total += 0.5;
            ColourHistogram::from_counts(&c).unwrap()
        };
        let slow = ColourHistogram::from_counts(&counts)
            .unwrap()
            .similarity(&other, 0.7);
        let fast = TargetHistogram::new(other).similarity(&counts, 0.7);
        assert!((slow - fast).abs() < 1e-5, "{slow} vs {fast}");
    }
}

#[test]
fn distance_and_weight_follow_eq_7_and_8() {
    assert_eq!(bhattacharyya_distance(1.0), 0.0);
    assert!((bhattacharyya_distance(0.75) - 0.5).abs() < 1e-7);
    assert_eq!(
        bhattacharyya_distance(1.0 + 1e-6),
        0.0,
        "rounding above 1 is no distance"
    );
    let sigma = 0.2;
    let peak = observation_probability(0.0, sigma);
    assert!((peak - 1.0 / ((2.0 * std::f64::consts::PI).sqrt() * 0.2)).abs() < 1e-12);
    assert!((observation_probability(sigma, sigma) / peak - (-0.5f64).exp()).abs() < 1e-12);
}

#[test]
fn adaptation_blends_bins_and_keeps_them_normalized() {
    let red = two_colour(20, 20, [250, 0, 0], [250, 0, 0]);
    let blue = two_colour(20, 20, [0, 0, 250], [0, 0, 250]);
    let mut target = TargetHistogram::new(red.clone());
    target.adapt(&blue, 0.25);
    let (r, b) = (hsv_bins([250, 0, 0]).0, hsv_bins([0, 0, 250]).0);
    assert!((target.histogram().hs()[r] - 0.75).abs() < 1e-6);
    assert!((target.histogram().hs()[b] - 0.25).abs() < 1e-6);
    assert!((target.histogram().hs().iter().sum::<f32>() - 1.0).abs() < 1e-6);
    let mut counts = KernelCounts::default();
    counts.bins[b] = 1.0;
    counts.bins[HS_BINS + 9] = 1.0;
    counts.total = 1.0;
    // √0.25 of the HS mass matches; V identical.
    assert!((target.similarity(&counts, 0.7) - (0.7 * 0.5 + 0.3)).abs() < 1e-5);
}

proptest::proptest! {
    #[test]
    fn similarity_is_symmetric_and_within_0_and_1(
        a in proptest::collection::vec(0.0f32..1.0, BINS),
        b in proptest::collection::vec(0.0f32..1.0, BINS),
        w in 0.0f32..=1.0,
    ) {
        let hist = |v: &[f32]| {
            let mut c = KernelCounts::default();
            let (hs, val): (f32, f32) = (v[..HS_BINS].iter().sum(), v[HS_BINS..].iter().sum());
            for (k, x) in v.iter().enumerate() {
                // Make both halves sum to the same total, as kernel counts do.
                c.bins[k] = if k < HS_BINS { x / hs.max(1e-6) } else { x / val.max(1e-6) };
            }
            c.total = 1.0;
            ColourHistogram::from_counts(&c).unwrap()
        };
        let (p, q) = (hist(&a), hist(&b));
        let (pq, qp) = (p.similarity(&q, w), q.similarity(&p, w));
        proptest::prop_assert!((pq - qp).abs() < 1e-5);
        proptest::prop_assert!((-1e-6..=1.0 + 1e-4).contains(&pq), "{}", pq);
        proptest::prop_assert!((p.similarity(&p, w) - 1.0).abs() < 1e-4);
        let (hs, v) = hsv_bins([(a[0] * 255.0) as u8, (b[0] * 255.0) as u8, (a[1] * 255.0) as u8]);
        proptest::prop_assert!(hs < HS_BINS && v < VALUE_BINS);
    }
}
