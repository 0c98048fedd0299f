//! Paper 000 Table 1: five cameras; the measurements of cameras 2 and 3 are lost from t = 10 s
//! to t = 25 s. ML and EIF with cameras 1–3, EIF with all five, and entropy-based active
//! perception (paper 000 §5) at cost 0.2 and 1.0 → mean error and camera measurements used.
//!
//! The scenario is `proto/scenarios/experiments/paper000.toml` (geometry, rates, noise and
//! power are ours: the paper gives none). Paper 000's cost is in nats per step of keeping a
//! camera on; our planner's cost is `energy-weight × Δpower × step`, so a paper cost `c` is the
//! weight `c / ((P_active − P_inactive) × step)` (the camera-only planner switches a node
//! between Active and Inactive).
//!
//! That reading is the paper's (§5): the reward is ½ log(|Ω^a|/|Ω|) in nats for one step's
//! measurement of the camera (2 fps and a 500 ms step: one frame per camera per step); an
//! action is taken when its reward beats its cost, at most one per step, the best by r − c;
//! switching a camera off saves c, so a camera stays on while its one-step information is worth
//! more than c. Paper 000's Ω is updated with "the sensors currently used", and the lost
//! measurements of cameras 2 and 3 "cannot be used for data fusion": the scenario sets
//! `drop-lost-cameras`, so the planner stops counting a camera that is on, expected to see the
//! robot, and delivers nothing. Without it, the planner believed the silent cameras 2 and 3 were
//! measuring (their expected gain was the largest, up to 4.7 nats) and at cost 1.0 used 1.6
//! measurements in the whole 15 s window; its track's σ grew to metres and the head dropped it
//! in most runs.

use super::runner::{self, Method};
use super::{Check, Options, Outcome, Row, Trace};
use nalgebra::Vector3;
use node_head::fusion::ml::DepthHandling;
use proto::Mode;
use proto::scenario::{Activation, Fusion, Scenario};
use sim::Level;
use sim::faults::{Blackout, Faults};

/// The experiment's scenario, as shipped.
pub const SCENARIO_TOML: &str = include_str!("../../../../proto/scenarios/experiments/paper000.toml");
/// Cameras 1–5 are these nodes.
pub const CAMERAS: [u32; 5] = [11, 12, 13, 14, 15];
/// The loss window of cameras 2 and 3, s.
pub const LOSS: (f64, f64) = (10.0, 25.0);
/// Simulated seconds per run.
pub const DURATION_S: f64 = 40.0;
/// The two active-perception costs of the paper.
pub const COSTS: [f64; 2] = [0.2, 1.0];

pub const ML3: &str = "ML (cameras 1-3)";
pub const EIF3: &str = "EIF (cameras 1-3)";
pub const EIF5: &str = "EIF (5 cameras)";

/// Row label of active perception at a cost.
pub fn active(cost: f64) -> String {
    format!("Active perception (cost {cost:.1})")
}

/// The paper's figures (papers/README.md).
pub fn paper() -> Vec<Row> {
    let row = |m: &str, e: f64, n: f64| Row {
        measurements: Some(n),
        ..super::paper_row(m, Some(e), None)
    };
    vec![
        row(ML3, 0.42, 225.0),
        row(EIF3, 0.37, 225.0),
        row(EIF5, 0.18, 395.0),
        row("Active perception (Table 1)", 0.24, 239.0),
        row(&active(0.2), 0.17, 249.0),
        row(&active(1.0), 0.26, 99.0),
    ]
}

/// The scenario parsed.
///
/// # Errors
/// The shipped file does not parse (a build defect).
pub fn scenario() -> crate::Result<Scenario> {
    Ok(Scenario::from_toml(SCENARIO_TOML, "paper000.toml")?)
}

fn loss() -> Faults {
    Faults {
        blackouts: [CAMERAS[1], CAMERAS[2]]
            .iter()
            .map(|&camera| Blackout {
                camera,
                from_s: LOSS.0,
                to_s: LOSS.1,
            })
            .collect(),
        ..Faults::default()
    }
}

/// Standard deviation of the ML depth, m: paper 000's "high value for the variance" (ours).
pub const ML_DEPTH_SIGMA_M: f64 = 1.0;

/// Paper 000 §3's usual ML depth: Z_i set to an average value with a high variance. The average
/// is the mean distance from the cameras to the floor's centre at the target's half height
/// (geometry only; no trajectory).
pub fn mean_depth(s: &Scenario) -> DepthHandling {
    let h = world::targets(s)
        .ok()
        .and_then(|t| t.first().map(|t| t.size[2] * 0.5))
        .unwrap_or(0.5);
    let c = Vector3::new(
        (s.world.min[0] + s.world.max[0]) * 0.5,
        (s.world.min[1] + s.world.max[1]) * 0.5,
        h,
    );
    let d: Vec<f64> = s
        .cameras()
        .filter_map(|n| s.camera_model(n.id).ok())
        .map(|m| (m.pose.centre() - c).norm())
        .collect();
    DepthHandling::MeanDepth {
        depth: d.iter().sum::<f64>() / d.len().max(1) as f64,
        sigma: ML_DEPTH_SIGMA_M,
    }
}

