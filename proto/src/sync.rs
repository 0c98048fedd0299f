//! Time sync, follower side: the estimator every node runs on the leader's beacons (FTSP,
//! paper 000 §6.1.3; Maróti et al. 2004).
//!
//! The leader (the server) broadcasts [`SyncBeacon`](crate::msg::SyncBeacon)s carrying its
//! cluster time. A follower pairs each beacon with its own local clock reading at receipt and
//! fits `leader − local = offset + drift · (local − local̄)` by least squares over the last
//! [`SyncEstimator::window`] pairs. [`SyncEstimator::to_cluster`] maps a local reading to
//! cluster time; [`SyncEstimator::error_ns`] is the RMS residual of the fit, the visible sync
//! error each node reports in `NodeStatus.sync_error_ns`.
//!
//! Sans-IO: the caller passes both clock readings in; nothing here reads a clock.

use crate::time::ClusterTime;
use std::collections::VecDeque;
use thiserror::Error;

/// Default regression window (FTSP uses 8 beacons).
pub const DEFAULT_WINDOW: usize = 8;

/// A beacon whose offset misses the current fit by more than this is taken as a leader restart
/// or clock step: the window is cleared and the fit restarts from that beacon.
pub const DEFAULT_RESET_THRESHOLD_NS: i64 = 50_000_000;

/// Why a beacon pair was not used. The estimator's state is unchanged.
#[derive(Debug, Error, PartialEq, Eq, Clone)]
pub enum SyncError {
    #[error("local receipt time {local_ns} ns is not after the previous one ({previous_ns} ns)")]
    LocalNotIncreasing { local_ns: i64, previous_ns: i64 },
    #[error("leader time {leader_ns} ns is not after the previous beacon's ({previous_ns} ns)")]
    LeaderNotIncreasing { leader_ns: i64, previous_ns: i64 },
}

/// Least-squares offset and drift of the local clock against the leader's.
#[derive(Clone, Debug)]
pub struct SyncEstimator {
    window: usize,
    reset_threshold_ns: i64,
    /// `(local_ns, leader_ns)` pairs, oldest first.
    pairs: VecDeque<(i64, i64)>,
    /// `leader − predicted` at each of the last `window` beacons, ns.
    innovations: VecDeque<f64>,
    fit: Option<Fit>,
    resets: u64,
    rejected: u64,
}

/// `leader − local = offset_at_ref + drift · (local − ref_local)`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fit {
    ref_local: i64,
    offset_at_ref: f64,
    drift: f64,
    rms_residual_ns: Option<f64>,
}

impl Default for SyncEstimator {
    fn default() -> Self {
        SyncEstimator::new(DEFAULT_WINDOW)
    }
}

impl SyncEstimator {
    /// An estimator regressing over the last `window` beacons (at least 2).
    pub fn new(window: usize) -> Self {
        SyncEstimator {
            window: window.max(2),
            reset_threshold_ns: DEFAULT_RESET_THRESHOLD_NS,
            pairs: VecDeque::new(),
            innovations: VecDeque::new(),
            fit: None,
            resets: 0,
            rejected: 0,
        }
    }

    /// Change the jump that makes the estimator restart its fit.
    pub fn with_reset_threshold_ns(mut self, ns: i64) -> Self {
        self.reset_threshold_ns = ns.max(1);
        self
    }

    pub fn window(&self) -> usize {
        self.window
    }

    /// Beacons currently in the regression.
    pub fn samples(&self) -> usize {
        self.pairs.len()
    }

    /// How many times a jump cleared the window.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// Beacon pairs refused as out of order.
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// Whether at least one beacon has been heard.
    pub fn is_synced(&self) -> bool {
        self.fit.is_some()
    }

    /// Feed one beacon: the local clock at receipt and the leader time it carried.
    ///
    /// # Errors
    /// [`SyncError`] if either clock did not advance since the previous beacon; the pair is
    /// counted as rejected and changes nothing.
    pub fn observe(&mut self, local_ns: i64, leader: ClusterTime) -> Result<(), SyncError> {
        if let Some(&(prev_local, prev_leader)) = self.pairs.back() {
            if local_ns <= prev_local {
                self.rejected += 1;
                return Err(SyncError::LocalNotIncreasing {
                    local_ns,
                    previous_ns: prev_local,
                });
            }
            if leader.0 <= prev_leader {
                self.rejected += 1;
                return Err(SyncError::LeaderNotIncreasing {
                    leader_ns: leader.0,
                    previous_ns: prev_leader,
                });
            }
        }
        let predicted = self.predict(local_ns).unwrap_or(ClusterTime(local_ns));
        self.innovations.push_back((leader.0 - predicted.0) as f64);
        while self.innovations.len() > self.window {
            self.innovations.pop_front();
        }
        if self.fit.is_some() && (leader.0 - predicted.0).abs() > self.reset_threshold_ns {
            self.pairs.clear();
            self.resets += 1;
        }
        self.pairs.push_back((local_ns, leader.0));
        while self.pairs.len() > self.window {
            self.pairs.pop_front();
        }
        self.fit = Some(self.regress());
        Ok(())
    }

