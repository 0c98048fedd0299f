//! `ocelli bench camera`: how long a camera node takes per frame for segmentation +
//! undistortion + contribution, per pipeline, at 640×480 and 352×288, on one core.
//!
//! Frames are rendered by the synthetic world (camera 10 of the default scenario, three
//! targets walking, the intrinsics scaled for 640×480); rendering is timed apart. Each frame
//! goes through `CameraNode::on_frame` (segmentation, undistortion, gating) and one
//! `on_message(Priors)` with every target (linearization into Ω_i, ξ_i). The process pins itself to
//! one CPU and runs single-threaded. Prints JSON, with paper 004's particle-filter and
//! background-model figures ([`super::particle`]).

use crate::Result;
use crate::error::OrFailed as _;
use node_camera::config::CameraConfig;
use node_camera::core::{CameraInput, CameraNode};
use node_camera::segment::{SegmentParams, Segmenter, recommended_step};
use proto::msg::{Message, Prior, Priors};
use proto::node::{Input, Node};
use proto::scenario::{Fusion, Scenario, Segmentation};
use proto::sensor::Frame;
use proto::{ClusterTime, Envelope, NodeId, TargetId, models};
use serde_json::json;
use std::time::Instant;
use world::render::Renderer;
use world::{Target, Trajectory};

/// What to measure and how long.
#[derive(Clone, Debug)]
pub struct Options {
    /// Frames timed per configuration (after a warm-up of 20).
    pub frames: usize,
    /// CPU to pin to.
    pub cpu: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options { frames: 200, cpu: 0 }
    }
}

