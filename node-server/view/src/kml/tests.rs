use super::*;
use crate::geo::LatLonAlt;
use crate::testkit::{TempFile, run_records, with_decisions, write};
use quick_xml::events::Event;
use quick_xml::reader::Reader;

const GEO: Geo = Geo {
    origin: [48.5, 9.06, 320.0],
    heading_deg: 30.0,
};

/// Every element of a KML document in order, with its text (fails on malformed XML).
fn parse(doc: &str) -> Vec<(String, String)> {
    let mut r = Reader::from_str(doc);
    r.config_mut().trim_text(true);
    let mut out: Vec<(String, String)> = Vec::new();
    let mut stack: Vec<String> = Vec::new();
    loop {
        match r.read_event().expect("well-formed KML") {
            Event::Start(e) => {
                let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
                stack.push(name.clone());
                out.push((name, String::new()));
            }
            Event::End(_) => {
                stack.pop();
            }
            Event::Text(t) => {
                let text = t.decode().expect("utf-8").into_owned();
                if let Some(last) = out.last_mut() {
                    last.1.push_str(&text);
                }
            }
            Event::GeneralRef(g) => {
                let name = g.decode().expect("utf-8");
                let c = match name.as_ref() {
                    "amp" => "&",
                    "lt" => "<",
                    "gt" => ">",
                    "quot" => "\"",
                    "apos" => "'",
                    other => panic!("unknown entity &{other};"),
                };
                if let Some(last) = out.last_mut() {
                    last.1.push_str(c);
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(stack.is_empty(), "unclosed elements {stack:?}");
    out
}

fn texts<'a>(els: &'a [(String, String)], name: &str) -> Vec<&'a str> {
    els.iter()
        .filter(|(n, _)| n == name)
        .map(|(_, t)| t.as_str())
        .collect()
}

fn lon_lat_alt(s: &str) -> LatLonAlt {
    let v: Vec<f64> = s
        .split([',', ' '])
        .map(|x| x.parse().expect("a number"))
        .collect();
    LatLonAlt {
        lon: v[0],
        lat: v[1],
        alt: v[2],
    }
}

#[test]
fn the_network_link_refreshes_every_second() {
    let els = parse(&network_link("http://127.0.0.1:8080/tracks.kml?a=1&b=2"));
    assert_eq!(
        texts(&els, "href"),
        vec!["http://127.0.0.1:8080/tracks.kml?a=1&b=2"]
    );
    assert_eq!(texts(&els, "refreshMode"), vec!["onInterval"]);
    assert_eq!(texts(&els, "refreshInterval"), vec!["1"]);
}

#[test]
fn the_live_document_places_tracks_and_cameras() {
    let mut state = ViewState::new();
    for r in with_decisions(&run_records(2)) {
        state.apply(&r);
    }
    assert!(matches!(live_document(&state), Err(KmlError::NoGeo)));
    state.set_geo(Some(GEO));
    let doc = live_document(&state).unwrap();
    let els = parse(&doc);
    let names = texts(&els, "name");
    assert!(names.contains(&"t1"), "{names:?}");
    assert!(names.contains(&"camera 10"));
    assert_eq!(els.iter().filter(|(n, _)| n == "Placemark").count(), 1 + 21);
    // The track's point maps back to its world position.
    let t = &state.tracks[&1];
    let i = els.iter().position(|(n, t)| n == "name" && t == "t1").unwrap();
    let coords = els[i..].iter().find(|(n, _)| n == "coordinates").unwrap();
    let back = GEO.to_local(lon_lat_alt(&coords.1));
    for k in 0..3 {
        assert!(
            (back[k] - t.position[k]).abs() < 1e-3,
            "{back:?} vs {:?}",
            t.position
        );
    }
    // Camera wedges are closed rings.
    let ring = els
        .iter()
        .filter(|(n, _)| n == "coordinates")
        .map(|(_, t)| t.split(' ').collect::<Vec<_>>())
        .find(|pts| pts.len() > 2)
        .unwrap();
    assert_eq!(ring.first(), ring.last());
}

#[test]
fn a_bad_geo_is_named() {
    let mut state = ViewState::new();
    state.set_geo(Some(Geo {
        origin: [91.0, 0.0, 0.0],
        heading_deg: 0.0,
    }));
    let e = live_document(&state).unwrap_err().to_string();
    assert!(e.contains("latitude 91"), "{e}");
}

#[test]
fn iso_times_match_hand_values() {
    assert_eq!(iso8601(0), "1970-01-01T00:00:00.000Z");
    assert_eq!(iso8601(1_700_000_000_123_000_000), "2023-11-14T22:13:20.123Z");
    // 2000-02-29 is day 11 016: a leap day in a year divisible by 400.
    assert_eq!(iso8601(951_782_400_000_000_000), "2000-02-29T00:00:00.000Z");
    assert_eq!(iso8601(-1_000_000), "1969-12-31T23:59:59.999Z");
}

#[test]
fn a_recording_becomes_time_stamped_gx_tracks() {
    let f = TempFile::new("kml.ocrec");
    write(&f.0, &run_records(4));
    let loaded = node_server::analysis::load(&f.0, None).unwrap();
    let mut out = Vec::new();
    let summary = kml_for_recording(&loaded, &GEO, &mut out).unwrap();
    assert_eq!(summary.tracks, 1);
    assert_eq!(summary.points, 21, "4 s of 5 Hz reports, both ends included");
    assert_eq!(summary.cameras, 21);
    let doc = String::from_utf8(out).unwrap();
    let els = parse(&doc);
    let whens = texts(&els, "when");
    let coords = texts(&els, "gx:coord");
    assert_eq!((whens.len(), coords.len()), (21, 21));
    assert_eq!(whens[0], "1970-01-01T00:00:01.000Z");
    assert_eq!(whens[20], "1970-01-01T00:00:05.000Z");
    assert!(whens.windows(2).all(|w| w[0] < w[1]));
    let last = GEO.to_local(lon_lat_alt(coords[20]));
    assert!(
        (last[0] - 3.0).abs() < 1e-3 && (last[1] - 2.0).abs() < 1e-3,
        "{last:?}"
    );
    assert!(doc.contains("xmlns:gx=\"http://www.google.com/kml/ext/2.2\""));
}
