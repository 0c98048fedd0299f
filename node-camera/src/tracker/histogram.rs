//! Paper 004 §2.3: the colour model of a person. A box's HSV histogram — a 2D hue-saturation
//! histogram (10×10 bins) and a 1D value histogram (10 bins) — with every pixel weighted by the
//! kernel `k(r) = 1 − r²` of its distance from the box centre (eq. 4–5); the Bhattacharyya
//! similarity of two histograms on HS and on V, blended (70:30 in the paper), the distance
//! `d = √(1 − ρ)` and the Gaussian weight of eq. 6–8.
//!
//! Speed: a pixel's two bins come from a table over RGB quantized to 6 bits per channel, and
//! are looked up once per frame, only in the 16×16 tiles some box touches ([`BinImage`]). A
//! sample's histogram sums kernel weights over a regular sub-sampling grid of at most a given
//! number of pixels (the paper's "per particle subsampling size", §3.2.4).

use proto::sensor::{Frame, FrameError};

pub const HUE_BINS: usize = 10;
pub const SATURATION_BINS: usize = 10;
pub const VALUE_BINS: usize = 10;
/// Bins of the 2D hue-saturation histogram, hue-major.
pub const HS_BINS: usize = HUE_BINS * SATURATION_BINS;
/// All bins: HS first, then V (the paper's 10 × 10 + 10 = 110).
pub const BINS: usize = HS_BINS + VALUE_BINS;

/// Bits per channel of the RGB → bins table.
const TABLE_BITS: u32 = 6;
/// Side of the tiles whose bins are looked up together, pixels.
const TILE: usize = 16;

/// The HS bin (`hue_bin × SATURATION_BINS + saturation_bin`) and the V bin of an RGB colour,
/// from the hexcone HSV model: hue in [0°, 360°), saturation `(max − min) / max`, value `max`.
pub fn hsv_bins(rgb: [u8; 3]) -> (usize, usize) {
    let [r, g, b] = rgb.map(f32::from);
    let max = r.max(g).max(b);
    let delta = max - r.min(g).min(b);
    let hue = if delta <= 0.0 {
        0.0
    } else if max == r {
        let h = (g - b) / delta;
        60.0 * if h < 0.0 { h + 6.0 } else { h }
    } else if max == g {
        60.0 * ((b - r) / delta + 2.0)
    } else {
        60.0 * ((r - g) / delta + 4.0)
    };
    let saturation = if max > 0.0 { delta / max } else { 0.0 };
    let bin = |v: f32, n: usize| ((v * n as f32) as usize).min(n - 1);
    let hs = bin(hue / 360.0, HUE_BINS) * SATURATION_BINS + bin(saturation, SATURATION_BINS);
    (hs, bin(max / 256.0, VALUE_BINS))
}

/// The colour the tracker's bin table reads a pixel as: each channel at the centre of its
/// `TABLE_BITS` cell. The table is built through it, and whatever bins pixels as the filters
/// do (the background model's held colours) goes through it too.
pub fn table_colour(rgb: [u8; 3]) -> [u8; 3] {
    let shift = 8 - TABLE_BITS;
    rgb.map(|c| (c >> shift << shift) | (1 << (shift - 1)))
}

/// Kernel-weighted bin sums of one box, not yet normalized: each pixel adds its kernel weight
/// to one HS bin and one V bin, so both halves sum to `total`.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelCounts {
    pub bins: [f32; BINS],
    pub total: f32,
}

impl Default for KernelCounts {
    fn default() -> Self {
        KernelCounts {
            bins: [0.0; BINS],
            total: 0.0,
        }
    }
}

/// Per-pixel bins of the current frame, looked up lazily tile by tile. One per tracker; it
/// allocates when the frame size changes and never otherwise.
#[derive(Debug)]
pub struct BinImage {
    /// `[hs bin, HS_BINS + v bin]` per quantized RGB colour.
    table: Vec<[u8; 2]>,
    width: usize,
    height: usize,
    tiles_x: usize,
    bins: Vec<[u8; 2]>,
    /// The frame stamp each tile's bins were looked up for.
    stamps: Vec<u32>,
    stamp: u32,
}

impl Default for BinImage {
    fn default() -> Self {
        BinImage::new()
    }
}

impl BinImage {
    pub fn new() -> BinImage {
        let levels = 1usize << TABLE_BITS;
        let shift = 8 - TABLE_BITS;
        // The cell's lowest level; `table_colour` takes it to the cell's centre.
        let cell = |q: usize| (q << shift) as u8;
        let mut table = Vec::with_capacity(levels * levels * levels);
        for r in 0..levels {
            for g in 0..levels {
                for b in 0..levels {
                    let (hs, v) = hsv_bins(table_colour([cell(r), cell(g), cell(b)]));
                    table.push([hs as u8, (HS_BINS + v) as u8]);
                }
            }
        }
        BinImage {
            table,
            width: 0,
            height: 0,
            tiles_x: 0,
            bins: Vec::new(),
            stamps: Vec::new(),
            stamp: 0,
        }
    }

