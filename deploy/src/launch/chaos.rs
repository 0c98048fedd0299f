//! The chaos mode of `ocelli launch` (`--chaos-every SECONDS`): the launcher itself SIGKILLs a
//! random node — a camera, a head, the server — at random times and its supervisor starts it
//! again. These kills are the launcher's own, so they never count towards giving up on a node
//! ([`Supervisor::chaos_kill`]); a real crash still does.
//!
//! [`Plan`] is the seeded, clock-free half (when the next kill is due, who it hits); [`Chaos`]
//! carries it out and writes each kill as one JSON line to `chaos.jsonl` in the run's folder
//! (`t_ns` cluster time, `node`, `pid`, and the recording's length at the kill,
//! `recording_bytes`), so a test can measure recovery and check nothing recorded was lost.

use crate::supervisor::{Event, Supervisor};
use anyhow::{Context, Result};
use proto::ClusterTime;
use rand::{Rng as _, RngCore as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// No kill in the last this-long of a launch with a duration: the run ends recovered.
pub const QUIET_BEFORE_END: Duration = Duration::from_secs(10);

/// What the chaos mode does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChaosOptions {
    /// The mean time between kills; each gap is uniform in half to one and a half of it.
    pub every: Duration,
    /// Chooses the victims and the gaps.
    pub seed: u64,
    /// No kill before this long after the nodes started (they come up, the target is found).
    pub after: Duration,
}

/// When kills are due (as offsets from the launch's start) and who they hit: the server one
/// kill in five, a head three in ten, a camera (or other sensor node) the rest, a role with no
/// node passing its share to the others.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Seeded like the simulated world's randomness: the same plan for the same seed.
    rng: ChaCha8Rng,
    every: Duration,
    next: Duration,
    /// No kill at or after this offset.
    until: Option<Duration>,
}

impl Plan {
    pub fn new(opts: &ChaosOptions, duration: Option<Duration>) -> Plan {
        let mut plan = Plan {
            rng: ChaCha8Rng::seed_from_u64(opts.seed),
            every: opts.every,
            next: Duration::ZERO,
            until: duration.map(|d| d.saturating_sub(QUIET_BEFORE_END)),
        };
        plan.next = opts.after + plan.gap();
        plan
    }

    fn gap(&mut self) -> Duration {
        self.every.mul_f64(0.5 + self.rng.random::<f64>())
    }

    /// Whether a kill is due `elapsed` into the launch (then the next one is scheduled).
    pub fn due(&mut self, elapsed: Duration) -> bool {
        if elapsed < self.next || self.until.is_some_and(|u| elapsed >= u) {
            return false;
        }
        self.next = elapsed + self.gap();
        true
    }

    /// The node to kill among `names` (the viewer is never one).
    pub fn victim<'a>(&mut self, names: &[&'a str]) -> Option<&'a str> {
        let of = |prefix: &str| -> Vec<&'a str> {
            names.iter().copied().filter(|n| n.starts_with(prefix)).collect()
        };
        let sensors: Vec<&str> = names
            .iter()
            .copied()
            .filter(|n| !n.starts_with("server-") && !n.starts_with("head-") && *n != "viewer")
            .collect();
        let groups = [(0.2, of("server-")), (0.3, of("head-")), (0.5, sensors)];
        let total: f64 = groups.iter().filter(|(_, g)| !g.is_empty()).map(|(w, _)| w).sum();
        let mut draw = self.rng.random::<f64>() * total;
        let pick = self.rng.next_u64();
        for (w, g) in groups.iter().filter(|(_, g)| !g.is_empty()) {
            if draw < *w {
                return Some(g[(pick % g.len() as u64) as usize]);
            }
            draw -= w;
        }
        None
    }
}

/// The chaos mode at work in a launch.
#[derive(Debug)]
pub struct Chaos {
    plan: Plan,
    log: PathBuf,
    recording: PathBuf,
}

