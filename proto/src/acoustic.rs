//! The acoustic observation kind (paper 001 §3.3): a two-microphone node's interaural level
//! difference (ILD) vector, the fingerprints surveyed a priori, and the maths both sides share.
//!
//! - eq. 13: ΔS(ω) = 20 log10 |s_l(ω)| − 20 log10 |s_r(ω)| ([`level_difference_db`]);
//! - eq. 14–15: each sampled frequency weighted by the Macaulay bracket
//!   a_j = ⟨min(|s_l|, |s_r|) − ε⟩ ([`macaulay_weight`], [`IldVector::from_amplitudes`]);
//! - eq. 16: the correlation of a new ILD vector with a fingerprint,
//!   X = ½ (cos∠(S_obs, S_i) + 1) ∈ [0, 1] ([`correlation`]). The paper prints "− 1" inside
//!   the braces but states 0 ≤ X ≤ 1, which only "+ 1" gives;
//! - eq. 17–18: the correlations spread over the plane with tensor-product cubic B-spline
//!   basis functions ([`spline`]), as control points (the paper) or interpolated.
//!
//! The fingerprint database and its versioned file format are in [`fingerprints`]. The FFT
//! that turns audio into amplitudes lives in the acoustic node (`node-acoustic`); `proto` only
//! sees amplitudes.

use crate::observation;
use crate::time::ClusterTime;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use thiserror::Error;

pub mod fingerprints;
pub mod spline;

pub use fingerprints::{Fingerprint, FingerprintDb, RoomSignature, SplineFit};
pub use spline::{Lattice, SplineSurface};

/// Most frequencies one ILD vector may carry (the paper's bench used 8,192).
pub const MAX_ILD_FREQUENCIES: usize = 16_384;

/// Why acoustic data was refused. Each variant names what is wrong.
#[derive(Debug, Error)]
pub enum AcousticError {
    #[error("{what}: {problem}")]
    Invalid { what: String, problem: String },
    #[error("ILD vector has {found} frequencies, the fingerprints have {expected}")]
    FrequencyCount { found: usize, expected: usize },
    #[error("ILD frequency {index} is {found} Hz, the fingerprints sampled {expected} Hz")]
    FrequencyMismatch { index: usize, found: f64, expected: f64 },
    /// Reading or writing the file failed (the I/O error is in the message, not a source, so
    /// that error chains name it once).
    #[error("fingerprint file {}: {error}", path.display())]
    Io { path: PathBuf, error: std::io::Error },
    #[error("fingerprint file {origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("{origin} is not an Ocelli fingerprint file (format {found:?}, expected {expected:?})")]
    Format {
        origin: String,
        found: String,
        expected: &'static str,
    },
    #[error("fingerprint file {origin} has format version {found}; this build reads version {expected}")]
    Version {
        origin: String,
        found: u32,
        expected: u32,
    },
    #[error(
        "fingerprint file {origin} was surveyed in another room (signature {found}, this world is {expected}): survey this room again"
    )]
    RoomMismatch {
        origin: String,
        found: RoomSignature,
        expected: RoomSignature,
    },
    #[error("fingerprint positions: {0}")]
    Lattice(String),
}

pub(crate) fn invalid(what: impl Into<String>, problem: impl Into<String>) -> AcousticError {
    AcousticError::Invalid {
        what: what.into(),
        problem: problem.into(),
    }
}

/// How an ILD vector is computed from audio: the contract between the survey, the acoustic
/// node and whoever reads the fingerprints. Stored in the fingerprint file, so a node analyses
/// new audio exactly as the survey did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct IldSettings {
    /// Audio sample rate, Hz.
    pub sample_rate: u32,
    /// FFT block length, samples (Hann window, half-overlapping blocks averaged per frame).
    pub block_len: usize,
    /// ω_1 and ω_N of the sampled frequencies Ω, Hz.
    pub f_min_hz: f64,
    pub f_max_hz: f64,
    /// N, the number of sampled frequencies (evenly spaced from ω_1 to ω_N inclusive).
    pub frequencies: usize,
    /// ε of eq. 15, in the node's amplitude units (RMS per bin of a full-scale-1 signal).
    pub epsilon: f64,
}

impl Default for IldSettings {
    fn default() -> Self {
        IldSettings {
            sample_rate: 48_000,
            block_len: 1024,
            f_min_hz: 150.0,
            f_max_hz: 8_000.0,
            frequencies: 64,
            epsilon: 0.01,
        }
    }
}

impl IldSettings {
    /// Ω: `frequencies` values evenly spaced from `f_min_hz` to `f_max_hz` inclusive.
    pub fn sampled_frequencies(&self) -> Vec<f64> {
        let n = self.frequencies;
        if n == 1 {
            return vec![self.f_min_hz];
        }
        let step = (self.f_max_hz - self.f_min_hz) / (n - 1) as f64;
        (0..n).map(|j| self.f_min_hz + step * j as f64).collect()
    }

