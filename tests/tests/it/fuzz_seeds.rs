//! The fuzz targets' seed corpora (`tests/fuzz/corpus/`) are made from the current protocol and
//! recording format. A seed of an old version only exercises the version check, so the fuzzer
//! would start far from every decoder behind it; these tests fail when a seed is stale.
//! `OCELLI_WRITE_FUZZ_SEEDS=1 cargo nextest run -p tests -E 'test(/fuzz_seeds/)'` rewrites
//! them (then commit the files).

use node_server::decision::Decision;
use node_server::record::{MeasuredFrame, Record, Stamped};
use node_server::recording::{Recorder, read_bytes};
use proto::ids::{NodeId, Role};
use proto::{ClusterTime, Message, encode};
use std::path::{Path, PathBuf};

fn corpus(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target)
}

/// Compare each `(file name, bytes)` with the file in `target`'s corpus; with
/// `OCELLI_WRITE_FUZZ_SEEDS` set, write the differing ones instead (and remove stale `seed-*`
/// files nobody makes any more).
fn check(target: &str, seeds: &[(String, Vec<u8>)]) {
    let dir = corpus(target);
    let write = std::env::var_os("OCELLI_WRITE_FUZZ_SEEDS").is_some();
    let mut stale = Vec::new();
    for (name, bytes) in seeds {
        let path = dir.join(name);
        if std::fs::read(&path).ok().as_deref() != Some(bytes.as_slice()) {
            if write {
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(&path, bytes).unwrap();
            }
            stale.push(name.clone());
        }
    }
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.starts_with("seed-") && !seeds.iter().any(|(n, _)| *n == name) {
            if write {
                std::fs::remove_file(dir.join(&name)).unwrap();
            }
            stale.push(format!("{name} (no longer made)"));
        }
    }
    assert!(
        write || stale.is_empty(),
        "stale fuzz seeds in {}: {stale:?}; rewrite them with OCELLI_WRITE_FUZZ_SEEDS=1 \
         cargo nextest run -p tests -E 'test(/fuzz_seeds/)'",
        dir.display()
    );
}

/// One encoded frame per message kind (proto's golden samples), named by kind.
fn frames() -> Vec<(&'static str, Vec<u8>)> {
    proto::examples::messages()
        .into_iter()
        .map(|env| (env.body.kind(), encode(&env).unwrap()))
        .collect()
}

#[test]
fn fuzz_seeds_wire_decode_hold_one_frame_of_every_kind() {
    let seeds: Vec<_> = frames()
        .into_iter()
        .map(|(kind, f)| (format!("seed-{kind}"), f))
        .collect();
    assert_eq!(seeds.len(), proto::wire::MESSAGE_KINDS.len());
    check("wire_decode", &seeds);
}

/// The `tcp_codec` input: two control bytes (frame limit / 4, piece size), then 4-byte
/// big-endian length-prefixed frames.
fn stream(limit_quarter: u8, piece: u8, frames: &[&[u8]]) -> Vec<u8> {
    let mut out = vec![limit_quarter, piece];
    for f in frames {
        out.extend_from_slice(&(f.len() as u32).to_be_bytes());
        out.extend_from_slice(f);
    }
    out
}

#[test]
fn fuzz_seeds_tcp_codec_are_length_prefixed_current_frames() {
    let all = frames();
    let get = |k: &str| all.iter().find(|(kind, _)| *kind == k).unwrap().1.as_slice();
    let small: Vec<&[u8]> = all
        .iter()
        .filter(|(_, f)| f.len() < 40)
        .map(|(_, f)| f.as_slice())
        .collect();
    let biggest = all
        .iter()
        .map(|(_, f)| f.as_slice())
        .max_by_key(|f| f.len())
        .unwrap();
    let seeds = vec![
        ("seed-small-frames".to_string(), stream(0xff, 7, &small)),
        // A limit of 16 bytes: the measurement is skipped as oversized, the heartbeat after it
        // still arrives.
        (
            "seed-oversized-then-ok".to_string(),
            stream(4, 3, &[get("measurement"), get("heartbeat")]),
        ),
        ("seed-one-big".to_string(), stream(0xff, 0x40, &[biggest])),
    ];
    check("tcp_codec", &seeds);
}

/// A recording holding every record kind, written by the server's own recorder.
fn recording() -> Vec<u8> {
    let dir = std::env::temp_dir().join(format!("ocelli-fuzz-seed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("seed.ocrec");
    let _ = std::fs::remove_file(&path);
    let samples = proto::examples::messages();
    let measured = samples
        .iter()
        .find_map(|e| match &e.body {
            Message::MeasuredFrame(m) => Some(MeasuredFrame::from_wire(e.source, m)),
            _ => None,
        })
        .unwrap();
    let at = |ms: i64| ClusterTime(1_000_000_000 + ms * 1_000_000);
    let records = [
        Record::Scenario("name = \"fuzz\"\n".into()),
        Record::Link {
            node: NodeId(10),
            up: true,
        },
        Record::Received(samples[0].clone()),
        Record::Decision(Decision::Admitted {
            node: NodeId(10),
            role: Role::Camera,
        }),
        Record::Sent {
            to: NodeId(10),
            env: samples[1].clone(),
        },
        Record::Received(samples[3].clone()),
        Record::Tick,
        Record::Measured(measured),
        Record::Received(samples[2].clone()),
    ];
    let mut rec = Recorder::create(&path, "fuzz").unwrap();
    for (k, r) in records.into_iter().enumerate() {
        rec.append(&Stamped::new(at(k as i64 * 100), r)).unwrap();
    }
    rec.sync().unwrap();
    drop(rec);
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    bytes
}

#[test]
fn fuzz_seeds_recording_reader_hold_every_record_kind_and_a_damaged_copy() {
    let small = recording();
    let back = read_bytes(&small, Path::new("seed-small")).unwrap();
    assert_eq!(back.records.len(), 9);
    assert!(back.skipped.is_empty());
    // Damage in the middle: a few bytes of the fifth record flipped.
    let mut damaged = small.clone();
    let mid = small.len() / 2;
    for b in &mut damaged[mid..mid + 6] {
        *b ^= 0x5a;
    }
    let back = read_bytes(&damaged, Path::new("seed-damaged")).unwrap();
    assert!(!back.skipped.is_empty(), "the damage is found");
    assert!(small.len() <= 4096, "libFuzzer's -max_len of the README");
    check(
        "recording_reader",
        &[
            ("seed-small".to_string(), small),
            ("seed-damaged".to_string(), damaged),
        ],
    );
}
