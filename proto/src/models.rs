//! Models shared by cameras and heads, so that the camera that linearizes and the head that
//! sums agree to the bit: the state layout, constant-velocity motion (paper 000 eq. 11), the
//! pin-hole measurement model and its Jacobian (paper 000 eq. 12–13, paper 002 eq. 1), the RSSI
//! models (paper 002 eq. 2–5), the ground-plane person model (paper 004 §3.2.3) and the
//! information form of one measurement.

use crate::camera::CameraModel;
use crate::msg::{Mat6, Vec6};
use nalgebra::{Matrix2, Matrix6, SMatrix, SVector, Vector2, Vector3, Vector6};
use serde::{Deserialize, Serialize};

/// Index of X in the state `[X Y Z Vx Vy Vz]`.
pub const POS: usize = 0;
/// Index of Vx in the state.
pub const VEL: usize = 3;
/// State dimension.
pub const STATE_DIM: usize = 6;

pub type State = Vector6<f64>;
pub type Info = Matrix6<f64>;

pub fn position(x: &State) -> Vector3<f64> {
    Vector3::new(x[0], x[1], x[2])
}

pub fn mat6_to_wire(m: &Matrix6<f64>) -> Mat6 {
    let mut out = [[0.0; 6]; 6];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = m[(i, j)];
        }
    }
    out
}

pub fn mat6_from_wire(m: &Mat6) -> Matrix6<f64> {
    Matrix6::from_fn(|i, j| m[i][j])
}

pub fn vec6_to_wire(v: &Vector6<f64>) -> Vec6 {
    [v[0], v[1], v[2], v[3], v[4], v[5]]
}

pub fn vec6_from_wire(v: &Vec6) -> Vector6<f64> {
    Vector6::from_column_slice(v)
}

/// Constant-velocity motion with white-noise acceleration (paper 000 eq. 11 plus its Gaussian
/// model noise). `accel_psd` is the acceleration noise spectral density per axis, m²/s³.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct MotionModel {
    pub accel_psd: [f64; 3],
}

impl Default for MotionModel {
    fn default() -> Self {
        // A walking robot or person: accelerations of a few tenths of m/s² over a second.
        MotionModel {
            accel_psd: [0.25, 0.25, 0.01],
        }
    }
}

impl MotionModel {
    /// Transition matrix G for a step of `dt` seconds.
    pub fn transition(&self, dt: f64) -> Matrix6<f64> {
        let mut g = Matrix6::identity();
        for a in 0..3 {
            g[(POS + a, VEL + a)] = dt;
        }
        g
    }

    /// g(μ) = G μ.
    pub fn predict_mean(&self, x: &State, dt: f64) -> State {
        self.transition(dt) * x
    }

    /// Process noise R for a step of `dt` seconds.
    pub fn process_noise(&self, dt: f64) -> Matrix6<f64> {
        let mut r = Matrix6::zeros();
        let (dt2, dt3) = (dt * dt, dt * dt * dt);
        for a in 0..3 {
            let q = self.accel_psd[a];
            r[(POS + a, POS + a)] = q * dt3 / 3.0;
            r[(POS + a, VEL + a)] = q * dt2 / 2.0;
            r[(VEL + a, POS + a)] = q * dt2 / 2.0;
            r[(VEL + a, VEL + a)] = q * dt;
        }
        r
    }
}

/// Pin-hole measurement of the target position: h(x) (eq. 12) and its 2×6 Jacobian (eq. 13).
/// `None` when the predicted point is (nearly) on the camera plane, where h is singular.
pub fn pinhole(camera: &CameraModel, x: &State) -> Option<(Vector2<f64>, SMatrix<f64, 2, 6>)> {
    let c = camera.pose.world_to_camera(&position(x));
    if c.z.abs() < 1e-6 {
        return None;
    }
    let iz = 1.0 / c.z;
    let h = Vector2::new(c.x * iz, c.y * iz);
    let dh_dc = SMatrix::<f64, 2, 3>::new(iz, 0.0, -c.x * iz * iz, 0.0, iz, -c.y * iz * iz);
    let dh_dp = dh_dc * camera.pose.rotation.matrix();
    let mut jac = SMatrix::<f64, 2, 6>::zeros();
    jac.fixed_view_mut::<2, 3>(0, POS).copy_from(&dh_dp);
    Some((h, jac))
}

/// Pin-hole measurement of where the target was `dt` seconds earlier, `P − V dt` (paper 000's
/// p_{i,t−1} term): its prediction and 2×6 Jacobian, which also observes velocity.
pub fn pinhole_previous(
    camera: &CameraModel,
    x: &State,
    dt: f64,
) -> Option<(Vector2<f64>, SMatrix<f64, 2, 6>)> {
    let (h, jac) = pinhole(camera, &back_in_time(x, dt))?;
    Some((h, aged_jacobian(jac, dt)))
}

