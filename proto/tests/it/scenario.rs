//! The scenario files: the embedded default, the commented example, and how broken files fail.

use proto::scenario::{DEFAULT_SCENARIO_TOML, Scenario, ScenarioError};
use std::path::Path;

/// `ocelli scenario default` prints the embedded text; it parses to the default, and the
/// default serializes to TOML that parses back to the same scenario.
#[test]
fn default_scenario_text_round_trips() {
    let s = Scenario::from_toml(DEFAULT_SCENARIO_TOML, "<printed>").unwrap();
    assert_eq!(s, Scenario::default_scenario());
    // A key the file leaves out takes its default: lost cameras are counted as their mode says.
    assert!(!DEFAULT_SCENARIO_TOML.contains("drop-lost-cameras"));
    assert!(!s.method.drop_lost_cameras);
    let again = Scenario::from_toml(&s.to_toml(), "<to_toml>").unwrap();
    assert_eq!(again, s);
}

fn example_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/example.toml")
}

fn example_text() -> String {
    std::fs::read_to_string(example_path()).unwrap()
}

/// Every key path of a TOML document, array indices dropped (`nodes.camera.pose.look-at`).
fn key_paths(v: &toml::Value, prefix: &str, out: &mut std::collections::BTreeSet<String>) {
    match v {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.insert(p.clone());
                key_paths(v, &p, out);
            }
        }
        toml::Value::Array(a) => a.iter().for_each(|v| key_paths(v, prefix, out)),
        _ => {}
    }
}

/// The commented example parses, builds every camera, and sets every field explicitly
/// somewhere (its key paths include every key the full serialization has), plus the optional
/// node keys and both pose forms and both trajectory kinds.
#[test]
fn example_parses_and_exercises_every_field() {
    let s = Scenario::load(&example_path()).unwrap();
    for c in s.cameras() {
        if c.radio_only() {
            s.sensor_position(c.id).unwrap();
        } else {
            s.camera_model(c.id).unwrap();
        }
    }
    let mut written = std::collections::BTreeSet::new();
    key_paths(&toml::from_str(&example_text()).unwrap(), "", &mut written);
    let mut full = std::collections::BTreeSet::new();
    key_paths(&toml::from_str(&s.to_toml()).unwrap(), "", &mut full);
    let missing: Vec<_> = full.difference(&written).collect();
    assert!(missing.is_empty(), "the example does not set: {missing:?}");
    for key in [
        "nodes.listen",
        "nodes.head",
        "nodes.power",
        "nodes.region",
        "nodes.camera.pose.look-at",
        "nodes.camera.pose.rvec",
        "nodes.camera.distortion.k3",
        "world.walls.attenuation-db",
        "nodes.position",
        "nodes.radio",
    ] {
        assert!(written.contains(key), "the example does not show `{key}`");
    }
    // Its rvec/tvec camera is where its comment says: at (5.8, 0.2, 2.6) looking at (3, 2, 0).
    let cam = s.camera_model(11).unwrap();
    let centre = cam.pose.centre();
    assert!(
        (centre - nalgebra::Vector3::new(5.8, 0.2, 2.6)).norm() < 1e-6,
        "{centre:?}"
    );
    let px = cam.project(&nalgebra::Vector3::new(3.0, 2.0, 0.0)).unwrap();
    assert!(
        (px - nalgebra::Vector2::new(175.0, 143.0)).norm() < 1e-3,
        "{px:?}"
    );
}

/// Replace `from` (which must occur) in the example and parse the result.
fn broken(from: &str, to: &str) -> ScenarioError {
    let text = example_text();
    assert!(text.contains(from), "`{from}` not in the example");
    Scenario::from_toml(&text.replacen(from, to, 1), "broken.toml").unwrap_err()
}

