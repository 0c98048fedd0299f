use super::*;
use approx::assert_abs_diff_eq;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn room(walls: &str) -> World {
    toml::from_str(&format!(
        "min = [0.0, 0.0, 0.0]\nmax = [4.0, 3.0, 3.0]\nwalls = [{walls}]"
    ))
    .unwrap()
}

fn omni(x: f64, y: f64) -> Microphone {
    Microphone {
        position: [x, y, 1.2],
        facing: [1.0, 0.0],
        directivity: 0.0,
    }
}

const DRY: AcousticParams = AcousticParams {
    speed_of_sound: 343.0,
    reflection: 0.0,
    transmission_db: 30.0,
    source_rms: 0.05,
    noise_rms: 0.0,
    source_height_m: 1.2,
    floor: false,
};

#[test]
fn knife_edge_loss_hand_values() {
    assert_eq!(knife_edge_loss_db(-1.0), 0.0);
    // J(0) = 6.9 + 20 log10(√1.01 − 0.1) = 6.03 dB (grazing).
    assert_abs_diff_eq!(knife_edge_loss_db(0.0), 6.0328, epsilon = 1e-3);
    // J(1) = 6.9 + 20 log10(√1.81 + 0.9) = 13.926 dB.
    assert_abs_diff_eq!(knife_edge_loss_db(1.0), 13.9257, epsilon = 1e-3);
}

/// In a dry room the only path is the direct one: gain 1/d, delay d/c.
#[test]
fn direct_path_spreads_and_delays() {
    let mic = omni(3.0, 1.0);
    let paths = sound_paths(&room(""), &DRY, [1.0, 1.0], &mic);
    let direct: Vec<_> = paths.iter().filter(|p| p.gain > 0.0).collect();
    assert_eq!(direct.len(), 1);
    assert_abs_diff_eq!(direct[0].length, 2.0, epsilon = 1e-12);
    let h = transfer(&paths, &DRY, 1000.0);
    assert_abs_diff_eq!(h.norm(), 0.5, epsilon = 1e-12);
    let phase = -std::f64::consts::TAU * 1000.0 * 2.0 / 343.0;
    assert_abs_diff_eq!(
        (h.arg() - phase).rem_euclid(std::f64::consts::TAU),
        0.0,
        epsilon = 1e-9
    );
}

/// The image source off the room's side y = 0: source (1, 1), microphone (3, 1), both 1.2 m
/// up: the reflected path is √(2² + 2²) long with gain ρ / length.
#[test]
fn first_order_reflection_by_image_source() {
    let params = AcousticParams {
        reflection: 0.6,
        ..DRY
    };
    let paths = sound_paths(&room(""), &params, [1.0, 1.0], &omni(3.0, 1.0));
    let want = 8f64.sqrt();
    let hit = paths
        .iter()
        .find(|p| (p.length - want).abs() < 1e-9)
        .expect("a reflection off y = 0");
    assert_abs_diff_eq!(hit.gain, 0.6 / want, epsilon = 1e-12);
    // Direct + 4 sides; with the floor, 6.
    assert_eq!(paths.len(), 5);
    let floor = AcousticParams {
        floor: true,
        ..params
    };
    let paths = sound_paths(&room(""), &floor, [1.0, 1.0], &omni(3.0, 1.0));
    let down = (4.0f64 + 2.4 * 2.4).sqrt();
    assert!(paths.iter().any(|p| (p.length - down).abs() < 1e-9));
}

/// A wall from the room's side between source and microphone: the direct path is attenuated
/// by the transmission loss, a diffracted path goes round the free end, and the diffracted
/// sound is weaker at high frequencies than at low.
#[test]
fn a_wall_blocks_transmits_and_diffracts_low_frequencies_best() {
    let world = room("{ from = [2.0, 0.0], to = [2.0, 2.0], height = 3.0 }");
    let mic = omni(3.0, 1.0);
    let paths = sound_paths(&world, &DRY, [1.0, 1.0], &mic);
    assert_abs_diff_eq!(paths[0].gain, 10f64.powf(-1.5) / 2.0, epsilon = 1e-12);
    let round: Vec<_> = paths.iter().filter(|p| p.diffraction_excess.is_some()).collect();
    assert_eq!(round.len(), 1, "{paths:?}");
    // Via (2, 2.001): √(1 + 1.001²) twice.
    let via = 2.0 * (1.0f64 + 1.001 * 1.001).sqrt();
    assert_abs_diff_eq!(round[0].length, via, epsilon = 1e-9);
    let power = |lo: f64, hi: f64| -> f64 {
        let n = 50;
        (0..n)
            .map(|k| transfer(&paths, &DRY, lo + (hi - lo) * k as f64 / n as f64).norm_sqr())
            .sum::<f64>()
            / n as f64
    };
    assert!(power(100.0, 300.0) > 3.0 * power(3000.0, 5000.0));
    // With no wall the same microphone hears 1/d at every frequency.
    assert_abs_diff_eq!(
        transfer(&sound_paths(&room(""), &DRY, [1.0, 1.0], &mic), &DRY, 3000.0).norm(),
        0.5,
        epsilon = 1e-12
    );
}

/// Rendered channels carry the level difference of their distances (dry room, omni), and the
/// same seed renders the same samples.
#[test]
fn rendered_levels_follow_distance_and_are_deterministic() {
    let world = room("");
    let node = TwoMicNode {
        left: omni(1.0, 1.0),
        right: omni(3.0, 1.0),
    };
    let render = |seed| {
        render_stereo(
            &world,
            &DRY,
            &node,
            [1.5, 1.0],
            16_000,
            16_000,
            &mut ChaCha8Rng::seed_from_u64(seed),
        )
    };
    let (l, r) = render(3);
    let rms = |x: &[f32]| (x.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
    // 0.5 m and 1.5 m: a factor of 3, and the left RMS is the source's at 0.5 m.
    assert_abs_diff_eq!(rms(&l) / rms(&r), 3.0, epsilon = 1e-3);
    assert_abs_diff_eq!(rms(&l), 0.05 / 0.5, epsilon = 0.004);
    assert_eq!(render(3), (l, r));
    assert_ne!(render(4).0, render(3).0);
}

mod pipeline;
