//! Cubic B-spline interpolation of values known on a regular lattice of survey positions
//! (paper 001 eq. 17–18): l(x) = Σ_i μ_i(ξ) c_i with μ_i(ξ) = μ¹(ξ − i_ξ) μ²(η − i_η), the
//! uniform cubic B-spline in each natural coordinate.
//!
//! The paper uses T-splines over a T-mesh; on a regular lattice a T-spline is a tensor-product
//! B-spline, which is what this is. Two ways to set the control coefficients c:
//! [`SplineSurface::from_control_points`] takes the values themselves (eq. 17 as printed:
//! smoothing, within the values' range), [`SplineSurface::interpolate`] solves for c so the
//! surface passes through the values at the lattice nodes (the tridiagonal (1, 4, 1)/6 system
//! per axis, mirror boundaries). Either surface is C² between knots. Outside the lattice the
//! natural coordinates are clamped to its edge.

use super::{AcousticError, invalid};
use serde::{Deserialize, Serialize};

/// Most lattice nodes a survey may span.
pub const MAX_LATTICE_NODES: usize = 250_000;

/// A regular lattice of survey positions: node `(i, j)` is at `origin + (i·dx, j·dy)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Lattice {
    pub origin: [f64; 2],
    pub spacing: [f64; 2],
    /// `[nx, ny]`.
    pub shape: [usize; 2],
}

impl Lattice {
    /// The smallest regular lattice whose nodes hold every position (within `tolerance`
    /// metres), and the node index of each position. A single column or row is a 1-D lattice.
    ///
    /// # Errors
    /// No positions, non-finite ones, positions that no regular spacing explains, two
    /// positions at one node, or a lattice of more than [`MAX_LATTICE_NODES`] nodes.
    pub fn fit(positions: &[[f64; 2]], tolerance: f64) -> Result<(Lattice, Vec<usize>), AcousticError> {
        if positions.is_empty() {
            return Err(AcousticError::Lattice("no positions".into()));
        }
        if let Some(p) = positions.iter().find(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return Err(AcousticError::Lattice(format!("position {p:?} is not finite")));
        }
        let mut origin = [0.0; 2];
        let mut spacing = [1.0; 2];
        let mut shape = [1; 2];
        for axis in 0..2 {
            let mut xs: Vec<f64> = positions.iter().map(|p| p[axis]).collect();
            xs.sort_by(f64::total_cmp);
            xs.dedup_by(|b, a| (*b - *a).abs() <= tolerance);
            origin[axis] = xs[0];
            if xs.len() > 1 {
                let min_gap = xs.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
                // The spacing is the smallest gap or a fraction of it (0, 0.8, 2.0 → 0.4), but
                // never so fine that the tolerance would let any position fit.
                let fits = |d: f64| {
                    d >= 10.0 * tolerance
                        && xs.iter().all(|x| {
                            let k = ((x - xs[0]) / d).round();
                            (xs[0] + k * d - x).abs() <= tolerance
                        })
                };
                let d = (1..=8)
                    .map(|k| min_gap / k as f64)
                    .find(|d| fits(*d))
                    .unwrap_or(min_gap);
                spacing[axis] = d;
                let last = ((xs[xs.len() - 1] - xs[0]) / d).round();
                if last + 1.0 > MAX_LATTICE_NODES as f64 {
                    return Err(AcousticError::Lattice(format!(
                        "a spacing of {d} m over {} m needs more than {MAX_LATTICE_NODES} nodes",
                        xs[xs.len() - 1] - xs[0]
                    )));
                }
                shape[axis] = last as usize + 1;
            }
        }
        if shape[0] * shape[1] > MAX_LATTICE_NODES {
            return Err(AcousticError::Lattice(format!(
                "{}×{} lattice nodes, at most {MAX_LATTICE_NODES}",
                shape[0], shape[1]
            )));
        }
        let lattice = Lattice {
            origin,
            spacing,
            shape,
        };
        let mut taken = vec![false; shape[0] * shape[1]];
        let mut nodes = Vec::with_capacity(positions.len());
        for p in positions {
            let node = lattice.node_of(p, tolerance).ok_or_else(|| {
                AcousticError::Lattice(format!(
                    "({}, {}) is not on the regular lattice from ({}, {}) with spacing ({}, {}) m \
                     that the other positions form: survey on a regular grid",
                    p[0], p[1], origin[0], origin[1], spacing[0], spacing[1]
                ))
            })?;
            if std::mem::replace(&mut taken[node], true) {
                return Err(AcousticError::Lattice(format!(
                    "two fingerprints at ({}, {})",
                    p[0], p[1]
                )));
            }
            nodes.push(node);
        }
        Ok((lattice, nodes))
    }

