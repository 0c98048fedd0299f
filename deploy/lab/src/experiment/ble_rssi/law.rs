//! The room's RSSI law from real packets: a least-squares fit of `RSSI = a log10 d + b` (paper
//! 002 eq. 2), its error on held-out packets, and the structure of the residuals — a per-sensor
//! offset, a smooth location-dependent part and per-packet noise — in the terms of our simulated
//! radio (`proto::scenario::RadioWorld`: a Gaussian field of sd σ and correlation length l,
//! covariance σ² exp(−r²/2l²), plus white noise τ).

use super::data::{Dataset, Packet};
use nalgebra::Vector3;
use proto::models::{RSSI_MIN_DISTANCE_M, RssiModel, fit_log_distance};

/// Sensor–beacon distance, m, clamped as the models clamp it.
pub fn distance(sensor: &Vector3<f64>, beacon: &Vector3<f64>) -> f64 {
    (beacon - sensor).norm().max(RSSI_MIN_DISTANCE_M)
}

/// A fitted log-distance law with its residual sd (dB) and packet count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogFit {
    pub a: f64,
    pub b: f64,
    pub sd_db: f64,
    pub n: usize,
}

impl LogFit {
    /// As the filter's model, with the fit's residual variance as σ²_D.
    pub fn model(&self) -> RssiModel {
        RssiModel::LogDistance {
            a: self.a,
            b: self.b,
            variance: self.sd_db * self.sd_db,
        }
    }

    /// Path-loss exponent n with `a = −10 n`.
    pub fn exponent(&self) -> f64 {
        -self.a / 10.0
    }
}

/// (distance, RSSI) of packets against the dataset's sensors.
pub fn pairs<'a>(
    ds: &'a Dataset,
    packets: impl Iterator<Item = &'a Packet> + 'a,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    packets.map(|p| (distance(&ds.sensors[p.sensor].pos, &p.truth), p.rssi))
}

/// Ordinary least squares of RSSI on log10 d (`proto::models::fit_log_distance`, the survey's
/// fit). `None` with fewer than three pairs or no spread in distance.
pub fn fit_log(pairs: impl Iterator<Item = (f64, f64)>) -> Option<LogFit> {
    let pairs: Vec<(f64, f64)> = pairs.collect();
    let RssiModel::LogDistance { a, b, variance } = fit_log_distance(&pairs)? else {
        return None;
    };
    Some(LogFit {
        a,
        b,
        sd_db: variance.sqrt(),
        n: pairs.len(),
    })
}

/// Root-mean-square and mean of `RSSI − model(d)`, dB. `None` without pairs.
pub fn error_db(model: &RssiModel, pairs: impl Iterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    let (mut n, mut s, mut s2) = (0usize, 0.0, 0.0);
    for (d, r) in pairs {
        let e = r - model.predict(d);
        n += 1;
        s += e;
        s2 += e * e;
    }
    (n > 0).then(|| ((s2 / n as f64).sqrt(), s / n as f64))
}

/// The residual structure of a law over a dataset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Structure {
    /// sd of all residuals, dB.
    pub total_db: f64,
    /// sd of the sensors' mean residuals (a constant offset per sensor), dB.
    pub sensor_offset_db: f64,
    /// Smooth location-dependent part within a sensor (the field's σ), dB.
    pub smooth_db: f64,
    /// Per-packet noise (the nugget τ), dB.
    pub noise_db: f64,
    /// Correlation length l of the smooth part, m.
    pub length_m: f64,
    /// ½ mean squared difference of same-sensor residuals under [`BIN_M`] apart, dB² (the
    /// direct nugget estimate).
    pub close_semivariance_db2: f64,
    /// ½ mean squared difference of a sensor's consecutive packets of one trajectory under
    /// [`CONSECUTIVE_S`] apart, dB² (the nugget seen in time instead of space).
    pub consecutive_semivariance_db2: f64,
}

/// Largest gap between two packets counted as consecutive, s.
pub const CONSECUTIVE_S: f64 = 0.6;

