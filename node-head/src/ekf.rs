//! A covariance-form Extended Kalman Filter on the same models, kept as the cross-check of the
//! information filter (they must agree to 1e-9 on the same inputs) and as the reference cost
//! in `ocelli bench head`: its update solves with the stacked innovation covariance, so it
//! grows with the cube of the measurement size where the EIF's sum grows linearly.

use crate::eif::{FilterError, symmetrize};
use nalgebra::{Cholesky, DMatrix, DVector, Matrix6};
use proto::models::{MotionModel, State};

/// One sensor's linearized measurement: z, h(μ̄), H (m×6) and Q (m×m).
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    pub z: DVector<f64>,
    pub predicted: DVector<f64>,
    pub jac: DMatrix<f64>,
    pub noise: DMatrix<f64>,
}

/// Mean and covariance.
#[derive(Clone, Debug, PartialEq)]
pub struct Ekf {
    pub mean: State,
    pub cov: Matrix6<f64>,
}

impl Ekf {
    pub fn new(mean: State, cov: Matrix6<f64>) -> Self {
        Ekf { mean, cov }
    }

    pub fn predict(&mut self, motion: &MotionModel, dt: f64) {
        let g = motion.transition(dt);
        self.mean = g * self.mean;
        self.cov = g * self.cov * g.transpose() + motion.process_noise(dt);
        symmetrize(&mut self.cov);
    }

    /// Batch update with every block stacked (Joseph form for the covariance).
    ///
    /// # Errors
    /// The innovation covariance is not positive definite; the filter is unchanged.
    pub fn update(&mut self, blocks: &[Block]) -> Result<(), FilterError> {
        let m: usize = blocks.iter().map(|b| b.z.len()).sum();
        if m == 0 {
            return Ok(());
        }
        let mut h = DMatrix::zeros(m, 6);
        let mut q = DMatrix::zeros(m, m);
        let mut nu = DVector::zeros(m);
        let mut row = 0;
        for b in blocks {
            let k = b.z.len();
            h.view_mut((row, 0), (k, 6)).copy_from(&b.jac);
            q.view_mut((row, row), (k, k)).copy_from(&b.noise);
            nu.rows_mut(row, k).copy_from(&(&b.z - &b.predicted));
            row += k;
        }
        let sigma = DMatrix::from_column_slice(6, 6, self.cov.as_slice());
        let s = &h * &sigma * h.transpose() + &q;
        let chol = Cholesky::new(s).ok_or(FilterError::NotPositiveDefinite("innovation covariance"))?;
        // K = Σ Hᵀ S⁻¹ = (S⁻¹ H Σ)ᵀ.
        let gain = chol.solve(&(&h * &sigma)).transpose();
        let dx = &gain * nu;
        let i_kh = DMatrix::identity(6, 6) - &gain * &h;
        let cov = &i_kh * &sigma * i_kh.transpose() + &gain * q * gain.transpose();
        for i in 0..6 {
            self.mean[i] += dx[i];
        }
        self.cov = Matrix6::from_fn(|i, j| cov[(i, j)]);
        symmetrize(&mut self.cov);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn direct_position_measurement_halves_variance() {
        let mut f = Ekf::new(State::zeros(), Matrix6::identity());
        let mut jac = DMatrix::zeros(1, 6);
        jac[(0, 0)] = 1.0;
        f.update(&[Block {
            z: DVector::from_element(1, 2.0),
            predicted: DVector::from_element(1, 0.0),
            jac,
            noise: DMatrix::identity(1, 1),
        }])
        .unwrap();
        assert_relative_eq!(f.mean[0], 1.0, epsilon = 1e-12);
        assert_relative_eq!(f.cov[(0, 0)], 0.5, epsilon = 1e-12);
        assert_relative_eq!(f.cov[(1, 1)], 1.0, epsilon = 1e-12);
    }
}
