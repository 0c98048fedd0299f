//! The prediction's convolution (paper 001 eq. 7): a truncated Gaussian applied along rows,
//! then along columns, each pass confined to runs of connected free cells and reflected at
//! their ends.
//!
//! Speed: the bulk of each pass is a plain stencil over whole rows — `out += w_k · shifted
//! input`, which the compiler vectorises — computed as if there were no walls. Cells whose
//! window leaves their run (near a wall, a blocked cell or the outline) are listed once per
//! kernel and recomputed by a reflected gather that overwrites the stencil's value.

use super::layout::{Grid, Run};

/// The truncated Gaussian kernel for one σ (normalised to sum 1), and the cells whose
/// window leaves their run along x (`row_fix`) or y (`col_fix`).
#[derive(Clone, Debug)]
pub(crate) struct Kernel {
    pub sigma_m: f64,
    weights: Vec<f64>,
    radius: usize,
    row_fix: Vec<u32>,
    col_fix: Vec<u32>,
}

impl Kernel {
    pub fn new(grid: &Grid, sigma_m: f64) -> Kernel {
        let s = sigma_m / grid.cell();
        let radius = if s < 1e-3 { 0 } else { (3.0 * s).ceil() as usize };
        let weights = gaussian_weights(s, radius);
        let (nx, _) = grid.shape();
        let inside =
            |pos: usize, run: Run| run.lo as usize + radius <= pos && pos + radius <= run.hi as usize;
        let (mut row_fix, mut col_fix) = (Vec::new(), Vec::new());
        if radius > 0 {
            for k in 0..grid.len() {
                if !inside(k % nx, grid.row_run[k]) {
                    row_fix.push(k as u32);
                }
                if !inside(k / nx, grid.col_run[k]) {
                    col_fix.push(k as u32);
                }
            }
        }
        Kernel {
            sigma_m,
            weights,
            radius,
            row_fix,
            col_fix,
        }
    }

    /// Whether the kernel moves nothing (σ below a thousandth of a cell).
    pub fn is_identity(&self) -> bool {
        self.radius == 0
    }

    /// Convolve `mass` in place, using `scratch` (same length) for the row pass's output.
    pub fn apply(&self, grid: &Grid, mass: &mut [f64], scratch: &mut [f64]) {
        if self.is_identity() {
            return;
        }
        let (nx, ny) = grid.shape();
        let (r, w) = (self.radius, &self.weights[..]);
        // Rows: mass → scratch.
        for (src, dst) in mass.chunks_exact(nx).zip(scratch.chunks_exact_mut(nx)) {
            dst.fill(0.0);
            if nx > 2 * r {
                let body = &mut dst[r..nx - r];
                for (k, wk) in w.iter().enumerate() {
                    for (o, v) in body.iter_mut().zip(&src[k..k + nx - 2 * r]) {
                        *o += wk * v;
                    }
                }
            }
        }
        for &k in &self.row_fix {
            let k = k as usize;
            let (j, i) = (k / nx, k % nx);
            let run = grid.row_run[k];
            scratch[k] = gather(w, r, i, run, |m| mass[j * nx + m]);
        }
        // Columns: scratch → mass.
        mass.fill(0.0);
        if ny > 2 * r {
            for j in r..ny - r {
                let out = &mut mass[j * nx..(j + 1) * nx];
                for (k, wk) in w.iter().enumerate() {
                    let t = j + k - r;
                    for (o, v) in out.iter_mut().zip(&scratch[t * nx..(t + 1) * nx]) {
                        *o += wk * v;
                    }
                }
            }
        }
        for &k in &self.col_fix {
            let k = k as usize;
            let (j, i) = (k / nx, k % nx);
            let run = grid.col_run[k];
            mass[k] = gather(w, r, j, run, |m| scratch[m * nx + i]);
        }
    }
}

