//! A scenario made ready for its simulated world before a run (`ocelli sim`, `launch`, the
//! experiments): the default RSSI model fitted to the simulated room when the scenario asks
//! (`method.rssi-survey`, paper 002 §VI), and what the method must know of the targets but a
//! real deployment states itself (`method.target-plane-z`, `method.target-colours`) filled in
//! from them when left out. Every node of the run then reads the same prepared scenario.

use crate::radio::surveyed;
use crate::targets::targets;
use proto::scenario::{Scenario, ScenarioError};

/// `scenario` prepared for a run with `seed`.
///
/// # Errors
/// The targets do not parse.
pub fn prepare(scenario: &Scenario, seed: u64) -> Result<Scenario, ScenarioError> {
    let mut out = surveyed(scenario, seed);
    let targets = targets(scenario)?;
    if out.method.target_plane_z.is_none()
        && let Some(first) = targets.first()
    {
        out.method.target_plane_z = Some(first.size[2] * 0.5);
    }
    if out.method.target_colours.is_empty() {
        out.method.target_colours = targets.iter().map(|t| t.colour).collect();
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_fill_only_what_the_method_leaves_out() {
        let s = Scenario::default_scenario();
        let p = prepare(&s, 1).unwrap();
        assert_eq!(
            p.method.target_plane_z,
            Some(0.25),
            "half the robot's 0.5 m height"
        );
        assert_eq!(p.method.target_colours, vec![[220, 40, 30]]);
        let mut own = s.clone();
        own.method.target_plane_z = Some(0.9);
        own.method.target_colours = vec![[1, 2, 3]];
        let p = prepare(&own, 1).unwrap();
        assert_eq!(p.method.target_plane_z, Some(0.9));
        assert_eq!(p.method.target_colours, vec![[1, 2, 3]]);
    }
}
