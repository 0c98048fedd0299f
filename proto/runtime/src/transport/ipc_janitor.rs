//! The domain's janitor: removes what dead iceoryx2 nodes left in `/dev/shm`, all the time, not
//! only when a node starts.
//!
//! iceoryx2 removes a dead node's files (its publishers' data segments, its connections, its
//! place in every service) only when some process creates a node, and then within a time limit
//! (`blocking_cleanup_dead_nodes`). Measured under `launch --chaos-every 1.2` with three
//! launches on two cores, that is not enough: a dead server holds about a hundred port and
//! service tags, its cleanup outlasts the limit (or its cleaner is itself killed), and its
//! segments stay until the next node of the domain starts — on a host where nothing crashes
//! again, for ever. The domain then held 256 → 300 files. So every process sweeps: a thread
//! lists the domain's nodes now and then and removes the stale resources of each dead one.
//! iceoryx2's cleaner lock makes concurrent sweeps of the same dead node safe (one wins, the
//! others hear "another instance is cleaning up" and try again at their next sweep).

use iceoryx2::node::{NodeCleanupFailure, NodeState};
use iceoryx2::prelude::*;
use iceoryx2::service::Service;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

/// How often a process of a small domain sweeps, on average. Each process offsets its period
/// by a hash of its pid so a host's sweeps spread out (a launch's processes have consecutive
/// pids); a sweep lists the domain's nodes (a few files per node).
pub(super) const SWEEP_PERIOD: Duration = Duration::from_secs(3);

/// Live iceoryx2 nodes per [`SWEEP_PERIOD`] a process's sweeps may find, on average: a
/// process that found more waits longer before its next sweep. Every process sweeping every period costs a
/// domain its size squared — in a 106-process hall the janitors took 0.35 of the cameras' 0.9
/// cores, a sweep of that domain about 10 ms — while one sweep finds every dead node of the
/// domain, whoever runs it. With this, a domain of `n` processes still sees about
/// `NODES_PER_PERIOD / 2` sweeps a period however large (each process holds about two nodes),
/// and one of fewer nodes than that sweeps every period as before.
pub(super) const NODES_PER_PERIOD: usize = 16;

/// What one sweep did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Swept {
    /// Dead nodes whose resources this sweep removed.
    pub cleaned: u64,
    /// Dead nodes another process was cleaning up, or had just cleaned.
    pub busy: u64,
    /// Dead nodes whose cleanup failed; tried again at the next sweep.
    pub failed: u64,
    /// Nodes of the domain the sweep listed, alive or dead (the dead ones it cleaned included).
    pub listed: usize,
}

