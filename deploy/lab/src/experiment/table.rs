//! Printing an experiment's outcome: a text table of ours beside the paper's, the JSON the
//! issue fixes (`{"experiment", "rows": [{method, mean_error_m, std_m, measurements,
//! active_cameras, rssi_measurements, power_mw}]}` plus level, runs, paper and shape), and a
//! Markdown section for `docs/results.md`.

use super::{Outcome, Row};
use sim::Level;
use std::fmt::Write as _;

/// How the level is labelled in every output.
pub fn level_label(level: Level) -> &'static str {
    match level {
        Level::Pixel => "pixel (rendered and segmented frames)",
        Level::Measurement => "measurement (truth projected plus noise)",
    }
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "–".to_string(), |v| format!("{v:.digits$}"))
}

const HEADERS: [&str; 9] = [
    "method",
    "param",
    "mean err m",
    "±95% m",
    "std m",
    "measurements",
    "active cams",
    "rssi",
    "power mW",
];

fn cells(r: &Row, extras: &[String]) -> Vec<String> {
    let mut c = vec![
        r.method.clone(),
        cell(r.param, 3),
        cell(r.mean_error_m, 3),
        cell(r.mean_error_ci95_m, 3),
        cell(r.std_m, 3),
        cell(r.measurements, 0),
        cell(r.active_cameras, 2),
        cell(r.rssi_measurements, 2),
        cell(r.power_mw, 0),
    ];
    for name in extras {
        let e = r.extra.iter().find(|e| &e.name == name);
        c.push(e.map_or_else(|| "–".to_string(), |e| cell(e.value, e.digits)));
    }
    c
}

/// The names of the rows' own columns ([`Row::extra`]), in order of first appearance.
fn extra_names(rows: &[Row]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for e in rows.iter().flat_map(|r| &r.extra) {
        if !names.contains(&e.name) {
            names.push(e.name.clone());
        }
    }
    names
}

fn headers(extras: &[String]) -> Vec<String> {
    HEADERS
        .iter()
        .map(|h| h.to_string())
        .chain(extras.iter().cloned())
        .collect()
}

/// The columns of `rows`' table: the param only if a row has one, the interval only if a row
/// has one (the papers' rows never do). Rows with their own columns show a common column only
/// where some row has a value in it.
fn columns(rows: &[Row]) -> Vec<usize> {
    let param = rows.iter().any(|r| r.param.is_some());
    let ci = rows.iter().any(|r| r.mean_error_ci95_m.is_some());
    let extras = extra_names(rows);
    let sparse = !extras.is_empty();
    let filled = |f: fn(&Row) -> Option<f64>| !sparse || rows.iter().any(|r| f(r).is_some());
    let common: [bool; 9] = [
        true,
        param,
        filled(|r| r.mean_error_m),
        ci,
        filled(|r| r.std_m),
        filled(|r| r.measurements),
        filled(|r| r.active_cameras),
        filled(|r| r.rssi_measurements),
        filled(|r| r.power_mw),
    ];
    (0..HEADERS.len())
        .filter(|&i| common[i])
        .chain(HEADERS.len()..HEADERS.len() + extras.len())
        .collect()
}

fn text_table(rows: &[Row], s: &mut String) {
    let idx = columns(rows);
    let extras = extra_names(rows);
    let heads = headers(&extras);
    let all: Vec<Vec<String>> = rows.iter().map(|r| cells(r, &extras)).collect();
    let width = |i: usize| {
        all.iter()
            .map(|c| c[i].chars().count())
            .chain([heads[i].chars().count()])
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..heads.len()).map(width).collect();
    let line = |c: &[String]| {
        let mut l = String::new();
        for &i in &idx {
            if i == 0 {
                let _ = write!(l, "{:<w$}", c[i], w = widths[i]);
            } else {
                let _ = write!(l, "  {:>w$}", c[i], w = widths[i]);
            }
        }
        l.trim_end().to_string()
    };
    let _ = writeln!(s, "{}", line(&heads));
    for c in &all {
        let _ = writeln!(s, "{}", line(c));
    }
}

/// The run's setup in words: the level and runs of a simulation, or what the runs of a real-data
/// experiment are (it has no level; its runs are seeds of its camera stand-in's noise).
fn setup(o: &Outcome, each: &str) -> String {
    if super::REAL_DATA.contains(&o.experiment.as_str()) {
        format!(
            "real data, no simulation; {} runs (stand-in noise seeds) from seed {}, {:.0} s of data",
            o.runs, o.seed, o.duration_s
        )
    } else {
        format!(
            "level: {}, {} runs from seed {}, {:.0} {each}",
            level_label(o.level),
            o.runs,
            o.seed,
            o.duration_s
        )
    }
}

/// Our table, the paper's, the shape checks and the notes, as text.
pub fn to_text(o: &Outcome) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "experiment {} — {}", o.experiment, setup(o, "s each"));
    let _ = writeln!(s, "\nours:");
    text_table(&o.rows, &mut s);
    // An experiment of our own (no paper behind it) has no paper table.
    if !o.paper.is_empty() {
        let _ = writeln!(s, "\npaper:");
        text_table(&o.paper, &mut s);
    }
    if !o.shape.is_empty() {
        let _ = writeln!(s, "\nshape:");
        for c in &o.shape {
            let verdict = if c.holds { "holds" } else { "DOES NOT HOLD" };
            let _ = writeln!(s, "  [{verdict}] {} ({})", c.claim, c.ours);
        }
    }
    if !o.notes.is_empty() {
        let _ = writeln!(s, "\nnotes:");
        for n in &o.notes {
            let _ = writeln!(s, "  - {n}");
        }
    }
    s
}

