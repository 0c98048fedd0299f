use super::*;
use nalgebra::Vector2;

fn multiviewx() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/multiviewx");
    assert!(
        dir.join("calibrations").is_dir(),
        "MultiviewX dataset missing at {} (shared/ must sit beside the repo)",
        dir.display()
    );
    dir
}

/// A scratch directory unique to one test, removed when it is dropped.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("ocelli-opencv-{name}-"))
        .tempdir()
        .unwrap()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const INTR: &str = r#"<?xml version="1.0"?>
<opencv_storage>
<image_width>640</image_width>
<image_height>480</image_height>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows><cols>3</cols><dt>d</dt>
  <data>500. 0. 320.5 0. 510. 240.25 0. 0. 1.</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix">
  <rows>1</rows><cols>5</cols><dt>d</dt>
  <data>-0.1 0.02
  0.001 -0.002 0.003</data></distortion_coefficients>
</opencv_storage>
"#;

#[test]
fn reads_intrinsics_with_image_size() {
    let scratch_dir = scratch("intr");
    let dir = scratch_dir.path();
    let p = write(dir, "intr.xml", INTR);
    let (k, d) = read_intrinsics(&p).unwrap();
    assert_eq!(
        k,
        Intrinsics {
            fx: 500.0,
            fy: 510.0,
            cx: 320.5,
            cy: 240.25,
            width: 640,
            height: 480
        }
    );
    assert_eq!(
        d,
        Distortion {
            k1: -0.1,
            k2: 0.02,
            p1: 0.001,
            p2: -0.002,
            k3: 0.003
        }
    );
}

/// Each broken file is rejected with the file name and what is wrong.
#[test]
fn broken_intrinsics_name_file_and_problem() {
    let scratch_dir = scratch("broken");
    let dir = scratch_dir.path();
    let cases: [(&str, String, &str); 7] = [
        (
            "no_matrix",
            INTR.replace("camera_matrix", "camera_mat"),
            "missing <camera_matrix>",
        ),
        (
            "no_rows",
            INTR.replacen("<rows>3</rows>", "", 1),
            "<camera_matrix>: missing <rows>",
        ),
        (
            "short",
            INTR.replace("0. 0. 1.</data>", "0. 0.</data>"),
            "needs 9 numbers, <data> has 8",
        ),
        ("nan", INTR.replace("500.", "nan"), "`nan` is not a finite number"),
        (
            "int",
            INTR.replacen("<dt>d</dt>", "<dt>i</dt>", 1),
            "expected `d` or `f`",
        ),
        (
            "root",
            INTR.replace("opencv_storage", "storage"),
            "expected root element <opencv_storage>",
        ),
        (
            "rational",
            INTR.replace("<cols>5</cols>", "<cols>8</cols>")
                .replace("0.003</data>", "0.003 0.5 0 0</data>"),
            "beyond k3",
        ),
    ];
    for (name, text, want) in cases {
        let p = write(dir, &format!("{name}.xml"), &text);
        let e = read_intrinsics(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{name}.xml")),
            "{name}: error does not name the file: {e}"
        );
        assert!(e.contains(want), "{name}: expected `{want}` in: {e}");
    }
    let e = read_intrinsics(&dir.join("absent.xml")).unwrap_err();
    assert!(
        matches!(e, OpenCvError::Io { .. }) && e.to_string().contains("absent.xml"),
        "{e}"
    );
}

#[test]
fn missing_image_size_uses_option_then_estimate() {
    let scratch_dir = scratch("size");
    let dir = scratch_dir.path();
    let text = INTR
        .replace("<image_width>640</image_width>", "")
        .replace("<image_height>480</image_height>", "");
    let p = write(dir, "intr.xml", &text);
    assert_eq!(read_intrinsics_with(&p, Some((800, 600))).unwrap().0.width, 800);
    let (k, _) = read_intrinsics(&p).unwrap();
    assert_eq!((k.width, k.height), (641, 481));
}

#[test]
fn extrinsics_missing_tvec_is_named() {
    let scratch_dir = scratch("extr");
    let dir = scratch_dir.path();
    let p = write(
        dir,
        "extr_A.xml",
        "<?xml version=\"1.0\"?><opencv_storage><rvec type_id=\"opencv-matrix\"><rows>3</rows><cols>1</cols><dt>d</dt><data>0 0 0</data></rvec></opencv_storage>",
    );
    let e = read_extrinsics(&p).unwrap_err().to_string();
    assert!(e.contains("extr_A.xml") && e.contains("missing <tvec>"), "{e}");
}

#[test]
fn calibration_dir_without_partner_file_fails_naming_it() {
    let scratch_dir = scratch("dir");
    let dir = scratch_dir.path();
    std::fs::create_dir_all(dir.join("intrinsic")).unwrap();
    write(&dir.join("intrinsic"), "intr_Cam9.xml", INTR);
    let e = read_calibration_dir(dir).unwrap_err().to_string();
    assert!(e.contains("extr_Cam9.xml") && e.contains("Cam9"), "{e}");
}