/// A position-only Jacobian, taken at `P − V dt`, as one with respect to the state at its own
/// time: the velocity columns are −dt × the position columns.
fn aged_jacobian<const M: usize>(mut jac: SMatrix<f64, M, 6>, dt: f64) -> SMatrix<f64, M, 6> {
    let dp = jac.fixed_view::<M, 3>(0, POS).into_owned();
    jac.fixed_view_mut::<M, 3>(0, VEL).copy_from(&(dp * -dt));
    jac
}

/// The state `dt` seconds earlier under constant velocity: `P − V dt`, same velocity.
pub fn back_in_time(x: &State, dt: f64) -> State {
    let mut back = *x;
    for a in 0..3 {
        back[POS + a] -= dt * x[VEL + a];
    }
    back
}

/// [`pinhole`] of a point seen `age_s` seconds before the state's time ([`pinhole_previous`]),
/// or exactly [`pinhole`] at age 0 or a non-finite age.
pub fn pinhole_aged(
    camera: &CameraModel,
    x: &State,
    age_s: f64,
) -> Option<(Vector2<f64>, SMatrix<f64, 2, 6>)> {
    if age_s.is_finite() && age_s != 0.0 {
        pinhole_previous(camera, x, age_s)
    } else {
        pinhole(camera, x)
    }
}

/// Squared Mahalanobis distance `νᵀ (J Σ Jᵀ + R)⁻¹ ν` of a normalized point (covariance `R`)
/// seen `age_s` seconds before the time of a track's (`mean`, `cov`), compared with where the
/// track puts the target then; `None` when that is behind the camera or the innovation
/// covariance is singular. The gate of cameras (against priors) and heads (against tracks).
pub fn gate_distance2(
    camera: &CameraModel,
    mean: &State,
    cov: &Matrix6<f64>,
    point: &Vector2<f64>,
    point_cov: &Matrix2<f64>,
    age_s: f64,
) -> Option<f64> {
    let then = back_in_time(mean, if age_s.is_finite() { age_s } else { 0.0 });
    if camera.pose.world_to_camera(&position(&then)).z <= 0.0 {
        return None;
    }
    let (h, jac) = pinhole_aged(camera, mean, age_s)?;
    let s = jac * cov * jac.transpose() + point_cov;
    let nu = point - h;
    let d2 = nu.dot(&s.cholesky()?.solve(&nu));
    d2.is_finite().then_some(d2)
}

/// An RSSI-range model (paper 002 §IV).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", tag = "kind")]
pub enum RssiModel {
    /// `RSSI = a log10(d) + b` (eq. 2), the default model, with its variance σ²_D (dB²).
    LogDistance { a: f64, b: f64, variance: f64 },
    /// `RSSI = a d + b`, the locally trained model (eq. 4–5), with σ²_tm (dB²).
    Linear { a: f64, b: f64, variance: f64 },
}

/// Distances below this are clamped: log d and the Jacobian blow up at the node itself.
pub const RSSI_MIN_DISTANCE_M: f64 = 0.1;

impl Default for RssiModel {
    fn default() -> Self {
        // Free-space-like indoor default: −45 dBm at 1 m, path-loss exponent 2.2, σ = 4 dB.
        RssiModel::LogDistance {
            a: -22.0,
            b: -45.0,
            variance: 16.0,
        }
    }
}

impl RssiModel {
    pub fn variance(&self) -> f64 {
        match *self {
            RssiModel::LogDistance { variance, .. } | RssiModel::Linear { variance, .. } => variance,
        }
    }

    /// The same model with its variance multiplied by `factor`.
    pub fn widened(&self, factor: f64) -> RssiModel {
        match *self {
            RssiModel::LogDistance { a, b, variance } => RssiModel::LogDistance {
                a,
                b,
                variance: variance * factor,
            },
            RssiModel::Linear { a, b, variance } => RssiModel::Linear {
                a,
                b,
                variance: variance * factor,
            },
        }
    }

    /// Predicted RSSI at distance `d` metres.
    pub fn predict(&self, d: f64) -> f64 {
        let d = d.max(RSSI_MIN_DISTANCE_M);
        match *self {
            RssiModel::LogDistance { a, b, .. } => a * d.log10() + b,
            RssiModel::Linear { a, b, .. } => a * d + b,
        }
    }

    /// d RSSI / d distance.
    pub fn slope(&self, d: f64) -> f64 {
        let d = d.max(RSSI_MIN_DISTANCE_M);
        match *self {
            RssiModel::LogDistance { a, .. } => a / (d * std::f64::consts::LN_10),
            RssiModel::Linear { a, .. } => a,
        }
    }

