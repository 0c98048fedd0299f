use super::*;
use crate::tracker::histogram::KernelCounts;
use crate::tracker::motion::State;
use proto::camera::{Distortion, Intrinsics, Pose};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn camera(position: [f64; 3], target: [f64; 3], distortion: Distortion) -> CameraModel {
    CameraModel {
        intrinsics: Intrinsics {
            fx: 500.0,
            fy: 500.0,
            cx: 320.0,
            cy: 240.0,
            width: 640,
            height: 480,
        },
        distortion,
        pose: Pose::look_at(Vector3::from(position), Vector3::from(target), Vector3::z()).unwrap(),
    }
}

fn histogram() -> ColourHistogram {
    let mut c = KernelCounts::default();
    c.bins[0] = 1.0;
    c.bins[100] = 1.0;
    c.total = 1.0;
    ColourHistogram::from_counts(&c).unwrap()
}

/// A person as the conversion models them: a vertical rectangle standing on the ground at
/// `mid`, `width` along the camera's (horizontal) x axis, `height` tall. Returns the box the
/// camera sees of it: the projections of its lower corners and of its top centre.
fn person_box(cam: &CameraModel, mid: [f64; 2], width: f64, height: f64) -> PixelBox {
    let x_axis = cam.pose.rotation.matrix().row(0).transpose();
    let m = Vector3::new(mid[0], mid[1], 0.0);
    let left = cam.project(&(m - x_axis * (0.5 * width))).unwrap();
    let right = cam.project(&(m + x_axis * (0.5 * width))).unwrap();
    let top = cam.project(&(m + Vector3::z() * height)).unwrap();
    assert!((left.y - right.y).abs() < 1e-6, "lower corners on one image row");
    PixelBox {
        xmin: left.x as f32,
        ymin: top.y as f32,
        xmax: right.x as f32,
        ymax: left.y as f32,
    }
}

fn convert(cam: &CameraModel, b: &PixelBox, spread: f64) -> Option<GroundObservation> {
    let s = [
        [spread, 0.0, 0.0, 0.0],
        [0.0, spread, 0.0, 0.0],
        [0.0, 0.0, spread, 0.0],
        [0.0, 0.0, 0.0, spread],
    ];
    to_ground(cam, b, &s, 1.0, ClusterTime::from_millis(7), histogram())
}

fn assert_close(o: &GroundObservation, mid: [f64; 2], width: f64, height: f64, tol: f64, what: &str) {
    let e = (o.position[0] - mid[0]).hypot(o.position[1] - mid[1]);
    assert!(e < tol, "{what}: position {:?} vs {mid:?} ({e:.4} m)", o.position);
    assert!((o.width_m - width).abs() < tol, "{what}: width {}", o.width_m);
    assert!((o.height_m - height).abs() < tol, "{what}: height {}", o.height_m);
}

#[test]
fn recovers_position_width_and_height_within_a_centimetre() {
    let cameras = [
        camera([0.0, 0.0, 3.0], [6.0, 2.0, 0.0], Distortion::default()),
        camera([-2.0, 5.0, 4.0], [3.0, 3.0, 0.5], Distortion::default()),
        camera([1.0, -1.0, 2.5], [1.5, 6.0, 0.0], Distortion::default()),
    ];
    let mut checked = 0;
    for (k, cam) in cameras.iter().enumerate() {
        for mid in [
            [4.0, 1.0],
            [6.0, 3.0],
            [2.0, 4.0],
            [3.0, 2.0],
            [1.5, 5.0],
            [8.0, 1.0],
        ] {
            let m = Vector3::new(mid[0], mid[1], 0.0);
            let (top, foot) = (m + Vector3::z() * 1.75, cam.project(&m));
            let visible = [Some(top), Some(m)].iter().flatten().all(|p| {
                cam.project(p)
                    .is_some_and(|q| (0.0..640.0).contains(&q.x) && (0.0..480.0).contains(&q.y))
            });
            if !visible || foot.is_none() {
                continue;
            }
            let b = person_box(cam, mid, 0.5, 1.75);
            let o = convert(cam, &b, 4.0).unwrap();
            assert_close(
                &o,
                mid,
                0.5,
                1.75,
                0.01,
                &format!("camera {k}, person at {mid:?}"),
            );
            assert_eq!(o.captured, ClusterTime::from_millis(7));
            checked += 1;
        }
    }
    assert!(checked >= 8, "only {checked} placements in view");
}