    /// # Errors
    /// A zero rate or block, a block that is not a power of two, an empty or inverted frequency
    /// range, a range above Nyquist, too many frequencies or a negative ε.
    pub fn validate(&self) -> Result<(), AcousticError> {
        let bad = |what: &str, problem: String| Err(invalid(format!("ILD settings: {what}"), problem));
        if self.sample_rate == 0 {
            return bad("sample-rate", "must be positive".into());
        }
        if self.block_len < 16 || !self.block_len.is_power_of_two() {
            return bad(
                "block-len",
                format!("{} is not a power of two ≥ 16", self.block_len),
            );
        }
        let nyquist = f64::from(self.sample_rate) / 2.0;
        let (lo, hi) = (self.f_min_hz, self.f_max_hz);
        if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo <= hi && hi <= nyquist) {
            return bad(
                "f-min-hz/f-max-hz",
                format!("[{lo}, {hi}] Hz is not a range inside [0, {nyquist}] Hz"),
            );
        }
        if self.frequencies == 0 || self.frequencies > MAX_ILD_FREQUENCIES {
            return bad(
                "frequencies",
                format!("{} is not in 1..={MAX_ILD_FREQUENCIES}", self.frequencies),
            );
        }
        if self.frequencies > 1 && lo == hi {
            return bad(
                "frequencies",
                "several frequencies need f-min-hz < f-max-hz".into(),
            );
        }
        if !(self.epsilon.is_finite() && self.epsilon >= 0.0) {
            return bad("epsilon", format!("{} is not a finite ε ≥ 0", self.epsilon));
        }
        Ok(())
    }
}

/// eq. 13: the level difference of two amplitudes, dB. Zero amplitudes give ±∞ or NaN; the
/// Macaulay weight of such a frequency is zero, and [`IldVector::from_amplitudes`] never
/// evaluates it.
pub fn level_difference_db(left: f64, right: f64) -> f64 {
    20.0 * left.log10() - 20.0 * right.log10()
}

/// eq. 15: a_j = ⟨min(|s_l|, |s_r|) − ε⟩, the Macaulay bracket ⟨x⟩ = max(x, 0). A frequency
/// either microphone hardly hears gets no weight.
pub fn macaulay_weight(left: f64, right: f64, epsilon: f64) -> f64 {
    (left.abs().min(right.abs()) - epsilon).max(0.0)
}

/// A weighted ILD vector (eq. 14): the sampled frequencies Ω and a_j ΔS(ω_j) at each.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IldVector {
    /// Ω, Hz, strictly increasing.
    pub frequencies_hz: Vec<f64>,
    /// a_j ΔS(ω_j), dB × amplitude.
    pub values: Vec<f64>,
}

impl IldVector {
    /// # Errors
    /// Lengths that differ, no or too many frequencies, non-finite numbers, or frequencies
    /// that are negative or not strictly increasing.
    pub fn new(frequencies_hz: Vec<f64>, values: Vec<f64>) -> Result<Self, AcousticError> {
        let v = IldVector {
            frequencies_hz,
            values,
        };
        v.validate()?;
        Ok(v)
    }

    /// eq. 13–15 from the two channels' amplitudes at the sampled frequencies.
    ///
    /// # Errors
    /// As [`IldVector::new`], or amplitudes that are negative, non-finite or of another length.
    pub fn from_amplitudes(
        frequencies_hz: Vec<f64>,
        left: &[f64],
        right: &[f64],
        epsilon: f64,
    ) -> Result<Self, AcousticError> {
        let n = frequencies_hz.len();
        if left.len() != n || right.len() != n {
            return Err(invalid(
                "ILD amplitudes",
                format!(
                    "{} left and {} right amplitudes for {n} frequencies",
                    left.len(),
                    right.len()
                ),
            ));
        }
        if let Some(a) = left.iter().chain(right).find(|a| !(a.is_finite() && **a >= 0.0)) {
            return Err(invalid(
                "ILD amplitudes",
                format!("{a} is not a finite amplitude ≥ 0"),
            ));
        }
        let values = left
            .iter()
            .zip(right)
            .map(|(&l, &r)| {
                let a = macaulay_weight(l, r, epsilon);
                if a > 0.0 {
                    a * level_difference_db(l, r)
                } else {
                    0.0
                }
            })
            .collect();
        IldVector::new(frequencies_hz, values)
    }