/// Mirroring keeps ground pixels, negates camera coordinates and is a proper rotation.
#[test]
fn mirror_pose_keeps_ground_projection_and_flips_depth() {
    let pose = Pose::from_rvec_tvec([0.3, -1.2, 2.0], [1.0, -0.5, 7.0]);
    for axis in [MirrorAxis::Y, MirrorAxis::Z] {
        let m = mirror_pose(&pose, axis);
        approx::assert_relative_eq!(m.rotation.matrix().determinant(), 1.0, epsilon = 1e-12);
        approx::assert_relative_eq!(
            m.rotation.matrix() * m.rotation.matrix().transpose(),
            Matrix3::identity(),
            epsilon = 1e-12
        );
        for p in [Vector3::new(1.0, 2.0, 0.0), Vector3::new(-3.0, 0.5, 1.5)] {
            let mirrored_world = axis.apply(&p);
            approx::assert_relative_eq!(
                m.world_to_camera(&mirrored_world),
                -pose.world_to_camera(&p),
                epsilon = 1e-12
            );
        }
        assert!(sees_ground_behind(&pose) != sees_ground_behind(&m));
    }
}

struct Foot {
    camera: usize,
    world: Vector3<f64>,
    pixel: Vector2<f64>,
}

/// Every annotated (person, view) pair of MultiviewX: the ground position and the bottom
/// centre of its box.
fn multiviewx_feet(dir: &Path) -> Vec<Foot> {
    let mut out = Vec::new();
    let mut files: Vec<_> = std::fs::read_dir(dir.join("annotations_positions"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no MultiviewX annotations");
    for f in files {
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&f).unwrap()).unwrap();
        for person in v.as_array().unwrap() {
            let pos = person["positionID"].as_i64().unwrap();
            let world = Vector3::new((pos % 1000) as f64 / 40.0, (pos / 1000) as f64 / 40.0, 0.0);
            for view in person["views"].as_array().unwrap() {
                let b = |k: &str| view[k].as_f64().unwrap();
                if b("xmin") < 0.0 {
                    continue;
                }
                out.push(Foot {
                    camera: view["viewNum"].as_u64().unwrap() as usize + 1,
                    world,
                    pixel: Vector2::new(0.5 * (b("xmin") + b("xmax")), b("ymax")),
                });
            }
        }
    }
    out
}

/// The real MultiviewX files: all six cameras import, are mirrored (the dataset's world is
/// left-handed), every annotated foot point is in front of its camera, and projects within a
/// few pixels of the bottom centre of its box, with either mirror axis.
#[test]
fn multiviewx_ground_points_land_on_box_bottoms() {
    let dir = multiviewx();
    let options = ImportOptions {
        handedness: Handedness::Auto,
        mirror_axis: MirrorAxis::Y,
        image_size: Some((1920, 1080)),
    };
    let cams = read_calibration_dir_with(&dir.join("calibrations"), &options).unwrap();
    assert_eq!(
        cams.keys().cloned().collect::<Vec<_>>(),
        (1..=6).map(|i| format!("Camera{i}")).collect::<Vec<_>>()
    );
    assert!(
        cams.values().all(|c| c.mirrored),
        "MultiviewX cameras should be detected as left-handed"
    );
    let feet = multiviewx_feet(&dir);
    assert!(feet.len() > 100, "only {} annotated views", feet.len());
    for axis in [MirrorAxis::Y, MirrorAxis::Z] {
        let cams = read_calibration_dir_with(
            &dir.join("calibrations"),
            &ImportOptions {
                mirror_axis: axis,
                ..options
            },
        )
        .unwrap();
        let mut errors = Vec::new();
        for f in &feet {
            let cam = &cams[&format!("Camera{}", f.camera)].model;
            let world = axis.apply(&f.world);
            let (_, depth) = cam.normalized(&world);
            assert!(
                depth > 0.0,
                "camera {} sees {:?} at depth {depth}",
                f.camera,
                f.world
            );
            let px = cam.project(&world).unwrap();
            errors.push((px - f.pixel).norm());
        }
        errors.sort_by(f64::total_cmp);
        let median = errors[errors.len() / 2];
        let p90 = errors[errors.len() * 9 / 10];
        eprintln!(
            "multiviewx foot reprojection ({axis:?} mirror): n = {}, median = {median:.2} px, p90 = {p90:.2} px",
            errors.len()
        );
        assert!(median < 8.0, "median foot error {median} px");
        assert!(p90 < 25.0, "p90 foot error {p90} px");
    }

    // With the default y mirror the world is z-up: a head 1.8 m above the foot projects above
    // it in the image (MultiviewX people are 1.8 m tall).
    let f = &feet[0];
    let cam = &cams[&format!("Camera{}", f.camera)].model;
    let head = cam
        .project(&(MirrorAxis::Y.apply(&f.world) + Vector3::new(0.0, 0.0, 1.8)))
        .unwrap();
    assert!(
        head.y < f.pixel.y - 20.0,
        "head at {head:?}, foot at {:?}",
        f.pixel
    );

    // As-is, the same files put the visible ground behind the cameras.
    let raw = read_calibration_dir_with(
        &dir.join("calibrations"),
        &ImportOptions {
            handedness: Handedness::AsIs,
            ..options
        },
    )
    .unwrap();
    assert!(raw.values().all(|c| !c.mirrored));
    let (_, depth) = raw[&format!("Camera{}", f.camera)].model.normalized(&f.world);
    assert!(depth < 0.0);
}
