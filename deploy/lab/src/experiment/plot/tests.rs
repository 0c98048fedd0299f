//! The figure of a synthetic trace: its size, each series' colour in its own panel, text drawn
//! with the embedded font, a valid PNG on disk, and typed errors. No golden images: plotters may
//! move a pixel between versions.

use super::*;
use crate::experiment::runner::Sample;
use image::{GenericImageView, Rgb};
use sim::Level;

/// A target walking along x at 0.4 m/s for 10 s, estimated 0.1 m off, seen by 3 cameras and 1
/// RSSI node, with a window from 2 to 4 s.
fn trace() -> Trace {
    let samples: Vec<Sample> = (0..50)
        .map(|k| {
            let t = f64::from(k) * 0.2;
            Sample {
                t,
                est: [t * 0.4 + 0.1, 2.0, 0.25],
                truth: [t * 0.4, 2.0, 0.25],
                sigma_m: 0.05,
                error_m: 0.1,
                cameras: 3,
                rssi_nodes: 1,
            }
        })
        .collect();
    Trace {
        method: "Synthetic method".into(),
        samples,
        window: Some((2.0, 4.0)),
    }
}

/// Pixels of exactly `c` inside the plot part of panel `k` (0, 1, 2): below the title band and
/// above the legend strip, whose swatches share the series' colours.
fn in_panel(img: &RgbImage, k: u32, c: RGBColor) -> usize {
    let third = WIDTH / 3;
    let want = Rgb([c.0, c.1, c.2]);
    (k * third..(k + 1) * third)
        .flat_map(|x| (TITLE_H..HEIGHT - LEGEND_H).map(move |y| (x, y)))
        .filter(|&(x, y)| *img.get_pixel(x, y) == want)
        .count()
}

#[test]
fn each_series_is_drawn_in_its_colour_in_its_panel() {
    let img = render("paper-test", 1, &trace()).unwrap();
    assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
    let expected: [(&str, u32, RGBColor); 7] = [
        ("truth", 0, TRUTH),
        ("estimate", 0, ESTIMATE),
        ("3σ rings", 0, BAND),
        ("error", 1, ESTIMATE),
        ("3σ bound", 1, BAND),
        ("window", 1, WINDOW),
        ("RSSI readings", 2, RSSI),
    ];
    for (name, k, c) in expected {
        let n = in_panel(&img, k, c);
        assert!(n > 40, "{name} in panel {k}: {n} pixels");
    }
    // Cameras share the truth's blue, in their own panel; nothing green left of it, no window
    // in the trajectory.
    assert!(in_panel(&img, 2, CAMERAS) > 40, "cameras in panel 2");
    assert_eq!(
        in_panel(&img, 0, RSSI) + in_panel(&img, 1, RSSI),
        0,
        "RSSI outside its panel"
    );
}

#[test]
fn the_title_band_holds_text_drawn_with_the_embedded_font() {
    let img = render("paper-test", 7, &trace()).unwrap();
    let dark = |y_range: std::ops::Range<u32>| {
        (0..WIDTH)
            .flat_map(|x| y_range.clone().map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let p = img.get_pixel(x, y).0;
                p.iter().map(|&c| u32::from(c)).sum::<u32>() < 3 * 90
            })
            .count()
    };
    // Nothing but text is drawn in the title band: dark pixels there are glyphs.
    let title = dark(0..TITLE_H);
    assert!(title > 300, "{title} dark pixels in the title band");
    // The legend strips hold labels too.
    assert!(dark(HEIGHT - LEGEND_H..HEIGHT) > 300, "legend labels");
    // A different title draws differently: the text is rendered, not a fixed banner.
    let other = render("another-experiment-name", 7, &trace()).unwrap();
    let band = |i: &RgbImage| i.view(0, 0, WIDTH, TITLE_H).to_image();
    assert_ne!(band(&img), band(&other));
}

#[test]
fn a_run_without_estimates_says_so() {
    let empty = Trace {
        samples: Vec::new(),
        ..trace()
    };
    let img = render("paper-test", 1, &empty).unwrap();
    assert_eq!(img.dimensions(), (WIDTH, HEIGHT));
    let dark_below_title = img
        .enumerate_pixels()
        .filter(|(_, y, p)| *y >= TITLE_H && p.0.iter().all(|&c| c < 90))
        .count();
    assert!(dark_below_title > 100, "the 'no estimate' line");
}

fn outcome(traces: Vec<Trace>) -> Outcome {
    Outcome {
        traces,
        ..Outcome::new(
            "paper-test",
            Level::Measurement,
            &super::super::Options::default(),
            10.0,
        )
    }
}

