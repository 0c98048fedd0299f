//! `ocelli experiment ble-rssi`: our RSSI models against real BLE data (issue 7). The dataset
//! (`shared/datasets/ble-rssi/`, Daniş et al. 2022: 12 fixed sensors, one beacon carried along
//! 4 trajectories, AR ground truth) answers three questions, with numbers in the usual rows:
//!
//! 1. The room's log-distance law `RSSI = a log10 d + b` (paper 002 eq. 2), fitted by least
//!    squares leaving one trajectory out and scored on it, beside our scenario default
//!    (`RssiModel::default()`) and our simulated radio's law (`RadioWorld::default()`), and the
//!    residuals split as our sim radio models them: per-sensor offset, smooth field σ with its
//!    correlation length, per-packet noise ([`law::structure`]).
//! 2. Paper 002 Algorithm 1 (`node_head::rssi_training::RssiTrainer`, M from the scenario)
//!    predicting each sensor's next packet, against the fitted and the default law.
//! 3. RSSI-only tracking with our EIF, with the default, the fitted and the trained models.
//!
//! The dataset has no cameras: Algorithm 1's auxiliary distances come from a camera stand-in,
//! the truth plus seeded noise ([`track`]). It is real data, so the outcome's `level`, `runs`
//! and `duration_s` mean: no level (the tables say "real data"), runs = stand-in noise seeds,
//! duration = seconds of data. Not part of `ocelli experiment all` (which must not depend on
//! the shared datasets): run it by name.

pub mod data;
pub mod launch;
pub mod law;
pub mod track;

use super::paper002_rssi_only::rssi_row;
use super::runner::{Sample, mean_std};
use super::{Check, Options, Outcome, Row, Trace};
use crate::error::OrFailed as _;
use data::Dataset;
use law::LogFit;
use proto::models::RssiModel;
use proto::scenario::{Method, RadioWorld};
use sim::Level;
use track::{Models, Prediction, Tracker, Training};

pub const NAME: &str = "ble-rssi";
/// σ of the camera stand-in per axis, m.
pub const STANDIN_SIGMA_M: f64 = 0.1;
/// A worse stand-in, to show how much the trained models lean on it, m.
pub const STANDIN_WIDE_SIGMA_M: f64 = 0.5;
/// Filter rate of the RSSI-only EIF: a step every 0.5 s (2 Hz).
pub const STEP_S: f64 = 0.5;
/// σ of the known-height constraint, m (the beacon is carried at 1.6–2.0 m).
pub const HEIGHT_SIGMA_M: f64 = 0.1;
/// Starting position σ, m: the filter starts at the sensors' centroid knowing nothing better.
pub const START_SIGMA_M: f64 = 5.0;
/// The paper's "below 90 cm" threshold, m.
pub const WITHIN_M: f64 = 0.9;

pub const LAW_DEFAULT: &str = "held-out RSSI RMSE dB: scenario default";
pub const LAW_SIM: &str = "held-out RSSI RMSE dB: sim radio law";
pub const LAW_FITTED: &str = "held-out RSSI RMSE dB: fitted a log d + b (LOTO)";
pub const LAW_ONE: &str = "held-out RSSI RMSE dB: fitted on one trajectory, scored on the rest";
pub const NEXT_DEFAULT: &str = "next-packet RMSE dB: scenario default";
pub const NEXT_FITTED: &str = "next-packet RMSE dB: fitted law (LOTO)";
pub const NEXT_LOCAL: &str = "next-packet RMSE dB: local line, always";
pub const NEXT_ALG1: &str = "next-packet RMSE dB: Algorithm 1";
pub const TRACK_DEFAULT: &str = "RSSI only, scenario default model";
pub const TRACK_FITTED: &str = "RSSI only, fitted law (LOTO)";
pub const TRACK_TRAINED: &str = "RSSI only, trained models";
pub const TRACK_TRAINED_WIDE: &str = "RSSI only, trained models, stand-in σ 0.5 m";

