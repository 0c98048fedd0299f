//! Runs one method of an experiment over N seeded simulations and aggregates what
//! node-server's report computes from each outcome: errors pooled over every run's samples,
//! sensors per step, camera measurements per run, power of the camera nodes.

use super::{Options, Row};
use node_server::analysis::Loaded;
use node_server::export::track_rows;
use node_server::report::{self, Report};
use proto::ClusterTime;
use proto::scenario::Scenario;
use serde::Serialize;
use sim::faults::Faults;
use sim::{Level, Sim, SimOptions};

/// One owner estimate of the (single) true target, scored against the truth.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sample {
    /// Scenario seconds.
    pub t: f64,
    pub est: [f64; 3],
    pub truth: [f64; 3],
    /// √ trace of the position covariance, m.
    pub sigma_m: f64,
    /// Horizontal-plus-vertical (3-D) distance to the truth, m.
    pub error_m: f64,
    pub cameras: u32,
    pub rssi_nodes: u32,
}

/// A method: its label, scenario and faults.
#[derive(Clone, Debug)]
pub struct Method {
    pub label: String,
    pub scenario: Scenario,
    pub faults: Faults,
    /// Whether the method takes RSSI (the RSSI column is n/a otherwise).
    pub uses_rssi: bool,
    /// Association gate of the report, m: a global track farther than this from the target on
    /// average is scored as a false track (node-server's default unless an experiment needs
    /// every track of its single target scored, however far it strays).
    pub gate_m: f64,
    /// ML depth handling of the heads (their default when `None`).
    pub ml_depth: Option<node_head::fusion::ml::DepthHandling>,
}

/// Every run of one method.
#[derive(Clone, Debug)]
pub struct Runs {
    pub row: Row,
    /// Each run's samples, in run order.
    pub samples: Vec<Vec<Sample>>,
}

impl Runs {
    /// Errors of the samples with `t` in `[from, to)`; `None` without samples.
    pub fn errors_in(&self, from: f64, to: f64) -> Option<Errors> {
        Errors::of(&self.samples, |t| t >= from && t < to)
    }

    /// The same for the samples outside `[from, to)`.
    pub fn errors_out(&self, from: f64, to: f64) -> Option<Errors> {
        Errors::of(&self.samples, |t| t < from || t >= to)
    }
}

/// Errors of a method's runs: mean and standard deviation pooled over every sample, with the
/// runs' own means for their spread.
#[derive(Clone, Debug, PartialEq)]
pub struct Errors {
    pub mean: f64,
    pub std: f64,
    pub samples: usize,
    /// Each run's mean, in run order; `None` for a run without a kept sample.
    pub run_means: Vec<Option<f64>>,
    /// Half-width of the 95% confidence interval of the mean over the runs.
    pub ci95: Option<f64>,
}

impl Errors {
    /// The errors of the samples of `runs` whose time `keep` accepts; `None` without any.
    pub fn of(runs: &[Vec<Sample>], keep: impl Fn(f64) -> bool) -> Option<Errors> {
        let per_run: Vec<Vec<f64>> = runs
            .iter()
            .map(|r| r.iter().filter(|s| keep(s.t)).map(|s| s.error_m).collect())
            .collect();
        let all: Vec<f64> = per_run.iter().flatten().copied().collect();
        let (mean, std) = mean_std(&all)?;
        let run_means: Vec<Option<f64>> = per_run.iter().map(|e| mean_std(e).map(|m| m.0)).collect();
        let present: Vec<f64> = run_means.iter().flatten().copied().collect();
        Some(Errors {
            mean,
            std,
            samples: all.len(),
            ci95: ci95(&present),
            run_means,
        })
    }
}

/// Half-width of the 95% confidence interval of the mean of `xs` (Student's t with n − 1
/// degrees of freedom, sample standard deviation); `None` below two values.
pub fn ci95(xs: &[f64]) -> Option<f64> {
    let n = xs.len();
    if n < 2 {
        return None;
    }
    let m = xs.iter().sum::<f64>() / n as f64;
    let var = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
    Some(t975(n - 1) * (var / n as f64).sqrt())
}

/// The 97.5% quantile of Student's t with `df` degrees of freedom; between tabulated degrees,
/// the next lower one's (a slightly wider interval).
fn t975(df: usize) -> f64 {
    const SMALL: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145,
        2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048,
        2.045, 2.042,
    ];
    match df {
        0 => f64::INFINITY,
        1..=30 => SMALL[df - 1],
        31..=39 => SMALL[29],
        40..=59 => 2.021,
        60..=119 => 2.000,
        120..=999 => 1.980,
        _ => 1.960,
    }
}

