//! RSSI-range model training (paper 002 §IV, Algorithm 1), run at the head.
//!
//! Each (node, track) keeps its last M pairs (distance, RSSI), the distance taken from the
//! auxiliary camera-only EIF. A local linear model `RSSI = a d + b` is fitted by eq. 4–5; its
//! variance σ²_tm = a² σ²_u + σ²_v (eq. 7) decides between it and the default model: the
//! trained model is used only when σ²_tm ≤ σ²_D. σ²_u is the variance of the auxiliary EIF's
//! distance along the node–target line: the window's mean when a pair is added, and the
//! filter's current one if larger at every step ([`RssiTrainer::recheck`]); σ²_v is estimated
//! from the fit's residuals. A slope
//! with 1/a → 0 is clamped to |1/a| = ε and b recomputed (eq. 5).

use nalgebra::{Matrix3, Vector3};
use proto::models::RssiModel;
use std::collections::VecDeque;

/// Fewest pairs a fit needs (two determine a line; residuals need more).
pub const MIN_PAIRS: usize = 4;

/// What Algorithm 1 decided on the last fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Choice {
    /// Not enough (or degenerate) pairs yet.
    Untrained,
    /// σ²_tm > σ²_D: the default model is used.
    Default { sigma_tm2: f64 },
    /// The trained model is used.
    Trained { sigma_tm2: f64 },
}

/// One node's trainer for one track.
#[derive(Clone, Debug)]
pub struct RssiTrainer {
    window: VecDeque<(f64, f64)>,
    capacity: usize,
    default: RssiModel,
    epsilon: f64,
    /// σ²_u of each pair in the window.
    sigma_u2: VecDeque<f64>,
    model: RssiModel,
    choice: Choice,
    /// The last fit (a, b, σ̂²_v).
    line: Option<(f64, f64, f64)>,
    /// The auxiliary filter's σ²_u at the last re-check; a refit in the same step keeps it.
    sigma_u2_now: f64,
}

impl RssiTrainer {
    /// `window` is M; `epsilon` the 1/a guard.
    pub fn new(default: RssiModel, window: usize, epsilon: f64) -> Self {
        let capacity = window.max(MIN_PAIRS);
        RssiTrainer {
            window: VecDeque::with_capacity(capacity),
            sigma_u2: VecDeque::with_capacity(capacity),
            capacity,
            default,
            epsilon: epsilon.abs().max(f64::MIN_POSITIVE),
            model: default,
            choice: Choice::Untrained,
            line: None,
            sigma_u2_now: 0.0,
        }
    }

    /// The model to linearize this node's RSSI with.
    pub fn model(&self) -> RssiModel {
        self.model
    }

    pub fn choice(&self) -> Choice {
        self.choice
    }

    pub fn pairs(&self) -> usize {
        self.window.len()
    }

    /// The newest (distance, RSSI) pair.
    pub fn last_pair(&self) -> Option<(f64, f64)> {
        self.window.back().copied()
    }

    /// Add a pair: `distance` from the auxiliary EIF, its variance `sigma_u2`, and the RSSI
    /// read. Non-finite input is ignored. Refits and re-runs Algorithm 1.
    pub fn push(&mut self, distance: f64, rssi: f64, sigma_u2: f64) {
        if !(distance.is_finite() && rssi.is_finite() && sigma_u2.is_finite()) {
            return;
        }
        if self.window.len() == self.capacity {
            self.window.pop_front();
            self.sigma_u2.pop_front();
        }
        self.window.push_back((distance, rssi));
        self.sigma_u2.push_back(sigma_u2.max(0.0));
        self.refit();
    }

    fn refit(&mut self) {
        self.line = fit(self.window.iter().copied(), self.epsilon);
        self.choose();
    }