/// The issue's JSON, with level, runs, seed, paper rows and the shape checks added.
pub fn to_json(o: &Outcome) -> serde_json::Value {
    serde_json::json!({
        "experiment": o.experiment,
        "level": o.level,
        "level_label": level_label(o.level),
        "runs": o.runs,
        "seed": o.seed,
        "duration_s": o.duration_s,
        "rows": o.rows,
        "paper": o.paper,
        "shape": o.shape,
        "notes": o.notes,
    })
}

fn md_table(rows: &[Row], s: &mut String) {
    let idx = columns(rows);
    let extras = extra_names(rows);
    let heads = headers(&extras);
    let _ = writeln!(
        s,
        "| {} |",
        idx.iter()
            .map(|&i| heads[i].as_str())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|{}", idx.iter().map(|_| "---|").collect::<String>());
    for r in rows {
        let c = cells(r, &extras);
        let _ = writeln!(
            s,
            "| {} |",
            idx.iter().map(|&i| c[i].as_str()).collect::<Vec<_>>().join(" | ")
        );
    }
}

/// A Markdown section: heading, command, our table, the paper's, the shape and the notes.
pub fn to_markdown(o: &Outcome, command: &str, figures: &[String]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## {}\n", o.experiment);
    let _ = writeln!(s, "```\n{command}\n```\n");
    let setup = setup(o, "simulated seconds each");
    let mut first = setup.chars();
    let capitalized: String = first
        .next()
        .map(|c| c.to_uppercase().chain(first).collect())
        .unwrap_or_default();
    let _ = writeln!(s, "{capitalized}.\n");
    let _ = writeln!(s, "Ours:\n");
    md_table(&o.rows, &mut s);
    if !o.paper.is_empty() {
        let _ = writeln!(s, "\nPaper:\n");
        md_table(&o.paper, &mut s);
    }
    if !o.shape.is_empty() {
        let _ = writeln!(s, "\nShape:\n");
        for c in &o.shape {
            let verdict = if c.holds { "holds" } else { "**does not hold**" };
            let _ = writeln!(s, "- {verdict}: {} ({})", c.claim, c.ours);
        }
    }
    if !o.notes.is_empty() {
        let _ = writeln!(s, "\nNotes:\n");
        for n in &o.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    for f in figures {
        let _ = writeln!(s, "\n![{f}]({f})");
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::Check;

    fn outcome() -> Outcome {
        Outcome {
            experiment: "x".into(),
            level: Level::Measurement,
            runs: 2,
            seed: 1,
            duration_s: 10.0,
            rows: vec![Row {
                method: "A".into(),
                mean_error_m: Some(0.25),
                power_mw: Some(100.0),
                ..Row::default()
            }],
            paper: vec![Row {
                method: "A".into(),
                mean_error_m: Some(0.3),
                ..Row::default()
            }],
            shape: vec![Check::new("c", false, "o".into())],
            notes: vec![],
            traces: vec![],
            particles: None,
        }
    }

    #[test]
    fn json_has_the_issue_keys_with_null_where_not_applicable() {
        let v = to_json(&outcome());
        assert_eq!(v["experiment"], "x");
        let row = &v["rows"][0];
        for k in [
            "method",
            "mean_error_m",
            "std_m",
            "measurements",
            "active_cameras",
            "rssi_measurements",
            "power_mw",
        ] {
            assert!(row.get(k).is_some(), "row lacks {k}: {row}");
        }
        assert!(row["std_m"].is_null());
        assert_eq!(row["mean_error_m"], 0.25);
        assert_eq!(v["level"], "measurement");
    }

    #[test]
    fn text_and_markdown_label_level_paper_and_failed_shape() {
        let t = to_text(&outcome());
        assert!(t.contains("measurement (truth projected plus noise)"));
        assert!(t.contains("paper:") && t.contains("DOES NOT HOLD"));
        let m = to_markdown(&outcome(), "ocelli experiment x", &["f.png".into()]);
        assert!(m.contains("| A | 0.250 |") && m.contains("![f.png](f.png)"));
        assert!(m.contains("**does not hold**"));
    }

    #[test]
    fn the_interval_column_appears_only_for_rows_that_have_one() {
        let mut o = outcome();
        assert!(!to_text(&o).contains("±95%"), "no row has an interval");
        o.rows[0].mean_error_ci95_m = Some(0.04);
        o.rows[0].run_errors_m = vec![Some(0.2), Some(0.3)];
        let m = to_markdown(&o, "c", &[]);
        assert!(m.contains("| method | mean err m | ±95% m | std m |"), "{m}");
        assert!(m.contains("| A | 0.250 | 0.040 | – |"), "{m}");
        // The paper's table has no interval column.
        assert!(m.contains("| method | mean err m | std m |"), "{m}");
        assert_eq!(to_json(&o)["rows"][0]["run_errors_m"][1], 0.3);
    }

    #[test]
    fn rows_with_their_own_columns_show_them_and_only_the_common_columns_with_values() {
        let mut o = outcome();
        o.rows[0].extra = vec![crate::experiment::Extra::new("bytes/s", Some(812.4), 0)];
        o.rows.push(Row {
            method: "B".into(),
            extra: vec![crate::experiment::Extra::new("ids", Some(2.0), 0)],
            ..Row::default()
        });
        let m = to_markdown(&o, "c", &[]);
        assert!(
            m.contains("| method | mean err m | power mW | bytes/s | ids |"),
            "{m}"
        );
        assert!(m.contains("| A | 0.250 | 100 | 812 | – |"), "{m}");
        assert!(m.contains("| B | – | – | – | 2 |"), "{m}");
        assert!(to_text(&o).contains("bytes/s"));
        assert_eq!(to_json(&o)["rows"][0]["extra"][0]["name"], "bytes/s");
    }
}
