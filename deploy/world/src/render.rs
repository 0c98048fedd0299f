//! The synthetic frame source: what a camera sees of the scenario's world at time `t`.
//!
//! Floor (tiles), room walls and ceiling, the scenario's occluding walls and every target as a
//! shaded coloured box, seen through the camera's own intrinsics *and lens distortion*: each
//! pixel's undistorted ray comes from a map computed once per camera with the exact inverse
//! of `proto`'s distortion, so straight edges bend as the lens bends them and undistortion
//! has real work to do. The static scene (and its depth) is rendered once; per frame only
//! targets are filled — each visible face is a convex polygon in undistorted coordinates,
//! tested per pixel over its distorted bounding box, far targets first (painter's algorithm),
//! hidden where a wall is nearer. Then a slow global illumination change and seeded sensor
//! noise. The output is a pure function of (scenario, camera, t, seed).

use crate::targets::{Target, targets};
use nalgebra::{Vector2, Vector3};
use proto::ClusterTime;
use proto::camera::CameraModel;
use proto::scenario::{Scenario, ScenarioError, World};
use proto::sensor::Frame;
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Standard deviation of the sensor noise, grey levels (triangular, per channel).
pub const NOISE_SD: f64 = 3.24;
/// Period and amplitude of the slow illumination change.
pub const ILLUMINATION_PERIOD_S: f64 = 40.0;
pub const ILLUMINATION_AMPLITUDE: f64 = 0.08;

/// A camera's renderer: its ray map and static scene, computed once.
#[derive(Debug, Clone)]
pub struct Renderer {
    camera: CameraModel,
    width: u32,
    height: u32,
    /// Undistorted normalized coordinates of each pixel centre (NaN where undefined).
    rays: Vec<[f32; 2]>,
    /// The static scene, RGB, before illumination and noise.
    background: Vec<u8>,
    /// Distance along each pixel's ray to the static surface, metres.
    depth: Vec<f32>,
    seed: u64,
}

