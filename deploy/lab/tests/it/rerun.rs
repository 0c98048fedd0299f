//! `ocelli replay RECORDING`: a logging run's recorded measurements re-run through the heads.
//! Replayed with the run's own method, policy, seed and network, the replay is the run (every
//! server record equal, bit for bit); replayed with another policy, it shows that policy's
//! sensor use on the very same measurements (paper 002's offline comparison).

use lab::replay::rerun::{Rerun, RerunOptions, rerun, without_measurements};
use node_server::analysis::Loaded;
use node_server::report::{self, Report};
use node_server::{Record, Stamped};
use proto::ClusterTime;
use proto::msg::Message;
use proto::scenario::{Activation, Fusion, Scenario};
use sim::{Level, Sim, SimOptions};

fn opts(seed: u64, duration_s: f64) -> SimOptions {
    SimOptions {
        seed,
        duration_s,
        level: Level::Measurement,
        record_measurements: true,
        ..SimOptions::default()
    }
}

/// A logging run written to a recording file and read back.
fn logging_run(fusion: Fusion, activation: Activation, o: &SimOptions, name: &str) -> (Vec<Stamped>, Loaded) {
    let mut scenario = Scenario::default_scenario();
    scenario.method.fusion = fusion;
    scenario.method.activation = activation;
    logging_run_of(scenario, o, name)
}

fn logging_run_of(scenario: Scenario, o: &SimOptions, name: &str) -> (Vec<Stamped>, Loaded) {
    let outcome = Sim::new(scenario, o.clone()).expect("simulates").run();
    let path = std::env::temp_dir().join(format!("ocelli-rerun-{name}-{}.ocrec", std::process::id()));
    outcome.write_recording(&path).expect("recording");
    let loaded = node_server::analysis::load(&path, None).expect("reads back with its scenario");
    let _ = std::fs::remove_file(&path);
    (outcome.records, loaded)
}

/// Replay `loaded` with `o`, the recorded method and policy unless given.
fn rerun_with(
    loaded: &Loaded,
    fusion: Option<Fusion>,
    activation: Option<Activation>,
    o: &SimOptions,
) -> lab::Result<Rerun> {
    rerun(
        loaded,
        &RerunOptions {
            fusion,
            activation,
            sim: o.clone(),
            t0: ClusterTime(0),
        },
    )
}

fn track_reports(records: &[&Stamped]) -> usize {
    records
        .iter()
        .filter(|s| matches!(&s.record, Record::Received(e) if matches!(e.body, Message::TrackReport(_))))
        .count()
}

#[test]
fn replaying_a_logging_run_with_its_own_method_and_policy_is_the_run() {
    for (fusion, activation, seed, level) in [
        (
            Fusion::DistributedEif,
            Activation::ThreeMode,
            3,
            Level::Measurement,
        ),
        (Fusion::CentralizedEif, Activation::AllOn, 4, Level::Measurement),
        (
            Fusion::DistributedEif,
            Activation::FullNode,
            5,
            Level::Measurement,
        ),
        (Fusion::DistributedEif, Activation::ThreeMode, 6, Level::Pixel),
    ] {
        let o = SimOptions {
            level,
            ..opts(seed, 8.0)
        };
        let (run, loaded) = logging_run(fusion, activation, &o, "same");
        let measured = run.len() - without_measurements(&run).len();
        // 21 cameras at 5 fps for 8 s, whatever their mode.
        assert!(measured > 21 * 5 * 7, "only {measured} measured frames");
        let replay = rerun_with(&loaded, Some(fusion), Some(activation), &o).expect("replays");
        assert_eq!(replay.frames, measured as u64);
        assert_eq!((replay.unknown_camera_frames, replay.superseded_frames), (0, 0));
        let (a, b) = (without_measurements(&run), without_measurements(&replay.records));
        assert!(
            track_reports(&a) > 20,
            "{fusion:?}/{activation:?}: only {} track reports",
            track_reports(&a)
        );
        let first_difference = a.iter().zip(&b).position(|(x, y)| x != y);
        assert_eq!(
            (a.len(), first_difference),
            (b.len(), None),
            "{fusion:?}/{activation:?}/{level:?}: the replay differs from the run"
        );
    }
}

/// The replay's estimates come from the recorded measurements: move every recorded point a
/// little and the estimates move.
#[test]
fn replayed_estimates_follow_the_recorded_measurements() {
    let o = opts(3, 6.0);
    let (_, mut loaded) = logging_run(Fusion::DistributedEif, Activation::AllOn, &o, "moved");
    let replay = |loaded: &Loaded| {
        let r = rerun_with(loaded, None, None, &o).expect("replays");
        node_server::export::track_rows(&r.loaded())
    };
    let before = replay(&loaded);
    for s in &mut loaded.records {
        if let Record::Measured(f) = &mut s.record {
            for d in &mut f.detections {
                d.point[0] += 0.01;
            }
        }
    }
    let after = replay(&loaded);
    assert!(before.len() > 20);
    let moved = before
        .iter()
        .zip(&after)
        .filter(|(a, b)| (a.x - b.x).abs() + (a.y - b.y).abs() > 1e-3)
        .count();
    assert!(
        moved > before.len() / 2,
        "{moved} of {} estimates moved",
        before.len()
    );
}

