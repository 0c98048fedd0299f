//! The deterministic simulation of the embedded default scenario (21 cameras, two heads, one
//! robot on a loop), at pixel level: every frame rendered and segmented. What a user of the
//! whole system sees: the robot keeps one global id, crosses the heads' border once in 20 s
//! with one handover, is tracked to a decimetre or so with all cameras on, and the proposed
//! three-mode activation keeps far fewer cameras on at a bounded loss of accuracy.

use node_server::analysis::Loaded;
use node_server::report::{self, Report};
use proto::ClusterTime;
use proto::scenario::{Activation, Scenario};
use sim::{Sim, SimOptions, WorldTruth};

const SEED: u64 = 1;
const DURATION_S: f64 = 20.0;
/// Three-mode's mean error may be at most this many times all-on's. Measured with these
/// options (pixel level, 20 s, `SimOptions::default()`), three-mode over all-on, seeds 1-5:
/// 0.405/0.114, 0.214/0.114, 0.362/0.115, 0.149/0.116, 0.441/0.117 m, i.e. 1.3-3.8 times
/// (seed 1: 3.6); paper 002 Table I has 33.5 cm against 28.6 cm. Before the activation cost
/// was an energy per step, three-mode kept 1.1-1.5 cameras and erred by 2.5-3.8 m.
const THREE_MODE_FACTOR: f64 = 5.0;

fn run(activation: Activation) -> Report {
    let mut scenario = Scenario::default_scenario();
    scenario.method.activation = activation;
    let opts = SimOptions {
        seed: SEED,
        duration_s: DURATION_S,
        ..SimOptions::default()
    };
    let outcome = Sim::new(scenario.clone(), opts)
        .expect("the default scenario simulates")
        .run();
    let truth = WorldTruth::new(&outcome.scenario, ClusterTime(0)).unwrap();
    let loaded = Loaded {
        scenario: outcome.scenario,
        records: outcome.records,
        skipped: Vec::new(),
    };
    report::compute(&loaded, Some(&truth))
}

fn globals_of_the_robot(r: &Report) -> usize {
    assert_eq!(r.targets.len(), 1, "one true target: {:?}", r.targets);
    r.targets[0].globals.len()
}

#[test]
fn the_default_scenario_is_tracked_with_one_id_and_three_mode_saves_cameras() {
    let all_on = run(Activation::AllOn);
    // Measured (same options), all-on, seeds 1-5: mean error 0.114-0.117 m, std
    // 0.054-0.056 m, 8.8 active cameras per step, 1 handover, 1 global id. The bound leaves
    // room for rendering or segmentation changes but not for a lost or duplicated track
    // (either costs metres on a few samples, pushing the mean well past it).
    let err_all = all_on.mean_error_m.expect("the scenario has ground truth");
    assert!(err_all < 0.2, "all-on mean error {err_all} m");
    assert_eq!(globals_of_the_robot(&all_on), 1, "{:?}", all_on.targets);
    assert_eq!(all_on.global_ids, 1);
    // The loop crosses x = 6 m once in the first 20 s (at 8.75 s).
    assert_eq!(all_on.handovers, 1);
    // Every node's runtime counts what it put on the wire; each camera sends something.
    let cameras: Vec<_> = all_on.bandwidth.iter().filter(|b| b.role == "camera").collect();
    assert_eq!(cameras.len(), 21, "{:?}", all_on.bandwidth);
    assert!(cameras.iter().all(|b| b.bytes_per_s > 0.0), "{cameras:?}");
    eprintln!("bandwidth (all-on): {:?}", all_on.bandwidth);

    let three = run(Activation::ThreeMode);
    let err_three = three.mean_error_m.expect("the scenario has ground truth");
    // Measured, three-mode, seeds 1-5: 2.6-3.8 active cameras per step (all-on 8.8), total
    // power 4.7-5.4 W (all-on 15.1 W with every node on). Its global ids are not asserted:
    // 1-3 over those seeds (see the crate's report of what remains).
    assert!(
        three.active_cameras_mean < 0.6 * all_on.active_cameras_mean,
        "three-mode {} cameras vs all-on {}",
        three.active_cameras_mean,
        all_on.active_cameras_mean
    );
    assert!(three.power_mw_mean < 0.6 * all_on.power_mw_mean);
    assert!(
        err_three < THREE_MODE_FACTOR * err_all,
        "three-mode {err_three} m vs all-on {err_all} m"
    );
}

/// A simulation's recording, written to disk and read back, replays through a fresh server to
/// the same decisions and the same track estimates as the run itself.
#[test]
fn replaying_a_sim_recording_gives_the_same_estimates() {
    use node_server::export::track_rows;
    use node_server::{ServerConfig, ServerNode};
    let scenario = Scenario::default_scenario();
    let opts = SimOptions {
        seed: 7,
        duration_s: 8.0,
        ..SimOptions::default()
    };
    let outcome = Sim::new(scenario.clone(), opts).expect("simulates").run();
    let path = std::env::temp_dir().join(format!("ocelli-sim-replay-{}.ocrec", std::process::id()));
    outcome.write_recording(&path).expect("recording");
    let loaded = node_server::analysis::load(&path, None).expect("reads back with its scenario");
    let _ = std::fs::remove_file(&path);
    // The file starts with the scenario and the run's origin (time 0, simulated world).
    assert!(matches!(loaded.records[1].record, node_server::Record::Origin(_)));
    assert_eq!(
        &loaded.records[2..],
        &outcome.records[..],
        "the file holds exactly the run's records"
    );
    let live = Loaded {
        scenario: scenario.clone(),
        records: outcome.records.clone(),
        skipped: Vec::new(),
    };
    let (a, b) = (track_rows(&live), track_rows(&loaded));
    assert!(a.len() > 10, "only {} track rows in 8 s", a.len());
    assert_eq!(a, b, "replayed estimates differ from the run's");
    let (_, stats) = ServerNode::restore(
        ServerConfig::from_scenario(scenario, proto::NodeId(1)),
        &outcome.records,
    );
    assert!(stats.decisions_matched > 0);
    assert_eq!(
        stats.decisions_mismatched, 0,
        "the replayed server decided differently"
    );
}
