//! Audio → weighted ILD vector (paper 001 eq. 13–15).
//!
//! A frame of both channels is cut into half-overlapping blocks of `block_len` samples, each
//! Hann-windowed and transformed (real FFT); the power of each bin is averaged over the blocks
//! (Welch), so one noisy block does not decide the ILD. Each of the N sampled frequencies ω_j
//! takes the mean power of the bins in its band (the bins nearer to ω_j than to its neighbours,
//! at least the nearest one). Amplitudes are normalised so that white noise of RMS σ reads σ in
//! every bin (power / Σ w²): ε of eq. 15 is then in the signal's own units. The ILD and its
//! Macaulay weights are `proto::acoustic`'s (eq. 13–15).
//!
//! The analyzer allocates its buffers once; analysing a frame allocates only the result.

use proto::acoustic::{AcousticError, IldSettings, IldVector};
use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::Arc;
use thiserror::Error;

/// Why a frame could not be analysed.
#[derive(Debug, Error)]
pub enum IldError {
    #[error("ILD settings: {0}")]
    Settings(#[from] AcousticError),
    #[error("frame of {left} left and {right} right samples: the channels differ in length")]
    ChannelLengths { left: usize, right: usize },
    #[error("frame of {len} samples is shorter than one {block} sample block")]
    TooShort { len: usize, block: usize },
    #[error("no block accumulated: nothing to analyse")]
    Empty,
}

/// Reusable FFT plan, window and buffers for one [`IldSettings`].
pub struct IldAnalyzer {
    settings: IldSettings,
    frequencies: Vec<f64>,
    /// Per sampled frequency, the FFT bins `lo..hi` it averages.
    bands: Vec<(usize, usize)>,
    fft: Arc<dyn RealToComplex<f32>>,
    window: Vec<f32>,
    window_power: f64,
    input: Vec<f32>,
    spectrum: Vec<Complex<f32>>,
    scratch: Vec<Complex<f32>>,
    power_left: Vec<f64>,
    power_right: Vec<f64>,
    blocks: usize,
}

impl std::fmt::Debug for IldAnalyzer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IldAnalyzer")
            .field("settings", &self.settings)
            .field("blocks", &self.blocks)
            .finish_non_exhaustive()
    }
}

impl IldAnalyzer {
    /// # Errors
    /// Invalid settings.
    pub fn new(settings: &IldSettings) -> Result<Self, IldError> {
        settings.validate()?;
        let n = settings.block_len;
        let fft = RealFftPlanner::<f32>::new().plan_fft_forward(n);
        // Periodic Hann window.
        let window: Vec<f32> = (0..n)
            .map(|i| (0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos()) as f32)
            .collect();
        let window_power = window.iter().map(|w| f64::from(*w).powi(2)).sum();
        let frequencies = settings.sampled_frequencies();
        let bin_hz = f64::from(settings.sample_rate) / n as f64;
        let bins = n / 2 + 1;
        let bands = frequencies
            .iter()
            .enumerate()
            .map(|(j, f)| {
                let lower = if j == 0 {
                    *f
                } else {
                    0.5 * (frequencies[j - 1] + f)
                };
                let upper = if j + 1 == frequencies.len() {
                    *f
                } else {
                    0.5 * (f + frequencies[j + 1])
                };
                let nearest = ((f / bin_hz).round() as usize).min(bins - 1);
                let lo = ((lower / bin_hz).ceil() as usize).min(nearest);
                // Bins strictly below the upper edge belong here; the next band starts there.
                let hi = (((upper / bin_hz).ceil() as usize).max(nearest + 1)).min(bins);
                (lo, hi)
            })
            .collect();
        Ok(IldAnalyzer {
            settings: settings.clone(),
            frequencies,
            bands,
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            window,
            window_power,
            power_left: vec![0.0; bins],
            power_right: vec![0.0; bins],
            blocks: 0,
        })
    }

    pub fn settings(&self) -> &IldSettings {
        &self.settings
    }

    /// Add one block (exactly `block_len` samples per channel) to the running power means.
    ///
    /// # Errors
    /// Channels of another length than the block.
    pub fn accumulate(&mut self, left: &[f32], right: &[f32]) -> Result<(), IldError> {
        let n = self.settings.block_len;
        if left.len() != n || right.len() != n {
            return Err(IldError::ChannelLengths {
                left: left.len(),
                right: right.len(),
            });
        }
        for (samples, power) in [(left, 0), (right, 1)] {
            for ((x, s), w) in self.input.iter_mut().zip(samples).zip(&self.window) {
                *x = s * w;
            }
            self.fft
                .process_with_scratch(&mut self.input, &mut self.spectrum, &mut self.scratch)
                .expect("buffers are sized by the plan");
            let acc = if power == 0 {
                &mut self.power_left
            } else {
                &mut self.power_right
            };
            for (p, c) in acc.iter_mut().zip(&self.spectrum) {
                *p += f64::from(c.norm_sqr());
            }
        }
        self.blocks += 1;
        Ok(())
    }

