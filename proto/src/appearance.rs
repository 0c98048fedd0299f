//! How alike two people look: paper 004's colour histograms (HS 10×10 then V 10 bins, each
//! part summing to its share of 1) compared with the Bhattacharyya coefficient on HS and on V,
//! blended 70:30 (eq. 6 with the paper's weights). The camera's particle filter keeps its own
//! fixed-size histograms; this is for the wire form (`TrackReport::appearance`), where the
//! server tells people apart.

use crate::observation::{HISTOGRAM_BINS as BINS, HISTOGRAM_HS_BINS as HS_BINS};

/// The HS part's weight in the blend (paper 004 §2.3).
pub const HS_WEIGHT: f32 = 0.7;

/// The blended Bhattacharyya coefficient of two appearances in `[0, 1]` (1: the same
/// colours); `None` when either is not a whole histogram (empty: nobody sent one).
pub fn similarity(a: &[f32], b: &[f32]) -> Option<f32> {
    if a.len() != BINS || b.len() != BINS {
        return None;
    }
    let rho = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p.max(0.0) * q.max(0.0)).sqrt())
            .sum::<f32>()
    };
    // Each part is normalized on its own, so a histogram whose parts carry other shares than
    // the camera's still compares in [0, 1].
    let part = |x: &[f32]| x.iter().map(|v| v.max(0.0)).sum::<f32>();
    let (hs_a, v_a) = (part(&a[..HS_BINS]), part(&a[HS_BINS..]));
    let (hs_b, v_b) = (part(&b[..HS_BINS]), part(&b[HS_BINS..]));
    if hs_a <= 0.0 || hs_b <= 0.0 || v_a <= 0.0 || v_b <= 0.0 {
        return None;
    }
    let hs = rho(&a[..HS_BINS], &b[..HS_BINS]) / (hs_a * hs_b).sqrt();
    let v = rho(&a[HS_BINS..], &b[HS_BINS..]) / (v_a * v_b).sqrt();
    Some((HS_WEIGHT * hs + (1.0 - HS_WEIGHT) * v).clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::{HISTOGRAM_BINS as BINS, HISTOGRAM_HS_BINS as HS_BINS};

    fn hist(hs_bin: usize, v_bin: usize) -> Vec<f32> {
        let mut h = vec![0.0; BINS];
        h[hs_bin] = 0.5;
        h[HS_BINS + v_bin] = 0.5;
        h
    }

    #[test]
    fn identical_is_one_disjoint_is_zero_and_the_parts_blend_70_30() {
        let a = hist(3, 2);
        assert!((similarity(&a, &a).unwrap() - 1.0).abs() < 1e-6);
        assert!(similarity(&a, &hist(40, 7)).unwrap().abs() < 1e-6);
        // Same hue and saturation, other brightness: only the HS part agrees.
        assert!((similarity(&a, &hist(3, 7)).unwrap() - 0.7).abs() < 1e-6);
        assert!((similarity(&a, &hist(40, 2)).unwrap() - 0.3).abs() < 1e-6);
    }

    #[test]
    fn a_missing_or_malformed_histogram_compares_to_nothing() {
        let a = hist(3, 2);
        assert_eq!(similarity(&a, &[]), None);
        assert_eq!(similarity(&a, &a[..50]), None);
        assert_eq!(similarity(&a, &vec![0.0; BINS]), None);
    }

    #[test]
    fn half_way_between_two_colours_is_half_alike_to_each() {
        let a = hist(3, 2);
        let b = hist(40, 7);
        let mix: Vec<f32> = a.iter().zip(&b).map(|(x, y)| 0.5 * (x + y)).collect();
        let s = similarity(&a, &mix).unwrap();
        assert!((s - 0.5f32.sqrt()).abs() < 1e-5, "{s}");
    }
}
