//! Validation at the boundary: every decoded message is checked before any node sees it.
//!
//! Checks: finite numbers; symmetric information matrices and covariances that are not
//! indefinite beyond [`PSD_TOLERANCE`]; sane sizes; plausible ranges.

use crate::msg::*;
use crate::observation::{GroundPerson, HISTOGRAM_BINS, HISTOGRAM_HS_BINS, MAX_BINS, MAX_OBSERVATIONS};
use crate::{MAX_CONTRIBUTORS, MAX_MEASURED_DETECTIONS, PROTOCOL_VERSION};
use nalgebra::{Matrix6, SymmetricEigen};
use thiserror::Error;

/// Relative tolerance for symmetry and for negative eigenvalues of PSD matrices.
pub const PSD_TOLERANCE: f64 = 1e-6;

/// What is wrong with a message; the string names the field.
#[derive(Debug, Error, PartialEq, Clone)]
#[error("{field}: {problem}")]
pub struct ValidationError {
    pub field: &'static str,
    pub problem: String,
}

fn err(field: &'static str, problem: impl Into<String>) -> ValidationError {
    ValidationError {
        field,
        problem: problem.into(),
    }
}

/// Something that can be checked at the boundary.
pub trait Validate {
    /// # Errors
    /// The first problem found, naming the field.
    fn validate(&self) -> Result<(), ValidationError>;
}

fn finite(field: &'static str, xs: &[f64]) -> Result<(), ValidationError> {
    match xs.iter().find(|x| !x.is_finite()) {
        Some(x) => Err(err(field, format!("not a finite number ({x})"))),
        None => Ok(()),
    }
}

fn finite32(field: &'static str, xs: &[f32]) -> Result<(), ValidationError> {
    match xs.iter().find(|x| !x.is_finite()) {
        Some(x) => Err(err(field, format!("not a finite number ({x})"))),
        None => Ok(()),
    }
}