    /// h(x) and the 1×6 Jacobian Hr = ∂h/∂d · ∂d/∂q (eq. 3) for a node at `node`.
    pub fn measurement(&self, node: &Vector3<f64>, x: &State) -> (f64, SMatrix<f64, 1, 6>) {
        let diff = position(x) - node;
        let d = diff.norm();
        let mut jac = SMatrix::<f64, 1, 6>::zeros();
        if d > 1e-9 {
            let g = diff * (self.slope(d) / d);
            for a in 0..3 {
                jac[(0, POS + a)] = g[a];
            }
        }
        (self.predict(d), jac)
    }
}

/// Fit the default model `RSSI = a log10 d + b` (paper 002 eq. 2) by least squares to
/// (distance m, RSSI dBm) pairs, as paper 002 §VI did with readings between every pair of nodes;
/// the variance σ²_D is the residuals' (two degrees of freedom removed). `None` with fewer than
/// three usable pairs or no spread in distance.
pub fn fit_log_distance(pairs: &[(f64, f64)]) -> Option<RssiModel> {
    let pts: Vec<(f64, f64)> = pairs
        .iter()
        .filter(|(d, r)| d.is_finite() && r.is_finite() && *d > 0.0)
        .map(|&(d, r)| (d.max(RSSI_MIN_DISTANCE_M).log10(), r))
        .collect();
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx <= 1e-12 {
        return None;
    }
    let a = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    let b = my - a * mx;
    let variance = pts.iter().map(|p| (p.1 - a * p.0 - b).powi(2)).sum::<f64>() / (n - 2.0).max(1.0);
    Some(RssiModel::LogDistance { a, b, variance })
}

/// Information form of one measurement linearized at `mean` (paper 002 §III):
/// Ω_i = Hᵀ Q⁻¹ H, ξ_i = Hᵀ Q⁻¹ (z − h(μ̄) + H μ̄). `None` when Q is not positive definite.
pub fn information_contribution<const M: usize>(
    z: &SVector<f64, M>,
    predicted: &SVector<f64, M>,
    jac: &SMatrix<f64, M, 6>,
    noise: &SMatrix<f64, M, M>,
    mean: &State,
) -> Option<(Info, State)> {
    let chol = noise.cholesky()?;
    // Q⁻¹ H by solving, not inverting.
    let qinv_h = chol.solve(jac);
    let innovation = z - predicted + jac * mean;
    let mut omega = jac.transpose() * qinv_h;
    omega = 0.5 * (omega + omega.transpose());
    let xi = qinv_h.transpose() * innovation;
    Some((omega, xi))
}

/// The camera half of a contribution: a normalized point with its 2×2 covariance, seen at the
/// mean's time.
pub fn camera_contribution(
    camera: &CameraModel,
    point: &Vector2<f64>,
    cov: &Matrix2<f64>,
    mean: &State,
) -> Option<(Info, State)> {
    camera_contribution_aged(camera, point, cov, mean, 0.0)
}

/// The camera half of a contribution from a frame captured `age_s` seconds before the mean's
/// time. Cameras are not frame-synchronized with the filter's steps, so the newest frame is up
/// to a frame period old when a step asks for it; fused as current, it makes the estimate trail
/// the target by speed × age. The constant-velocity model carries the state back instead
/// (`pinhole_previous`), which also lets the frame observe velocity. The process noise over
/// the age is left out: over a frame period it is small against the pixel noise. A negative age
/// (a frame newer than the mean) carries the state forward.
pub fn camera_contribution_aged(
    camera: &CameraModel,
    point: &Vector2<f64>,
    cov: &Matrix2<f64>,
    mean: &State,
    age_s: f64,
) -> Option<(Info, State)> {
    let (h, jac) = pinhole_aged(camera, mean, age_s)?;
    information_contribution(point, &h, &jac, cov, mean)
}

/// The RSSI half of a contribution: one reading with the node's model.
pub fn rssi_contribution(
    model: &RssiModel,
    node: &Vector3<f64>,
    dbm: f64,
    mean: &State,
) -> Option<(Info, State)> {
    rssi_contribution_aged(model, node, dbm, mean, 0.0)
}

/// The RSSI model linearized for a packet received `age_s` seconds before the mean's time: the
/// reading predicted at where the state puts the target then, and the Jacobian with respect to
/// the state now (see [`pinhole_aged`]). A non-finite age counts as 0.
pub fn rssi_aged(
    model: &RssiModel,
    node: &Vector3<f64>,
    mean: &State,
    age_s: f64,
) -> (f64, SMatrix<f64, 1, 6>) {
    let age_s = if age_s.is_finite() { age_s } else { 0.0 };
    let (h, jac) = model.measurement(node, &back_in_time(mean, age_s));
    (h, aged_jacobian(jac, age_s))
}

