//! The metrics pinned to reference values: py-motmetrics 1.4.0 and Stone Soup 1.9.1 on the
//! inputs in `scenarios.json` (written by `scenarios.py`), as printed by `reference.py`:
//!
//! ```text
//! python -m venv venv && venv/bin/pip install motmetrics==1.4.0 stonesoup==1.9.1
//! venv/bin/python scenarios.py && venv/bin/python reference.py
//! ```
//!
//! `reference.py` feeds motmetrics' `MOTAccumulator` Euclidean distance matrices with NaN beyond
//! the threshold, summarises with `mm.metrics.create().compute`, derives the per-target values
//! from its event table and its `id_global_assignment`, and runs Stone Soup's
//! `GOSPAMetric(c, p).compute_over_time` on `State`s at the frame times. Hand-computed GOSPA
//! cases, consistency properties and input validation follow the reference cases.

use super::*;
use proptest::prelude::*;

/// What the reference tools gave for one scenario.
struct Expected {
    name: &'static str,
    mota: f64,
    motp_m: f64,
    idf1: f64,
    idp: f64,
    idr: f64,
    idtp: usize,
    id_switches: usize,
    fragmentations: usize,
    mostly_tracked: usize,
    partially_tracked: usize,
    mostly_lost: usize,
    false_positives: usize,
    misses: usize,
    matches: usize,
    objects: usize,
    predictions: usize,
    /// Mean distance, localisation, missed, false.
    gospa: [f64; 4],
    gospa_frames: usize,
    targets: &'static [TargetRow],
}