    /// Start measuring on `frame`: the bins of the previous frame become stale.
    ///
    /// # Errors
    /// A frame whose buffer does not fit its size ([`Frame::check`]); nothing changes then.
    pub fn bind<'a>(&'a mut self, frame: &'a Frame) -> Result<FrameBins<'a>, FrameError> {
        frame.check()?;
        let (w, h) = (frame.width as usize, frame.height as usize);
        if (w, h) != (self.width, self.height) {
            self.tiles_x = w.div_ceil(TILE);
            self.width = w;
            self.height = h;
            self.bins = vec![[0, 0]; w * h];
            self.stamps = vec![0; self.tiles_x * h.div_ceil(TILE)];
            self.stamp = 0;
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.stamps.fill(0);
            self.stamp = 1;
        }
        Ok(FrameBins { image: self, frame })
    }
}

/// A [`BinImage`] bound to one frame: histograms of boxes in it.
#[derive(Debug)]
pub struct FrameBins<'a> {
    image: &'a mut BinImage,
    frame: &'a Frame,
}

impl FrameBins<'_> {
    pub fn width(&self) -> usize {
        self.image.width
    }

    pub fn height(&self) -> usize {
        self.image.height
    }

    /// Look up the bins of every tile the pixel rectangle touches (inclusive bounds).
    fn ensure(&mut self, x0: usize, y0: usize, x1: usize, y1: usize) {
        let im = &mut *self.image;
        let data = &self.frame.data;
        let shift = 8 - TABLE_BITS;
        for ty in y0 / TILE..=y1 / TILE {
            for tx in x0 / TILE..=x1 / TILE {
                let t = ty * im.tiles_x + tx;
                if im.stamps[t] == im.stamp {
                    continue;
                }
                im.stamps[t] = im.stamp;
                let (xa, xb) = (tx * TILE, ((tx + 1) * TILE).min(im.width));
                for y in ty * TILE..((ty + 1) * TILE).min(im.height) {
                    let row = y * im.width;
                    let px = &data[(row + xa) * 3..(row + xb) * 3];
                    for (rgb, out) in px.chunks_exact(3).zip(&mut im.bins[row + xa..row + xb]) {
                        let i = ((rgb[0] as usize >> shift) << (2 * TABLE_BITS))
                            | ((rgb[1] as usize >> shift) << TABLE_BITS)
                            | (rgb[2] as usize >> shift);
                        *out = im.table[i];
                    }
                }
            }
        }
    }

    /// The kernel-weighted counts of the box with centre `centre` and half sizes `half`
    /// (pixels; pixel centres at integer coordinates), reading every `step`-th pixel of every
    /// `step`-th row of the part inside the frame. The kernel is eq. 4 with `r = |w − c| / a`,
    /// `a = √(hx² + hy²)` (eq. 5's bandwidth over the half sizes, so `r` reaches 1 at the
    /// corners). A box outside the frame gives zero counts.
    pub fn kernel_counts(&mut self, centre: [f32; 2], half: [f32; 2], step: usize, out: &mut KernelCounts) {
        out.bins = [0.0; BINS];
        out.total = 0.0;
        let [hx, hy] = half;
        let [cx, cy] = centre;
        if !(hx > 0.0 && hy > 0.0 && cx.is_finite() && cy.is_finite()) {
            return;
        }
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let (fx0, fx1) = ((cx - hx).ceil().max(0.0), (cx + hx).floor().min(w - 1.0));
        let (fy0, fy1) = ((cy - hy).ceil().max(0.0), (cy + hy).floor().min(h - 1.0));
        if fx0 > fx1 || fy0 > fy1 {
            return;
        }
        let (x0, x1, y0, y1) = (fx0 as usize, fx1 as usize, fy0 as usize, fy1 as usize);
        self.ensure(x0, y0, x1, y1);
        let inv_a2 = 1.0 / (hx * hx + hy * hy);
        let step = step.max(1);
        let width = self.image.width;
        let bins = &self.image.bins;
        let mut total = 0.0;
        for y in (y0..=y1).step_by(step) {
            let dy = y as f32 - cy;
            let base = 1.0 - dy * dy * inv_a2;
            let row = &bins[y * width..(y + 1) * width];
            for x in (x0..=x1).step_by(step) {
                let dx = x as f32 - cx;
                let k = (base - dx * dx * inv_a2).max(0.0);
                let [hs, v] = row[x];
                out.bins[hs as usize] += k;
                out.bins[v as usize] += k;
                total += k;
            }
        }
        out.total = total;
    }
}