/// The runs' ratios of `a`'s mean error to `b`'s, paired by run (same seeds, same order; a run
/// either lacks, or where `b`'s mean is not positive, left out): their mean, its 95% half-width
/// and the number of pairs. `None` unless both rows come from the same runs and one pairs.
pub fn paired_ratio(a: &Row, b: &Row) -> Option<(f64, Option<f64>, usize)> {
    let (x, y) = (&a.run_errors_m, &b.run_errors_m);
    if x.len() != y.len() {
        return None;
    }
    let r: Vec<f64> = x
        .iter()
        .zip(y)
        .filter_map(|(x, y)| match (x, y) {
            (Some(x), Some(y)) if *y > 0.0 => Some(x / y),
            _ => None,
        })
        .collect();
    if r.is_empty() {
        return None;
    }
    Some((r.iter().sum::<f64>() / r.len() as f64, ci95(&r), r.len()))
}

/// [`paired_ratio`] in words for a shape check, "" when the rows cannot be paired: "; per run
/// 1.26x ±0.08 (95%, 5 runs)".
pub fn paired_ratio_text(a: Option<&Row>, b: Option<&Row>) -> String {
    let Some((a, b)) = a.zip(b) else {
        return String::new();
    };
    match paired_ratio(a, b) {
        Some((r, Some(ci), n)) => format!("; per run {r:.2}x ±{ci:.2} (95%, {n} runs)"),
        _ => String::new(),
    }
}

/// Mean and (population) standard deviation.
pub fn mean_std(xs: &[f64]) -> Option<(f64, f64)> {
    if xs.is_empty() {
        return None;
    }
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    Some((m, (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()))
}

/// One simulation of a method: the report and the scored samples.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run_once(
    m: &Method,
    seed: u64,
    level: Level,
    duration_s: f64,
) -> crate::Result<(Report, Vec<Sample>)> {
    let opts = SimOptions {
        seed,
        duration_s,
        level,
        faults: m.faults.clone(),
        ml_depth: m.ml_depth,
        ..SimOptions::default()
    };
    let outcome = Sim::new(m.scenario.clone(), opts)?.run();
    let loaded = Loaded {
        scenario: m.scenario.clone(),
        records: outcome.records,
        skipped: Vec::new(),
    };
    let truth = sim::WorldTruth::new(&m.scenario, ClusterTime(0))?;
    let report = report::compute_with(&loaded, Some(&truth), m.gate_m);
    // The report associates global tracks with the true target; score exactly those.
    let globals = report
        .targets
        .first()
        .map(|t| t.globals.clone())
        .unwrap_or_default();
    let target = truth.targets().first();
    let samples = track_rows(&loaded)
        .into_iter()
        .filter(|r| r.owner && globals.contains(&r.global))
        .filter_map(|r| {
            let x = target?.truth_at(r.t);
            let truth = [x[0], x[1], x[2]];
            let est = [r.x, r.y, r.z];
            let error_m = est
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            Some(Sample {
                t: r.t,
                est,
                truth,
                sigma_m: r.sigma_m,
                error_m,
                cameras: r.cameras,
                rssi_nodes: r.rssi_nodes,
            })
        })
        .collect();
    crate::progress::tell(&crate::progress::Step::Run {
        method: &m.label,
        seed,
    });
    Ok((report, samples))
}

/// Run a method `opts.runs` times (seeds `seed`, `seed + 1`, …) and aggregate.
///
/// # Errors
/// A scenario the simulation cannot build.
pub fn run_method(m: &Method, opts: &Options, level: Level, duration_s: f64) -> crate::Result<Runs> {
    let runs = opts.runs.max(1);
    let (mut cams, mut rssi, mut meas, mut power) = (0.0, 0.0, 0.0, 0.0);
    let mut samples = Vec::new();
    let mut untracked = 0u32;
    let mut run_power = Vec::with_capacity(runs as usize);
    for k in 0..runs {
        let seed = opts.seed.wrapping_add(u64::from(k));
        let (rep, s) = run_once(m, seed, level, duration_s)?;
        tracing::debug!(method = %m.label, seed, samples = s.len(), "experiment run done");
        cams += rep.active_cameras_mean;
        rssi += rep.rssi_nodes_mean;
        meas += rep.active_cameras_mean * rep.steps as f64;
        let p = camera_power(&m.scenario, &rep);
        power += p;
        run_power.push(p);
        if s.is_empty() {
            untracked += 1;
        }
        samples.push(s);
    }
    let n = f64::from(runs);
    let errors = Errors::of(&samples, |_| true);
    Ok(Runs {
        row: Row {
            method: m.label.clone(),
            measurements: Some(meas / n),
            active_cameras: Some(cams / n),
            rssi_measurements: m.uses_rssi.then_some(rssi / n),
            power_mw: Some(power / n),
            param: None,
            untracked_runs: Some(untracked),
            run_power_mw: run_power,
            ..Row::default()
        }
        .with_errors(errors),
        samples,
    })
}