/// The law our simulated radio draws from, as a model: a = −10 n, b = power at 1 m, variance
/// = field² + noise².
pub fn sim_law(r: &RadioWorld) -> RssiModel {
    RssiModel::LogDistance {
        a: -10.0 * r.path_loss_exponent,
        b: r.tx_power_dbm,
        variance: r.multipath_db.powi(2) + r.noise_db.powi(2),
    }
}

fn law_text(m: &RssiModel) -> String {
    match *m {
        RssiModel::LogDistance { a, b, variance } => {
            format!("{a:.1} log10 d {b:+.1} (sd {:.1} dB)", variance.sqrt())
        }
        RssiModel::Linear { a, b, variance } => format!("{a:.2} d {b:+.1} (sd {:.1} dB)", variance.sqrt()),
    }
}

/// Whether `x` lies within a factor `f` of `reference`.
fn within_factor(x: f64, reference: f64, f: f64) -> bool {
    x >= reference / f && x <= reference * f
}

fn param_row(method: &str, v: Option<f64>) -> Row {
    Row {
        method: method.to_string(),
        param: v,
        ..Row::default()
    }
}

/// Pooled squared error and count on held-out packets, per model.
#[derive(Default)]
struct HeldOut {
    n: usize,
    sse: [f64; 3],
}

/// The law fitted on trajectory `i` alone, and its squared errors (sum, count) on all the
/// others.
fn calibrate_on_one(ds: &Dataset, i: usize) -> Option<(LogFit, f64, usize)> {
    let fit = law::fit_log(law::pairs(ds, ds.trajectories[i].packets.iter()))?;
    let m = fit.model();
    let rest = ds
        .trajectories
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != i)
        .flat_map(|(_, t)| &t.packets);
    let (mut sse, mut n) = (0.0, 0usize);
    for (d, r) in law::pairs(ds, rest) {
        sse += (r - m.predict(d)).powi(2);
        n += 1;
    }
    Some((fit, sse, n))
}

/// One leave-one-trajectory-out fold: the law fitted without trajectory `i`, and the mean
/// carrying height of the calibration trajectories.
fn fold(ds: &Dataset, i: usize) -> Option<(LogFit, f64)> {
    let calib = || {
        ds.trajectories
            .iter()
            .enumerate()
            .filter(move |(j, _)| *j != i)
            .flat_map(|(_, t)| &t.packets)
    };
    let fit = law::fit_log(law::pairs(ds, calib()))?;
    let zs: Vec<f64> = calib().map(|p| p.truth.z).collect();
    Some((fit, mean_std(&zs)?.0))
}

/// Run it on the dataset at [`data::default_dir`].
///
/// # Errors
/// The dataset is missing (the message names the path) or malformed, or has fewer than two
/// trajectories.
pub fn run(opts: &Options) -> crate::Result<Outcome> {
    run_from(&data::default_dir(), opts)
}

/// Run it on the dataset at `dir`.
///
/// # Errors
/// As [`run`].
pub fn run_from(dir: &std::path::Path, opts: &Options) -> crate::Result<Outcome> {
    let ds = data::load(dir)?;
    run_on(&ds, opts)
}

/// The laws every fold is compared with: the scenario's default, our simulated radio's, the
/// one fitted to all packets and the structure of its residuals.
struct Laws {
    scenario: RssiModel,
    sim: RssiModel,
    all: LogFit,
    structure: law::Structure,
    method: Method,
}

impl Laws {
    fn fit(ds: &Dataset) -> crate::Result<Laws> {
        let all = law::fit_log(law::pairs(ds, ds.trajectories.iter().flat_map(|t| &t.packets)))
            .or_failed("fitting the log-distance law to all packets")?;
        let structure = law::structure(ds, &all.model()).or_failed("residual structure")?;
        Ok(Laws {
            scenario: RssiModel::default(),
            sim: sim_law(&RadioWorld::default()),
            all,
            structure,
            method: Method::default(),
        })
    }
}