    /// Blocks accumulated since the last [`IldAnalyzer::finish`].
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// The amplitude at each sampled frequency of the accumulated blocks, left and right.
    fn amplitudes(&self) -> (Vec<f64>, Vec<f64>) {
        let scale = 1.0 / (self.blocks as f64 * self.window_power);
        let band = |power: &[f64], (lo, hi): (usize, usize)| {
            let mean = power[lo..hi].iter().sum::<f64>() / (hi - lo) as f64;
            (mean * scale).sqrt()
        };
        self.bands
            .iter()
            .map(|b| (band(&self.power_left, *b), band(&self.power_right, *b)))
            .unzip()
    }

    /// The weighted ILD vector of the accumulated blocks (eq. 13–15); clears them.
    ///
    /// # Errors
    /// No block accumulated.
    pub fn finish(&mut self) -> Result<IldVector, IldError> {
        if self.blocks == 0 {
            return Err(IldError::Empty);
        }
        let (left, right) = self.amplitudes();
        self.power_left.fill(0.0);
        self.power_right.fill(0.0);
        self.blocks = 0;
        Ok(IldVector::from_amplitudes(
            self.frequencies.clone(),
            &left,
            &right,
            self.settings.epsilon,
        )?)
    }

    /// The ILD vector of one frame: all its half-overlapping blocks, averaged.
    ///
    /// # Errors
    /// Channels of different lengths, or a frame shorter than one block.
    pub fn analyze(&mut self, left: &[f32], right: &[f32]) -> Result<IldVector, IldError> {
        if left.len() != right.len() {
            return Err(IldError::ChannelLengths {
                left: left.len(),
                right: right.len(),
            });
        }
        let n = self.settings.block_len;
        if left.len() < n {
            return Err(IldError::TooShort {
                len: left.len(),
                block: n,
            });
        }
        self.power_left.fill(0.0);
        self.power_right.fill(0.0);
        self.blocks = 0;
        for start in block_starts(left.len(), n) {
            self.accumulate(&left[start..start + n], &right[start..start + n])?;
        }
        self.finish()
    }
}

/// Starts of the half-overlapping blocks of `n` samples in a frame of `len`.
pub fn block_starts(len: usize, n: usize) -> impl Iterator<Item = usize> {
    let hop = (n / 2).max(1);
    let count = if len < n { 0 } else { 1 + (len - n) / hop };
    (0..count).map(move |b| b * hop)
}

