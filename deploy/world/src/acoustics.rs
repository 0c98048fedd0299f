//! The simulated room acoustics: both channels of a two-microphone node, rendered from a
//! sound source (a target emitting white noise, as in paper 001 §3.3) at a floor position, so
//! the acoustic pipeline runs from samples like the cameras run from pixels.
//!
//! Sound reaches each microphone along these paths, each a delay d/c and a gain:
//! - the direct path, 1/d spherical spreading;
//! - first-order reflections by image sources: off each interior wall (either face, when
//!   source and microphone are on that side and the reflection point is on the wall below its
//!   top), the room's four sides and the floor, each scaled by the reflection coefficient;
//! - where a wall blocks a path's leg: transmission through it (`transmission_db` per wall),
//!   and for the direct path diffraction around the blocking wall's two ends and over its top
//!   (when lower than the room), each a single knife edge with ITU-R P.526's approximation
//!   J(ν) = 6.9 + 20 log10(√((ν − 0.1)² + 1) + ν − 0.1) dB, ν = 2 √(Δ/λ) from the excess path
//!   length Δ — so diffraction is frequency dependent (low frequencies bend round a wall more);
//! - each microphone's directivity, (1 − β) + β cos θ between its facing and the arrival.
//!
//! Rendering is in the frequency domain: the source's white noise (seeded) is transformed,
//! multiplied per microphone by Σ_paths gain(f) e^{−j2πfτ}, transformed back, and sensor noise
//! is added. The block is circular (a periodic noise source), which for white noise is as
//! good as a linear convolution. Pure in (world, node, source, parameters, RNG).

use nalgebra::{Vector2, Vector3};
use proto::scenario::{Wall, World};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;

/// How sound behaves in the simulated room.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcousticParams {
    /// Speed of sound, m/s.
    pub speed_of_sound: f64,
    /// Amplitude reflection coefficient of walls, the room's sides and the floor.
    pub reflection: f64,
    /// Loss through one wall, dB.
    pub transmission_db: f64,
    /// RMS of the source's white noise at 1 m, of full scale.
    pub source_rms: f64,
    /// RMS of each microphone's own noise, of full scale.
    pub noise_rms: f64,
    /// Height of the source (a person's mouth or a speaker), m.
    pub source_height_m: f64,
    /// Whether the floor reflects.
    pub floor: bool,
}

impl Default for AcousticParams {
    fn default() -> Self {
        AcousticParams {
            speed_of_sound: 343.0,
            reflection: 0.6,
            transmission_db: 30.0,
            source_rms: 0.05,
            noise_rms: 2e-4,
            source_height_m: 1.2,
            floor: true,
        }
    }
}

/// One microphone: where it is, which way it faces in the plane, and how directional it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microphone {
    pub position: [f64; 3],
    /// Facing direction in the plane (need not be unit length).
    pub facing: [f64; 2],
    /// β: 0 omnidirectional, 0.5 sub-cardioid, 1 cardioid.
    pub directivity: f64,
}

/// A two-microphone acoustic node (left, right).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoMicNode {
    pub left: Microphone,
    pub right: Microphone,
}

impl TwoMicNode {
    /// A head-like pair at `centre`: microphones `spacing` m apart across `facing`, each
    /// turned 60° outward, sub-cardioid (β = 0.5).
    pub fn ears(centre: [f64; 3], facing_rad: f64, spacing: f64) -> TwoMicNode {
        let ear = |side: f64| {
            let across = facing_rad + side * std::f64::consts::FRAC_PI_2;
            let turn = facing_rad + side * std::f64::consts::FRAC_PI_3;
            Microphone {
                position: [
                    centre[0] + 0.5 * spacing * across.cos(),
                    centre[1] + 0.5 * spacing * across.sin(),
                    centre[2],
                ],
                facing: [turn.cos(), turn.sin()],
                directivity: 0.5,
            }
        };
        TwoMicNode {
            left: ear(1.0),
            right: ear(-1.0),
        }
    }
}

impl TwoMicNode {
    /// The scenario's acoustic node: its two microphones where the spec puts them, each
    /// turned 60° outward from the pair's facing (left to the left), with its directivity.
    pub fn from_spec(spec: &proto::scenario::AcousticSpec) -> TwoMicNode {
        let mic = |position: [f64; 3], turn: f64| {
            let a = spec.facing_rad + turn;
            Microphone {
                position,
                facing: [a.cos(), a.sin()],
                directivity: spec.directivity,
            }
        };
        TwoMicNode {
            left: mic(spec.left, std::f64::consts::FRAC_PI_3),
            right: mic(spec.right, -std::f64::consts::FRAC_PI_3),
        }
    }
}

/// One propagation path to a microphone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoundPath {
    /// Total length, m (the delay is length / c).
    pub length: f64,
    /// Frequency-independent gain: spreading, reflections, transmission, directivity.
    pub gain: f64,
    /// Excess length over the blocked straight line for a diffracted path (knife-edge loss
    /// applies per frequency); `None` otherwise.
    pub diffraction_excess: Option<f64>,
}