/// What the leave-one-trajectory-out folds measured.
#[derive(Default)]
struct Folds {
    held: HeldOut,
    pred: Prediction,
    /// Tracking samples per model: scenario default, fitted, trained, trained with the wide
    /// stand-in; one entry per trajectory (and stand-in seed).
    tracks: [Vec<Vec<Sample>>; 4],
    notes: Vec<String>,
    one_sse: f64,
    one_n: usize,
    one_slopes: Vec<f64>,
}

/// Each trajectory held out in turn: the law fitted without it, predicted and tracked on it.
///
/// # Errors
/// A fold whose law cannot be fitted.
fn cross_validate(ds: &Dataset, laws: &Laws, opts: &Options) -> crate::Result<Folds> {
    let (scenario, sim, method) = (laws.scenario, laws.sim, &laws.method);
    let runs = opts.runs.max(1);
    let mut f = Folds::default();
    let cx = ds.sensors.iter().map(|s| s.pos.x).sum::<f64>() / ds.sensors.len() as f64;
    let cy = ds.sensors.iter().map(|s| s.pos.y).sum::<f64>() / ds.sensors.len() as f64;

    for (i, traj) in ds.trajectories.iter().enumerate() {
        let (fit, height) = fold(ds, i).or_failed(format!("fitting without {}", traj.name))?;
        let (one, sse, n) = calibrate_on_one(ds, i).or_failed(format!("fitting on {}", traj.name))?;
        f.one_sse += sse;
        f.one_n += n;
        f.one_slopes.push(one.a);
        let fitted = fit.model();
        for (k, m) in [scenario, sim, fitted].iter().enumerate() {
            f.held.sse[k] += law::pairs(ds, traj.packets.iter())
                .map(|(d, r)| (r - m.predict(d)).powi(2))
                .sum::<f64>();
        }
        f.held.n += traj.packets.len();
        let (rmse, bias) =
            law::error_db(&fitted, law::pairs(ds, traj.packets.iter())).unwrap_or((f64::NAN, f64::NAN));
        f.notes.push(format!(
            "{} held out: fit {} on {} packets, n = {:.2}; on {} packets RMSE {rmse:.2} dB, bias {bias:+.2} dB; height {height:.2} m.",
            traj.name,
            law_text(&fitted),
            fit.n,
            fit.exponent(),
            traj.packets.len(),
        ));
        let tracker = Tracker {
            motion: method.motion,
            step_s: STEP_S,
            height_m: height,
            height_sigma_m: HEIGHT_SIGMA_M,
            start_xy: [cx, cy],
            start_sigma_m: START_SIGMA_M,
        };
        f.tracks[0].push(track::track(
            &ds.sensors,
            traj,
            &Models::Fixed(scenario),
            &tracker,
        ));
        f.tracks[1].push(track::track(&ds.sensors, traj, &Models::Fixed(fitted), &tracker));
        for r in 0..runs {
            let tr = Training {
                window: method.rssi_window,
                epsilon: method.rssi_epsilon,
                sigma_m: STANDIN_SIGMA_M,
                seed: opts
                    .seed
                    .wrapping_add(u64::from(r))
                    .wrapping_mul(0x9E37_79B9)
                    .wrapping_add(i as u64),
            };
            f.pred
                .add(&track::predict_next(&ds.sensors, traj, &scenario, &fitted, &tr));
            f.tracks[2].push(track::track(
                &ds.sensors,
                traj,
                &Models::Trained(fitted, tr),
                &tracker,
            ));
            let wide = Training {
                sigma_m: STANDIN_WIDE_SIGMA_M,
                ..tr
            };
            f.tracks[3].push(track::track(
                &ds.sensors,
                traj,
                &Models::Trained(fitted, wide),
                &tracker,
            ));
        }
    }
    Ok(f)
}