/// Width of a semivariogram bin, m.
pub const BIN_M: f64 = 0.1;
/// Largest horizontal separation the semivariogram is fitted over, m.
pub const MAX_LAG_M: f64 = 6.0;

/// Empirical semivariogram of same-sensor residuals against the horizontal distance between the
/// beacon positions of the two packets (pairs across all trajectories): per bin of [`BIN_M`],
/// (bin centre m, γ dB², pairs).
pub fn semivariogram(residuals: &[Vec<(f64, f64, f64)>]) -> Vec<(f64, f64, usize)> {
    let bins = (MAX_LAG_M / BIN_M).round() as usize;
    let mut sum = vec![0.0; bins];
    let mut count = vec![0usize; bins];
    for sensor in residuals {
        for (i, p) in sensor.iter().enumerate() {
            for q in &sensor[i + 1..] {
                let r = ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt();
                let k = (r / BIN_M) as usize;
                if k < bins {
                    sum[k] += 0.5 * (p.2 - q.2).powi(2);
                    count[k] += 1;
                }
            }
        }
    }
    (0..bins)
        .filter(|&k| count[k] > 0)
        .map(|k| ((k as f64 + 0.5) * BIN_M, sum[k] / count[k] as f64, count[k]))
        .collect()
}

/// Fit γ(r) = τ² + σ²(1 − exp(−r²/2l²)) to a semivariogram by pair-weighted least squares:
/// a grid over l, τ² and σ² linear (and non-negative) for each l. Returns (τ², σ², l).
pub fn fit_semivariogram(bins: &[(f64, f64, usize)]) -> Option<(f64, f64, f64)> {
    let mut best: Option<(f64, (f64, f64, f64))> = None;
    for step in 1..=200 {
        let l = 0.05 * f64::from(step);
        let (mut sww, mut swg, mut swgg, mut swy, mut swgy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(r, y, n) in bins {
            let w = n as f64;
            let g = 1.0 - (-r * r / (2.0 * l * l)).exp();
            sww += w;
            swg += w * g;
            swgg += w * g * g;
            swy += w * y;
            swgy += w * g * y;
        }
        let det = sww * swgg - swg * swg;
        if sww <= 0.0 || det.abs() < 1e-12 {
            continue;
        }
        let (mut tau2, mut sig2) = ((swgg * swy - swg * swgy) / det, (sww * swgy - swg * swy) / det);
        if tau2 < 0.0 {
            tau2 = 0.0;
            sig2 = (swgy / swgg).max(0.0);
        } else if sig2 < 0.0 {
            sig2 = 0.0;
            tau2 = swy / sww;
        }
        let sse: f64 = bins
            .iter()
            .map(|&(r, y, n)| n as f64 * (y - tau2 - sig2 * (1.0 - (-r * r / (2.0 * l * l)).exp())).powi(2))
            .sum();
        if best.is_none_or(|(s, _)| sse < s) {
            best = Some((sse, (tau2, sig2, l)));
        }
    }
    best.map(|(_, p)| p)
}

/// The residual structure of `model` over every packet of the dataset.
pub fn structure(ds: &Dataset, model: &RssiModel) -> Option<Structure> {
    let mut per_sensor: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new(); ds.sensors.len()];
    let (mut consecutive, mut n_consecutive) = (0.0, 0usize);
    for traj in &ds.trajectories {
        let mut last: Vec<Option<(f64, f64)>> = vec![None; ds.sensors.len()];
        for p in &traj.packets {
            let d = distance(&ds.sensors[p.sensor].pos, &p.truth);
            let e = p.rssi - model.predict(d);
            per_sensor[p.sensor].push((p.truth.x, p.truth.y, e));
            if let Some((t, e0)) = last[p.sensor]
                && p.t - t < CONSECUTIVE_S
            {
                consecutive += 0.5 * (e - e0).powi(2);
                n_consecutive += 1;
            }
            last[p.sensor] = Some((p.t, e));
        }
    }
    let all: Vec<f64> = per_sensor.iter().flatten().map(|p| p.2).collect();
    let (_, total) = super::super::runner::mean_std(&all)?;
    let means: Vec<f64> = per_sensor
        .iter()
        .filter(|s| !s.is_empty())
        .map(|s| s.iter().map(|p| p.2).sum::<f64>() / s.len() as f64)
        .collect();
    let (_, offset) = super::super::runner::mean_std(&means)?;
    let bins = semivariogram(&per_sensor);
    let close = bins.first().filter(|b| b.0 < BIN_M)?.1;
    let (tau2, sig2, l) = fit_semivariogram(&bins)?;
    Some(Structure {
        total_db: total,
        sensor_offset_db: offset,
        smooth_db: sig2.sqrt(),
        noise_db: tau2.sqrt(),
        length_m: l,
        close_semivariance_db2: close,
        consecutive_semivariance_db2: consecutive / n_consecutive.max(1) as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn fit_log_recovers_a_noisy_law() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 2.0).expect("valid sd");
        let pairs: Vec<(f64, f64)> = (0..2000)
            .map(|k| {
                let d = 0.5 + f64::from(k % 200) * 0.05;
                (d, -26.0 * d.log10() - 48.0 + noise.sample(&mut rng))
            })
            .collect();
        let f = fit_log(pairs.into_iter()).expect("fits");
        assert!((f.a + 26.0).abs() < 0.6, "{f:?}");
        assert!((f.b + 48.0).abs() < 0.4, "{f:?}");
        assert!((f.sd_db - 2.0).abs() < 0.15, "{f:?}");
        assert!((f.exponent() - 2.6).abs() < 0.06);
    }

    #[test]
    fn fit_log_needs_spread_in_distance() {
        assert!(fit_log([(2.0, -60.0), (2.0, -61.0), (2.0, -59.0)].into_iter()).is_none());
        assert!(fit_log([(2.0, -60.0), (3.0, -61.0)].into_iter()).is_none());
    }

    #[test]
    fn error_db_is_rms_and_bias() {
        let m = RssiModel::Linear {
            a: 0.0,
            b: -60.0,
            variance: 1.0,
        };
        let (rmse, bias) =
            error_db(&m, [(1.0, -57.0), (2.0, -63.0), (3.0, -57.0)].into_iter()).expect("pairs");
        assert!((bias - 1.0).abs() < 1e-12);
        assert!((rmse - 3.0).abs() < 1e-12);
    }

    #[test]
    fn semivariogram_fit_recovers_nugget_sill_and_length() {
        // Exact model values on the bin grid: the fit must land on the generating parameters.
        let bins: Vec<(f64, f64, usize)> = (0..60)
            .map(|k| {
                let r = (f64::from(k) + 0.5) * BIN_M;
                (r, 4.0 + 25.0 * (1.0 - (-r * r / (2.0 * 1.5 * 1.5)).exp()), 100)
            })
            .collect();
        let (tau2, sig2, l) = fit_semivariogram(&bins).expect("fits");
        assert!((tau2 - 4.0).abs() < 0.05, "{tau2}");
        assert!((sig2 - 25.0).abs() < 0.1, "{sig2}");
        assert!((l - 1.5).abs() < 0.026, "{l}");
    }

    #[test]
    fn semivariogram_of_white_noise_is_flat_at_its_variance() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let noise = Normal::new(0.0, 3.0).expect("valid sd");
        let pts: Vec<(f64, f64, f64)> = (0..800)
            .map(|_| {
                let (x, y): (f64, f64) = (rng.random_range(0.0..6.0), rng.random_range(0.0..6.0));
                (x, y, noise.sample(&mut rng))
            })
            .collect();
        let bins = semivariogram(&[pts]);
        for &(r, g, n) in bins.iter().filter(|b| b.2 >= 300) {
            assert!((g - 9.0).abs() < 2.0, "flat at 9 dB², bin {r} m: {g} over {n}");
        }
        let (tau2, sig2, _) = fit_semivariogram(&bins).expect("fits");
        assert!((tau2 + sig2 - 9.0).abs() < 1.0, "{tau2} + {sig2}");
    }
}
