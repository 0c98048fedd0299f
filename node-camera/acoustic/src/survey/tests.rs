use super::*;
use crate::wav::tests::{TempDir, write_i16};
use proto::acoustic::IldVector;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

fn world() -> World {
    World {
        min: [0.0, 0.0, 0.0],
        max: [2.0, 2.0, 2.5],
        walls: Vec::new(),
        radio: RadioWorld::default(),
        geo: None,
    }
}

/// White noise on the left; the right is the left through a comb filter whose delay depends
/// on the position, so every position has its own ILD across frequency.
fn record(path: &Path, position: [f64; 2], seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 3000.0).unwrap();
    let left: Vec<f64> = (0..24_000).map(|_| noise.sample(&mut rng)).collect();
    let delay = 2 + (position[0] * 3.0 + position[1] * 7.0) as usize;
    let samples = (0..left.len()).flat_map(|i| {
        let r = 0.6 * left[i] + 0.4 * if i >= delay { left[i - delay] } else { 0.0 };
        [left[i] as i16, r as i16]
    });
    write_i16(path, 2, 48_000, samples);
}

fn settings() -> IldSettings {
    IldSettings {
        f_min_hz: 200.0,
        f_max_hz: 6000.0,
        frequencies: 32,
        ..IldSettings::default()
    }
}

#[test]
fn a_survey_fingerprints_each_position_and_a_new_recording_matches_its_own() {
    let dir = TempDir::new("survey");
    std::fs::create_dir_all(dir.0.join("rec")).unwrap();
    let positions = [[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5]];
    let mut csv = String::from("# a 2×2 survey\nx,y,wav\n");
    for (k, p) in positions.iter().enumerate() {
        record(&dir.0.join(format!("rec/p{k}.wav")), *p, k as u64);
        csv += &format!("{}, {}, rec/p{k}.wav\n", p[0], p[1]);
    }
    let csv_path = dir.0.join("positions.csv");
    std::fs::write(&csv_path, csv).unwrap();
    let db = survey(&csv_path, &world(), &settings()).unwrap();
    assert_eq!(db.fingerprints().len(), 4);
    assert_eq!(db.fingerprints()[1].position, [1.5, 0.5]);
    assert_eq!(db.lattice().shape, [2, 2]);
    // A new recording (other noise) at position 2 correlates best with fingerprint 2.
    let probe = dir.0.join("probe.wav");
    record(&probe, positions[2], 99);
    let mut analyzer = IldAnalyzer::new(&settings()).unwrap();
    let values = fingerprint_of(&probe, &mut analyzer).unwrap();
    let x = db
        .correlations(&IldVector::new(db.frequencies().to_vec(), values).unwrap())
        .unwrap();
    let best = (0..4).max_by(|a, b| x[*a].total_cmp(&x[*b])).unwrap();
    assert_eq!(best, 2, "correlations {x:?}");
    // The database survives its file.
    let out = dir.0.join("fp.json");
    db.save(&out).unwrap();
    assert_eq!(FingerprintDb::load(&out).unwrap(), db);
}

#[test]
fn bad_surveys_name_the_file_and_line() {
    let dir = TempDir::new("survey-bad");
    record(&dir.0.join("ok.wav"), [0.5, 0.5], 1);
    write_i16(
        &dir.0.join("mono.wav"),
        1,
        48_000,
        (0..4800).map(|i| (i % 200) as i16 * 50),
    );
    let run = |csv: &str| {
        let path = dir.0.join("p.csv");
        std::fs::write(&path, csv).unwrap();
        survey(&path, &world(), &settings()).unwrap_err().to_string()
    };
    let e = run("x,y,wav\n0.5,0.5,ok.wav\n1.5,0.5,gone.wav\n");
    assert!(
        e.contains("p.csv:3") && e.contains("gone.wav") && e.contains("does not exist"),
        "{e}"
    );
    let e = run("x,y,wav\n0.5,0.5,ok.wav\n2.5,0.5,ok.wav\n");
    assert!(e.contains("p.csv:3") && e.contains("outside the world"), "{e}");
    let e = run("x,y,file\n0.5,0.5,ok.wav\n");
    assert!(e.contains("p.csv:1") && e.contains("expected `x,y,wav`"), "{e}");
    let e = run("x,y,wav\n0.5,north,ok.wav\n");
    assert!(e.contains("p.csv:2") && e.contains("\"north\""), "{e}");
    let e = run("x,y,wav\n0.5,0.5\n");
    assert!(e.contains("p.csv:2") && e.contains("fewer than 3"), "{e}");
    let e = run("x,y,wav\n0.5,0.5,mono.wav\n");
    assert!(e.contains("mono.wav") && e.contains("1 channel"), "{e}");
    let e = run("x,y,wav\n");
    assert!(e.contains("no positions"), "{e}");
}

#[test]
fn bounding_world_spans_the_positions() {
    let rows = vec![
        SurveyRow {
            line: 2,
            position: [1.0, 2.0],
            wav: PathBuf::new(),
        },
        SurveyRow {
            line: 3,
            position: [3.0, -1.0],
            wav: PathBuf::new(),
        },
    ];
    let w = bounding_world(&rows, 0.5);
    assert_eq!((w.min, w.max), ([0.5, -1.5, 0.0], [3.5, 2.5, 3.0]));
}