/// (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity).
type TargetRow = (u32, usize, usize, usize, usize, &'static [u32], Option<u32>);

/// Printed by `reference.py` (py-motmetrics 1.4.0, Stone Soup 1.9.1).
const EXPECTED: [Expected; 4] = [
    Expected {
        name: "switch_fp_miss",
        mota: 0.5,
        motp_m: 0.28898604422182345,
        idf1: 0.64,
        idp: 0.6153846153846154,
        idr: 0.6666666666666666,
        idtp: 8,
        id_switches: 1,
        fragmentations: 2,
        mostly_tracked: 1,
        partially_tracked: 1,
        mostly_lost: 0,
        false_positives: 3,
        misses: 2,
        matches: 9,
        objects: 12,
        predictions: 13,
        gospa: [
            1.2316434070363724,
            0.7316434070363723,
            0.16666666666666666,
            0.3333333333333333,
        ],
        gospa_frames: 6,
        // (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity)
        targets: &[
            (1, 6, 6, 1, 0, &[10, 11], Some(10)),
            (2, 6, 4, 0, 2, &[20], Some(20)),
        ],
    },
    Expected {
        name: "fragmentation",
        mota: 0.4722222222222222,
        motp_m: 0.2838719408423149,
        idf1: 0.6071428571428571,
        idp: 0.85,
        idr: 0.4722222222222222,
        idtp: 17,
        id_switches: 1,
        fragmentations: 4,
        mostly_tracked: 1,
        partially_tracked: 2,
        mostly_lost: 1,
        false_positives: 1,
        misses: 17,
        matches: 18,
        objects: 36,
        predictions: 20,
        gospa: [2.2893566876003986, 0.6893566876003983, 1.6, 0.0],
        gospa_frames: 10,
        // (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity)
        targets: &[
            (3, 10, 9, 0, 1, &[4], Some(4)),
            (5, 10, 7, 1, 2, &[7, 8], Some(7)),
            (6, 6, 0, 0, 0, &[], None),
            (9, 10, 3, 0, 1, &[12], Some(12)),
        ],
    },
    Expected {
        name: "crossing",
        mota: 0.7777777777777778,
        motp_m: 0.23061742605747018,
        idf1: 0.6666666666666666,
        idp: 0.6666666666666666,
        idr: 0.6666666666666666,
        idtp: 12,
        id_switches: 2,
        fragmentations: 1,
        mostly_tracked: 2,
        partially_tracked: 0,
        mostly_lost: 0,
        false_positives: 1,
        misses: 1,
        matches: 15,
        objects: 18,
        predictions: 18,
        gospa: [0.26542826466664793, 0.26542826466664793, 0.0, 0.0],
        gospa_frames: 9,
        // (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity)
        targets: &[
            (1, 9, 9, 1, 0, &[100, 200], Some(200)),
            (2, 9, 8, 1, 1, &[200, 100], Some(100)),
        ],
    },
    Expected {
        name: "three_d_mixed",
        mota: 0.6,
        motp_m: 0.6578590072872806,
        idf1: 0.8,
        idp: 0.8,
        idr: 0.8,
        idtp: 12,
        id_switches: 0,
        fragmentations: 2,
        mostly_tracked: 2,
        partially_tracked: 1,
        mostly_lost: 0,
        false_positives: 3,
        misses: 3,
        matches: 12,
        objects: 15,
        predictions: 15,
        gospa: [
            1.4919854070230223,
            0.6032142857142856,
            0.8571428571428571,
            0.8571428571428571,
        ],
        gospa_frames: 7,
        // (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity)
        targets: &[
            (7, 6, 6, 0, 0, &[1], Some(1)),
            (42, 6, 3, 0, 2, &[2], Some(2)),
            (100, 3, 3, 0, 0, &[5], Some(5)),
        ],
    },
];

#[derive(serde::Deserialize)]
struct Scenario {
    name: String,
    dim: usize,
    threshold: f64,
    gospa_c: f64,
    gospa_p: f64,
    frames: Vec<RawFrame>,
}

#[derive(serde::Deserialize)]
struct RawFrame {
    t: f64,
    truth: Vec<(u32, Vec<f64>)>,
    hyps: Vec<(u32, Vec<f64>)>,
}

fn scenarios() -> Vec<Scenario> {
    serde_json::from_str(include_str!("scenarios.json")).expect("scenarios.json parses")
}

fn frames<const D: usize>(s: &Scenario) -> Vec<Frame<D>> {
    let list = |l: &[(u32, Vec<f64>)]| -> Vec<(u32, [f64; D])> {
        l.iter()
            .map(|(id, p)| (*id, p.as_slice().try_into().expect("dimension")))
            .collect()
    };
    s.frames
        .iter()
        .map(|f| Frame {
            t: f.t,
            truth: list(&f.truth),
            hyps: list(&f.hyps),
        })
        .collect()
}

fn run(s: &Scenario) -> MotMetrics {
    let config = MetricsConfig {
        threshold_m: s.threshold,
        gospa_c_m: s.gospa_c,
        gospa_p: s.gospa_p,
    };
    match s.dim {
        2 => evaluate(&frames::<2>(s), &config),
        3 => evaluate(&frames::<3>(s), &config),
        d => panic!("dimension {d}"),
    }
    .expect("valid scenario")
}

fn close(name: &str, what: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() < 1e-9,
        "{name}: {what} = {got}, reference {want}"
    );
}