/// A broken file fails with the path, the field and what was expected.
#[test]
fn broken_files_name_path_field_and_expectation() {
    let cases: [(&str, &str, &[&str]); 15] = [
        (
            "step-ms = 200",
            "step-ms = \"fast\"",
            &["step-ms", "invalid type", "expected u64"],
        ),
        ("fps = 5.0", "fps = [5.0]", &["fps", "invalid type"]),
        (
            "fusion = \"distributed-eif\"",
            "fusion = \"magic\"",
            &["fusion", "unknown variant `magic`", "distributed-eif"],
        ),
        ("id = 11\n", "id = 10\n", &["nodes[id=10]", "duplicate node id"]),
        (
            "id = 11\nrole = \"camera\"\nhead = 2",
            "id = 11\nrole = \"camera\"\nhead = 9",
            &["nodes[id=11].head", "no head with id 9"],
        ),
        (
            "deadline-ms = 80",
            "deadline-ms = 200",
            &["method.deadline-ms", "expected 0 < deadline-ms < step-ms"],
        ),
        (
            "pixel-sigma = 18.0",
            "pixel-sigma = nan",
            &["method.pixel-sigma", "expected a positive number"],
        ),
        (
            "fx = 320.0, fy = 320.0, cx = 176.0",
            "fx = -320.0, fy = 320.0, cx = 176.0",
            &["nodes[id=10].camera.intrinsics", "positive focal"],
        ),
        (
            "look-at = [3.0, 2.0, 0.0]",
            "look-at = [0.2, 0.2, 0.0]",
            &["nodes[id=10].camera.pose", "degenerate"],
        ),
        (
            "position = [0.2, 0.2, 2.6]",
            "position = [0.2, inf, 2.6]",
            &["nodes[id=10].camera.pose", "finite"],
        ),
        (
            "height = 1.2",
            "height = -1.2",
            &["world.walls[0].height", "positive"],
        ),
        (
            "radio = \"ble:hci0\"",
            "radio = \"bluetooth\"",
            &[
                "radio",
                "expected `ble`, `ble:ADAPTER` or `file:PATH.mbd@SENSOR-MAC`",
            ],
        ),
        (
            "position = [5.9, 3.9, 2.2]",
            "position = [5.9, nan, 2.2]",
            &["nodes[id=13].position", "finite"],
        ),
        (
            "position = [5.9, 3.9, 2.2]\n",
            "",
            &["nodes[id=13].camera", "radio-only"],
        ),
        (
            "region = [0.0, 0.0, 6.0, 4.0]",
            "region = [0.0, 0.0, 6.0, 4.0]\nradio = \"ble\"",
            &["nodes[id=2].radio", "only camera nodes carry a radio"],
        ),
    ];
    for (from, to, wants) in cases {
        let e = broken(from, to).to_string();
        assert!(e.contains("broken.toml"), "no path in: {e}");
        for want in wants {
            assert!(e.contains(want), "`{from}` → `{to}`: expected `{want}` in: {e}");
        }
    }
    // A missing required key.
    let e = broken("name = \"example\"\n", "").to_string();
    assert!(
        e.contains("broken.toml") && e.contains("missing field `name`"),
        "{e}"
    );
    // A pose of neither form says which forms exist.
    let e = broken("pose = { position", "pose = { place").to_string();
    assert!(e.contains("look-at") && e.contains("rvec"), "{e}");
}

/// `Scenario::load` names the file it could not read.
#[test]
fn missing_file_is_named() {
    let e = Scenario::load(Path::new("/nonexistent/scenario.toml")).unwrap_err();
    assert!(matches!(e, ScenarioError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/scenario.toml"), "{e}");
}

/// A camera given by OpenCV files, relative to the scenario file: MultiviewX's Camera1, with
/// the image size from inline intrinsics and its left-handed extrinsics mirrored (y reflected).
#[test]
fn opencv_camera_in_a_scenario() {
    let calib = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/multiviewx/calibrations");
    assert!(
        calib.is_dir(),
        "MultiviewX calibrations missing at {}",
        calib.display()
    );
    let dir = std::env::temp_dir().join(format!("ocelli-scenario-opencv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = format!(
        "name = \"mvx\"\n[world]\nmin = [0.0, -16.0, 0.0]\nmax = [25.0, 0.0, 3.0]\n\
         [[nodes]]\nid = 1\nrole = \"head\"\n\
         [[nodes]]\nid = 2\nrole = \"camera\"\n\
         camera.intrinsics = {{ fx = 1.0, fy = 1.0, cx = 0.0, cy = 0.0, width = 1920, height = 1080 }}\n\
         camera.opencv-intrinsic = \"{0}/intrinsic/intr_Camera1.xml\"\n\
         camera.opencv-extrinsic = \"{0}/extrinsic/extr_Camera1.xml\"\n",
        calib.display()
    );
    let path = dir.join("mvx.toml");
    std::fs::write(&path, text).unwrap();
    let s = Scenario::load(&path).unwrap();
    let cam = s.camera_model(2).unwrap();
    assert_eq!((cam.intrinsics.width, cam.intrinsics.height), (1920, 1080));
    assert!((cam.intrinsics.fx - 903.074_129_936_791_8).abs() < 1e-9);
    // Person 0 of frame 1 stands at positionID 243441 → (11.025, 6.075) m, mirrored to
    // (11.025, −6.075); view 0 boxes it at x 1335..1390, bottom 609.
    let foot = cam.project(&nalgebra::Vector3::new(11.025, -6.075, 0.0)).unwrap();
    assert!(
        (foot - nalgebra::Vector2::new(1362.5, 609.0)).norm() < 15.0,
        "{foot:?}"
    );
    // A missing calibration file names the node, the field and the file.
    std::fs::write(
        &path,
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("intr_Camera1", "intr_Nope"),
    )
    .unwrap();
    let e = Scenario::load(&path)
        .unwrap()
        .camera_model(2)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nodes[id=2].camera.opencv-intrinsic") && e.contains("intr_Nope.xml"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn walls_hide_only_what_is_behind_them_and_below_their_top() {
    use nalgebra::Vector3;
    let mut w = Scenario::default_scenario().world;
    w.walls = vec![proto::scenario::Wall {
        from: [0.0, 1.0],
        to: [2.0, 1.0],
        height: 2.0,
        attenuation_db: 0.0,
    }];
    let a = Vector3::new(1.0, 0.0, 1.0);
    assert!(w.occluded(&a, &Vector3::new(1.0, 2.0, 1.0)));
    // Beside the wall, in front of it, or over its top: seen.
    assert!(!w.occluded(&a, &Vector3::new(5.0, 2.0, 1.0)));
    assert!(!w.occluded(&a, &Vector3::new(1.0, 0.5, 1.0)));
    assert!(!w.occluded(&Vector3::new(1.0, 0.0, 3.0), &Vector3::new(1.0, 2.0, 2.5)));
}
