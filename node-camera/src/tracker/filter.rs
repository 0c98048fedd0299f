//! One person's colour particle filter (paper 004 §2.2–2.4, §3.2.2): a weighted sample set over
//! the person's box (centre, velocity, size). Each iteration chooses samples by the cumulative
//! weight histogram, moves them by their motion models, and weighs each by the Bhattacharyya
//! distance of its box's colour histogram to the target (eq. 4–8), times its overlap with the
//! person's foreground region when there is one (§3.2.2 (iii)). It reports the mean state, the
//! maximum-likelihood state with its confidence, and the sample set; the target histogram
//! adapts towards the maximum-likelihood sample's at a rate the caller sets from its confidence
//! (eq. 9).

use crate::tracker::boxes::iou;
use crate::tracker::histogram::{ColourHistogram, FrameBins, KernelCounts, TargetHistogram, sampling_step};
use crate::tracker::motion::{self, Bounds, Diffusion, MotionModel, State};
use crate::tracker::params::ParticleParams;
use crate::tracker::resample;
use proto::msg::PixelBox;
use rand::Rng;
use rand_distr::StandardNormal;

/// One sample of the output set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub state: State,
    /// Normalized weight π (the set sums to 1).
    pub weight: f32,
}

/// One person's particle filter.
#[derive(Clone, Debug)]
pub struct ParticleFilter {
    states: Vec<State>,
    /// Each sample's inherited motion model (combined mode).
    carried: Vec<MotionModel>,
    /// Normalized weights of the last measurement.
    weights: Vec<f64>,
    target: TargetHistogram,
    mean: State,
    ml: usize,
    /// The maximum-likelihood sample's weight before normalization, in (0, 1].
    ml_likelihood: f32,
    /// Its colour similarity to the target (blended Bhattacharyya ρ).
    ml_similarity: f32,
    ml_histogram: Option<ColourHistogram>,
    iterations: u64,
    scratch: Scratch,
}

/// Buffers reused every iteration.
#[derive(Clone, Debug, Default)]
struct Scratch {
    states: Vec<State>,
    carried: Vec<MotionModel>,
    models: Vec<MotionModel>,
    cumulative: Vec<f64>,
    picks: Vec<usize>,
    counts: KernelCounts,
    best: KernelCounts,
}

impl ParticleFilter {
    /// A filter whose target is the appearance inside `bbox` in the bound frame, its samples
    /// spread around the box. `None` when the box has no pixels in the frame.
    pub fn new(
        bins: &mut FrameBins<'_>,
        bbox: &PixelBox,
        p: &ParticleParams,
        rng: &mut impl Rng,
    ) -> Option<ParticleFilter> {
        let target = box_histogram(bins, bbox, p)?;
        Some(ParticleFilter::with_target(target, bbox, p, rng))
    }

    /// A filter with a given target histogram (e.g. trained by presenting the object, §2.6.2),
    /// its samples spread around `bbox` by the position diffusion.
    pub fn with_target(
        target: ColourHistogram,
        bbox: &PixelBox,
        p: &ParticleParams,
        rng: &mut impl Rng,
    ) -> ParticleFilter {
        let start = State::from_box(bbox);
        let n = p.particles.max(1);
        let mut carried = Vec::with_capacity(n);
        motion::initial_models(n, p, &mut carried);
        let states = (0..n)
            .map(|_| {
                let (dx, dy): (f32, f32) = (rng.sample(StandardNormal), rng.sample(StandardNormal));
                State {
                    x: start.x + p.position_sigma_px * dx,
                    y: start.y + p.position_sigma_px * dy,
                    ..start
                }
            })
            .collect();
        ParticleFilter {
            states,
            carried,
            weights: vec![1.0 / n as f64; n],
            target: TargetHistogram::new(target),
            mean: start,
            ml: 0,
            ml_likelihood: 1.0,
            ml_similarity: 1.0,
            ml_histogram: None,
            iterations: 0,
            scratch: Scratch::default(),
        }
    }