#[test]
fn write_all_writes_one_valid_png_per_method() {
    let dir = std::env::temp_dir().join(format!("ocelli-plot-test-{}", std::process::id()));
    let second = Trace {
        method: "Active perception (cost 0.2)".into(),
        ..trace()
    };
    let paths = write_all(&outcome(vec![trace(), second]), &dir).unwrap();
    let names: Vec<String> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "paper-test-synthetic-method.png",
            "paper-test-active-perception-cost-0-2.png"
        ]
    );
    for p in &paths {
        let bytes = std::fs::read(p).unwrap();
        assert!(
            bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
            "{}: no PNG signature",
            p.display()
        );
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png).unwrap();
        assert_eq!((img.width(), img.height()), (WIDTH, HEIGHT));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_unwritable_directory_is_a_typed_error_naming_it() {
    let file = std::env::temp_dir().join(format!("ocelli-plot-not-a-dir-{}", std::process::id()));
    std::fs::write(&file, b"").unwrap();
    let err = write_all(&outcome(vec![trace()]), &file.join("figures")).unwrap_err();
    assert!(matches!(err, PlotError::CreateDir { .. }), "{err:?}");
    assert!(err.to_string().contains("ocelli-plot-not-a-dir"), "{err}");
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn method_labels_become_file_names() {
    assert_eq!(slug("Active perception (cost 0.2)"), "active-perception-cost-0-2");
    assert_eq!(slug("RSSI only — Rectangular"), "rssi-only-rectangular");
}

/// One filter sweeping the image's columns over 4 s, its samples at (100, 120) in a grey frame.
fn particle_trace() -> crate::experiment::ParticleTrace {
    use crate::experiment::{ParticleTrace, PdfSlice, SampleSnapshot};
    let frames = (0..40)
        .map(|k| {
            let mut columns = vec![0.0; 88];
            columns[(k * 2) % 88] = 1.0;
            let mut rows = vec![0.0; 72];
            rows[30] = 1.0;
            PdfSlice {
                t: k as f64 * 0.1,
                columns,
                rows,
            }
        })
        .collect();
    ParticleTrace {
        method: "particle filters".into(),
        width: 352,
        height: 288,
        bin_px: 4,
        frames,
        snapshot: Some(SampleSnapshot {
            t: 2.0,
            image: image::RgbImage::from_pixel(352, 288, Rgb([128, 128, 128])),
            samples: (0..50)
                .map(|i| [100.0 + (i % 5) as f32, 120.0 + (i / 10) as f32, 0.02])
                .collect(),
            means: vec![[102.0, 122.0]],
            why: "test".into(),
        }),
    }
}

#[test]
fn the_particle_figure_is_written_beside_the_traces_with_samples_and_pdf_drawn() {
    let dir = std::env::temp_dir().join(format!("ocelli-plot-particles-{}", std::process::id()));
    let o = Outcome {
        particles: Some(particle_trace()),
        ..outcome(vec![trace()])
    };
    let paths = write_all(&o, &dir).unwrap();
    let last = paths.last().unwrap();
    assert_eq!(last.file_name().unwrap(), "paper-test-particles.png");
    let img = image::open(last).unwrap();
    assert_eq!((img.width(), img.height()), (WIDTH, HEIGHT));
    let count = |x0: u32, x1: u32, f: &dyn Fn(image::Rgba<u8>) -> bool| {
        (x0..x1)
            .flat_map(|x| (TITLE_H..HEIGHT - LEGEND_H).map(move |y| (x, y)))
            .filter(|&(x, y)| f(img.get_pixel(x, y)))
            .count()
    };
    let third = WIDTH / 3;
    // The pdf panels are shaded in the pdf's blue; the sample panel has green samples and the
    // yellow mean over the grey frame.
    let blue = |p: image::Rgba<u8>| p[2] > 100 && p[0] < 60 && p[1] < 80;
    assert!(count(0, third, &blue) > 200, "column pdf drawn");
    assert!(count(third, 2 * third, &blue) > 200, "row pdf drawn");
    let green = |p: image::Rgba<u8>| p[1] > 180 && p[0] < 100 && p[2] < 100;
    let yellow = |p: image::Rgba<u8>| p[0] > 220 && p[1] > 200 && p[2] < 60;
    assert!(count(2 * third, WIDTH, &green) > 20, "samples drawn");
    assert!(count(2 * third, WIDTH, &yellow) > 10, "mean drawn");
    std::fs::remove_dir_all(&dir).unwrap();
}
