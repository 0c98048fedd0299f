use super::*;
use crate::testkit::{S, TempFile, run_records, with_decisions, write};
use node_server::{Decision, Record, Stamped};
use proto::{ClusterTime, TargetId};
use std::io::Cursor;

fn loaded(records: &[Stamped]) -> Loaded {
    let f = TempFile::new("mcap.ocrec");
    write(&f.0, records);
    node_server::analysis::load(&f.0, None).unwrap()
}

const GEO: Geo = Geo {
    origin: [48.5, 9.06, 320.0],
    heading_deg: 0.0,
};

/// A recording's file read back with the mcap reader: its channels, their schemas, and how
/// many messages each got.
#[test]
fn a_recording_reads_back_with_foxglove_schemas() {
    let mut records = with_decisions(&run_records(4));
    records.push(Stamped::new(
        ClusterTime(6 * S),
        Record::Decision(Decision::Lost { global: TargetId(1) }),
    ));
    let loaded = loaded(&records);
    let mut buf = Cursor::new(Vec::new());
    let summary = write_mcap(&loaded, Some(&GEO), &mut buf).unwrap();
    let bytes = buf.into_inner();

    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    let mut schemas: BTreeMap<String, (String, String, String)> = BTreeMap::new();
    let mut last_track: Option<serde_json::Value> = None;
    for m in ::mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let topic = m.channel.topic.clone();
        *counts.entry(topic.clone()).or_default() += 1;
        let schema = m.channel.schema.as_ref().unwrap();
        schemas.insert(
            topic.clone(),
            (
                schema.name.clone(),
                schema.encoding.clone(),
                m.channel.message_encoding.clone(),
            ),
        );
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        if topic == TRACKS {
            last_track = Some(v);
        }
    }
    let scene = |s: &str| (s.to_string(), "jsonschema".to_string(), "json".to_string());
    assert_eq!(schemas[ROOM], scene("foxglove.SceneUpdate"));
    assert_eq!(schemas[CAMERAS], scene("foxglove.SceneUpdate"));
    assert_eq!(schemas[TRACKS], scene("foxglove.SceneUpdate"));
    assert_eq!(schemas[TF], scene("foxglove.FrameTransform"));
    assert_eq!(schemas[LOCATION], scene("foxglove.LocationFix"));
    assert_eq!(schemas[NODE_STATUS], scene("ocelli.NodeStatus"));
    // One room; 21 track reports became 21 track updates plus the deletion when it was lost,
    // 21 transforms and 21 fixes; 21 camera poses at the start.
    assert_eq!(counts[ROOM], 1);
    assert_eq!(counts[TRACKS], 22);
    assert_eq!(counts[LOCATION], 21);
    assert_eq!(counts[TF], 21 + 21);
    assert!(counts[CAMERAS] >= 2, "the start, then camera 10 coming up");
    assert!(counts[NODE_STATUS] >= 5, "camera 10's statuses");
    assert!(!counts.contains_key(HANDOVER));
    for (topic, n) in &counts {
        assert_eq!(summary.messages.get(topic.as_str()), Some(n), "{topic}");
    }
    let del = last_track.unwrap();
    assert_eq!(del["deletions"][0]["id"], "track-1");
    assert_eq!(del["deletions"][0]["type"], 0);

    // The summary section agrees, and the file's statistics count every message.
    let s = ::mcap::Summary::read(&bytes).unwrap().unwrap();
    let stats = s.stats.unwrap();
    assert_eq!(stats.message_count, counts.values().sum::<u64>());
    assert_eq!(stats.channel_count as usize, 7);
}

#[test]
fn track_entities_carry_id_height_ellipse_and_trail() {
    let loaded = loaded(&with_decisions(&run_records(2)));
    let mut buf = Cursor::new(Vec::new());
    write_mcap(&loaded, None, &mut buf).unwrap();
    let bytes = buf.into_inner();
    let last = ::mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .filter(|m| m.channel.topic == TRACKS)
        .last()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&last.data).unwrap();
    let e = &v["entities"][0];
    assert_eq!(e["id"], "track-1");
    assert_eq!(e["frame_id"], "world");
    assert_eq!(e["texts"][0]["text"], "t1");
    let cyl = &e["cylinders"][0];
    assert!(
        (cyl["size"]["z"].as_f64().unwrap() - 0.5).abs() < 1e-12,
        "height from z = 0.25"
    );
    assert!((cyl["pose"]["position"]["x"].as_f64().unwrap() - 2.0).abs() < 1e-9);
    let kinds: Vec<u64> = e["lines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["type"].as_u64().unwrap())
        .collect();
    assert_eq!(kinds, vec![u64::from(LINE_LOOP), u64::from(LINE_STRIP)]);
    assert_eq!(e["lines"][1]["points"].as_array().unwrap().len(), 11);
    // Without geo there is no location channel.
    assert!(
        ::mcap::MessageStream::new(&bytes)
            .unwrap()
            .all(|m| m.unwrap().channel.topic != LOCATION)
    );
}

#[test]
fn location_covariance_turns_with_the_heading() {
    let t = TrackView {
        cov_xy: [4.0, 0.0, 1.0],
        sigma_m: 6f64.sqrt(),
        ..TrackView::default()
    };
    let east = location(&GEO, &t, 0);
    assert_eq!(east.position_covariance[0], 4.0);
    assert_eq!(east.position_covariance[4], 1.0);
    assert!((east.position_covariance[8] - 1.0).abs() < 1e-12);
    let turned = Geo {
        heading_deg: 90.0,
        ..GEO
    };
    let f = location(&turned, &t, 0);
    assert!(
        (f.position_covariance[0] - 1.0).abs() < 1e-12,
        "x points south: east gets y's variance"
    );
    assert!((f.position_covariance[4] - 4.0).abs() < 1e-12);
}