#[test]
fn a_level_camera_and_the_bounding_box_of_all_corners_are_exact_too() {
    // Level camera, person facing it: every corner of the rectangle is at one depth, so the
    // ordinary bounding box of the four projected corners is the conversion's box.
    let cam = camera([0.0, 0.0, 1.5], [10.0, 0.0, 1.5], Distortion::default());
    for mid in [[4.0, 0.0], [6.0, 1.0], [9.0, -1.5]] {
        let m = Vector3::new(mid[0], mid[1], 0.0);
        let (w, h) = (0.6, 1.8);
        let x_axis = cam.pose.rotation.matrix().row(0).transpose();
        let corners: Vec<_> = [(-0.5, 0.0), (0.5, 0.0), (-0.5, h), (0.5, h)]
            .iter()
            .map(|&(a, z)| cam.project(&(m + x_axis * (a * w) + Vector3::z() * z)).unwrap())
            .collect();
        let b = PixelBox {
            xmin: corners.iter().map(|p| p.x).fold(f64::MAX, f64::min) as f32,
            xmax: corners.iter().map(|p| p.x).fold(f64::MIN, f64::max) as f32,
            ymin: corners.iter().map(|p| p.y).fold(f64::MAX, f64::min) as f32,
            ymax: corners.iter().map(|p| p.y).fold(f64::MIN, f64::max) as f32,
        };
        let o = convert(&cam, &b, 1.0).unwrap();
        assert_close(&o, mid, w, h, 0.01, &format!("level camera, person at {mid:?}"));
    }
}

#[test]
fn undistorts_before_casting_rays() {
    let lens = Distortion {
        k1: -0.28,
        k2: 0.09,
        ..Distortion::default()
    };
    let cam = camera([0.0, 0.0, 3.0], [6.0, 0.0, 0.0], lens);
    let pinhole = CameraModel {
        distortion: Distortion::default(),
        ..cam
    };
    let mut worst_ignored = 0.0f64;
    for mid in [[3.0, 0.0], [5.0, 0.0], [9.0, 0.0]] {
        // On the camera's vertical centre plane the distorted lower corners stay on one row and
        // the top centre on the middle column.
        let b = person_box(&cam, mid, 0.5, 1.75);
        let o = convert(&cam, &b, 1.0).unwrap();
        assert_close(&o, mid, 0.5, 1.75, 0.01, &format!("distorted, person at {mid:?}"));
        let ignored = convert(&pinhole, &b, 1.0).unwrap();
        let e = (ignored.position[0] - mid[0]).hypot(ignored.position[1] - mid[1]);
        let off = e
            .max((ignored.width_m - 0.5).abs())
            .max((ignored.height_m - 1.75).abs());
        worst_ignored = worst_ignored.max(off);
    }
    // Near the image centre the lens barely bends; at the bottom edge it costs decimetres.
    assert!(
        worst_ignored > 0.05,
        "ignoring the lens should cost more than 5 cm: {worst_ignored}"
    );
}

#[test]
fn boxes_above_the_horizon_are_dropped() {
    // Pitched down by atan(2/20): the horizon is the row 240 − 500 · 0.1 = 190.
    let cam = camera([0.0, 0.0, 2.0], [20.0, 0.0, 0.0], Distortion::default());
    let b = |ymax: f32| PixelBox {
        xmin: 300.0,
        ymin: ymax - 60.0,
        xmax: 330.0,
        ymax,
    };
    assert!(convert(&cam, &b(150.0), 1.0).is_none());
    assert!(convert(&cam, &b(189.0), 1.0).is_none());
    let o = convert(&cam, &b(200.0), 1.0).unwrap();
    // Row 200 is 10 px below the horizon: far, but in front of the camera.
    assert!(o.position[0] > 20.0 && o.position[0].is_finite(), "{o:?}");
    assert!(ground_point(&cam, [320.0, 100.0]).is_none());
}

#[test]
fn the_ground_covariance_grows_with_distance() {
    let cam = camera([0.0, 0.0, 3.0], [6.0, 0.0, 0.0], Distortion::default());
    let near = convert(&cam, &person_box(&cam, [3.0, 0.0], 0.5, 1.75), 4.0).unwrap();
    let far = convert(&cam, &person_box(&cam, [9.0, 0.0], 0.5, 1.75), 4.0).unwrap();
    let trace = |o: &GroundObservation| o.cov[0] + o.cov[2];
    assert!(
        trace(&far) > 4.0 * trace(&near),
        "near {:?} far {:?}",
        near.cov,
        far.cov
    );
    // Along the line of sight (x) the far person is less certain than across it (y).
    assert!(far.cov[0] > far.cov[2], "{:?}", far.cov);
    let det = |o: &GroundObservation| o.cov[0] * o.cov[2] - o.cov[1] * o.cov[1];
    assert!(det(&near) > 0.0 && det(&far) > det(&near));
}

