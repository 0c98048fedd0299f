//! The paper 004 pipeline on MultiviewX (`../shared/datasets/multiviewx`): it must find the
//! moving people of the views.
//!
//! **The shipped annotations do not describe these images.** `annotations_positions/0000N.json`
//! (N = 1…5) were compared with `Image_subsets/C*/000M.jpg` under every file offset and view
//! mapping: drawn over the images their boxes fall on empty pavement, and the detections'
//! agreement with them is at chance level for every mapping (see the report of issue 3). The
//! ground truth here is therefore hand-labelled: the centre (mid-body) of every person at
//! least ~80 px tall in frame `0002` of C1 (complete: 17 people, so precision can be judged),
//! and of the 15 clearly separable people of the crowded C3 frame `0002` (recall only),
//! read off a 100 px grid drawn over the full-resolution image.
//!
//! Five frames are far too short for the adaptive model to learn a background, so it is
//! initialised with the per-pixel temporal median of the view's five frames
//! ([`AdaptiveBackground::init_median`]) and then all frames are segmented in order.

use node_camera::adaptive_background::{AdaptiveBackground, AdaptiveBackgroundParams};
use node_camera::source::ImageSequence;
use proto::ClusterTime;
use proto::sensor::Detection;
use proto::sensor::Frame;
use std::path::{Path, PathBuf};

fn dataset() -> PathBuf {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/datasets/multiviewx");
    assert!(
        d.join("Image_subsets/C1").is_dir(),
        "MultiviewX subset missing at {} (shared/ must sit beside the repo)",
        d.display()
    );
    d
}

/// Hand-labelled person centres, full-resolution pixels, frame 0002 of C1 (complete).
const C1_FRAME2: [[f32; 2]; 17] = [
    [10.0, 540.0],
    [115.0, 540.0],
    [200.0, 540.0],
    [380.0, 560.0],
    [650.0, 520.0],
    [820.0, 530.0],
    [920.0, 540.0],
    [1280.0, 545.0],
    [1308.0, 520.0],
    [1355.0, 550.0],
    [1395.0, 510.0],
    [1558.0, 540.0],
    [1728.0, 535.0],
    [1815.0, 550.0],
    [1810.0, 800.0],
    [1740.0, 960.0],
    [1890.0, 700.0],
];

/// Hand-labelled centres of the clearly separable people of C3 frame 0002 (not complete).
const C3_FRAME2: [[f32; 2]; 15] = [
    [128.0, 530.0],
    [280.0, 700.0],
    [445.0, 540.0],
    [495.0, 530.0],
    [710.0, 680.0],
    [950.0, 660.0],
    [880.0, 640.0],
    [1207.0, 470.0],
    [1243.0, 470.0],
    [1328.0, 470.0],
    [1220.0, 640.0],
    [1430.0, 620.0],
    [1528.0, 610.0],
    [1625.0, 650.0],
    [1850.0, 590.0],
];

fn contains(d: &Detection, p: &[f32; 2]) -> bool {
    (d.bbox.xmin..=d.bbox.xmax).contains(&p[0]) && (d.bbox.ymin..=d.bbox.ymax).contains(&p[1])
}

/// 1920×1080 processed on a 640×360 grid (step 3): people are 8–60 grid pixels wide.
fn params() -> AdaptiveBackgroundParams {
    AdaptiveBackgroundParams {
        step: 3,
        min_pixels: 40,
        merge: 1,
        erosion_min: 3,
        ..AdaptiveBackgroundParams::default()
    }
}

/// Detections of every frame of view `cam`.
fn detect_view(dir: &Path, cam: usize) -> (Vec<Frame>, Vec<Vec<Detection>>) {
    let seq = ImageSequence::with_rate(&dir.join(format!("Image_subsets/C{cam}")), 2.0).unwrap();
    assert_eq!(seq.len(), 5, "C{cam} should hold five frames");
    let frames: Vec<Frame> = seq
        .files()
        .iter()
        .enumerate()
        .map(|(i, p)| ImageSequence::load(p, ClusterTime::from_millis(i as i64 * 500)).unwrap())
        .collect();
    let mut seg = AdaptiveBackground::new(params());
    seg.init_median(&frames.iter().collect::<Vec<_>>()).unwrap();
    let mut all = Vec::new();
    let mut dets = Vec::new();
    for f in &frames {
        seg.process(f, &mut dets).unwrap();
        all.push(dets.clone());
    }
    (frames, all)
}