/// Check a 6×6 matrix is finite, symmetric and positive semi-definite within tolerance.
///
/// # Errors
/// Names `field` and the first violated property.
#[allow(clippy::needless_range_loop)] // (i, j) index pairs read clearer than zipped iterators
pub fn check_psd6(field: &'static str, m: &Mat6) -> Result<(), ValidationError> {
    for row in m {
        finite(field, row)?;
    }
    let scale = m
        .iter()
        .flatten()
        .fold(0.0f64, |a, x| a.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    for i in 0..6 {
        for j in (i + 1)..6 {
            if (m[i][j] - m[j][i]).abs() > PSD_TOLERANCE * scale {
                return Err(err(
                    field,
                    format!("not symmetric at ({i},{j}): {} vs {}", m[i][j], m[j][i]),
                ));
            }
        }
    }
    // Decompose the matrix scaled to unit magnitude: entries near f64::MAX would overflow the
    // eigen-solver into NaN, and a NaN comparison must not wave an indefinite matrix through.
    let mat = Matrix6::from_fn(|i, j| 0.5 * (m[i][j] / scale + m[j][i] / scale));
    let min = SymmetricEigen::new(mat).eigenvalues.min();
    if min.is_nan() || min < -PSD_TOLERANCE {
        return Err(err(
            field,
            format!("indefinite (smallest eigenvalue {:e})", min * scale),
        ));
    }
    Ok(())
}

fn check_cov2(field: &'static str, c: &[f64; 3]) -> Result<(), ValidationError> {
    finite(field, c)?;
    let [xx, xy, yy] = *c;
    if xx <= 0.0 || yy <= 0.0 || xx * yy - xy * xy <= 0.0 {
        return Err(err(field, "covariance is not positive definite"));
    }
    Ok(())
}

fn check_grid(g: &GridPosterior) -> Result<(), ValidationError> {
    finite32(
        "track_report.grid",
        &[g.origin[0], g.origin[1], g.cell_m, g.peak_mass],
    )?;
    if !(g.cell_m > 0.0 && (0.0..=1.0).contains(&g.peak_mass)) {
        return Err(err(
            "track_report.grid",
            format!(
                "cell {} m and peak mass {} (expected a positive cell, a mass in [0, 1])",
                g.cell_m, g.peak_mass
            ),
        ));
    }
    let side = 1..=MAX_GRID_POSTERIOR_SIDE;
    if !(side.contains(&g.nx) && side.contains(&g.ny)) {
        return Err(err(
            "track_report.grid",
            format!(
                "{}x{} cells (expected 1..={MAX_GRID_POSTERIOR_SIDE} per side)",
                g.nx, g.ny
            ),
        ));
    }
    if g.cells.len() != usize::from(g.nx) * usize::from(g.ny) {
        return Err(err(
            "track_report.grid",
            format!("{} values for {}x{} cells", g.cells.len(), g.nx, g.ny),
        ));
    }
    Ok(())
}

impl Validate for Envelope {
    fn validate(&self) -> Result<(), ValidationError> {
        self.body.validate()
    }
}

impl Validate for Message {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Message::Hello(h) => {
                if h.version != PROTOCOL_VERSION {
                    return Err(err(
                        "hello.version",
                        format!(
                            "protocol version {} is not supported (this build speaks {PROTOCOL_VERSION})",
                            h.version
                        ),
                    ));
                }
                Ok(())
            }
            Message::HelloAck(a) => {
                if a.reason.len() > 512 {
                    return Err(err("hello_ack.reason", "longer than 512 bytes"));
                }
                Ok(())
            }
            Message::Heartbeat => Ok(()),
            Message::Measurement(m) => {
                finite("measurement.pose.rvec", &m.pose.rvec)?;
                finite("measurement.pose.tvec", &m.pose.tvec)?;
                check_observations("measurement.observations", &m.observations)
            }
            Message::Answers(a) => check_answers(a),
            Message::NodeStatus(_) => Ok(()),
            Message::Priors(p) => check_priors(p),
            Message::Command(_) => Ok(()),
            Message::TrackReport(r) => {
                finite("track_report.mean", &r.mean)?;
                check_psd6("track_report.cov", &r.cov)?;
                finite("track_report.power_mw", &[r.power_mw])?;
                if r.power_mw < 0.0 {
                    return Err(err(
                        "track_report.power_mw",
                        format!("negative power {} mW", r.power_mw),
                    ));
                }
                check_bins("track_report.appearance", &r.appearance)?;
                if let Some(g) = &r.grid {
                    check_grid(g)?;
                }
                if r.contributors.len() > MAX_CONTRIBUTORS {
                    return Err(err(
                        "track_report.contributors",
                        format!(
                            "{} entries exceed the maximum of {MAX_CONTRIBUTORS}",
                            r.contributors.len()
                        ),
                    ));
                }
                Ok(())
            }
            Message::Assignment(_) => Ok(()),
            Message::Handover(h) => {
                finite("handover.mean", &h.mean)?;
                check_psd6("handover.cov", &h.cov)
            }
            Message::SyncBeacon(_) => Ok(()),
            Message::Liveness(_) => Ok(()),
            Message::FrameReport(_) => Ok(()),
            Message::MeasuredFrame(f) => {
                if f.detections.len() > MAX_MEASURED_DETECTIONS {
                    return Err(err(
                        "measured_frame.detections",
                        format!(
                            "{} entries exceed the maximum of {MAX_MEASURED_DETECTIONS}",
                            f.detections.len()
                        ),
                    ));
                }
                if f.rssi.len() > MAX_OBSERVATIONS {
                    return Err(err(
                        "measured_frame.rssi",
                        format!(
                            "{} entries exceed the maximum of {MAX_OBSERVATIONS}",
                            f.rssi.len()
                        ),
                    ));
                }
                for r in &f.rssi {
                    check_dbm("measured_frame.rssi", r.dbm)?;
                }
                for d in &f.detections {
                    finite32("measured_frame.detections.centre", &d.centre)?;
                    finite32("measured_frame.detections.foot", &d.foot)?;
                    check_box("measured_frame.detections.pixel_box", &d.pixel_box)?;
                    let c = &d.colour;
                    finite32(
                        "measured_frame.detections.colour",
                        &[c.hue, c.saturation, c.intensity],
                    )?;
                    finite("measured_frame.detections.point", &d.point)?;
                    check_cov2("measured_frame.detections.cov", &d.cov)?;
                }
                Ok(())
            }
            Message::SampleRequest(_) => Ok(()),
            Message::SampleSet(s) => {
                if s.samples.len() > MAX_SAMPLES {
                    return Err(err(
                        "sample_set.samples",
                        format!("{} entries exceed the maximum of {MAX_SAMPLES}", s.samples.len()),
                    ));
                }
                for x in &s.samples {
                    finite32("sample_set.samples", &x.state)?;
                    finite32("sample_set.samples", &[x.weight])?;
                    if x.weight < 0.0 {
                        return Err(err("sample_set.samples", format!("negative weight {}", x.weight)));
                    }
                }
                Ok(())
            }
            Message::ViewSubscribe(_) => Ok(()),
            Message::ViewUpdate(u) => check_view_update(u),
            Message::PeopleFrame(f) => check_people_frame(f),
            Message::TagsHeard(t) => {
                at_most("tags_heard.tags", t.tags.len(), MAX_TAGS_HEARD)?;
                increasing("tags_heard.tags", t.tags.iter().map(|h| h.tag))?;
                t.tags.iter().try_for_each(|h| {
                    check_dbm("tags_heard.tags", f64::from(h.dbm))?;
                    finite32("tags_heard.tags", &h.near)
                })
            }
            Message::TagHomes(t) => {
                at_most("tag_homes.homes", t.homes.len(), MAX_TAGS_HEARD)?;
                increasing("tag_homes.homes", t.homes.iter().map(|h| h.tag))
            }
        }
    }
}

