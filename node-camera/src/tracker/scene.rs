//! Synthetic frames for the tracker's tests and its benchmark: people drawn as two-colour
//! boxes (shirt over trousers) moving and bouncing off the image borders over a textured,
//! noisy background. Pure in (scene, frame index): the same call draws the same pixels.

use proto::ClusterTime;
use proto::msg::PixelBox;
use proto::sensor::Frame;

/// One drawn person.
#[derive(Clone, Debug, PartialEq)]
pub struct Person {
    pub shirt: [u8; 3],
    pub trousers: [u8; 3],
    /// Box width and height, pixels.
    pub size: [f32; 2],
    /// Top-left corner at frame 0.
    pub start: [f32; 2],
    /// Pixels per frame.
    pub velocity: [f32; 2],
}

/// A scene of people over a background.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub width: u32,
    pub height: u32,
    pub people: Vec<Person>,
    /// Uniform pixel noise amplitude (± levels) on every pixel.
    pub noise: u8,
    /// Frames per second, for capture times.
    pub fps: f64,
}

/// `p` bounced between 0 and `range` (a triangle wave).
fn bounce(p: f32, range: f32) -> f32 {
    if range <= 0.0 {
        return 0.0;
    }
    let m = p.rem_euclid(2.0 * range);
    if m > range { 2.0 * range - m } else { m }
}

/// A small deterministic hash of a pixel and frame, for noise.
fn hash(x: u32, y: u32, t: u32) -> u32 {
    let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77) ^ t.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^ (h >> 12)
}

/// Fill a box (clipped to the frame) with one colour.
pub fn fill_box(frame: &mut Frame, b: &PixelBox, rgb: [u8; 3]) {
    let (w, h) = (frame.width as f32, frame.height as f32);
    let x0 = b.xmin.ceil().max(0.0) as usize;
    let x1 = (b.xmax.floor().min(w - 1.0)).max(-1.0) as i64;
    let y0 = b.ymin.ceil().max(0.0) as usize;
    let y1 = (b.ymax.floor().min(h - 1.0)).max(-1.0) as i64;
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            let i = (y as usize * frame.width as usize + x as usize) * 3;
            frame.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
}

impl Scene {
    /// `n` people with well separated hues, sizes about a sixth of the image height, moving
    /// in different directions.
    pub fn crowd(width: u32, height: u32, n: usize) -> Scene {
        let hh = height as f32 / 6.0;
        let people = (0..n)
            .map(|i| {
                let hue = i as f32 / n.max(1) as f32 * 6.0;
                let shirt = hue_rgb(hue, 220.0);
                let trousers = hue_rgb((hue + 3.0) % 6.0, 90.0);
                let k = i as f32;
                Person {
                    shirt,
                    trousers,
                    size: [hh * 0.45, hh],
                    start: [
                        (k * 0.37 + 0.1).fract() * width as f32,
                        (k * 0.61 + 0.2).fract() * height as f32,
                    ],
                    velocity: [1.5 + (k * 0.7) % 2.0, 0.8 - (k * 0.9) % 1.6],
                }
            })
            .collect();
        Scene {
            width,
            height,
            people,
            noise: 6,
            fps: 15.0,
        }
    }

    /// Person `i`'s box at frame `t`.
    pub fn box_at(&self, i: usize, t: u32) -> PixelBox {
        let p = &self.people[i];
        let x = bounce(
            p.start[0] + p.velocity[0] * t as f32,
            self.width as f32 - p.size[0],
        );
        let y = bounce(
            p.start[1] + p.velocity[1] * t as f32,
            self.height as f32 - p.size[1],
        );
        PixelBox {
            xmin: x,
            ymin: y,
            xmax: x + p.size[0],
            ymax: y + p.size[1],
        }
    }

    /// Draw frame `t` into `out` (resized if needed).
    pub fn render(&self, t: u32, out: &mut Frame) {
        let (w, h) = (self.width, self.height);
        if (out.width, out.height) != (w, h) {
            *out = Frame::new(w, h, ClusterTime::ZERO);
        }
        out.captured = ClusterTime::from_secs_f64(t as f64 / self.fps);
        for y in 0..h {
            for x in 0..w {
                let i = (y as usize * w as usize + x as usize) * 3;
                // A soft, low-saturation texture.
                let base = 96 + ((x / 24 + y / 24) % 2) as u8 * 16 + (y * 32 / h) as u8;
                out.data[i..i + 3].copy_from_slice(&[base, base + 8, base - 6]);
            }
        }
        for i in 0..self.people.len() {
            let p = &self.people[i];
            let b = self.box_at(i, t);
            let mid = b.ymin + 0.55 * (b.ymax - b.ymin);
            fill_box(out, &PixelBox { ymax: mid, ..b }, p.shirt);
            fill_box(out, &PixelBox { ymin: mid, ..b }, p.trousers);
        }
        self.add_noise(t, out);
    }

    /// Uniform noise of ±`noise` levels on every byte.
    pub fn add_noise(&self, t: u32, out: &mut Frame) {
        if self.noise == 0 {
            return;
        }
        let span = 2 * self.noise as u32 + 1;
        let w = out.width;
        for (k, px) in out.data.chunks_exact_mut(3).enumerate() {
            let (x, y) = (k as u32 % w, k as u32 / w);
            let r = hash(x, y, t);
            for (c, v) in px.iter_mut().enumerate() {
                let n = ((r >> (8 * c)) & 0xFF) % span;
                *v = (*v as i32 + n as i32 - self.noise as i32).clamp(0, 255) as u8;
            }
        }
    }
}

/// A saturated colour of hue sector `h` ∈ [0, 6) at value `v`.
fn hue_rgb(h: f32, v: f32) -> [u8; 3] {
    let f = h.fract();
    let (a, b) = ((v * (1.0 - f)) as u8, (v * f) as u8);
    let v = v as u8;
    match h as u32 {
        0 => [v, b, 0],
        1 => [a, v, 0],
        2 => [0, v, b],
        3 => [0, a, v],
        4 => [b, 0, v],
        _ => [v, 0, a],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn people_bounce_inside_the_frame_and_are_drawn() {
        let s = Scene::crowd(160, 120, 3);
        let mut f = Frame::new(1, 1, ClusterTime::ZERO);
        for t in [0, 37, 400] {
            s.render(t, &mut f);
            for i in 0..3 {
                let b = s.box_at(i, t);
                assert!(
                    b.xmin >= 0.0 && b.xmax <= 160.0 && b.ymin >= 0.0 && b.ymax <= 120.0,
                    "{b:?}"
                );
                let c = f.pixel(((b.xmin + b.xmax) / 2.0) as u32, (b.ymin + 2.0) as u32);
                let want = s.people[i].shirt;
                assert!(
                    (0..3).all(|k| c[k].abs_diff(want[k]) <= s.noise),
                    "{c:?} vs {want:?}"
                );
            }
        }
        assert_eq!(bounce(12.0, 10.0), 8.0);
        assert_eq!(bounce(-3.0, 10.0), 3.0);
    }
}
