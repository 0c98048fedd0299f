//! Timing of the tracker's hot path, for `ocelli bench camera`: milliseconds per frame of
//! [`MultiTracker::step`] on synthetic frames ([`Scene::crowd`]: coloured people moving over a
//! noisy background), with each person's true box as its foreground region and a foreground
//! mask drawn from the same boxes. Drawing the frames is not timed; neither is the background
//! model (`adaptive_background`, timed on its own). The feet ([`crate::tracker::feet`]: each
//! person's lower edge in the mask) are timed apart, on the step's people.

use crate::region::Grid;
use crate::tracker::feet;
use crate::tracker::manager::{Foreground, MultiTracker, TrackerInput};
use crate::tracker::params::ParticleParams;
use crate::tracker::scene::Scene;
use proto::ClusterTime;
use proto::msg::PixelBox;
use proto::sensor::Frame;
use proto::sensor::{Detection, rgb_to_hsi};

/// The frame rate the benchmark's tracker is told (its waits only; frames come as fast as it
/// runs).
const BENCH_FPS: f64 = 15.0;
use std::time::Instant;

/// Frames run before timing starts (filters start after `init-frames`).
const WARMUP_FRAMES: u32 = 5;

/// What one timing run measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BenchResult {
    pub median_ms: f64,
    pub p90_ms: f64,
    /// Median microseconds per frame of the people's lower edges ([`feet::lower_edges`]) and
    /// whose they are ([`feet::anothers_feet`]).
    pub feet_median_us: f64,
    /// Filters running at the end (should equal the people drawn).
    pub filters: usize,
}

fn region(b: &PixelBox) -> Detection {
    let bbox = PixelBox {
        xmin: b.xmin.ceil(),
        ymin: b.ymin.ceil(),
        xmax: b.xmax.floor(),
        ymax: b.ymax.floor(),
    };
    let area = ((bbox.xmax - bbox.xmin + 1.0) * (bbox.ymax - bbox.ymin + 1.0)).max(0.0) as u32;
    Detection {
        centre: [0.5 * (bbox.xmin + bbox.xmax), 0.5 * (bbox.ymin + bbox.ymax)],
        foot: [0.5 * (bbox.xmin + bbox.xmax), bbox.ymax],
        bbox,
        area,
        colour: rgb_to_hsi(0.0, 0.0, 0.0),
    }
}

/// Median milliseconds per frame for `people` people with `params` at `width × height`, over
/// `frames` timed frames, timed by the wall clock; also the 90th percentile, the feet's time
/// and the filters running.
#[allow(clippy::disallowed_methods)] // a bench reads the clock; the tracker it times does not
pub fn bench_with(
    params: &ParticleParams,
    width: u32,
    height: u32,
    people: usize,
    frames: usize,
) -> BenchResult {
    let origin = Instant::now();
    let mut wall_ms = || origin.elapsed().as_secs_f64() * 1e3;
    bench_timed(params, width, height, people, frames, &mut wall_ms)
}

/// [`bench_with`] timed by any clock in milliseconds — e.g. the thread's CPU time, which a
/// shared machine's preemption does not inflate.
pub fn bench_timed(
    params: &ParticleParams,
    width: u32,
    height: u32,
    people: usize,
    frames: usize,
    now_ms: &mut dyn FnMut() -> f64,
) -> BenchResult {
    let scene = Scene::crowd(width.max(16), height.max(16), people);
    let (w, h) = (scene.width, scene.height);
    let grid = Grid::new(w, h, 1);
    let Ok(mut tracker) = MultiTracker::new(params.clone(), BENCH_FPS, 1) else {
        return BenchResult {
            median_ms: f64::NAN,
            p90_ms: f64::NAN,
            feet_median_us: f64::NAN,
            filters: 0,
        };
    };
    let mut frame = Frame::new(w, h, ClusterTime::ZERO);
    let mut mask = vec![0u8; grid.len()];
    let mut times = Vec::with_capacity(frames);
    let mut feet_times = Vec::with_capacity(frames);
    for t in 0..WARMUP_FRAMES + frames.max(1) as u32 {
        scene.render(t, &mut frame);
        let boxes: Vec<PixelBox> = (0..people).map(|i| scene.box_at(i, t)).collect();
        let regions: Vec<Detection> = boxes.iter().map(region).collect();
        mask.fill(0);
        for d in &regions {
            let b = d.bbox;
            for y in b.ymin as usize..=(b.ymax as usize).min(h as usize - 1) {
                let row = y * w as usize;
                mask[row + b.xmin as usize..=row + (b.xmax as usize).min(w as usize - 1)].fill(1);
            }
        }
        let foreground = Foreground::new(&mask, grid).ok();
        let input = TrackerInput {
            frame: &frame,
            regions: &regions,
            foreground,
            with_samples: false,
        };
        let start = now_ms();
        let out = tracker.step(&input);
        let elapsed = now_ms() - start;
        let people = std::hint::black_box(out).unwrap_or_default();
        let start = now_ms();
        let edges = feet::lower_edges(&people, &regions, foreground.as_ref());
        let theirs = edges
            .iter()
            .enumerate()
            .filter(|&(i, e)| e.is_some_and(|e| feet::anothers_feet(&people, i, e)))
            .count();
        std::hint::black_box((edges, theirs));
        let feet_elapsed = now_ms() - start;
        if t >= WARMUP_FRAMES {
            times.push(elapsed);
            feet_times.push(feet_elapsed);
        }
    }
    times.sort_by(f64::total_cmp);
    feet_times.sort_by(f64::total_cmp);
    BenchResult {
        median_ms: times[times.len() / 2],
        p90_ms: times[(times.len() * 9 / 10).min(times.len() - 1)],
        feet_median_us: feet_times[feet_times.len() / 2] * 1e3,
        filters: tracker.ids().len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bench_runs_a_filter_per_person() {
        let params = ParticleParams {
            particles: 20,
            ..ParticleParams::default()
        };
        let r = bench_with(&params, 160, 120, 3, 3);
        assert_eq!(r.filters, 3);
        assert!(r.median_ms.is_finite() && r.median_ms >= 0.0 && r.p90_ms >= r.median_ms);
        assert!(r.feet_median_us.is_finite() && r.feet_median_us >= 0.0);
        assert!(bench_with(&params, 64, 48, 0, 2).median_ms.is_finite());
    }
}