/// Tags named each once, in increasing order (a set: a second entry of one tag would be two
/// answers to one question).
fn increasing(field: &'static str, tags: impl Iterator<Item = crate::TagId>) -> Result<(), ValidationError> {
    let mut last = None;
    for t in tags {
        if last.is_some_and(|l| l >= t) {
            return Err(err(field, format!("tag {t} is out of order or named twice")));
        }
        last = Some(t);
    }
    Ok(())
}

fn at_most(field: &'static str, len: usize, max: usize) -> Result<(), ValidationError> {
    if len > max {
        return Err(err(field, format!("{len} entries exceed the maximum of {max}")));
    }
    Ok(())
}

/// A message that is `part` of `parts` (of `whole`, which has 1 to `max` parts).
fn check_part(
    field: &'static str,
    whole: &str,
    part: u16,
    parts: u16,
    max: u16,
) -> Result<(), ValidationError> {
    if parts == 0 || parts > max || part >= parts {
        return Err(err(
            field,
            format!("part {part} of {parts} ({whole} has 1 to {max} parts)"),
        ));
    }
    Ok(())
}

/// A view update: bounded lists, a part within its round, finite tracks with a position
/// covariance whose variances are not negative.
fn check_view_update(u: &crate::view::ViewUpdate) -> Result<(), ValidationError> {
    use crate::view::{
        MAX_VIEW_CONTRIBUTORS, MAX_VIEW_HANDOVERS, MAX_VIEW_NODES, MAX_VIEW_PARTS, MAX_VIEW_TRACKS,
    };
    check_part("view_update.part", "a round", u.part, u.parts, MAX_VIEW_PARTS)?;
    at_most("view_update.tracks", u.tracks.len(), MAX_VIEW_TRACKS)?;
    at_most("view_update.nodes", u.nodes.len(), MAX_VIEW_NODES)?;
    at_most("view_update.handovers", u.handovers.len(), MAX_VIEW_HANDOVERS)?;
    for t in &u.tracks {
        finite("view_update.tracks.mean", &t.mean)?;
        finite("view_update.tracks.cov_pos", &t.cov_pos)?;
        let c = &t.cov_pos;
        if c[0] < 0.0 || c[3] < 0.0 || c[5] < 0.0 {
            return Err(err("view_update.tracks.cov_pos", "a negative variance"));
        }
        at_most(
            "view_update.tracks.contributors",
            t.contributors.len(),
            MAX_VIEW_CONTRIBUTORS,
        )?;
    }
    Ok(())
}

