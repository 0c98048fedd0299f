//! These read the real dataset; absent, they fail naming its path.
use super::*;
use std::sync::OnceLock;

fn dataset() -> &'static Dataset {
    static DS: OnceLock<Dataset> = OnceLock::new();
    DS.get_or_init(|| {
        let dir = data::default_dir();
        data::load(&dir).unwrap_or_else(|e| panic!("the ble-rssi tests need the dataset: {e}"))
    })
}

fn outcome() -> &'static Outcome {
    static OUT: OnceLock<Outcome> = OnceLock::new();
    OUT.get_or_init(|| {
        let opts = Options {
            runs: 2,
            ..Options::default()
        };
        run_on(dataset(), &opts).unwrap_or_else(|e| panic!("{e:#}"))
    })
}

fn param(prefix: &str) -> f64 {
    let o = outcome();
    o.rows
        .iter()
        .find(|r| r.method.starts_with(prefix))
        .and_then(|r| r.param)
        .unwrap_or_else(|| panic!("no {prefix} row: {:?}", o.rows))
}

fn error(method: &str) -> f64 {
    outcome()
        .row(method)
        .and_then(|r| r.mean_error_m)
        .unwrap_or_else(|| panic!("no error for {method}"))
}

#[test]
fn a_missing_dataset_fails_naming_its_path() {
    let e = run_from(
        std::path::Path::new("/nonexistent/ble-rssi-dir"),
        &Options::default(),
    )
    .expect_err("no dataset there");
    let msg = format!("{e:#}");
    assert!(
        msg.contains("/nonexistent/ble-rssi-dir") && msg.contains(NAME),
        "{msg}"
    );
}

#[test]
fn the_dataset_is_what_its_readme_says() {
    let ds = dataset();
    assert_eq!(ds.sensors.len(), 12);
    assert_eq!(ds.trajectories.len(), 4);
    let packets: Vec<&data::Packet> = ds.trajectories.iter().flat_map(|t| &t.packets).collect();
    assert!(packets.len() > 6000, "{}", packets.len());
    // Carried at a roughly constant height: what the 2-D tracking assumes.
    assert!(packets.iter().all(|p| (1.5..2.1).contains(&p.truth.z)));
    for t in &ds.trajectories {
        assert!(
            t.packets.windows(2).all(|w| w[0].t <= w[1].t),
            "{} in time order",
            t.name
        );
    }
}

#[test]
fn rssi_falls_with_distance_in_every_fold() {
    let ds = dataset();
    for i in 0..ds.trajectories.len() {
        let (fit, height) = fold(ds, i).expect("fits");
        assert!(fit.a < -8.0, "fold {i}: {fit:?}");
        assert!((3.0..10.0).contains(&fit.sd_db), "fold {i}: {fit:?}");
        assert!((1.6..2.0).contains(&height), "fold {i}: {height}");
    }
}

#[test]
fn the_fitted_law_beats_both_invented_laws_on_held_out_trajectories() {
    let (fitted, sim, default) = (param(LAW_FITTED), param(LAW_SIM), param(LAW_DEFAULT));
    assert!(fitted + 1.0 < sim, "{fitted} vs sim {sim}");
    assert!(sim + 2.0 < default, "{sim} vs default {default}");
    // One trajectory is enough to calibrate: the law is the room's, not the path's.
    let one = param(LAW_ONE);
    assert!((one - fitted).abs() < 0.5, "{one} vs {fitted}");
}

#[test]
fn residual_parts_add_up_to_the_total_residual() {
    let s = law::structure(
        dataset(),
        &law::fit_log(law::pairs(
            dataset(),
            dataset().trajectories.iter().flat_map(|t| &t.packets),
        ))
        .expect("fits")
        .model(),
    )
    .expect("structure");
    let parts = s.sensor_offset_db.powi(2) + s.smooth_db.powi(2) + s.noise_db.powi(2);
    assert!((parts.sqrt() - s.total_db).abs() < 0.1 * s.total_db, "{s:?}");
    // The nugget seen in space and in time agree.
    assert!(
        (s.close_semivariance_db2 - s.consecutive_semivariance_db2).abs() < 0.25 * s.close_semivariance_db2,
        "{s:?}"
    );
    assert!(s.length_m > 0.2 && s.length_m < 5.0, "{s:?}");
}

#[test]
fn trained_models_predict_held_out_packets_better_than_the_scenario_default() {
    let (alg1, local, fitted, default) = (
        param(NEXT_ALG1),
        param(NEXT_LOCAL),
        param(NEXT_FITTED),
        param(NEXT_DEFAULT),
    );
    assert!(alg1 + 3.0 < default, "{alg1} vs {default}");
    assert!(local + 0.3 < fitted, "{local} vs {fitted}");
    assert!(alg1 < fitted, "{alg1} vs {fitted}");
}

#[test]
fn trained_models_track_better_than_the_fitted_law_which_beats_the_default() {
    let (trained, fitted, default) = (error(TRACK_TRAINED), error(TRACK_FITTED), error(TRACK_DEFAULT));
    assert!(trained < 0.7 * fitted, "{trained} vs {fitted}");
    assert!(fitted < 0.5 * default, "{fitted} vs {default}");
    // A worse stand-in makes the trained models worse: they lean on it.
    assert!(
        error(TRACK_TRAINED_WIDE) > trained,
        "{} vs {trained}",
        error(TRACK_TRAINED_WIDE)
    );
}