/// The law and prediction rows (RMSE in dB, the law's parameters, the residual structure).
fn parameter_rows(laws: &Laws, f: &Folds) -> Vec<Row> {
    let held_rmse = |k: usize| (f.held.n > 0).then(|| (f.held.sse[k] / f.held.n as f64).sqrt());
    let mut rows = vec![
        param_row(
            &format!("{LAW_DEFAULT} ({})", law_text(&laws.scenario)),
            held_rmse(0),
        ),
        param_row(&format!("{LAW_SIM} ({})", law_text(&laws.sim)), held_rmse(1)),
        param_row(LAW_FITTED, held_rmse(2)),
        param_row(
            LAW_ONE,
            (f.one_n > 0).then(|| (f.one_sse / f.one_n as f64).sqrt()),
        ),
        param_row("fitted law, all packets: slope a, dB/decade", Some(laws.all.a)),
        param_row("fitted law, all packets: b (dBm at 1 m)", Some(laws.all.b)),
        param_row("fitted law, all packets: residual sd dB", Some(laws.all.sd_db)),
    ];
    let radio = RadioWorld::default();
    rows.extend([
        param_row(
            "residual: per-sensor offset sd dB (sim: 0)",
            Some(laws.structure.sensor_offset_db),
        ),
        param_row(
            &format!("residual: smooth field sd dB (sim: {:.1})", radio.multipath_db),
            Some(laws.structure.smooth_db),
        ),
        param_row(
            &format!(
                "residual: correlation length m (sim: {:.1})",
                radio.multipath_length_m
            ),
            Some(laws.structure.length_m),
        ),
        param_row(
            &format!("residual: per-packet noise sd dB (sim: {:.1})", radio.noise_db),
            Some(laws.structure.noise_db),
        ),
        param_row(NEXT_DEFAULT, f.pred.rmse(f.pred.scenario)),
        param_row(NEXT_FITTED, f.pred.rmse(f.pred.fitted)),
        param_row(NEXT_LOCAL, f.pred.rmse(f.pred.local)),
        param_row(NEXT_ALG1, f.pred.rmse(f.pred.algorithm1)),
    ]);
    rows
}

/// One tracking row per model (errors over trajectories), the share within
/// [`WITHIN_M`] of each, and the first trajectory's trace of each.
fn tracking_rows(ds: &Dataset, f: &Folds) -> (Vec<Row>, Vec<f64>, Vec<Trace>) {
    let mut rows = Vec::new();
    let mut within = Vec::new();
    let mut traces = Vec::new();
    for (label, runs_k) in [TRACK_DEFAULT, TRACK_FITTED, TRACK_TRAINED, TRACK_TRAINED_WIDE]
        .into_iter()
        .zip(&f.tracks)
    {
        let (row, frac) = rssi_row(label, runs_k, WITHIN_M);
        // Its "runs" are trajectories (and stand-in seeds of the same trajectories), not
        // independent seeds of one experiment: no interval over them.
        rows.push(Row {
            mean_error_ci95_m: None,
            run_errors_m: Vec::new(),
            ..row
        });
        within.push(frac);
        traces.push(Trace {
            method: format!("{label} — {}", ds.trajectories[0].name),
            samples: runs_k.first().cloned().unwrap_or_default(),
            window: None,
        });
    }

    (rows, within, traces)
}