    /// Re-run Algorithm 1's choice on the last fit with the auxiliary filter's σ²_u now, when
    /// that exceeds the window's. Called every step: while no camera sees the target the
    /// auxiliary filter only predicts, its σ²_u grows, and a line fitted where the target was
    /// gives way to the default model, as paper 002 §VI describes for its occlusion.
    /// Non-finite input is ignored.
    pub fn recheck(&mut self, sigma_u2_now: f64) {
        if sigma_u2_now.is_finite() {
            self.sigma_u2_now = sigma_u2_now.max(0.0);
            self.choose();
        }
    }

    /// Algorithm 1's choice on the last fit, with σ²_u the larger of the window's mean and the
    /// last re-check's.
    fn choose(&mut self) {
        let Some((a, b, sigma_v2)) = self.line else {
            self.model = self.default;
            self.choice = Choice::Untrained;
            return;
        };
        let window = self.sigma_u2.iter().sum::<f64>() / self.sigma_u2.len().max(1) as f64;
        let sigma_tm2 = a * a * window.max(self.sigma_u2_now) + sigma_v2;
        if sigma_tm2 > self.default.variance() {
            self.model = self.default;
            self.choice = Choice::Default { sigma_tm2 };
        } else {
            self.model = RssiModel::Linear {
                a,
                b,
                // Never claim more precision than a floor of 0.25 dB².
                variance: sigma_tm2.max(0.25),
            };
            self.choice = Choice::Trained { sigma_tm2 };
        }
    }
}

/// σ²_u: the variance of the distance from `node` to a target estimated at `target` with
/// position covariance `cov`, along the node–target line. NaN when the two coincide (no
/// direction), which [`RssiTrainer`] ignores.
pub fn distance_variance(target: &Vector3<f64>, cov: &Matrix3<f64>, node: &Vector3<f64>) -> f64 {
    let diff = target - node;
    let d = diff.norm();
    if d > 1e-6 {
        let u = diff / d;
        u.dot(&(cov * u))
    } else {
        f64::NAN
    }
}