/// ITU-R P.526 single knife-edge loss J(ν), dB (0 for ν ≤ −0.78).
pub fn knife_edge_loss_db(nu: f64) -> f64 {
    if nu <= -0.78 {
        return 0.0;
    }
    6.9 + 20.0 * (((nu - 0.1).powi(2) + 1.0).sqrt() + nu - 0.1).log10()
}

/// The walls of the room's outline as reflectors (full height).
fn outline(world: &World) -> [Wall; 4] {
    let (x0, y0, x1, y1) = (world.min[0], world.min[1], world.max[0], world.max[1]);
    let h = world.max[2].max(0.0) + 100.0;
    let wall = |from: [f64; 2], to: [f64; 2]| Wall {
        from,
        to,
        height: h,
        attenuation_db: 0.0,
    };
    [
        wall([x0, y0], [x1, y0]),
        wall([x1, y0], [x1, y1]),
        wall([x1, y1], [x0, y1]),
        wall([x0, y1], [x0, y0]),
    ]
}

/// Walls (other than `skip`) crossed by the leg `a → b`.
fn walls_crossed(world: &World, a: &Vector3<f64>, b: &Vector3<f64>, skip: Option<usize>) -> usize {
    world
        .walls
        .iter()
        .enumerate()
        .filter(|(k, w)| Some(*k) != skip && w.crosses(a, b))
        .count()
}

fn inside(world: &World, p: &Vector3<f64>) -> bool {
    (0..3).all(|a| p[a] >= world.min[a] - 1e-9 && p[a] <= world.max[a] + 1e-9)
}

/// Mirror of `p` across the infinite line through `a`, `b` (in the plane; z kept).
fn mirror(p: &Vector3<f64>, a: [f64; 2], b: [f64; 2]) -> Vector3<f64> {
    let (a, d) = (
        Vector2::new(a[0], a[1]),
        Vector2::new(b[0] - a[0], b[1] - a[1]).normalize(),
    );
    let q = Vector2::new(p.x, p.y) - a;
    let r = a + d * (2.0 * q.dot(&d)) - q;
    Vector3::new(r.x, r.y, p.z)
}

/// Where segment `p → q` crosses the wall's line, as (fraction along p→q, fraction along the
/// wall), if the lines are not parallel.
fn crossing(p: &Vector3<f64>, q: &Vector3<f64>, w: &Wall) -> Option<(f64, f64)> {
    let (ex, ey) = (w.to[0] - w.from[0], w.to[1] - w.from[1]);
    let (dx, dy) = (q.x - p.x, q.y - p.y);
    let denom = dx * ey - dy * ex;
    if denom.abs() < 1e-12 {
        return None;
    }
    let (apx, apy) = (w.from[0] - p.x, w.from[1] - p.y);
    Some(((apx * ey - apy * ex) / denom, (apx * dy - apy * dx) / denom))
}

impl Microphone {
    fn directivity_gain(&self, from: &Vector3<f64>) -> f64 {
        let arrival = Vector2::new(from.x - self.position[0], from.y - self.position[1]);
        let facing = Vector2::new(self.facing[0], self.facing[1]);
        let cos = match (arrival.try_normalize(1e-12), facing.try_normalize(1e-12)) {
            (Some(a), Some(f)) => a.dot(&f),
            _ => 1.0,
        };
        (1.0 - self.directivity) + self.directivity * cos
    }
}