/// Median wall-clock milliseconds of the ILD of one `block_len`-sample stereo frame (one
/// block: two windowed FFTs, band powers, eq. 13–15) with the default settings, over `iters`
/// frames.
#[allow(clippy::disallowed_methods)] // a bench owns its clock; the analyzer it times does not
pub fn bench_ild(iters: usize) -> f64 {
    let settings = IldSettings::default();
    let mut analyzer = IldAnalyzer::new(&settings).expect("default settings are valid");
    let n = settings.block_len;
    // A deterministic broadband signal: a chirp-like sum, the right channel 3 dB down.
    let left: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f32 / settings.sample_rate as f32;
            0.3 * (2.0 * std::f32::consts::PI * (300.0 + 4000.0 * t) * t * 40.0).sin()
        })
        .collect();
    let right: Vec<f32> = left.iter().map(|v| v * 0.708).collect();
    let mut times: Vec<f64> = (0..iters.max(1) + iters / 10)
        .map(|_| {
            let start = std::time::Instant::now();
            std::hint::black_box(analyzer.analyze(&left, &right).expect("one full block"));
            start.elapsed().as_secs_f64() * 1e3
        })
        .skip(iters / 10)
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Ten sampled frequencies on exact FFT bins, 10 bins apart (468.75 Hz at 48 kHz / 1024).
    fn settings() -> IldSettings {
        IldSettings {
            sample_rate: 48_000,
            block_len: 1024,
            f_min_hz: 468.75,
            f_max_hz: 4687.5,
            frequencies: 10,
            epsilon: 0.01,
        }
    }

    /// Sines at every sampled frequency, the right channel `d_j` dB quieter at ω_j: the ILD
    /// vector divided by its weights is d_j.
    #[test]
    fn ild_of_a_stereo_signal_with_known_level_differences() {
        let s = settings();
        let freqs = s.sampled_frequencies();
        let d: Vec<f64> = (0..10).map(|j| -6.0 + 1.7 * j as f64).collect();
        let len = 8192;
        let mut left = vec![0.0f32; len];
        let mut right = vec![0.0f32; len];
        for (j, f) in freqs.iter().enumerate() {
            let phase = 0.37 * j as f64;
            let gain = 10f64.powf(-d[j] / 20.0);
            for i in 0..len {
                let v = 0.05 * (2.0 * std::f64::consts::PI * f * i as f64 / 48_000.0 + phase).sin();
                left[i] += v as f32;
                right[i] += (v * gain) as f32;
            }
        }
        let mut a = IldAnalyzer::new(&s).unwrap();
        let ild = a.analyze(&left, &right).unwrap();
        assert_eq!(ild.frequencies_hz, freqs);
        // Recover ΔS_j = value / a_j with a_j from the same amplitudes.
        for start in block_starts(len, 1024) {
            a.accumulate(&left[start..start + 1024], &right[start..start + 1024])
                .unwrap();
        }
        let (l, r) = a.amplitudes();
        for j in 0..10 {
            let weight = proto::acoustic::macaulay_weight(l[j], r[j], 0.01);
            assert!(weight > 0.0);
            assert_abs_diff_eq!(ild.values[j] / weight, d[j], epsilon = 0.01);
        }
    }

    /// White noise in both channels, the right at half the amplitude: 6.02 dB at every
    /// frequency, and the amplitude reads the noise's RMS.
    #[test]
    fn ild_of_scaled_white_noise_is_flat() {
        let s = settings();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.2).unwrap();
        let left: Vec<f32> = (0..48_000).map(|_| noise.sample(&mut rng) as f32).collect();
        let right: Vec<f32> = left.iter().map(|v| v * 0.5).collect();
        let mut a = IldAnalyzer::new(&s).unwrap();
        let ild = a.analyze(&left, &right).unwrap();
        for start in block_starts(left.len(), 1024) {
            a.accumulate(&left[start..start + 1024], &right[start..start + 1024])
                .unwrap();
        }
        let (l, r) = a.amplitudes();
        for j in 0..10 {
            assert_abs_diff_eq!(
                proto::acoustic::level_difference_db(l[j], r[j]),
                6.0206,
                epsilon = 1e-4
            );
            assert!(
                (l[j] - 0.2).abs() < 0.04,
                "band {j}: amplitude {} for RMS 0.2",
                l[j]
            );
            assert!(ild.values[j] > 0.0);
        }
    }

    /// A frequency one microphone does not hear gets weight 0 (Macaulay bracket), the others
    /// keep theirs.
    #[test]
    fn macaulay_weighting_silences_a_frequency_one_channel_lacks() {
        let s = settings();
        let freqs = s.sampled_frequencies();
        let len = 4096;
        let mut left = vec![0.0f32; len];
        let mut right = vec![0.0f32; len];
        for (j, f) in freqs.iter().enumerate() {
            for i in 0..len {
                let v = (0.05 * (2.0 * std::f64::consts::PI * f * i as f64 / 48_000.0).sin()) as f32;
                left[i] += v;
                if j != 4 {
                    right[i] += 0.5 * v;
                }
            }
        }
        let ild = IldAnalyzer::new(&s).unwrap().analyze(&left, &right).unwrap();
        assert_eq!(ild.values[4], 0.0);
        assert!(ild.values.iter().enumerate().all(|(j, v)| j == 4 || *v > 0.0));
    }

    #[test]
    fn bad_frames_are_refused() {
        let mut a = IldAnalyzer::new(&settings()).unwrap();
        assert!(matches!(
            a.analyze(&[0.0; 2000], &[0.0; 1999]),
            Err(IldError::ChannelLengths { .. })
        ));
        assert!(matches!(
            a.analyze(&[0.0; 500], &[0.0; 500]),
            Err(IldError::TooShort { .. })
        ));
        assert!(matches!(a.finish(), Err(IldError::Empty)));
        let bad = IldSettings {
            block_len: 1000,
            ..settings()
        };
        assert!(IldAnalyzer::new(&bad).is_err());
        assert_eq!(block_starts(2048, 1024).collect::<Vec<_>>(), vec![0, 512, 1024]);
    }

    #[test]
    fn bench_ild_runs() {
        let ms = bench_ild(3);
        assert!(ms.is_finite() && ms > 0.0);
    }
}