    /// One iteration on the bound frame: choose samples, predict, measure. `roi` is the
    /// foreground region assigned to this person, if any.
    pub fn step(
        &mut self,
        bins: &mut FrameBins<'_>,
        roi: Option<&PixelBox>,
        p: &ParticleParams,
        rng: &mut impl Rng,
    ) {
        let n = p.particles.max(1);
        let s = &mut self.scratch;
        resample::resample(&self.weights, n, rng, &mut s.cumulative, &mut s.picks);
        s.states.clear();
        s.states.extend(s.picks.iter().map(|&i| self.states[i]));
        s.carried.clear();
        s.carried.extend(s.picks.iter().map(|&i| self.carried[i]));
        std::mem::swap(&mut self.states, &mut s.states);
        std::mem::swap(&mut self.carried, &mut s.carried);
        motion::models_for_step(&mut self.carried, p, rng, &mut s.models);
        let bounds = Bounds {
            width: bins.width() as f32,
            height: bins.height() as f32,
        };
        let diffusion = Diffusion::from_params(p);
        for (state, &model) in self.states.iter_mut().zip(&s.models) {
            motion::propagate(state, model, &diffusion, bounds, rng);
        }
        self.measure(bins, roi, p);
        self.iterations += 1;
    }

    /// Weigh every sample (eq. 5–8, times the region overlap term), normalize, and find the
    /// mean and maximum-likelihood states.
    fn measure(&mut self, bins: &mut FrameBins<'_>, roi: Option<&PixelBox>, p: &ParticleParams) {
        let step = sampling_step(self.mean.w, self.mean.h, p.histogram_pixels);
        let inv_two_sigma2 = 1.0 / (2.0 * p.sigma as f64 * p.sigma as f64);
        let roi_term = roi.filter(|_| p.roi_sigma > 0.0).map(|r| {
            let inv = 1.0 / (2.0 * p.roi_sigma as f64 * p.roi_sigma as f64);
            (r, inv)
        });
        let s = &mut self.scratch;
        self.weights.clear();
        let (mut best, mut best_w, mut best_rho) = (0, -1.0, 0.0);
        for (i, state) in self.states.iter().enumerate() {
            bins.kernel_counts(state.centre(), state.half(), step, &mut s.counts);
            let rho = self.target.similarity(&s.counts, p.hs_weight) as f64;
            // d² = 1 − ρ (eq. 7); eq. 8 without its constant, which normalization removes.
            let mut w = (-(1.0 - rho).max(0.0) * inv_two_sigma2).exp();
            if let Some((r, inv)) = roi_term {
                let miss = 1.0 - iou(&state.bbox(), r) as f64;
                w *= (-miss * miss * inv).exp();
            }
            if s.counts.total <= 0.0 {
                w = 0.0;
            }
            if w > best_w {
                best_w = w;
                best = i;
                best_rho = rho;
                std::mem::swap(&mut s.counts, &mut s.best);
            }
            self.weights.push(w);
        }
        self.ml = best;
        self.ml_likelihood = best_w.max(0.0) as f32;
        self.ml_similarity = best_rho as f32;
        self.ml_histogram = ColourHistogram::from_counts(&s.best);
        resample::normalise(&mut self.weights);
        let mut mean = [0.0f64; 6];
        for (state, &w) in self.states.iter().zip(&self.weights) {
            for (m, v) in mean.iter_mut().zip(state.to_array()) {
                *m += w * v as f64;
            }
        }
        self.mean = State::from_array(mean.map(|m| m as f32));
    }

    /// Eq. 9: blend the maximum-likelihood sample's histogram into the target at rate `alpha`
    /// (0 leaves it). Returns whether it adapted.
    pub fn adapt(&mut self, alpha: f32) -> bool {
        match &self.ml_histogram {
            Some(h) if alpha > 0.0 => {
                self.target.adapt(h, alpha);
                true
            }
            _ => false,
        }
    }

