//! The scenario's parts for paper 001: an acoustic node's microphones, analysis and
//! fingerprints (`[nodes.acoustic]`), and the grid estimator's parameters (`[method.grid]`),
//! with their checks.

use super::{NodeRole, Scenario, ScenarioError};
use crate::acoustic::IldSettings;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A two-microphone acoustic node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct AcousticSpec {
    /// The left and right microphones, `[x, y, z]` m, world frame.
    pub left: [f64; 3],
    pub right: [f64; 3],
    /// The direction the pair faces in the floor plane, radians from +x (each microphone is
    /// turned 60° outward from it, as a head's ears are; the simulated room uses it).
    #[serde(default)]
    pub facing_rad: f64,
    /// Microphone directivity β: 0 omnidirectional, 0.5 sub-cardioid, 1 cardioid.
    #[serde(default = "half")]
    pub directivity: f64,
    /// Audio analysed per ILD vector, ms.
    #[serde(default = "default_frame_ms")]
    pub frame_ms: f64,
    /// How audio becomes an ILD vector; a fingerprint file carries its own, which must agree.
    #[serde(default = "low_band")]
    pub ild: IldSettings,
    /// The fingerprint database (`ocelli acoustic survey`), relative to the scenario file. The
    /// head fusing this node reads it. Absent in a simulation: the simulated room is surveyed
    /// before the run on a lattice of `survey-spacing-m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fingerprints: Option<PathBuf>,
    /// Spacing of the simulated survey lattice, m (simulation only).
    #[serde(default = "quarter")]
    pub survey_spacing_m: f64,
}

fn half() -> f64 {
    0.5
}
fn quarter() -> f64 {
    0.25
}
fn default_frame_ms() -> f64 {
    250.0
}

/// Paper 001's real-room band (Table 2: up to 386 Hz) at 8 kHz: low frequencies bend round
/// walls and vary smoothly over the floor, so a survey lattice of decimetres describes them.
pub fn low_band() -> IldSettings {
    IldSettings {
        sample_rate: 8_000,
        block_len: 1024,
        f_min_hz: 20.0,
        f_max_hz: 386.0,
        frequencies: 40,
        epsilon: 1e-4,
    }
}

impl AcousticSpec {
    /// The pair's centre, m.
    pub fn centre(&self) -> [f64; 3] {
        std::array::from_fn(|a| 0.5 * (self.left[a] + self.right[a]))
    }
}

/// The grid estimator's parameters (paper 001 §2.2–2.4, 3.2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct GridMethod {
    /// Side of a grid cell, m.
    pub cell_m: f64,
    /// Random-walk diffusion of the target, m/√s (σ per axis after dt is diffusion·√dt).
    pub diffusion: f64,
    /// A camera's probability of detecting the target where it sees the floor (P_d).
    pub detection_probability: f64,
    /// Beyond this distance a camera detects nothing, m.
    pub max_range_m: f64,
    /// How likely a detection is clutter, relative to a perfect match (κ).
    pub clutter: f64,
    /// Exponent on the acoustic likelihood (1: the paper's correlation).
    pub acoustic_sharpness: f64,
    /// Most cells per side of the posterior a report carries (at most 64).
    pub report_side: u16,
}

impl Default for GridMethod {
    fn default() -> Self {
        GridMethod {
            cell_m: 0.1,
            diffusion: 0.5,
            detection_probability: 0.9,
            max_range_m: 15.0,
            clutter: 1e-3,
            acoustic_sharpness: 1.0,
            report_side: 48,
        }
    }
}

impl Scenario {
    /// Acoustic nodes and the grid method: what serde's types cannot say.
    pub(super) fn check_acoustic(&self, origin: &str) -> Result<(), ScenarioError> {
        let bad = |field: String, problem: String| ScenarioError::Invalid {
            path: origin.into(),
            field,
            problem,
        };
        let g = &self.method.grid;
        let positive = [
            ("cell-m", g.cell_m),
            ("max-range-m", g.max_range_m),
            ("acoustic-sharpness", g.acoustic_sharpness),
        ];
        for (key, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(
                    format!("method.grid.{key}"),
                    format!("expected a positive number, got {v}"),
                ));
            }
        }
        if !(g.diffusion.is_finite() && g.diffusion >= 0.0) {
            return Err(bad(
                "method.grid.diffusion".into(),
                format!("expected a number ≥ 0, got {}", g.diffusion),
            ));
        }
        for (key, v) in [
            ("detection-probability", g.detection_probability),
            ("clutter", g.clutter),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(bad(
                    format!("method.grid.{key}"),
                    format!("expected a probability in [0, 1], got {v}"),
                ));
            }
        }
        if !(1..=crate::msg::MAX_GRID_POSTERIOR_SIDE).contains(&g.report_side) {
            return Err(bad(
                "method.grid.report-side".into(),
                format!("expected 1..=64 cells, got {}", g.report_side),
            ));
        }
        let heads: Vec<u32> = self.heads().map(|h| h.id).collect();
        for n in &self.nodes {
            let field = |f: &str| format!("nodes[id={}].{f}", n.id);
            if n.role != NodeRole::Acoustic {
                if n.acoustic.is_some() {
                    return Err(bad(
                        field("acoustic"),
                        "only acoustic nodes have microphones".into(),
                    ));
                }
                continue;
            }
            let Some(a) = &n.acoustic else {
                return Err(bad(
                    field("acoustic"),
                    "an acoustic node needs `left` and `right` microphone positions".into(),
                ));
            };
            if let Some(h) = n.head
                && !heads.contains(&h)
            {
                return Err(bad(field("head"), format!("no head with id {h}")));
            }
            let numbers = [a.left, a.right].concat();
            if !(numbers.iter().all(|v| v.is_finite()) && a.facing_rad.is_finite()) {
                return Err(bad(
                    field("acoustic"),
                    "expected finite positions and facing".into(),
                ));
            }
            if a.left == a.right {
                return Err(bad(
                    field("acoustic"),
                    "the two microphones are at the same place".into(),
                ));
            }
            if !(0.0..=1.0).contains(&a.directivity) {
                return Err(bad(
                    field("acoustic.directivity"),
                    format!("expected β in [0, 1], got {}", a.directivity),
                ));
            }
            a.ild
                .validate()
                .map_err(|e| bad(field("acoustic.ild"), e.to_string()))?;
            let block_ms = a.ild.block_len as f64 * 1000.0 / f64::from(a.ild.sample_rate);
            if !(a.frame_ms.is_finite() && a.frame_ms >= block_ms) {
                return Err(bad(
                    field("acoustic.frame-ms"),
                    format!(
                        "{} ms is shorter than one {} sample block ({block_ms} ms)",
                        a.frame_ms, a.ild.block_len
                    ),
                ));
            }
            if !(a.survey_spacing_m.is_finite() && a.survey_spacing_m > 0.0) {
                return Err(bad(
                    field("acoustic.survey-spacing-m"),
                    format!("expected a positive spacing, got {}", a.survey_spacing_m),
                ));
            }
        }
        Ok(())
    }
}