    /// # Errors
    /// As [`IldVector::new`].
    pub fn validate(&self) -> Result<(), AcousticError> {
        validate_frequencies("ILD vector", &self.frequencies_hz)?;
        if self.values.len() != self.frequencies_hz.len() {
            return Err(invalid(
                "ILD vector",
                format!(
                    "{} values for {} frequencies",
                    self.values.len(),
                    self.frequencies_hz.len()
                ),
            ));
        }
        if let Some(v) = self.values.iter().find(|v| !v.is_finite()) {
            return Err(invalid("ILD vector", format!("value {v} is not finite")));
        }
        Ok(())
    }
}

impl IldVector {
    /// The wire observation (`proto::observation::IldVector`): evenly spaced bands from
    /// `first_hz` by `step_hz`, values as `f32`.
    ///
    /// # Errors
    /// Frequencies that are not evenly spaced (beyond 10⁻⁶ of the step) or more than
    /// [`crate::observation::MAX_BINS`] of them.
    pub fn to_observation(&self, captured: ClusterTime) -> Result<observation::IldVector, AcousticError> {
        let f = &self.frequencies_hz;
        if f.len() > observation::MAX_BINS {
            return Err(invalid(
                "ILD observation",
                format!(
                    "{} bands, the wire carries at most {}",
                    f.len(),
                    observation::MAX_BINS
                ),
            ));
        }
        let step = if f.len() > 1 {
            (f[f.len() - 1] - f[0]) / (f.len() - 1) as f64
        } else {
            0.0
        };
        if let Some((j, x)) = f
            .iter()
            .enumerate()
            .find(|(j, x)| (f[0] + step * *j as f64 - **x).abs() > 1e-6 * step.max(1.0))
        {
            return Err(invalid(
                "ILD observation",
                format!("frequency {j} ({x} Hz) breaks the even spacing of {step} Hz"),
            ));
        }
        Ok(observation::IldVector {
            first_hz: f[0] as f32,
            // A single band has no spacing; the wire wants a positive one.
            step_hz: if f.len() > 1 { step as f32 } else { 1.0 },
            ild_db: self.values.iter().map(|v| *v as f32).collect(),
            captured,
        })
    }

    /// From the wire observation.
    ///
    /// # Errors
    /// As [`IldVector::new`].
    pub fn from_observation(o: &observation::IldVector) -> Result<IldVector, AcousticError> {
        let (first, step) = (f64::from(o.first_hz), f64::from(o.step_hz));
        IldVector::new(
            (0..o.ild_db.len()).map(|j| first + step * j as f64).collect(),
            o.ild_db.iter().map(|v| f64::from(*v)).collect(),
        )
    }
}

pub(crate) fn validate_frequencies(what: &str, f: &[f64]) -> Result<(), AcousticError> {
    if f.is_empty() || f.len() > MAX_ILD_FREQUENCIES {
        return Err(invalid(
            what,
            format!("{} frequencies, expected 1..={MAX_ILD_FREQUENCIES}", f.len()),
        ));
    }
    if let Some(x) = f.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
        return Err(invalid(what, format!("frequency {x} Hz is not finite and ≥ 0")));
    }
    if let Some(w) = f.windows(2).find(|w| w[1] <= w[0]) {
        return Err(invalid(
            what,
            format!("frequencies not strictly increasing ({} then {} Hz)", w[0], w[1]),
        ));
    }
    Ok(())
}

