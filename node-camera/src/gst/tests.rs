//! GStreamer sources on real encoded video and a real HTTP MJPEG stream (see `kit`).

mod kit;
#[cfg(feature = "rtsp-tests")]
mod rtsp;

use super::*;
use kit::{Clock, GREY, MjpegServer, Picture, colours, encode, near, tmp};
use proto::sensor::Frame;
use proto::sensor::FrameSource;

const RED: [u8; 3] = [220, 30, 30];
const GREEN: [u8; 3] = [30, 200, 40];
const BLUE: [u8; 3] = [30, 40, 220];
const YELLOW: [u8; 3] = [230, 220, 40];
const CYAN: [u8; 3] = [40, 210, 220];
const MAGENTA: [u8; 3] = [210, 40, 200];

/// A camera whose rows (90 × 3 = 270 bytes) are not a multiple of GStreamer's 4-byte stride.
const CAMERA: (u32, u32) = (90, 50);

fn pictures(width: u32, height: u32, tops: &[[u8; 3]]) -> Vec<Picture> {
    tops.iter().map(|&top| Picture { width, height, top }).collect()
}

fn open_file(path: &std::path::Path, looping: bool) -> (GstSource, SharedStats) {
    let input = GstInput::File {
        path: path.into(),
        looping,
    };
    let mut options = GstOptions::for_camera(&input, 15.0);
    // Only a bound: a loaded test machine must not turn a slow decode into a failed capture.
    options.max_wait = Duration::from_secs(5);
    let stats = SharedStats::default();
    let source = GstSource::open(input, CAMERA.0, CAMERA.1, options, stats.clone()).unwrap();
    (source, stats)
}

/// Capture until the source ends or `limit` captures: the frames' top colours.
fn play(source: &mut GstSource, clock: &Clock, limit: usize) -> (Vec<[u8; 3]>, usize, bool) {
    let (mut tops, mut errors) = (Vec::new(), 0);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    for _ in 0..limit {
        let now = clock.now();
        match source.capture(now, &mut frame) {
            Ok(true) => {
                assert_eq!((frame.width, frame.height), CAMERA);
                assert_eq!(frame.check(), Ok(()));
                assert_eq!(frame.captured, now);
                let (top, bottom) = colours(&frame);
                assert!(near(bottom, GREY), "bottom half {bottom:?}");
                tops.push(top);
            }
            Ok(false) => return (tops, errors, true),
            Err(_) => errors += 1,
        }
    }
    (tops, errors, false)
}

fn same_colours(got: &[[u8; 3]], want: &[[u8; 3]]) -> bool {
    got.len() == want.len() && got.iter().zip(want).all(|(&g, &w)| near(g, w))
}

#[test]
fn avi_mjpeg_file_gives_every_frame_in_order_at_the_camera_size() {
    let (_dir, path) = tmp("six.avi");
    let tops = [RED, GREEN, BLUE, YELLOW, CYAN, MAGENTA];
    encode(&path, &pictures(96, 64, &tops), 10, "jpegenc quality=95 ! avimux");
    let (mut source, stats) = open_file(&path, false);
    assert_eq!(source.size(), CAMERA);
    let clock = Clock::start();
    let (got, errors, ended) = play(&mut source, &clock, 50);
    assert!(ended && errors == 0, "ended {ended}, {errors} errors");
    assert!(same_colours(&got, &tops), "{got:?}");
    // It stays ended.
    assert!(
        !source
            .capture(clock.now(), &mut Frame::new(1, 1, ClusterTime::ZERO))
            .unwrap()
    );
    let s = stats.snapshot();
    assert_eq!(
        (s.frames, s.ends, s.errors, s.reconnects, s.caps_changes),
        (6, 1, 0, 0, 0)
    );
    let _ = std::fs::remove_file(path);
}