/// Pin the calling thread to one CPU; returns whether it worked.
#[allow(unsafe_code)]
fn pin_to(cpu: usize) -> bool {
    // SAFETY: `set` is a plain bitmask owned by this frame; sched_setaffinity only reads it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

/// VmRSS and VmHWM of this process, KiB.
pub fn memory_kib() -> (u64, u64) {
    let text = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        text.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn bench_scenario(width: u32, height: u32) -> Result<Scenario> {
    let mut s = Scenario::default_scenario();
    s.method.fusion = Fusion::DistributedEif;
    let node = s.nodes.iter_mut().find(|n| n.id == 10).or_failed("camera 10")?;
    let cam = node.camera.as_mut().or_failed("camera 10 geometry")?;
    let k = cam.intrinsics.as_mut().or_failed("intrinsics")?;
    let scale = width as f64 / k.width as f64;
    (k.fx, k.fy, k.cx, k.cy) = (k.fx * scale, k.fy * scale, k.cx * scale, k.cy * scale);
    (k.width, k.height) = (width, height);
    // Two more people-sized targets crossing the view.
    let mut targets = world::targets(&s)?;
    targets.push(Target {
        id: 2,
        trajectory: Trajectory::Loop {
            waypoints: vec![[2.0, 1.5], [4.5, 3.5], [2.5, 4.0]],
            speed: 0.7,
            pauses: Vec::new(),
        },
        size: [0.4, 0.4, 1.7],
        colour: [40, 90, 200],
        rssi_tag: true,
    });
    targets.push(Target {
        id: 3,
        trajectory: Trajectory::Loop {
            waypoints: vec![[4.0, 1.0], [3.0, 3.0]],
            speed: 0.5,
            pauses: Vec::new(),
        },
        size: [0.5, 0.5, 1.2],
        colour: [60, 170, 60],
        rssi_tag: true,
    });
    world::set_targets(&mut s, &targets);
    Ok(s)
}

struct Outcome {
    render_median_ms: f64,
    median_ms: f64,
    segment_median_ms: f64,
    p90_ms: f64,
    detections_per_frame: f64,
    camera_contributions: f64,
}

#[allow(clippy::disallowed_methods)] // a bench reads the clock; the core it times does not
fn run_one(s: &Scenario, kind: Segmentation, step: u32, frames: usize) -> Result<Outcome> {
    let mut cfg = CameraConfig::from_scenario(s, 10)?;
    let width = cfg.camera.intrinsics.width;
    cfg.segment = SegmentParams::for_scenario(s, width);
    cfg.segment.kind = kind;
    cfg.segment.colour_difference.step = step;
    cfg.segment.adaptive_background.step = step;
    let min = (48 * width * width / (352 * 352) / (step * step)).max(4);
    cfg.segment.colour_difference.min_pixels = min;
    cfg.segment.adaptive_background.min_pixels = min;
    let renderer = Renderer::for_node(s, 10, 11)?;
    let targets = world::targets(s)?;
    // The same pipeline alone, to split segmentation from the rest.
    let mut alone = Segmenter::new(&cfg.segment);
    let mut dets = Vec::new();
    let mut seg_times = Vec::with_capacity(frames);
    let mut render_times = Vec::with_capacity(frames);
    let mut node = CameraNode::new(cfg, ClusterTime::ZERO);
    let mut frame = Frame::new(0, 0, ClusterTime::ZERO);
    let mut times = Vec::with_capacity(frames);
    let warmup = 20;
    let mut contributions = 0u64;
    for k in 0..warmup + frames {
        let t = k as f64 * 0.2;
        let now = ClusterTime::from_secs_f64(t);
        let start = Instant::now();
        renderer.render(&targets, t, now, &mut frame);
        let render_elapsed = start.elapsed().as_secs_f64() * 1e3;
        let priors = Envelope {
            source: NodeId(2),
            seq: k as u64,
            time: now,
            body: Message::Priors(Priors {
                part: 0,
                parts: 1,
                tracks: targets
                    .iter()
                    .map(|tg| Prior {
                        target: TargetId(tg.id),
                        step: k as u64,
                        mean: models::vec6_to_wire(&tg.truth_at(t)),
                        cov: models::mat6_to_wire(&(nalgebra::Matrix6::identity() * 0.04)),
                        deadline: now + 80_000_000,
                        radio: false,
                    })
                    .collect(),
            }),
        };
        // The core takes the frame by value; the copy is made before the clock starts.
        let input = Input::Sensor(CameraInput::Frame(frame.clone()));
        let start = Instant::now();
        let mut out = node.handle(now, input);
        out.extend(node.handle(now, Input::Message(priors)));
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        alone.process(&frame, &mut dets)?;
        let seg_elapsed = start.elapsed().as_secs_f64() * 1e3;
        if k >= warmup {
            seg_times.push(seg_elapsed);
            render_times.push(render_elapsed);
            times.push(elapsed);
            contributions += out
                .iter()
                .filter_map(|o| match &o.body {
                    Message::Answers(a) => Some(a.contributions.iter().filter(|c| c.camera()).count()),
                    _ => None,
                })
                .sum::<usize>() as u64;
        }
        std::hint::black_box(out);
    }
    times.sort_by(f64::total_cmp);
    seg_times.sort_by(f64::total_cmp);
    render_times.sort_by(f64::total_cmp);
    let c = node.counters();
    Ok(Outcome {
        median_ms: times[times.len() / 2],
        segment_median_ms: seg_times[seg_times.len() / 2],
        render_median_ms: render_times[render_times.len() / 2],
        p90_ms: times[times.len() * 9 / 10],
        detections_per_frame: c.detections as f64 / c.frames.max(1) as f64,
        camera_contributions: contributions as f64 / frames as f64,
    })
}

/// Run the benchmark; its figures as JSON.
///
/// # Errors
/// A part of the system under test could not be set up.
pub fn run(args: &Options) -> Result<serde_json::Value> {
    let pinned = pin_to(args.cpu);
    let frames = args.frames.max(10);
    let mut results = Vec::new();
    let mut best_recommended: Option<(f64, &str, u32)> = None;
    let mut best_full: Option<(f64, &str)> = None;
    for (w, h) in [(640u32, 480u32), (352, 288)] {
        let s = bench_scenario(w, h)?;
        let rec = recommended_step(w);
        for (kind, name) in [
            (Segmentation::AdaptiveBackground, "adaptive-background"),
            (Segmentation::ColourDifference, "colour-difference"),
        ] {
            let mut steps = vec![1];
            if rec != 1 {
                steps.push(rec);
            }
            for step in steps {
                let o = run_one(&s, kind, step, frames)?;
                results.push(json!({
                    "pipeline": name,
                    "width": w,
                    "height": h,
                    "step": step,
                    "recommended": step == rec,
                    "median_ms": o.median_ms,
                    "segmentation_only_median_ms": o.segment_median_ms,
                    "synthetic_render_median_ms": o.render_median_ms,
                    "p90_ms": o.p90_ms,
                    "detections_per_frame": o.detections_per_frame,
                    "camera_contributions_per_frame": o.camera_contributions,
                }));
                if w == 640 && step == rec && best_recommended.is_none_or(|b| o.median_ms < b.0) {
                    best_recommended = Some((o.median_ms, name, step));
                }
                if w == 640 && step == 1 && best_full.is_none_or(|b| o.median_ms < b.0) {
                    best_full = Some((o.median_ms, name));
                }
            }
        }
    }
    let (rss, hwm) = memory_kib();
    let (best_ms, best_name, best_step) = best_recommended.or_failed("no 640x480 result")?;
    let (full_ms, full_name) = best_full.or_failed("no full-resolution result")?;
    let mut out = json!({
        "bench": "camera",
        "what": "segmentation + undistortion + gating + contribution per frame (CameraNode::on_frame + one Priors of every target), rendering excluded",
        "pinned_cpu": if pinned { Some(args.cpu) } else { None },
        "threads": 1,
        "frames": frames,
        "targets": 3,
        "results": results,
        "ms_per_frame_640x480": best_ms,
        "ms_per_frame_640x480_pipeline": best_name,
        "ms_per_frame_640x480_step": best_step,
        "ms_per_frame_640x480_full_resolution": full_ms,
        "ms_per_frame_640x480_full_resolution_pipeline": full_name,
        "vm_rss_kib": rss,
        "vm_hwm_kib": hwm,
    });
    // Paper 004's path: the colour particle filters and the background model alone.
    if let Some(map) = out.as_object_mut() {
        map.extend(super::particle::particle_filter_keys(frames));
        map.insert(
            "background_fps_320x240".into(),
            json!(super::particle::background_fps(320, 240, frames)),
        );
    }
    Ok(out)
}
