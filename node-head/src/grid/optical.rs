//! The optical likelihood of paper 001 (eq. 2, 6) over the grid: what one camera's detections
//! — and its silence — say about where the target is.
//!
//! Each camera's probability of detection P_d is fixed by geometry, so it is computed once per
//! camera and grid ([`OpticalSensor::new`]): a free cell's centre, lifted to the target's
//! mid-height, must project in front of the camera and inside the image, lie within the
//! camera's range, and be visible past the walls (`World::occluded`); P_d is then
//! [`OpticalParams::detection_probability`], elsewhere 0. Per step only the detection term is
//! evaluated, and only over the cells the camera sees:
//!
//! - a camera not capturing (CameraOff, Inactive) says nothing: likelihood 1;
//! - no detection: 1 − P_d — the belief drops exactly where the camera would have seen the
//!   target (information, not silence);
//! - detections z_j (undistorted normalized points with covariance R_j):
//!   κ (1 − P_d) + P_d Σ_j exp(−½ eᵀ S⁻¹ e), e = z_j − h(cell), S = R_j + the cell's footprint
//!   in the image ((cell²/12) / depth² per axis). κ ([`OpticalParams::clutter`]) is how likely
//!   a detection is clutter relative to a perfect match: a cell the camera does not see keeps
//!   κ, so a lone false detection cannot wipe out the belief.

use super::GridError;
use super::layout::Grid;
use nalgebra::{Matrix2, Vector2, Vector3};
use proto::Mode;
use proto::camera::CameraModel;
use proto::observation::PinholePoint;
use proto::scenario::World;

/// The optical model's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpticalParams {
    /// P_d inside the field of view.
    pub detection_probability: f64,
    /// Beyond this distance (camera centre to the target's mid-height point) P_d is 0, m.
    pub max_range_m: f64,
    /// Height of the point a detection marks (the middle of a person), m.
    pub target_height_m: f64,
    /// κ, the clutter floor of the detection likelihood.
    pub clutter: f64,
}

impl Default for OpticalParams {
    fn default() -> Self {
        OpticalParams {
            detection_probability: 0.9,
            max_range_m: 15.0,
            target_height_m: 0.85,
            clutter: 1e-3,
        }
    }
}

impl OpticalParams {
    /// # Errors
    /// P_d or κ outside `[0, 1]`, or a range or height that is not finite and positive.
    pub fn validate(&self) -> Result<(), GridError> {
        let unit = |v: f64| (0.0..=1.0).contains(&v);
        if !(unit(self.detection_probability)
            && unit(self.clutter)
            && self.max_range_m.is_finite()
            && self.max_range_m > 0.0
            && self.target_height_m.is_finite()
            && self.target_height_m >= 0.0)
        {
            return Err(GridError::Invalid(format!(
                "optical parameters out of range: {self:?}"
            )));
        }
        Ok(())
    }
}

/// One detection as a camera reports it: an undistorted normalized point and its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    pub point: [f64; 2],
    /// `[σxx, σxy, σyy]`, normalized units².
    pub cov: [f64; 3],
}

impl From<&PinholePoint> for Detection {
    fn from(m: &PinholePoint) -> Self {
        Detection {
            point: m.point,
            cov: m.cov,
        }
    }
}

/// What one camera contributed to a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpticalOutcome {
    /// The camera was not capturing: likelihood 1.
    Silent,
    /// It captured and saw nothing: 1 − P_d.
    NoDetection,
    /// It reported this many detections.
    Detected(usize),
}

/// A free cell the camera sees: its index, P_d, projection and footprint variance.
#[derive(Clone, Copy, Debug)]
struct SeenCell {
    index: usize,
    pd: f64,
    projection: Vector2<f64>,
    footprint_var: f64,
}

/// One camera's precomputed view of the grid.
#[derive(Clone, Debug)]
pub struct OpticalSensor {
    camera_id: u32,
    cells: usize,
    seen: Vec<SeenCell>,
    seen_mask: Vec<bool>,
    clutter: f64,
}