    fn regress(&self) -> Fit {
        let n = self.pairs.len() as f64;
        let ref_local = self.pairs.back().map_or(0, |p| p.0);
        // Centre on the newest local reading so the numbers stay small (ns differences fit f64
        // exactly for windows far below 2^53 ns ≈ 104 days).
        let xs: Vec<f64> = self.pairs.iter().map(|p| (p.0 - ref_local) as f64).collect();
        let ys: Vec<f64> = self.pairs.iter().map(|p| (p.1 - p.0) as f64).collect();
        let xm = xs.iter().sum::<f64>() / n;
        let ym = ys.iter().sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| (x - xm).powi(2)).sum();
        let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - xm) * (y - ym)).sum();
        let drift = if self.pairs.len() >= 2 && sxx > 0.0 {
            sxy / sxx
        } else {
            0.0
        };
        let offset_at_ref = ym - drift * xm;
        // Residual with n − 2 degrees of freedom: meaningful from three beacons on.
        let rms_residual_ns = (self.pairs.len() >= 3).then(|| {
            let ss: f64 = xs
                .iter()
                .zip(&ys)
                .map(|(x, y)| (y - (offset_at_ref + drift * x)).powi(2))
                .sum();
            (ss / (n - 2.0)).sqrt()
        });
        Fit {
            ref_local,
            offset_at_ref,
            drift,
            rms_residual_ns,
        }
    }

    fn predict(&self, local_ns: i64) -> Option<ClusterTime> {
        let f = self.fit?;
        let offset = f.offset_at_ref + f.drift * (local_ns - f.ref_local) as f64;
        Some(ClusterTime(local_ns.saturating_add(offset.round() as i64)))
    }

    /// Cluster time at a local clock reading; `None` before the first beacon.
    pub fn to_cluster(&self, local_ns: i64) -> Option<ClusterTime> {
        self.predict(local_ns)
    }

    /// Current offset `leader − local` at `local_ns`, ns (0 before the first beacon).
    pub fn offset_ns(&self, local_ns: i64) -> i64 {
        self.predict(local_ns).map_or(0, |c| c.0 - local_ns)
    }

    /// Estimated drift of the leader against the local clock (dimensionless, e.g. 5e-5 = 50 ppm).
    pub fn drift(&self) -> f64 {
        self.fit.map_or(0.0, |f| f.drift)
    }

    /// The visible sync error: RMS over the last window of beacons of the node's cluster time
    /// minus the leader's at each beacon's arrival, before that beacon was fitted, ns. `None`
    /// before the first beacon.
    pub fn prediction_error_ns(&self) -> Option<f64> {
        (!self.innovations.is_empty()).then(|| {
            let ss: f64 = self.innovations.iter().map(|e| e * e).sum();
            (ss / self.innovations.len() as f64).sqrt()
        })
    }

    /// RMS residual of the regression, ns. `None` until three beacons are in the window.
    pub fn error_ns(&self) -> Option<f64> {
        self.fit.and_then(|f| f.rms_residual_ns)
    }

    /// A node's cluster time at local reading `local_ns`: the fit's, or the local reading
    /// itself before the first beacon. Every runtime (processes and the simulation) keeps its
    /// nodes' time this way.
    pub fn corrected(&self, local_ns: i64) -> ClusterTime {
        self.to_cluster(local_ns).unwrap_or(ClusterTime(local_ns))
    }

    /// What a node reports of its sync in `NodeStatus`: the offset at `local_ns` and the
    /// visible error ([`Self::prediction_error_ns`]), ns; the error is −1 before the first
    /// beacon.
    pub fn report(&self, local_ns: i64) -> (i64, i64) {
        (
            self.offset_ns(local_ns),
            self.prediction_error_ns().map_or(-1, |e| e.round() as i64),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A follower clock: `local = (true − offset) · (1 + skew)`; beacons are received after a
    /// random delay in `[0, jitter]`.
    struct Clock {
        offset_ns: f64,
        skew: f64,
    }

    impl Clock {
        fn local(&self, true_ns: i64) -> i64 {
            ((true_ns as f64 - self.offset_ns) * (1.0 + self.skew)).round() as i64
        }
    }

    fn run(skew: f64, jitter_ns: f64, beacons: usize, seed: u64) -> (SyncEstimator, Clock, ChaCha8Rng) {
        let clock = Clock {
            offset_ns: 3.7e9,
            skew,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut est = SyncEstimator::default();
        for k in 0..beacons {
            let sent = 10_000_000_000 + k as i64 * 1_000_000_000;
            let received = sent + rng.random_range(0.0..=jitter_ns) as i64;
            est.observe(clock.local(received), ClusterTime(sent)).unwrap();
        }
        (est, clock, rng)
    }

    #[test]
    fn error_falls_to_jitter_level_with_skew_and_drift() {
        let jitter = 100_000.0; // 100 µs of receive delay
        let (est, clock, mut rng) = run(80e-6, jitter, 20, 7);
        assert_eq!(est.samples(), DEFAULT_WINDOW);
        // Drift recovered to within a few ppm of the truth (leader − local slope ≈ −skew).
        assert!((est.drift() + 80e-6).abs() < 5e-6, "drift {}", est.drift());
        // Clock readings shortly after the last beacon map to true time within the jitter level.
        // (The delay is uniform in [0, jitter], so the fit is biased by its mean, jitter / 2.)
        let last = 10_000_000_000 + 19 * 1_000_000_000i64;
        for _ in 0..50 {
            let t = last + rng.random_range(0..500_000_000);
            let got = est.to_cluster(clock.local(t)).unwrap();
            assert!(((got.0 - t) as f64).abs() < jitter, "error {} ns", got.0 - t);
        }
        // The visible error is of the order of the jitter's spread (σ of U(0, J) ≈ 0.29 J).
        let e = est.error_ns().unwrap();
        assert!(e > 0.05 * jitter && e < jitter, "residual {e}");
    }

    #[test]
    fn without_regression_the_skew_would_dominate() {
        // Sanity for the test above: a pure-offset estimate from the first beacon is off by
        // skew × elapsed ≫ jitter after 20 s, so the regression is doing the work.
        let (est, clock, _) = run(80e-6, 100_000.0, 20, 11);
        let t = 10_000_000_000 + 19 * 1_000_000_000i64 + 400_000_000;
        let offset_first = 10_000_000_000 - clock.local(10_000_000_000);
        let naive = clock.local(t) + offset_first;
        assert!((naive - t).abs() > 1_000_000);
        assert!((est.to_cluster(clock.local(t)).unwrap().0 - t).abs() < 100_000);
    }

    #[test]
    fn prediction_error_is_the_offset_at_first_and_the_jitter_once_converged() {
        let jitter = 100_000.0;
        let (est, _, _) = run(80e-6, jitter, 1, 3);
        // Unsynchronized: the local clock is 3.7 s behind.
        let first = est.prediction_error_ns().unwrap();
        assert!((first - 3.7e9).abs() < 1e6, "first {first}");
        let (est, _, _) = run(80e-6, jitter, 4, 3);
        let early = est.prediction_error_ns().unwrap();
        assert!(early > 1e8, "still carries the first offset: {early}");
        // Once the window holds only fitted predictions, the error is of the jitter's order.
        let (est, _, _) = run(80e-6, jitter, 30, 3);
        let late = est.prediction_error_ns().unwrap();
        assert!(late > 0.05 * jitter && late < 2.0 * jitter, "late {late}");
        assert_eq!(SyncEstimator::default().prediction_error_ns(), None);
    }

    #[test]
    fn error_unknown_until_three_beacons() {
        let (est, _, _) = run(10e-6, 10_000.0, 2, 1);
        assert!(est.is_synced());
        assert_eq!(est.error_ns(), None);
        let (est, _, _) = run(10e-6, 10_000.0, 3, 1);
        assert!(est.error_ns().is_some());
    }

    #[test]
    fn out_of_order_pairs_are_rejected_and_change_nothing() {
        let mut est = SyncEstimator::default();
        est.observe(1_000, ClusterTime(5_000)).unwrap();
        est.observe(2_000, ClusterTime(6_000)).unwrap();
        let before = est.to_cluster(3_000);
        assert!(matches!(
            est.observe(2_000, ClusterTime(7_000)),
            Err(SyncError::LocalNotIncreasing { .. })
        ));
        assert!(matches!(
            est.observe(2_500, ClusterTime(6_000)),
            Err(SyncError::LeaderNotIncreasing { .. })
        ));
        assert_eq!(est.rejected(), 2);
        assert_eq!(est.samples(), 2);
        assert_eq!(est.to_cluster(3_000), before);
    }

    #[test]
    fn a_leader_jump_restarts_the_fit() {
        let mut est = SyncEstimator::default();
        for k in 0..5i64 {
            est.observe(k * 1_000_000_000, ClusterTime(k * 1_000_000_000 + 42))
                .unwrap();
        }
        // The leader restarts 10 s ahead.
        est.observe(5_000_000_000, ClusterTime(15_000_000_000)).unwrap();
        assert_eq!(est.resets(), 1);
        assert_eq!(est.samples(), 1);
        assert_eq!(est.offset_ns(5_000_000_000), 10_000_000_000);
    }
}
