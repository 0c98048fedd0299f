//! Exponential reconnect backoff with jitter. The random draw is passed in, so tests are
//! deterministic and runtimes use an OS-seeded generator.

use rand::Rng;
use std::time::Duration;

/// Reconnect delay policy: `initial · factor^attempt`, capped at `max`, minus up to `jitter`
/// (a fraction in `[0, 1]`) of itself so that many nodes restarting together spread out.
#[derive(Clone, Debug, PartialEq)]
pub struct Backoff {
    pub initial: Duration,
    pub max: Duration,
    pub factor: f64,
    pub jitter: f64,
    attempt: u32,
}

impl Default for Backoff {
    fn default() -> Self {
        Backoff::new(Duration::from_millis(50), Duration::from_secs(2), 2.0, 0.3)
    }
}

impl Backoff {
    pub fn new(initial: Duration, max: Duration, factor: f64, jitter: f64) -> Self {
        Backoff {
            initial,
            max,
            factor: factor.max(1.0),
            jitter: jitter.clamp(0.0, 1.0),
            attempt: 0,
        }
    }

    /// The delay before attempt `attempt` without jitter.
    pub fn base_delay(&self, attempt: u32) -> Duration {
        let scaled = self.initial.as_secs_f64() * self.factor.powi(attempt.min(64) as i32);
        Duration::from_secs_f64(scaled.min(self.max.as_secs_f64()))
    }

    /// The next delay, with jitter drawn from `rng`; advances the attempt counter.
    pub fn next_delay(&mut self, rng: &mut impl Rng) -> Duration {
        let base = self.base_delay(self.attempt);
        self.attempt = self.attempt.saturating_add(1);
        let cut: f64 = rng.random_range(0.0..=self.jitter);
        base.mul_f64(1.0 - cut)
    }

    /// Call after a link came up: the next failure starts from `initial` again.
    pub fn reset(&mut self) {
        self.attempt = 0;
    }

    pub fn attempt(&self) -> u32 {
        self.attempt
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn base_delay_doubles_until_the_cap() {
        let b = Backoff::new(Duration::from_millis(10), Duration::from_millis(500), 2.0, 0.0);
        let d: Vec<u128> = (0..8).map(|a| b.base_delay(a).as_millis()).collect();
        assert_eq!(d, vec![10, 20, 40, 80, 160, 320, 500, 500]);
    }

    #[test]
    fn jitter_stays_within_its_fraction_and_reset_restarts() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut b = Backoff::new(Duration::from_millis(100), Duration::from_secs(10), 2.0, 0.5);
        let mut distinct = std::collections::BTreeSet::new();
        for attempt in 0..6 {
            let base = b.base_delay(attempt);
            let d = b.next_delay(&mut rng);
            assert!(
                d <= base && d >= base.mul_f64(0.5),
                "attempt {attempt}: {d:?} vs {base:?}"
            );
            distinct.insert(d.as_nanos() * 1000 / base.as_nanos());
        }
        assert!(distinct.len() > 1, "jitter never varied");
        assert_eq!(b.attempt(), 6);
        b.reset();
        assert!(b.next_delay(&mut rng) <= Duration::from_millis(100));
    }
}