/// Normalised weights of a Gaussian of σ = `s` cells truncated at `radius`, widened so the
/// discrete kernel's variance is s² (truncation at 3σ alone loses 3 % of it).
fn gaussian_weights(s: f64, radius: usize) -> Vec<f64> {
    if radius == 0 {
        return vec![1.0];
    }
    let build = |width: f64| -> Vec<f64> {
        let mut w: Vec<f64> = (0..=2 * radius)
            .map(|k| {
                let d = k as f64 - radius as f64;
                (-0.5 * d * d / (width * width)).exp()
            })
            .collect();
        let total: f64 = w.iter().sum();
        w.iter_mut().for_each(|v| *v /= total);
        w
    };
    let variance = |w: &[f64]| -> f64 {
        w.iter()
            .enumerate()
            .map(|(k, v)| v * (k as f64 - radius as f64).powi(2))
            .sum()
    };
    // The variance grows with the width: bisect for the width that gives s².
    let (mut lo, mut hi) = (s, 4.0 * s);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if variance(&build(mid)) < s * s {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    build(0.5 * (lo + hi))
}

/// The kernel gathered at position `pos` of a line, reading `value(m)` for positions inside
/// `run`, reflected at its ends; 0 for a blocked cell (empty run).
fn gather(w: &[f64], r: usize, pos: usize, run: Run, value: impl Fn(usize) -> f64) -> f64 {
    let (lo, hi) = (run.lo as usize, run.hi as usize);
    if lo > hi {
        return 0.0;
    }
    let first = pos as isize - r as isize;
    if hi - lo < r {
        // A run shorter than the kernel: fold every tap.
        return w
            .iter()
            .enumerate()
            .map(|(k, wk)| wk * value(reflect(first + k as isize, lo, hi)))
            .sum();
    }
    // One reflection at most on each side: taps below `lo` mirror to 2 lo − 1 − m, taps
    // above `hi` to 2 hi + 1 − m, the rest read straight through.
    let mut acc = 0.0;
    for (k, wk) in w.iter().enumerate() {
        let m = first + k as isize;
        let idx = if m < lo as isize {
            (2 * lo as isize - 1 - m) as usize
        } else if m > hi as isize {
            (2 * hi as isize + 1 - m) as usize
        } else {
            m as usize
        };
        acc += wk * value(idx);
    }
    acc
}

/// Index `m` folded into `lo..=hi` by half-sample symmetric reflection
/// (`lo − 1 → lo`, `hi + 1 → hi`, repeatedly for a short run).
fn reflect(m: isize, lo: usize, hi: usize) -> usize {
    if m >= lo as isize && m <= hi as isize {
        return m as usize;
    }
    let len = (hi - lo + 1) as isize;
    let mut x = (m - lo as isize).rem_euclid(2 * len);
    if x >= len {
        x = 2 * len - 1 - x;
    }
    lo + x as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    use proptest::prelude::*;
    use proto::scenario::World;

    /// The plain definition: every cell gathers every tap, reflected within its run, rows
    /// then columns.
    fn reference(grid: &Grid, w: &[f64], r: usize, mass: &[f64]) -> Vec<f64> {
        let (nx, _) = grid.shape();
        let pass = |runs: &[Run], input: &[f64], along_x: bool| -> Vec<f64> {
            (0..input.len())
                .map(|k| {
                    let (j, i) = (k / nx, k % nx);
                    let (lo, hi) = (runs[k].lo as usize, runs[k].hi as usize);
                    if lo > hi {
                        return 0.0;
                    }
                    let pos = if along_x { i } else { j } as isize;
                    w.iter()
                        .enumerate()
                        .map(|(t, wt)| {
                            let m = reflect(pos + t as isize - r as isize, lo, hi);
                            wt * input[if along_x { j * nx + m } else { m * nx + i }]
                        })
                        .sum()
                })
                .collect()
        };
        let rows = pass(&grid.row_run, mass, true);
        pass(&grid.col_run, &rows, false)
    }

    proptest! {
        /// The stencil-plus-fix-up convolution equals the plain definition, for any walls,
        /// kernel width and belief.
        #[test]
        fn fast_convolution_equals_the_definition(
            values in proptest::collection::vec(0.0f64..1.0, 600),
            sigma in 0.05f64..1.5,
            wall in proptest::collection::vec(0.0f64..3.0, 4),
        ) {
            let world: World = toml::from_str(&format!(
                "min = [0.0, 0.0, 0.0]\nmax = [3.0, 2.0, 2.5]\nwalls = [{{ from = [{}, {}], to = [{}, {}], height = 2.0 }}]",
                wall[0], wall[1] * 0.66, wall[2], wall[3] * 0.66
            ))
            .unwrap();
            let grid = Grid::new(&world, 0.1).unwrap();
            let kernel = Kernel::new(&grid, sigma);
            let mut mass: Vec<f64> = (0..grid.len())
                .map(|k| if grid.is_free(k) { values[k % values.len()] } else { 0.0 })
                .collect();
            let want = reference(&grid, &kernel.weights, kernel.radius, &mass);
            let mut scratch = vec![0.0; mass.len()];
            kernel.apply(&grid, &mut mass, &mut scratch);
            for (a, b) in mass.iter().zip(&want) {
                prop_assert!((a - b).abs() < 1e-12, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn reflect_folds_at_both_ends() {
        assert_eq!(reflect(3, 2, 6), 3);
        assert_eq!(reflect(1, 2, 6), 2);
        assert_eq!(reflect(0, 2, 6), 3);
        assert_eq!(reflect(7, 2, 6), 6);
        assert_eq!(reflect(9, 2, 6), 4);
        // A one-cell run keeps everything.
        assert_eq!(reflect(-5, 4, 4), 4);
    }

    #[test]
    fn weights_have_the_walk_variance() {
        for s in [0.4f64, 1.0, 4.47, 10.0] {
            let r = (3.0 * s).ceil() as usize;
            let w = gaussian_weights(s, r);
            let total: f64 = w.iter().sum();
            let var: f64 = w
                .iter()
                .enumerate()
                .map(|(k, v)| v * (k as f64 - r as f64).powi(2))
                .sum();
            assert!((total - 1.0).abs() < 1e-12);
            assert!((var - s * s).abs() < 1e-5 * s * s, "σ {s}: variance {var}");
        }
    }
}
