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

/// How often a process sweeps, on average. Each process offsets its period by its pid so a
/// host's sweeps spread out; a sweep lists the domain's nodes (a few files per node).
pub(super) const SWEEP_PERIOD: Duration = Duration::from_secs(3);

/// What one sweep did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Swept {
    /// Dead nodes whose resources this sweep removed.
    pub cleaned: u64,
    /// Dead nodes another process was cleaning up, or had just cleaned.
    pub busy: u64,
    /// Dead nodes whose cleanup failed; tried again at the next sweep.
    pub failed: u64,
}

/// Remove the stale resources of every dead node of `config`'s domain.
pub(super) fn sweep<S: Service>(config: &Config) -> Swept {
    let mut dead = Vec::new();
    let listed = Node::<S>::list(config, |state| {
        if let NodeState::Dead(view) = state {
            dead.push(view);
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listed {
        tracing::debug!(error = ?e, "could not list the domain's iceoryx2 nodes");
    }
    let mut swept = Swept::default();
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

/// The janitor thread's body: sweep every `period` until `stop` is dropped.
pub(super) fn run<S: Service>(config: Config, period: Duration, stop: Receiver<()>) {
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
    }
}

/// This process's sweep period: [`SWEEP_PERIOD`] ± a third, by pid.
pub(super) fn period_for(pid: u32) -> Duration {
    let third = SWEEP_PERIOD / 3;
    let spread = u64::from(pid % 1000) * 2 * third.as_millis() as u64 / 1000;
    SWEEP_PERIOD - third + Duration::from_millis(spread)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_spread_around_the_mean() {
        let periods: Vec<Duration> = (0..1000).map(period_for).collect();
        let lo = *periods.iter().min().unwrap();
        let hi = *periods.iter().max().unwrap();
        assert_eq!(lo, SWEEP_PERIOD - SWEEP_PERIOD / 3);
        assert!(hi < SWEEP_PERIOD + SWEEP_PERIOD / 3, "{hi:?}");
        assert!(hi > SWEEP_PERIOD, "{hi:?}");
    }
}