#[test]
fn the_propagated_covariance_matches_sampling() {
    // Independent check of the Jacobian: sample boxes from the spread, convert each, and
    // compare the positions' covariance with the propagated one.
    let cam = camera(
        [0.0, 0.0, 3.0],
        [6.0, 2.0, 0.0],
        Distortion {
            k1: -0.1,
            ..Distortion::default()
        },
    );
    let b = person_box(
        &camera([0.0, 0.0, 3.0], [6.0, 2.0, 0.0], Distortion::default()),
        [5.0, 2.5],
        0.5,
        1.75,
    );
    let s = State::from_box(&b);
    let spread = [
        [4.0, 1.0, 0.5, 0.0],
        [1.0, 3.0, 0.0, 1.0],
        [0.5, 0.0, 2.0, 0.3],
        [0.0, 1.0, 0.3, 5.0],
    ];
    let o = to_ground(&cam, &b, &spread, 0.0, ClusterTime::ZERO, histogram()).unwrap();
    let l = nalgebra::Matrix4::from_fn(|i, j| spread[i][j])
        .cholesky()
        .unwrap()
        .l();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let zero = [[0.0; 4]; 4];
    let n = 20_000;
    let positions: Vec<[f64; 2]> = (0..n)
        .map(|_| {
            let z = nalgebra::Vector4::from_fn(|_, _| StandardNormal.sample(&mut rng));
            let d = l * z;
            let state = State {
                x: s.x + d[0] as f32,
                y: s.y + d[1] as f32,
                w: s.w + d[2] as f32,
                h: s.h + d[3] as f32,
                ..s
            };
            to_ground(&cam, &state.bbox(), &zero, 0.0, ClusterTime::ZERO, histogram())
                .unwrap()
                .position
        })
        .collect();
    let mean = |k: usize| positions.iter().map(|p| p[k]).sum::<f64>() / n as f64;
    let (mx, my) = (mean(0), mean(1));
    let c = |a: usize, ma: f64, b: usize, mb: f64| {
        positions.iter().map(|p| (p[a] - ma) * (p[b] - mb)).sum::<f64>() / (n - 1) as f64
    };
    let sampled = [c(0, mx, 0, mx), c(0, mx, 1, my), c(1, my, 1, my)];
    let scale = sampled[0].max(sampled[2]);
    for k in 0..3 {
        assert!(
            (sampled[k] - o.cov[k]).abs() < 0.06 * scale,
            "entry {k}: sampled {sampled:?} vs propagated {:?}",
            o.cov
        );
    }
}

#[test]
fn a_corner_floor_keeps_a_collapsed_sample_set_uncertain() {
    let cam = camera([0.0, 0.0, 3.0], [6.0, 0.0, 0.0], Distortion::default());
    let b = person_box(&cam, [5.0, 0.0], 0.5, 1.75);
    let zero = [[0.0; 4]; 4];
    let none = to_ground(&cam, &b, &zero, 0.0, ClusterTime::ZERO, histogram()).unwrap();
    let floor = to_ground(&cam, &b, &zero, 1.0, ClusterTime::ZERO, histogram()).unwrap();
    assert_eq!(none.cov, [0.0; 3]);
    assert!(floor.cov[0] > 0.0 && floor.cov[2] > 0.0);
}

#[test]
fn a_measured_lower_edge_puts_a_filter_on_the_upper_body_where_the_person_stands() {
    let cam = camera([0.0, 0.0, 3.0], [6.0, 2.0, 0.0], Distortion::default());
    let (mid, width, height) = ([4.0, 1.0], 0.5, 1.7);
    let whole = person_box(&cam, mid, width, height);
    // The filter's box covers the upper half of the person only.
    let upper = PixelBox {
        ymax: 0.5 * (whole.ymin + whole.ymax),
        ..whole
    };
    let person = PersonEstimate::at_box(0, upper, Some(0));
    let at = ClusterTime::from_millis(7);
    let own = observe(&cam, &person, None, 1.0, 1.0, at).unwrap();
    let off = (own.position[0] - mid[0]).hypot(own.position[1] - mid[1]);
    assert!(off > 1.0, "the box's own edge puts them {off:.2} m off");
    let measured = observe(&cam, &person, Some(whole.ymax), 1.0, 1.0, at).unwrap();
    assert_close(&measured, mid, width, height, 0.01, "measured edge");
    // An edge above the box's top is no edge: the box stands as it is.
    assert_eq!(
        observe(&cam, &person, Some(upper.ymin - 1.0), 1.0, 1.0, at),
        Some(own.clone())
    );
    // At half resolution the box and the edge scale together.
    let half = PixelBox {
        xmin: upper.xmin / 2.0,
        ymin: upper.ymin / 2.0,
        xmax: upper.xmax / 2.0,
        ymax: upper.ymax / 2.0,
    };
    let small = PersonEstimate::at_box(0, half, Some(0));
    let scaled = observe(&cam, &small, Some(whole.ymax / 2.0), 2.0, 1.0, at).unwrap();
    assert_close(&scaled, mid, width, height, 0.01, "half resolution");
}