/// A step's priors: a part within the step's parts, 1 to [`MAX_PRIORS`] priors of one step
/// and deadline, each track once, with finite means and proper covariances.
fn check_priors(p: &Priors) -> Result<(), ValidationError> {
    check_part("priors.part", "a step", p.part, p.parts, MAX_PRIOR_PARTS)?;
    if p.tracks.is_empty() {
        return Err(err("priors.tracks", "no prior"));
    }
    at_most("priors.tracks", p.tracks.len(), MAX_PRIORS)?;
    let first = &p.tracks[0];
    for (i, t) in p.tracks.iter().enumerate() {
        if t.step != first.step || t.deadline != first.deadline {
            return Err(err(
                "priors.tracks",
                format!(
                    "step {} (deadline {}) beside step {} (deadline {})",
                    t.step, t.deadline.0, first.step, first.deadline.0
                ),
            ));
        }
        if p.tracks[..i].iter().any(|q| q.target == t.target) {
            return Err(err("priors.tracks", format!("track {} twice", t.target)));
        }
        finite("priors.tracks.mean", &t.mean)?;
        check_psd6("priors.tracks.cov", &t.cov)?;
    }
    Ok(())
}

/// A node's answers: at most [`MAX_PRIORS`] contributions, each track once, each bringing
/// one thing (information that is finite and positive semi-definite, or a ground-plane person
/// gated to that track), and bounded, plausible tag readings.
fn check_answers(a: &Answers) -> Result<(), ValidationError> {
    at_most("answers.rssi", a.rssi.len(), MAX_OBSERVATIONS)?;
    for r in &a.rssi {
        check_dbm("answers.rssi", r.dbm)?;
    }
    at_most("answers.contributions", a.contributions.len(), MAX_PRIORS)?;
    for (i, c) in a.contributions.iter().enumerate() {
        if a.contributions[..i].iter().any(|q| q.target == c.target) {
            return Err(err("answers.contributions", format!("track {} twice", c.target)));
        }
        // Exactly one of the two: what a node folded, or the person for the head to fold.
        // (It also bounds a full message well inside a frame.)
        match (&c.info, &c.ground) {
            (None, None) => {
                return Err(err(
                    "answers.contributions",
                    format!("the contribution to {} brings nothing", c.target),
                ));
            }
            (Some(_), Some(_)) => {
                return Err(err(
                    "answers.contributions",
                    format!(
                        "the contribution to {} brings both information and a person",
                        c.target
                    ),
                ));
            }
            _ => {}
        }
        if let Some(info) = &c.info {
            check_psd6("answers.contributions.info.matrix", &info.matrix)?;
            finite("answers.contributions.info.vector", &info.vector)?;
        }
        if let Some(p) = &c.ground {
            if p.target.is_some_and(|t| t != c.target) {
                return Err(err(
                    "answers.contributions.ground",
                    format!(
                        "a ground person gated to {} in a contribution to {}",
                        p.target.unwrap_or(c.target),
                        c.target
                    ),
                ));
            }
            check_person(p).map_err(|e| {
                err(
                    "answers.contributions.ground",
                    format!("{}: {}", e.field, e.problem),
                )
            })?;
        }
    }
    Ok(())
}

/// A camera's people: bounded lists, each person once, readings in range, every person's
/// quantised covariance positive definite and its histogram a histogram.
fn check_people_frame(f: &PeopleFrame) -> Result<(), ValidationError> {
    at_most("people_frame.people", f.people.len(), MAX_OBSERVATIONS)?;
    at_most("people_frame.rssi", f.rssi.len(), MAX_OBSERVATIONS)?;
    for r in &f.rssi {
        check_dbm("people_frame.rssi", r.dbm)?;
    }
    for (i, p) in f.people.iter().enumerate() {
        if f.people[..i].iter().any(|q| q.local == p.local) {
            return Err(err("people_frame.people", format!("person {} twice", p.local)));
        }
        check_person(p).map_err(|e| err("people_frame.people", format!("{}: {}", e.field, e.problem)))?;
    }
    Ok(())
}