#[test]
fn clear_mot_identity_and_gospa_match_the_reference_tools() {
    let scenarios = scenarios();
    assert_eq!(scenarios.len(), EXPECTED.len());
    for (s, e) in scenarios.iter().zip(&EXPECTED) {
        assert_eq!(s.name, e.name);
        let m = run(s);
        let n = e.name;
        close(n, "mota", m.mota.unwrap(), e.mota);
        close(n, "motp_m", m.motp_m.unwrap(), e.motp_m);
        close(n, "idf1", m.idf1.unwrap(), e.idf1);
        close(n, "idp", m.idp.unwrap(), e.idp);
        close(n, "idr", m.idr.unwrap(), e.idr);
        let counts = [
            m.idtp,
            m.id_switches,
            m.fragmentations,
            m.mostly_tracked,
            m.partially_tracked,
            m.mostly_lost,
            m.false_positives,
            m.misses,
            m.matches,
            m.objects,
            m.predictions,
            m.gospa_frames,
        ];
        let want = [
            e.idtp,
            e.id_switches,
            e.fragmentations,
            e.mostly_tracked,
            e.partially_tracked,
            e.mostly_lost,
            e.false_positives,
            e.misses,
            e.matches,
            e.objects,
            e.predictions,
            e.gospa_frames,
        ];
        assert_eq!(
            counts, want,
            "{n}: idtp, switches, frag, MT, PT, ML, FP, misses, matches, objects, predictions, gospa frames"
        );
        let g = [m.gospa_m, m.gospa_localisation, m.gospa_missed, m.gospa_false];
        for (k, what) in ["gospa_m", "gospa_localisation", "gospa_missed", "gospa_false"]
            .iter()
            .enumerate()
        {
            close(n, what, g[k], e.gospa[k]);
        }
        let targets: Vec<_> = m
            .targets
            .iter()
            .map(|t| {
                (
                    t.id,
                    t.frames,
                    t.tracked,
                    t.id_switches,
                    t.fragmentations,
                    t.hyp_ids.clone(),
                    t.identity,
                )
            })
            .collect();
        let want: Vec<_> = e
            .targets
            .iter()
            .map(|&(id, f, tr, sw, fr, h, i)| (id, f, tr, sw, fr, h.to_vec(), i))
            .collect();
        assert_eq!(targets, want, "{n}: per target");
        for t in &m.targets {
            close(n, "coverage", t.coverage, t.tracked as f64 / t.frames as f64);
        }
    }
}

fn frame2(t: f64, truth: &[(u32, [f64; 2])], hyps: &[(u32, [f64; 2])]) -> Frame<2> {
    Frame {
        t,
        truth: truth.to_vec(),
        hyps: hyps.to_vec(),
    }
}

#[test]
fn events_say_which_pairs_switched_and_who_was_missed() {
    // Truth 1 is followed by 101, then 102 takes it over (a switch) while 101 drifts off
    // (a false positive); truth 2 is missed throughout.
    let frames = [
        frame2(0.0, &[(1, [0.0, 0.0]), (2, [5.0, 5.0])], &[(101, [0.2, 0.0])]),
        frame2(
            0.2,
            &[(1, [0.1, 0.0]), (2, [5.0, 5.0])],
            &[(101, [3.0, 0.0]), (102, [0.4, 0.0])],
        ),
    ];
    let ev = events(&frames, &MetricsConfig::default()).unwrap();
    assert_eq!(ev.len(), 2);
    assert_eq!(ev[0].pairs.len(), 1);
    let m = &ev[0].pairs[0];
    assert_eq!((m.truth, m.hypothesis, m.switch), (1, 101, false));
    assert!((m.distance_m - 0.2).abs() < 1e-12);
    assert_eq!(
        (ev[0].misses.clone(), ev[0].false_positives.clone()),
        (vec![2], vec![])
    );
    let m = &ev[1].pairs[0];
    assert_eq!((m.truth, m.hypothesis, m.switch), (1, 102, true));
    assert_eq!(
        (ev[1].misses.clone(), ev[1].false_positives.clone()),
        (vec![2], vec![101])
    );
    assert_eq!(ev[1].t, 0.2);
}

#[test]
fn a_frames_pairs_are_listed_by_truth_id_however_they_were_made() {
    // Truth 2 keeps its pair of frame 0 (made first, CLEAR MOT's step 1); truth 1 is paired in
    // frame 1's assignment (step 2).
    let frames = [
        frame2(0.0, &[(2, [5.0, 0.0])], &[(102, [5.1, 0.0])]),
        frame2(
            0.2,
            &[(2, [5.0, 0.0]), (1, [0.0, 0.0])],
            &[(102, [5.1, 0.0]), (101, [0.1, 0.0])],
        ),
    ];
    let ev = events(&frames, &MetricsConfig::default()).unwrap();
    let got: Vec<(u32, u32)> = ev[1].pairs.iter().map(|p| (p.truth, p.hypothesis)).collect();
    assert_eq!(got, vec![(1, 101), (2, 102)]);
}

