//! Paper 004 §2.2 (i), the "choose samples" step: a cumulative histogram of the samples'
//! weights, and each new sample drawn from it, so a sample's number of successors follows its
//! relative weight (multinomial resampling, as in Isard and Blake's Condensation).

use rand::Rng;

/// Scale weights to sum to 1. A set whose weights are all zero or not finite (the target
/// matched nowhere) becomes uniform; returns whether the weights were usable.
pub fn normalise(weights: &mut [f64]) -> bool {
    let total: f64 = weights.iter().sum();
    if total > 0.0 && total.is_finite() && weights.iter().all(|w| *w >= 0.0) {
        let f = 1.0 / total;
        weights.iter_mut().for_each(|w| *w *= f);
        true
    } else {
        let u = 1.0 / weights.len().max(1) as f64;
        weights.iter_mut().for_each(|w| *w = u);
        false
    }
}

/// Draw `n` parent indices from `weights` (non-negative, not necessarily normalized) by
/// binary search in their cumulative histogram. `cumulative` is scratch. The draws are
/// independent, so `picks` comes out in random order. Empty `weights` draw nothing.
pub fn resample(
    weights: &[f64],
    n: usize,
    rng: &mut impl Rng,
    cumulative: &mut Vec<f64>,
    picks: &mut Vec<usize>,
) {
    picks.clear();
    cumulative.clear();
    let mut sum = 0.0;
    cumulative.extend(weights.iter().map(|w| {
        sum += w.max(0.0);
        sum
    }));
    let Some(last) = weights.len().checked_sub(1) else {
        return;
    };
    if !(sum > 0.0 && sum.is_finite()) {
        picks.extend((0..n).map(|_| rng.random_range(0..=last)));
        return;
    }
    for _ in 0..n {
        let u = rng.random::<f64>() * sum;
        picks.push(cumulative.partition_point(|&c| c <= u).min(last));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// χ² critical values at p = 0.001 for 1..=7 degrees of freedom.
    const CHI2_999: [f64; 7] = [10.83, 13.82, 16.27, 18.47, 20.52, 22.46, 24.32];

    fn chi_square(weights: &[f64], draws: usize, seed: u64) -> (f64, Vec<usize>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (mut cum, mut picks) = (Vec::new(), Vec::new());
        resample(weights, draws, &mut rng, &mut cum, &mut picks);
        let mut counts = vec![0usize; weights.len()];
        for &p in &picks {
            counts[p] += 1;
        }
        let total: f64 = weights.iter().sum();
        let chi2 = weights
            .iter()
            .zip(&counts)
            .filter(|(w, _)| **w > 0.0)
            .map(|(w, &c)| {
                let e = w / total * draws as f64;
                (c as f64 - e).powi(2) / e
            })
            .sum();
        (chi2, counts)
    }

    #[test]
    fn successors_follow_the_weights() {
        // Unnormalized weights with a zero: the zero-weight sample never has a successor.
        let weights = [1.0, 2.0, 3.0, 0.0, 4.0, 0.5, 0.5, 9.0];
        for seed in 0..5 {
            let (chi2, counts) = chi_square(&weights, 20_000, seed);
            assert_eq!(counts[3], 0);
            assert!(
                chi2 < CHI2_999[6],
                "seed {seed}: χ² = {chi2:.2}, counts {counts:?}"
            );
        }
    }

    #[test]
    fn the_chi_square_check_catches_a_biased_resampler() {
        // Counts as an off-by-one search would give them (each weight credited to its
        // neighbour) fail the same check: the test above can fail.
        let weights = [1.0, 2.0, 3.0, 4.0];
        let (_, counts) = chi_square(&weights, 20_000, 1);
        let shifted: Vec<usize> = counts.iter().cycle().skip(1).take(4).copied().collect();
        let chi2: f64 = weights
            .iter()
            .zip(&shifted)
            .map(|(w, &c)| {
                let e = w / 10.0 * 20_000.0;
                (c as f64 - e).powi(2) / e
            })
            .sum();
        assert!(chi2 > CHI2_999[2], "{chi2}");
    }

    #[test]
    fn a_single_dominant_sample_takes_every_successor() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let (mut cum, mut picks) = (Vec::new(), Vec::new());
        resample(&[0.0, 0.0, 1e-300, 0.0], 50, &mut rng, &mut cum, &mut picks);
        assert!(picks.iter().all(|&p| p == 2), "{picks:?}");
        resample(&[], 5, &mut rng, &mut cum, &mut picks);
        assert!(picks.is_empty());
    }

    #[test]
    fn normalise_sums_to_one_or_falls_back_to_uniform() {
        let mut w = vec![1.0, 3.0, 4.0];
        assert!(normalise(&mut w));
        assert_eq!(w, vec![0.125, 0.375, 0.5]);
        let mut dead = vec![0.0; 4];
        assert!(!normalise(&mut dead));
        assert_eq!(dead, vec![0.25; 4]);
        let mut nan = vec![1.0, f64::NAN];
        assert!(!normalise(&mut nan));
        assert_eq!(nan, vec![0.5, 0.5]);
        // Uniform draws from a dead set still give every index a chance.
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut cum, mut picks) = (Vec::new(), Vec::new());
        resample(&[0.0; 4], 400, &mut rng, &mut cum, &mut picks);
        assert!((0..4).all(|i| picks.contains(&i)));
    }
}
