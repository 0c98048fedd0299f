use super::*;

/// A fresh directory under the system's temp dir, removed when dropped.
pub(crate) struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("node-acoustic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Write interleaved 16-bit samples.
pub(crate) fn write_i16(path: &Path, channels: u16, rate: u32, samples: impl IntoIterator<Item = i16>) {
    let spec = hound::WavSpec {
        channels,
        sample_rate: rate,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for s in samples {
        w.write_sample(s).unwrap();
    }
    w.finalize().unwrap();
}

/// A deterministic noise-like sample.
fn noise(i: usize) -> i16 {
    ((i as f64 * 12.9898).sin() * 43758.5453)
        .fract()
        .mul_add(8000.0, 0.0) as i16
}

#[test]
fn a_good_stereo_file_reads_as_two_channels() {
    let dir = TempDir::new("good");
    let path = dir.0.join("good.wav");
    write_i16(&path, 2, 48_000, (0..9600).map(noise));
    let clip = read_stereo(&path, 48_000).unwrap();
    assert_eq!(clip.left.len(), 4800);
    assert_eq!(clip.left[1], f32::from(noise(2)) / 32768.0);
    assert_eq!(clip.right[1], f32::from(noise(3)) / 32768.0);
    assert_eq!(clip.clipped_samples, 0);
    assert!((clip.duration() - 0.1).abs() < 1e-12);
    // Float WAVs read too.
    let fpath = dir.0.join("float.wav");
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 48_000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(&fpath, spec).unwrap();
    for i in 0..2000 {
        w.write_sample(f32::from(noise(i)) / 32768.0).unwrap();
    }
    w.finalize().unwrap();
    assert_eq!(read_stereo(&fpath, 48_000).unwrap().left.len(), 1000);
}

#[test]
fn each_kind_of_bad_file_gets_its_own_error_naming_the_file() {
    let dir = TempDir::new("bad");
    let check = |name: &str, err: WavError, wanted: &str| {
        let text = err.to_string();
        assert!(text.contains(name), "{name}: {text}");
        assert!(text.contains(wanted), "{name}: {text} lacks {wanted:?}");
    };
    let mono = dir.0.join("mono.wav");
    write_i16(&mono, 1, 48_000, (0..4800).map(noise));
    let e = read_stereo(&mono, 48_000).unwrap_err();
    assert!(matches!(e, WavError::Channels { channels: 1, .. }));
    check("mono.wav", e, "1 channel(s)");

    let rate = dir.0.join("rate.wav");
    write_i16(&rate, 2, 44_100, (0..4800).map(noise));
    let e = read_stereo(&rate, 48_000).unwrap_err();
    assert!(matches!(e, WavError::SampleRate { found: 44_100, .. }));
    check("rate.wav", e, "44100 Hz");

    let silent = dir.0.join("silent.wav");
    write_i16(
        &silent,
        2,
        48_000,
        (0..4800).map(|i| if i % 2 == 0 { noise(i) } else { 0 }),
    );
    let e = read_stereo(&silent, 48_000).unwrap_err();
    assert!(matches!(e, WavError::Silent { channel: "right", .. }));
    check("silent.wav", e, "silent");

    let clipped = dir.0.join("clipped.wav");
    write_i16(
        &clipped,
        2,
        48_000,
        (0..4800).map(|i| if i % 10 == 0 { i16::MAX } else { noise(i) }),
    );
    let e = read_stereo(&clipped, 48_000).unwrap_err();
    assert!(matches!(e, WavError::Clipped { .. }));
    check("clipped.wav", e, "10.0 %");

    let truncated = dir.0.join("truncated.wav");
    write_i16(&truncated, 2, 48_000, (0..4800).map(noise));
    let len = std::fs::metadata(&truncated).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&truncated)
        .unwrap()
        .set_len(len - 1001)
        .unwrap();
    let e = read_stereo(&truncated, 48_000).unwrap_err();
    assert!(matches!(e, WavError::Truncated { declared: 4800, .. }), "{e}");
    check("truncated.wav", e, "truncated");

    let text = dir.0.join("notes.wav");
    std::fs::write(&text, "x,y,wav\n").unwrap();
    let e = read_stereo(&text, 48_000).unwrap_err();
    assert!(matches!(e, WavError::Open { .. }));
    check("notes.wav", e, "cannot read as WAV");

    let missing = dir.0.join("missing.wav");
    check(
        "missing.wav",
        read_stereo(&missing, 48_000).unwrap_err(),
        "cannot read",
    );
}

/// A file that is partly silent and briefly clipped is read; its frames say which to skip.
#[test]
fn silent_and_clipped_frames_are_marked_not_fatal() {
    let dir = TempDir::new("frames");
    let path = dir.0.join("mixed.wav");
    // 4 frames of 1000 stereo samples: good, silent, clipped (a 20-sample burst), good.
    let samples = (0..8000).map(|i| match i / 2000 {
        1 => 0,
        2 if (i % 2000) < 40 => i16::MIN,
        _ => noise(i),
    });
    write_i16(&path, 2, 48_000, samples);
    let clip = read_stereo(&path, 48_000).unwrap();
    assert_eq!(clip.clipped_samples, 40);
    let q: Vec<FrameQuality> = clip.frames(1000).map(|f| f.quality).collect();
    assert_eq!(
        q,
        vec![
            FrameQuality::Good,
            FrameQuality::Silent,
            FrameQuality::Clipped,
            FrameQuality::Good
        ]
    );
    let t: Vec<f64> = clip.frames(1000).map(|f| f.t).collect();
    assert!((t[3] - 3000.0 / 48_000.0).abs() < 1e-12);
}
