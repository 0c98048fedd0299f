//! RSSI weighed by the errors it makes. Paper 002 weighs a reading by its model's variance:
//! σ²_D for the default model, σ²_tm = a²σ²_u + σ²_v for a trained line (Algorithm 1). In our
//! world readings err more than that, and persistently (a multipath field that changes over a
//! metre or two): on Table I's runs the normalized innovations averaged 2.1 for trained lines and
//! 1.35 for the default model, where 1 is right. A filter that trusts RSSI twice too much lets it
//! pull the estimate off what the cameras see.
//!
//! So each track matches the noise to its innovations (covariance matching): per kind of model,
//! a running mean of (ν² − HΣ̄Hᵀ) / σ², the reading's error variance in units of the variance its
//! model claims, and readings are weighed with the claimed variance times that ratio, never less
//! than the claim. One ratio per kind, not per node: each trained line claims its own σ²_tm, and
//! the ratio scales them all alike (a node's window of 20 pairs is too few to estimate its own).
//! Algorithm 1's choice between a trained line and the default keeps the paper's variances; the
//! activation planner weighs a node's RSSI as the filter will.

use proto::models::RssiModel;

/// Per-track ratios of the RSSI errors' variance to the models' claimed variances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RssiNoise {
    /// Default (log-distance) model, trained (linear) lines.
    ratio: [f64; 2],
}

impl Default for RssiNoise {
    fn default() -> Self {
        RssiNoise { ratio: [1.0; 2] }
    }
}

impl RssiNoise {
    /// A new reading's weight in the running mean: about the last 20 readings of a kind count.
    const NEW: f64 = 0.05;
    /// One reading moves the ratio by at most this many claimed variances (a 5σ error), so that
    /// a lone wild reading does not silence a kind for seconds.
    const MAX_SAMPLE: f64 = 25.0;
    /// Readings whose prediction is this many claimed variances uncertain are not counted: the
    /// innovation is then mostly the prediction's error, and subtracting HΣ̄Hᵀ leaves a sample
    /// as likely to be hugely negative as positive (a wide prior at a birth or in an occlusion
    /// would drag the ratio far below 1, and it would not widen when it matters).
    const MAX_PRIOR_SHARE: f64 = 3.0;

    fn kind(model: &RssiModel) -> usize {
        match model {
            RssiModel::LogDistance { .. } => 0,
            RssiModel::Linear { .. } => 1,
        }
    }

    /// One reading weighed with `model`: its innovation `nu` (dB) and the prediction's share
    /// of the innovation's variance `hph` (dB²). Non-finite input, and a reading whose
    /// prediction is too uncertain to tell its error ([`Self::MAX_PRIOR_SHARE`]), are ignored.
    pub fn observe(&mut self, model: &RssiModel, nu: f64, hph: f64) {
        let v = model.variance();
        let sample = (nu * nu - hph) / v;
        if !sample.is_finite() || v <= 0.0 || hph > Self::MAX_PRIOR_SHARE * v {
            return;
        }
        let r = &mut self.ratio[Self::kind(model)];
        *r += Self::NEW * (sample.min(Self::MAX_SAMPLE) - *r);
    }

    /// How much wider than claimed readings of `model`'s kind are weighed (at least 1).
    pub fn factor(&self, model: &RssiModel) -> f64 {
        self.ratio[Self::kind(model)].max(1.0)
    }

    /// `model` with the variance the filter weighs it with.
    pub fn weighed(&self, model: &RssiModel) -> RssiModel {
        model.widened(self.factor(model))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const DEFAULT: RssiModel = RssiModel::LogDistance {
        a: -22.0,
        b: -45.0,
        variance: 16.0,
    };
    const TRAINED: RssiModel = RssiModel::Linear {
        a: -3.0,
        b: -50.0,
        variance: 4.0,
    };

    /// Feed `n` readings of `model` whose errors have standard deviation `sd` around a
    /// prediction with variance share `hph`; the factor averaged over the last half of them
    /// (one value of a running mean over ~20 readings is itself noisy).
    fn feed(noise: &mut RssiNoise, model: &RssiModel, sd: f64, hph: f64, n: usize) -> f64 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let e = Normal::new(0.0, (sd * sd + hph).sqrt()).unwrap();
        let mut sum = 0.0;
        for k in 0..n {
            noise.observe(model, e.sample(&mut rng), hph);
            if k >= n / 2 {
                sum += noise.factor(model);
            }
        }
        sum / (n - n / 2) as f64
    }

    #[test]
    fn readings_that_err_twice_the_claim_are_weighed_at_twice_the_variance() {
        let mut noise = RssiNoise::default();
        // Trained lines claim 4 dB² but err with 8; the prediction adds 2 dB² to the innovation.
        let mean = feed(&mut noise, &TRAINED, 8f64.sqrt(), 2.0, 4000);
        assert!((mean - 2.0).abs() < 0.15, "mean factor {mean}");
        let f = noise.factor(&TRAINED);
        assert!((noise.weighed(&TRAINED).variance() - 4.0 * f).abs() < 1e-12);
        // The default model's kind has seen nothing: weighed as claimed.
        assert_eq!(noise.factor(&DEFAULT), 1.0);
        assert_eq!(noise.weighed(&DEFAULT), DEFAULT);
    }

    #[test]
    fn readings_as_good_as_claimed_are_never_weighed_tighter() {
        let mut noise = RssiNoise::default();
        // Errors of 4 dB² where 16 are claimed: the ratio falls to about a quarter, the factor
        // stays 1.
        let mean = feed(&mut noise, &DEFAULT, 2.0, 1.0, 2000);
        assert_eq!(mean, 1.0, "narrowed below the claim");
    }

    #[test]
    fn a_wide_prediction_does_not_drag_the_ratio_down() {
        // Readings exactly as noisy as claimed, under a prediction 10 claimed variances wide: the
        // samples (ν² − HΣ̄Hᵀ)/σ² would scatter far below zero; they are not counted.
        let mut noise = RssiNoise::default();
        feed(&mut noise, &DEFAULT, 4.0, 160.0, 500);
        assert_eq!(noise.ratio[0], 1.0);
        // Then errors twice the claim under a narrow prediction still widen at once.
        let mean = feed(&mut noise, &DEFAULT, 32f64.sqrt(), 1.0, 4000);
        assert!((mean - 2.0).abs() < 0.15, "mean factor {mean}");
    }

    #[test]
    fn a_wild_reading_moves_the_ratio_a_bounded_step_and_nan_none() {
        let mut noise = RssiNoise::default();
        noise.observe(&DEFAULT, 400.0, 0.0);
        let f = noise.factor(&DEFAULT);
        assert!((f - (1.0 + RssiNoise::NEW * 24.0)).abs() < 1e-12, "{f}");
        noise.observe(&DEFAULT, f64::NAN, 0.0);
        noise.observe(&DEFAULT, 1.0, f64::INFINITY);
        assert_eq!(noise.factor(&DEFAULT), f);
    }
}