    fn node_of(&self, p: &[f64; 2], tolerance: f64) -> Option<usize> {
        let mut idx = [0usize; 2];
        for axis in 0..2 {
            let k = ((p[axis] - self.origin[axis]) / self.spacing[axis]).round();
            let on = self.origin[axis] + k * self.spacing[axis];
            if (on - p[axis]).abs() > tolerance || k < 0.0 || k as usize >= self.shape[axis] {
                return None;
            }
            idx[axis] = k as usize;
        }
        Some(idx[1] * self.shape[0] + idx[0])
    }

    pub fn len(&self) -> usize {
        self.shape[0] * self.shape[1]
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// World position of node `index` (row-major, x fastest).
    pub fn node_position(&self, index: usize) -> [f64; 2] {
        let (i, j) = (index % self.shape[0], index / self.shape[0]);
        [
            self.origin[0] + i as f64 * self.spacing[0],
            self.origin[1] + j as f64 * self.spacing[1],
        ]
    }

    /// Natural coordinate (ξ or η) of a world coordinate along `axis`, clamped to the lattice.
    pub fn natural(&self, axis: usize, x: f64) -> f64 {
        let n = self.shape[axis];
        if n == 1 {
            return 0.0;
        }
        ((x - self.origin[axis]) / self.spacing[axis]).clamp(0.0, (n - 1) as f64)
    }
}

/// The four uniform cubic B-spline basis values for coefficients `i−1, i, i+1, i+2` at
/// fractional position `t ∈ [0, 1]` past node `i`. They sum to 1.
pub fn cubic_bspline_weights(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    let u = 1.0 - t;
    [
        u * u * u / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ]
}

/// Node index `k` of an axis of `n` nodes, mirrored at the ends (`−1 → 1`, `n → n − 2`).
pub fn mirror(k: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let last = n as isize - 1;
    let period = 2 * last;
    let mut k = k.rem_euclid(period);
    if k > last {
        k = period - k;
    }
    k as usize
}

/// Where a natural coordinate falls: the node `i` to its left and the four basis weights.
pub fn locate(xi: f64, n: usize) -> (isize, [f64; 4]) {
    if n == 1 {
        return (0, [0.0, 1.0, 0.0, 0.0]);
    }
    let i = (xi.floor() as isize).clamp(0, n as isize - 2);
    (i, cubic_bspline_weights(xi - i as f64))
}

/// Solve (c_{i−1} + 4 c_i + c_{i+1}) / 6 = v_i with mirror ends, in place (Thomas algorithm).
fn prefilter(v: &mut [f64], scratch: &mut Vec<f64>) {
    let n = v.len();
    if n < 2 {
        return;
    }
    // Row 0: (4 c0 + 2 c1)/6; rows 1..n−1: (c + 4c + c)/6; row n−1: (2 c_{n−2} + 4 c_{n−1})/6.
    scratch.clear();
    scratch.resize(n, 0.0);
    let upper = |i: usize| if i == 0 { 2.0 / 6.0 } else { 1.0 / 6.0 };
    let lower = |i: usize| if i == n - 1 { 2.0 / 6.0 } else { 1.0 / 6.0 };
    let diag = 4.0 / 6.0;
    let mut denom = diag;
    scratch[0] = upper(0) / denom;
    v[0] /= denom;
    for i in 1..n {
        denom = diag - lower(i) * scratch[i - 1];
        scratch[i] = if i + 1 < n { upper(i) / denom } else { 0.0 };
        v[i] = (v[i] - lower(i) * v[i - 1]) / denom;
    }
    for i in (0..n - 1).rev() {
        v[i] -= scratch[i] * v[i + 1];
    }
}

/// An interpolating tensor-product cubic B-spline over a lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct SplineSurface {
    pub lattice: Lattice,
    /// Control coefficients, row-major like the lattice.
    pub coefficients: Vec<f64>,
}