/// Eq. 4–5 over (d, RSSI) pairs with the 1/a → ε guard; returns (a, b, σ̂²_v), the residual
/// variance with two degrees of freedom removed. `None` with fewer than [`MIN_PAIRS`].
pub fn fit(pairs: impl Iterator<Item = (f64, f64)> + Clone, epsilon: f64) -> Option<(f64, f64, f64)> {
    let n = pairs.clone().count();
    if n < MIN_PAIRS {
        return None;
    }
    let nf = n as f64;
    let (mut sd, mut sr, mut sdd, mut sdr) = (0.0, 0.0, 0.0, 0.0);
    for (d, r) in pairs.clone() {
        sd += d;
        sr += r;
        sdd += d * d;
        sdr += d * r;
    }
    let (dbar, rbar) = (sd / nf, sr / nf);
    let num = sdr - rbar * sd;
    let den = sdd - dbar * sd;
    if num == 0.0 && den == 0.0 {
        // No spread in distance and no trend: nothing to fit.
        return None;
    }
    // 1/a = den / num; when it tends to 0 (a steep or undefined slope) clamp it to ±ε.
    let inv_a = if num == 0.0 { f64::INFINITY } else { den / num };
    let a = if inv_a.is_infinite() || inv_a.is_nan() {
        // No RSSI trend (num = 0): flat model.
        0.0
    } else if inv_a.abs() < epsilon {
        let sign = if num * den < 0.0 { -1.0 } else { 1.0 };
        sign / epsilon
    } else {
        1.0 / inv_a
    };
    let b = rbar - a * dbar;
    let sse: f64 = pairs.map(|(d, r)| (r - a * d - b).powi(2)).sum();
    Some((a, b, sse / (nf - 2.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_line() {
        let pairs: Vec<_> = (0..10)
            .map(|i| (1.0 + i as f64 * 0.3, -40.0 - 5.0 * (1.0 + i as f64 * 0.3)))
            .collect();
        let (a, b, v) = fit(pairs.iter().copied(), 1e-3).unwrap();
        assert!((a + 5.0).abs() < 1e-9 && (b + 40.0).abs() < 1e-9 && v < 1e-18);
        assert!(fit(pairs[..3].iter().copied(), 1e-3).is_none());
    }

    #[test]
    fn epsilon_guard_clamps_steep_slopes() {
        // Almost no spread in distance but a strong RSSI trend: 1/a ≈ −1e-5 → a = −1/ε.
        let pairs: Vec<_> = (0..4)
            .map(|i| (2.0 + 1e-5 * i as f64, -50.0 - i as f64))
            .collect();
        let (a, b, _) = fit(pairs.iter().copied(), 1e-2).unwrap();
        assert!((a + 100.0).abs() < 1e-9, "{a}");
        let (dbar, rbar) = (2.0 + 1.5e-5, -51.5);
        assert!((b - (rbar - a * dbar)).abs() < 1e-9);
        // No spread and no trend: nothing to fit.
        assert!(fit([(2.0, -50.0); 4].iter().copied(), 1e-2).is_none());
    }

    #[test]
    fn algorithm_1_chooses_default_when_distance_is_uncertain() {
        let default = RssiModel::default();
        let mut good = RssiTrainer::new(default, 10, 1e-3);
        let mut bad = RssiTrainer::new(default, 10, 1e-3);
        for i in 0..10 {
            let d = 2.0 + 0.1 * i as f64;
            let r = -50.0 - 6.0 * d + if i % 2 == 0 { 0.5 } else { -0.5 };
            good.push(d, r, 0.01);
            bad.push(d, r, 4.0); // 2 m of distance error: a²σ²_u = 144 > 16
        }
        assert!(
            matches!(good.choice(), Choice::Trained { .. }),
            "{:?}",
            good.choice()
        );
        assert!(matches!(good.model(), RssiModel::Linear { .. }));
        assert!(matches!(bad.choice(), Choice::Default { .. }));
        assert_eq!(bad.model(), default);
        assert_eq!(good.pairs(), 10);
        // The window keeps the last M.
        good.push(3.0, -70.0, 0.01);
        assert_eq!(good.pairs(), 10);
    }

    #[test]
    fn a_trained_line_gives_way_while_the_distance_is_uncertain_and_returns_after() {
        let default = RssiModel::default();
        let mut t = RssiTrainer::new(default, 10, 1e-3);
        for i in 0..10 {
            let d = 2.0 + 0.1 * i as f64;
            t.push(d, -50.0 - 6.0 * d + if i % 2 == 0 { 0.5 } else { -0.5 }, 0.01);
        }
        let trained = t.model();
        assert!(matches!(t.choice(), Choice::Trained { .. }));
        // The window's σ²_u rules while the filter is at least as sure as it was.
        t.recheck(0.001);
        assert_eq!(t.model(), trained);
        t.recheck(f64::NAN);
        assert_eq!(t.model(), trained);
        // Cameras lost: 2 m of distance error, a²σ²_u = 144 > σ²_D = 16.
        t.recheck(4.0);
        assert!(matches!(t.choice(), Choice::Default { .. }), "{:?}", t.choice());
        assert_eq!(t.model(), default);
        // A pair added in that step refits but keeps the re-check's σ²_u.
        t.push(2.5, -65.0, 0.01);
        assert!(matches!(t.choice(), Choice::Default { .. }), "{:?}", t.choice());
        // Cameras back: a line again.
        t.recheck(0.01);
        assert!(matches!(t.choice(), Choice::Trained { .. }), "{:?}", t.choice());
        assert_eq!(t.pairs(), 10);
        // Untrained stays untrained.
        let mut fresh = RssiTrainer::new(default, 10, 1e-3);
        fresh.recheck(0.0);
        assert_eq!(fresh.choice(), Choice::Untrained);
    }
}
