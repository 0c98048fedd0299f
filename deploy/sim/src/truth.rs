//! The simulated world's targets as a report's truth: where each one truly was at a cluster
//! time, for scoring a simulated (or locally launched) run. Only the lab and the launcher read
//! it; no node does.

use node_server::report::Truth;
use proto::ClusterTime;
use proto::scenario::{Scenario, ScenarioError};
use world::Target;

/// The targets of a scenario whose time 0 was cluster time `t0`.
#[derive(Clone, Debug)]
pub struct WorldTruth {
    targets: Vec<Target>,
    t0_s: f64,
}

impl WorldTruth {
    /// # Errors
    /// The scenario's targets do not parse.
    pub fn new(scenario: &Scenario, t0: ClusterTime) -> Result<WorldTruth, ScenarioError> {
        Ok(WorldTruth {
            targets: world::targets(scenario)?,
            t0_s: t0.as_secs_f64(),
        })
    }

    /// Truth for the report if the scenario has targets, none otherwise.
    ///
    /// # Errors
    /// As [`WorldTruth::new`].
    pub fn of(scenario: &Scenario, t0: ClusterTime) -> Result<Option<WorldTruth>, ScenarioError> {
        let t = WorldTruth::new(scenario, t0)?;
        Ok((!t.targets.is_empty()).then_some(t))
    }

    pub fn targets(&self) -> &[Target] {
        &self.targets
    }
}

impl Truth for WorldTruth {
    fn ids(&self) -> Vec<u32> {
        self.targets.iter().map(|t| t.id).collect()
    }

    fn position(&self, index: usize, t: f64) -> [f64; 3] {
        let p = self.targets[index].position_at(t - self.t0_s);
        [p.x, p.y, p.z]
    }
}