impl SplineSurface {
    /// The surface through `values` (one per lattice node, row-major, x fastest).
    ///
    /// # Errors
    /// A count that is not the lattice's, or non-finite values.
    pub fn interpolate(lattice: &Lattice, values: &[f64]) -> Result<Self, AcousticError> {
        let [nx, ny] = lattice.shape;
        if values.len() != nx * ny {
            return Err(invalid(
                "spline values",
                format!("{} values for a {nx}×{ny} lattice", values.len()),
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(invalid("spline values", format!("{v} is not finite")));
        }
        let mut c = values.to_vec();
        let mut scratch = Vec::new();
        for row in c.chunks_mut(nx) {
            prefilter(row, &mut scratch);
        }
        let mut column = vec![0.0; ny];
        for i in 0..nx {
            for j in 0..ny {
                column[j] = c[j * nx + i];
            }
            prefilter(&mut column, &mut scratch);
            for j in 0..ny {
                c[j * nx + i] = column[j];
            }
        }
        Ok(SplineSurface {
            lattice: lattice.clone(),
            coefficients: c,
        })
    }

    /// The surface Σ_i μ_i(ξ) v_i with the values themselves as control coefficients — eq. 17
    /// as the paper prints it. It smooths rather than interpolates (a knot gets (v_{i−1} +
    /// 4 v_i + v_{i+1}) / 6 along each axis) and never leaves the values' range (the basis is
    /// a partition of unity), so a likelihood built from values in [0, 1] stays in [0, 1].
    ///
    /// # Errors
    /// As [`SplineSurface::interpolate`].
    pub fn from_control_points(lattice: &Lattice, values: &[f64]) -> Result<Self, AcousticError> {
        let [nx, ny] = lattice.shape;
        if values.len() != nx * ny {
            return Err(invalid(
                "spline values",
                format!("{} values for a {nx}×{ny} lattice", values.len()),
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(invalid("spline values", format!("{v} is not finite")));
        }
        Ok(SplineSurface {
            lattice: lattice.clone(),
            coefficients: values.to_vec(),
        })
    }

    /// The surface at world position `(x, y)` (clamped to the lattice).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let [nx, ny] = self.lattice.shape;
        let (i, wx) = locate(self.lattice.natural(0, x), nx);
        let (j, wy) = locate(self.lattice.natural(1, y), ny);
        let mut sum = 0.0;
        for (b, wyb) in wy.iter().enumerate() {
            if *wyb == 0.0 {
                continue;
            }
            let row = mirror(j - 1 + b as isize, ny) * nx;
            for (a, wxa) in wx.iter().enumerate() {
                sum += wyb * wxa * self.coefficients[row + mirror(i - 1 + a as isize, nx)];
            }
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use proptest::prelude::*;

    fn lattice(nx: usize, ny: usize) -> Lattice {
        Lattice {
            origin: [1.0, -2.0],
            spacing: [0.5, 0.25],
            shape: [nx, ny],
        }
    }

    #[test]
    fn basis_weights_sum_to_one_and_match_hand_values() {
        assert_eq!(cubic_bspline_weights(0.0), [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0, 0.0]);
        let w = cubic_bspline_weights(0.5);
        // (1/8)/6, (3/8 − 6/4 + 4)/6, (−3/8 + 3/4 + 3/2 + 1)/6, (1/8)/6
        assert_abs_diff_eq!(w[0], 1.0 / 48.0, epsilon = 1e-15);
        assert_abs_diff_eq!(w[1], 23.0 / 48.0, epsilon = 1e-15);
        assert_abs_diff_eq!(w[2], 23.0 / 48.0, epsilon = 1e-15);
        assert_abs_diff_eq!(w[3], 1.0 / 48.0, epsilon = 1e-15);
    }

    #[test]
    fn mirror_reflects_at_both_ends() {
        assert_eq!(mirror(-1, 5), 1);
        assert_eq!(mirror(5, 5), 3);
        assert_eq!(mirror(6, 5), 2);
        assert_eq!(mirror(3, 5), 3);
        assert_eq!(mirror(-2, 1), 0);
    }

    proptest! {
        /// Values are reproduced at every knot.
        #[test]
        fn reproduces_values_at_knots(
            nx in 1usize..7, ny in 1usize..7,
            seed in proptest::collection::vec(-3.0f64..3.0, 36),
        ) {
            let l = lattice(nx, ny);
            let values: Vec<f64> = seed[..nx * ny].to_vec();
            let s = SplineSurface::interpolate(&l, &values).unwrap();
            for (k, v) in values.iter().enumerate() {
                let [x, y] = l.node_position(k);
                prop_assert!((s.eval(x, y) - v).abs() < 1e-9, "node {k}: {} vs {v}", s.eval(x, y));
            }
        }
    }

    /// A quadratic trend is reproduced nearly exactly between knots in the interior, the
    /// surface is continuous with a continuous slope, and stays within the data's range plus a
    /// small overshoot.
    #[test]
    fn smooth_between_knots() {
        let l = lattice(9, 7);
        let f = |x: f64, y: f64| 0.3 * x * x - 0.5 * x * y + 2.0 * y;
        let values: Vec<f64> = (0..l.len())
            .map(|k| {
                let [x, y] = l.node_position(k);
                f(x, y)
            })
            .collect();
        let s = SplineSurface::interpolate(&l, &values).unwrap();
        // Interior midpoint, away from the mirror boundaries.
        let (x, y) = (1.0 + 4.25 * 0.5, -2.0 + 3.5 * 0.25);
        assert_abs_diff_eq!(s.eval(x, y), f(x, y), epsilon = 2e-3);
        // Continuity and C¹ across a knot line: one-sided slopes agree.
        let h = 1e-6;
        let x0 = 1.0 + 4.0 * 0.5;
        let left = (s.eval(x0, y) - s.eval(x0 - h, y)) / h;
        let right = (s.eval(x0 + h, y) - s.eval(x0, y)) / h;
        assert_abs_diff_eq!(left, right, epsilon = 1e-4);
        assert_abs_diff_eq!(s.eval(x0 - 1e-12, y), s.eval(x0 + 1e-12, y), epsilon = 1e-9);
    }

    /// eq. 17 as printed: a knot gets (v₋ + 4 v + v₊)/6 per axis, and the surface stays in
    /// the values' range.
    #[test]
    fn control_point_surface_smooths_within_the_range() {
        let l = lattice(3, 1);
        let s = SplineSurface::from_control_points(&l, &[0.0, 1.0, 0.5]).unwrap();
        assert_abs_diff_eq!(s.eval(1.5, -2.0), (0.0 + 4.0 + 0.5) / 6.0, epsilon = 1e-12);
        // The first knot mirrors: (v₁ + 4 v₀ + v₁)/6.
        assert_abs_diff_eq!(s.eval(1.0, -2.0), 2.0 / 6.0, epsilon = 1e-12);
        for k in 0..=100 {
            let v = s.eval(1.0 + k as f64 * 0.01, -2.0);
            assert!((0.0..=1.0).contains(&v), "{v}");
        }
    }

    #[test]
    fn fit_finds_the_lattice_and_refuses_irregular_positions() {
        let mut pos = Vec::new();
        for j in 0..3 {
            for i in 0..4 {
                if (i, j) != (2, 1) {
                    pos.push([0.5 + 0.4 * i as f64, 1.0 + 0.6 * j as f64]);
                }
            }
        }
        let (l, nodes) = Lattice::fit(&pos, 0.01).unwrap();
        assert_eq!(l.shape, [4, 3]);
        assert_abs_diff_eq!(l.spacing[0], 0.4, epsilon = 1e-12);
        assert_abs_diff_eq!(l.spacing[1], 0.6, epsilon = 1e-12);
        assert_eq!(nodes[0], 0);
        // (2, 1) was skipped: the 7th position is (3, 1), node 7.
        assert_eq!(nodes[6], 7);
        let (l, _) = Lattice::fit(&[[0.0, 0.0], [0.8, 0.0], [2.0, 0.0]], 0.01).unwrap();
        assert_abs_diff_eq!(l.spacing[0], 0.4, epsilon = 1e-12);
        assert_eq!(l.shape, [6, 1]);
        pos.push([0.5 + 0.13, 1.0]);
        let e = Lattice::fit(&pos, 0.01).unwrap_err();
        assert!(e.to_string().contains("regular"), "{e}");
        let e = Lattice::fit(&[[0.0, 0.0], [0.0, 0.0]], 0.01).unwrap_err();
        assert!(e.to_string().contains("two fingerprints"), "{e}");
    }
}