impl Chaos {
    /// # Errors
    /// The kill log cannot be created.
    pub fn new(
        opts: &ChaosOptions,
        duration: Option<Duration>,
        run: &Path,
        recording: &Path,
    ) -> Result<Chaos> {
        let log = run.join("chaos.jsonl");
        std::fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        Ok(Chaos {
            plan: Plan::new(opts, duration),
            log,
            recording: recording.to_path_buf(),
        })
    }

    /// Kill a node if one is due `elapsed` into the launch; the supervisor's event.
    ///
    /// # Errors
    /// The kill cannot be written to the log.
    pub fn strike(&mut self, sup: &mut Supervisor, elapsed: Duration, now: Instant) -> Result<Option<Event>> {
        if !self.plan.due(elapsed) {
            return Ok(None);
        }
        let names: Vec<String> = sup
            .children_mut()
            .iter_mut()
            .filter_map(|c| c.running().then(|| c.name.clone()))
            .collect();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let Some(victim) = self.plan.victim(&refs) else {
            return Ok(None);
        };
        let Some(event) = sup.chaos_kill(victim, now) else {
            return Ok(None);
        };
        #[allow(clippy::disallowed_methods)] // the launcher is a runtime: it owns the clock
        let t = ClusterTime::wall_clock();
        let Event::ChaosKilled { name, pid, .. } = &event else {
            return Ok(Some(event));
        };
        let bytes = std::fs::metadata(&self.recording).map_or(0, |m| m.len());
        let line = serde_json::json!({"t_ns": t.0, "node": name, "pid": pid, "recording_bytes": bytes});
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&self.log)
            .with_context(|| format!("opening {}", self.log.display()))?;
        writeln!(f, "{line}").with_context(|| format!("writing {}", self.log.display()))?;
        Ok(Some(event))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(seed: u64) -> ChaosOptions {
        ChaosOptions {
            every: Duration::from_secs(4),
            seed,
            after: Duration::from_secs(10),
        }
    }

    /// The kill offsets (whole seconds) of a plan over `seconds`.
    fn kills(plan: &mut Plan, seconds: u64) -> Vec<u64> {
        (0..seconds * 10)
            .map(|ds| Duration::from_millis(ds * 100))
            .filter(|&t| plan.due(t))
            .map(|t| t.as_secs())
            .collect()
    }

    #[test]
    fn kills_wait_for_the_warm_up_keep_their_gaps_and_stop_before_the_end() {
        let mut plan = Plan::new(&opts(1), Some(Duration::from_secs(60)));
        let at = kills(&mut plan, 60);
        assert!(at.len() >= 6, "{at:?}");
        assert!(at[0] >= 12 && *at.last().unwrap() < 50, "{at:?}");
        assert!(
            at.windows(2).all(|w| w[1] - w[0] >= 1 && w[1] - w[0] <= 7),
            "{at:?}"
        );
        // Seeded: the same plan again, another with another seed.
        assert_eq!(
            kills(&mut Plan::new(&opts(1), Some(Duration::from_secs(60))), 60),
            at
        );
        assert_ne!(
            kills(&mut Plan::new(&opts(2), Some(Duration::from_secs(60))), 60),
            at
        );
    }

    #[test]
    fn victims_are_every_role_but_never_the_viewer() {
        let names = ["server-1", "head-2", "head-3", "camera-10", "camera-11", "viewer"];
        let mut plan = Plan::new(&opts(7), None);
        let mut hit = std::collections::BTreeMap::<&str, u32>::new();
        for _ in 0..2000 {
            *hit.entry(plan.victim(&names).unwrap()).or_default() += 1;
        }
        assert!(!hit.contains_key("viewer"), "{hit:?}");
        assert_eq!(hit.len(), 5, "{hit:?}");
        assert!((300..500).contains(&hit["server-1"]), "{hit:?}");
        assert_eq!(plan.victim(&["viewer"]), None);
        assert_eq!(plan.victim(&["camera-10"]), Some("camera-10"));
    }
}
