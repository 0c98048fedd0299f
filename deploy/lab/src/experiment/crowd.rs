//! `ocelli experiment crowd` (issue 16): many people at once. The crowd scenario
//! (`proto/scenarios/crowd.toml`: the default room's 21 cameras and two heads, ten people —
//! similar and different colours, crossing, meeting, side by side, one standing still 10 s, two
//! tagged) at pixel level, per fusion method (distributed and centralized EIF) and camera
//! tracker (segmentation, paper 004's particle filters) over seeded runs,
//! scored by node-server's report with the standard multi-target metrics (CLEAR MOT, IDF1,
//! GOSPA, `node_server::metrics`, on the floor with a 1 m threshold), each a mean over the runs
//! with its 95% interval. A guard row keeps the single-target default scenario's error in
//! sight: many-target work must not cost the one-target case.
//!
//! Ground truth is read only to score.

use super::runner::{self, Method, ci95, mean_std};
use super::{Check, Extra, Options, Outcome, Row};
use node_server::report::{ASSOCIATION_GATE_M, Report};
use proto::scenario::{CameraTracker, Fusion, Scenario};
use sim::Level;
use sim::faults::Faults;

/// The experiment's name.
pub const NAME: &str = "crowd";
/// The scenario, as committed.
pub const SCENARIO_TOML: &str = include_str!("../../../../proto/scenarios/crowd.toml");
/// Simulated seconds per run.
pub const DURATION_S: f64 = 60.0;
/// The methods compared: fusion at the heads, and what the cameras make of their frames.
pub const METHODS: [(&str, Fusion, CameraTracker); 4] = [
    (
        "distributed EIF",
        Fusion::DistributedEif,
        CameraTracker::Segmentation,
    ),
    (
        "centralized EIF",
        Fusion::CentralizedEif,
        CameraTracker::Segmentation,
    ),
    (
        "distributed EIF, particle cameras",
        Fusion::DistributedEif,
        CameraTracker::Particle,
    ),
    (
        "centralized EIF, particle cameras",
        Fusion::CentralizedEif,
        CameraTracker::Particle,
    ),
];
/// The guard row's label.
pub const GUARD: &str = "guard: default scenario, one robot (distributed EIF)";
/// Issue 16's goals.
pub const GOAL_MOTA: f64 = 0.95;
pub const GOAL_IDF1: f64 = 0.95;
pub const GOAL_SINGLE_M: f64 = 0.15;

/// The crowd scenario.
///
/// # Errors
/// Never for the committed file (a test checks it).
pub fn scenario() -> crate::Result<Scenario> {
    Ok(Scenario::from_toml(SCENARIO_TOML, "crowd.toml")?)
}

/// One run's figures, from its report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunScore {
    pub mota: Option<f64>,
    pub motp_m: Option<f64>,
    pub idf1: Option<f64>,
    pub id_switches: Option<f64>,
    pub fragmentations: Option<f64>,
    pub gospa_m: Option<f64>,
    pub global_ids: f64,
    /// The smallest share of frames any true person was tracked in.
    pub min_coverage: Option<f64>,
    pub false_tracks: f64,
}

impl RunScore {
    /// The figures of `r`.
    pub fn of(r: &Report) -> RunScore {
        RunScore {
            mota: r.mota,
            motp_m: r.motp_m,
            idf1: r.idf1,
            id_switches: r.id_switches.map(|x| x as f64),
            fragmentations: r.fragmentations.map(|x| x as f64),
            gospa_m: r.gospa_m,
            global_ids: r.global_ids as f64,
            min_coverage: r
                .mot
                .as_ref()
                .and_then(|m| m.targets.iter().map(|t| t.coverage).min_by(f64::total_cmp)),
            false_tracks: r.false_tracks as f64,
        }
    }
}