fn picture(frame: &Frame, dets: &[Detection], truth: &[[f32; 2]], path: &Path) {
    let mut img = frame.clone();
    for d in dets {
        let b = d.bbox;
        img.draw_box(
            b.xmin as i64,
            b.ymin as i64,
            b.xmax as i64,
            b.ymax as i64,
            [255, 0, 255],
            4,
        );
    }
    for p in truth {
        let (x, y) = (p[0] as i64, p[1] as i64);
        img.draw_box(x - 6, y - 6, x + 6, y + 6, [0, 255, 0], 4);
    }
    image::RgbImage::from_raw(img.width, img.height, img.data)
        .unwrap()
        .save(path)
        .unwrap();
}

/// Every hand-labelled person of C1 and C3 lies in a detection box, and every C1 detection
/// holds a person. Measured (merge 1, erosion needing 3 of 4 neighbours): C1 17/17 people in
/// 10 boxes, 9/10 boxes hold a person (the tenth is a head above a merged group); C3 14/15
/// people in 14 boxes, its largest box (five people walking together, with their shadows)
/// 15.5 % of the frame. The bounds (≥ 85 % recall, ≥ 80 % precision, no box over 20 % of the
/// frame) leave room for a miss or two, not for a broken pipeline: the area bound stops one
/// frame-sized box from "finding" everyone. Nearby people merge into groups (paper 004's
/// merging), so there are fewer boxes than people; moving shadows belong to their person.
#[test]
fn paper004_finds_the_moving_people_of_multiviewx() {
    let dir = dataset();
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target");
    let _ = std::fs::create_dir_all(&out);
    for (cam, truth) in [(1usize, &C1_FRAME2[..]), (3, &C3_FRAME2[..])] {
        let (frames, dets) = detect_view(&dir, cam);
        let d2 = &dets[2];
        picture(
            &frames[2],
            d2,
            truth,
            &out.join(format!("multiviewx_c{cam}_adaptive_background.png")),
        );
        let found = truth.iter().filter(|p| d2.iter().any(|d| contains(d, p))).count();
        let frame_area = (frames[2].width * frames[2].height) as f32;
        for d in d2 {
            let a = (d.bbox.xmax - d.bbox.xmin) * (d.bbox.ymax - d.bbox.ymin);
            let share = a / frame_area;
            assert!(
                share < 0.2,
                "C{cam}: a box covers {:.0}% of the frame",
                100.0 * share
            );
        }
        eprintln!(
            "C{cam} frame 2: {found}/{} people in {} boxes",
            truth.len(),
            d2.len()
        );
        assert!(
            found * 100 >= truth.len() * 85,
            "C{cam}: recall {found}/{}",
            truth.len()
        );
        if cam == 1 {
            let correct = d2.iter().filter(|d| truth.iter().any(|p| contains(d, p))).count();
            eprintln!("C1 frame 2: {correct}/{} boxes hold a person", d2.len());
            assert!(d2.len() >= 4, "groups should not all merge: {} boxes", d2.len());
            assert!(
                correct * 100 >= d2.len() * 80,
                "C1: precision {correct}/{}",
                d2.len()
            );
        }
        // Every view, every frame: people are found (boxes are mostly people-sized).
        for (i, d) in dets.iter().enumerate() {
            assert!(!d.is_empty(), "C{cam} frame {i}: nothing found");
        }
    }
    for cam in [2usize, 4, 5, 6] {
        let (_, dets) = detect_view(&dir, cam);
        for (i, d) in dets.iter().enumerate() {
            assert!(!d.is_empty(), "C{cam} frame {i}: nothing found");
        }
    }
}
