//! Every scenario file in `proto/scenarios/` passes `ocelli scenario check`, and the issue-16
//! scenarios are what they claim: the crowd's people are each in view of two cameras or more
//! all the time, and the hall is the generator's output for the command line in its header.

use proto::scenario::Scenario;
use std::path::{Path, PathBuf};
use world::generate::{HallSpec, generate_toml};

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../proto/scenarios")
}

fn toml_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("proto/scenarios is readable") {
        let p = e.expect("a directory entry").path();
        if p.is_dir() {
            toml_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "toml") {
            out.push(p);
        }
    }
}

#[test]
fn every_scenario_file_passes_the_check() {
    let mut files = Vec::new();
    toml_files(&scenarios_dir(), &mut files);
    assert!(files.len() >= 5, "{files:?}");
    for f in files {
        if let Err(e) = deploy::cmd::scenario::check(&f) {
            panic!("{}: {e:#}", f.display());
        }
    }
}

/// Cameras whose image holds `p`.
fn seeing(s: &Scenario, p: &nalgebra::Vector3<f64>) -> usize {
    s.cameras()
        .filter(|c| {
            let cam = s.camera_model(c.id).expect("camera model");
            cam.project(p).is_some_and(|px| {
                let i = &cam.intrinsics;
                px.x >= 0.0 && px.y >= 0.0 && px.x < f64::from(i.width) && px.y < f64::from(i.height)
            })
        })
        .count()
}

#[test]
fn every_person_of_the_crowd_is_in_view_of_two_cameras_all_the_time() {
    let s = Scenario::load(&scenarios_dir().join("crowd.toml")).expect("crowd.toml");
    let people = world::targets(&s).expect("its people");
    assert!(people.len() >= 8);
    for t in &people {
        let fewest = (0..240)
            .map(|k| seeing(&s, &t.position_at(f64::from(k) * 0.25)))
            .min()
            .unwrap_or(0);
        assert!(fewest >= 2, "person {} is seen by only {fewest} cameras", t.id);
    }
}

#[test]
fn the_hall_is_the_generators_output_for_its_header() {
    let text = std::fs::read_to_string(scenarios_dir().join("hall.toml")).expect("hall.toml");
    let header: Vec<&str> = text.lines().take_while(|l| l.starts_with('#')).collect();
    assert!(
        header[0]
            .contains("ocelli scenario generate --cameras 100 --heads 5 --people 10 --size 30x20 --seed 1"),
        "{header:?}"
    );
    let body: String = text
        .lines()
        .skip(header.len())
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(body, generate_toml(&HallSpec::default()), "regenerate hall.toml");
    let s = Scenario::from_toml(&body, "hall.toml").expect("parses");
    assert_eq!((s.cameras().count(), s.heads().count()), (100, 5));
    assert!(world::targets(&s).expect("its people").len() >= 10);
}