/// The mean over runs of one figure and its 95% half-width, as two columns (`name`, `±95%`
/// after it). Runs without the figure are left out.
fn mean_ci(name: &str, values: &[Option<f64>], digits: usize) -> [Extra; 2] {
    let v: Vec<f64> = values.iter().flatten().copied().collect();
    [
        Extra::new(name, mean_std(&v).map(|m| m.0), digits),
        Extra::new(&format!("{name} ±95%"), ci95(&v), digits),
    ]
}

/// A method's row from its runs' scores.
pub fn row(method: &str, people: usize, scores: &[RunScore]) -> Row {
    let col = |f: fn(&RunScore) -> Option<f64>| scores.iter().map(f).collect::<Vec<_>>();
    let mut extra = Vec::new();
    extra.extend(mean_ci("MOTA", &col(|s| s.mota), 3));
    extra.extend(mean_ci("MOTP m", &col(|s| s.motp_m), 3));
    extra.extend(mean_ci("IDF1", &col(|s| s.idf1), 3));
    extra.extend(mean_ci("ID sw", &col(|s| s.id_switches), 1));
    extra.extend(mean_ci("frag", &col(|s| s.fragmentations), 1));
    extra.extend(mean_ci("global ids", &col(|s| Some(s.global_ids)), 1));
    extra.push(Extra::new("people", Some(people as f64), 0));
    extra.extend(mean_ci("GOSPA m", &col(|s| s.gospa_m), 3));
    let cov: Vec<f64> = scores.iter().filter_map(|s| s.min_coverage).collect();
    extra.push(Extra::new(
        "min coverage",
        cov.iter().copied().min_by(f64::total_cmp),
        3,
    ));
    let ft: Vec<f64> = scores.iter().map(|s| s.false_tracks).collect();
    extra.push(Extra::new("false tracks", mean_std(&ft).map(|m| m.0), 1));
    Row {
        method: method.to_string(),
        extra,
        ..Row::default()
    }
}

fn method_on(scenario: &Scenario, label: &str, fusion: Fusion, cameras: CameraTracker) -> Method {
    let mut scenario = scenario.clone();
    scenario.method.fusion = fusion;
    scenario.method.camera_tracker = cameras;
    Method {
        label: label.to_string(),
        scenario,
        faults: Faults::default(),
        uses_rssi: true,
        gate_m: ASSOCIATION_GATE_M,
        ml_depth: None,
    }
}

fn extra(row: Option<&Row>, name: &str) -> f64 {
    row.and_then(|r| r.extra.iter().find(|e| e.name == name))
        .and_then(|e| e.value)
        .unwrap_or(f64::NAN)
}

/// Run it.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run(opts: &Options) -> crate::Result<Outcome> {
    let level = opts.level_or(Level::Pixel);
    let duration_s = opts.duration_s.unwrap_or(DURATION_S);
    let base = scenario()?;
    let people = world::targets(&base)?.len();
    let mut out = Outcome::new(NAME, level, opts, duration_s);
    for (label, fusion, cameras) in METHODS {
        let m = method_on(&base, label, fusion, cameras);
        let mut scores = Vec::new();
        for k in 0..out.runs {
            let seed = opts.seed.wrapping_add(u64::from(k));
            let (report, _) = runner::run_once(&m, seed, level, duration_s)?;
            scores.push(RunScore::of(&report));
        }
        out.rows.push(row(label, people, &scores));
    }
    let guard = method_on(
        &Scenario::default_scenario(),
        GUARD,
        Fusion::DistributedEif,
        CameraTracker::Segmentation,
    );
    out.rows
        .push(runner::run_method(&guard, opts, level, duration_s)?.row);
    out.shape = goals(&out, people);
    out.notes = notes(people, duration_s);
    Ok(out)
}

