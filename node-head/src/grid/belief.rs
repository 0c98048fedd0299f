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
use super::convolve::Kernel;
use super::layout::Grid;
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

/// The belief over a grid.
#[derive(Clone, Debug)]
pub struct Belief {
    grid: Arc<Grid>,
    mass: Vec<f64>,
    /// The row pass's output.
    scratch: Vec<f64>,
    kernel: Option<Kernel>,
}

impl Belief {
    /// Uniform over the free cells (no prior knowledge).
    pub fn uniform(grid: Arc<Grid>) -> Belief {
        let mut b = Belief {
            mass: vec![0.0; grid.len()],
            scratch: vec![0.0; grid.len()],
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
        flush_negligible(&mut b.mass);
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
            self.kernel = Some(Kernel::new(&self.grid, sigma));
        }
        if let Some(kernel) = &self.kernel {
            kernel.apply(&self.grid, &mut self.mass, &mut self.scratch);
            flush_negligible(&mut self.mass);
        }
        Ok(())
    }

    /// Correction by a likelihood over the same grid (eq. 4–5, 8–9).
    ///
    /// # Errors
    /// A likelihood of another length, or a value that is negative or not finite; the belief
    /// is unchanged.
    pub fn correct(&mut self, likelihood: &[f64]) -> Result<Correction, GridError> {
        if likelihood.len() != self.grid.len() {
            check_likelihood(&self.grid, likelihood)?;
        }
        let (mut total, mut valid) = (0.0, true);
        for (m, l) in self.mass.iter().zip(likelihood) {
            valid &= l.is_finite() && *l >= 0.0;
            total += m * l;
        }
        if !valid {
            check_likelihood(&self.grid, likelihood)?;
        }
        if total.is_finite() && total > f64::MIN_POSITIVE {
            let inv = 1.0 / total;
            self.mass
                .iter_mut()
                .zip(likelihood)
                .for_each(|(m, l)| *m *= l * inv);
            flush_negligible(&mut self.mass);
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
        let cell = self.grid.cell();
        // Moments in cell units about cell (0, 0)'s centre, one pass.
        let (mut m0, mut mx, mut my, mut mxx, mut mxy, mut myy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut best, mut best_mass) = (0, f64::NEG_INFINITY);
        for (j, row) in self.mass.chunks_exact(nx).enumerate() {
            let y = j as f64;
            let (mut r0, mut rx, mut rxx) = (0.0, 0.0, 0.0);
            for (i, m) in row.iter().enumerate() {
                let x = i as f64;
                r0 += m;
                rx += m * x;
                rxx += m * x * x;
                if *m > best_mass {
                    best_mass = *m;
                    best = j * nx + i;
                }
            }
            m0 += r0;
            mx += rx;
            mxx += rxx;
            my += r0 * y;
            mxy += rx * y;
            myy += r0 * y * y;
        }
        let m0 = if m0 > 0.0 { m0 } else { 1.0 };
        let (ex, ey) = (mx / m0, my / m0);
        let var = |second: f64, a: f64, b: f64| (second / m0 - a * b) * cell * cell;
        let cell_var = cell * cell / 12.0;
        let [x0, y0] = self.grid.centre(0, 0);
        let cxy = var(mxy, ex, ey);
        Estimate {
            mean: [x0 + ex * cell, y0 + ey * cell],
            covariance: [
                [var(mxx, ex, ex).max(0.0) + cell_var, cxy],
                [cxy, var(myy, ey, ey).max(0.0) + cell_var],
            ],
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

/// Mass below this is set to zero: far below anything an estimate can show, and it keeps
/// subnormal numbers (tens of times slower to compute with) out of the arithmetic.
pub const NEGLIGIBLE_MASS: f64 = 1e-250;

fn flush_negligible(mass: &mut [f64]) {
    for m in mass {
        if *m < NEGLIGIBLE_MASS {
            *m = 0.0;
        }
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

#[cfg(test)]
mod tests;
