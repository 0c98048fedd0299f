//! Google Earth as a visualization node (paper 004 §3.4.3): KML of the live view and of whole
//! recordings.
//!
//! - [`network_link`]: what `/live.kml` answers, a NetworkLink that makes Google Earth fetch
//!   `/tracks.kml` every second.
//! - [`live_document`]: what `/tracks.kml` answers, one placemark per track (its global id as the
//!   name, at its position) and per camera (its position, and its field of view on the floor,
//!   coloured by mode).
//! - [`kml_for_recording`]: a whole recording for `ocelli export --format kml`, each global
//!   track a `gx:Track` of time-stamped positions (its owner's estimates, as
//!   [`node_server::export`] gives them), so Google Earth's time slider plays it back.
//!
//! Positions go through [`Geo`]; without a `[world.geo]` there is nothing to place, and the
//! functions say so ([`KmlError::NoGeo`], [`NO_GEO`]). Altitudes are absolute: the origin's
//! altitude plus the world z.

use crate::geo::Geo;
use crate::state::{NodeView, ViewState};
use node_server::analysis::Loaded;
use node_server::export::track_rows;
use proto::Mode;
use quick_xml::escape::escape;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write;
use thiserror::Error;

/// The KML media type.
pub const CONTENT_TYPE: &str = "application/vnd.google-earth.kml+xml";

/// What the KML endpoints and export answer without `[world.geo]`.
pub const NO_GEO: &str = "no [world.geo] in the scenario: Google Earth needs to know where the site is.\n\
Add to the scenario, with the floor origin's WGS84 latitude and longitude (degrees), its altitude\n\
above mean sea level (m) and the compass bearing of the world's +y axis:\n\n\
[world.geo]\norigin = [48.5, 9.06, 320.0]\nheading-deg = 0.0\n";

/// Why KML could not be written.
#[derive(Debug, Error)]
pub enum KmlError {
    #[error("{NO_GEO}")]
    NoGeo,
    #[error(transparent)]
    Geo(#[from] crate::geo::GeoError),
    #[error("writing KML: {0}")]
    Io(#[from] std::io::Error),
}

/// What [`kml_for_recording`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KmlSummary {
    pub tracks: usize,
    pub points: usize,
    pub cameras: usize,
}

const HEADER: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<kml xmlns=\"http://www.opengis.net/kml/2.2\" \
xmlns:gx=\"http://www.google.com/kml/ext/2.2\">\n";

/// Styles: KML colours are `aabbggrr`.
const STYLES: &str = "<Style id=\"track\"><IconStyle><color>ff2a6bff</color><scale>1.2</scale>\
<Icon><href>http://maps.google.com/mapfiles/kml/shapes/man.png</href></Icon></IconStyle>\
<LineStyle><color>ff2a6bff</color><width>3</width></LineStyle></Style>\n\
<Style id=\"camera-active\"><IconStyle><color>ff3cb43c</color></IconStyle>\
<LineStyle><color>ff3cb43c</color></LineStyle><PolyStyle><color>553cb43c</color></PolyStyle></Style>\n\
<Style id=\"camera-off\"><IconStyle><color>ff00a5ff</color></IconStyle>\
<LineStyle><color>ff00a5ff</color></LineStyle><PolyStyle><color>4400a5ff</color></PolyStyle></Style>\n\
<Style id=\"camera-inactive\"><IconStyle><color>ff909090</color></IconStyle>\
<LineStyle><color>ff909090</color></LineStyle><PolyStyle><color>22909090</color></PolyStyle></Style>\n\
<Style id=\"camera-down\"><IconStyle><color>ff2020e0</color></IconStyle>\
<LineStyle><color>ff2020e0</color><width>2</width></LineStyle><PolyStyle><color>112020e0</color></PolyStyle></Style>\n";

/// `/live.kml`: a NetworkLink to `href` (the absolute `/tracks.kml` URL), refreshed every second.
pub fn network_link(href: &str) -> String {
    format!(
        "{HEADER}<NetworkLink><name>Ocelli live</name><open>1</open><flyToView>1</flyToView>\
         <Link><href>{}</href><refreshMode>onInterval</refreshMode><refreshInterval>1</refreshInterval>\
         </Link></NetworkLink>\n</kml>\n",
        escape(href)
    )
}

fn coord(geo: &Geo, p: [f64; 3]) -> String {
    let g = geo.to_wgs84(p);
    format!("{:.8},{:.8},{:.3}", g.lon, g.lat, g.alt)
}

fn camera_style(n: &NodeView) -> &'static str {
    match (n.up, n.mode) {
        (false, _) => "camera-down",
        (true, Some(Mode::CameraOff)) => "camera-off",
        (true, Some(Mode::Inactive)) => "camera-inactive",
        (true, _) => "camera-active",
    }
}

