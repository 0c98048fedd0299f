//! Paper 004 §2.2 (ii): the prediction step. A sample's state is its box in the image —
//! centre, velocity and size (§3.2.2 (ii): "the state also comprises the object's size") — and
//! it moves by one of three models, each with Gaussian diffusion: random position (scattered
//! uniformly over the image), zero velocity, constant velocity (`X_t = A X_{t−1} + w`). In the
//! combined mode the non-random samples keep their parent's model. Units are pixels and
//! iterations (frames), as in the paper.

use crate::tracker::params::{MotionMode, ParticleParams};
use proto::msg::PixelBox;
use rand::Rng;
use rand_distr::StandardNormal;

/// One sample's state: box centre, velocity per iteration, box size (pixels).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    pub x: f32,
    pub y: f32,
    pub vx: f32,
    pub vy: f32,
    pub w: f32,
    pub h: f32,
}

impl State {
    /// At rest, filling `b`.
    pub fn from_box(b: &PixelBox) -> State {
        State {
            x: 0.5 * (b.xmin + b.xmax),
            y: 0.5 * (b.ymin + b.ymax),
            vx: 0.0,
            vy: 0.0,
            w: b.xmax - b.xmin,
            h: b.ymax - b.ymin,
        }
    }

    pub fn bbox(&self) -> PixelBox {
        PixelBox {
            xmin: self.x - 0.5 * self.w,
            ymin: self.y - 0.5 * self.h,
            xmax: self.x + 0.5 * self.w,
            ymax: self.y + 0.5 * self.h,
        }
    }

    pub fn centre(&self) -> [f32; 2] {
        [self.x, self.y]
    }

    pub fn half(&self) -> [f32; 2] {
        [0.5 * self.w, 0.5 * self.h]
    }

    /// The same state in an image `factor` times larger (e.g. 2 for a Bayer half-resolution
    /// frame mapped back to the sensor's pixels).
    pub fn scaled(&self, factor: f32) -> State {
        State {
            x: self.x * factor,
            y: self.y * factor,
            vx: self.vx * factor,
            vy: self.vy * factor,
            w: self.w * factor,
            h: self.h * factor,
        }
    }

    /// The six values in a fixed order (x, y, vx, vy, w, h).
    pub fn to_array(&self) -> [f32; 6] {
        [self.x, self.y, self.vx, self.vy, self.w, self.h]
    }

    pub fn from_array(a: [f32; 6]) -> State {
        let [x, y, vx, vy, w, h] = a;
        State { x, y, vx, vy, w, h }
    }
}

/// How one sample moves in one iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionModel {
    RandomPosition,
    ZeroVelocity,
    ConstantVelocity,
}

/// The image the samples live in, pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub width: f32,
    pub height: f32,
}

/// The Gaussian diffusion of every model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diffusion {
    pub position: f32,
    pub velocity: f32,
    /// Relative (log-normal) size spread.
    pub size: f32,
    pub min_size: f32,
}

impl Diffusion {
    pub fn from_params(p: &ParticleParams) -> Diffusion {
        Diffusion {
            position: p.position_sigma_px,
            velocity: p.velocity_sigma_px,
            size: p.size_sigma,
            min_size: p.min_size_px,
        }
    }
}

fn normal(rng: &mut impl Rng) -> f32 {
    rng.sample(StandardNormal)
}

/// Move one sample by `model`, then keep its centre in the image and its size between
/// `min_size` and the image.
pub fn propagate(s: &mut State, model: MotionModel, d: &Diffusion, bounds: Bounds, rng: &mut impl Rng) {
    match model {
        MotionModel::RandomPosition => {
            s.x = rng.random::<f32>() * bounds.width;
            s.y = rng.random::<f32>() * bounds.height;
            s.vx = 0.0;
            s.vy = 0.0;
        }
        MotionModel::ZeroVelocity => {
            s.vx = 0.0;
            s.vy = 0.0;
            s.x += d.position * normal(rng);
            s.y += d.position * normal(rng);
        }
        MotionModel::ConstantVelocity => {
            s.x += s.vx + d.position * normal(rng);
            s.y += s.vy + d.position * normal(rng);
            s.vx += d.velocity * normal(rng);
            s.vy += d.velocity * normal(rng);
        }
    }
    if d.size > 0.0 {
        s.w *= (d.size * normal(rng)).exp();
        s.h *= (d.size * normal(rng)).exp();
    }
    let min = d.min_size;
    s.w = s.w.clamp(min, bounds.width.max(min));
    s.h = s.h.clamp(min, bounds.height.max(min));
    s.x = s.x.clamp(0.0, (bounds.width - 1.0).max(0.0));
    s.y = s.y.clamp(0.0, (bounds.height - 1.0).max(0.0));
}