/// The information of one RSSI reading `dbm` linearized as (`h`, `jac`) with variance
/// `variance` (dB²), about `mean`.
pub fn rssi_information(
    dbm: f64,
    h: f64,
    jac: &SMatrix<f64, 1, 6>,
    variance: f64,
    mean: &State,
) -> Option<(Info, State)> {
    let z = SVector::<f64, 1>::new(dbm);
    let hv = SVector::<f64, 1>::new(h);
    let q = SMatrix::<f64, 1, 1>::new(variance);
    information_contribution(&z, &hv, jac, &q, mean)
}

/// [`rssi_contribution`] of a packet received `age_s` seconds before the mean's time: the
/// range is the one to where the state puts the target then (see
/// [`camera_contribution_aged`]).
pub fn rssi_contribution_aged(
    model: &RssiModel,
    node: &Vector3<f64>,
    dbm: f64,
    mean: &State,
    age_s: f64,
) -> Option<(Info, State)> {
    let (h, jac) = rssi_aged(model, node, mean, age_s);
    rssi_information(dbm, h, &jac, model.variance(), mean)
}

/// The ground-plane person model (paper 004 §3.2.3): a camera's 2D → 3D unit measures the floor
/// point under the target, the state's `(X, Y)`, as it was `age_s` seconds before the state's
/// time — `h(x) = (X − age·Vx, Y − age·Vy)` — and its 2×6 Jacobian. Linear, so it needs no
/// camera model: the camera already cast its rays. A non-finite age counts as 0.
pub fn ground_aged(x: &State, age_s: f64) -> (Vector2<f64>, SMatrix<f64, 2, 6>) {
    let age_s = if age_s.is_finite() { age_s } else { 0.0 };
    let then = back_in_time(x, age_s);
    let mut jac = SMatrix::<f64, 2, 6>::zeros();
    jac[(0, POS)] = 1.0;
    jac[(1, POS + 1)] = 1.0;
    (Vector2::new(then[POS], then[POS + 1]), aged_jacobian(jac, age_s))
}

/// Standard deviation of a ground-plane person's centre height (half the height a camera
/// measured), m.
pub const GROUND_CENTRE_Z_SIGMA_M: f64 = 0.25;

/// The information a ground-plane person's measured height gives: the target's centre is at
/// half of it, with [`GROUND_CENTRE_Z_SIGMA_M`] (heights do not change, so no aging). `None`
/// for a height that is not finite and positive.
pub fn ground_height_contribution(height_m: f64, mean: &State) -> Option<(Info, State)> {
    if !(height_m.is_finite() && height_m > 0.0) {
        return None;
    }
    let mut jac = SMatrix::<f64, 1, 6>::zeros();
    jac[(0, POS + 2)] = 1.0;
    let z = nalgebra::Vector1::new(0.5 * height_m);
    let predicted = nalgebra::Vector1::new(mean[POS + 2]);
    let noise = nalgebra::Matrix1::new(GROUND_CENTRE_Z_SIGMA_M.powi(2));
    information_contribution(&z, &predicted, &jac, &noise, mean)
}

/// Squared Mahalanobis distance `νᵀ (H Σ Hᵀ + R)⁻¹ ν` of a floor position (covariance `R`) seen
/// `age_s` seconds before the time of a track's (`mean`, `cov`), in the ground plane; `None`
/// when the innovation covariance is singular. The ground-plane gate of cameras (against
/// priors) and heads (against tracks).
pub fn ground_gate_distance2(
    mean: &State,
    cov: &Matrix6<f64>,
    position: &Vector2<f64>,
    position_cov: &Matrix2<f64>,
    age_s: f64,
) -> Option<f64> {
    let (h, jac) = ground_aged(mean, age_s);
    let s = jac * cov * jac.transpose() + position_cov;
    let nu = position - h;
    let d2 = nu.dot(&s.cholesky()?.solve(&nu));
    d2.is_finite().then_some(d2)
}

/// The information Ω_i, ξ_i of a floor position (covariance `cov`) seen `age_s` seconds before
/// the mean's time (see [`camera_contribution_aged`]); `None` when `cov` is not positive
/// definite.
pub fn ground_contribution_aged(
    position: &Vector2<f64>,
    cov: &Matrix2<f64>,
    mean: &State,
    age_s: f64,
) -> Option<(Info, State)> {
    let (h, jac) = ground_aged(mean, age_s);
    information_contribution(position, &h, &jac, cov, mean)
}