/// Remove the stale resources of every dead node of `config`'s domain.
pub(super) fn sweep<S: Service>(config: &Config) -> Swept {
    let mut dead = Vec::new();
    let mut listed = 0;
    let listing = Node::<S>::list(config, |state| {
        listed += 1;
        if let NodeState::Dead(view) = state {
            dead.push(view);
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listing {
        tracing::debug!(error = ?e, "could not list the domain's iceoryx2 nodes");
    }
    let mut swept = Swept {
        listed,
        ..Swept::default()
    };
    for view in dead {
        match view.try_remove_stale_resources() {
            Ok(()) => swept.cleaned += 1,
            Err(
                NodeCleanupFailure::AnotherInstanceIsCleaningUpTheNode
                | NodeCleanupFailure::ResourcesAlreadyCleanedUp,
            ) => swept.busy += 1,
            Err(e) => {
                tracing::debug!(error = ?e, "a dead node's cleanup failed");
                swept.failed += 1;
            }
        }
    }
    swept
}

/// The janitor thread's body: sweep until `stop` is dropped, waiting [`next_wait`] this
/// process and the nodes the last sweep found alive.
pub(super) fn run<S: Service>(config: Config, pid: u32, stop: Receiver<()>) {
    let mut period = period_for(pid, 0);
    let mut first = true;
    loop {
        match stop.recv_timeout(period) {
            Err(RecvTimeoutError::Timeout) => {}
            Ok(()) | Err(RecvTimeoutError::Disconnected) => return,
        }
        let swept = sweep::<S>(&config);
        if swept.cleaned > 0 || swept.failed > 0 {
            tracing::info!(
                cleaned = swept.cleaned,
                failed = swept.failed,
                busy = swept.busy,
                "removed stale iceoryx2 resources of dead nodes"
            );
        }
        // The nodes still there: a domain that had many dead ones is not swept less for them.
        let live = swept
            .listed
            .saturating_sub(usize::try_from(swept.cleaned).unwrap_or(usize::MAX));
        period = next_wait(pid, live, first);
        first = false;
    }
}

/// Longest stretch of a process's sweep period: one odd listing cannot stall its sweeps for
/// minutes.
const MAX_STRETCH: f64 = 20.0;

/// A fraction in [0, 1) from `pid` (Fibonacci hashing with `factor`: consecutive pids land far
/// apart).
fn fraction(pid: u32, factor: u32) -> f64 {
    f64::from(pid.wrapping_mul(factor) >> 22) / 1024.0
}

/// Process `pid`'s wait before its next sweep when its last one found `live` nodes:
/// [`SWEEP_PERIOD`], stretched by `live / NODES_PER_PERIOD` when that is more than one (at
/// most [`MAX_STRETCH`]), ± a third by a hash of the pid.
pub(super) fn period_for(pid: u32, live: usize) -> Duration {
    let stretch = (live as f64 / NODES_PER_PERIOD as f64).clamp(1.0, MAX_STRETCH);
    let mean = SWEEP_PERIOD.mul_f64(stretch);
    mean.mul_f64(2.0 / 3.0 + fraction(pid, 2_654_435_769) * 2.0 / 3.0)
}

/// The wait after a sweep that found `live` nodes. After a process's first sweep it is a
/// pid-hashed share of [`period_for`]: a launch's processes all start together, so their first
/// sweeps fall within the same second, and a whole stretched period of the same length after
/// them would leave the domain unswept for most of it.
pub(super) fn next_wait(pid: u32, live: usize, first: bool) -> Duration {
    let period = period_for(pid, live);
    if first {
        period.mul_f64(fraction(pid, 2_246_822_519))
    } else {
        period
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_spread_around_the_mean() {
        for (live, mean) in [
            (0, SWEEP_PERIOD),
            (NODES_PER_PERIOD, SWEEP_PERIOD),
            (4 * NODES_PER_PERIOD, SWEEP_PERIOD * 4),
        ] {
            // A launch's processes: consecutive pids.
            let periods: Vec<Duration> = (4000..4100).map(|pid| period_for(pid, live)).collect();
            let lo = *periods.iter().min().unwrap();
            let hi = *periods.iter().max().unwrap();
            assert!(lo >= mean * 2 / 3 && lo < mean * 3 / 4, "{live}: {lo:?}");
            assert!(hi < mean * 4 / 3 && hi > mean * 5 / 4, "{live}: {hi:?}");
        }
        // However many nodes, at most MAX_STRETCH periods.
        assert!(period_for(1, usize::MAX) < SWEEP_PERIOD.mul_f64(MAX_STRETCH * 4.0 / 3.0));
    }

    #[test]
    fn a_large_domain_is_swept_as_often_as_a_small_one() {
        // Processes of two iceoryx2 nodes each, consecutive pids.
        let rate = |processes: u32| -> f64 {
            (9000..9000 + processes)
                .map(|pid| SWEEP_PERIOD.as_secs_f64() / period_for(pid, 2 * processes as usize).as_secs_f64())
                .sum()
        };
        let want = NODES_PER_PERIOD as f64 / 2.0;
        assert!(
            (rate(want as u32) - want).abs() < 0.2 * want,
            "{}",
            rate(want as u32)
        );
        for processes in [20, 106, 150] {
            let got = rate(processes);
            assert!(
                (got - want).abs() < 0.2 * want,
                "{processes} processes: {got:.2} sweeps a period"
            );
        }
        // A small domain: every process every period, as before.
        assert!((rate(4) - 4.0).abs() < 0.2 * 4.0, "{}", rate(4));
    }

    #[test]
    fn a_launch_leaves_no_long_unswept_gap() {
        // 106 processes started together (consecutive pids), 212 nodes: every sweep of the
        // domain in its first two minutes, as `run` schedules them.
        let mut sweeps: Vec<f64> = Vec::new();
        for pid in 7000..7106u32 {
            let mut t = period_for(pid, 0).as_secs_f64();
            let mut first = true;
            while t < 120.0 {
                sweeps.push(t);
                t += next_wait(pid, 212, first).as_secs_f64();
                first = false;
            }
        }
        sweeps.sort_by(f64::total_cmp);
        let longest = sweeps.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        assert!(longest < 3.0, "the domain went {longest:.1} s unswept");
        assert!(sweeps[0] < 4.0);
    }
}