/// What the experiment expects of the room and of Algorithm 1, checked.
fn shape_checks(laws: &Laws, f: &Folds, rows: &[Row], within: &[f64]) -> Vec<Check> {
    let radio = RadioWorld::default();
    let row_param = |m: &str| {
        rows.iter()
            .find(|r| r.method.starts_with(m))
            .and_then(|r| r.param)
            .unwrap_or(f64::NAN)
    };
    let row_err = |m: &str| {
        rows.iter()
            .find(|r| r.method == m)
            .and_then(|r| r.mean_error_m)
            .unwrap_or(f64::INFINITY)
    };
    let (h_def, h_sim, h_fit) = (row_param(LAW_DEFAULT), row_param(LAW_SIM), row_param(LAW_FITTED));
    let (n_def, n_fit, n_loc, n_alg) = (
        row_param(NEXT_DEFAULT),
        row_param(NEXT_FITTED),
        row_param(NEXT_LOCAL),
        row_param(NEXT_ALG1),
    );
    let trained_share = f.pred.trained as f64 / f.pred.n.max(1) as f64;
    vec![
        Check::new(
            "RSSI falls with distance (fitted slope a < 0)",
            laws.all.a < 0.0,
            format!("a = {:.1} dB/decade, n = {:.2}", laws.all.a, laws.all.exponent()),
        ),
        Check::new(
            "our sim radio's path-loss exponent (2.6) within ±0.5 of the room's",
            (laws.all.exponent() - radio.path_loss_exponent).abs() <= 0.5,
            format!(
                "room n = {:.2}, b = {:.1} dBm (sim −48.0)",
                laws.all.exponent(),
                laws.all.b
            ),
        ),
        Check::new(
            "the scenario default law is within 2 dB RMSE of the fitted law on held-out packets",
            h_def <= h_fit + 2.0,
            format!("{h_def:.2} vs {h_fit:.2} dB (sim law {h_sim:.2} dB)"),
        ),
        Check::new(
            "our sim radio's multipath sd (5 dB) within a factor 1.5 of the room's smooth part",
            within_factor(laws.structure.smooth_db, radio.multipath_db, 1.5),
            format!(
                "smooth {:.2} dB over l = {:.2} m, per-packet {:.2} dB, sensor offsets {:.2} dB",
                laws.structure.smooth_db,
                laws.structure.length_m,
                laws.structure.noise_db,
                laws.structure.sensor_offset_db
            ),
        ),
        Check::new(
            "our sim radio's per-packet noise (2 dB) within a factor 1.5 of the room's",
            within_factor(laws.structure.noise_db, radio.noise_db, 1.5),
            format!(
                "{:.2} dB (direct: ½ mean squared difference of same-sensor packets under 0.1 m apart {:.1} dB², of consecutive packets under {} s apart {:.1} dB²)",
                laws.structure.noise_db,
                laws.structure.close_semivariance_db2,
                law::CONSECUTIVE_S,
                laws.structure.consecutive_semivariance_db2
            ),
        ),
        Check::new(
            "Algorithm 1 predicts the next packet better than the fitted law",
            n_alg < n_fit,
            format!(
                "{n_alg:.2} vs {n_fit:.2} dB (local line always {n_loc:.2}, scenario default {n_def:.2}; trained chosen for {:.0}%)",
                100.0 * trained_share
            ),
        ),
        Check::new(
            "trained models track better than the fitted default model",
            row_err(TRACK_TRAINED) < row_err(TRACK_FITTED),
            format!(
                "{:.3} vs {:.3} m (scenario default {:.3} m)",
                row_err(TRACK_TRAINED),
                row_err(TRACK_FITTED),
                row_err(TRACK_DEFAULT)
            ),
        ),
        Check::new(
            "paper 002: trained models below 0.9 m in at least 80% of samples",
            within[2] >= 0.8,
            format!(
                "{:.0}% (stand-in σ 0.5 m {:.0}%, fitted law {:.0}%, scenario default {:.0}%)",
                100.0 * within[2],
                100.0 * within[3],
                100.0 * within[1],
                100.0 * within[0]
            ),
        ),
    ]
}

