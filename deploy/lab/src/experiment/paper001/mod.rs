//! Paper 001 (`ocelli experiment paper001`): hear what the cameras cannot see. Two studies, in
//! shape: [`acoustic`] — the acoustic likelihood alone as walls get in the way (Table 1,
//! Fig. 10: nearest-peak error small with one short wall, worse with two; entropy up with a
//! second wall); [`tracking`] — a person out of every camera's view behind a wall, the grid
//! estimator with optical detections and non-detections against optical + acoustic (Fig. 18:
//! the fused error stays within about 1 m while optical-only grows).
//!
//! Both run at sensor level on the real estimator (`node_head::grid`) and the simulated room
//! (`world::acoustics` renders the audio, the ILD is node-acoustic's), not through the node
//! processes of the simulation runtime: the tracking study needs the belief itself for its KL
//! divergence. Runs are seeds of the noise (audio, detections, test positions).

pub mod acoustic;
pub mod tracking;

use super::{Check, Options, Outcome, Row, Trace};
use crate::Result;
use sim::Level;

pub const NAME: &str = "paper001";
pub const OPTICAL: &str = "grid, optical (detection + no-detection)";
pub const FUSED: &str = "grid, optical + acoustic";
pub const FUSED_SHARP: &str = "grid, optical + acoustic sharpened";
/// Test sources per wall configuration and run.
const SOURCES: usize = 6;

