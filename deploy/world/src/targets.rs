//! The simulated world's targets: where each one truly is over time (its trajectory), its
//! size and colour, and whether it carries a radio tag. Parsed from the scenario's
//! `[[targets]]` tables, which `proto` keeps opaque so that no node can read them.

use nalgebra::Vector3;
use proto::models::State;
use proto::scenario::{Scenario, ScenarioError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

/// A simulated target.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Target {
    pub id: u32,
    pub trajectory: Trajectory,
    /// Width, depth, height of the coloured solid, metres.
    pub size: [f64; 3],
    /// RGB colour of the solid.
    pub colour: [u8; 3],
    /// Whether it carries an RSSI tag.
    #[serde(default = "yes")]
    pub rssi_tag: bool,
}

fn yes() -> bool {
    true
}

/// Where a target is over time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", tag = "kind")]
pub enum Trajectory {
    /// Closed polygon of floor waypoints `[x, y]` driven at constant speed, starting at the first.
    Loop { waypoints: Vec<[f64; 2]>, speed: f64 },
    /// Open polyline, stopping at the end.
    Path { waypoints: Vec<[f64; 2]>, speed: f64 },
}

/// The targets of `scenario`, parsed and checked (unique ids, at least two finite waypoints, a
/// positive speed and size).
///
/// # Errors
/// A target table that does not parse, or fails a check, naming `targets[i]` and the field.
pub fn targets(scenario: &Scenario) -> Result<Vec<Target>, ScenarioError> {
    let bad = |field: String, problem: String| ScenarioError::Invalid {
        path: scenario.name.clone(),
        field,
        problem,
    };
    let mut out = Vec::with_capacity(scenario.targets.len());
    let mut ids = BTreeSet::new();
    for (i, table) in scenario.targets.iter().enumerate() {
        let t: Target = table
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| bad(format!("targets[{i}]"), e.message().to_string()))?;
        let field = |f: &str| format!("targets[id={}]{f}", t.id);
        if !ids.insert(t.id) {
            return Err(bad(field(""), "duplicate target id".into()));
        }
        let (w, s, _) = t.trajectory.parts();
        if w.len() < 2 {
            return Err(bad(
                field(".trajectory.waypoints"),
                format!("expected at least two waypoints, got {}", w.len()),
            ));
        }
        if !w.iter().flatten().all(|x| x.is_finite()) {
            return Err(bad(
                field(".trajectory.waypoints"),
                "expected finite [x, y] points".into(),
            ));
        }
        if !(s.is_finite() && s > 0.0) {
            return Err(bad(
                field(".trajectory.speed"),
                format!("expected a positive speed in m/s, got {s}"),
            ));
        }
        if !t.size.iter().all(|x| x.is_finite() && *x > 0.0) {
            return Err(bad(
                field(".size"),
                format!("expected positive width, depth, height, got {:?}", t.size),
            ));
        }
        out.push(t);
    }
    Ok(out)
}

/// Write `targets` into `scenario`'s target tables (experiments that build their world in
/// code).
///
/// # Panics
/// Never: targets always serialize to TOML tables.
pub fn set_targets(scenario: &mut Scenario, targets: &[Target]) {
    scenario.targets = targets
        .iter()
        .map(|t| toml::Table::try_from(t).expect("targets serialize to tables"))
        .collect();
}

impl Trajectory {
    /// The floor waypoints `[x, y]` it drives through.
    pub fn waypoints(&self) -> &[[f64; 2]] {
        self.parts().0
    }

    fn parts(&self) -> (&[[f64; 2]], f64, bool) {
        match self {
            Trajectory::Loop { waypoints, speed } => (waypoints, *speed, true),
            Trajectory::Path { waypoints, speed } => (waypoints, *speed, false),
        }
    }

    /// Floor position `[x, y]` and velocity `[vx, vy]` at `t` seconds after the start.
    pub fn at(&self, t: f64) -> ([f64; 2], [f64; 2]) {
        let (w, speed, closed) = self.parts();
        let n = if closed { w.len() } else { w.len() - 1 };
        let seg_len = |i: usize| {
            let (a, b) = (w[i], w[(i + 1) % w.len()]);
            ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt()
        };
        let total: f64 = (0..n).map(seg_len).sum();
        if total <= 0.0 {
            return (w[0], [0.0, 0.0]);
        }
        let mut s = (t.max(0.0) * speed).min(if closed { f64::INFINITY } else { total });
        if closed {
            s %= total;
        }
        for i in 0..n {
            let l = seg_len(i);
            if s <= l || i == n - 1 {
                let (a, b) = (w[i], w[(i + 1) % w.len()]);
                let f = if l > 0.0 { (s / l).min(1.0) } else { 0.0 };
                let moving = closed || t * speed < total;
                let v = if l > 0.0 && moving {
                    [(b[0] - a[0]) / l * speed, (b[1] - a[1]) / l * speed]
                } else {
                    [0.0, 0.0]
                };
                return ([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])], v);
            }
            s -= l;
        }
        (w[0], [0.0, 0.0])
    }
}

impl Target {
    /// Ground truth: the state `[X Y Z Vx Vy Vz]` of the target's centre at `t` seconds.
    pub fn truth_at(&self, t: f64) -> State {
        let ([x, y], [vx, vy]) = self.trajectory.at(t);
        State::new(x, y, self.size[2] * 0.5, vx, vy, 0.0)
    }

    /// The true centre at `t` seconds, metres.
    pub fn position_at(&self, t: f64) -> Vector3<f64> {
        let x = self.truth_at(t);
        Vector3::new(x[0], x[1], x[2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_written_back_parse_to_themselves() {
        let mut s = Scenario::default_scenario();
        let mut ts = targets(&s).unwrap();
        ts[0].trajectory = Trajectory::Path {
            waypoints: vec![[1.0, 1.0], [2.0, 3.0]],
            speed: 0.7,
        };
        set_targets(&mut s, &ts);
        assert_eq!(targets(&s).unwrap(), ts);
    }
}
