//! The four studies: their scenes, their rows and their shape checks.

use super::camera::{self, CameraRun, Illumination, Setup, Tracker, Walker};
use super::score::{self, Single, mean, share};
use super::{FPS, NAME};
use crate::experiment::runner::{Errors, Sample};
use crate::experiment::{Check, Extra, Options, Outcome, ParticleTrace, Row, Trace};
use node_camera::tracker::params::ParticleParams;
use proto::scenario::{Scenario, Wall};
use world::{Target, Trajectory};

/// The camera node every study watches through.
pub const CAMERA: u32 = 10;
/// Where node 10 looks on the floor and its position there, m (the default scenario's pose).
const LOOK_AT: [f64; 2] = [3.73, 2.27];
const CAMERA_XY: [f64; 2] = [0.95, 0.15];
/// The single person enters after the background model has seen the empty room this long, s.
const ENTER_S: f64 = 2.0;
/// The crowd: people, seconds between entries, walking speed (m/s), and the empty seconds
/// after the last one leaves (filters must be destroyed by then).
const CROWD: usize = 6;
const CROWD_GAP_S: f64 = 3.0;
const CROWD_SPEED: f64 = 0.7;
const CROWD_TAIL_S: f64 = 4.0;
/// The people's colours (the crowd's six; the five in view take the first five).
const COLOURS: [[u8; 3]; CROWD] = [
    [200, 40, 40],
    [40, 170, 60],
    [50, 70, 210],
    [220, 200, 40],
    [190, 60, 190],
    [40, 180, 190],
];
/// The bandwidth goal's case: a stream of people on the crowd's paths, one entering every
/// [`STREAM_GAP_S`], five or more in view at once for a good part of it.
const STREAM: usize = 16;
const STREAM_GAP_S: f64 = 1.0;
/// The illumination settings: name and the end gain of each colour channel.
const LIGHTS: [(&str, [f64; 3]); 2] = [
    ("dimming to 50%", [0.5, 0.5, 0.5]),
    ("dimming with colour shift", [0.45, 0.65, 0.95]),
];

const SEGMENTATION: &str = "segmentation alone";
const PARTICLE: &str = "particle filters";
/// The particle filters as the networked scenarios run them: only what a region supports
/// this frame is reported (`report-unsupported = false`).
const PARTICLE_SUPPORTED: &str = "particle filters, supported only";

/// Unit vectors along node 10's view on the floor and across it.
fn axes() -> ([f64; 2], [f64; 2]) {
    let d = [LOOK_AT[0] - CAMERA_XY[0], LOOK_AT[1] - CAMERA_XY[1]];
    let n = d[0].hypot(d[1]);
    let along = [d[0] / n, d[1] / n];
    (along, [-along[1], along[0]])
}

fn at(base: [f64; 2], dir: [f64; 2], s: f64) -> [f64; 2] {
    [base[0] + s * dir[0], base[1] + s * dir[1]]
}

fn person(id: u32, colour: [u8; 3], trajectory: Trajectory) -> Target {
    Target {
        id,
        trajectory,
        size: [0.5, 0.3, 1.7],
        colour,
        rssi_tag: false,
    }
}

/// The red person walking to and fro across node 10's view, 1.4 m either side of its centre.
fn walker() -> Walker {
    let (_, across) = axes();
    Walker {
        target: person(
            1,
            [200, 40, 40],
            Trajectory::Loop {
                waypoints: vec![at(LOOK_AT, across, 1.4), at(LOOK_AT, across, -1.4)],
                speed: 0.5,
                pauses: Vec::new(),
            },
        ),
        enter_s: ENTER_S,
        leave_s: f64::INFINITY,
    }
}

fn setup(scenario: Scenario, walkers: Vec<Walker>, duration_s: f64) -> Setup {
    Setup {
        scenario,
        camera: CAMERA,
        walkers,
        fps: FPS,
        duration_s,
        illumination: None,
    }
}