/// eq. 16: X = ½ (Sᵀ S_i / (|S| |S_i|) + 1) ∈ [0, 1]; 1 when the vectors point the same way,
/// ½ (no information) when either is zero. The slices must have the same length (the caller
/// checks the frequencies).
pub fn correlation(observed: &[f64], fingerprint: &[f64]) -> f64 {
    debug_assert_eq!(observed.len(), fingerprint.len());
    let (mut dot, mut a2, mut b2) = (0.0, 0.0, 0.0);
    for (a, b) in observed.iter().zip(fingerprint) {
        dot += a * b;
        a2 += a * a;
        b2 += b * b;
    }
    let norms = (a2 * b2).sqrt();
    if !(norms > 0.0 && norms.is_finite()) {
        return 0.5;
    }
    (0.5 * (dot / norms + 1.0)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn level_difference_is_twenty_log_ratio() {
        assert_abs_diff_eq!(level_difference_db(1.0, 0.1), 20.0, epsilon = 1e-12);
        assert_abs_diff_eq!(level_difference_db(0.5, 1.0), -6.0206, epsilon = 1e-4);
        assert_abs_diff_eq!(level_difference_db(0.3, 0.3), 0.0, epsilon = 1e-12);
    }

    #[test]
    fn macaulay_weight_is_the_bracket_of_the_smaller_amplitude() {
        // min(0.5, 0.2) − 0.01 = 0.19
        assert_abs_diff_eq!(macaulay_weight(0.5, 0.2, 0.01), 0.19, epsilon = 1e-12);
        // Below ε: ⟨0.005 − 0.01⟩ = 0.
        assert_eq!(macaulay_weight(0.005, 3.0, 0.01), 0.0);
        assert_eq!(macaulay_weight(0.01, 0.01, 0.01), 0.0);
    }

    #[test]
    fn weighted_ild_vector_from_amplitudes() {
        let f = vec![100.0, 200.0, 300.0];
        let v = IldVector::from_amplitudes(f, &[1.0, 0.001, 0.2], &[0.1, 0.5, 0.4], 0.01).unwrap();
        // (0.1 − 0.01)·20 dB; weight 0 (0.001 < ε); (0.2 − 0.01)·(−6.0206) dB.
        assert_abs_diff_eq!(v.values[0], 0.09 * 20.0, epsilon = 1e-9);
        assert_eq!(v.values[1], 0.0);
        assert_abs_diff_eq!(v.values[2], 0.19 * -6.020_599_913, epsilon = 1e-8);
        // A silent channel never produces a NaN.
        let silent = IldVector::from_amplitudes(vec![1.0], &[0.0], &[0.0], 0.01).unwrap();
        assert_eq!(silent.values, vec![0.0]);
    }

    #[test]
    fn bad_ild_vectors_are_refused_with_the_problem() {
        let e = IldVector::new(vec![1.0, 1.0], vec![0.0, 0.0]).unwrap_err();
        assert!(e.to_string().contains("strictly increasing"), "{e}");
        let e = IldVector::new(vec![1.0], vec![f64::NAN]).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
        let e = IldVector::new(vec![1.0, 2.0], vec![0.0]).unwrap_err();
        assert!(e.to_string().contains("1 values for 2"), "{e}");
        let e = IldVector::from_amplitudes(vec![1.0], &[-1.0], &[1.0], 0.0).unwrap_err();
        assert!(e.to_string().contains("amplitude"), "{e}");
    }

    #[test]
    fn correlation_is_one_for_the_same_direction_zero_for_opposite() {
        let a = [1.0, -2.0, 3.0];
        assert_abs_diff_eq!(correlation(&a, &[2.0, -4.0, 6.0]), 1.0, epsilon = 1e-12);
        assert_abs_diff_eq!(correlation(&a, &[-1.0, 2.0, -3.0]), 0.0, epsilon = 1e-12);
        // Orthogonal: cos = 0 → ½.
        assert_abs_diff_eq!(correlation(&[1.0, 0.0], &[0.0, 5.0]), 0.5, epsilon = 1e-12);
        assert_eq!(correlation(&[0.0, 0.0], &[1.0, 1.0]), 0.5);
        // Hand value: cos = (1·1 + 1·0)/(√2·1) = 0.7071 → 0.85355.
        assert_abs_diff_eq!(
            correlation(&[1.0, 1.0], &[1.0, 0.0]),
            0.853_553_39,
            epsilon = 1e-8
        );
    }

    /// Through the wire observation and back: the frequencies a fingerprint database
    /// expects, the values to f32 precision; uneven bands are refused.
    #[test]
    fn wire_observation_round_trip() {
        let s = IldSettings::default();
        let values: Vec<f64> = (0..s.frequencies).map(|j| (j as f64 * 0.7).sin() * 3.0).collect();
        let v = IldVector::new(s.sampled_frequencies(), values).unwrap();
        let o = v.to_observation(ClusterTime(42)).unwrap();
        assert_eq!(o.ild_db.len(), s.frequencies);
        let back = IldVector::from_observation(&o).unwrap();
        for (a, b) in back.frequencies_hz.iter().zip(&v.frequencies_hz) {
            assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
        }
        for (a, b) in back.values.iter().zip(&v.values) {
            assert_abs_diff_eq!(a, b, epsilon = 1e-6);
        }
        let uneven = IldVector::new(vec![100.0, 200.0, 350.0], vec![0.0; 3]).unwrap();
        assert!(uneven.to_observation(ClusterTime(0)).is_err());
    }

    #[test]
    fn settings_sample_frequencies_inclusive_and_validate() {
        let s = IldSettings {
            f_min_hz: 100.0,
            f_max_hz: 400.0,
            frequencies: 4,
            ..IldSettings::default()
        };
        assert_eq!(s.sampled_frequencies(), vec![100.0, 200.0, 300.0, 400.0]);
        s.validate().unwrap();
        let above = IldSettings {
            f_max_hz: 30_000.0,
            ..IldSettings::default()
        };
        assert!(above.validate().unwrap_err().to_string().contains("24000"));
        let block = IldSettings {
            block_len: 1000,
            ..IldSettings::default()
        };
        assert!(block.validate().unwrap_err().to_string().contains("power of two"));
    }
}