/// Mean total power of the scenario's camera nodes (the papers count no head or server).
fn camera_power(scenario: &Scenario, rep: &Report) -> f64 {
    rep.energy
        .iter()
        .filter(|e| scenario.cameras().any(|c| c.id == e.node))
        .map(|e| e.mean_power_mw)
        .sum::<f64>()
        + 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(errors: &[(f64, f64)]) -> Vec<Sample> {
        errors
            .iter()
            .map(|&(t, e)| Sample {
                t,
                est: [0.0; 3],
                truth: [0.0; 3],
                sigma_m: 0.0,
                error_m: e,
                cameras: 0,
                rssi_nodes: 0,
            })
            .collect()
    }

    #[test]
    fn the_interval_is_students_t_over_the_runs_own_means() {
        // Means 1, 2, 3: sample sd 1, so the half-width is t(2) / √3.
        let h = ci95(&[1.0, 2.0, 3.0]).unwrap();
        assert!((h - 4.303 / 3f64.sqrt()).abs() < 1e-12, "{h}");
        assert_eq!(ci95(&[1.0]), None, "one run has no spread");
        assert_eq!(ci95(&[2.0, 2.0]), Some(0.0));
        // Between tabulated degrees the next lower one's quantile: wider, never narrower.
        assert!(t975(35) == t975(30) && t975(35) > t975(40) && t975(10_000) == 1.96);
    }

    #[test]
    fn errors_pool_the_samples_and_keep_each_runs_mean() {
        // Run 1 has three samples, run 2 one: the pooled mean weighs samples, the runs' means
        // weigh runs.
        let runs = vec![run(&[(0.0, 1.0), (1.0, 1.0), (2.0, 4.0)]), run(&[(0.5, 3.0)])];
        let e = Errors::of(&runs, |_| true).unwrap();
        assert_eq!((e.mean, e.samples), (9.0 / 4.0, 4));
        assert_eq!(e.run_means, vec![Some(2.0), Some(3.0)]);
        assert_eq!(e.ci95, ci95(&[2.0, 3.0]));
        // A window that leaves a run without samples leaves that run out, in its place.
        let late = Errors::of(&runs, |t| t >= 1.0).unwrap();
        assert_eq!(
            (late.mean, late.run_means.clone(), late.ci95),
            (2.5, vec![Some(2.5), None], None)
        );
        assert!(Errors::of(&runs, |t| t > 9.0).is_none());
        let row = Row::default().with_errors(Some(e));
        assert_eq!(row.mean_error_m, Some(2.25));
        assert_eq!(row.run_errors_m, vec![Some(2.0), Some(3.0)]);
    }

    #[test]
    fn ratios_pair_the_runs_by_seed() {
        // −1 stands for a run without samples.
        let row = |e: &[f64]| Row {
            run_errors_m: e.iter().map(|&x| (x >= 0.0).then_some(x)).collect(),
            ..Row::default()
        };
        // Run by run 2x and 4x: mean 3x, though the pooled means (2.5 / 1) would say 2.5x.
        let (r, ci, n) = paired_ratio(&row(&[2.0, 3.0]), &row(&[1.0, 0.75])).unwrap();
        assert_eq!((r, ci, n), (3.0, ci95(&[2.0, 4.0]), 2));
        // A run either lacks is left out, not paired with the next one; so is a run whose
        // denominator is zero.
        let (r, _, n) = paired_ratio(&row(&[2.0, -1.0, 6.0, 1.0]), &row(&[1.0, 5.0, -1.0, 0.0])).unwrap();
        assert_eq!((r, n), (2.0, 1));
        assert!(
            paired_ratio(&row(&[2.0]), &row(&[1.0, 1.0])).is_none(),
            "unpaired runs"
        );
        let text = paired_ratio_text(Some(&row(&[2.0, 3.0])), Some(&row(&[1.0, 0.75])));
        assert!(
            text.starts_with("; per run 3.00x ±") && text.ends_with("(95%, 2 runs)"),
            "{text}"
        );
        assert_eq!(paired_ratio_text(None, Some(&row(&[1.0]))), "");
    }
}
