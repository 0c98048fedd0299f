//! Cluster time: nanoseconds on the leader's time base, as kept by FTSP-style sync.
//!
//! Node logic never reads a clock: runtimes pass the current `ClusterTime` in.

use serde::{Deserialize, Serialize};
use std::ops::{Add, Sub};

/// A point in cluster time, nanoseconds since the cluster epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ClusterTime(pub i64);

impl ClusterTime {
    pub const ZERO: ClusterTime = ClusterTime(0);

    pub fn from_secs_f64(s: f64) -> Self {
        ClusterTime((s * 1e9).round() as i64)
    }

    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }

    pub fn from_millis(ms: i64) -> Self {
        ClusterTime(ms * 1_000_000)
    }

    /// The host's wall clock as cluster time: nanoseconds since the Unix epoch. For process
    /// runtimes only (clippy.toml forbids it in node cores, like `SystemTime::now`): processes
    /// on one host agree on it, and the server's sync beacons correct it across hosts.
    #[allow(clippy::disallowed_methods)] // the one place the wall clock is read
    pub fn wall_clock() -> ClusterTime {
        let ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        ClusterTime(i64::try_from(ns).unwrap_or(i64::MAX))
    }

    /// Signed duration `self - earlier` in seconds.
    pub fn secs_since(self, earlier: ClusterTime) -> f64 {
        // Saturating (`Sub`): stamps come off the wire, and a garbage one must not overflow.
        (self - earlier) as f64 * 1e-9
    }
}

/// Nanosecond offsets.
impl Add<i64> for ClusterTime {
    type Output = ClusterTime;
    fn add(self, ns: i64) -> ClusterTime {
        ClusterTime(self.0.saturating_add(ns))
    }
}

impl Sub for ClusterTime {
    type Output = i64;
    fn sub(self, other: ClusterTime) -> i64 {
        self.0.saturating_sub(other.0)
    }
}