/// How many of `n` samples are scattered, and how many of the rest use zero velocity.
pub fn model_counts(n: usize, random_fraction: f32, zero_velocity_fraction: f32) -> (usize, usize) {
    let random = ((n as f32 * random_fraction).round() as usize).min(n);
    let zero = (((n - random) as f32 * zero_velocity_fraction).round() as usize).min(n - random);
    (random, zero)
}

/// The models a fresh sample set starts with: the zero velocity share first, then constant
/// velocity (samples are exchangeable, so the order carries no meaning).
pub fn initial_models(n: usize, p: &ParticleParams, out: &mut Vec<MotionModel>) {
    let (_, zero) = model_counts(n, 0.0, p.zero_velocity_fraction);
    out.clear();
    out.extend((0..n).map(|i| {
        if i < zero {
            MotionModel::ZeroVelocity
        } else {
            MotionModel::ConstantVelocity
        }
    }));
}

/// This iteration's model of each sample. `carried` holds each sample's inherited model (its
/// parent's, after resampling) and is updated where a sample takes a new one. The first
/// samples are scattered (resampling leaves the set in random order, so that is a random
/// choice). Fixed mode: then the zero velocity share, then constant velocity. Combined mode: a
/// scattered sample's successors get zero or constant velocity by the configured share; every
/// other sample moves by its carried model.
pub fn models_for_step(
    carried: &mut [MotionModel],
    p: &ParticleParams,
    rng: &mut impl Rng,
    out: &mut Vec<MotionModel>,
) {
    let n = carried.len();
    let (random, zero) = model_counts(n, p.random_fraction, p.zero_velocity_fraction);
    out.clear();
    for (i, c) in carried.iter_mut().enumerate() {
        let model = match p.motion {
            MotionMode::Fixed if i < random => MotionModel::RandomPosition,
            MotionMode::Fixed if i < random + zero => MotionModel::ZeroVelocity,
            MotionMode::Fixed => MotionModel::ConstantVelocity,
            MotionMode::Combined if i < random => {
                *c = if rng.random::<f32>() < p.zero_velocity_fraction {
                    MotionModel::ZeroVelocity
                } else {
                    MotionModel::ConstantVelocity
                };
                MotionModel::RandomPosition
            }
            MotionMode::Combined => *c,
        };
        if p.motion == MotionMode::Fixed {
            *c = model;
        }
        out.push(model);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    const BOUNDS: Bounds = Bounds {
        width: 640.0,
        height: 480.0,
    };

    fn diffusion() -> Diffusion {
        Diffusion {
            position: 3.0,
            velocity: 0.5,
            size: 0.0,
            min_size: 4.0,
        }
    }

    /// Mean and standard deviation of one coordinate after one step from `start`.
    fn moments(start: State, model: MotionModel, pick: fn(&State) -> f32) -> (f32, f32) {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 20_000;
        let xs: Vec<f32> = (0..n)
            .map(|_| {
                let mut s = start;
                propagate(&mut s, model, &diffusion(), BOUNDS, &mut rng);
                pick(&s)
            })
            .collect();
        let mean = xs.iter().sum::<f32>() / n as f32;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / n as f32;
        (mean, var.sqrt())
    }

    fn moving() -> State {
        State {
            x: 100.0,
            y: 200.0,
            vx: 5.0,
            vy: -2.0,
            w: 30.0,
            h: 60.0,
        }
    }

    #[test]
    fn zero_velocity_diffuses_around_the_position() {
        let (m, s) = moments(moving(), MotionModel::ZeroVelocity, |s| s.x);
        assert!((m - 100.0).abs() < 0.1 && (s - 3.0).abs() < 0.1, "{m} {s}");
        let (vm, vs) = moments(moving(), MotionModel::ZeroVelocity, |s| s.vx);
        assert_eq!((vm, vs), (0.0, 0.0));
    }

    #[test]
    fn constant_velocity_moves_by_the_velocity() {
        let (m, s) = moments(moving(), MotionModel::ConstantVelocity, |s| s.x);
        assert!((m - 105.0).abs() < 0.1 && (s - 3.0).abs() < 0.1, "{m} {s}");
        let (m, _) = moments(moving(), MotionModel::ConstantVelocity, |s| s.y);
        assert!((m - 198.0).abs() < 0.1, "{m}");
        let (vm, vs) = moments(moving(), MotionModel::ConstantVelocity, |s| s.vx);
        assert!((vm - 5.0).abs() < 0.02 && (vs - 0.5).abs() < 0.02, "{vm} {vs}");
    }

    #[test]
    fn random_position_covers_the_image() {
        let (m, s) = moments(moving(), MotionModel::RandomPosition, |s| s.x);
        // Uniform on [0, 640): mean 320, sd 640/√12 = 184.8.
        assert!((m - 320.0).abs() < 4.0 && (s - 184.75).abs() < 3.0, "{m} {s}");
        let (m, _) = moments(moving(), MotionModel::RandomPosition, |s| s.y);
        assert!((m - 240.0).abs() < 3.0, "{m}");
    }

    #[test]
    fn size_diffuses_log_normally_and_stays_in_bounds() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let d = Diffusion {
            size: 0.1,
            ..diffusion()
        };
        let mut logs = Vec::new();
        for _ in 0..10_000 {
            let mut s = moving();
            propagate(&mut s, MotionModel::ZeroVelocity, &d, BOUNDS, &mut rng);
            logs.push((s.w / 30.0).ln());
        }
        let mean = logs.iter().sum::<f32>() / logs.len() as f32;
        let sd = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / logs.len() as f32).sqrt();
        assert!(mean.abs() < 0.005 && (sd - 0.1).abs() < 0.005, "{mean} {sd}");
        let mut tiny = State {
            w: 4.5,
            h: 5000.0,
            x: -20.0,
            y: 900.0,
            ..moving()
        };
        for _ in 0..50 {
            propagate(&mut tiny, MotionModel::ConstantVelocity, &d, BOUNDS, &mut rng);
            assert!(tiny.w >= 4.0 && tiny.h <= 480.0, "{tiny:?}");
            assert!((0.0..=639.0).contains(&tiny.x) && (0.0..=479.0).contains(&tiny.y));
        }
    }

    fn count(models: &[MotionModel], which: MotionModel) -> usize {
        models.iter().filter(|&&m| m == which).count()
    }

    #[test]
    fn fixed_mode_assigns_the_configured_shares() {
        let p = ParticleParams {
            motion: MotionMode::Fixed,
            random_fraction: 0.1,
            zero_velocity_fraction: 0.25,
            ..ParticleParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut carried = vec![MotionModel::ConstantVelocity; 100];
        let mut out = Vec::new();
        models_for_step(&mut carried, &p, &mut rng, &mut out);
        assert_eq!(count(&out, MotionModel::RandomPosition), 10);
        assert_eq!(count(&out, MotionModel::ZeroVelocity), 23); // round(90 × 0.25) = 22.5 → 23
        assert_eq!(count(&out, MotionModel::ConstantVelocity), 67);
    }

    #[test]
    fn combined_mode_hands_the_model_down_and_scatters_the_random_share() {
        let p = ParticleParams {
            motion: MotionMode::Combined,
            random_fraction: 0.1,
            zero_velocity_fraction: 0.5,
            ..ParticleParams::default()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        // A set descended from constant velocity samples only.
        let mut carried = vec![MotionModel::ConstantVelocity; 100];
        let mut out = Vec::new();
        models_for_step(&mut carried, &p, &mut rng, &mut out);
        assert_eq!(count(&out, MotionModel::RandomPosition), 10);
        assert_eq!(count(&out, MotionModel::ConstantVelocity), 90, "inherited");
        assert_eq!(count(&out, MotionModel::ZeroVelocity), 0);
        // The scattered samples got a model for their successors, by the configured share.
        let given: Vec<_> = carried[..10].to_vec();
        assert!(given.iter().all(|m| *m != MotionModel::RandomPosition));
        let mut zero = 0;
        for _ in 0..200 {
            let mut c = vec![MotionModel::ConstantVelocity; 100];
            models_for_step(&mut c, &p, &mut rng, &mut out);
            zero += count(&c[..10], MotionModel::ZeroVelocity);
        }
        assert!(
            (900..1100).contains(&zero),
            "{zero} of 2000 scattered took zero velocity"
        );
    }

    #[test]
    fn initial_models_split_by_the_zero_velocity_share() {
        let p = ParticleParams {
            zero_velocity_fraction: 0.3,
            ..ParticleParams::default()
        };
        let mut out = Vec::new();
        initial_models(100, &p, &mut out);
        assert_eq!(count(&out, MotionModel::ZeroVelocity), 30);
        assert_eq!(count(&out, MotionModel::ConstantVelocity), 70);
    }

    #[test]
    fn box_and_state_round_trip() {
        let b = PixelBox {
            xmin: 10.0,
            ymin: 20.0,
            xmax: 40.0,
            ymax: 80.0,
        };
        let s = State::from_box(&b);
        assert_eq!((s.x, s.y, s.w, s.h), (25.0, 50.0, 30.0, 60.0));
        assert_eq!(s.bbox(), b);
        assert_eq!(s.scaled(2.0).bbox().xmax, 80.0);
        assert_eq!(State::from_array(s.to_array()), s);
    }
}
