//! The acoustic likelihood over the grid (paper 001 eq. 16–18): a new ILD vector is
//! correlated with every fingerprint, and the correlations are interpolated over the cells
//! with cubic B-splines.
//!
//! The spline's basis weights depend only on where the cells sit on the survey lattice, so
//! [`AcousticSensor::new`] computes them once per grid column and row; each observation then
//! costs n correlations, the spline's prefilter over the lattice and a separable evaluation
//! (4 + 4 multiply-adds per cell). The paper's likelihood is the interpolated correlation
//! itself (`sharpness` 1) with the correlations as the spline's control points; a floor keeps
//! it positive (an interpolating spline may undershoot).

use super::GridError;
use super::layout::Grid;
use proto::acoustic::spline::{locate, mirror};
use proto::acoustic::{FingerprintDb, IldVector, SplineFit};

/// The acoustic model's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcousticParams {
    /// Exponent on the interpolated correlation (1 in the paper; larger trusts each frame more).
    pub sharpness: f64,
    /// Smallest likelihood value (spline undershoot below it is clamped).
    pub floor: f64,
    /// The correlations as the spline's control points (the paper) or interpolated.
    pub fit: SplineFit,
}

impl Default for AcousticParams {
    fn default() -> Self {
        AcousticParams {
            sharpness: 1.0,
            floor: 1e-6,
            fit: SplineFit::ControlPoints,
        }
    }
}

/// Spline taps of one grid column or row: the four lattice indices and their weights.
type Taps = ([usize; 4], [f64; 4]);

fn taps(lattice_nodes: usize, natural: f64) -> Taps {
    let (i, w) = locate(natural, lattice_nodes);
    let idx = [0, 1, 2, 3].map(|a| mirror(i - 1 + a as isize, lattice_nodes));
    (idx, w)
}

/// One acoustic node's fingerprints, prepared for a grid.
#[derive(Clone, Debug)]
pub struct AcousticSensor {
    db: FingerprintDb,
    params: AcousticParams,
    shape: (usize, usize),
    free: Vec<bool>,
    columns: Vec<Taps>,
    rows: Vec<Taps>,
}

impl AcousticSensor {
    /// # Errors
    /// A sharpness or floor that is not finite and positive.
    pub fn new(grid: &Grid, db: FingerprintDb, params: AcousticParams) -> Result<Self, GridError> {
        if !(params.sharpness.is_finite()
            && params.sharpness > 0.0
            && params.floor.is_finite()
            && params.floor > 0.0)
        {
            return Err(GridError::Invalid(format!(
                "acoustic parameters out of range: {params:?}"
            )));
        }
        let (nx, ny) = grid.shape();
        let lattice = db.lattice();
        let columns = (0..nx)
            .map(|i| taps(lattice.shape[0], lattice.natural(0, grid.centre(i, 0)[0])))
            .collect();
        let rows = (0..ny)
            .map(|j| taps(lattice.shape[1], lattice.natural(1, grid.centre(0, j)[1])))
            .collect();
        Ok(AcousticSensor {
            db,
            params,
            shape: (nx, ny),
            free: grid.free_mask().to_vec(),
            columns,
            rows,
        })
    }

    pub fn db(&self) -> &FingerprintDb {
        &self.db
    }

    /// l^a over the grid (eq. 17), floored and raised to the sharpness; zero on blocked cells.
    ///
    /// # Errors
    /// An ILD vector sampled at other frequencies than the fingerprints, or not finite.
    pub fn likelihood_map(&self, ild: &IldVector) -> Result<Vec<f64>, GridError> {
        let mut out = vec![1.0; self.shape.0 * self.shape.1];
        self.apply(ild, &mut out)?;
        Ok(out)
    }

