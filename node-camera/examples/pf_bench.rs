//! Prints the particle filter tracker's milliseconds per frame (median) for 1, 5 and 10
//! people × 100 particles at 320×240 and 640×480, as `ocelli bench camera` will report them.
//! Run with `cargo run --release -p node-camera --example pf_bench [frames] [budgets,…]`.
//!
//! Timed by this thread's CPU clock (`CLOCK_THREAD_CPUTIME_ID`), so other processes on a
//! shared machine do not inflate it.

use node_camera::tracker::bench::bench_timed;
use node_camera::tracker::params::ParticleParams;

/// CPU time this thread has used, milliseconds.
#[allow(unsafe_code)]
fn cpu_ms() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec owned by this frame.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0;
    if ok {
        ts.tv_sec as f64 * 1e3 + ts.tv_nsec as f64 * 1e-6
    } else {
        f64::NAN
    }
}

fn main() {
    let frames = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(200);
    let budgets: Vec<u32> = std::env::args()
        .nth(2)
        .map(|a| a.split(',').filter_map(|v| v.parse().ok()).collect())
        .unwrap_or_else(|| vec![ParticleParams::default().histogram_pixels]);
    for budget in budgets {
        for (w, h) in [(320u32, 240u32), (640, 480)] {
            for people in [1usize, 5, 10] {
                let params = ParticleParams {
                    histogram_pixels: budget,
                    ..ParticleParams::default()
                };
                let r = bench_timed(&params, w, h, people, frames, &mut cpu_ms);
                println!(
                    "pf_ms_per_frame_{w}x{h}_{people}x100 histogram-pixels={budget}: median {:.3} ms, p90 {:.3} ms, filters {}",
                    r.median_ms, r.p90_ms, r.filters
                );
            }
        }
    }
}
