//! Scoring a camera run against its truth: per true person in view, the nearest reported person
//! on the floor within the matching threshold; tracked shares, image and ground errors, the
//! identities the camera gave them, and CLEAR MOT / IDF1 through `node_server::metrics`.

use super::camera::{CameraRun, FrameRecord, Reported, TruePerson};
use crate::experiment::runner::Sample;
use node_server::metrics::{self, MetricsConfig, MotMetrics};
use std::collections::BTreeSet;

/// A reported person matches a true one within this distance on the floor, m.
pub const MATCH_M: f64 = 1.0;

/// One run of a single-person study.
#[derive(Clone, Debug, Default)]
pub struct Single {
    /// Frames with the person in view, and of those the ones with a match.
    pub in_view: usize,
    pub tracked: usize,
    /// The same for the frames in which a wall hides the person's centre.
    pub hidden: usize,
    pub tracked_hidden: usize,
    /// Distance of the matched box's centre to the true box's, pixels, per matched frame.
    pub image_px: Vec<f64>,
    pub image_px_hidden: Vec<f64>,
    /// Ground errors as samples (for the errors, intervals and figures).
    pub samples: Vec<Sample>,
    /// Distinct reported ids matched to the person.
    pub identities: usize,
    /// Distinct reported ids never matched to anyone.
    pub spurious: usize,
}

