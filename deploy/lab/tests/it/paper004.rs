//! `ocelli experiment paper004`, short (one run of 6 s): every study's rows are there with
//! finite figures and the shape checks are evaluated. Whether they hold is the experiment's
//! finding (docs/results.md), not asserted here.

use lab::experiment::{self, Options};

#[test]
fn paper004_short_run_has_every_study_with_finite_rows_and_evaluated_checks() {
    let opts = Options {
        runs: 1,
        seed: 1,
        level: None,
        duration_s: Some(6.0),
    };
    let o = experiment::run(experiment::paper004::NAME, &opts).expect("the experiment runs");
    let table = experiment::table::to_text(&o);
    for study in [
        "1 occlusion",
        "1 wide occlusion",
        "2 dimming",
        "2 dimming with colour shift",
        "3 crowd",
        "3 stream",
        "4 bandwidth: five or more in view",
        "4 bandwidth",
    ] {
        assert!(
            o.rows.iter().any(|r| r.method.starts_with(study)),
            "no rows of {study}: {table}"
        );
    }
    assert_eq!(o.rows.len(), 21, "{table}");
    for r in &o.rows {
        assert!(!r.extra.is_empty(), "{} has no figures", r.method);
        let values = r.extra.iter().filter_map(|e| e.value).chain(r.mean_error_m);
        for v in values {
            assert!(v.is_finite(), "{}: {v} in {table}", r.method);
        }
    }
    // The occlusion rows are scored (the person is in view), and bytes were counted.
    let tracked = |m: &str| {
        o.row(m)
            .and_then(|r| r.extra.iter().find(|e| e.name == "tracked"))
            .and_then(|e| e.value)
    };
    assert!(tracked("1 occlusion: particle filters").is_some(), "{table}");
    assert!(
        tracked("1 wide occlusion: segmentation alone").is_some(),
        "{table}"
    );
    assert!(o.shape.len() >= 9, "{table}");
    assert!(!o.traces.is_empty());
}