#[test]
fn webm_vp8_file_starts_over_when_it_loops() {
    let (_dir, path) = tmp("four.webm");
    let tops = [RED, GREEN, BLUE, YELLOW];
    encode(&path, &pictures(64, 48, &tops), 10, "vp8enc deadline=1 ! webmmux");
    let (mut source, stats) = open_file(&path, true);
    let clock = Clock::start();
    let (got, errors, ended) = play(&mut source, &clock, 40);
    // A new lap starts within the capture that met the end: no capture is lost to it.
    assert!(!ended && errors == 0, "ended {ended}, {errors} errors");
    assert_eq!(got.len(), 40);
    for (i, top) in got.iter().enumerate() {
        assert!(near(*top, tops[i % 4]), "frame {i}: {top:?}");
    }
    let s = stats.snapshot();
    assert_eq!((s.frames, s.ends, s.reconnects, s.errors), (40, 9, 0, 0), "{s:?}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn a_file_whose_frames_change_size_still_gives_the_camera_size() {
    // A multipart JPEG file, the format of an MJPEG camera's stream, three sizes in a row.
    let (_dir, path) = tmp("sizes.mjpeg");
    let frames = [
        Picture {
            width: 96,
            height: 64,
            top: RED,
        },
        Picture {
            width: 160,
            height: 120,
            top: GREEN,
        },
        Picture {
            width: 48,
            height: 32,
            top: BLUE,
        },
    ];
    encode(&path, &frames, 10, "jpegenc quality=95 ! multipartmux");
    let (mut source, stats) = open_file(&path, false);
    let (got, errors, ended) = play(&mut source, &Clock::start(), 50);
    assert!(ended && errors == 0);
    assert!(same_colours(&got, &[RED, GREEN, BLUE]), "{got:?}");
    let s = stats.snapshot();
    assert_eq!((s.frames, s.caps_changes), (3, 2), "{s:?}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn missing_and_corrupt_files_are_clear_errors_and_counted() {
    let stats = SharedStats::default();
    let open = |path: &std::path::Path| {
        let input = GstInput::File {
            path: path.into(),
            looping: false,
        };
        GstSource::open(
            input.clone(),
            64,
            48,
            GstOptions::for_camera(&input, 15.0),
            stats.clone(),
        )
    };
    let (_dir, missing) = tmp("no-such.avi");
    let e = open(&missing).unwrap_err();
    assert!(
        matches!(e, SourceError::Io { .. }) && e.to_string().contains("no-such.avi"),
        "{e}"
    );
    assert_eq!(stats.snapshot().stream_errors, 1);

    let (_dir, garbage) = tmp("garbage.avi");
    let bytes: Vec<u8> = (0..20_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&garbage, bytes).unwrap();
    let e = open(&garbage).unwrap_err().to_string();
    assert!(
        e.contains("garbage.avi") && e.contains("cannot be decoded"),
        "{e}"
    );
    assert_eq!(stats.snapshot().decode_errors, 1);

    // A good file damaged in the middle: the frames around the damage arrive, the frames it
    // destroyed are counted, the file then ends; nothing panics.
    let (_dir, damaged) = tmp("damaged.avi");
    let tops = [RED, GREEN, BLUE, YELLOW, CYAN, MAGENTA, RED, GREEN];
    encode(
        &damaged,
        &pictures(96, 64, &tops),
        10,
        "jpegenc quality=95 ! avimux",
    );
    let mut bytes = std::fs::read(&damaged).unwrap();
    let n = bytes.len();
    for b in &mut bytes[n * 2 / 5..n * 3 / 5] {
        *b = 0x5a;
    }
    std::fs::write(&damaged, bytes).unwrap();
    let input = GstInput::File {
        path: damaged.clone(),
        looping: false,
    };
    let mut source = GstSource::open(
        input.clone(),
        CAMERA.0,
        CAMERA.1,
        GstOptions::for_camera(&input, 15.0),
        stats.clone(),
    )
    .unwrap();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let clock = Clock::start();
    let mut got = Vec::new();
    let mut ended = false;
    for _ in 0..60 {
        match source.capture(clock.now(), &mut frame) {
            Ok(true) => got.push(colours(&frame).0),
            Ok(false) => {
                ended = true;
                break;
            }
            Err(_) => {}
        }
    }
    assert!(ended, "the damaged file never ended");
    assert!(
        got.len() >= 2 && near(got[0], RED) && near(got[1], GREEN),
        "{got:?}"
    );
    assert!(
        near(*got.last().unwrap(), GREEN),
        "the last frame is lost: {got:?}"
    );
    let s = stats.snapshot();
    assert!(s.corrupt_frames >= 1, "damage not seen: {s:?}");
    // Every frame of the file is either delivered or counted as lost.
    assert_eq!(got.len() as u64 + s.corrupt_frames, tops.len() as u64, "{s:?}");
    for p in [garbage, damaged] {
        let _ = std::fs::remove_file(p);
    }
}

fn open_stream(port: u16, stall: Duration) -> (GstSource, SharedStats) {
    let input = GstInput::HttpMjpeg {
        url: format!("http://127.0.0.1:{port}/video.mjpg"),
    };
    let mut options = GstOptions::for_camera(&input, 15.0);
    options.stall_timeout = stall;
    options.max_wait = Duration::from_millis(200);
    options.backoff = Backoff::new(Duration::from_millis(100), Duration::from_millis(800), 2.0, 0.0);
    let stats = SharedStats::default();
    let source = GstSource::open(input, CAMERA.0, CAMERA.1, options, stats.clone()).unwrap();
    (source, stats)
}

/// Capture until a frame whose top is `top` arrives (or `within` passes): whether it did.
fn wait_for(source: &mut GstSource, clock: &Clock, top: [u8; 3], within: Duration) -> bool {
    let deadline = clock.elapsed() + within;
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    while clock.elapsed() < deadline {
        if let Ok(true) = source.capture(clock.now(), &mut frame) {
            assert_eq!((frame.width, frame.height), CAMERA);
            if near(colours(&frame).0, top) {
                return true;
            }
        }
    }
    false
}

/// Capture for `span`: how many captures failed.
fn failures_during(source: &mut GstSource, clock: &Clock, span: Duration) -> usize {
    let deadline = clock.elapsed() + span;
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut failed = 0;
    while clock.elapsed() < deadline {
        failed += usize::from(source.capture(clock.now(), &mut frame).is_err());
        std::thread::sleep(Duration::from_millis(20));
    }
    failed
}

#[test]
fn mjpeg_stream_that_drops_reconnects_when_the_server_is_back() {
    let red = Picture {
        width: 80,
        height: 60,
        top: RED,
    };
    let server = MjpegServer::start(0, red);
    let port = server.port;
    let (mut source, stats) = open_stream(port, Duration::from_secs(3));
    let clock = Clock::start();
    assert!(
        wait_for(&mut source, &clock, RED, Duration::from_secs(10)),
        "no frame from the server"
    );
    server.stop();
    assert!(failures_during(&mut source, &clock, Duration::from_millis(1500)) > 0);
    let down = stats.snapshot();
    assert!(
        down.stream_errors + down.ends >= 1,
        "the drop went unseen: {down:?}"
    );
    let _server = MjpegServer::start(port, Picture { top: BLUE, ..red });
    assert!(
        wait_for(&mut source, &clock, BLUE, Duration::from_secs(15)),
        "frames did not resume: {:?}",
        stats.snapshot()
    );
    let s = stats.snapshot();
    assert!(s.reconnects >= 1 && s.frames >= 2, "{s:?}");
    assert_eq!(s.stalls, 0, "{s:?}");
}

#[test]
fn mjpeg_stream_that_stalls_is_restarted_and_a_pause_is_not_a_stall() {
    let red = Picture {
        width: 80,
        height: 60,
        top: RED,
    };
    let server = MjpegServer::start(0, red);
    let (mut source, stats) = open_stream(server.port, Duration::from_secs(1));
    let clock = Clock::start();
    assert!(wait_for(&mut source, &clock, RED, Duration::from_secs(10)));
    // The camera stops capturing for longer than the stall timeout (switched off by its
    // head), then captures again: no stall.
    std::thread::sleep(Duration::from_millis(1500));
    assert!(wait_for(&mut source, &clock, RED, Duration::from_secs(5)));
    assert_eq!(stats.snapshot().stalls, 0);
    server.silence(true);
    assert!(failures_during(&mut source, &clock, Duration::from_millis(2500)) > 0);
    let silent = stats.snapshot();
    assert!(silent.stalls >= 1 && silent.reconnects >= 1, "{silent:?}");
    server.show(Picture { top: GREEN, ..red });
    server.silence(false);
    assert!(
        wait_for(&mut source, &clock, GREEN, Duration::from_secs(15)),
        "{:?}",
        stats.snapshot()
    );
}

#[test]
fn mjpeg_stream_switching_size_keeps_the_camera_size() {
    let small = Picture {
        width: 80,
        height: 60,
        top: RED,
    };
    let server = MjpegServer::start(0, small);
    let (mut source, stats) = open_stream(server.port, Duration::from_secs(3));
    let clock = Clock::start();
    assert!(wait_for(&mut source, &clock, RED, Duration::from_secs(10)));
    server.show(Picture {
        width: 320,
        height: 240,
        top: CYAN,
    });
    assert!(wait_for(&mut source, &clock, CYAN, Duration::from_secs(10)));
    let s = stats.snapshot();
    assert!(s.caps_changes >= 1 && s.reconnects == 0, "{s:?}");
}

#[test]
fn a_missing_element_names_its_package() {
    init().unwrap();
    if gst::ElementFactory::find("libcamerasrc").is_some() {
        // With libcamera installed but no camera on a build machine, the source still opens
        // (it fails on the bus and reconnects); nothing more to check here.
        return;
    }
    let input = GstInput::Libcamera { camera: None };
    let e = GstSource::open(
        input.clone(),
        64,
        48,
        GstOptions::for_camera(&input, 15.0),
        SharedStats::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("libcamerasrc") && e.contains("gstreamer1.0-libcamera"),
        "{e}"
    );
}

#[test]
fn open_source_plays_a_file_spec_and_its_stats_come_along() {
    let (_dir, path) = tmp("spec.avi");
    let tops = [GREEN, BLUE, RED];
    encode(&path, &pictures(64, 48, &tops), 10, "jpegenc quality=95 ! avimux");
    let spec = crate::source_spec::SourceSpec::parse(&format!("file:{}", path.display())).unwrap();
    let mut opened = crate::source_spec::open_source(&spec, CAMERA.0, CAMERA.1, 15.0).unwrap();
    assert_eq!(opened.source.size(), CAMERA);
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    let mut got = Vec::new();
    for i in 0..20 {
        match opened
            .source
            .capture(ClusterTime::from_millis(i * 66), &mut frame)
        {
            Ok(true) => got.push(colours(&frame).0),
            Ok(false) => break,
            Err(e) => panic!("{e}"),
        }
    }
    assert!(same_colours(&got, &tops), "{got:?}");
    let s = opened.stats.snapshot();
    assert_eq!((s.frames, s.ends, s.errors), (3, 1, 0), "{s:?}");
    let _ = std::fs::remove_file(path);
}

#[test]
fn a_file_played_newest_first_keeps_its_order_and_ends() {
    let (_dir, path) = tmp("newest.avi");
    let tops = [RED, GREEN, BLUE, YELLOW, CYAN, MAGENTA];
    encode(&path, &pictures(64, 48, &tops), 20, "jpegenc quality=95 ! avimux");
    let input = GstInput::File {
        path: path.clone(),
        looping: false,
    };
    let mut options = GstOptions::for_camera(&input, 15.0);
    options.pacing = Pacing::Newest;
    let stats = SharedStats::default();
    let mut source = GstSource::open(input, CAMERA.0, CAMERA.1, options, stats.clone()).unwrap();
    // The file plays at its own 20 fps whatever the camera takes: frames may be skipped, never
    // repeated or reordered.
    let (got, _, ended) = play(&mut source, &Clock::start(), 100);
    assert!(ended);
    assert!(!got.is_empty() && got.len() <= tops.len(), "{got:?}");
    let mut next = 0;
    for top in &got {
        let at = tops[next..].iter().position(|&t| near(*top, t)).map(|p| p + next);
        next = at.expect("a frame out of order or repeated") + 1;
    }
    assert_eq!(stats.snapshot().ends, 1);
    let _ = std::fs::remove_file(path);
}