fn centre(b: &proto::msg::PixelBox) -> [f64; 2] {
    [0.5 * f64::from(b.xmin + b.xmax), 0.5 * f64::from(b.ymin + b.ymax)]
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Of `items` with their floor positions, the one nearest `at` within [`MATCH_M`], with its
/// distance.
fn nearest_within<T>(at: [f64; 2], items: impl Iterator<Item = (T, [f64; 2])>) -> Option<(T, f64)> {
    items
        .map(|(item, g)| (item, dist(g, at)))
        .filter(|(_, d)| *d <= MATCH_M)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The reported person nearest `truth` on the floor within [`MATCH_M`], with its distance.
fn nearest<'a>(truth: &TruePerson, reported: &'a [Reported]) -> Option<(&'a Reported, f64)> {
    nearest_within(
        truth.ground,
        reported.iter().filter_map(|r| r.ground.map(|g| (r, g))),
    )
}

/// Score a single-person run: every frame with the person in view.
pub fn single(run: &CameraRun) -> Single {
    let mut s = Single::default();
    let mut matched_ids = BTreeSet::new();
    let mut all_ids = BTreeSet::new();
    for f in &run.frames {
        all_ids.extend(f.reported.iter().map(|r| r.id));
        for truth in f.truth.iter().filter(|p| p.in_view) {
            s.in_view += 1;
            s.hidden += usize::from(truth.occluded);
            let Some((r, d)) = nearest(truth, &f.reported) else {
                continue;
            };
            matched_ids.insert(r.id);
            s.tracked += 1;
            let px = dist(centre(&r.bbox), centre(&truth.bbox));
            s.image_px.push(px);
            if truth.occluded {
                s.tracked_hidden += 1;
                s.image_px_hidden.push(px);
            }
            let g = r.ground.unwrap_or(truth.ground);
            s.samples.push(Sample {
                t: f.t,
                est: [g[0], g[1], 0.0],
                truth: [truth.ground[0], truth.ground[1], 0.0],
                sigma_m: 0.0,
                error_m: d,
                cameras: 1,
                rssi_nodes: 0,
            });
        }
    }
    s.identities = matched_ids.len();
    s.spurious = all_ids.difference(&matched_ids).count();
    s
}

/// The windows `[from, to)` of the run in which a wall hides a true person's centre.
pub fn hidden_windows(frames: &[FrameRecord]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut start = None;
    for f in frames {
        let hidden = f.truth.iter().any(|p| p.in_view && p.occluded);
        match (hidden, start) {
            (true, None) => start = Some(f.t),
            (false, Some(a)) => {
                out.push((a, f.t));
                start = None;
            }
            _ => {}
        }
    }
    if let (Some(a), Some(last)) = (start, frames.last()) {
        out.push((a, last.t));
    }
    out
}

/// CLEAR MOT and IDF1 of a run on the floor: the true people in view against every reported
/// person with a floor position.
///
/// # Errors
/// A frame the metrics refuse (never for a run's own records: times increase, ids are unique).
pub fn mot(run: &CameraRun) -> crate::error::Result<MotMetrics> {
    let frames: Vec<metrics::Frame<2>> = run
        .frames
        .iter()
        .map(|f| metrics::Frame {
            t: f.t,
            truth: f
                .truth
                .iter()
                .filter(|p| p.in_view)
                .map(|p| (p.id, p.ground))
                .collect(),
            hyps: f
                .reported
                .iter()
                .filter_map(|r| r.ground.map(|g| (r.id, g)))
                .collect(),
        })
        .collect();
    let config = MetricsConfig {
        threshold_m: MATCH_M,
        ..MetricsConfig::default()
    };
    Ok(metrics::evaluate(&frames, &config)?)
}

/// Reports that are within [`MATCH_M`] on the floor of a true person whose centre is out of
/// view and of no one whose centre is in view: people half out of the image, whom the camera
/// sees but the truth does not count, or people who just left it (a filter reported after its
/// person), so that CLEAR MOT scores them false positives (for both methods alike). Counted so
/// the false positives can be read; the scores stay as the truth has them.
pub fn on_people_out_of_view(run: &CameraRun) -> usize {
    let near = |g: [f64; 2], in_view: bool| {
        move |p: &TruePerson| p.in_view == in_view && dist(g, p.ground) <= MATCH_M
    };
    run.frames
        .iter()
        .map(|f| {
            f.reported
                .iter()
                .filter_map(|r| r.ground)
                .filter(|&g| f.truth.iter().any(near(g, false)) && !f.truth.iter().any(near(g, true)))
                .count()
        })
        .sum()
}

/// Reports beyond the first near one true person in view: each report with a floor position
/// goes to the nearest true person in view within [`MATCH_M`], and every report a person gets
/// after their first is counted. Those are the camera's second reports of someone (two filters
/// on one person, or a filter whose person left sitting on another), most of which CLEAR MOT
/// scores as false positives (it matches one to one; this gives each report to its nearest).
/// Counted so the false positives can be read (two people closer than the threshold, each
/// reported once, can show as one person reported twice).
pub fn second_reports(run: &CameraRun) -> usize {
    run.frames
        .iter()
        .map(|f| {
            let in_view: Vec<&TruePerson> = f.truth.iter().filter(|p| p.in_view).collect();
            let mut reports = vec![0usize; in_view.len()];
            for g in f.reported.iter().filter_map(|r| r.ground) {
                if let Some((k, _)) =
                    nearest_within(g, in_view.iter().enumerate().map(|(k, p)| (k, p.ground)))
                {
                    reports[k] += 1;
                }
            }
            reports.iter().map(|n| n.saturating_sub(1)).sum::<usize>()
        })
        .sum()
}

/// Mean of `xs`; `None` when empty.
pub fn mean(xs: &[f64]) -> Option<f64> {
    (!xs.is_empty()).then(|| xs.iter().sum::<f64>() / xs.len() as f64)
}

/// `a / b`, `None` when `b` is 0.
pub fn share(a: usize, b: usize) -> Option<f64> {
    (b > 0).then(|| a as f64 / b as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::msg::PixelBox;

    const BOX: PixelBox = PixelBox {
        xmin: 0.0,
        ymin: 0.0,
        xmax: 10.0,
        ymax: 30.0,
    };

    fn truth(id: u32, x: f64, in_view: bool) -> TruePerson {
        TruePerson {
            id,
            ground: [x, 2.0],
            bbox: BOX,
            in_view,
            occluded: false,
        }
    }

    fn reported(id: u32, x: f64) -> Reported {
        Reported {
            id,
            bbox: BOX,
            ground: Some([x, 2.0]),
        }
    }

    fn run(truth: Vec<TruePerson>, reported: Vec<Reported>) -> CameraRun {
        CameraRun {
            frames: vec![FrameRecord {
                reported,
                ..FrameRecord::new(0.0, truth)
            }],
            width: 320,
            height: 240,
            live_at_end: 0,
            particles: None,
        }
    }

    #[test]
    fn a_person_reported_three_times_has_two_second_reports() {
        // Person 1 at x = 1 reported three times, person 2 at x = 5 once; a report more than
        // 1 m from anyone, and one at a person out of view, are not second reports.
        let r = run(
            vec![truth(1, 1.0, true), truth(2, 5.0, true), truth(3, 9.0, false)],
            vec![
                reported(10, 1.0),
                reported(11, 1.4),
                reported(12, 0.5),
                reported(13, 5.2),
                reported(14, 2.5),
                reported(15, 9.0),
            ],
        );
        assert_eq!(second_reports(&r), 2);
        assert_eq!(on_people_out_of_view(&r), 1);
        // Each report goes to its nearest person: one report each is no second report.
        let apart = run(
            vec![truth(1, 1.0, true), truth(2, 1.8, true)],
            vec![reported(10, 0.9), reported(11, 1.9)],
        );
        assert_eq!(second_reports(&apart), 0);
    }
}