    /// The mean state `E[S_t] = Σ π_i X_i` (§2.5.1 (ii)).
    pub fn mean(&self) -> State {
        self.mean
    }

    /// The maximum-likelihood state (§2.5.1 (iii)).
    pub fn ml_state(&self) -> State {
        self.states.get(self.ml).copied().unwrap_or(self.mean)
    }

    /// Its confidence: the best sample's weight before normalization relative to a perfect
    /// match (eq. 8 times `√(2π) σ`, times the region term when a region was given), in
    /// [0, 1]. The paper's "absolute value of the pdf's peak" (§2.4).
    pub fn ml_likelihood(&self) -> f32 {
        self.ml_likelihood
    }

    /// The maximum-likelihood sample's colour similarity to the target (blended
    /// Bhattacharyya ρ, eq. 6), in [0, 1].
    pub fn ml_similarity(&self) -> f32 {
        self.ml_similarity
    }

    /// The largest normalized weight (how peaked the pdf is: 1/N when uniform).
    pub fn peak_weight(&self) -> f32 {
        self.weights.get(self.ml).copied().unwrap_or(0.0) as f32
    }

    pub fn target(&self) -> &ColourHistogram {
        self.target.histogram()
    }

    /// Iterations run since the filter started.
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    /// The weighted sample set (§2.5.1 (i)).
    pub fn samples(&self) -> impl Iterator<Item = Sample> + '_ {
        self.states.iter().zip(&self.weights).map(|(&state, &w)| Sample {
            state,
            weight: w as f32,
        })
    }

    /// Weighted covariance of the samples' box (x, y, w, h), pixels² — the spread the ground
    /// conversion propagates.
    pub fn box_covariance(&self) -> [[f64; 4]; 4] {
        let pick = |s: &State| [s.x as f64, s.y as f64, s.w as f64, s.h as f64];
        let m = pick(&self.mean);
        let mut c = [[0.0; 4]; 4];
        for (s, &w) in self.states.iter().zip(&self.weights) {
            let v = pick(s);
            let d = [v[0] - m[0], v[1] - m[1], v[2] - m[2], v[3] - m[3]];
            for (i, row) in c.iter_mut().enumerate() {
                for (j, cell) in row.iter_mut().enumerate() {
                    *cell += w * d[i] * d[j];
                }
            }
        }
        c
    }
}

/// The appearance inside `bbox` in the bound frame, read as a filter's target is (eq. 4–5,
/// sub-sampled to `histogram-pixels`); `None` when the box has no pixels in the frame.
pub fn box_histogram(
    bins: &mut FrameBins<'_>,
    bbox: &PixelBox,
    p: &ParticleParams,
) -> Option<ColourHistogram> {
    let start = State::from_box(bbox);
    let step = sampling_step(start.w, start.h, p.histogram_pixels);
    let mut counts = KernelCounts::default();
    bins.kernel_counts(start.centre(), start.half(), step, &mut counts);
    ColourHistogram::from_counts(&counts)
}

/// Eq. 9's rate for this iteration (§2.4 "adapt wisely", §3.2.2 (i)): nothing while the
/// best sample's colour similarity is below `adapt-min-similarity` or, with a background
/// model, the foreground share under its box is below `adapt-min-foreground`; otherwise `alpha`,
/// times the foreground share when there is one.
pub fn adaptation_rate(p: &ParticleParams, similarity: f32, foreground: Option<f32>) -> f32 {
    if !(similarity.is_finite() && similarity >= p.adapt_min_similarity) {
        return 0.0;
    }
    match foreground {
        None => p.alpha,
        Some(f) if f.is_finite() && f >= p.adapt_min_foreground => p.alpha * f.clamp(0.0, 1.0),
        Some(_) => 0.0,
    }
}

#[cfg(test)]
mod tests;
