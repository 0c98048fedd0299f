//! The belief of paper 001's grid-based recursive Bayesian estimator (§2.2–2.4) and its two
//! steps.
//!
//! - Prediction (eq. 1, 3, 7): the belief convolved with the random-walk motion kernel, a
//!   Gaussian of σ = q·√dt per axis, truncated at 3σ, applied separably — along every row, then
//!   along every column. Each pass moves belief only within a run of connected free cells
//!   ([`Grid`]); at a run's ends (a wall, a blocked cell, the outline) the kernel reflects
//!   (half-sample symmetric extension). With a symmetric kernel that makes each pass a
//!   symmetric, doubly stochastic matrix: mass is conserved exactly, a uniform belief stays
//!   uniform (walls neither attract nor repel), and belief never crosses a wall in one step —
//!   a target walks around a wall's end, not through it.
//! - Correction (eq. 4–5, 8–9): the prior times the likelihood, normalised. If that product
//!   vanishes (or underflows) everywhere, the belief restarts from the likelihood alone over
//!   the free cells, or from uniform if that is zero too, and the step says so
//!   ([`Correction`]). The belief is never NaN.
//!
//! The belief is kept as probability mass per cell (summing to 1); a density is mass / cell².

use super::GridError;
use super::layout::{Grid, Run};
use serde::Serialize;
use std::sync::Arc;

/// Random-walk motion (paper 001 §4.2.2): each axis diffuses as σ = `sigma_per_sqrt_s`·√dt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RandomWalk {
    /// Diffusion, m/√s (a person wandering: about 0.5–1).
    pub sigma_per_sqrt_s: f64,
}

/// How a correction went.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Correction {
    /// Prior × likelihood, normalised.
    Applied,
    /// The product vanished everywhere: restarted from the likelihood alone.
    ResetToLikelihood,
    /// The likelihood was zero on every free cell too: restarted uniform.
    ResetToUniform,
}

/// The belief's summary each step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Estimate {
    /// Mean `[x, y]`, metres.
    pub mean: [f64; 2],
    /// 2×2 covariance, m², including each cell's own spread (cell²/12 per axis).
    pub covariance: [[f64; 2]; 2],
    /// Centre `[x, y]` of the most likely cell, and its `(i, j)`.
    pub most_likely: [f64; 2],
    pub most_likely_cell: (usize, usize),
}

impl Estimate {
    /// √(trace Σ): the RMS distance of the target from the mean, metres.
    pub fn sigma_m(&self) -> f64 {
        (self.covariance[0][0] + self.covariance[1][1]).max(0.0).sqrt()
    }
}

/// The grid itself, for a heat map or a recording: probability mass per cell, row-major
/// (x fastest), `ny` rows of `nx`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeatMap {
    pub origin: [f64; 2],
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
    pub values: Vec<f32>,
}

/// The truncated Gaussian kernel for one σ, normalised to sum 1.
#[derive(Clone, Debug)]
struct Kernel {
    sigma_m: f64,
    weights: Vec<f64>,
    radius: usize,
}