fn mean(v: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.into_iter().fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

fn acoustic_rows(opts: &Options, o: &mut Outcome) -> Result<Vec<acoustic::Cell>> {
    let mut cells: Vec<acoustic::Cell> = Vec::new();
    for k in 0..o.runs {
        for (i, c) in acoustic::study(SOURCES, opts.seed.wrapping_add(u64::from(k)))?
            .into_iter()
            .enumerate()
        {
            match cells.get_mut(i) {
                Some(acc) => {
                    acc.errors_m.extend(c.errors_m);
                    acc.errors_interpolating_m.extend(c.errors_interpolating_m);
                    acc.entropies.extend(c.entropies);
                }
                None => cells.push(c),
            }
        }
    }
    for c in &cells {
        let (m, sd) = super::runner::mean_std(&c.errors_m).unwrap_or((f64::NAN, f64::NAN));
        o.rows.push(Row {
            method: format!(
                "acoustic only, {} wall{}, Ld {:.1} m, Lw {:.1} m (entropy {:.2} nats)",
                c.walls,
                if c.walls == 1 { "" } else { "s" },
                c.distance_m,
                c.length_m,
                c.mean_entropy()
            ),
            mean_error_m: Some(m),
            std_m: Some(sd),
            param: Some(c.distance_m),
            ..Row::default()
        });
    }
    for walls in [1u32, 2] {
        let errors: Vec<f64> = cells
            .iter()
            .filter(|c| c.walls == walls)
            .flat_map(|c| c.errors_interpolating_m.iter().copied())
            .collect();
        let (m, sd) = super::runner::mean_std(&errors).unwrap_or((f64::NAN, f64::NAN));
        o.rows.push(Row {
            method: format!(
                "acoustic only, {walls} wall{}, every case, interpolating spline",
                if walls == 1 { "" } else { "s" }
            ),
            mean_error_m: Some(m),
            std_m: Some(sd),
            ..Row::default()
        });
    }
    Ok(cells)
}

fn acoustic_checks(cells: &[acoustic::Cell], o: &mut Outcome) {
    let pick = |walls: u32| -> Vec<&acoustic::Cell> { cells.iter().filter(|c| c.walls == walls).collect() };
    let (one, two) = (pick(1), pick(2));
    let err = |v: &[&acoustic::Cell]| mean(v.iter().flat_map(|c| c.errors_m.iter().copied()));
    let ent = |v: &[&acoustic::Cell]| mean(v.iter().map(|c| c.mean_entropy()));
    let short = |v: &[&acoustic::Cell]| {
        let v: Vec<&acoustic::Cell> = v
            .iter()
            .copied()
            .filter(|c| c.length_m == acoustic::LENGTHS_M[0])
            .collect();
        err(&v)
    };
    let long = |v: &[&acoustic::Cell]| {
        let l = acoustic::LENGTHS_M[acoustic::LENGTHS_M.len() - 1];
        let v: Vec<&acoustic::Cell> = v.iter().copied().filter(|c| c.length_m == l).collect();
        err(&v)
    };
    if let (Some(e1), Some(e2)) = (err(&one), err(&two)) {
        o.shape.push(Check::new(
            "two walls locate worse than one (Fig. 10a vs 10b)",
            e2 > e1,
            format!("mean nearest-peak error {e1:.3} m with one wall, {e2:.3} m with two"),
        ));
    }
    if let (Some(s), Some(l)) = (short(&one), long(&one)) {
        o.shape.push(Check::new(
            "one wall: a short wall locates better than a long one",
            s < l,
            format!("{s:.3} m with the shortest wall, {l:.3} m with the longest"),
        ));
    }
    if let (Some(h1), Some(h2)) = (ent(&one), ent(&two)) {
        o.shape.push(Check::new(
            "a second wall raises the likelihood's differential entropy (Fig. 10c)",
            h2 > h1,
            format!("{h1:.2} nats with one wall, {h2:.2} with two"),
        ));
    }
}

fn tracking_rows(opts: &Options, duration_s: f64, o: &mut Outcome) -> Result<()> {
    let windows = tracking::windows(duration_s);
    let hidden = |t: f64| windows.iter().any(|w| t >= w.0 && t < w.1);
    let (mut a_runs, mut b_runs, mut c_runs) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..o.runs {
        let [a, b, c] = tracking::run_once(opts.seed.wrapping_add(u64::from(k)), duration_s)?;
        if k == 0 {
            let window = windows.first().copied();
            for (label, steps) in [(OPTICAL, &a), (FUSED, &b), (FUSED_SHARP, &c)] {
                o.traces.push(Trace {
                    method: label.into(),
                    samples: tracking::samples(steps),
                    window,
                });
            }
        }
        a_runs.push(a);
        b_runs.push(b);
        c_runs.push(c);
    }
    let mut figures = Vec::new();
    let sharp_label = format!("{FUSED_SHARP} (likelihood^{})", tracking::SHARPENED);
    for (label, runs) in [
        (OPTICAL, &a_runs),
        (FUSED, &b_runs),
        (sharp_label.as_str(), &c_runs),
    ] {
        let steps = || runs.iter().flatten();
        let in_window: Vec<f64> = steps().filter(|s| hidden(s.t)).map(|s| s.error_m).collect();
        let (m, sd) = super::runner::mean_std(&in_window).unwrap_or((f64::NAN, f64::NAN));
        let kl = mean(steps().filter(|s| hidden(s.t)).map(|s| s.kl)).unwrap_or(f64::NAN);
        let seen_err = mean(steps().filter(|s| !hidden(s.t)).map(|s| s.error_m)).unwrap_or(f64::NAN);
        // Error at the end of the hidden stretch (its last quarter), for "grows".
        let late = windows.first().map_or(f64::NAN, |w| {
            let from = w.1 - 0.25 * (w.1 - w.0);
            mean(steps().filter(|s| s.t >= from && s.t < w.1).map(|s| s.error_m)).unwrap_or(f64::NAN)
        });
        o.rows.push(Row {
            method: format!("{label}: hidden stretch (KL {kl:.2} nats)"),
            mean_error_m: Some(m),
            std_m: Some(sd),
            ..Row::default()
        });
        o.rows.push(Row {
            method: format!("{label}: in view"),
            mean_error_m: Some(seen_err),
            ..Row::default()
        });
        figures.push((m, late, kl));
    }
    let (opt, fus) = (figures[0], figures[1]);
    o.shape.push(Check::new(
        "fused estimate within about 1 m while hidden (Fig. 18a)",
        fus.1 <= 1.0 && fus.0 <= 1.0,
        format!(
            "optical + acoustic {:.2} m mean, {:.2} m at the end of the stretch",
            fus.0, fus.1
        ),
    ));
    o.shape.push(Check::new(
        "optical-only error grows while hidden, above the fused one (Fig. 18a)",
        opt.1 > opt.0 && opt.1 > fus.1,
        format!(
            "optical only {:.2} m mean, {:.2} m at the end of the stretch",
            opt.0, opt.1
        ),
    ));
    o.shape.push(Check::new(
        "KL divergence lower with the acoustic sensor while hidden (Fig. 18b)",
        fus.2 < opt.2,
        format!("{:.2} nats fused, {:.2} optical only", fus.2, opt.2),
    ));
    let sharp = figures[2];
    o.notes.push(format!(
        "Not the paper's likelihood: with the acoustic likelihood raised to the power {} \
         ([method.grid] acoustic-sharpness) the hidden-stretch error is {:.2} m ({:.2} m at its \
         end) and the KL divergence {:.2} nats.",
        tracking::SHARPENED,
        sharp.0,
        sharp.1,
        sharp.2
    ));
    o.notes.push(format!(
        "Tracking: hidden windows {:?} s (no camera sees the target); rows 'hidden stretch' average \
         every step inside them, 'in view' the rest; KL is D(truth-centred Gaussian σ 0.3 m ‖ \
         belief), the Gaussian on the free cells in the truth's line of sight (unrestricted, it \
         spilt through the corridor's walls and read 20–30 nats with the estimate 1 cm off). The \
         acoustic node stands on the corridor's side wall in the hidden stretch; at the \
         corridor's end, where the walk changes only its range, the fused hidden-stretch error \
         was 0.70 m and the KL 1.15 nats (5 runs from seed 1).",
        windows
            .iter()
            .map(|w| format!("{:.1}–{:.1}", w.0, w.1))
            .collect::<Vec<_>>()
    ));
    Ok(())
}

/// Run both studies.
///
/// # Errors
/// A scenario, survey or likelihood the estimator refuses.
pub fn run(opts: &Options) -> Result<Outcome> {
    let duration_s = opts.duration_s.unwrap_or(tracking::DURATION_S);
    let mut o = Outcome::new(NAME, Level::Measurement, opts, duration_s);
    let cells = acoustic_rows(opts, &mut o)?;
    acoustic_checks(&cells, &mut o);
    tracking_rows(opts, duration_s, &mut o)?;
    o.notes.push(
        "Acoustic rows: mean and std of the nearest-peak error over the test sources (param: the \
         nearer wall's distance L_d); the entropy is the differential entropy of the normalised \
         likelihood. Per-case rows use the paper's spline (correlations as control points, eq. \
         17); the two 'every case' rows score the same test sounds with the spline interpolating \
         the correlations. The room is the paper's bench (Table 1) scaled by 3 because our band \
         is the paper's real-room 20–386 Hz: the paper's 2 cm and 20 cm are 6 cm and 60 cm here, \
         and its 10 cm speaker spacing our 0.3 m lattice (a source's mean distance to the \
         nearest lattice node is 0.115 m)."
            .into(),
    );
    o.notes.push(
        "Level: sensor-level, on the real estimator and the simulated room's rendered audio, not \
         through the node processes (the KL divergence needs the belief)."
            .into(),
    );
    o.paper = vec![
        super::paper_row("acoustic only, 1 wall (11 of 12 cases within)", Some(0.02), None),
        super::paper_row("acoustic only, 2 walls (4 of 9 cases over)", Some(0.20), None),
        super::paper_row("grid, optical + acoustic: hidden (within)", Some(1.0), None),
    ];
    Ok(o)
}
