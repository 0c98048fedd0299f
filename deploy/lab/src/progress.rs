//! Progress of long studies, for whoever shows it: the library says what it finished, the
//! binary decides whether and how to show it (a terminal's progress bar, or nothing). One
//! process-wide observer, set once by the binary; without one, telling is a no-op.

use std::sync::OnceLock;

/// Something a long study finished.
#[derive(Clone, Debug, PartialEq)]
pub enum Step<'a> {
    /// One simulated run of a method: its label and seed.
    Run { method: &'a str, seed: u64 },
}

type Observer = Box<dyn Fn(&Step<'_>) + Send + Sync>;

static OBSERVER: OnceLock<Observer> = OnceLock::new();

/// Call `observer` for every step from now on. Only the first call takes effect (it returns
/// `false` for the others): the binary sets it once, at start.
pub fn observe(observer: impl Fn(&Step<'_>) + Send + Sync + 'static) -> bool {
    OBSERVER.set(Box::new(observer)).is_ok()
}

/// Tell the observer, if any, that `step` is done.
pub fn tell(step: &Step<'_>) {
    if let Some(o) = OBSERVER.get() {
        o(step);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    #[test]
    fn the_first_observer_hears_every_step_and_a_second_is_refused() {
        static SEEDS: AtomicU64 = AtomicU64::new(0);
        tell(&Step::Run {
            method: "before",
            seed: 100,
        });
        assert!(observe(|Step::Run { seed, .. }| {
            SEEDS.fetch_add(*seed, Ordering::SeqCst);
        }));
        assert!(!observe(|_| {}));
        tell(&Step::Run { method: "a", seed: 1 });
        tell(&Step::Run { method: "b", seed: 2 });
        assert_eq!(SEEDS.load(Ordering::SeqCst), 3);
    }
}
