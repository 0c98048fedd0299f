//! The acoustic pipeline at "pixel level": samples rendered by the room simulation → ILD
//! vectors (node-acoustic) → fingerprints → the grid estimator (node-head) → a position.

use super::super::*;
use super::room;
use node_acoustic::frames::frame_ilds;
use node_acoustic::ild::{IldAnalyzer, block_starts};
use node_acoustic::wav::StereoClip;
use node_head::grid::RandomWalk;
use node_head::grid::locate::{LocateParams, Locator};
use proto::acoustic::{Fingerprint, FingerprintDb, IldSettings};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;

/// Paper 001's real-room band (Table 2: 0–386 Hz): low frequencies bend round walls and vary
/// smoothly over the floor, so a survey lattice of a few decimetres can describe them.
fn settings() -> IldSettings {
    IldSettings {
        sample_rate: 8_000,
        block_len: 1024,
        f_min_hz: 20.0,
        f_max_hz: 386.0,
        frequencies: 40,
        epsilon: 1e-4,
    }
}

/// Survey the room on a 0.25 m lattice (one second per position), then locate a still source
/// over 10 s of half-second frames; the fix's error and σ.
fn survey_and_locate(world: &World, node: &TwoMicNode, truth: [f64; 2], seed: u64) -> (f64, f64) {
    let (spacing, seconds) = (0.25, 10);
    let params = AcousticParams::default();
    let s = settings();
    let rate = s.sample_rate as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut analyzer = IldAnalyzer::new(&s).unwrap();
    let mut fingerprints = Vec::new();
    let (nx, ny) = (
        ((world.max[0] - world.min[0]) / spacing) as usize,
        ((world.max[1] - world.min[1]) / spacing) as usize,
    );
    for j in 0..ny {
        for i in 0..nx {
            let p = [
                world.min[0] + spacing * (i as f64 + 0.5),
                world.min[1] + spacing * (j as f64 + 0.5),
            ];
            let (l, r) = render_stereo(world, &params, node, p, rate, s.sample_rate, &mut rng);
            for start in block_starts(l.len(), s.block_len) {
                analyzer
                    .accumulate(&l[start..start + s.block_len], &r[start..start + s.block_len])
                    .unwrap();
            }
            fingerprints.push(Fingerprint {
                position: p,
                values: analyzer.finish().unwrap().values,
            });
        }
    }
    let db = FingerprintDb::new(world, s.clone(), fingerprints).unwrap();
    let (left, right) = render_stereo(
        world,
        &params,
        node,
        truth,
        rate * seconds,
        s.sample_rate,
        &mut rng,
    );
    let clip = StereoClip {
        path: PathBuf::from("rendered"),
        sample_rate: s.sample_rate,
        left,
        right,
        clipped_samples: 0,
    };
    let (frames, counts) = frame_ilds(&clip, &s, 500.0).unwrap();
    assert_eq!(counts.good, 2 * seconds);
    let locate = LocateParams {
        motion: RandomWalk {
            sigma_per_sqrt_s: 0.05,
        },
        ..LocateParams::default()
    };
    let mut locator = Locator::new(world, db, &locate).unwrap();
    let mut fix = None;
    for f in &frames {
        fix = Some(locator.step(f.t, f.ild.as_ref()).unwrap());
    }
    let fix = fix.unwrap();
    let err = ((fix.x - truth[0]).powi(2) + (fix.y - truth[1]).powi(2)).sqrt();
    (err, fix.sigma_m)
}

/// In line of sight, 2.5 m from the node, between survey positions: within two 10 cm cells.
#[test]
fn rendered_audio_locates_a_source_in_line_of_sight() {
    let node = TwoMicNode::ears([0.1, 1.5, 1.2], 0.0, 0.2);
    let (err, sigma) = survey_and_locate(&room(""), &node, [2.6, 2.1], 1);
    assert!(err <= 0.2, "{err} m off (σ {sigma})");
    assert!(sigma < 0.5, "σ {sigma}");
}

/// Behind a wall the node cannot see past (no line of sight): still within two cells.
#[test]
fn rendered_audio_locates_a_source_behind_a_wall() {
    let world = room("{ from = [2.0, 0.0], to = [2.0, 1.6], height = 2.5 }");
    let node = TwoMicNode::ears([0.1, 1.5, 1.2], 0.0, 0.2);
    let truth = Vector3::new(3.1, 0.6, 1.2);
    assert!(world.occluded(&Vector3::new(0.1, 1.5, 1.2), &truth));
    let (err, sigma) = survey_and_locate(&world, &node, [truth.x, truth.y], 1);
    assert!(err <= 0.2, "{err} m off (σ {sigma})");
}