/// The occlusion scene: a pillar `width_m` wide and 3 m high, 1.2 m in front of the walk's
/// middle.
pub fn occlusion_scene(duration_s: f64, width_m: f64) -> Setup {
    let mut s = Scenario::default_scenario();
    s.name = format!("{NAME}-occlusion");
    let (along, across) = axes();
    let centre = at(LOOK_AT, along, -1.2);
    s.world.walls.push(Wall {
        from: at(centre, across, -0.5 * width_m),
        to: at(centre, across, 0.5 * width_m),
        height: 3.0,
        attenuation_db: 0.0,
    });
    setup(s, vec![walker()], duration_s)
}

fn particle() -> Tracker {
    Tracker::Particle(ParticleParams::default())
}

/// The methods the occlusion and crowd studies compare: segmentation alone, the particle
/// filters as the paper has them, and as the networked scenarios run them.
fn compared() -> [(&'static str, Tracker); 3] {
    let supported_only = Tracker::Particle(ParticleParams {
        report_unsupported: false,
        ..ParticleParams::default()
    });
    [
        (SEGMENTATION, Tracker::Segmentation),
        (PARTICLE, particle()),
        (PARTICLE_SUPPORTED, supported_only),
    ]
}

/// Every run of `tracker` on `setup`, seeds from `opts`.
fn runs(
    setup: &Setup,
    tracker: &Tracker,
    opts: &Options,
    jpeg_every: usize,
) -> crate::error::Result<Vec<CameraRun>> {
    (0..opts.runs.max(1))
        .map(|k| camera::run(setup, tracker, opts.seed.wrapping_add(u64::from(k)), jpeg_every))
        .collect()
}

/// A single-person study's row from its runs' scores.
fn single_row(method: String, scores: &[Single]) -> Row {
    let sum = |f: fn(&Single) -> usize| scores.iter().map(f).sum::<usize>();
    let all = |f: fn(&Single) -> &Vec<f64>| scores.iter().flat_map(f).copied().collect::<Vec<_>>();
    let samples: Vec<Vec<Sample>> = scores.iter().map(|s| s.samples.clone()).collect();
    let hidden = sum(|s| s.hidden);
    let per_run = |f: fn(&Single) -> usize| Some(sum(f) as f64 / scores.len().max(1) as f64);
    let mut extra = vec![
        Extra::new("tracked", share(sum(|s| s.tracked), sum(|s| s.in_view)), 3),
        Extra::new("lost frames", per_run(|s| s.in_view - s.tracked), 1),
        Extra::new("img err px", mean(&all(|s| &s.image_px)), 1),
    ];
    if hidden > 0 {
        extra.push(Extra::new(
            "tracked hidden",
            share(sum(|s| s.tracked_hidden), hidden),
            3,
        ));
        extra.push(Extra::new(
            "img err hidden px",
            mean(&all(|s| &s.image_px_hidden)),
            1,
        ));
    }
    extra.push(Extra::new("ids", per_run(|s| s.identities), 2));
    extra.push(Extra::new("spurious ids", per_run(|s| s.spurious), 2));
    Row {
        method,
        extra,
        ..Row::default()
    }
    .with_errors(Errors::of(&samples, |_| true))
}

fn extra(row: Option<&Row>, name: &str) -> f64 {
    row.and_then(|r| r.extra.iter().find(|e| e.name == name))
        .and_then(|e| e.value)
        .unwrap_or(f64::NAN)
}

/// One of study 1's pillars.
struct Pillar {
    /// Row label.
    study: &'static str,
    width_m: f64,
    /// How its checks and note name it.
    name: &'static str,
    /// How much of the person it hides.
    hides: &'static str,
}

/// Study 1's pillars. The narrow one hides a vertical strip of the 0.5 m wide person; the wide
/// one nine tenths of them, so that the sliver beside it is often too small a region for
/// segmentation alone (paper 004's case: the filter keeps a person segmentation loses).
const PILLARS: [Pillar; 2] = [
    Pillar {
        study: "1 occlusion",
        width_m: 0.2,
        name: "Partial occlusion",
        hides: "a vertical strip",
    },
    Pillar {
        study: "1 wide occlusion",
        width_m: 0.45,
        name: "Wide partial occlusion",
        hides: "all but a sliver",
    },
];

/// Study 1: the pillars.
///
/// # Errors
/// As [`camera::run`].
pub fn occlusion(opts: &Options, duration_s: f64, out: &mut Outcome) -> crate::error::Result<()> {
    for k in 0..PILLARS.len() {
        pillar(opts, duration_s, k, out)?;
    }
    Ok(())
}

/// Pillar `k`'s rows, traces (the first pillar's also the particle figure), note and checks.
fn pillar(opts: &Options, duration_s: f64, k: usize, out: &mut Outcome) -> crate::error::Result<()> {
    let Pillar {
        study,
        width_m,
        name,
        hides,
    } = PILLARS[k];
    let narrow = k == 0;
    let scene = occlusion_scene(duration_s, width_m);
    for (label, tracker) in compared() {
        let runs = runs(&scene, &tracker, opts, 0)?;
        let scores: Vec<Single> = runs.iter().map(score::single).collect();
        let windows = runs
            .first()
            .map(|r| score::hidden_windows(&r.frames))
            .unwrap_or_default();
        let method = format!("{study}: {label}");
        let row = single_row(method.clone(), &scores);
        // Ground error while hidden, as its own column.
        let hidden = Errors::of(
            &scores.iter().map(|s| s.samples.clone()).collect::<Vec<_>>(),
            |t| windows.iter().any(|w| t >= w.0 && t < w.1),
        );
        let mut row = row;
        row.extra
            .push(Extra::new("ground err hidden m", hidden.map(|e| e.mean), 3));
        out.rows.push(row);
        out.traces.push(Trace {
            method: method.clone(),
            samples: scores.first().map(|s| s.samples.clone()).unwrap_or_default(),
            window: windows.first().copied(),
        });
        if label == PARTICLE {
            if narrow {
                out.particles = runs
                    .first()
                    .and_then(|r| r.particles.clone())
                    .map(|p| ParticleTrace {
                        method: method.clone(),
                        ..p
                    });
                out.notes.push(
                    "Figs. 6–7 (`--plot`: paper004-particles.png), the first particle run of the occlusion study: the filters' pdf over time projected on the image's columns and rows, and the frame four frames into the first partial occlusion with every sample (size: weight) and each filter's mean."
                        .into(),
                );
            }
            let hidden_s: f64 = windows.iter().map(|w| w.1 - w.0).sum();
            out.notes.push(format!(
                "{}: a pillar {width_m} m wide, 3 m high, 1.2 m in front of the middle of a 2.8 m walk at 0.5 m/s across node 10's view, 3.5 m away; it hides the person's centre {hidden_s:.1} s of {duration_s:.0} s in the first run ({} passes), {hides} of them (they are 0.5 m wide) while it does. The person enters after {ENTER_S} s of empty room. Segmentation alone keeps an id while a region overlaps the previous frame's region of that id; a region that splits off, or comes back after a frame without one, gets a new id.",
                if narrow { "Occlusion" } else { "Wide occlusion" },
                windows.len(),
            ));
        }
    }
    let seg = out.row(&format!("{study}: {SEGMENTATION}"));
    let pf = out.row(&format!("{study}: {PARTICLE}"));
    let (th_s, th_p) = (extra(seg, "tracked hidden"), extra(pf, "tracked hidden"));
    let (id_s, id_p) = (extra(seg, "ids"), extra(pf, "ids"));
    if narrow {
        out.shape.push(Check::new(
            "Partial occlusion: the particle filters keep the person in at least as many hidden frames as segmentation alone",
            th_p >= th_s,
            format!("tracked while hidden {th_p:.3} vs {th_s:.3}"),
        ));
    } else {
        out.shape.push(Check::new(
            &format!(
                "{name} (a pillar {width_m} m wide before a 0.5 m wide person): the particle filters keep the person in more hidden frames than segmentation alone, which loses them"
            ),
            th_p > th_s && th_s < 1.0,
            format!("tracked while hidden {th_p:.3} vs {th_s:.3}"),
        ));
    }
    out.shape.push(Check::new(
        &format!(
            "{name}: the particle filters give the person fewer identities than segmentation alone (no loss, no split)"
        ),
        id_p < id_s,
        format!("{id_p:.2} vs {id_s:.2} ids per run"),
    ));
    Ok(())
}

/// Study 2: adaptation on and off under each illumination change.
///
/// # Errors
/// As [`camera::run`].
pub fn illumination(opts: &Options, duration_s: f64, out: &mut Outcome) -> crate::error::Result<()> {
    let on = ParticleParams::default();
    let off = ParticleParams {
        alpha: 0.0,
        ..on.clone()
    };
    let mut ours = Vec::new();
    for (name, end_gain) in LIGHTS {
        let mut scene = setup(Scenario::default_scenario(), vec![walker()], duration_s);
        scene.illumination = Some(Illumination {
            end_gain,
            from_s: ENTER_S,
            to_s: duration_s,
        });
        let mut pair = Vec::new();
        for (label, p) in [("adaptation on", &on), ("adaptation off", &off)] {
            let runs = runs(&scene, &Tracker::Particle(p.clone()), opts, 0)?;
            let scores: Vec<Single> = runs.iter().map(score::single).collect();
            let row = single_row(format!("2 {name}: {label}"), &scores);
            pair.push((extra(Some(&row), "lost frames"), extra(Some(&row), "img err px")));
            out.rows.push(row);
        }
        ours.push(format!(
            "{name}: lost {:.1} vs {:.1} frames, image error {:.1} vs {:.1} px",
            pair[0].0, pair[1].0, pair[0].1, pair[1].1
        ));
        if name == LIGHTS[LIGHTS.len() - 1].0 {
            out.shape.push(Check::new(
                "Self-adaptation (colour shift): with adaptation the filter loses the person in no more frames, with no larger image error, than without",
                pair[0].0 <= pair[1].0 && pair[0].1 <= pair[1].1,
                ours.join("; "),
            ));
        }
    }
    out.notes.push(format!(
        "Illumination: the occlusion study's walk without the pillar; from {ENTER_S} s to the end every channel's gain goes linearly from 1 to the end gain ({}), laid over the rendered frames (the renderer's own ±8% change stays underneath). Adaptation off is alpha = 0; on is the scenario's alpha = {} with its similarity and foreground gates.",
        LIGHTS
            .iter()
            .map(|(n, g)| format!("{n}: {g:?}"))
            .collect::<Vec<_>>()
            .join(", "),
        on.alpha
    ));
    Ok(())
}

/// The crowd: six people in six colours crossing node 10's view, from beyond its left edge to
/// beyond its right edge, one every [`CROWD_GAP_S`].
pub fn crowd_scene() -> Setup {
    people_stream("crowd", CROWD, CROWD_GAP_S)
}

/// The crowd's `k`-th walker: the paths repeat every [`CROWD`] people, each from beyond the
/// view's left edge to beyond its right, entering at `enter_s`.
fn crowd_walker(k: usize, enter_s: f64) -> Walker {
    let j = (k % CROWD) as f64;
    let from = [1.1, 4.0 + 0.6 * j];
    let to = [4.5 + 0.7 * j, 0.2];
    let length = (to[0] - from[0]).hypot(to[1] - from[1]);
    Walker {
        target: person(
            k as u32 + 1,
            COLOURS[k % CROWD],
            Trajectory::Path {
                waypoints: vec![from, to],
                speed: CROWD_SPEED,
                pauses: Vec::new(),
            },
        ),
        enter_s,
        leave_s: enter_s + length / CROWD_SPEED + 0.5,
    }
}

/// `n` people on the crowd's paths, one entering every `gap_s` from 1 s, the run ending
/// [`CROWD_TAIL_S`] after the last has left.
fn people_stream(name: &str, n: usize, gap_s: f64) -> Setup {
    let walkers: Vec<Walker> = (0..n).map(|k| crowd_walker(k, 1.0 + gap_s * k as f64)).collect();
    let last = walkers.iter().map(|w| w.leave_s).fold(0.0, f64::max);
    let mut s = Scenario::default_scenario();
    s.name = format!("{NAME}-{name}");
    setup(s, walkers, (last + CROWD_TAIL_S).ceil())
}

/// The stream: [`STREAM`] people on the crowd's paths, one entering every [`STREAM_GAP_S`].
pub fn stream_scene() -> Setup {
    people_stream("stream", STREAM, STREAM_GAP_S)
}

/// A CLEAR MOT row of `runs`, with each run's metrics.
fn mot_row(
    method: String,
    runs: &[CameraRun],
) -> crate::error::Result<(Row, Vec<node_server::metrics::MotMetrics>)> {
    let mots = runs
        .iter()
        .map(score::mot)
        .collect::<crate::error::Result<Vec<_>>>()?;
    let avg = |f: &dyn Fn(&node_server::metrics::MotMetrics) -> Option<f64>| {
        let v: Vec<f64> = mots.iter().filter_map(f).collect();
        mean(&v)
    };
    // A count of each run's, averaged over the runs.
    let per_run =
        |count: &dyn Fn(&CameraRun) -> usize| mean(&runs.iter().map(|r| count(r) as f64).collect::<Vec<_>>());
    let row = Row {
        method,
        extra: vec![
            Extra::new("MOTA", avg(&|m| m.mota), 3),
            Extra::new("IDF1", avg(&|m| m.idf1), 3),
            Extra::new("MOTP m", avg(&|m| m.motp_m), 3),
            Extra::new("ids", avg(&|m| Some(m.unique_hypotheses as f64)), 2),
            Extra::new("id switches", avg(&|m| Some(m.id_switches as f64)), 2),
            Extra::new("misses", avg(&|m| Some(m.misses as f64)), 1),
            Extra::new("false pos", avg(&|m| Some(m.false_positives as f64)), 1),
            Extra::new("on people out of view", per_run(&score::on_people_out_of_view), 1),
            Extra::new("second reports", per_run(&score::second_reports), 1),
            Extra::new("mostly lost", avg(&|m| Some(m.mostly_lost as f64)), 2),
            Extra::new("live at end", per_run(&|r| r.live_at_end), 2),
        ],
        ..Row::default()
    };
    Ok((row, mots))
}

/// Study 3b: the particle filters in a stream of people, five or more in view at once for a
/// good part of it (the bandwidth goal's case). Returns its runs (for the bandwidth).
///
/// # Errors
/// As [`camera::run`].
pub fn stream(opts: &Options, duration_s: f64, out: &mut Outcome) -> crate::error::Result<Vec<CameraRun>> {
    let mut scene = stream_scene();
    if opts.duration_s.is_some() {
        scene.duration_s = scene.duration_s.min(duration_s);
    }
    let runs = runs(&scene, &particle(), opts, 0)?;
    let (row, _) = mot_row(format!("3 stream: {PARTICLE}"), &runs)?;
    out.rows.push(row);
    out.notes.push(format!(
        "Stream: {STREAM} people on the crowd's paths (its colours in turn), one entering every {STREAM_GAP_S} s, up to {} in view at once; {:.0} s per run, scored as the crowd. The bandwidth's five-in-view rows are taken over its frames with five or more people in view ({:.1} s per run).",
        runs.iter().flat_map(|r| &r.frames).map(in_view).max().unwrap_or(0),
        scene.duration_s,
        runs.iter().flat_map(|r| &r.frames).filter(|f| in_view(f) >= FIVE).count() as f64 / FPS / runs.len().max(1) as f64,
    ));
    Ok(runs)
}

/// Study 3: CLEAR MOT of both methods in the crowd. Returns the particle filters' runs (for
/// the bandwidth).
///
/// # Errors
/// As [`camera::run`].
pub fn crowd(opts: &Options, duration_s: f64, out: &mut Outcome) -> crate::error::Result<Vec<CameraRun>> {
    let mut scene = crowd_scene();
    // A shorter duration asked for cuts the crowd short too (fewer people enter then).
    if opts.duration_s.is_some() {
        scene.duration_s = scene.duration_s.min(duration_s);
    }
    let mut kept = Vec::new();
    let mut mota = Vec::new();
    for (label, tracker) in compared() {
        let runs = runs(&scene, &tracker, opts, FPS as usize)?;
        let (row, mots) = mot_row(format!("3 crowd: {label}"), &runs)?;
        mota.push(extra(Some(&row), "MOTA"));
        let people: usize = mots.first().map_or(0, |m| m.unique_objects);
        if label == PARTICLE {
            let lost: usize = mots.iter().map(|m| m.mostly_lost).sum();
            out.shape.push(Check::new(
                "Crowd: every person who enters is picked up by a filter of its own (none mostly lost)",
                lost == 0 && people > 0,
                format!("{lost} mostly lost over {} runs of {people} people", runs.len()),
            ));
            let live: usize = runs.iter().map(|r| r.live_at_end).sum();
            out.shape.push(Check::new(
                "Crowd: filters are destroyed once their people have left (none alive at the end)",
                live == 0,
                format!(
                    "{live} filters alive {CROWD_TAIL_S} s after the last person left, over {} runs",
                    runs.len()
                ),
            ));
            kept = runs;
        }
        out.rows.push(row);
    }
    out.shape.push(Check::new(
        "Crowd (ours, not a paper claim): the particle filters' MOTA is at least segmentation alone's",
        mota[1] >= mota[0],
        format!("{:.3} vs {:.3}", mota[1], mota[0]),
    ));
    out.shape.push(Check::new(
        "Crowd (ours): reporting only the filters a region supports (`report-unsupported = false`, as the crowd and hall scenarios do) gives a MOTA at least segmentation alone's",
        mota[2] >= mota[0],
        format!("{:.3} vs {:.3}", mota[2], mota[0]),
    ));
    out.notes.push(format!(
        "Crowd: {CROWD} people (0.5 x 0.3 x 1.7 m, six colours) cross node 10's view diagonally at {CROWD_SPEED} m/s from beyond its left edge to beyond its right, entering every {CROWD_GAP_S} s, up to four in view at once; {:.0} s per run, the last {CROWD_TAIL_S} s empty. Truth: the people whose centre projects inside the image; a report within 1 m of someone whose centre is out of it (half out of the image, or just gone) and of no one in view is a false positive for both methods, counted in `on people out of view`; `second reports` counts the reports beyond a person's first (each report given to the nearest true person in view within 1 m): two filters on one person, or one whose person left sitting on another. CLEAR MOT and IDF1 from node_server::metrics on the floor with a 1 m threshold; MOTA, IDF1, MOTP mean over runs, counts per run. `supported only` (here and in the occlusion rows): the particle filters with `report-unsupported = false`, reporting a filter only in frames where a region supports it (the crowd and hall scenarios' setting, where heads fuse many cameras and predict a hidden person themselves; the filters run as the row above's). The occlusion rows show its cost to a camera standing alone: the person behind the pillar is not reported while no region supports their filter.",
        scene.duration_s
    ));
    Ok(kept)
}

/// The five of the bandwidth goal: frames with this many people in view or more.
const FIVE: usize = 5;

/// People whose centre is in view in a frame.
fn in_view(f: &camera::FrameRecord) -> usize {
    f.truth.iter().filter(|p| p.in_view).count()
}

/// Bytes per second of the frames of a set of particle runs that `keep` keeps.
struct Rates {
    seconds: f64,
    /// People in view and people reported, per frame.
    in_view: f64,
    reported: f64,
    /// What the camera sends (one people frame per head step), with a deployment's time
    /// stamps, and had every frame been sent; every filter's sample set every frame.
    sent: Option<f64>,
    wall_clock: Option<f64>,
    every_frame: Option<f64>,
    sample_sets: Option<f64>,
    /// Bytes per person sent, and histograms sent per second.
    per_person_sent: Option<f64>,
    histograms_per_s: Option<f64>,
    /// Filters per frame (a filter whose person walked out of view is not reported for its
    /// last frames, but has a sample set).
    filters: f64,
}

fn rates(runs: &[CameraRun], keep: fn(&camera::FrameRecord) -> bool) -> Rates {
    let frames: Vec<&camera::FrameRecord> = runs.iter().flat_map(|r| &r.frames).filter(|f| keep(f)).collect();
    let seconds = frames.len() as f64 / FPS;
    let per_s = |bytes: usize| (seconds > 0.0).then(|| bytes as f64 / seconds);
    let sum = |f: fn(&camera::FrameRecord) -> usize| frames.iter().map(|r| f(r)).sum::<usize>();
    let per_frame = |f: fn(&camera::FrameRecord) -> usize| {
        mean(&frames.iter().map(|r| f(r) as f64).collect::<Vec<_>>()).unwrap_or(0.0)
    };
    let sent_people = sum(|f| f.people_sent);
    Rates {
        seconds,
        in_view: per_frame(in_view),
        reported: per_frame(|f| f.reported.len()),
        filters: per_frame(|f| f.sample_sets),
        sent: per_s(sum(|f| f.observation_bytes)),
        wall_clock: per_s(sum(|f| f.wall_clock_bytes)),
        every_frame: per_s(sum(|f| f.every_frame_bytes)),
        sample_sets: per_s(sum(|f| f.sample_set_bytes)),
        per_person_sent: (sent_people > 0).then(|| sum(|f| f.observation_bytes) as f64 / sent_people as f64),
        histograms_per_s: per_s(sum(|f| f.histograms_sent)),
    }
}

/// Study 4: bytes per second of the crowd's particle runs, and of the stream's frames with five
/// or more people in view.
pub fn bandwidth(crowd: &[CameraRun], stream: &[CameraRun], out: &mut Outcome) {
    let c = rates(crowd, |_| true);
    let f = rates(stream, |f| in_view(f) >= FIVE);
    let (w, h) = crowd.first().map_or((0, 0), |r| (r.width, r.height));
    let raw = f64::from(w) * f64::from(h) * 3.0 * FPS;
    let jpegs: Vec<f64> = crowd
        .iter()
        .flat_map(|r| &r.frames)
        .filter_map(|f| f.jpeg_bytes.map(|b| b as f64))
        .collect();
    let jpeg = mean(&jpegs).map(|b| b * FPS);
    // Per person: per person reported (what the camera sends is its people); for the sample
    // sets, per filter (each has one).
    let row = |method: &str, v: Option<f64>, r: &Rates, people: Option<f64>| Row {
        method: format!("4 bandwidth: {method}"),
        extra: vec![
            Extra::new("bytes/s", v, 0),
            Extra::new(
                "bytes/s per person",
                v.zip(people.filter(|&n| n > 0.0)).map(|(v, n)| v / n),
                0,
            ),
            Extra::new("people in view", Some(r.in_view), 2),
            Extra::new("people reported", Some(r.reported), 2),
        ],
        ..Row::default()
    };
    out.rows
        .push(row("ground observations as sent", c.sent, &c, Some(c.reported)));
    out.rows.push(row(
        "ground observations, had every frame been sent",
        c.every_frame,
        &c,
        Some(c.reported),
    ));
    out.rows.push(row(
        "five or more in view: ground observations as sent",
        f.sent,
        &f,
        Some(f.reported),
    ));
    out.rows.push(row(
        "five or more in view: had every frame been sent",
        f.every_frame,
        &f,
        Some(f.reported),
    ));
    out.rows.push(row(
        "every sample set every frame",
        c.sample_sets,
        &c,
        Some(c.filters),
    ));
    out.rows
        .push(row(&format!("raw RGB {w}x{h} frames"), Some(raw), &c, None));
    out.rows.push(row(
        &format!("JPEG q{} frames", camera::JPEG_QUALITY),
        jpeg,
        &c,
        None,
    ));
    let nan = |v: Option<f64>| v.unwrap_or(f64::NAN);
    let five_bps = nan(f.sent);
    out.shape.push(Check::new(
        "Bandwidth: a camera with five or more people in view puts at most 2 kB/s of ground observations on the wire (the issue's goal; also with a deployment's time stamps)",
        five_bps <= 2000.0 && nan(f.wall_clock) <= 2000.0 && f.in_view >= FIVE as f64,
        format!(
            "{five_bps:.0} B/s ({:.0} B/s with wall-clock time stamps), {:.2} people in view and {:.2} reported per frame",
            nan(f.wall_clock),
            f.in_view,
            f.reported
        ),
    ));
    let j = nan(jpeg);
    let ob = nan(c.sent);
    out.shape.push(Check::new(
        "Bandwidth: what leaves the camera is at least 100 times smaller than even compressed video",
        ob * 100.0 <= j,
        format!(
            "{ob:.0} B/s vs JPEG {j:.0} B/s ({:.0}x), raw {raw:.0} B/s",
            j / ob
        ),
    ));
    let s = nan(c.sample_sets) / c.filters;
    out.shape.push(Check::new(
        "Bandwidth: every filter's sample set every frame costs the paper's order, within 3x of 15 kB/s per filter",
        (5000.0..=45000.0).contains(&s),
        format!("{s:.0} B/s per filter at {FPS} fps"),
    ));
    out.notes.push(format!(
        "Bandwidth: the crowd's particle runs ({:.0} s of frames, {:.2} people in view and {:.2} reported per frame on average) and the stream's frames with five or more people in view ({:.0} s, {:.2} in view, {:.2} reported). Ground observations are the people frames the camera core sends (`node_camera::ground_people::PeopleSender`, protocol encoding with its envelope): one per head step ({} ms) with the newest frame's people, quantised, {:.0} bytes per person sent in the crowd and {:.0} in the stream's, the colour histogram with a person's first frame and then only when it changed (Bhattacharyya distance > {}, at most every {} s) or every {} s ({:.2} and {:.2} histograms/s); time stamps count from the run's start, with a deployment's (nanoseconds since the Unix epoch) the stream's are {:.0} B/s. `had every frame been sent` is the same message at every frame ({FPS} fps), not what the camera does. Per person is per person reported, for the sample sets per filter ({:.2} filters per frame in the crowd: a filter whose person walked out of view is not reported in its last frames). Sample sets are every filter's SampleSet envelope every frame (100 samples of 7 f32), which the camera sends only on request; raw is 8-bit RGB; JPEG is the `image` crate's baseline encoder at quality {} on every {FPS}th frame. Paper: about 15 kB/s per camera for 100 samples; raw VGA at 15 fps is 37 Mbit/s (8-bit Bayer).",
        c.seconds,
        c.in_view,
        c.reported,
        f.seconds,
        f.in_view,
        f.reported,
        Scenario::default_scenario().method.step_ms,
        nan(c.per_person_sent),
        nan(f.per_person_sent),
        node_camera::ground_people::HISTOGRAM_CHANGE,
        node_camera::ground_people::HISTOGRAM_MIN_PERIOD_NS / 1_000_000_000,
        node_camera::ground_people::HISTOGRAM_REFRESH_NS / 1_000_000_000,
        nan(c.histograms_per_s),
        nan(f.histograms_per_s),
        nan(f.wall_clock),
        c.filters,
        camera::JPEG_QUALITY
    ));
}

/// The paper's figures: its bandwidth numbers (the paper gives no tracking table).
pub fn paper() -> Vec<Row> {
    let row = |method: &str, bps: f64| Row {
        method: method.into(),
        extra: vec![Extra::new("bytes/s", Some(bps), 0)],
        ..Row::default()
    };
    vec![
        row("4 bandwidth: sample set of 100 particles", 15_000.0),
        row("4 bandwidth: raw VGA 8-bit at 15 fps", 640.0 * 480.0 * 15.0),
    ]
}