/// The events of a run add up to its counts.
fn assert_events_sum_to<const D: usize>(name: &str, frames: &[Frame<D>], config: &MetricsConfig) {
    let m = evaluate(frames, config).unwrap();
    let ev = events(frames, config).unwrap();
    let pairs: Vec<&Pair> = ev.iter().flat_map(|e| &e.pairs).collect();
    let switches = pairs.iter().filter(|p| p.switch).count();
    assert_eq!(switches, m.id_switches, "{name}: switches");
    assert_eq!(pairs.len() - switches, m.matches, "{name}: matches");
    assert_eq!(
        ev.iter().map(|e| e.misses.len()).sum::<usize>(),
        m.misses,
        "{name}: misses"
    );
    assert_eq!(
        ev.iter().map(|e| e.false_positives.len()).sum::<usize>(),
        m.false_positives,
        "{name}: false positives"
    );
    if let Some(motp) = m.motp_m {
        let mean = pairs.iter().map(|p| p.distance_m).sum::<f64>() / pairs.len() as f64;
        assert!(
            (mean - motp).abs() < 1e-9,
            "{name}: MOTP {motp}, events' mean {mean}"
        );
    }
}

#[test]
fn events_of_the_reference_scenarios_add_up_to_their_counts() {
    for s in scenarios() {
        let config = MetricsConfig {
            threshold_m: s.threshold,
            gospa_c_m: s.gospa_c,
            gospa_p: s.gospa_p,
        };
        match s.dim {
            2 => assert_events_sum_to(&s.name, &frames::<2>(&s), &config),
            3 => assert_events_sum_to(&s.name, &frames::<3>(&s), &config),
            d => panic!("dimension {d}"),
        }
    }
}

#[test]
fn gospa_by_hand() {
    // Frame 0: truth A at the origin matched 0.5 m off; truth B at (10, 0) missed; a false
    // hypothesis at (3, 4), 5 m from A. Frame 1 is empty (not scored); frame 2 has one false
    // hypothesis. With c = 2, p = 1: frame 0 = 0.5 + 2/2 + 2/2 = 2.5, frame 2 = 1.
    let frames = [
        frame2(
            0.0,
            &[(1, [0.0, 0.0]), (2, [10.0, 0.0])],
            &[(7, [0.5, 0.0]), (8, [3.0, 4.0])],
        ),
        frame2(0.1, &[], &[]),
        frame2(0.2, &[], &[(9, [1.0, 1.0])]),
    ];
    let m = evaluate(
        &frames,
        &MetricsConfig {
            threshold_m: 1.0,
            gospa_c_m: 2.0,
            gospa_p: 1.0,
        },
    )
    .unwrap();
    assert_eq!(m.gospa_frames, 2);
    close("p=1", "gospa_m", m.gospa_m, (2.5 + 1.0) / 2.0);
    close("p=1", "localisation", m.gospa_localisation, 0.5 / 2.0);
    close("p=1", "missed", m.gospa_missed, 1.0 / 2.0);
    close("p=1", "false", m.gospa_false, 2.0 / 2.0);
    // p = 2: frame 0 = sqrt(0.25 + 4/2 + 4/2), frame 2 = sqrt(4/2).
    let m = evaluate(
        &frames,
        &MetricsConfig {
            threshold_m: 1.0,
            gospa_c_m: 2.0,
            gospa_p: 2.0,
        },
    )
    .unwrap();
    close("p=2", "gospa_m", m.gospa_m, (4.25f64.sqrt() + 2f64.sqrt()) / 2.0);
    close("p=2", "localisation", m.gospa_localisation, 0.25 / 2.0);
    close("p=2", "missed", m.gospa_missed, 2.0 / 2.0);
    close("p=2", "false", m.gospa_false, 4.0 / 2.0);
}

