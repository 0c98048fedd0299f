use super::*;

fn parse(s: &str) -> SourceSpec {
    SourceSpec::parse(s).unwrap_or_else(|e| panic!("{s}: {e}"))
}

fn problem(s: &str) -> String {
    match SourceSpec::parse(s) {
        Err(e) => e.to_string(),
        Ok(spec) => panic!("{s} parsed as {spec:?}"),
    }
}

#[test]
fn every_form_parses_to_its_source() {
    assert_eq!(parse("synthetic"), SourceSpec::Synthetic);
    assert_eq!(parse(" libcamera "), SourceSpec::Libcamera { camera: None });
    assert_eq!(
        parse("libcamera:/base/soc/i2c0mux/i2c@1/imx708@1a"),
        SourceSpec::Libcamera {
            camera: Some("/base/soc/i2c0mux/i2c@1/imx708@1a".into())
        }
    );
    assert_eq!(
        parse("v4l2:/dev/video2"),
        SourceSpec::V4l2 {
            device: "/dev/video2".into()
        }
    );
    assert_eq!(
        parse("file:clips/lab.mp4"),
        SourceSpec::File {
            path: "clips/lab.mp4".into(),
            looping: false
        }
    );
    assert_eq!(
        parse("file:///data/lab.avi?loop"),
        SourceSpec::File {
            path: "/data/lab.avi".into(),
            looping: true
        }
    );
    assert_eq!(
        parse("file:a.webm?loop=false"),
        SourceSpec::File {
            path: "a.webm".into(),
            looping: false
        }
    );
    // Stream URLs stay as they are, their own query and port included.
    let rtsp = "rtsp://user:pw@192.168.1.20:554/Streaming/Channels/101?transportmode=unicast";
    assert_eq!(parse(rtsp), SourceSpec::Rtsp { url: rtsp.into() });
    assert_eq!(
        parse("RTSPS://cam.local/live"),
        SourceSpec::Rtsp {
            url: "RTSPS://cam.local/live".into()
        }
    );
    let mjpeg = "http://10.0.0.5:8080/video.mjpg?fps=15&res=vga";
    assert_eq!(parse(mjpeg), SourceSpec::HttpMjpeg { url: mjpeg.into() });
    assert!(matches!(parse("https://cam/mjpeg"), SourceSpec::HttpMjpeg { .. }));
    assert_eq!(
        parse("images:frames"),
        SourceSpec::Images {
            dir: "frames".into(),
            manifest: None,
            looping: false
        }
    );
    assert_eq!(
        parse("images:frames?manifest=frames/times.txt&loop"),
        SourceSpec::Images {
            dir: "frames".into(),
            manifest: Some("frames/times.txt".into()),
            looping: true
        }
    );
}

#[test]
fn display_gives_back_what_parse_reads() {
    for s in [
        "synthetic",
        "libcamera",
        "libcamera:imx219",
        "v4l2:/dev/video0",
        "file:a b/clip.avi",
        "file:clip.avi?loop",
        "rtsp://cam:554/s",
        "http://cam/v.mjpg?x=1",
        "images:d",
        "images:d?loop",
        "images:d?manifest=m.txt",
        "images:d?manifest=m.txt&loop",
    ] {
        let spec = parse(s);
        assert_eq!(spec.to_string(), s);
        assert_eq!(parse(&spec.to_string()), spec);
    }
}

#[test]
fn bad_specs_say_what_is_wrong() {
    assert!(matches!(SourceSpec::parse("  "), Err(SpecError::Empty)));
    let unknown = problem("webcam0");
    assert!(
        unknown.contains("webcam0") && unknown.contains("rtsp://") && unknown.contains("images:DIR"),
        "{unknown}"
    );
    assert!(problem("ftp://cam/x").contains("unknown --source"));
    assert!(problem("rtsp://").contains("no host"));
    assert!(problem("http://:8080/x").contains("no host"));
    assert!(problem("http://cam/a b").contains("white space"));
    assert!(problem("file:").contains("path is empty"));
    assert!(problem("file:?loop").contains("path is empty"));
    assert!(problem("file:a.avi?lop").contains("unknown option `lop`"));
    assert!(problem("file:a.avi?loop=maybe").contains("true or false"));
    assert!(problem("images:d?manifest").contains("manifest=FILE"));
    assert!(problem("images:d?speed=2").contains("known: manifest, loop"));
    assert!(problem("v4l2:").contains("/dev/video0"));
    assert!(problem("libcamera:").contains("camera name is empty"));
}

