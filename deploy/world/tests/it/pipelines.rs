//! The synthetic world end to end: rendered frames through both pipelines.

use nalgebra::Vector3;
use node_camera::segment::{SegmentParams, Segmenter};
use proto::ClusterTime;
use proto::scenario::{Scenario, Segmentation};
use proto::sensor::Frame;
use std::path::Path;
use world::render::Renderer;

/// Both pipelines find the target in every camera that sees it, near the distorted
/// projection of its centre, over 20 s of the default scenario; a picture of camera 10 with
/// the boxes is written to `target/`.
#[test]
fn both_pipelines_find_the_rendered_target() {
    let s = Scenario::default_scenario();
    let targets = world::targets(&s).unwrap();
    for kind in [Segmentation::ColourDifference, Segmentation::AdaptiveBackground] {
        let (mut seen, mut found) = (0, 0);
        for cam_id in [10u32, 13, 17, 22, 27] {
            let cam = s.camera_model(cam_id).unwrap();
            let r = Renderer::for_node(&s, cam_id, 5).unwrap();
            let mut params = SegmentParams::for_scenario(&s, cam.intrinsics.width);
            params.kind = kind;
            let mut seg = Segmenter::new(&params);
            let mut f = Frame::new(0, 0, ClusterTime::ZERO);
            let mut dets = Vec::new();
            for k in 0..100 {
                let t = k as f64 * 0.2;
                r.render(&targets, t, ClusterTime::from_secs_f64(t), &mut f);
                seg.process(&f, &mut dets).unwrap();
                let x = targets[0].truth_at(t);
                let Some(p) = cam.project(&Vector3::new(x[0], x[1], x[2])) else {
                    continue;
                };
                // Count frames after warm-up where the target is well inside the image.
                if k < 15 || p.x < 20.0 || p.y < 20.0 || p.x > 332.0 || p.y > 268.0 {
                    continue;
                }
                seen += 1;
                if dets.iter().any(|d| {
                    ((d.centre[0] as f64 - p.x).powi(2) + (d.centre[1] as f64 - p.y).powi(2)).sqrt() < 12.0
                }) {
                    found += 1;
                }
                if cam_id == 10 && k == 60 {
                    let mut img = f.clone();
                    for d in &dets {
                        let b = d.bbox;
                        img.draw_box(
                            b.xmin as i64 - 1,
                            b.ymin as i64 - 1,
                            b.xmax as i64 + 1,
                            b.ymax as i64 + 1,
                            [0, 255, 0],
                            1,
                        );
                    }
                    let out =
                        Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("synthetic_cam10_{kind:?}.png"));
                    image::RgbImage::from_raw(img.width, img.height, img.data)
                        .unwrap()
                        .save(out)
                        .unwrap();
                }
            }
        }
        eprintln!("{kind:?}: found in {found}/{seen} frames");
        assert!(seen > 50, "{kind:?}: target rarely in view ({seen})");
        assert!(
            found * 100 >= seen * 90,
            "{kind:?}: found in {found}/{seen} frames"
        );
    }
}