#[test]
fn gospa_assigns_optimally_not_nearest_first() {
    // Truths at x = 0 and 1.5, hypotheses at 0.8 and 2.3 (c = 2, p = 1). Nearest first pairs
    // 1.5 with 0.8 (0.7) and leaves 0 and 2.3 (2.3 ≥ c: a miss and a false target, 2): 2.7.
    // The optimum pairs 0–0.8 and 1.5–2.3: 1.6.
    let frames = [frame2(
        0.0,
        &[(1, [0.0, 0.0]), (2, [1.5, 0.0])],
        &[(1, [0.8, 0.0]), (2, [2.3, 0.0])],
    )];
    let m = evaluate(&frames, &MetricsConfig::default()).unwrap();
    close("optimal", "gospa_m", m.gospa_m, 1.6);
    close("optimal", "gospa_missed", m.gospa_missed, 0.0);
    // A pair exactly c apart is a miss plus a false target (Stone Soup keeps d < c only).
    let frames = [frame2(0.0, &[(1, [0.0, 0.0])], &[(1, [2.0, 0.0])])];
    let m = evaluate(&frames, &MetricsConfig::default()).unwrap();
    close("at c", "gospa_m", m.gospa_m, 2.0);
    close("at c", "gospa_localisation", m.gospa_localisation, 0.0);
    close("at c", "gospa_missed", m.gospa_missed, 1.0);
}

#[test]
fn json_names_are_stable() {
    let m = run(&scenarios()[0]);
    let v = serde_json::to_value(&m).unwrap();
    for key in [
        "mota",
        "motp_m",
        "idf1",
        "idp",
        "idr",
        "id_switches",
        "fragmentations",
        "mostly_tracked",
        "partially_tracked",
        "mostly_lost",
        "false_positives",
        "misses",
        "matches",
        "gospa_m",
        "gospa_localisation",
        "gospa_missed",
        "gospa_false",
        "targets",
    ] {
        assert!(v.get(key).is_some_and(|x| !x.is_null()), "missing {key}");
    }
    let t = &v["targets"][0];
    for key in [
        "id",
        "coverage",
        "id_switches",
        "fragmentations",
        "hyp_ids",
        "identity",
    ] {
        assert!(t.get(key).is_some(), "target is missing {key}");
    }
    let back: MotMetrics = serde_json::from_value(v).unwrap();
    assert_eq!(back, m);
}

#[test]
fn undefined_ratios_are_none() {
    // Only false tracks: no truth, so MOTA, IDR and MOTP are undefined; IDP is 0.
    let frames = [frame2(0.0, &[], &[(3, [0.0, 0.0])])];
    let m = evaluate(&frames, &MetricsConfig::default()).unwrap();
    assert_eq!((m.mota, m.motp_m, m.idr), (None, None, None));
    assert_eq!((m.idp, m.idf1, m.false_positives), (Some(0.0), Some(0.0), 1));
    let m = evaluate::<3>(&[], &MetricsConfig::default()).unwrap();
    assert_eq!((m.frames, m.idf1, m.gospa_m, m.gospa_frames), (0, None, 0.0, 0));
}

#[test]
fn bad_input_is_named() {
    let ok = frame2(0.0, &[(1, [0.0, 0.0])], &[(1, [0.0, 0.0])]);
    let cfg = MetricsConfig::default();
    let bad_cfg = |c: MetricsConfig| evaluate(std::slice::from_ref(&ok), &c).unwrap_err();
    assert!(matches!(
        bad_cfg(MetricsConfig {
            threshold_m: 0.0,
            ..cfg
        }),
        MetricsError::Parameter {
            name: "threshold_m",
            ..
        }
    ));
    assert!(matches!(
        bad_cfg(MetricsConfig {
            gospa_c_m: f64::NAN,
            ..cfg
        }),
        MetricsError::Parameter {
            name: "gospa_c_m",
            ..
        }
    ));
    let e = bad_cfg(MetricsConfig { gospa_p: 0.5, ..cfg });
    assert_eq!(e.to_string(), "gospa_p = 0.5: expected a finite number >= 1");
    let e = evaluate(&[ok.clone(), frame2(0.0, &[], &[])], &cfg).unwrap_err();
    assert_eq!(
        e,
        MetricsError::Time {
            frame: 1,
            t: 0.0,
            previous: 0.0
        }
    );
    let e = evaluate(&[frame2(0.0, &[(4, [0.0, 0.0]), (4, [1.0, 0.0])], &[])], &cfg).unwrap_err();
    assert_eq!(e.to_string(), "frame 0: truth id 4 appears twice");
    let e = evaluate(&[ok, frame2(1.0, &[], &[(2, [f64::INFINITY, 0.0])])], &cfg).unwrap_err();
    assert_eq!(
        e,
        MetricsError::NonFinite {
            frame: 1,
            side: Side::Hypothesis,
            id: 2
        }
    );
}