/// A quantised person: proper standard deviations and correlation (so its covariance is
/// positive definite), a histogram of the right size with each part's fullest bin at 255.
fn check_person(p: &GroundPerson) -> Result<(), ValidationError> {
    if p.sigma_mm.contains(&0) {
        return Err(err("ground.sigma_mm", "a standard deviation of 0 mm"));
    }
    if p.correlation == i8::MIN {
        return Err(err(
            "ground.correlation",
            "-128 (a correlation of -1: the covariance is singular)",
        ));
    }
    let Some(h) = &p.histogram else {
        return Ok(());
    };
    if h.len() != HISTOGRAM_BINS {
        return Err(err(
            "ground.histogram",
            format!("{} bins (expected {HISTOGRAM_BINS})", h.len()),
        ));
    }
    let (hs, v) = h.split_at(HISTOGRAM_HS_BINS);
    if hs.iter().max() != Some(&255) || v.iter().max() != Some(&255) {
        return Err(err("ground.histogram", "a part whose fullest bin is not 255"));
    }
    Ok(())
}

/// Each observation of a list: finite numbers, proper covariances, sane sizes.
fn check_observations(field: &'static str, obs: &[Observation]) -> Result<(), ValidationError> {
    if obs.len() > MAX_OBSERVATIONS {
        return Err(err(
            field,
            format!("{} entries exceed the maximum of {MAX_OBSERVATIONS}", obs.len()),
        ));
    }
    obs.iter().try_for_each(|o| {
        o.validate()
            .map_err(|e| err(field, format!("{}: {}", e.field, e.problem)))
    })
}

impl Validate for Observation {
    fn validate(&self) -> Result<(), ValidationError> {
        match self {
            Observation::Pinhole(p) => {
                finite("pinhole.point", &p.point)?;
                if let Some(q) = p.prev_point {
                    finite("pinhole.prev_point", &q)?;
                }
                check_cov2("pinhole.cov", &p.cov)?;
                check_box("pinhole.pixel_box", &p.pixel_box)?;
                finite32(
                    "pinhole.colour",
                    &[p.colour.hue, p.colour.saturation, p.colour.intensity],
                )
            }
            Observation::Rssi(r) => check_dbm("rssi.dbm", r.dbm),
            Observation::Ground(p) => check_person(p),
            Observation::Acoustic(a) => {
                finite32("acoustic.bands", &[a.first_hz, a.step_hz])?;
                if a.first_hz < 0.0 || a.step_hz <= 0.0 {
                    return Err(err("acoustic.bands", "expected first ≥ 0 Hz and a positive step"));
                }
                check_bins("acoustic.ild_db", &a.ild_db)
            }
        }
    }
}

fn check_bins(field: &'static str, xs: &[f32]) -> Result<(), ValidationError> {
    if xs.len() > MAX_BINS {
        return Err(err(
            field,
            format!("{} bins exceed the maximum of {MAX_BINS}", xs.len()),
        ));
    }
    finite32(field, xs)
}

fn check_dbm(field: &'static str, dbm: f64) -> Result<(), ValidationError> {
    finite(field, &[dbm])?;
    if !(-200.0..=30.0).contains(&dbm) {
        return Err(err(field, format!("{dbm} dBm is outside -200..30 dBm")));
    }
    Ok(())
}

fn check_box(field: &'static str, b: &PixelBox) -> Result<(), ValidationError> {
    finite32(field, &[b.xmin, b.ymin, b.xmax, b.ymax])?;
    if b.xmax < b.xmin || b.ymax < b.ymin {
        return Err(err(field, "max is below min"));
    }
    Ok(())
}
