//! A process's cluster clock: the host's wall clock (ns since the Unix epoch) corrected by the
//! offset and drift a `proto::sync::SyncEstimator` fits over the leader's beacons, exactly as
//! the simulation keeps its nodes' time. Processes on one host agree on the wall clock before
//! the first beacon; across hosts the beacons correct it.

use proto::ClusterTime;
use proto::sync::SyncEstimator;
use std::sync::{Arc, Mutex, MutexGuard};

/// A shareable cluster clock (the transport stamps heartbeats with it).
#[derive(Clone, Debug, Default)]
pub struct HostClock {
    sync: Arc<Mutex<SyncEstimator>>,
    /// The leader does not follow anyone: its cluster time is its host clock.
    leader: bool,
}

impl HostClock {
    /// A follower's clock, corrected by the beacons it is given.
    pub fn follower() -> HostClock {
        HostClock::default()
    }

    /// The leader's clock: the host clock, never corrected.
    pub fn leader() -> HostClock {
        HostClock {
            leader: true,
            ..HostClock::default()
        }
    }

    #[allow(clippy::disallowed_methods)] // the process runtime owns the clock
    fn host_ns() -> i64 {
        ClusterTime::wall_clock().0
    }

    fn estimator(&self) -> MutexGuard<'_, SyncEstimator> {
        self.sync.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The current cluster time.
    pub fn now(&self) -> ClusterTime {
        let host = Self::host_ns();
        if self.leader {
            return ClusterTime(host);
        }
        self.estimator().corrected(host)
    }

    /// Feed a beacon just received from the leader; returns the new estimate (offset, error,
    /// ns) for the node's status, or `None` if the beacon was not used (out of order, or this is
    /// the leader).
    pub fn observe(&self, leader_time: ClusterTime) -> Option<(i64, i64)> {
        if self.leader {
            return None;
        }
        let host = Self::host_ns();
        let mut s = self.estimator();
        match s.observe(host, leader_time) {
            Ok(()) => Some(s.report(host)),
            Err(e) => {
                tracing::debug!(error = %e, "sync beacon not used");
                None
            }
        }
    }

    /// The clock as the transports take it.
    pub fn for_transport(&self) -> crate::transport::Clock {
        let me = self.clone();
        Arc::new(move || me.now())
    }
}
