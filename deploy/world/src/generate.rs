//! `ocelli scenario generate`: a hall-like scenario from a few numbers — cameras on the walls
//! and on a grid of posts aimed to cover the floor, heads whose regions tile the hall (each
//! camera in the cluster of the region it looks at), people walking loops that cross the hall
//! and its clusters, some of them tagged. The text is a scenario file; [`generate`] parses and
//! checks it as `ocelli scenario check` does.

use proto::scenario::{CameraTracker, Scenario, ScenarioError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HallSpec {
    pub cameras: u32,
    pub heads: u32,
    pub people: u32,
    /// Floor size, metres (x, y).
    pub size: [f64; 2],
    /// Every `tag_every`-th person carries a tag (0: nobody).
    pub tag_every: u32,
    pub seed: u64,
    /// What the cameras make of their frames.
    pub camera_tracker: CameraTracker,
}

impl Default for HallSpec {
    fn default() -> Self {
        HallSpec {
            cameras: 100,
            heads: 5,
            people: 10,
            size: [30.0, 20.0],
            tag_every: 3,
            seed: 1,
            // Measured in docs/multi-target-hall.md: in the hall's crowds paper 004's particle
            // cameras cover more of everyone, with a better MOTA and IDF1, than segmentation
            // (though with more global ids).
            camera_tracker: CameraTracker::Particle,
        }
    }
}

/// Camera mounting height, metres.
pub const MOUNT_Z: f64 = 2.8;
/// How far into the hall a wall camera looks, metres.
const WALL_AIM_M: f64 = 4.5;
/// How far from its post a post camera looks (a steep view), metres.
const POST_AIM_M: f64 = 2.5;

/// Least distance, metres, between two people's waypoints in the same slot of their loops, in a
/// hall wide enough for its people ([`apart`]).
/// People start their loops at the same end of the hall at once; two whose first waypoints
/// were drawn a few centimetres apart started inside each other and, at like speeds, walked
/// most of the loop side by side (the first hall's people 9 and 10: 6 cm apart at the start,
/// and 9 the least covered person in every run).
pub const WAYPOINTS_APART_M: f64 = 1.0;

/// Seed offset of the waypoint re-draws' stream.
const REDRAW_STREAM: u64 = 0x5eed_a9a7;

/// `v`, or when it lies within [`WAYPOINTS_APART_M`] of one of `taken`, a re-draw in `range`
/// that does not (the farthest of 64 tries if none is clear: a hall too narrow for its
/// people).
fn apart(v: f64, taken: &[f64], range: std::ops::Range<f64>, rng: &mut ChaCha8Rng) -> f64 {
    let clearance = |v: f64| taken.iter().map(|t| (t - v).abs()).fold(f64::INFINITY, f64::min);
    if clearance(v) >= WAYPOINTS_APART_M {
        return v;
    }
    let mut best = v;
    for _ in 0..64 {
        let c = rng.random_range(range.clone());
        if clearance(c) >= WAYPOINTS_APART_M {
            return c;
        }
        if clearance(c) > clearance(best) {
            best = c;
        }
    }
    best
}

/// A particle hall's `[method.particle]`: its cameras' people are fused by the heads, so a
/// filter no region supports stays home (measured in docs/multi-target.md, "On main since stop
/// 38"). Its people do not stop, so it holds no one in the foreground (`hold-still-s`: it cost
/// the hall identity, "… stop 40").
const PARTICLE_SECTION: &str = "
[method.particle]
# Only the filters a region supports this frame leave the camera: an unsupported filter's box
# mostly stands where nobody is, and the heads predict the hidden ones themselves.
report-unsupported = false
";

/// A particle hall's planner weight and motion model, tuned on the 100-camera hall
/// (docs/multi-target-hall.md, stop 47). A segmenting hall keeps paper 002's room values: with
/// these its false positives rose by a third and its MOTA fell (same document).
const PARTICLE_ENERGY_WEIGHT: &str = "\
# A hall is watched for everyone in it, so a camera's power weighs less than in paper 002's
# room (0.001): measured on the 100-camera hall (docs/multi-target-hall.md, stop 47), people
# are covered more of the time for a few per cent more power.
energy-weight = 0.0001
";
const PARTICLE_MOTION: &str = "\
# People crossing a hall keep their pace between turns. Measured on the 100-camera hall, a
# smaller acceleration density than the robot room's 0.25 covers people more of the time with
# fewer global ids, for some more false positives (docs/multi-target-hall.md, stop 47).
motion = { accel-psd = [0.05, 0.05, 0.01] }
";
const ROOM_ENERGY_WEIGHT: &str = "energy-weight = 0.001\n";
const ROOM_MOTION: &str = "motion = { accel-psd = [0.25, 0.25, 0.01] }\n";

/// The scenario's TOML text.
pub fn generate_toml(spec: &HallSpec) -> String {
    let [w, d] = spec.size;
    let heads = spec.heads.max(1);
    // What the camera tracker decides: its own section, and the planner weight and motion
    // model measured with it.
    let (particle, energy_weight, motion) = match spec.camera_tracker {
        CameraTracker::Segmentation => ("", ROOM_ENERGY_WEIGHT, ROOM_MOTION),
        CameraTracker::Particle => (PARTICLE_SECTION, PARTICLE_ENERGY_WEIGHT, PARTICLE_MOTION),
    };
    let mut t = String::new();
    let _ = write!(
        t,
        r#"name = "hall-{cams}c-{heads}h-{people}p"
description = "Generated hall ({w} x {d} m): {cams} cameras on the walls and posts, {heads} heads tiling the floor, {people} people (ocelli scenario generate --seed {seed})"

[world]
min = [0.0, 0.0, 0.0]
max = [{w}, {d}, 3.0]

[network]
transport = "ipc"
domain = "ocelli-hall"
heartbeat-ms = 200
liveness-timeout-ms = 1000
sync-beacon-ms = 1000
queue-len = 256

[method]
fusion = "distributed-eif"
activation = "three-mode"
segmentation = "adaptive-background"
camera-tracker = "{tracker}"
step-ms = 200
deadline-ms = 80
pixel-sigma = 18.0
rssi-window = 20
rssi-epsilon = 0.001
{energy_weight}previous-point = false
# A camera that is on but delivered nothing last step (a person it was woken for walked out
# of its view, or another track took the detection) is not counted as watching: the planner
# wakes another (measured in docs/multi-target.md).
drop-lost-cameras = true
track-timeout-ms = 3000
gate-chi2 = 13.8
{motion}rssi-default = {{ kind = "log-distance", a = -22.0, b = -45.0, variance = 16.0 }}
{particle}
[power]
camera-mw = 650.0
node-active-mw = 69.0
node-low-power-mw = 7.2

[[nodes]]
id = 1
role = "server"
rssi = false
"#,
        cams = spec.cameras,
        people = spec.people,
        seed = spec.seed,
        tracker = match spec.camera_tracker {
            CameraTracker::Segmentation => "segmentation",
            CameraTracker::Particle => "particle",
        },
    );
    // Heads: the floor cut into `heads` strips along its longer side.
    let along_x = w >= d;
    let strip = if along_x { w } else { d } / f64::from(heads);
    let region = |k: u32| {
        let (a, b) = (f64::from(k) * strip, f64::from(k + 1) * strip);
        if along_x { [a, 0.0, b, d] } else { [0.0, a, w, b] }
    };
    let head_of = |x: f64, y: f64| {
        let v = if along_x { x } else { y };
        2 + ((v / strip).floor().max(0.0) as u32).min(heads - 1)
    };
    for k in 0..heads {
        let r = region(k);
        let _ = write!(
            t,
            "\n[[nodes]]\nid = {}\nrole = \"head\"\nregion = [{:.2}, {:.2}, {:.2}, {:.2}]\n",
            2 + k,
            r[0],
            r[1],
            r[2],
            r[3]
        );
    }
    for (k, (pos, aim)) in camera_poses(spec).into_iter().enumerate() {
        let _ = write!(
            t,
            r#"
[[nodes]]
id = {id}
role = "camera"
head = {head}
camera.intrinsics = {{ fx = 320.0, fy = 320.0, cx = 176.0, cy = 144.0, width = 352, height = 288 }}
camera.pose = {{ position = [{px:.2}, {py:.2}, {pz:.2}], look-at = [{ax:.2}, {ay:.2}, 0.0] }}
camera.fps = 5.0
"#,
            id = 100 + k,
            head = head_of(aim[0], aim[1]),
            px = pos[0],
            py = pos[1],
            pz = pos[2],
            ax = aim[0],
            ay = aim[1],
        );
    }
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    // Re-draws of a waypoint too near another person's come from their own stream, so that a
    // conflict changes that waypoint alone and not everything drawn after it.
    let mut redraw = ChaCha8Rng::seed_from_u64(spec.seed ^ REDRAW_STREAM);
    // Per waypoint slot, the across-the-hall coordinates people drawn so far have there.
    let mut taken: [Vec<f64>; 4] = Default::default();
    for p in 0..spec.people {
        // A loop from one end of the hall to the other and back by another way: it crosses
        // every cluster.
        let m = 1.0;
        let across = if along_x { d } else { w };
        let range = m..(across - m).max(m + 0.1);
        let mut draw = |slot: usize, rng: &mut ChaCha8Rng| {
            let v = apart(
                rng.random_range(range.clone()),
                &taken[slot],
                range.clone(),
                &mut redraw,
            );
            taken[slot].push(v);
            v
        };
        let pts: Vec<[f64; 2]> = if along_x {
            vec![
                [m, draw(0, &mut rng)],
                [w / 2.0, draw(1, &mut rng)],
                [w - m, draw(2, &mut rng)],
                [w / 2.0, draw(3, &mut rng)],
            ]
        } else {
            vec![
                [draw(0, &mut rng), m],
                [draw(1, &mut rng), d / 2.0],
                [draw(2, &mut rng), d - m],
                [draw(3, &mut rng), d / 2.0],
            ]
        };
        let speed = rng.random_range(0.6..1.3);
        let colour: [u8; 3] = [rng.random(), rng.random(), rng.random()];
        let tagged = spec.tag_every > 0 && p % spec.tag_every == 0;
        let wp: Vec<String> = pts
            .iter()
            .map(|q| format!("[{:.2}, {:.2}]", q[0], q[1]))
            .collect();
        let _ = write!(
            t,
            r#"
[[targets]]
id = {id}
size = [0.45, 0.3, 1.7]
colour = [{r}, {g}, {b}]
rssi-tag = {tagged}
trajectory = {{ kind = "loop", speed = {speed:.2}, waypoints = [{wp}] }}
"#,
            id = p + 1,
            r = colour[0],
            g = colour[1],
            b = colour[2],
            wp = wp.join(", "),
        );
    }
    t
}

/// Where each camera sits and the floor point it looks at: a third of them along the walls,
/// evenly spaced round the perimeter and aimed [`WALL_AIM_M`] into the hall, the rest on a grid
/// of posts, each aimed [`POST_AIM_M`] from its post in turn north, east, south and west.
pub fn camera_poses(spec: &HallSpec) -> Vec<([f64; 3], [f64; 2])> {
    let [w, d] = spec.size;
    let n = spec.cameras as usize;
    let walls = n / 3;
    let posts = n - walls;
    let mut out = Vec::with_capacity(n);
    let perimeter = 2.0 * (w + d);
    for k in 0..walls {
        let s = (k as f64 + 0.5) * perimeter / walls as f64;
        let (p, inward) = if s < w {
            ([s, 0.0], [0.0, 1.0])
        } else if s < w + d {
            ([w, s - w], [-1.0, 0.0])
        } else if s < 2.0 * w + d {
            ([w - (s - w - d), d], [0.0, -1.0])
        } else {
            ([0.0, d - (s - 2.0 * w - d)], [1.0, 0.0])
        };
        let aim = [p[0] + inward[0] * WALL_AIM_M, p[1] + inward[1] * WALL_AIM_M];
        out.push(([p[0], p[1], MOUNT_Z], aim));
    }
    // Posts: a grid with cells as square as the hall allows.
    let cols = ((posts as f64 * w / d).sqrt().round() as usize).clamp(1, posts.max(1));
    let rows = posts.div_ceil(cols).max(1);
    let dirs = [[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [-1.0, 0.0]];
    for k in 0..posts {
        let (i, j) = (k % cols, k / cols);
        let p = [
            (i as f64 + 0.5) * w / cols as f64,
            (j as f64 + 0.5) * d / rows as f64,
        ];
        let dir = dirs[(i + j) % 4];
        let aim = [p[0] + dir[0] * POST_AIM_M, p[1] + dir[1] * POST_AIM_M];
        out.push(([p[0], p[1], MOUNT_Z], aim));
    }
    out
}

/// The generated scenario, parsed and checked (the simulated world's targets too).
///
/// # Errors
/// The numbers give a scenario that does not validate (no camera, a zero size, …).
pub fn generate(spec: &HallSpec) -> Result<(Scenario, String), ScenarioError> {
    let text = generate_toml(spec);
    let s = Scenario::from_toml(&text, "generated hall")?;
    crate::targets(&s)?;
    Ok((s, text))
}

/// Fraction of a grid of floor points (every `step` metres, at height `z`) that at least
/// `k` cameras of `s` see in their image.
pub fn coverage(s: &Scenario, step: f64, z: f64, k: usize) -> f64 {
    let cams: Vec<_> = s.cameras().filter_map(|c| s.camera_model(c.id).ok()).collect();
    let (lo, hi) = (s.world.min, s.world.max);
    let (mut seen, mut all) = (0usize, 0usize);
    let mut x = lo[0] + step / 2.0;
    while x < hi[0] {
        let mut y = lo[1] + step / 2.0;
        while y < hi[1] {
            let p = nalgebra::Vector3::new(x, y, z);
            let n = cams
                .iter()
                .filter(|c| {
                    c.project(&p).is_some_and(|px| {
                        let i = &c.intrinsics;
                        px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(i.width) && px.y < f64::from(i.height)
                    })
                })
                .count();
            seen += usize::from(n >= k);
            all += 1;
            y += step;
        }
        x += step;
    }
    if all == 0 { 0.0 } else { seen as f64 / all as f64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_generated_hall_validates_and_every_floor_point_is_seen_twice() {
        let spec = HallSpec::default();
        let (s, _) = generate(&spec).unwrap();
        assert_eq!(s.cameras().count(), 100);
        assert_eq!(s.heads().count(), 5);
        assert_eq!(crate::targets(&s).unwrap().len(), 10);
        let c = coverage(&s, 0.5, 0.0, 2);
        assert!(c >= 1.0, "floor seen by two cameras: {:.1}%", 100.0 * c);
        // Every head has cameras; the same seed gives the same file.
        for (h, members) in s.clusters() {
            assert!(!members.is_empty(), "head {h} has no camera");
        }
        assert_eq!(generate_toml(&spec), generate_toml(&spec));
    }

    #[test]
    fn no_two_people_share_a_waypoint() {
        for seed in 1..=12 {
            no_two_people_share_a_waypoint_with(seed);
        }
    }

    fn no_two_people_share_a_waypoint_with(seed: u64) {
        let (s, _) = generate(&HallSpec {
            seed,
            ..HallSpec::default()
        })
        .unwrap();
        let loops: Vec<Vec<[f64; 2]>> = crate::targets(&s)
            .unwrap()
            .into_iter()
            .map(|t| match t.trajectory {
                crate::Trajectory::Loop { waypoints, .. } => waypoints,
                other => panic!("a generated person walks a loop: {other:?}"),
            })
            .collect();
        for (i, a) in loops.iter().enumerate() {
            for b in &loops[i + 1..] {
                for (p, q) in a.iter().zip(b) {
                    let gap = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
                    assert!(
                        gap >= WAYPOINTS_APART_M - 0.01,
                        "seed {seed}: {p:?} and {q:?}: {gap:.2} m"
                    );
                }
            }
        }
    }

    #[test]
    fn the_cameras_track_as_the_spec_says() {
        for tracker in [CameraTracker::Particle, CameraTracker::Segmentation] {
            let spec = HallSpec {
                cameras: 12,
                heads: 2,
                people: 3,
                camera_tracker: tracker,
                ..HallSpec::default()
            };
            let (s, _) = generate(&spec).unwrap();
            assert_eq!(s.method.camera_tracker, tracker);
            // The planner weight and motion model tuned on particle halls; a segmenting hall
            // keeps paper 002's room values.
            let (energy_weight, psd) = match tracker {
                CameraTracker::Particle => (1e-4, 0.05),
                CameraTracker::Segmentation => (1e-3, 0.25),
            };
            assert_eq!(s.method.energy_weight, energy_weight);
            assert_eq!(s.method.motion.accel_psd, [psd, psd, 0.01]);
        }
        assert_eq!(HallSpec::default().camera_tracker, CameraTracker::Particle);
    }
}
