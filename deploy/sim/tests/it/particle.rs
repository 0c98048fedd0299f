//! Paper 004's camera end to end: the default scenario with `camera-tracker = "particle"`, at
//! pixel level (every frame rendered, segmented and tracked by the per-person colour particle
//! filters), people sent as ground-plane observations and fused by the heads, in both the
//! distributed and the centralized EIF. The robot is tracked and every camera puts bytes on
//! the wire.

use node_server::analysis::Loaded;
use node_server::report::{self, Report};
use proto::ClusterTime;
use proto::scenario::{CameraTracker, Fusion, Scenario};
use sim::{Sim, SimOptions, WorldTruth};

const DURATION_S: f64 = 12.0;
/// Measured with these options (pixel level, 12 s, seed 1, all cameras on): mean error 0.464 m
/// (std 0.135, one global id) distributed, 0.441 m (std 0.342, two global ids) centralized;
/// segmentation with pin-hole points errs about 0.11 m on the same scenario. The particle
/// filters' mean box trails the moving robot and its lower edge is the robot's near side:
/// the floor positions lag by a few decimetres. The bound catches a lost or wandering track.
const BOUND_M: f64 = 0.6;

fn run(fusion: Fusion) -> Report {
    let mut scenario = Scenario::default_scenario();
    scenario.method.camera_tracker = CameraTracker::Particle;
    scenario.method.fusion = fusion;
    scenario.method.activation = proto::scenario::Activation::AllOn;
    let opts = SimOptions {
        seed: 1,
        duration_s: DURATION_S,
        ..SimOptions::default()
    };
    let outcome = Sim::new(scenario, opts).expect("the scenario simulates").run();
    let truth = WorldTruth::new(&outcome.scenario, ClusterTime(0)).unwrap();
    let loaded = Loaded {
        scenario: outcome.scenario,
        records: outcome.records,
        skipped: Vec::new(),
    };
    report::compute(&loaded, Some(&truth))
}

fn check(r: &Report, bound_m: f64) {
    let err = r.mean_error_m.expect("the scenario has ground truth");
    let cameras: Vec<_> = r.bandwidth.iter().filter(|b| b.role == "camera").collect();
    let mean_bps = cameras.iter().map(|b| b.bytes_per_s).sum::<f64>() / cameras.len().max(1) as f64;
    eprintln!(
        "particle: mean error {err:.3} m, {} global ids, camera bytes/s mean {mean_bps:.0}, targets {:?}",
        r.global_ids, r.targets
    );
    assert!(err < bound_m, "mean error {err} m");
    assert_eq!(cameras.len(), 21, "{:?}", r.bandwidth);
    assert!(cameras.iter().all(|b| b.bytes_per_s > 0.0), "{cameras:?}");
}

#[test]
fn particle_cameras_track_the_robot_on_the_ground_plane_distributed() {
    check(&run(Fusion::DistributedEif), BOUND_M);
}

#[test]
fn particle_cameras_track_the_robot_on_the_ground_plane_centralized() {
    check(&run(Fusion::CentralizedEif), BOUND_M);
}
