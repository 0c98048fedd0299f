//! The Extended Information Filter on the 6-state constant-velocity model (paper 000 Fig. 4,
//! paper 002 §III), in information form.
//!
//! Prediction: Σ = Ω⁻¹ (Cholesky), Σ̄ = G Σ Gᵀ + R (symmetrized), Ω̄ = Σ̄⁻¹ (Cholesky),
//! μ̄ = g(μ), ξ̄ = Ω̄ μ̄. Update: Ω = Ω̄ + Σ Ω_i, ξ = ξ̄ + Σ ξ_i, the mean recovered by a Cholesky
//! solve (never an explicit inverse where a solve will do). Summation happens in an
//! [`Accumulator`] that allocates nothing, so the cost per contribution is a 6×6 add.

use nalgebra::{Cholesky, Matrix6, Vector6};
use proto::models::{Info, MotionModel, State};
use proto::msg::{Mat6, Vec6};
use thiserror::Error;

/// A numerical failure of the filter; the filter's state is left unchanged.
#[derive(Debug, Error, Clone, Copy, PartialEq, Eq)]
pub enum FilterError {
    #[error("{0} is not positive definite")]
    NotPositiveDefinite(&'static str),
    #[error("{0} is not finite")]
    NotFinite(&'static str),
}

/// Symmetrize in place: (M + Mᵀ) / 2.
pub fn symmetrize(m: &mut Matrix6<f64>) {
    for i in 0..6 {
        for j in (i + 1)..6 {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// The inverse of a symmetric positive-definite 6×6 matrix, symmetrized.
///
/// # Errors
/// [`FilterError::NotPositiveDefinite`] naming `what`.
pub fn spd_inverse(m: &Matrix6<f64>, what: &'static str) -> Result<Matrix6<f64>, FilterError> {
    let chol = Cholesky::new(*m).ok_or(FilterError::NotPositiveDefinite(what))?;
    let mut inv = chol.inverse();
    symmetrize(&mut inv);
    Ok(inv)
}

/// Running sum of information contributions for one step. `Copy`, no heap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accumulator {
    pub omega: Info,
    pub xi: State,
    /// Contributions summed.
    pub count: usize,
}

impl Default for Accumulator {
    fn default() -> Self {
        Accumulator {
            omega: Matrix6::zeros(),
            xi: Vector6::zeros(),
            count: 0,
        }
    }
}

impl Accumulator {
    pub fn clear(&mut self) {
        *self = Accumulator::default();
    }

    /// Add one contribution given as nalgebra values.
    pub fn add(&mut self, omega: &Info, xi: &State) {
        self.omega += omega;
        self.xi += xi;
        self.count += 1;
    }

    /// Add a pseudo-measurement (a prior on the state): information like any other, but not
    /// counted, so a step that had only this is still prediction only.
    pub fn add_prior(&mut self, omega: &Info, xi: &State) {
        self.omega += omega;
        self.xi += xi;
    }

    /// Add one contribution straight from its wire form (row-major), without conversion.
    pub fn add_wire(&mut self, omega: &Mat6, xi: &Vec6) {
        for (i, row) in omega.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                self.omega[(i, j)] += v;
            }
            self.xi[i] += xi[i];
        }
        self.count += 1;
    }
}

/// One track's filter.
#[derive(Clone, Debug, PartialEq)]
pub struct Eif {
    omega: Info,
    xi: State,
    mean: State,
    cov: Matrix6<f64>,
}

impl Eif {
    /// Start from a Gaussian in covariance form.
    ///
    /// # Errors
    /// A covariance that is not finite or not positive definite.
    pub fn from_gaussian(mean: State, cov: Matrix6<f64>) -> Result<Self, FilterError> {
        if mean.iter().chain(cov.iter()).any(|x| !x.is_finite()) {
            return Err(FilterError::NotFinite("initial gaussian"));
        }
        let mut cov = cov;
        symmetrize(&mut cov);
        let omega = spd_inverse(&cov, "initial covariance")?;
        Ok(Eif {
            xi: omega * mean,
            omega,
            mean,
            cov,
        })
    }

    /// Start from canonical parameters.
    ///
    /// # Errors
    /// Ω not positive definite.
    pub fn from_information(omega: Info, xi: State) -> Result<Self, FilterError> {
        let mut omega = omega;
        symmetrize(&mut omega);
        let chol = Cholesky::new(omega).ok_or(FilterError::NotPositiveDefinite("information matrix"))?;
        let mean = chol.solve(&xi);
        let mut cov = chol.inverse();
        symmetrize(&mut cov);
        Ok(Eif { omega, xi, mean, cov })
    }

    pub fn omega(&self) -> &Info {
        &self.omega
    }
    pub fn xi(&self) -> &State {
        &self.xi
    }
    /// μ (after an update) or μ̄ (after a prediction).
    pub fn mean(&self) -> &State {
        &self.mean
    }
    /// Σ = Ω⁻¹, kept alongside for priors, gating and reports.
    pub fn cov(&self) -> &Matrix6<f64> {
        &self.cov
    }

    /// The prediction of Fig. 4 lines 1–4 for a step of `dt` seconds.
    ///
    /// # Errors
    /// The predicted covariance is not positive definite; the filter is unchanged.
    pub fn predict(&mut self, motion: &MotionModel, dt: f64) -> Result<(), FilterError> {
        let next = self.predicted(motion, dt)?;
        *self = next;
        Ok(())
    }

    /// The prediction as a new filter, leaving `self` alone (activation looks one step ahead).
    ///
    /// # Errors
    /// As [`Eif::predict`].
    pub fn predicted(&self, motion: &MotionModel, dt: f64) -> Result<Eif, FilterError> {
        if !dt.is_finite() {
            return Err(FilterError::NotFinite("dt"));
        }
        let g = motion.transition(dt);
        let mut cov = g * self.cov * g.transpose() + motion.process_noise(dt);
        symmetrize(&mut cov);
        let omega = spd_inverse(&cov, "predicted covariance")?;
        let mean = g * self.mean;
        Ok(Eif {
            xi: omega * mean,
            omega,
            mean,
            cov,
        })
    }

    /// The update of Fig. 4 lines 5–6 with summed contributions. An empty accumulator is a
    /// prediction-only step and leaves the filter as it is.
    ///
    /// # Errors
    /// Ω + ΣΩ_i is not positive definite or not finite; the filter is unchanged.
    pub fn update(&mut self, acc: &Accumulator) -> Result<(), FilterError> {
        if acc.count == 0 {
            return Ok(());
        }
        let mut omega = self.omega + acc.omega;
        symmetrize(&mut omega);
        let xi = self.xi + acc.xi;
        if omega.iter().chain(xi.iter()).any(|x| !x.is_finite()) {
            return Err(FilterError::NotFinite("updated information"));
        }
        let chol = Cholesky::new(omega).ok_or(FilterError::NotPositiveDefinite("updated information"))?;
        let mean = chol.solve(&xi);
        let mut cov = chol.inverse();
        symmetrize(&mut cov);
        *self = Eif { omega, xi, mean, cov };
        Ok(())
    }

    /// Differential entropy up to a constant: −½ log|Ω|.
    pub fn entropy(&self) -> f64 {
        -0.5 * log_det_spd(&self.omega).unwrap_or(f64::NEG_INFINITY)
    }
}

/// log|M| of a symmetric positive-definite matrix via Cholesky.
pub fn log_det_spd(m: &Matrix6<f64>) -> Option<f64> {
    let chol = Cholesky::new(*m)?;
    let l = chol.l_dirty();
    Some((0..6).map(|i| 2.0 * l[(i, i)].ln()).sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn spd(seed: &[f64; 36], scale: f64) -> Matrix6<f64> {
        let a = Matrix6::from_column_slice(seed);
        a * a.transpose() * scale + Matrix6::identity() * 0.1
    }

    #[test]
    fn information_and_covariance_starts_agree() {
        let mean = State::new(1.0, 2.0, 0.5, 0.1, -0.2, 0.0);
        let cov = Matrix6::from_diagonal(&Vector6::new(0.5, 0.4, 0.1, 0.2, 0.2, 0.01));
        let a = Eif::from_gaussian(mean, cov).unwrap();
        let b = Eif::from_information(*a.omega(), *a.xi()).unwrap();
        assert_relative_eq!(a.mean(), b.mean(), epsilon = 1e-12);
        assert_relative_eq!(a.cov(), b.cov(), epsilon = 1e-12);
    }

    #[test]
    fn prediction_grows_uncertainty_and_moves_mean() {
        let mean = State::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        let mut f = Eif::from_gaussian(mean, Matrix6::identity() * 0.01).unwrap();
        let before = f.entropy();
        f.predict(&MotionModel::default(), 0.5).unwrap();
        assert!(f.entropy() > before);
        assert_relative_eq!(f.mean()[0], 0.5, epsilon = 1e-12);
        // ξ̄ = Ω̄ μ̄ holds.
        assert_relative_eq!(f.omega() * f.mean(), *f.xi(), epsilon = 1e-9);
    }

    #[test]
    fn empty_update_is_prediction_only() {
        let mut f = Eif::from_gaussian(State::zeros(), Matrix6::identity()).unwrap();
        let before = f.clone();
        f.update(&Accumulator::default()).unwrap();
        assert_eq!(f, before);
    }

    #[test]
    fn failed_update_leaves_state() {
        let mut f = Eif::from_gaussian(State::zeros(), Matrix6::identity()).unwrap();
        let before = f.clone();
        let mut acc = Accumulator::default();
        acc.add(&(Matrix6::identity() * -5.0), &State::zeros());
        assert_eq!(
            f.update(&acc),
            Err(FilterError::NotPositiveDefinite("updated information"))
        );
        assert_eq!(f, before);
    }

    #[test]
    fn wire_and_matrix_accumulation_agree() {
        let m = Matrix6::from_fn(|i, j| (i * 6 + j) as f64);
        let v = State::from_fn(|i, _| i as f64);
        let (mut a, mut b) = (Accumulator::default(), Accumulator::default());
        a.add(&m, &v);
        b.add_wire(&proto::models::mat6_to_wire(&m), &proto::models::vec6_to_wire(&v));
        assert_eq!(a, b);
    }

    proptest! {
        /// Adding information never increases entropy, and the posterior mean solves Ω μ = ξ.
        #[test]
        fn update_reduces_entropy(
            seed in proptest::array::uniform32(-1.0f64..1.0),
            extra in proptest::array::uniform4(-1.0f64..1.0),
        ) {
            let mut s = [0.0; 36];
            s[..32].copy_from_slice(&seed);
            s[32..].copy_from_slice(&extra);
            let prior = spd(&s, 1.0);
            let mut f = Eif::from_information(prior, State::from_fn(|i, _| s[i])).unwrap();
            let before = f.entropy();
            let mut acc = Accumulator::default();
            let mut t = s;
            t.reverse();
            acc.add(&spd(&t, 0.5), &State::from_fn(|i, _| t[i]));
            f.update(&acc).unwrap();
            prop_assert!(f.entropy() <= before + 1e-12);
            let resid = f.omega() * f.mean() - f.xi();
            prop_assert!(resid.norm() <= 1e-8 * (1.0 + f.xi().norm()));
        }
    }
}