/// The five methods.
///
/// # Errors
/// The shipped scenario does not parse.
pub fn methods() -> crate::Result<Vec<Method>> {
    let base = scenario()?;
    let three = |mut s: Scenario| {
        s.nodes
            .retain(|n| n.camera.is_none() || CAMERAS[..3].contains(&n.id));
        s
    };
    let with = |fusion: Fusion, activation: Activation, weight: Option<f64>| {
        let mut s = base.clone();
        s.method.fusion = fusion;
        s.method.activation = activation;
        if let Some(w) = weight {
            s.method.energy_weight = w;
        }
        s
    };
    let step_s = base.method.step_ms as f64 * 1e-3;
    let p = base.power;
    let swing_mw = p.in_mode(Mode::Active) - p.in_mode(Mode::Inactive);
    let method = |label: String, scenario: Scenario| Method {
        label,
        scenario,
        faults: loss(),
        uses_rssi: false,
        gate_m: node_server::report::ASSOCIATION_GATE_M,
        ml_depth: None,
    };
    let mut ml = method(ML3.into(), three(with(Fusion::Ml, Activation::AllOn, None)));
    ml.ml_depth = Some(mean_depth(&ml.scenario));
    let mut out = vec![
        ml,
        method(
            EIF3.into(),
            three(with(Fusion::CentralizedEif, Activation::AllOn, None)),
        ),
        method(EIF5.into(), with(Fusion::CentralizedEif, Activation::AllOn, None)),
    ];
    for c in COSTS {
        let w = c / (swing_mw * step_s);
        out.push(method(
            active(c),
            with(Fusion::CentralizedEif, Activation::CameraEntropy, Some(w)),
        ));
    }
    Ok(out)
}

/// Run it.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run(opts: &Options) -> crate::Result<Outcome> {
    let level = opts.level_or(Level::Pixel);
    let duration_s = opts.duration_s.unwrap_or(DURATION_S);
    let mut rows = Vec::new();
    let mut traces = Vec::new();
    let mut windows = Vec::new();
    for m in methods()? {
        let runs = runner::run_method(&m, opts, level, duration_s)?;
        let inside = |t: f64| t >= LOSS.0 && t < LOSS.1;
        let cameras = |i: bool| {
            runs.samples
                .iter()
                .flatten()
                .filter(|s| inside(s.t) == i)
                .map(|s| f64::from(s.cameras))
                .sum::<f64>()
                / runs.samples.len().max(1) as f64
        };
        let err = |e: Option<runner::Errors>| e.map_or("–".to_string(), |e| format!("{:.3} m", e.mean));
        windows.push(format!(
            "{} {}, {:.0} / {}, {:.0}",
            m.label,
            err(runs.errors_in(LOSS.0, LOSS.1)),
            cameras(true),
            err(runs.errors_out(LOSS.0, LOSS.1)),
            cameras(false)
        ));
        traces.push(Trace {
            method: m.label.clone(),
            samples: runs.samples.first().cloned().unwrap_or_default(),
            window: Some(LOSS),
        });
        rows.push(runs.row);
    }
    let mut out = Outcome {
        rows,
        paper: paper(),
        notes: vec![
            "Geometry, 2 fps, 500 ms step, 18 px noise and power are ours; the paper gives none.".to_string(),
            "Paper cost c (nats per step of a camera on) = energy-weight × (P_active − P_inactive) × step."
                .into(),
            format!(
                "ML takes paper 000's usual depth: Z_i = the mean camera-to-floor-centre distance, σ = {ML_DEPTH_SIGMA_M} m (not the known target plane our heads default to)."
            ),
            "Measurements = camera measurements the filter used per run (cameras per step × steps).".into(),
            "Lost cameras (cameras 2 and 3 in the loss window) are not counted by the planner once they deliver nothing (method.drop-lost-cameras).".into(),
            format!(
                "Inside / outside the loss window, mean error and measurements per run (of scored samples): {}.",
                windows.join("; ")
            ),
        ],
        traces,
        ..Outcome::new("paper000-table1", level, opts, duration_s)
    };
    out.shape = shape(&out);
    Ok(out)
}

/// The paper's shape, checked on our rows: error EIF5 < active perception < EIF3 < ML; active
/// perception uses at least 35% fewer measurements than EIF5; a higher cost means fewer
/// measurements.
pub fn shape(o: &Outcome) -> Vec<Check> {
    let err = |m: &str| o.row(m).and_then(|r| r.mean_error_m).unwrap_or(f64::INFINITY);
    let meas = |m: &str| o.row(m).and_then(|r| r.measurements).unwrap_or(f64::NAN);
    let (lo, hi) = (active(COSTS[0]), active(COSTS[1]));
    let mut v = Vec::new();
    for (k, ap) in [&lo, &hi].into_iter().enumerate() {
        // The ML comparison is stated once, with the lower cost (the paper's cost-1.0 error,
        // 0.26 m, sits between EIF5 and EIF3 too).
        let ml = if k == 0 { " < ML" } else { "" };
        v.push(Check::new(
            &format!("error EIF5 < {ap} < EIF3{ml}"),
            err(EIF5) < err(ap) && err(ap) < err(EIF3) && (k > 0 || err(EIF3) < err(ML3)),
            format!(
                "{:.3} / {:.3} / {:.3} / ML {:.3} m",
                err(EIF5),
                err(ap),
                err(EIF3),
                err(ML3)
            ),
        ));
        v.push(Check::new(
            &format!("{ap} uses at least 35% fewer measurements than EIF5"),
            meas(ap) <= 0.65 * meas(EIF5),
            format!("{:.0} vs {:.0}", meas(ap), meas(EIF5)),
        ));
    }
    v.push(Check::new(
        "a higher cost means fewer measurements",
        meas(&hi) < meas(&lo),
        format!("{:.0} (cost 1.0) vs {:.0} (cost 0.2)", meas(&hi), meas(&lo)),
    ));
    v
}