/// The notes under the table: the data, the laws, the stand-in, each fold.
fn notes(ds: &Dataset, laws: &Laws, f: &Folds) -> Vec<String> {
    let trained_share = f.pred.trained as f64 / f.pred.n.max(1) as f64;
    let mut notes = vec![
        format!(
            "Real data: {} ({} sensors, {} trajectories, {} packets). No simulation level; runs = seeds of the camera stand-in noise; duration = seconds of data.",
            ds.dir.display(),
            ds.sensors.len(),
            ds.trajectories.len(),
            f.held.n
        ),
        "param: dB for the RSSI rows, m for the correlation length, dB/decade and dBm for the law, the fraction of samples with a horizontal error below 0.9 m for the tracking rows.".into(),
        format!(
            "Law over all packets: {} (n = {:.2}); scenario default {}; sim radio {}. d is the 3-D sensor–beacon distance.",
            law_text(&laws.all.model()),
            laws.all.exponent(),
            law_text(&laws.scenario),
            law_text(&laws.sim)
        ),
        "Residual structure (residuals of the all-packet law, pairs of packets of the same sensor across all trajectories): per-sensor offset = sd of the sensors' mean residuals; the same-sensor semivariogram vs horizontal separation (0.1 m bins to 6 m) fitted with τ² + σ²(1 − exp(−r²/2l²)), our sim radio's field covariance: σ = smooth part, l = correlation length, τ = per-packet noise.".into(),
        format!(
            "CAMERA STAND-IN: Algorithm 1's auxiliary distances come from the ground truth plus Gaussian noise of σ = {STANDIN_SIGMA_M} m per axis (seeded, independent per packet), σ²_u = {:.3} m². It is used only to train (and to place the model evaluation of a next-packet prediction); the tracked estimate never sees it, and trained models enter the EIF only as trained on earlier steps. A real camera filter's errors would be larger and correlated in time.",
            STANDIN_SIGMA_M * STANDIN_SIGMA_M
        ),
        format!(
            "Algorithm 1: M = {}, ε = {}, default = the fold's fitted law with σ²_D = its residual variance; the trained line is chosen when σ²_tm ≤ σ²_D (chosen for {:.0}% of scored packets). Next-packet rows score {} packets whose sensor already had M pairs, every model on the same packets.",
            laws.method.rssi_window,
            laws.method.rssi_epsilon,
            100.0 * trained_share,
            f.pred.n
        ),
        format!(
            "Tracking: EIF (node_head::eif, scenario motion model) at {:.0} Hz, every packet of the step one contribution linearized at the prior; start at the sensors' centroid with σ = {START_SIGMA_M} m (no warm-up excluded); height held by a pseudo-measurement at the calibration trajectories' mean beacon height (σ = {HEIGHT_SIGMA_M} m); error horizontal, against the truth of the step's last packet.",
            1.0 / STEP_S
        ),
    ];
    notes.extend(f.notes.iter().cloned());
    notes.push(format!(
        "Calibrated on one trajectory alone, the slope a is {} dB/decade (in file order).",
        f.one_slopes
            .iter()
            .map(|a| format!("{a:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    notes
}

/// Run it on a loaded dataset.
///
/// # Errors
/// Fewer than two trajectories, or a law that cannot be fitted.
pub fn run_on(ds: &Dataset, opts: &Options) -> crate::Result<Outcome> {
    let n_traj = ds.trajectories.len();
    if n_traj < 2 {
        return Err(crate::LabError::failed(
            "ble-rssi",
            format!(
                "{}: {n_traj} trajectories, need 2 to cross-validate",
                ds.dir.display()
            ),
        ));
    }
    let laws = Laws::fit(ds)?;
    let folds = cross_validate(ds, &laws, opts)?;
    let mut rows = parameter_rows(&laws, &folds);
    let (tracking, within, traces) = tracking_rows(ds, &folds);
    rows.extend(tracking);
    let shape = shape_checks(&laws, &folds, &rows, &within);
    let notes = notes(ds, &laws, &folds);
    let duration_s = ds.trajectories.iter().map(data::Trajectory::duration_s).sum();
    Ok(Outcome {
        experiment: NAME.into(),
        level: Level::Measurement,
        runs: opts.runs.max(1),
        seed: opts.seed,
        duration_s,
        rows,
        paper: vec![Row {
            param: Some(0.8),
            ..super::paper_row(TRACK_TRAINED, Some(0.55), None)
        }],
        shape,
        notes,
        traces,
        particles: None,
    })
}

#[cfg(test)]
mod tests;