#[test]
fn features_are_named_when_missing() {
    let v4l2 = parse("v4l2:/dev/video0");
    assert_eq!(
        v4l2.missing_feature(),
        (!cfg!(feature = "v4l2")).then_some("v4l2")
    );
    for s in ["file:x.mp4", "rtsp://cam/s", "http://cam/m", "libcamera"] {
        let spec = parse(s);
        let missing = spec.missing_feature();
        assert_eq!(
            missing,
            (!cfg!(feature = "gstreamer")).then_some("gstreamer"),
            "{s}"
        );
        if missing.is_some() {
            let e = open_source(&spec, 64, 48, 15.0).unwrap_err();
            assert!(
                matches!(
                    e,
                    SpecError::NotBuilt {
                        feature: "gstreamer",
                        ..
                    }
                ),
                "{e:?}"
            );
            assert!(
                e.to_string()
                    .contains("this ocelli was built without the `gstreamer` feature"),
                "{e}"
            );
        }
    }
    assert_eq!(parse("synthetic").missing_feature(), None);
    assert_eq!(parse("images:d").missing_feature(), None);
}

#[test]
fn open_refuses_impossible_cameras_and_synthetic() {
    let spec = parse("images:/nonexistent");
    assert!(matches!(
        open_source(&spec, 0, 48, 15.0).unwrap_err(),
        SpecError::Size { width: 0, height: 48 }
    ));
    let tall = open_source(&spec, 64, MAX_FRAME_SIDE + 1, 15.0).unwrap_err();
    assert!(matches!(tall, SpecError::Size { width: 64, height } if height == MAX_FRAME_SIDE + 1));
    assert!(matches!(open_source(&spec, 64, 48, f64::NAN).unwrap_err(), SpecError::Rate(r) if r.is_nan()));
    assert!(matches!(
        open_source(&parse("synthetic"), 64, 48, 15.0).unwrap_err(),
        SpecError::NeedsScenario
    ));
    let e = open_source(&spec, 64, 48, 15.0).unwrap_err();
    assert!(e.to_string().contains("/nonexistent"), "{e}");
}

fn frames_dir(name: &str, n: u8) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ocelli-spec-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for i in 0..n {
        image::RgbImage::from_pixel(8, 6, image::Rgb([10 * i, 0, 0]))
            .save(d.join(format!("{i:03}.png")))
            .unwrap();
    }
    d
}

fn run(source: &mut dyn FrameSource, captures: usize) -> Vec<Option<u8>> {
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    (0..captures)
        .map(|i| {
            let got = source.capture(ClusterTime::from_millis(i as i64 * 100), &mut frame);
            got.unwrap().then(|| frame.data[0])
        })
        .collect()
}

#[test]
fn images_stop_at_their_end_or_loop_and_are_counted() {
    let d = frames_dir("images", 3);
    let spec = SourceSpec::parse(&format!("images:{}", d.display())).unwrap();
    let mut opened = open_source(&spec, 8, 6, 10.0).unwrap();
    assert_eq!(opened.source.size(), (8, 6));
    assert_eq!(
        run(opened.source.as_mut(), 5),
        vec![Some(0), Some(10), Some(20), None, None]
    );
    let stats = opened.stats.snapshot();
    assert_eq!((stats.frames, stats.ends, stats.errors), (3, 1, 0));

    let looped = SourceSpec::parse(&format!("images:{}?loop", d.display())).unwrap();
    let mut opened = open_source(&looped, 8, 6, 10.0).unwrap();
    assert_eq!(
        run(opened.source.as_mut(), 4),
        vec![Some(0), Some(10), Some(20), Some(0)]
    );
    assert_eq!(opened.stats.snapshot().ends, 0);

    // A frame deleted under a running source is a counted error, not a panic.
    std::fs::remove_file(d.join("001.png")).unwrap();
    let mut frame = Frame::new(1, 1, ClusterTime::ZERO);
    for _ in 0..3 {
        assert!(opened.source.capture(ClusterTime::ZERO, &mut frame).is_err());
    }
    assert_eq!(opened.stats.snapshot().errors, 3);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn shared_stats_count_across_clones_and_logging_thins_out() {
    let a = SharedStats::default();
    let b = a.clone();
    assert_eq!(a.bump(Count::Stall), 1);
    assert_eq!(b.bump(Count::Stall), 2);
    b.bump(Count::CorruptFrame);
    let s = a.snapshot();
    assert_eq!((s.stalls, s.corrupt_frames, s.frames), (2, 1, 0));
    let logged: Vec<u64> = (1..=40).filter(|&n| worth_logging(n)).collect();
    assert_eq!(logged, vec![1, 2, 3, 4, 8, 16, 32]);
}
