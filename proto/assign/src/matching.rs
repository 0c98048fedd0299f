//! Maximum-weight matchings over `pathfinding`'s Kuhn–Munkres solver.
//!
//! The solver wants exact (integer) weights and at least as many columns as rows; this module
//! gives it both: float weights are quantised (2⁴⁰ steps over their range, fewer only for
//! matrices with thousands of rows, so that no sum can overflow), and a tall matrix is solved
//! transposed. A forbidden pair has weight 0 and is dropped from the answer, so what comes back
//! only ever pairs allowed entries.

use pathfinding::kuhn_munkres::kuhn_munkres;
use pathfinding::matrix::Matrix;

/// Steps of the quantised weights (about 10⁻¹² of the weight range).
const STEPS: i64 = 1 << 40;

/// A maximum-weight matching over float weights; entry `r` is the column of row `r`.
///
/// `weight(r, c)` is `Some(w)` with `0 ≤ w ≤ max_weight` for an allowed pair and `None` for a
/// forbidden one. With `cardinality_first` the matching first has as many pairs as possible,
/// then the largest total weight among those (py-motmetrics' rule: its solver adds "expensive
/// edges" for forbidden pairs); without, only the total weight counts and a pair of weight 0
/// is as good as none. Optimal up to the quantisation step (≈ `max_weight` × 10⁻¹²).
pub fn max_weight_matching(
    rows: usize,
    cols: usize,
    max_weight: f64,
    cardinality_first: bool,
    weight: impl Fn(usize, usize) -> Option<f64>,
) -> Vec<Option<usize>> {
    let n = rows.min(cols) as i64;
    // n · (bonus + steps) must fit in an i64 with room for the solver's labels.
    let steps = STEPS.min(i64::MAX / 16 / ((n + 1) * (n + 1))).max(1);
    let bonus = if cardinality_first { n * steps + 1 } else { 0 };
    let scale = if max_weight > 0.0 {
        steps as f64 / max_weight
    } else {
        0.0
    };
    let integer = |r: usize, c: usize| match weight(r, c) {
        Some(w) => bonus + ((w * scale).round() as i64).clamp(0, steps),
        None => 0,
    };
    let mut out = solve(rows, cols, integer);
    for (r, c) in out.iter_mut().enumerate() {
        if c.is_some_and(|c| weight(r, c).is_none()) {
            *c = None;
        }
    }
    out
}

/// A maximum-weight matching over non-negative integer weights (exact); pairs of weight 0 are
/// left out of the answer.
pub fn max_weight_matching_exact(
    rows: usize,
    cols: usize,
    weight: impl Fn(usize, usize) -> i64,
) -> Vec<Option<usize>> {
    let mut out = solve(rows, cols, &weight);
    for (r, c) in out.iter_mut().enumerate() {
        if c.is_some_and(|c| weight(r, c) <= 0) {
            *c = None;
        }
    }
    out
}

/// Kuhn–Munkres on a rows × cols weight matrix of any shape; every row of the smaller side is
/// given a partner (possibly through a weight-0 pair, which callers filter).
fn solve(rows: usize, cols: usize, weight: impl Fn(usize, usize) -> i64) -> Vec<Option<usize>> {
    if rows == 0 || cols == 0 {
        return vec![None; rows];
    }
    if rows <= cols {
        let m = Matrix::from_fn(rows, cols, |(r, c)| weight(r, c));
        kuhn_munkres(&m).1.into_iter().map(Some).collect()
    } else {
        let m = Matrix::from_fn(cols, rows, |(c, r)| weight(r, c));
        let mut out = vec![None; rows];
        for (c, r) in kuhn_munkres(&m).1.into_iter().enumerate() {
            out[r] = Some(c);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Best total over all matchings, by enumeration: (pairs, weight) compared lexicographically
    /// when `cardinality_first`, else the weight alone.
    fn brute(w: &[Vec<Option<f64>>], cols: usize, cardinality_first: bool) -> (usize, f64) {
        fn go(
            w: &[Vec<Option<f64>>],
            r: usize,
            used: &mut Vec<bool>,
            acc: (usize, f64),
            best: &mut Vec<(usize, f64)>,
        ) {
            if r == w.len() {
                best.push(acc);
                return;
            }
            go(w, r + 1, used, acc, best);
            for c in 0..used.len() {
                if let (false, Some(x)) = (used[c], w[r][c]) {
                    used[c] = true;
                    go(w, r + 1, used, (acc.0 + 1, acc.1 + x), best);
                    used[c] = false;
                }
            }
        }
        let mut all = Vec::new();
        go(w, 0, &mut vec![false; cols], (0, 0.0), &mut all);
        let key = |a: &(usize, f64)| if cardinality_first { (a.0, a.1) } else { (0, a.1) };
        all.into_iter()
            .max_by(|a, b| key(a).partial_cmp(&key(b)).unwrap())
            .unwrap()
    }

    fn total(w: &[Vec<Option<f64>>], a: &[Option<usize>]) -> (usize, f64) {
        a.iter()
            .enumerate()
            .filter_map(|(r, c)| c.map(|c| w[r][c].expect("allowed")))
            .fold((0, 0.0), |(n, s), x| (n + 1, s + x))
    }

    #[test]
    fn cardinality_first_prefers_more_pairs_over_weight() {
        // Row 0 can pair with column 0 (weight 1.0) or column 1 (0.1); row 1 only with column 0.
        let w = [vec![Some(1.0), Some(0.1)], vec![Some(0.2), None]];
        let get = |r: usize, c: usize| w[r][c];
        assert_eq!(max_weight_matching(2, 2, 1.0, true, get), vec![Some(1), Some(0)]);
        // Without the cardinality rule the heavier single pair (1.0 > 0.1 + 0.2) wins.
        assert_eq!(max_weight_matching(2, 2, 1.0, false, get), vec![Some(0), None]);
    }

    #[test]
    fn tall_and_wide_matrices_agree_with_enumeration() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for case in 0..300 {
            let rows = rng.random_range(0..6);
            let cols = rng.random_range(0..6);
            let w: Vec<Vec<Option<f64>>> = (0..rows)
                .map(|_| {
                    (0..cols)
                        .map(|_| rng.random_bool(0.7).then(|| rng.random_range(0.0..2.0)))
                        .collect()
                })
                .collect();
            for cardinality_first in [false, true] {
                let a = max_weight_matching(rows, cols, 2.0, cardinality_first, |r, c| w[r][c]);
                let mut seen = vec![false; cols];
                for c in a.iter().flatten() {
                    assert!(!seen[*c], "case {case}: column {c} used twice");
                    seen[*c] = true;
                }
                let got = total(&w, &a);
                let best = brute(&w, cols, cardinality_first);
                if cardinality_first {
                    assert_eq!(got.0, best.0, "case {case}: pairs");
                }
                assert!((got.1 - best.1).abs() < 1e-9, "case {case}: {got:?} vs {best:?}");
            }
        }
    }

    #[test]
    fn exact_matching_drops_zero_pairs() {
        let w = [[3, 0, 1], [1, 0, 0]];
        let a = max_weight_matching_exact(2, 3, |r, c| w[r][c]);
        assert_eq!(a, vec![Some(0), None]);
        let t = [[0, 4], [5, 1], [0, 0]];
        assert_eq!(
            max_weight_matching_exact(3, 2, |r, c| t[r][c]),
            vec![Some(1), Some(0), None]
        );
    }
}