/// Every path from a source at `source` (floor x, y; height from `params`) to `mic`.
pub fn sound_paths(
    world: &World,
    params: &AcousticParams,
    source: [f64; 2],
    mic: &Microphone,
) -> Vec<SoundPath> {
    let s = Vector3::new(source[0], source[1], params.source_height_m);
    let m = Vector3::from(mic.position);
    let through = |walls: usize| 10f64.powf(-params.transmission_db * walls as f64 / 20.0);
    let mut paths = Vec::new();
    // Direct, possibly through walls.
    let d = (m - s).norm().max(0.1);
    let blocked = walls_crossed(world, &s, &m, None);
    paths.push(SoundPath {
        length: d,
        gain: through(blocked) / d * mic.directivity_gain(&s),
        diffraction_excess: None,
    });
    // Diffraction round the ends and over the top of each wall blocking the direct path.
    for (k, w) in world.walls.iter().enumerate().filter(|(_, w)| w.crosses(&s, &m)) {
        let mut edges = Vec::new();
        for (end, other) in [(w.from, w.to), (w.to, w.from)] {
            let out = Vector2::new(end[0] - other[0], end[1] - other[1]).normalize() * 1e-3;
            edges.push(Vector3::new(end[0] + out.x, end[1] + out.y, 0.5 * (s.z + m.z)));
        }
        if w.height < world.max[2]
            && let Some((t, _)) = crossing(&s, &m, w)
        {
            let p = s + (m - s) * t;
            edges.push(Vector3::new(p.x, p.y, w.height + 1e-3));
        }
        for e in edges {
            if !inside(world, &e)
                || walls_crossed(world, &s, &e, Some(k)) + walls_crossed(world, &e, &m, Some(k)) > 0
            {
                continue;
            }
            let length = (e - s).norm() + (m - e).norm();
            paths.push(SoundPath {
                length,
                gain: mic.directivity_gain(&e) / length,
                diffraction_excess: Some(length - d),
            });
        }
    }
    // First-order reflections: interior walls, the outline, the floor.
    let outline = outline(world);
    let reflectors = world
        .walls
        .iter()
        .enumerate()
        .map(|(k, w)| (Some(k), w))
        .chain(outline.iter().map(|w| (None, w)));
    for (k, w) in reflectors {
        let image = mirror(&s, w.from, w.to);
        let Some((t, u)) = crossing(&image, &m, w) else {
            continue;
        };
        if !(0.0..=1.0).contains(&t) || !(0.0..=1.0).contains(&u) {
            continue;
        }
        let r = image + (m - image) * t;
        if r.z > w.height || (k.is_some() && side(w, &s) != side(w, &m)) {
            continue;
        }
        let walls = walls_crossed(world, &s, &r, k) + walls_crossed(world, &r, &m, k);
        let length = (r - s).norm() + (m - r).norm();
        paths.push(SoundPath {
            length,
            gain: params.reflection * through(walls) / length * mic.directivity_gain(&r),
            diffraction_excess: None,
        });
    }
    if params.floor {
        let image = Vector3::new(s.x, s.y, -s.z);
        let t = s.z / (s.z + m.z).max(1e-9);
        let r = image + (m - image) * t;
        let walls = walls_crossed(world, &s, &r, None) + walls_crossed(world, &r, &m, None);
        let length = (m - image).norm();
        paths.push(SoundPath {
            length,
            gain: params.reflection * through(walls) / length * mic.directivity_gain(&r),
            diffraction_excess: None,
        });
    }
    paths
}

/// Which side of the wall's line a point is on.
fn side(w: &Wall, p: &Vector3<f64>) -> bool {
    (w.to[0] - w.from[0]) * (p.y - w.from[1]) - (w.to[1] - w.from[1]) * (p.x - w.from[0]) > 0.0
}

/// The transfer function of a set of paths at `freq` Hz.
pub fn transfer(paths: &[SoundPath], params: &AcousticParams, freq: f64) -> Complex<f64> {
    let lambda = params.speed_of_sound / freq.max(1e-6);
    paths
        .iter()
        .map(|p| {
            let loss = p
                .diffraction_excess
                .map(|excess| 10f64.powf(-knife_edge_loss_db(2.0 * (excess.max(0.0) / lambda).sqrt()) / 20.0))
                .unwrap_or(1.0);
            let phase = -std::f64::consts::TAU * freq * p.length / params.speed_of_sound;
            Complex::from_polar(p.gain * loss, phase)
        })
        .sum()
}

/// Both channels of `node`, `samples` long at `sample_rate`, with the source at `source`.
pub fn render_stereo(
    world: &World,
    params: &AcousticParams,
    node: &TwoMicNode,
    source: [f64; 2],
    samples: usize,
    sample_rate: u32,
    rng: &mut impl Rng,
) -> (Vec<f32>, Vec<f32>) {
    let n = samples.max(2);
    let mut planner = RealFftPlanner::<f64>::new();
    let (forward, inverse) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let white = Normal::new(0.0, params.source_rms.max(0.0)).expect("finite RMS");
    let mut signal: Vec<f64> = (0..n).map(|_| white.sample(rng)).collect();
    let mut spectrum = forward.make_output_vec();
    forward
        .process(&mut signal, &mut spectrum)
        .expect("sized by the plan");
    let noise = Normal::new(0.0, params.noise_rms.max(0.0)).expect("finite RMS");
    let mut channel = |mic: &Microphone| -> Vec<f32> {
        let paths = sound_paths(world, params, source, mic);
        let mut shaped: Vec<Complex<f64>> = spectrum
            .iter()
            .enumerate()
            .map(|(k, x)| x * transfer(&paths, params, k as f64 * f64::from(sample_rate) / n as f64))
            .collect();
        // A real signal's DC and Nyquist bins are real.
        shaped[0].im = 0.0;
        if n.is_multiple_of(2) {
            let last = shaped.len() - 1;
            shaped[last].im = 0.0;
        }
        let mut out = inverse.make_output_vec();
        inverse.process(&mut shaped, &mut out).expect("sized by the plan");
        out.iter()
            .map(|v| (v / n as f64 + noise.sample(rng)) as f32)
            .collect()
    };
    let left = channel(&node.left);
    let right = channel(&node.right);
    (left, right)
}

#[cfg(test)]
mod tests;