impl Kernel {
    fn new(cell: f64, sigma_m: f64) -> Kernel {
        let s = sigma_m / cell;
        let radius = if s < 1e-3 { 0 } else { (3.0 * s).ceil() as usize };
        let build = |width: f64| -> Vec<f64> {
            let mut w: Vec<f64> = (0..=2 * radius)
                .map(|k| {
                    let d = k as f64 - radius as f64;
                    if radius == 0 {
                        1.0
                    } else {
                        (-0.5 * d * d / (width * width)).exp()
                    }
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
        // Truncation at 3σ and sampling lose variance (3 % at 3σ); widen the Gaussian until
        // the discrete kernel's variance is the random walk's, q² dt.
        let mut width = s.max(1e-3);
        let mut weights = build(width);
        for _ in 0..6 {
            let v = variance(&weights);
            if radius == 0 || v <= 0.0 || (v - s * s).abs() <= 1e-6 * s * s {
                break;
            }
            width *= (s * s / v).sqrt().min(2.0);
            weights = build(width);
        }
        Kernel {
            sigma_m,
            weights,
            radius,
        }
    }
}

/// The belief over a grid.
#[derive(Clone, Debug)]
pub struct Belief {
    grid: Arc<Grid>,
    mass: Vec<f64>,
    /// The row pass's output, and the column pass's input and output, transposed.
    scratch: Vec<f64>,
    transposed: Vec<f64>,
    kernel: Option<Kernel>,
}

impl Belief {
    /// Uniform over the free cells (no prior knowledge).
    pub fn uniform(grid: Arc<Grid>) -> Belief {
        let mut b = Belief {
            mass: vec![0.0; grid.len()],
            scratch: vec![0.0; grid.len()],
            transposed: vec![0.0; grid.len()],
            grid,
            kernel: None,
        };
        b.reset_uniform();
        b
    }

    /// An isotropic Gaussian around `mean` (σ metres) over the free cells; uniform if it
    /// puts no mass on any free cell.
    pub fn gaussian(grid: Arc<Grid>, mean: [f64; 2], sigma: f64) -> Belief {
        let mut b = Belief::uniform(grid);
        let s2 = (sigma * sigma).max(1e-12);
        for k in 0..b.mass.len() {
            if b.grid.is_free(k) {
                let [x, y] = b.grid.centre_of(k);
                let d2 = (x - mean[0]).powi(2) + (y - mean[1]).powi(2);
                b.mass[k] = (-0.5 * d2 / s2).exp();
            } else {
                b.mass[k] = 0.0;
            }
        }
        if !b.normalise() {
            b.reset_uniform();
        }
        b
    }

    pub fn grid(&self) -> &Arc<Grid> {
        &self.grid
    }

    /// Probability mass per cell, row-major; zero on blocked cells; sums to 1.
    pub fn mass(&self) -> &[f64] {
        &self.mass
    }

    fn reset_uniform(&mut self) {
        let u = 1.0 / self.grid.free_count() as f64;
        for (k, m) in self.mass.iter_mut().enumerate() {
            *m = if self.grid.is_free(k) { u } else { 0.0 };
        }
    }

    /// Divide by the total; false (and nothing changed) when it is not positive and finite.
    fn normalise(&mut self) -> bool {
        let total: f64 = self.mass.iter().sum();
        if !(total.is_finite() && total > f64::MIN_POSITIVE) {
            return false;
        }
        let inv = 1.0 / total;
        self.mass.iter_mut().for_each(|m| *m *= inv);
        true
    }

    /// Prediction over `dt` seconds (eq. 3, 7).
    ///
    /// # Errors
    /// A `dt` or diffusion that is negative or not finite; the belief is unchanged.
    pub fn predict(&mut self, motion: &RandomWalk, dt: f64) -> Result<(), GridError> {
        let q = motion.sigma_per_sqrt_s;
        if !(dt.is_finite() && dt >= 0.0 && q.is_finite() && q >= 0.0) {
            return Err(GridError::Invalid(format!(
                "prediction over dt = {dt} s with diffusion {q} m/√s"
            )));
        }
        let sigma = q * dt.sqrt();
        if self.kernel.as_ref().is_none_or(|k| k.sigma_m != sigma) {
            self.kernel = Some(Kernel::new(self.grid.cell(), sigma));
        }
        let Some(kernel) = self.kernel.as_ref() else {
            return Ok(());
        };
        if kernel.radius == 0 {
            return Ok(());
        }
        let (nx, ny) = self.grid.shape();
        convolve_lines(nx, &self.grid.row_run, kernel, &self.mass, &mut self.scratch);
        transpose(nx, ny, &self.scratch, &mut self.transposed);
        convolve_lines(
            ny,
            &self.grid.col_run_t,
            kernel,
            &self.transposed,
            &mut self.scratch,
        );
        transpose(ny, nx, &self.scratch, &mut self.mass);
        Ok(())
    }

    /// Correction by a likelihood over the same grid (eq. 4–5, 8–9).
    ///
    /// # Errors
    /// A likelihood of another length, or a value that is negative or not finite; the belief
    /// is unchanged.
    pub fn correct(&mut self, likelihood: &[f64]) -> Result<Correction, GridError> {
        check_likelihood(&self.grid, likelihood)?;
        let total: f64 = self.mass.iter().zip(likelihood).map(|(m, l)| m * l).sum();
        if total.is_finite() && total > f64::MIN_POSITIVE {
            let inv = 1.0 / total;
            self.mass
                .iter_mut()
                .zip(likelihood)
                .for_each(|(m, l)| *m *= l * inv);
            return Ok(Correction::Applied);
        }
        for (k, (m, l)) in self.mass.iter_mut().zip(likelihood).enumerate() {
            *m = if self.grid.is_free(k) { *l } else { 0.0 };
        }
        if self.normalise() {
            Ok(Correction::ResetToLikelihood)
        } else {
            self.reset_uniform();
            Ok(Correction::ResetToUniform)
        }
    }

    /// Mean, covariance and most likely cell.
    pub fn estimate(&self) -> Estimate {
        let (nx, _) = self.grid.shape();
        let (mut sx, mut sy, mut best) = (0.0, 0.0, 0);
        for (k, m) in self.mass.iter().enumerate() {
            if *m > 0.0 {
                let [x, y] = self.grid.centre_of(k);
                sx += m * x;
                sy += m * y;
                if *m > self.mass[best] {
                    best = k;
                }
            }
        }
        let (mut cxx, mut cxy, mut cyy) = (0.0, 0.0, 0.0);
        for (k, m) in self.mass.iter().enumerate() {
            if *m > 0.0 {
                let [x, y] = self.grid.centre_of(k);
                let (dx, dy) = (x - sx, y - sy);
                cxx += m * dx * dx;
                cxy += m * dx * dy;
                cyy += m * dy * dy;
            }
        }
        let cell_var = self.grid.cell().powi(2) / 12.0;
        Estimate {
            mean: [sx, sy],
            covariance: [[cxx + cell_var, cxy], [cxy, cyy + cell_var]],
            most_likely: self.grid.centre_of(best),
            most_likely_cell: (best % nx, best / nx),
        }
    }

    /// The grid as `f32` mass per cell.
    pub fn heat_map(&self) -> HeatMap {
        let (nx, ny) = self.grid.shape();
        HeatMap {
            origin: self.grid.origin(),
            cell: self.grid.cell(),
            nx,
            ny,
            values: self.mass.iter().map(|m| *m as f32).collect(),
        }
    }

    /// Differential entropy of the belief as a piecewise-constant density, nats:
    /// −Σ p ln(p / cell²).
    pub fn differential_entropy(&self) -> f64 {
        let area = self.grid.cell().powi(2);
        -self
            .mass
            .iter()
            .filter(|m| **m > 0.0)
            .map(|m| m * (m / area).ln())
            .sum::<f64>()
    }
}

/// A likelihood must cover the grid with finite values ≥ 0.
///
/// # Errors
/// The first violation.
pub fn check_likelihood(grid: &Grid, likelihood: &[f64]) -> Result<(), GridError> {
    if likelihood.len() != grid.len() {
        return Err(GridError::Invalid(format!(
            "likelihood has {} cells, the grid {}",
            likelihood.len(),
            grid.len()
        )));
    }
    if let Some((k, l)) = likelihood
        .iter()
        .enumerate()
        .find(|(_, l)| !(l.is_finite() && **l >= 0.0))
    {
        return Err(GridError::Invalid(format!(
            "likelihood at cell {k} is {l}, not a finite value ≥ 0"
        )));
    }
    Ok(())
}

/// One separable pass over consecutive lines of `len` cells: each cell gathers the kernel
/// over its run, reflected at the run's ends.
fn convolve_lines(len: usize, runs: &[Run], kernel: &Kernel, input: &[f64], out: &mut [f64]) {
    let r = kernel.radius;
    let w = &kernel.weights[..];
    for ((line_in, line_out), line_runs) in input
        .chunks_exact(len)
        .zip(out.chunks_exact_mut(len))
        .zip(runs.chunks_exact(len))
    {
        for (i, (o, run)) in line_out.iter_mut().zip(line_runs).enumerate() {
            let (lo, hi) = (run.lo as usize, run.hi as usize);
            if lo > hi {
                *o = 0.0;
            } else if i >= lo + r && i + r <= hi {
                let window = &line_in[i - r..=i + r];
                *o = w.iter().zip(window).map(|(a, b)| a * b).sum();
            } else {
                let mut acc = 0.0;
                for (k, wk) in w.iter().enumerate() {
                    acc += wk * line_in[reflect(i as isize + k as isize - r as isize, lo, hi)];
                }
                *o = acc;
            }
        }
    }
}

/// Index `m` folded into `lo..=hi` by half-sample symmetric reflection
/// (`lo − 1 → lo`, `hi + 1 → hi`, repeatedly for a short run).
fn reflect(m: isize, lo: usize, hi: usize) -> usize {
    let len = (hi - lo + 1) as isize;
    let mut x = (m - lo as isize).rem_euclid(2 * len);
    if x >= len {
        x = 2 * len - 1 - x;
    }
    lo + x as usize
}

/// `out` (cols × rows) = transpose of `input` (rows × cols, `cols` per row).
fn transpose(cols: usize, rows: usize, input: &[f64], out: &mut [f64]) {
    for (j, row) in input.chunks_exact(cols).enumerate().take(rows) {
        for (i, v) in row.iter().enumerate() {
            out[i * rows + j] = *v;
        }
    }
}

#[cfg(test)]
mod tests;
