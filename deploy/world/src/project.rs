//! Measurement-level detections: each target's true centre projected through the camera plus
//! Gaussian pixel noise, for long parameter sweeps where rendering and segmenting every frame
//! is not needed. Everything built on it must say so in its output ("measurement level").
//!
//! A target is detected when its centre is in front of the camera, inside the image and not
//! hidden by a wall (the segment from the camera to the centre crosses no wall below its top).

use crate::targets::Target;
use nalgebra::Vector3;
use proto::camera::CameraModel;
use proto::msg::PixelBox;
use proto::scenario::World;
use proto::sensor::{Detection, rgb_to_hsi};
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// The detections `camera` would report at `t` seconds: one per visible target.
pub fn project_truth(
    camera: &CameraModel,
    world: &World,
    targets: &[Target],
    t: f64,
    sigma_px: f64,
    rng: &mut impl Rng,
) -> Vec<Detection> {
    let Ok(noise) = Normal::new(0.0, sigma_px.max(0.0)) else {
        return Vec::new();
    };
    let k = &camera.intrinsics;
    let centre_of_camera = camera.pose.centre();
    let mut out = Vec::new();
    for target in targets {
        let x = target.truth_at(t);
        let centre = Vector3::new(x[0], x[1], x[2]);
        let Some(px) = camera.project(&centre) else {
            continue;
        };
        let inside = px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(k.width) && px.y < f64::from(k.height);
        if !inside || world.occluded(&centre_of_camera, &centre) {
            continue;
        }
        // The solid's projected extent gives the box; the noise moves the whole region.
        let (dx, dy) = (noise.sample(rng), noise.sample(rng));
        let half = Vector3::new(target.size[0], target.size[1], target.size[2]) * 0.5;
        let mut bbox = PixelBox {
            xmin: f32::MAX,
            ymin: f32::MAX,
            xmax: f32::MIN,
            ymax: f32::MIN,
        };
        for corner in 0..8 {
            let sign = |bit: usize| if corner & bit == 0 { -1.0 } else { 1.0 };
            let c = centre + Vector3::new(sign(1) * half.x, sign(2) * half.y, sign(4) * half.z);
            if let Some(p) = camera.project(&c) {
                bbox.xmin = bbox.xmin.min((p.x + dx) as f32);
                bbox.ymin = bbox.ymin.min((p.y + dy) as f32);
                bbox.xmax = bbox.xmax.max((p.x + dx) as f32);
                bbox.ymax = bbox.ymax.max((p.y + dy) as f32);
            }
        }
        if bbox.xmax < bbox.xmin {
            continue;
        }
        let centre_px = [(px.x + dx) as f32, (px.y + dy) as f32];
        let [r, g, b] = target.colour;
        out.push(Detection {
            centre: centre_px,
            foot: [centre_px[0], bbox.ymax],
            bbox,
            area: ((bbox.xmax - bbox.xmin) * (bbox.ymax - bbox.ymin)).max(1.0) as u32,
            colour: rgb_to_hsi(f32::from(r), f32::from(g), f32::from(b)),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;
    use proto::scenario::{Scenario, Wall};
    use rand::SeedableRng;

    #[test]
    fn visible_targets_project_near_the_truth_and_walls_hide_them() {
        let mut s = Scenario::default_scenario();
        let all = crate::targets(&s).unwrap();
        let cam = s.camera_model(10).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let t = (0..200)
            .map(|i| i as f64 * 0.25)
            .find(|&t| !project_truth(&cam, &s.world, &all, t, 0.0, &mut rng).is_empty());
        let t = t.expect("camera 10 sees the robot somewhere on its loop");
        let d = project_truth(&cam, &s.world, &all, t, 0.0, &mut rng);
        let truth = all[0].truth_at(t);
        let want = cam.project(&Vector3::new(truth[0], truth[1], truth[2])).unwrap();
        assert!((f64::from(d[0].centre[0]) - want.x).abs() < 1e-3);
        assert!(d[0].bbox.xmin <= d[0].centre[0] && d[0].centre[0] <= d[0].bbox.xmax);
        // A tall wall right in front of the camera hides everything.
        let c = cam.pose.centre();
        let to = Vector3::new(truth[0], truth[1], truth[2]);
        let mid = (c + to) * 0.5;
        let dir = Vector2::new(to.y - c.y, c.x - to.x).normalize() * 2.0;
        s.world.walls.push(Wall {
            from: [mid.x - dir.x, mid.y - dir.y],
            to: [mid.x + dir.x, mid.y + dir.y],
            height: 10.0,
            attenuation_db: 6.0,
        });
        assert!(project_truth(&cam, &s.world, &all, t, 0.0, &mut rng).is_empty());
    }
}