/// A recording without measurements (an ordinary run) cannot be re-run, and says how to make
/// one that can.
#[test]
fn an_ordinary_recording_is_refused_with_a_hint() {
    let o = SimOptions {
        record_measurements: false,
        ..opts(1, 2.0)
    };
    let (_, loaded) = logging_run(Fusion::DistributedEif, Activation::AllOn, &o, "plain");
    let e = rerun_with(&loaded, None, None, &o).unwrap_err().to_string();
    assert!(e.contains("--record-measurements"), "{e}");
}

fn replay_with(loaded: &Loaded, activation: Activation, o: &SimOptions) -> Report {
    let replay = rerun_with(loaded, None, Some(activation), o).expect("replays");
    let truth = sim::WorldTruth::new(&replay.scenario, ClusterTime(0)).unwrap();
    report::compute(&replay.loaded(), Some(&truth))
}

#[test]
fn one_logging_run_replayed_with_three_mode_uses_fewer_cameras_and_less_power_than_all_on() {
    let o = opts(2, 20.0);
    let (_, loaded) = logging_run(Fusion::DistributedEif, Activation::AllOn, &o, "policies");
    let all_on = replay_with(&loaded, Activation::AllOn, &o);
    let three = replay_with(&loaded, Activation::ThreeMode, &o);
    eprintln!(
        "all-on: {:?} m, {:.2} cameras, {:.0} mW; three-mode: {:?} m, {:.2} cameras, {:.0} mW",
        all_on.mean_error_m,
        all_on.active_cameras_mean,
        all_on.power_mw_mean,
        three.mean_error_m,
        three.active_cameras_mean,
        three.power_mw_mean
    );
    let err_all = all_on.mean_error_m.expect("the scenario has ground truth");
    let err_three = three.mean_error_m.expect("the scenario has ground truth");
    assert!(err_all < 0.3, "all-on replay error {err_all} m");
    assert!(
        three.active_cameras_mean < 0.6 * all_on.active_cameras_mean,
        "three-mode {} cameras vs all-on {}",
        three.active_cameras_mean,
        all_on.active_cameras_mean
    );
    assert!(
        three.power_mw_mean < 0.6 * all_on.power_mw_mean,
        "three-mode {} mW vs all-on {} mW",
        three.power_mw_mean,
        all_on.power_mw_mean
    );
    assert!(
        err_three < 5.0 * err_all,
        "three-mode {err_three} m vs all-on {err_all} m"
    );
}

/// A run that surveys its default RSSI model records the model it used, and its replay (which
/// must not survey again) gives the same records.
#[test]
fn a_surveyed_run_records_its_model_and_replays_the_same() {
    let mut scenario = Scenario::default_scenario();
    scenario.method.rssi_survey = true;
    let literature = scenario.method.rssi_default;
    let o = opts(8, 6.0);
    let (run, loaded) = logging_run_of(scenario, &o, "surveyed");
    let m = &loaded.scenario.method;
    assert!(!m.rssi_survey, "the recording still asks for a survey");
    assert_ne!(
        m.rssi_default, literature,
        "the recording lost the surveyed model"
    );
    let replay = rerun_with(&loaded, None, None, &o).expect("replays");
    assert_eq!(
        without_measurements(&run),
        without_measurements(&replay.records),
        "the replay of a surveyed run differs from it"
    );
}

/// A logging run records what its cameras measured under the run's faults: the same run with
/// extra segmentation noise records detections that moved, by about the noise added.
#[test]
fn a_logging_run_records_its_detections_under_the_segmentation_noise_fault() {
    let plain = opts(3, 4.0);
    let noisy = SimOptions {
        faults: sim::faults::Faults {
            extra_pixel_sigma: 30.0,
            ..Default::default()
        },
        ..plain.clone()
    };
    // (camera, frame) → the centre of its single detection, pixels. Frames are matched by their
    // 100 ms slot: capture times follow each camera's synchronized clock, which differs by a
    // fraction of a millisecond between runs.
    let centres = |o: &SimOptions, name: &str| -> std::collections::BTreeMap<(u32, i64), [f32; 2]> {
        let (records, _) = logging_run(Fusion::DistributedEif, Activation::AllOn, o, name);
        records
            .iter()
            .filter_map(|s| match &s.record {
                Record::Measured(f) if f.detections.len() == 1 => Some((
                    (f.camera.0, (f.captured.as_secs_f64() * 10.0).round() as i64),
                    f.detections[0].centre,
                )),
                _ => None,
            })
            .collect()
    };
    let (a, again, b) = (
        centres(&plain, "seg-plain"),
        centres(&plain, "seg-plain-again"),
        centres(&noisy, "seg-noisy"),
    );
    assert!(a.len() > 20, "{} frames", a.len());
    assert_eq!(a, again, "a logging run is deterministic");
    let moved: Vec<f64> = a
        .iter()
        .filter_map(|(k, p)| {
            b.get(k)
                .map(|q| f64::from(p[0] - q[0]).hypot(f64::from(p[1] - q[1])))
        })
        .collect();
    assert!(
        moved.len() * 2 > a.len(),
        "{} of {} frames in both",
        moved.len(),
        a.len()
    );
    let rms = (moved.iter().map(|m| m * m).sum::<f64>() / moved.len() as f64).sqrt();
    // σ grows from 18 to √(18² + 30²) ≈ 35 px per axis: the same draws scaled move a centre by
    // about 17 px per axis, independent draws by about 39.
    assert!(rms > 10.0 && rms < 80.0, "centres moved {rms:.1} px rms");
}