/// The camera placemarks of a view.
fn cameras(out: &mut String, geo: &Geo, state: &ViewState) -> usize {
    let mut count = 0;
    out.push_str("<Folder><name>Cameras</name>\n");
    for n in state.nodes.values() {
        let Some(cam) = &n.camera else { continue };
        count += 1;
        let mode = n.mode.map_or("mode unknown".to_string(), |m| format!("{m:?}"));
        let life = match (n.up, n.stale) {
            (false, _) => "down",
            (true, true) => "stale",
            (true, false) => "up",
        };
        let mut ring: Vec<String> = cam
            .footprint
            .iter()
            .map(|p| coord(geo, [p[0], p[1], 0.05]))
            .collect();
        if let Some(first) = ring.first().cloned() {
            ring.push(first);
        }
        let _ = writeln!(
            out,
            "<Placemark id=\"camera-{id}\"><name>camera {id}</name><description>{mode}, {life}, head {head}</description>\
             <styleUrl>#{style}</styleUrl><MultiGeometry>\
             <Point><altitudeMode>absolute</altitudeMode><coordinates>{pos}</coordinates></Point>\
             <Polygon><altitudeMode>absolute</altitudeMode><outerBoundaryIs><LinearRing><coordinates>{ring}</coordinates>\
             </LinearRing></outerBoundaryIs></Polygon></MultiGeometry></Placemark>",
            id = n.id,
            head = n.head.map_or("none".into(), |h| h.to_string()),
            style = camera_style(n),
            pos = coord(geo, cam.position),
            ring = ring.join(" "),
        );
    }
    out.push_str("</Folder>\n");
    count
}

/// `/tracks.kml`: one placemark per track and per camera of the view.
///
/// # Errors
/// [`KmlError::NoGeo`] without `[world.geo]`; a `[world.geo]` that does not validate.
pub fn live_document(state: &ViewState) -> Result<String, KmlError> {
    let geo = state.geo.ok_or(KmlError::NoGeo)?;
    geo.validate()?;
    let mut out = String::with_capacity(4096 + 512 * state.nodes.len());
    out.push_str(HEADER);
    let _ = writeln!(
        out,
        "<Document><name>Ocelli: {}</name>",
        escape(state.scenario.as_str())
    );
    out.push_str(STYLES);
    out.push_str("<Folder><name>Tracks</name>\n");
    for t in state.tracks.values() {
        let _ = writeln!(
            out,
            "<Placemark id=\"track-{g}\"><name>t{g}</name><description>head {owner}, σ {sigma:.2} m, \
             {cams} cameras</description><styleUrl>#track</styleUrl>\
             <Point><altitudeMode>absolute</altitudeMode><coordinates>{pos}</coordinates></Point></Placemark>",
            g = t.global,
            owner = t.owner,
            sigma = t.sigma_m,
            cams = t.cameras.len(),
            pos = coord(&geo, t.position),
        );
    }
    out.push_str("</Folder>\n");
    cameras(&mut out, &geo, state);
    out.push_str("</Document>\n</kml>\n");
    Ok(out)
}

/// ISO 8601 UTC time of nanoseconds since the Unix epoch, to the millisecond.
pub fn iso8601(ns: i64) -> String {
    let secs = ns.div_euclid(1_000_000_000);
    let millis = ns.rem_euclid(1_000_000_000) / 1_000_000;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let (y, m, d) = civil_from_days(days);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// Year, month, day of a day count since 1970-01-01 (proleptic Gregorian; H. Hinnant's
/// `civil_from_days`).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = (if mp < 10 { mp + 3 } else { mp - 9 }) as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

/// A whole recording as KML: every global track a `gx:Track` of its owner's time-stamped
/// positions, and the cameras as they were at the start.
///
/// # Errors
/// IO errors of `out`; a `[world.geo]` that does not validate.
pub fn kml_for_recording(loaded: &Loaded, geo: &Geo, out: &mut impl Write) -> Result<KmlSummary, KmlError> {
    geo.validate()?;
    let mut by_global: BTreeMap<u32, Vec<(f64, [f64; 3])>> = BTreeMap::new();
    for r in track_rows(loaded).into_iter().filter(|r| r.owner) {
        by_global
            .entry(r.global)
            .or_default()
            .push((r.t, [r.x, r.y, r.z]));
    }
    let mut doc = String::new();
    doc.push_str(HEADER);
    let _ = writeln!(
        doc,
        "<Document><name>Ocelli recording: {}</name>",
        escape(loaded.scenario.name.as_str())
    );
    doc.push_str(STYLES);
    out.write_all(doc.as_bytes())?;
    let mut summary = KmlSummary::default();
    out.write_all(b"<Folder><name>Tracks</name>\n")?;
    for (g, mut points) in by_global {
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut s = format!(
            "<Placemark id=\"track-{g}\"><name>t{g}</name><styleUrl>#track</styleUrl>\
             <gx:Track><altitudeMode>absolute</altitudeMode>\n"
        );
        for (t, _) in &points {
            let _ = writeln!(s, "<when>{}</when>", iso8601((t * 1e9).round() as i64));
        }
        for (_, p) in &points {
            let g = geo.to_wgs84(*p);
            let _ = writeln!(s, "<gx:coord>{:.8} {:.8} {:.3}</gx:coord>", g.lon, g.lat, g.alt);
        }
        s.push_str("</gx:Track></Placemark>\n");
        out.write_all(s.as_bytes())?;
        summary.tracks += 1;
        summary.points += points.len();
    }
    out.write_all(b"</Folder>\n")?;
    let mut site = ViewState::with_scenario(&loaded.scenario);
    site.set_geo(Some(*geo));
    let mut cams = String::new();
    summary.cameras = cameras(&mut cams, geo, &site);
    out.write_all(cams.as_bytes())?;
    out.write_all(b"</Document>\n</kml>\n")?;
    Ok(summary)
}

#[cfg(test)]
mod tests;