/// Issue 16's goals, checked on the rows (they are goals: they may fail).
fn goals(out: &Outcome, people: usize) -> Vec<Check> {
    let mut checks = Vec::new();
    for (label, _, _) in METHODS {
        let r = out.row(label);
        let (mota, idf1, ids) = (extra(r, "MOTA"), extra(r, "IDF1"), extra(r, "global ids"));
        checks.push(Check::new(
            &format!("{label}: MOTA >= {GOAL_MOTA} and IDF1 >= {GOAL_IDF1}"),
            mota >= GOAL_MOTA && idf1 >= GOAL_IDF1,
            format!("MOTA {mota:.3}, IDF1 {idf1:.3}"),
        ));
        checks.push(Check::new(
            &format!("{label}: global ids <= people + 1"),
            ids <= people as f64 + 1.0,
            format!("{ids:.1} ids for {people} people"),
        ));
    }
    let single = out.row(GUARD).and_then(|r| r.mean_error_m).unwrap_or(f64::NAN);
    checks.push(Check::new(
        &format!("single target unchanged: default scenario error <= {GOAL_SINGLE_M} m"),
        single <= GOAL_SINGLE_M,
        format!("{single:.3} m"),
    ));
    checks
}

fn notes(people: usize, duration_s: f64) -> Vec<String> {
    vec![
        format!(
            "Scenario: proto/scenarios/crowd.toml — the default room's 21 cameras (352x288, adaptive-background segmentation; with particle cameras, paper 004's colour particle filters on its regions, each person sent as a floor position) and two heads, {people} people 1.6-1.8 m tall: two reds and two greens of similar colour, two crossing diagonals, two greens side by side 0.6 m apart through the cluster boundary, two who meet and stand together 3 s, one who stands still 10 s every lap, two tagged; {duration_s:.0} s per run."
        ),
        "Metrics: node-server's report (node_server::metrics) on frames one filter step apart after 2 s of warm-up, on the floor with a 1 m threshold; each a mean over the runs with the 95% half-width of that mean (Student's t over the runs). `global ids` counts every global id the server gave, `false tracks` the global tracks farther than 2 m on average from every person, `min coverage` the smallest share of frames any person was tracked in over all runs.".into(),
        "Guard: the default scenario (one robot) with distributed EIF at the same level, duration and seeds; its error column is the report's 3-D error of the robot's tracks.".into(),
        "Where the errors come from (docs/multi-target.md): people whose regions merge in a view are one detection, which the camera gives to one nearby track while the others coast; a person who walks beside another for long is lost to that track, and the head's merge rules do not undo that. Particle cameras keep a filter per person through a merge, but a camera may hold two filters on one person, one above the other in its columns, and give one to each of two tracks of that person a metre apart, which then both live: most of their false positives in a traced run (docs/paper004.md; the stacked-filter rule takes many of those pairs, not all). They also place each person from one view: a hidden person's columns may end at a nearer one's feet, a metre off.".into(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_committed_crowd_has_what_the_issue_asks() {
        let s = scenario().unwrap();
        let targets = world::targets(&s).unwrap();
        assert!(targets.len() >= 8, "{} people", targets.len());
        assert_eq!(targets.iter().filter(|t| t.rssi_tag).count(), 2);
        // Someone stands still 10 s.
        assert!(
            targets
                .iter()
                .any(|t| t.trajectory.pauses().iter().any(|p| p.seconds >= 10.0))
        );
    }

    #[test]
    fn a_row_gives_each_figure_with_its_interval() {
        let score = |mota: f64, ids: f64| RunScore {
            mota: Some(mota),
            global_ids: ids,
            min_coverage: Some(mota),
            ..RunScore::default()
        };
        let r = row("m", 10, &[score(0.8, 11.0), score(0.9, 13.0), score(1.0, 12.0)]);
        let get = |n: &str| r.extra.iter().find(|e| e.name == n).and_then(|e| e.value);
        assert!((get("MOTA").unwrap() - 0.9).abs() < 1e-12);
        assert_eq!(get("MOTA ±95%"), ci95(&[0.8, 0.9, 1.0]));
        assert_eq!(get("global ids"), Some(12.0));
        assert_eq!(get("people"), Some(10.0));
        assert_eq!(get("min coverage"), Some(0.8));
        // Figures no run has stay empty.
        assert_eq!(get("IDF1"), None);
        assert_eq!(get("IDF1 ±95%"), None);
    }
}