/// Random runs: up to 4 truths and 4 hypotheses per frame on a small grid of ids, positions in
/// a 4 m square.
fn random_run() -> impl Strategy<Value = Vec<Frame<2>>> {
    let list = || prop::collection::btree_map(0u32..6, (0.0..4.0f64, 0.0..4.0f64), 0..5);
    prop::collection::vec((list(), list()), 1..12).prop_map(|frames| {
        frames
            .into_iter()
            .enumerate()
            .map(|(k, (truth, hyps))| Frame {
                t: k as f64 * 0.1,
                truth: truth.into_iter().map(|(id, (x, y))| (id, [x, y])).collect(),
                hyps: hyps.into_iter().map(|(id, (x, y))| (id + 100, [x, y])).collect(),
            })
            .collect()
    })
}

proptest! {
    #[test]
    fn counts_add_up(frames in random_run()) {
        let m = evaluate(&frames, &MetricsConfig::default()).unwrap();
        prop_assert_eq!(m.matches + m.id_switches + m.misses, m.objects);
        prop_assert_eq!(m.matches + m.id_switches + m.false_positives, m.predictions);
        prop_assert_eq!(m.mostly_tracked + m.partially_tracked + m.mostly_lost, m.unique_objects);
        prop_assert!(m.idtp <= m.objects.min(m.predictions));
        prop_assert_eq!(m.targets.iter().map(|t| t.id_switches).sum::<usize>(), m.id_switches);
        prop_assert_eq!(m.targets.iter().map(|t| t.tracked).sum::<usize>(), m.matches + m.id_switches);
        if let Some(motp) = m.motp_m {
            prop_assert!((0.0..=1.0).contains(&motp));
            // The targets' own MOTPs, weighed by their matches, give the run's.
            let weighed: f64 = m.targets.iter().filter_map(|t| t.motp_m.map(|x| x * t.tracked as f64)).sum();
            prop_assert!((weighed / (m.matches + m.id_switches) as f64 - motp).abs() < 1e-9);
        }
        // Each target's IDF1 counts the frames it shares with its identity: together the IDTP.
        for t in &m.targets {
            prop_assert!((0.0..=1.0).contains(&t.idf1));
            if t.identity.is_none() {
                prop_assert_eq!(t.idf1, 0.0);
            }
        }
        // GOSPA with p = 1 adds up, and is at most c/2 per present target.
        prop_assert!((m.gospa_localisation + m.gospa_missed + m.gospa_false - m.gospa_m).abs() < 1e-9);
    }

    #[test]
    fn events_add_up_to_the_counts(frames in random_run()) {
        assert_events_sum_to("random run", &frames, &MetricsConfig::default());
    }

    #[test]
    fn a_perfect_tracker_scores_perfectly(frames in random_run()) {
        let perfect: Vec<Frame<2>> = frames
            .iter()
            .map(|f| Frame { t: f.t, truth: f.truth.clone(), hyps: f.truth.iter().map(|(id, p)| (id + 50, *p)).collect() })
            .collect();
        let m = evaluate(&perfect, &MetricsConfig::default()).unwrap();
        prop_assert_eq!((m.misses, m.false_positives, m.id_switches, m.fragmentations), (0, 0, 0, 0));
        prop_assert_eq!(m.idtp, m.objects);
        prop_assert!(m.gospa_m.abs() < 1e-12);
        for t in &m.targets {
            prop_assert_eq!((t.idf1, t.motp_m), (1.0, Some(0.0)));
        }
        if m.objects > 0 {
            prop_assert_eq!((m.mota, m.idf1), (Some(1.0), Some(1.0)));
        }
    }
}
