//! A launch's acoustic nodes: those of a grid-fusing scenario without a fingerprint file get
//! the simulated room's survey before the run.

use anyhow::Result;
use proto::scenario::Scenario;
use std::path::Path;

/// A grid-fusing scenario's acoustic nodes without a fingerprint file get the simulated room's
/// survey (`sim::acoustic::survey`), written to the run directory, as a deployment would
/// survey its room with `ocelli acoustic survey` before the run.
///
/// # Errors
/// A survey that cannot be made or written.
pub fn with_fingerprints(mut scenario: Scenario, run_dir: &Path) -> Result<Scenario> {
    if scenario.method.fusion != proto::scenario::Fusion::Grid {
        return Ok(scenario);
    }
    let missing: Vec<u32> = scenario
        .acoustic_nodes()
        .filter(|n| n.acoustic.as_ref().is_some_and(|a| a.fingerprints.is_none()))
        .map(|n| n.id)
        .collect();
    for id in missing {
        let db =
            sim::acoustic::survey(&scenario, id).map_err(|e| anyhow::anyhow!("acoustic node {id}: {e}"))?;
        let path = run_dir.join(format!("fingerprints-{id}.json"));
        db.save(&path)?;
        if let Some(a) = scenario
            .nodes
            .iter_mut()
            .find(|n| n.id == id)
            .and_then(|n| n.acoustic.as_mut())
        {
            a.fingerprints = Some(path);
        }
    }
    Ok(scenario)
}
