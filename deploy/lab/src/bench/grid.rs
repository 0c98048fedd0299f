//! `ocelli bench grid`: paper 001's hot paths — one predict + correct of the grid estimator on
//! 200 × 200 cells (goal: at most 2 ms on one core), and the ILD of one 1024-sample stereo
//! frame (two windowed FFTs, band powers, eq. 13–15).

use serde_json::{Value, json};

/// Time both; `scale` multiplies the repetitions.
pub fn run(scale: f64) -> Value {
    let iters = |n: f64| ((n * scale).round() as usize).max(3);
    let update_ms = node_head::grid::bench::bench_update(200, 200, iters(200.0));
    let ild_ms = node_acoustic::bench_ild(iters(2000.0));
    json!({
        "grid_update_ms_200x200": update_ms,
        "grid_update_goal_ms": 2.0,
        "ild_ms_1024_samples": ild_ms,
    })
}

#[cfg(test)]
mod tests {
    /// Runs and reports finite, positive times (their values are measured, not asserted).
    #[test]
    fn grid_bench_runs() {
        let v = super::run(0.01);
        for key in ["grid_update_ms_200x200", "ild_ms_1024_samples"] {
            let ms = v[key].as_f64().unwrap();
            assert!(ms.is_finite() && ms > 0.0, "{key}: {ms}");
        }
    }
}
