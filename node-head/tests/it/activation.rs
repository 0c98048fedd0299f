//! Sensor activation through `HeadNode`: a higher energy weight keeps fewer cameras on.

use crate::sim::{ONE_TARGET, Radio, Sim, error, ring_scenario};

fn run(activation: &str, weight: f64, radio: bool) -> (f64, f64, f64, f64) {
    run_seed(activation, weight, radio, 31)
}

fn run_seed(activation: &str, weight: f64, radio: bool, seed: u64) -> (f64, f64, f64, f64) {
    let mut scenario = ring_scenario(8, "distributed-eif", activation, weight, ONE_TARGET);
    // With a radio, the paper's 18 px segmentation noise: beside 4 px cameras a reading weighed
    // by the errors it makes (`rssi_noise`) is worth less than its radio's power, and CameraOff
    // would never pay.
    if radio {
        scenario.method.pixel_sigma = 18.0;
    }
    let mut sim = Sim::new(&scenario, seed);
    if radio {
        sim.radio = Some(Radio {
            tx_dbm: -48.0,
            exponent: 2.6,
            multipath_db: 3.0,
            noise_db: 1.0,
        });
    }
    let (mut cams, mut power, mut err, mut n, mut off) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for k in 0..80 {
        let r = sim.step();
        if k >= 20 {
            let s = sim.head.last_step();
            cams += s.active_cameras as f64;
            off += s.camera_off as f64;
            power += s.power_mw;
            err += r.first().map_or(10.0, |r| error(&sim, r, 0));
            n += 1.0;
        }
    }
    assert!(sim.head.counters().commands > 0 || activation == "all-on");
    (cams / n, power / n, err / n, off / n)
}

#[test]
fn all_on_keeps_every_camera() {
    let (cams, power, err, _) = run("all-on", 0.0, false);
    assert_eq!(cams, 8.0);
    assert!((power - 8.0 * 719.0).abs() < 1e-6);
    assert!(err < 0.2, "{err}");
}

#[test]
fn higher_energy_weight_chooses_fewer_cameras() {
    // Weights in nats per mJ; a step is 0.2 s, so 5e-4 prices a camera node at 0.07 nats a step.
    let (cheap, p_cheap, e_cheap, _) = run("camera-entropy", 5e-4, false);
    let (dear, p_dear, e_dear, _) = run("camera-entropy", 5e-3, false);
    assert!(dear < cheap, "active cameras {dear} (dear) vs {cheap} (cheap)");
    assert!(p_dear < p_cheap);
    assert!(dear >= 1.0, "tracking needs a camera: {dear}");
    assert!(e_cheap < 0.3 && e_dear < 0.6, "errors {e_cheap} {e_dear}");
}

/// Over ten seeds: one seed's run is too short to compare two powers within 5% (seed 31
/// alone: three-mode 537 vs full-node 485 mW; over seeds 31–40: 504 vs 511).
#[test]
fn three_mode_uses_camera_off_nodes_within_full_nodes_power() {
    let seeds = 31u64..41;
    let n = (seeds.end - seeds.start) as f64;
    let (mut p_full, mut p_three, mut cams, mut err, mut off) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for seed in seeds {
        let full = run_seed("full-node", 5e-3, true, seed).1;
        let (c, p, e, o) = run_seed("three-mode", 5e-3, true, seed);
        // No seed far off: the average must not hide one run going wrong.
        assert!(
            p <= full * 1.15,
            "seed {seed}: three-mode {p} mW vs full-node {full} mW"
        );
        p_full += full / n;
        (p_three, cams, err, off) = (p_three + p / n, cams + c / n, err + e / n, off + o / n);
    }
    assert!(cams < 8.0);
    assert!(off > 0.0, "no node was ever left in CameraOff");
    assert!(
        p_three <= p_full * 1.05,
        "three-mode {p_three} mW vs full-node {p_full} mW"
    );
    assert!(err < 0.6, "{err}");
}