impl OpticalSensor {
    /// P_d over `grid` for `camera` in `world` (the geometry-only part, done once).
    ///
    /// # Errors
    /// Invalid parameters.
    pub fn new(
        camera_id: u32,
        camera: &CameraModel,
        grid: &Grid,
        world: &World,
        params: &OpticalParams,
    ) -> Result<Self, GridError> {
        params.validate()?;
        let centre = camera.pose.centre();
        let (w, h) = (
            f64::from(camera.intrinsics.width),
            f64::from(camera.intrinsics.height),
        );
        let mut seen = Vec::new();
        for k in (0..grid.len()).filter(|k| grid.is_free(*k)) {
            let [x, y] = grid.centre_of(k);
            let point = Vector3::new(x, y, params.target_height_m);
            let (p, depth) = camera.normalized(&point);
            // |p| < 4 (beyond 150° across) keeps strong distortion from folding far-off
            // points back into the image.
            if !(depth > 1e-3 && p.x.abs() < 4.0 && p.y.abs() < 4.0) {
                continue;
            }
            let px = camera.normalized_to_pixel(&p);
            let in_image = px.x >= 0.0 && px.x < w && px.y >= 0.0 && px.y < h;
            if !in_image || (point - centre).norm() > params.max_range_m || world.occluded(&centre, &point) {
                continue;
            }
            seen.push(SeenCell {
                index: k,
                pd: params.detection_probability,
                projection: p,
                footprint_var: grid.cell().powi(2) / 12.0 / (depth * depth),
            });
        }
        let mut seen_mask = vec![false; grid.len()];
        seen.iter().for_each(|c| seen_mask[c.index] = true);
        Ok(OpticalSensor {
            camera_id,
            cells: grid.len(),
            seen,
            seen_mask,
            clutter: params.clutter,
        })
    }

    /// P_d per grid cell (row-major), for display and tests.
    pub fn detection_probability(&self) -> Vec<f64> {
        let mut pd = vec![0.0; self.cells];
        for c in &self.seen {
            pd[c.index] = c.pd;
        }
        pd
    }

    /// How many cells the camera sees.
    pub fn cells_seen(&self) -> usize {
        self.seen.len()
    }

    /// Multiply this camera's likelihood for one step into `likelihood` (eq. 6, 12).
    ///
    /// # Errors
    /// A likelihood of another grid's size, or a detection whose point is not finite or whose
    /// covariance is not positive definite; `likelihood` is then unchanged.
    pub fn apply(
        &self,
        mode: Mode,
        detections: &[Detection],
        likelihood: &mut [f64],
    ) -> Result<OpticalOutcome, GridError> {
        if likelihood.len() != self.cells {
            return Err(GridError::Invalid(format!(
                "likelihood has {} cells, camera {}'s grid {}",
                likelihood.len(),
                self.camera_id,
                self.cells
            )));
        }
        if !mode.camera_on() {
            return Ok(OpticalOutcome::Silent);
        }
        if detections.is_empty() {
            for c in &self.seen {
                likelihood[c.index] *= 1.0 - c.pd;
            }
            return Ok(OpticalOutcome::NoDetection);
        }
        let checked = detections
            .iter()
            .map(|d| self.check(d))
            .collect::<Result<Vec<_>, _>>()?;
        let kappa = self.clutter;
        for (l, seen) in likelihood.iter_mut().zip(&self.seen_mask) {
            if !seen {
                *l *= kappa; // P_d = 0: only clutter explains the detections
            }
        }
        for c in &self.seen {
            let floor = kappa * (1.0 - c.pd);
            // Past this squared distance a match adds less than 10⁻¹³ of the clutter term
            // (or underflows): skip its exp, and keep subnormals out of the product.
            let cut = if floor > 0.0 {
                (2.0 * ((c.pd / floor).ln() + 30.0)).min(1400.0)
            } else {
                1400.0
            };
            let mut matched = 0.0;
            for (z, r) in &checked {
                let (sxx, sxy, syy) = (
                    r[(0, 0)] + c.footprint_var,
                    r[(0, 1)],
                    r[(1, 1)] + c.footprint_var,
                );
                let e = z - c.projection;
                let m2 =
                    (syy * e.x * e.x - 2.0 * sxy * e.x * e.y + sxx * e.y * e.y) / (sxx * syy - sxy * sxy);
                if m2 < cut {
                    matched += (-0.5 * m2).exp();
                }
            }
            likelihood[c.index] *= floor + c.pd * matched;
        }
        Ok(OpticalOutcome::Detected(checked.len()))
    }

    fn check(&self, d: &Detection) -> Result<(Vector2<f64>, Matrix2<f64>), GridError> {
        let bad = |problem: String| GridError::Camera {
            camera: self.camera_id,
            problem,
        };
        let [sxx, sxy, syy] = d.cov;
        if !(d.point.iter().chain(&d.cov).all(|v| v.is_finite())) {
            return Err(bad(format!(
                "detection {:?} with covariance {:?} is not finite",
                d.point, d.cov
            )));
        }
        if !(sxx > 0.0 && syy > 0.0 && sxx * syy - sxy * sxy > 0.0) {
            return Err(bad(format!(
                "detection covariance {:?} is not positive definite",
                d.cov
            )));
        }
        Ok((Vector2::from(d.point), Matrix2::new(sxx, sxy, sxy, syy)))
    }
}

#[cfg(test)]
mod tests;
