//! The simulated world's targets: where each one truly is over time (its trajectory), its
//! size and colour, and whether it carries a radio tag. Parsed from the scenario's
//! `[[targets]]` tables, which `proto` keeps opaque so that no node can read them.
//! A trajectory may stop at some of its waypoints for a while (`pauses`): a person standing
//! still, the case a motion-segmenting camera loses and a tracker must coast through.

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
    Loop {
        waypoints: Vec<[f64; 2]>,
        speed: f64,
        /// Stops on the way, every lap (none by default).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pauses: Vec<Pause>,
    },
    /// Open polyline, stopping at the end.
    Path {
        waypoints: Vec<[f64; 2]>,
        speed: f64,
        /// Stops on the way (none by default).
        #[serde(default, skip_serializing_if = "Vec::is_empty")]
        pauses: Vec<Pause>,
    },
}

/// A stop: standing still at waypoint `at` (its index) for `seconds` each time it is reached
/// (a pause at waypoint 0 is taken at the start and, on a loop, at the start of every lap).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Pause {
    pub at: usize,
    pub seconds: f64,
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
        if let Some(p) = t
            .trajectory
            .pauses()
            .iter()
            .find(|p| p.at >= w.len() || !(p.seconds.is_finite() && p.seconds >= 0.0))
        {
            return Err(bad(
                field(".trajectory.pauses"),
                format!(
                    "expected a waypoint index below {} and seconds >= 0, got at = {}, seconds = {}",
                    w.len(),
                    p.at,
                    p.seconds
                ),
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

    /// Its stops.
    pub fn pauses(&self) -> &[Pause] {
        match self {
            Trajectory::Loop { pauses, .. } | Trajectory::Path { pauses, .. } => pauses,
        }
    }

    fn parts(&self) -> (&[[f64; 2]], f64, bool) {
        match self {
            Trajectory::Loop { waypoints, speed, .. } => (waypoints, *speed, true),
            Trajectory::Path { waypoints, speed, .. } => (waypoints, *speed, false),
        }
    }

    /// Floor position `[x, y]` and velocity `[vx, vy]` at `t` seconds after the start.
    pub fn at(&self, t: f64) -> ([f64; 2], [f64; 2]) {
        if self.pauses().iter().all(|p| p.seconds <= 0.0) {
            return self.moving_at(t);
        }
        match self.walking_time(t) {
            (tau, false) => self.moving_at(tau),
            (tau, true) => (self.moving_at(tau).0, [0.0, 0.0]),
        }
    }

    /// The seconds of walking behind `t` seconds of the trajectory (its pauses taken out), and
    /// whether it stands at a pause at `t`.
    fn walking_time(&self, t: f64) -> (f64, bool) {
        let (w, speed, closed) = self.parts();
        let n = if closed { w.len() } else { w.len() - 1 };
        let leg_s = |i: usize| {
            let (a, b) = (w[i], w[(i + 1) % w.len()]);
            ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt() / speed
        };
        let pause_s = |i: usize| {
            self.pauses()
                .iter()
                .filter(|p| p.at == i)
                .map(|p| p.seconds)
                .sum::<f64>()
        };
        let walk_s: f64 = (0..n).map(leg_s).sum();
        let lap_s = walk_s + (0..n).map(pause_s).sum::<f64>();
        let mut left = t.max(0.0);
        let mut tau = 0.0;
        if closed && lap_s > 0.0 {
            let laps = (left / lap_s).floor();
            left -= laps * lap_s;
            tau = laps * walk_s;
        }
        for i in 0..n {
            let p = pause_s(i);
            if left < p {
                return (tau, true);
            }
            left -= p;
            let l = leg_s(i);
            if left < l {
                return (tau + left, false);
            }
            left -= l;
            tau += l;
        }
        // Past the end of an open path (or a rounding at the end of a lap).
        (tau + left, false)
    }

    /// [`Trajectory::at`] without its pauses.
    fn moving_at(&self, t: f64) -> ([f64; 2], [f64; 2]) {
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
            pauses: vec![Pause { at: 1, seconds: 2.0 }],
        };
        set_targets(&mut s, &ts);
        assert_eq!(targets(&s).unwrap(), ts);
    }

    fn square(pauses: Vec<Pause>) -> Trajectory {
        // A 4 m square at 1 m/s: a lap of 16 s walking.
        Trajectory::Loop {
            waypoints: vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]],
            speed: 1.0,
            pauses,
        }
    }

    fn close(a: ([f64; 2], [f64; 2]), b: ([f64; 2], [f64; 2])) -> bool {
        a.0.iter()
            .chain(&a.1)
            .zip(b.0.iter().chain(&b.1))
            .all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn a_loop_stands_still_at_its_pause_every_lap_and_walks_on_after_it() {
        let plain = square(Vec::new());
        let paused = square(vec![Pause { at: 1, seconds: 10.0 }]);
        // Before the stop the two agree.
        for t in [0.0, 1.5, 3.9] {
            assert!(close(paused.at(t), plain.at(t)), "t = {t}");
        }
        // Standing at waypoint 1 from 4 s to 14 s, with no velocity.
        for t in [4.0, 9.0, 13.99] {
            assert_eq!(paused.at(t).1, [0.0, 0.0], "t = {t}");
            assert!((paused.at(t).0[0] - 4.0).abs() < 1e-9 && paused.at(t).0[1].abs() < 1e-9);
        }
        // Then 10 s behind the plain loop, for the rest of the lap and the next ones (26 s).
        for t in [14.5, 20.0, 25.9, 26.0 + 2.0, 26.0 + 15.0] {
            assert!(
                close(paused.at(t), plain.at(t - 10.0 * ((t + 22.0) / 26.0).floor())),
                "t = {t}"
            );
        }
        // The second lap stops again at 26 + 4 s.
        assert_eq!(paused.at(26.0 + 5.0).1, [0.0, 0.0]);
    }

    #[test]
    fn a_path_pauses_at_its_start_and_stops_at_its_end() {
        let path = Trajectory::Path {
            waypoints: vec![[0.0, 0.0], [3.0, 0.0]],
            speed: 1.0,
            pauses: vec![Pause { at: 0, seconds: 2.0 }],
        };
        assert_eq!(path.at(1.0), ([0.0, 0.0], [0.0, 0.0]));
        assert!(close(path.at(3.0), ([1.0, 0.0], [1.0, 0.0])));
        assert_eq!(path.at(60.0), ([3.0, 0.0], [0.0, 0.0]));
    }

    #[test]
    fn a_pause_past_the_waypoints_or_negative_is_refused() {
        let mut s = Scenario::default_scenario();
        let mut ts = targets(&s).unwrap();
        for (at, seconds) in [(4, 1.0), (0, -1.0), (0, f64::NAN)] {
            ts[0].trajectory = square(vec![Pause { at, seconds }]);
            set_targets(&mut s, &ts);
            let e = targets(&s).unwrap_err().to_string();
            assert!(
                e.contains(".trajectory.pauses") && e.contains("waypoint index below 4"),
                "{e}"
            );
        }
    }
}
