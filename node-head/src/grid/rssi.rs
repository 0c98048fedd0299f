//! The RSSI likelihood over the grid: a tag's reading at a node, through that node's model
//! (paper 002 eq. 2 or its trained linear form), as a Gaussian in dB around what the model
//! predicts at each cell's distance — the same model the EIFs linearize, used without
//! linearization.

use super::GridError;
use super::layout::Grid;
use nalgebra::Vector3;
use proto::models::RssiModel;

/// Multiply the likelihood of reading `dbm` at `node` into `likelihood`, the target at height
/// `target_z` over each free cell.
///
/// # Errors
/// A reading that is not finite, a model whose variance is not positive, or a likelihood of
/// another size; `likelihood` is then unchanged.
pub fn apply(
    grid: &Grid,
    node: &Vector3<f64>,
    model: &RssiModel,
    dbm: f64,
    target_z: f64,
    likelihood: &mut [f64],
) -> Result<(), GridError> {
    let exponent = log_factor(grid, node, model, dbm, target_z, likelihood.len())?;
    for (k, l) in likelihood.iter_mut().enumerate() {
        if grid.is_free(k) {
            *l *= exponent(k).exp();
        }
    }
    Ok(())
}

/// As [`apply`], in log space: add the log of the reading's likelihood to `log_likelihood` on
/// each free cell. Summed over many readings it stays finite where their product underflows
/// far from the tag (`crate::unseen::fix`).
///
/// # Errors
/// As [`apply`]; `log_likelihood` is then unchanged.
pub fn add_log(
    grid: &Grid,
    node: &Vector3<f64>,
    model: &RssiModel,
    dbm: f64,
    target_z: f64,
    log_likelihood: &mut [f64],
) -> Result<(), GridError> {
    let exponent = log_factor(grid, node, model, dbm, target_z, log_likelihood.len())?;
    for (k, l) in log_likelihood.iter_mut().enumerate() {
        if grid.is_free(k) {
            *l += exponent(k);
        }
    }
    Ok(())
}

/// The reading's log-likelihood (up to a constant) at cell `k`: a Gaussian in dB around what
/// the model predicts at the cell's distance; checks the reading, the model and the length.
fn log_factor<'a>(
    grid: &'a Grid,
    node: &'a Vector3<f64>,
    model: &'a RssiModel,
    dbm: f64,
    target_z: f64,
    len: usize,
) -> Result<impl Fn(usize) -> f64 + 'a, GridError> {
    let var = model.variance();
    if !(dbm.is_finite() && var.is_finite() && var > 0.0) {
        return Err(GridError::Invalid(format!(
            "RSSI reading {dbm} dBm with model variance {var} dB²"
        )));
    }
    if len != grid.len() {
        return Err(GridError::Invalid(format!(
            "likelihood has {len} cells, the grid {}",
            grid.len()
        )));
    }
    let inv = -0.5 / var;
    Ok(move |k: usize| {
        let [x, y] = grid.centre_of(k);
        let d = (Vector3::new(x, y, target_z) - node).norm().max(0.1);
        let r = dbm - model.predict(d);
        inv * r * r
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::scenario::World;

    #[test]
    fn the_likelihood_peaks_on_the_ring_the_model_predicts() {
        let world: World = toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [6.0, 6.0, 2.5]").unwrap();
        let grid = Grid::new(&world, 0.1).unwrap();
        let model = RssiModel::LogDistance {
            a: -22.0,
            b: -45.0,
            variance: 4.0,
        };
        let node = Vector3::new(0.0, 0.0, 0.5);
        // The reading the model predicts 3 m away.
        let dbm = model.predict(3.0);
        let mut l = vec![1.0; grid.len()];
        apply(&grid, &node, &model, dbm, 0.5, &mut l).unwrap();
        let best = (0..l.len()).max_by(|a, b| l[*a].total_cmp(&l[*b])).unwrap();
        let [x, y] = grid.centre_of(best);
        assert!(((x * x + y * y).sqrt() - 3.0).abs() < 0.1, "peak at ({x}, {y})");
        let near = grid.index_of(0.5, 0.5).unwrap();
        assert!(l[near] < 1e-3 * l[best]);
        assert!(apply(&grid, &node, &model, f64::NAN, 0.5, &mut l).is_err());
    }
}
