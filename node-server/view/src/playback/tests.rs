use super::*;
use crate::testkit::{S, TempFile, run_records, with_decisions, write};
use std::io::Write as _;

fn indexed(seconds: i64) -> (TempFile, Arc<RecordingIndex>, Vec<Stamped>) {
    let f = TempFile::new("play.ocrec");
    let records = with_decisions(&run_records(seconds));
    write(&f.0, &records);
    let index = RecordingIndex::build(&f.0, None).unwrap();
    (f, Arc::new(index), records)
}

/// The view after applying every record up to `t` directly: what a seek must reproduce.
fn direct(records: &[Stamped], t: i64) -> ViewState {
    let mut v = ViewState::new();
    for r in records.iter().filter(|r| r.at.0 <= t) {
        v.apply(r);
    }
    v
}

#[test]
fn seeking_anywhere_equals_playing_from_the_start() {
    let (_f, index, records) = indexed(30);
    let (start, end) = index.span_ns();
    assert_eq!((start, end), (0, 31 * S));
    let (n, checkpoints) = index.counts();
    assert_eq!(n, records.len() as u64);
    assert!(checkpoints >= 6, "a checkpoint every 5 s: {checkpoints}");
    let mut p = Player::new(index.clone()).unwrap();
    for t in [end, 3 * S, 17 * S + S / 10, 0, 25 * S, 12 * S, end + 99 * S] {
        p.seek(t).unwrap();
        let want = direct(&records, t.clamp(start, end));
        assert_eq!(p.state(), &want, "seek to {t}");
    }
}

#[test]
fn playing_forward_applies_records_in_order() {
    let (_f, index, records) = indexed(10);
    let mut p = Player::new(index).unwrap();
    assert!(!p.state().tracks.contains_key(&1));
    assert!(p.advance_to(2 * S).unwrap());
    assert_eq!(p.state(), &direct(&records, 2 * S));
    assert!(!p.advance_to(2 * S).unwrap(), "nothing new");
    p.advance_to(6 * S).unwrap();
    assert_eq!(p.state(), &direct(&records, 6 * S));
    assert!((p.state().tracks[&1].position[0] - 3.5).abs() < 1e-9);
}

#[test]
fn commands_play_pause_seek_and_speed() {
    let (_f, index, _) = indexed(10);
    let mut p = Player::new(index).unwrap();
    p.command(Command::Play).unwrap();
    assert!(p.playing);
    p.command(Command::Seek(4.0)).unwrap();
    assert_eq!(p.position_ns(), 4 * S);
    p.command(Command::Speed(1000.0)).unwrap();
    assert_eq!(p.speed, 100.0, "clamped");
    p.command(Command::Pause).unwrap();
    assert!(!p.playing);
    let info = p.info();
    assert_eq!((info.start, info.end, info.position), (0.0, 11.0, 4.0));
    // Play at the end starts over.
    p.command(Command::Seek(1e9)).unwrap();
    p.command(Command::Play).unwrap();
    assert_eq!(p.position_ns(), 0);
}

#[test]
fn a_torn_recording_plays_up_to_the_tear_and_says_so() {
    let (f, _, records) = indexed(6);
    let mut file = std::fs::OpenOptions::new().append(true).open(&f.0).unwrap();
    file.write_all(&[200, 0, 0, 0, 1, 2, 3]).unwrap(); // a record cut short
    drop(file);
    let index = Arc::new(RecordingIndex::build(&f.0, None).unwrap());
    assert_eq!(index.counts().0, records.len() as u64);
    let mut p = Player::new(index.clone()).unwrap();
    p.seek(index.span_ns().1).unwrap();
    let text = &p.state().problems.back().unwrap().text;
    assert!(
        text.contains("torn") && text.contains("7 bytes skipped"),
        "{text}"
    );
    assert!(p.state().tracks.contains_key(&1));
}

#[test]
fn records_of_another_protocol_version_are_skipped_and_named() {
    let f = TempFile::new("version.ocrec");
    let records = with_decisions(&run_records(2));
    let mut rec = node_server::Recorder::create(&f.0, "default").unwrap();
    for r in &records {
        let mut payload = r.encode().unwrap();
        if payload[0] == 1 {
            payload[9] = 9; // a received envelope whose wire header says protocol version 9
        }
        rec.append_payload(&payload).unwrap();
    }
    drop(rec);
    let index = Arc::new(RecordingIndex::build(&f.0, None).unwrap());
    let mut p = Player::new(index.clone()).unwrap();
    p.seek(index.span_ns().1).unwrap();
    let s = p.state();
    // Counted per skipped stretch: adjacent undecodable records are skipped as one.
    assert!(s.totals.undecodable > 0);
    let problem = s.problems.iter().find(|p| p.text.contains("version")).unwrap();
    assert!(problem.text.contains("do not decode"), "{}", problem.text);
    assert_eq!(problem.count, s.totals.undecodable, "one problem, counted");
}

#[test]
fn not_a_recording_is_an_error() {
    let f = TempFile::new("junk.ocrec");
    std::fs::write(&f.0, b"hello, world").unwrap();
    let e = RecordingIndex::build(&f.0, None).unwrap_err().to_string();
    assert!(e.contains("not an Ocelli recording"), "{e}");
    let g = TempFile::new("empty.ocrec");
    drop(node_server::Recorder::create(&g.0, "x").unwrap());
    assert!(matches!(
        RecordingIndex::build(&g.0, None),
        Err(PlaybackError::Empty(_))
    ));
}

#[tokio::test(start_paused = true)]
async fn the_producer_plays_at_the_chosen_speed() {
    let (_f, index, records) = indexed(10);
    let player = Player::new(index).unwrap();
    let (publisher, feed) = crate::feed::channel(ViewState::new());
    let (tx, rx) = mpsc::channel(4);
    let stop = CancellationToken::new();
    let task = tokio::spawn(run(
        player,
        publisher,
        rx,
        Duration::from_millis(100),
        stop.clone(),
    ));
    tx.send(Command::Speed(2.0)).await.unwrap();
    tx.send(Command::Play).await.unwrap();
    tokio::time::sleep(Duration::from_millis(2050)).await;
    let p = feed.latest();
    let info = p.playback.clone().unwrap();
    assert!(info.playing);
    // 2 s of clock at 2× is about 4 s of recording.
    assert!((info.position - 4.0).abs() < 0.35, "{info:?}");
    let at = (info.position * 1e9) as i64;
    assert_eq!(*p.state, direct(&records, at));
    tx.send(Command::Pause).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let paused = feed.latest().playback.clone().unwrap().position;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(feed.latest().playback.clone().unwrap().position, paused);
    stop.cancel();
    task.await.unwrap().unwrap();
}