    /// Multiply l^a into `likelihood` (eq. 12).
    ///
    /// # Errors
    /// As [`AcousticSensor::likelihood_map`], or a likelihood of another grid's size;
    /// `likelihood` is then unchanged.
    pub fn apply(&self, ild: &IldVector, likelihood: &mut [f64]) -> Result<(), GridError> {
        let (nx, ny) = self.shape;
        if likelihood.len() != nx * ny {
            return Err(GridError::Invalid(format!(
                "likelihood has {} cells, the acoustic grid {}",
                likelihood.len(),
                nx * ny
            )));
        }
        let surface = self.db.likelihood_surface(ild, self.params.fit)?;
        let lnx = surface.lattice.shape[0];
        let c = &surface.coefficients;
        // First along x for every lattice row, then along y.
        let lattice_rows = surface.lattice.shape[1];
        let mut along_x = vec![0.0; lattice_rows * nx];
        for r in 0..lattice_rows {
            let row = &c[r * lnx..(r + 1) * lnx];
            for (i, (idx, w)) in self.columns.iter().enumerate() {
                along_x[r * nx + i] = (0..4).map(|a| w[a] * row[idx[a]]).sum();
            }
        }
        let (floor, sharp) = (self.params.floor, self.params.sharpness);
        for (j, (idx, w)) in self.rows.iter().enumerate() {
            for i in 0..nx {
                let k = j * nx + i;
                if !self.free[k] {
                    likelihood[k] = 0.0;
                    continue;
                }
                let v: f64 = (0..4).map(|b| w[b] * along_x[idx[b] * nx + i]).sum();
                let v = v.max(floor);
                likelihood[k] *= if sharp == 1.0 { v } else { v.powf(sharp) };
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use proto::acoustic::{Fingerprint, IldSettings};
    use proto::scenario::World;

    #[test]
    fn grid_map_equals_the_spline_surface_and_peaks_at_the_source() {
        let world: World = toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [3.0, 2.0, 2.5]").unwrap();
        let settings = IldSettings {
            f_min_hz: 100.0,
            f_max_hz: 1600.0,
            frequencies: 16,
            ..IldSettings::default()
        };
        // Each frequency a plane wave across the room: every position its own ILD vector.
        let field = |x: f64, y: f64| -> Vec<f64> {
            (0..16)
                .map(|j| {
                    let a = j as f64 * 2.399;
                    (2.0 * (a.cos() * x + a.sin() * y) + 0.7 * j as f64).sin()
                })
                .collect()
        };
        let mut fps = Vec::new();
        for j in 0..4 {
            for i in 0..6 {
                let (x, y) = (0.25 + 0.5 * i as f64, 0.25 + 0.5 * j as f64);
                fps.push(Fingerprint {
                    position: [x, y],
                    values: field(x, y),
                });
            }
        }
        let db = FingerprintDb::new(&world, settings, fps).unwrap();
        let grid = Grid::new(&world, 0.1).unwrap();
        let ild = IldVector::new(db.frequencies().to_vec(), field(1.75, 1.25)).unwrap();
        for fit in [SplineFit::ControlPoints, SplineFit::Interpolating] {
            let params = AcousticParams {
                fit,
                ..AcousticParams::default()
            };
            let sensor = AcousticSensor::new(&grid, db.clone(), params).unwrap();
            let map = sensor.likelihood_map(&ild).unwrap();
            let surface = db.likelihood_surface(&ild, fit).unwrap();
            for (k, m) in map.iter().enumerate() {
                let [x, y] = grid.centre_of(k);
                assert_abs_diff_eq!(*m, surface.eval(x, y).max(1e-6), epsilon = 1e-12);
            }
            let best = (0..map.len()).max_by(|a, b| map[*a].total_cmp(&map[*b])).unwrap();
            let [bx, by] = grid.centre_of(best);
            assert!(
                (bx - 1.75).abs() <= 0.11 && (by - 1.25).abs() <= 0.11,
                "{fit:?}: peak at ({bx}, {by})"
            );
        }
        // Wrong frequencies are refused.
        let sensor = AcousticSensor::new(&grid, db, AcousticParams::default()).unwrap();
        let other = IldVector::new((1..=16).map(f64::from).collect(), vec![0.0; 16]).unwrap();
        assert!(sensor.likelihood_map(&other).is_err());
    }
}