/// Sub-sampling step so that a `w × h` box reads at most about `budget` pixels.
pub fn sampling_step(w: f32, h: f32, budget: u32) -> usize {
    let area = (w.max(1.0) * h.max(1.0)) as f64;
    ((area / budget.max(1) as f64).sqrt().ceil() as usize).max(1)
}

/// A normalized histogram: the HS bins sum to 1 and the V bins sum to 1 (eq. 5's `f`).
#[derive(Clone, Debug, PartialEq)]
pub struct ColourHistogram {
    bins: [f32; BINS],
}

impl ColourHistogram {
    /// Normalize kernel counts; `None` when the box had no weight (outside the frame).
    pub fn from_counts(counts: &KernelCounts) -> Option<ColourHistogram> {
        if !(counts.total > 0.0 && counts.total.is_finite()) {
            return None;
        }
        let f = 1.0 / counts.total;
        Some(ColourHistogram {
            bins: counts.bins.map(|c| c * f),
        })
    }

    /// All bins, HS (hue-major) then V.
    pub fn bins(&self) -> &[f32; BINS] {
        &self.bins
    }

    pub fn hs(&self) -> &[f32] {
        &self.bins[..HS_BINS]
    }

    pub fn value(&self) -> &[f32] {
        &self.bins[HS_BINS..]
    }

    /// Blended Bhattacharyya similarity (eq. 6 on HS and on V, `hs_weight : 1 − hs_weight`).
    pub fn similarity(&self, other: &ColourHistogram, hs_weight: f32) -> f32 {
        let rho = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(p, q)| (p * q).sqrt()).sum::<f32>();
        hs_weight * rho(self.hs(), other.hs()) + (1.0 - hs_weight) * rho(self.value(), other.value())
    }

    /// Eq. 9: `q ← α p + (1 − α) q`, for every bin.
    pub fn blend_towards(&mut self, p: &ColourHistogram, alpha: f32) {
        let alpha = alpha.clamp(0.0, 1.0);
        for (q, p) in self.bins.iter_mut().zip(&p.bins) {
            *q = alpha * p + (1.0 - alpha) * *q;
        }
    }
}

/// Eq. 7: the Bhattacharyya distance of a similarity.
pub fn bhattacharyya_distance(rho: f32) -> f32 {
    (1.0 - rho).max(0.0).sqrt()
}

/// Eq. 8: the observation probability of a sample at Bhattacharyya distance `d`.
pub fn observation_probability(d: f64, sigma: f64) -> f64 {
    (-d * d / (2.0 * sigma * sigma)).exp() / ((2.0 * std::f64::consts::PI).sqrt() * sigma)
}

/// The target histogram with its bins' square roots kept, so a sample's similarity costs one
/// square root per bin.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetHistogram {
    hist: ColourHistogram,
    sqrt: [f32; BINS],
}

impl TargetHistogram {
    pub fn new(hist: ColourHistogram) -> TargetHistogram {
        let sqrt = hist.bins.map(f32::sqrt);
        TargetHistogram { hist, sqrt }
    }

    pub fn histogram(&self) -> &ColourHistogram {
        &self.hist
    }

    /// Blended Bhattacharyya similarity of raw counts to the target (0 for empty counts).
    pub fn similarity(&self, counts: &KernelCounts, hs_weight: f32) -> f32 {
        if counts.total <= 0.0 {
            return 0.0;
        }
        let norm = 1.0 / counts.total.sqrt();
        let hs = sqrt_dot(&counts.bins[..HS_BINS], &self.sqrt[..HS_BINS]);
        let v = sqrt_dot(&counts.bins[HS_BINS..], &self.sqrt[HS_BINS..]);
        (hs_weight * hs + (1.0 - hs_weight) * v) * norm
    }

    /// Eq. 9 towards `p`, keeping the square roots.
    pub fn adapt(&mut self, p: &ColourHistogram, alpha: f32) {
        self.hist.blend_towards(p, alpha);
        self.sqrt = self.hist.bins.map(f32::sqrt);
    }
}

/// `Σ √c_b · s_b` in eight lanes (so the compiler vectorizes it).
fn sqrt_dot(c: &[f32], s: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (cc, sc) = (c.chunks_exact(8), s.chunks_exact(8));
    let (cr, sr) = (cc.remainder(), sc.remainder());
    for (a, b) in cc.zip(sc) {
        for l in 0..8 {
            acc[l] += a[l].sqrt() * b[l];
        }
    }
    let tail: f32 = cr.iter().zip(sr).map(|(a, b)| a.sqrt() * b).sum();
    acc.iter().sum::<f32>() + tail
}

#[cfg(test)]
mod tests;