fn mix(a: u64, b: u64) -> u64 {
    // SplitMix64 finaliser over a combination: cheap, well-spread seeds.
    let mut z = a ^ b.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A surface hit: distance along the (unit) ray and colour.
fn static_hit(world: &World, origin: &Vector3<f64>, dir: &Vector3<f64>) -> (f64, [u8; 3]) {
    let mut best = (f64::INFINITY, [0u8, 0, 0]);
    let (lo, hi) = (world.min, world.max);
    let mut consider = |s: f64, colour: [u8; 3]| {
        if s > 1e-6 && s < best.0 {
            best = (s, colour);
        }
    };
    // Floor and ceiling.
    if dir.z.abs() > 1e-12 {
        let s = (lo[2] - origin.z) / dir.z;
        let p = origin + dir * s;
        let (tx, ty) = ((p.x / 0.5).floor() as i64, (p.y / 0.5).floor() as i64);
        let checker = (tx + ty).rem_euclid(2) == 0;
        let fx = p.x / 0.5 - tx as f64;
        let fy = p.y / 0.5 - ty as f64;
        let grout = fx < 0.04 || fy < 0.04;
        let wave = ((p.x * 0.7).sin() * (p.y * 0.9).cos() * 10.0) as i32;
        let base: i32 = if grout {
            70
        } else if checker {
            150
        } else {
            120
        };
        let v = (base + wave).clamp(0, 255) as u8;
        consider(s, [v, v.saturating_sub(6), v.saturating_sub(14)]);
        let s = (hi[2] - origin.z) / dir.z;
        consider(s, [200, 200, 195]);
    }
    // Room walls: planes x = lo/hi, y = lo/hi.
    for (axis, bound, colour) in [
        (0usize, lo[0], [170u8, 160, 140]),
        (0, hi[0], [150, 165, 175]),
        (1, lo[1], [175, 170, 150]),
        (1, hi[1], [160, 150, 165]),
    ] {
        let d = dir[axis];
        if d.abs() > 1e-12 {
            let s = (bound - origin[axis]) / d;
            let p = origin + dir * s;
            let along = if axis == 0 { p.y } else { p.x };
            let stripe = ((along / 0.6).floor() as i64).rem_euclid(2) == 0;
            let k = if stripe { 0 } else { 12 };
            consider(s, [colour[0] - k, colour[1] - k, colour[2] - k]);
        }
    }
    // Occluding walls: vertical quads from the floor to their height.
    for w in &world.walls {
        let a = Vector2::new(w.from[0], w.from[1]);
        let e = Vector2::new(w.to[0] - w.from[0], w.to[1] - w.from[1]);
        let d2 = Vector2::new(dir.x, dir.y);
        let denom = d2.x * e.y - d2.y * e.x;
        if denom.abs() < 1e-12 {
            continue;
        }
        let ao = a - Vector2::new(origin.x, origin.y);
        let s = (ao.x * e.y - ao.y * e.x) / denom;
        let u = (ao.x * d2.y - ao.y * d2.x) / denom;
        let z = origin.z + dir.z * s;
        if (0.0..=1.0).contains(&u) && z >= 0.0 && z <= w.height {
            let brick = (((u * e.norm()) / 0.3).floor() as i64 + (z / 0.15).floor() as i64).rem_euclid(2);
            consider(s, if brick == 0 { [120, 70, 60] } else { [105, 62, 55] });
        }
    }
    best
}

impl Renderer {
    /// Build the renderer of a camera in the scenario's world.
    pub fn new(world: &World, camera: &CameraModel, seed: u64) -> Renderer {
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let n = w as usize * h as usize;
        let mut rays = Vec::with_capacity(n);
        let mut background = vec![0u8; n * 3];
        let mut depth = vec![f32::INFINITY; n];
        let origin = camera.pose.centre();
        let inv = camera.pose.rotation.inverse();
        for v in 0..h {
            for u in 0..w {
                let i = (v * w + u) as usize;
                match camera.undistort(&Vector2::new(u as f64, v as f64)) {
                    Ok(p) => {
                        rays.push([p.x as f32, p.y as f32]);
                        let dir = (inv * Vector3::new(p.x, p.y, 1.0)).normalize();
                        let (s, rgb) = static_hit(world, &origin, &dir);
                        if s.is_finite() {
                            background[i * 3..i * 3 + 3].copy_from_slice(&rgb);
                            depth[i] = s as f32;
                        }
                    }
                    Err(_) => rays.push([f32::NAN, f32::NAN]),
                }
            }
        }
        Renderer {
            camera: *camera,
            width: w,
            height: h,
            rays,
            background,
            depth,
            seed,
        }
    }

    /// The renderer of camera node `id` of `scenario`.
    ///
    /// # Errors
    /// The node has no usable camera geometry.
    pub fn for_node(
        scenario: &Scenario,
        id: u32,
        seed: u64,
    ) -> Result<Renderer, proto::scenario::ScenarioError> {
        let cam = scenario.camera_model(id)?;
        Ok(Renderer::new(&scenario.world, &cam, mix(seed, id as u64)))
    }

    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Render the scene at `t` seconds after the scenario start into `frame` (resized if
    /// needed); `captured` is stamped on it.
    pub fn render(&self, targets: &[Target], t: f64, captured: ClusterTime, frame: &mut Frame) {
        let n = self.width as usize * self.height as usize;
        frame.width = self.width;
        frame.height = self.height;
        frame.captured = captured;
        frame.data.resize(n * 3, 0);
        frame.data.copy_from_slice(&self.background);
        let origin = self.camera.pose.centre();
        let mut order: Vec<(f64, &Target)> = targets
            .iter()
            .map(|tg| {
                let s = tg.truth_at(t);
                ((Vector3::new(s[0], s[1], s[2]) - origin).norm(), tg)
            })
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (dist, tg) in order {
            self.draw_box(tg, t, dist as f32, &mut frame.data);
        }
        self.finish(t, &mut frame.data);
    }

    fn draw_box(&self, tg: &Target, t: f64, dist: f32, data: &mut [u8]) {
        let s = tg.truth_at(t);
        let c = Vector3::new(s[0], s[1], s[2]);
        let half = Vector3::new(tg.size[0], tg.size[1], tg.size[2]) * 0.5;
        let origin = self.camera.pose.centre();
        let light = Vector3::new(0.3, 0.5, 0.8).normalize();
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut normal = Vector3::zeros();
                normal[axis] = sign;
                let fc = c + normal.component_mul(&half);
                if normal.dot(&(origin - fc)) <= 0.0 {
                    continue;
                }
                let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut poly = [Vector2::zeros(); 4];
                let mut ok = true;
                for (k, (s1, s2)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .into_iter()
                    .enumerate()
                {
                    let mut p = fc;
                    p[a1] += s1 * half[a1];
                    p[a2] += s2 * half[a2];
                    let (q, z) = self.camera.normalized(&p);
                    if z < 0.05 {
                        ok = false;
                    }
                    poly[k] = q;
                }
                if !ok {
                    continue;
                }
                let shade = 0.55 + 0.45 * normal.dot(&light).max(0.0);
                let rgb = tg
                    .colour
                    .map(|v| (v as f64 * shade).round().clamp(0.0, 255.0) as u8);
                self.fill(&poly, rgb, dist, data);
            }
        }
    }

    /// Fill a convex polygon given in undistorted normalized coordinates.
    fn fill(&self, poly: &[Vector2<f64>; 4], rgb: [u8; 3], dist: f32, data: &mut [u8]) {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        // Corners and edge midpoints bound the distorted outline well; a margin covers bulge.
        for k in 0..4 {
            let a = poly[k];
            let b = poly[(k + 1) % 4];
            for p in [a, (a + b) * 0.5] {
                let px = self.camera.normalized_to_pixel(&p);
                x0 = x0.min(px.x);
                y0 = y0.min(px.y);
                x1 = x1.max(px.x);
                y1 = y1.max(px.y);
            }
        }
        let margin = 3.0 + 0.05 * (x1 - x0).max(y1 - y0);
        let (w, h) = (self.width as f64, self.height as f64);
        if !(x1 + margin >= 0.0 && y1 + margin >= 0.0 && x0 - margin < w && y0 - margin < h) {
            return;
        }
        let u0 = (x0 - margin).max(0.0) as usize;
        let v0 = (y0 - margin).max(0.0) as usize;
        let u1 = ((x1 + margin).min(w - 1.0)) as usize;
        let v1 = ((y1 + margin).min(h - 1.0)) as usize;
        // Edge functions, oriented so the inside is non-negative.
        let area: f64 = (0..4)
            .map(|k| {
                let (a, b) = (poly[k], poly[(k + 1) % 4]);
                a.x * b.y - b.x * a.y
            })
            .sum();
        let sign = if area >= 0.0 { 1.0f32 } else { -1.0 };
        let edges: [[f32; 3]; 4] = std::array::from_fn(|k| {
            let (a, b) = (poly[k], poly[(k + 1) % 4]);
            // (b − a) × (p − a) = ex·(py − ay) − ey·(px − ax)
            let (ex, ey) = ((b.x - a.x) as f32, (b.y - a.y) as f32);
            [sign * -ey, sign * ex, sign * (ey * a.x as f32 - ex * a.y as f32)]
        });
        let width = self.width as usize;
        for v in v0..=v1 {
            for u in u0..=u1 {
                let i = v * width + u;
                let [x, y] = self.rays[i];
                let inside = edges.iter().all(|e| e[0] * x + e[1] * y + e[2] >= 0.0);
                if inside && dist < self.depth[i] {
                    data[i * 3..i * 3 + 3].copy_from_slice(&rgb);
                }
            }
        }
    }

    /// Illumination gain at `t` seconds.
    pub fn illumination(&self, t: f64) -> f64 {
        let phase = (self.seed % 1000) as f64 / 1000.0 * std::f64::consts::TAU;
        1.0 + ILLUMINATION_AMPLITUDE * (std::f64::consts::TAU * t / ILLUMINATION_PERIOD_S + phase).sin()
    }

    /// Apply illumination and seeded sensor noise.
    fn finish(&self, t: f64, data: &mut [u8]) {
        let gain = (self.illumination(t) * 256.0).round() as i32;
        let tn = (t * 1e9).round() as i64 as u64;
        let mut seeder = ChaCha8Rng::seed_from_u64(mix(self.seed, tn));
        apply_gain_and_noise(data, gain, seeder.next_u64() | 1);
    }
}

/// Per pixel one xorshift64* draw (from `state`) gives six nibbles, two per channel; a channel
/// becomes `clamp(⌊v·gain/256⌋ + a + b − 7)`. Done in blocks: a serial pass draws a block's
/// noise bytes (byte `c` of a pixel's draw is its channel `c`), then a flat pass over the
/// block's bytes applies gain and noise in 16-bit lanes, which the compiler vectorizes:
/// `⌊v·gain/256⌋ = v + ⌊v·(gain − 256)/256⌋` keeps every product within `i16` for the
/// illumination's few percent.
fn apply_gain_and_noise(data: &mut [u8], gain: i32, mut state: u64) {
    const BLOCK: usize = 64;
    let dg = gain - 256;
    // |v·dg| ≤ 255·128 fits i16.
    let narrow = dg.abs() <= 128;
    let dg16 = dg as i16;
    // One spare byte: each pixel writes four noise bytes, the next pixel overwrites the last.
    let mut noise = [0u8; BLOCK * 3 + 1];
    for block in data.chunks_mut(BLOCK * 3) {
        let pixels = block.len() / 3;
        for k in 0..pixels {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            let r = state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 16;
            noise[k * 3..k * 3 + 4].copy_from_slice(&(r as u32).to_le_bytes());
        }
        let bytes = pixels * 3;
        if narrow {
            for (v, &nb) in block[..bytes].iter_mut().zip(&noise[..bytes]) {
                let x = *v as i16;
                let n = (nb & 7) as i16 + ((nb >> 4) & 7) as i16 - 7;
                *v = (x + ((x * dg16) >> 8) + n).clamp(0, 255) as u8;
            }
        } else {
            for (v, &nb) in block[..bytes].iter_mut().zip(&noise[..bytes]) {
                let n = (nb & 7) as i32 + ((nb >> 4) & 7) as i32 - 7;
                *v = (((*v as i32 * gain) >> 8) + n).clamp(0, 255) as u8;
            }
        }
    }
}

/// Render one frame of camera node `id` at `t` seconds: the pure-function form (builds the
/// renderer; runtimes keep a [`Renderer`] instead).
///
/// # Errors
/// The node has no usable camera geometry.
pub fn render_frame(scenario: &Scenario, id: u32, t: f64, seed: u64) -> Result<Frame, ScenarioError> {
    let r = Renderer::for_node(scenario, id, seed)?;
    let mut f = Frame::new(0, 0, ClusterTime::ZERO);
    r.render(&targets(scenario)?, t, ClusterTime::from_secs_f64(t), &mut f);
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::scenario::Wall;

    /// The per-pixel form the blocked, vectorized [`apply_gain_and_noise`] must equal.
    fn gain_and_noise_reference(data: &mut [u8], gain: i32, mut state: u64) {
        for px in data.chunks_exact_mut(3) {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            let r = state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 16;
            for (c, v) in px.iter_mut().enumerate() {
                let a = ((r >> (c * 8)) & 7) as i32;
                let b = ((r >> (c * 8 + 4)) & 7) as i32;
                *v = (((*v as i32 * gain) >> 8) + a + b - 7).clamp(0, 255) as u8;
            }
        }
    }

    #[test]
    fn blocked_noise_equals_the_per_pixel_form() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // Odd lengths end in a partial block; gains cover dark, bright, and the wide path.
        for (pixels, gain) in [
            (352 * 288, 236),
            (1000, 256),
            (131, 277),
            (64, 200),
            (65, 700),
            (7, 10),
        ] {
            let mut a = vec![0u8; pixels * 3];
            rng.fill_bytes(&mut a);
            a[0] = 255;
            a[1] = 0;
            let mut b = a.clone();
            let state = rng.next_u64() | 1;
            apply_gain_and_noise(&mut a, gain, state);
            gain_and_noise_reference(&mut b, gain, state);
            assert_eq!(a, b, "{pixels} pixels at gain {gain}");
        }
    }

    #[test]
    fn deterministic_for_a_seed_and_noisy_across_seeds() {
        let s = Scenario::default_scenario();
        let a = render_frame(&s, 10, 3.0, 7).unwrap();
        let b = render_frame(&s, 10, 3.0, 7).unwrap();
        let c = render_frame(&s, 10, 3.0, 8).unwrap();
        assert_eq!(a, b);
        assert_ne!(a.data, c.data);
        assert_eq!((a.width, a.height), (352, 288));
        assert_eq!(a.check(), Ok(()));
    }

    /// The target's colour appears around the distorted projection of its centre, and the
    /// pixels there are the target's hue.
    #[test]
    fn target_lands_where_the_lens_projects_it() {
        let s = Scenario::default_scenario();
        let r = Renderer::for_node(&s, 10, 1).unwrap();
        let cam = s.camera_model(10).unwrap();
        let mut f = Frame::new(0, 0, ClusterTime::ZERO);
        let all = targets(&s).unwrap();
        let tg = &all[0];
        // Find a time when the target is well inside camera 10's view.
        let t = (0..400)
            .map(|k| k as f64 * 0.25)
            .find(|&t| {
                let x = tg.truth_at(t);
                cam.project(&Vector3::new(x[0], x[1], x[2]))
                    .is_some_and(|p| p.x > 60.0 && p.x < 290.0 && p.y > 60.0 && p.y < 230.0)
            })
            .expect("target visible at some time");
        r.render(&all, t, ClusterTime::ZERO, &mut f);
        let x = tg.truth_at(t);
        let p = cam.project(&Vector3::new(x[0], x[1], x[2])).unwrap();
        let [red, g, b] = f.pixel(p.x as u32, p.y as u32);
        assert!(
            red as i32 > g as i32 + 60 && red as i32 > b as i32 + 60,
            "{:?} at {p}",
            [red, g, b]
        );
        // Far from it, no target colour.
        let far = f.pixel(5, 5);
        assert!((far[0] as i32 - far[1] as i32).abs() < 40, "{far:?}");
    }

    #[test]
    fn walls_hide_targets_behind_them() {
        let mut s = Scenario::default_scenario();
        let cam = s.camera_model(10).unwrap();
        let all = targets(&s).unwrap();
        let tg = all[0].clone();
        let t = 0.0;
        let x = tg.truth_at(t);
        let p = cam.project(&Vector3::new(x[0], x[1], x[2])).unwrap();
        let r = Renderer::for_node(&s, 10, 1).unwrap();
        let mut open = Frame::new(0, 0, ClusterTime::ZERO);
        r.render(&all, t, ClusterTime::ZERO, &mut open);
        // A tall wall between camera 10 (at 0.95, 0.15) and the target.
        let c = cam.pose.centre();
        let mid = [(c.x + x[0]) / 2.0, (c.y + x[1]) / 2.0];
        s.world.walls.push(Wall {
            from: [mid[0] - 1.0, mid[1] + 1.0],
            to: [mid[0] + 1.0, mid[1] - 1.0],
            height: 3.0,
            attenuation_db: 6.0,
        });
        let r = Renderer::for_node(&s, 10, 1).unwrap();
        let mut hidden = Frame::new(0, 0, ClusterTime::ZERO);
        r.render(&all, t, ClusterTime::ZERO, &mut hidden);
        let mut empty = Frame::new(0, 0, ClusterTime::ZERO);
        r.render(&[], t, ClusterTime::ZERO, &mut empty);
        if (0.0..352.0).contains(&p.x) && (0.0..288.0).contains(&p.y) {
            let a = open.pixel(p.x as u32, p.y as u32);
            let b = hidden.pixel(p.x as u32, p.y as u32);
            assert!(a[0] as i32 > a[1] as i32 + 60, "visible without the wall: {a:?}");
            assert_eq!(b, empty.pixel(p.x as u32, p.y as u32), "hidden by the wall");
            assert_eq!(hidden, empty, "no target pixel anywhere");
        } else {
            panic!("target at t=0 is outside camera 10's view ({p})");
        }
    }

    /// Two people on one line of sight: whichever order they are listed in, the nearer one's
    /// colour fills the pixel where both are seen (painter's algorithm, far first).
    #[test]
    fn the_nearer_of_two_people_on_a_line_of_sight_is_drawn() {
        let s = Scenario::default_scenario();
        let cam = s.camera_model(10).unwrap();
        let r = Renderer::for_node(&s, 10, 1).unwrap();
        let c = cam.pose.centre();
        let person = |id: u32, along: f64, colour: [u8; 3]| {
            // On the ray from the camera through the room's centre, `along` of the way.
            let at = [c.x + along * (6.0 - c.x), c.y + along * (4.0 - c.y)];
            crate::Target {
                id,
                trajectory: crate::Trajectory::Path {
                    waypoints: vec![at, at],
                    speed: 1.0,
                    pauses: Vec::new(),
                },
                size: [0.5, 0.5, 1.8],
                colour,
                rssi_tag: false,
            }
        };
        let (red, green) = ([220, 20, 20], [20, 200, 20]);
        let near = person(1, 0.6, red);
        let far = person(2, 1.0, green);
        // Where the far one's centre projects: the near one, taller than that line of sight
        // where it stands, covers it.
        let x = far.truth_at(0.0);
        let p = cam.project(&Vector3::new(x[0], x[1], x[2])).unwrap();
        assert!(
            (0.0..352.0).contains(&p.x) && (0.0..288.0).contains(&p.y),
            "far person outside camera 10's view ({p})"
        );
        for order in [[near.clone(), far.clone()], [far.clone(), near.clone()]] {
            let mut f = Frame::new(0, 0, ClusterTime::ZERO);
            r.render(&order, 0.0, ClusterTime::ZERO, &mut f);
            let px = f.pixel(p.x as u32, p.y as u32);
            assert!(
                px[0] as i32 > px[1] as i32 + 60,
                "the nearer (red) person is drawn over the farther (green): {px:?}"
            );
        }
        // The far one alone is visible at that pixel: the test can fail.
        let mut f = Frame::new(0, 0, ClusterTime::ZERO);
        r.render(std::slice::from_ref(&far), 0.0, ClusterTime::ZERO, &mut f);
        let px = f.pixel(p.x as u32, p.y as u32);
        assert!(
            px[1] as i32 > px[0] as i32 + 60,
            "the far (green) person alone: {px:?}"
        );
    }
}
