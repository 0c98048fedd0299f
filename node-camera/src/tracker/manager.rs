//! The multi-person tracker of paper 004 §3.2.1–3.2.2: one colour particle filter per person.
//! A foreground region (from the background model, `adaptive_background`) that no filter explains for
//! `init-frames` frames starts a filter with its current appearance as target; a filter with no
//! supporting region for `destroy-s` seconds is destroyed; of two filters that share a region
//! for `duplicate-s` seconds with boxes alike (IoU), one inside the other or one
//! above the other in its columns, one is eliminated: the smaller when nested or stacked (it
//! sits on a part of the other's person), else the younger, unless the older's colours matched
//! clearly worse (it drifted there). Each filter keeps its local id for life. The region
//! assigned to a filter shapes its weights; the foreground share under its best box gates its
//! adaptation.
//!
//! Ours, beyond §3.2.1: a region that is a fragment of a person a filter follows (a strip of
//! them an occluder cut off, or a piece inside their box, in their colours:
//! [`crate::tracker::fragment`]) starts no filter, and joins that filter's region, so the
//! person keeps one filter and one id behind a pillar. A filter no region alone supports is
//! supported by the narrower parts beside it in its colours, joined, when together they
//! support its box (the pillar hides the person's middle).
//!
//! Per frame: the RGB frame, the regions and (optionally) the foreground mask in; per person
//! out: id, mean state, maximum-likelihood state and confidence, box, sample spread, target
//! histogram, and on request the sample set.

use crate::adaptive_background::AdaptiveBackground;
use crate::region::Grid;
use crate::tracker::boxes::{area, column_overlap, contains, iou, is_finite, overlap_of_smaller, union};
use crate::tracker::filter::{ParticleFilter, Sample, adaptation_rate, box_histogram};
use crate::tracker::fragment::{is_beside, is_fragment, is_fragment_of, same_colours};
use crate::tracker::histogram::{BinImage, ColourHistogram, FrameBins};
use crate::tracker::motion::State;
use crate::tracker::params::{ParamsError, ParticleParams};
use proto::msg::PixelBox;
use proto::sensor::Detection;
use proto::sensor::{Frame, FrameError};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

/// A person's id on this camera, unique for the tracker's life.
pub type LocalId = u32;

/// IoU a region needs with a waiting candidate to count as the same new object.
const CANDIDATE_IOU: f32 = 0.3;

/// The parts of a person an occluder split, joined, are at most this many times as wide as
/// their filter's box (`parts_beside`).
const PARTS_WIDTH: f32 = 2.0;

/// Input the tracker rejects; it changes no state.
#[derive(Debug, Error, PartialEq)]
pub enum TrackerError {
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("region {index} has a box that is not finite or not ordered: {bbox:?}")]
    Region { index: usize, bbox: PixelBox },
    #[error("foreground mask has {got} bytes, its {width}x{height} grid needs {want}")]
    Mask {
        got: usize,
        want: usize,
        width: usize,
        height: usize,
    },
    #[error("foreground grid covers a {grid_width}-pixel-wide frame, the frame is {frame_width} wide")]
    MaskGrid { grid_width: usize, frame_width: u32 },
    #[error("box {0:?} has no pixels in the frame")]
    EmptyBox(PixelBox),
    #[error("already tracking {0} people (max-people)")]
    Full(usize),
}

/// The background model's per-pixel foreground, on its processing grid.
#[derive(Clone, Copy, Debug)]
pub struct Foreground<'a> {
    mask: &'a [u8],
    grid: Grid,
}

impl<'a> Foreground<'a> {
    /// A mask of one byte per grid pixel, non-zero = foreground.
    ///
    /// # Errors
    /// [`TrackerError::Mask`] when the mask does not fit the grid.
    pub fn new(mask: &'a [u8], grid: Grid) -> Result<Foreground<'a>, TrackerError> {
        if mask.len() != grid.len() {
            return Err(TrackerError::Mask {
                got: mask.len(),
                want: grid.len(),
                width: grid.width,
                height: grid.height,
            });
        }
        Ok(Foreground { mask, grid })
    }

    /// The moving-pixel mask of a paper 004 background model's last frame; `None` before its
    /// first frame.
    pub fn of(seg: &'a AdaptiveBackground) -> Option<Foreground<'a>> {
        let grid = seg.grid()?;
        Foreground::new(seg.mask(), grid).ok()
    }

    /// The lower edge (frame pixels, continuous) of a person standing in `columns`, found
    /// between the rows `rows.0..=rows.1`: per grid column the lowest foreground pixel, and
    /// of those the median, so that a few columns of a neighbour's legs or of noise do not
    /// move it. `None` when no column has a foreground pixel there.
    pub fn lowest_edge(&self, columns: (f32, f32), rows: (f32, f32)) -> Option<f32> {
        let g = &self.grid;
        if g.is_empty() {
            return None;
        }
        let s = g.step as f32;
        let x0 = (columns.0 / s).ceil().max(0.0) as usize;
        let x1 = ((columns.1 / s).floor().max(0.0) as usize).min(g.width - 1);
        let y0 = (rows.0 / s).ceil().max(0.0) as usize;
        let y1 = ((rows.1 / s).floor().max(0.0) as usize).min(g.height - 1);
        let mut lowest: Vec<usize> = (x0..=x1)
            .filter_map(|x| (y0..=y1).rev().find(|&y| self.mask[y * g.width + x] != 0))
            .collect();
        if lowest.is_empty() {
            return None;
        }
        let mid = lowest.len() / 2;
        let (_, &mut y, _) = lowest.select_nth_unstable(mid);
        // A grid pixel stands for the `step` frame rows from its own, as a region's box does
        // (`RegionStats`), and a region's box ends half a pixel below its last row
        // (`region_box`): the same edge either way.
        Some(((y + 1) * g.step) as f32 - 0.5)
    }

    /// Share of the grid pixels under `b` (frame pixels) that are foreground; 0 for a box
    /// outside the grid.
    pub fn fraction(&self, b: &PixelBox) -> f32 {
        let g = &self.grid;
        let s = g.step as f32;
        let x0 = (b.xmin / s).ceil().max(0.0);
        let y0 = (b.ymin / s).ceil().max(0.0);
        let x1 = (b.xmax / s).floor().min(g.width as f32 - 1.0);
        let y1 = (b.ymax / s).floor().min(g.height as f32 - 1.0);
        if !(x0 <= x1 && y0 <= y1) {
            return 0.0;
        }
        let (x0, x1, y0, y1) = (x0 as usize, x1 as usize, y0 as usize, y1 as usize);
        let set: usize = (y0..=y1)
            .map(|y| {
                self.mask[y * g.width + x0..=y * g.width + x1]
                    .iter()
                    .filter(|&&v| v != 0)
                    .count()
            })
            .sum();
        set as f32 / ((x1 - x0 + 1) * (y1 - y0 + 1)) as f32
    }
}

/// One frame's input.
#[derive(Clone, Copy, Debug)]
pub struct TrackerInput<'a> {
    pub frame: &'a Frame,
    /// Foreground regions of this frame (pixel boxes, inclusive pixel indices as `adaptive_background`
    /// reports them).
    pub regions: &'a [Detection],
    pub foreground: Option<Foreground<'a>>,
    /// Put each filter's sample set in the output.
    pub with_samples: bool,
}

/// What the camera reports of one person per frame (§2.5.1).
#[derive(Clone, Debug, PartialEq)]
pub struct PersonEstimate {
    pub id: LocalId,
    /// The mean state.
    pub mean: State,
    /// The maximum-likelihood state and its confidence: its weight before normalization (eq. 8
    /// times the region term) relative to a perfect match, in [0, 1].
    pub ml: State,
    pub ml_confidence: f32,
    /// The maximum-likelihood sample's colour similarity to the target.
    pub ml_similarity: f32,
    /// The largest normalized weight.
    pub peak_weight: f32,
    /// Foreground share under the maximum-likelihood box (with a background model).
    pub foreground: Option<f32>,
    /// The mean state's box.
    pub bbox: PixelBox,
    /// Weighted covariance of the samples' (x, y, w, h), pixels².
    pub box_covariance: [[f64; 4]; 4],
    /// The target histogram after this frame's adaptation.
    pub histogram: ColourHistogram,
    /// The sample set when asked for, else empty.
    pub samples: Vec<Sample>,
    pub frames_tracked: u64,
    /// Consecutive frames without a supporting region.
    pub unsupported_frames: u32,
    /// This frame's supporting region (index into the input's regions), if any.
    pub region: Option<usize>,
}

#[cfg(test)]
impl PersonEstimate {
    /// A person at rest filling `bbox`, supported by `region` (tests of what reads estimates).
    pub(crate) fn at_box(id: LocalId, bbox: PixelBox, region: Option<usize>) -> PersonEstimate {
        let mut counts = crate::tracker::histogram::KernelCounts::default();
        counts.bins[0] = 1.0;
        counts.total = 1.0;
        let state = State::from_box(&bbox);
        PersonEstimate {
            id,
            mean: state,
            ml: state,
            ml_confidence: 1.0,
            ml_similarity: 1.0,
            peak_weight: 1.0,
            foreground: None,
            bbox,
            box_covariance: [[0.0; 4]; 4],
            histogram: ColourHistogram::from_counts(&counts).expect("a histogram with a count"),
            samples: Vec::new(),
            frames_tracked: 1,
            unsupported_frames: u32::from(region.is_none()),
            region,
        }
    }
}

/// What the tracker did since it started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackerCounters {
    pub frames: u64,
    pub started: u64,
    pub destroyed: u64,
    pub duplicates_eliminated: u64,
    /// Regions that would have started a filter with `max-people` already tracked.
    pub refused_full: u64,
    /// Regions that would have started a filter but were a fragment of a tracked person
    /// (`fragment`).
    pub refused_fragments: u64,
}

#[derive(Clone, Debug)]
struct Person {
    id: LocalId,
    filter: ParticleFilter,
    unsupported: u32,
    /// This frame's region, index into the input.
    region: Option<usize>,
    foreground: Option<f32>,
}

#[derive(Clone, Debug)]
struct Candidate {
    bbox: PixelBox,
    seen: u32,
}

/// Two filters sharing a region, and for how many consecutive frames.
#[derive(Clone, Debug)]
struct Shared {
    older: LocalId,
    younger: LocalId,
    frames: u32,
    /// Sum over those frames of the older's colour similarity minus the younger's.
    older_lead: f32,
    /// This frame, the smaller of the two (the younger when their areas are equal) when one box
    /// lies inside the other or above or below it in its columns without the two being alike
    /// (IoU below `duplicate-iou`).
    nested: Option<LocalId>,
}

/// How much worse (mean colour similarity over the shared frames) the older of two duplicates
/// must match for it, not the younger, to be eliminated: a filter that drifted onto someone
/// else's region gives way to the one that matches them, while two filters on the same person
/// keep the older id.
const DRIFTED_MARGIN: f32 = 0.05;

/// How much of the smaller of two filters' boxes must lie inside the larger for the pair to be
/// nested (a filter on a part of the other's person) although their IoU is under
/// `duplicate-iou`. Near 1: two people partly hiding each other overlap less than this.
const NESTED_OVERLAP: f32 = 0.9;

/// How much of the narrower of two filters' boxes' columns must lie inside the wider's for the
/// pair to be stacked (one above the other on one person, a fragment of their legs or of
/// their head and the wall above, in one region) and so nested too, whatever their overlap in
/// area or height. Two people side by side, or one partly hiding the other from the side,
/// share fewer columns. A person right behind another in one region shares as many, and goes
/// too (their box, higher in the image, was not nested): the price of taking the fragments,
/// measured in docs/paper004.md, where 0.6 took more people and 0.9 left fragments.
const STACKED_COLUMNS: f32 = 0.8;

/// The multi-person tracker of one camera.
#[derive(Debug)]
pub struct MultiTracker {
    params: ParticleParams,
    /// The destroy and duplicate waits in this camera's frames.
    destroy_frames: u32,
    duplicate_frames: u32,
    rng: ChaCha8Rng,
    image: BinImage,
    frame_size: Option<(u32, u32)>,
    people: Vec<Person>,
    candidates: Vec<Candidate>,
    shared: Vec<Shared>,
    next_id: LocalId,
    counters: TrackerCounters,
}

/// A region's box in continuous pixel coordinates (pixel `i` spans `[i − ½, i + ½]`).
pub fn region_box(d: &Detection) -> PixelBox {
    PixelBox {
        xmin: d.bbox.xmin - 0.5,
        ymin: d.bbox.ymin - 0.5,
        xmax: d.bbox.xmax + 0.5,
        ymax: d.bbox.ymax + 0.5,
    }
}

/// Whether a region supports a filter's box: the box centre inside it, or enough overlap.
fn supports(region: &PixelBox, b: &PixelBox, min_iou: f32) -> bool {
    let c = [0.5 * (b.xmin + b.xmax), 0.5 * (b.ymin + b.ymax)];
    contains(region, c) || iou(region, b) >= min_iou.max(f32::MIN_POSITIVE)
}

/// The supporting region with the largest overlap.
fn best_region(b: &PixelBox, regions: &[PixelBox], min_iou: f32) -> Option<usize> {
    regions
        .iter()
        .enumerate()
        .filter(|(_, r)| supports(r, b, min_iou))
        .max_by(|(_, a), (_, c)| iou(a, b).total_cmp(&iou(c, b)))
        .map(|(i, _)| i)
}

/// Whether region `r` has the colours of `target`, its histogram read from the bound frame.
fn in_colours(r: &PixelBox, target: &ColourHistogram, bins: &mut FrameBins<'_>, p: &ParticleParams) -> bool {
    box_histogram(bins, r, p).is_some_and(|c| same_colours(&c, target, p.hs_weight))
}

/// A filter's region of interest: region `i`, the one that best supports its `predicted` box,
/// joined with the fragments of its person at that box (regions an occluder cut off from it
/// that have its `target`'s colours: `fragment`). So the filter is weighed against its
/// person's whole outline, not only the larger part.
fn with_fragments(
    i: usize,
    predicted: &PixelBox,
    regions: &[PixelBox],
    target: &ColourHistogram,
    bins: &mut FrameBins<'_>,
    p: &ParticleParams,
) -> PixelBox {
    regions
        .iter()
        .enumerate()
        .filter(|&(k, r)| k != i && is_fragment(r, predicted) && in_colours(r, target, bins, p))
        .fold(regions[i], |roi, (_, r)| union(&roi, r))
}

/// For a filter whose `predicted` box no region alone supports (a pillar hides its person's
/// middle): the parts beside the box that are narrower than it and in its `target`'s colours,
/// joined, if together they support the box and are at most [`PARTS_WIDTH`] times as wide
/// (two people either side of a lost filter are not its parts); with the index of the part
/// overlapping the box most (the first of equals), which stands for them.
fn parts_beside(
    predicted: &PixelBox,
    regions: &[PixelBox],
    target: &ColourHistogram,
    bins: &mut FrameBins<'_>,
    p: &ParticleParams,
) -> Option<(usize, PixelBox)> {
    let width = predicted.xmax - predicted.xmin;
    let parts: Vec<usize> = (0..regions.len())
        .filter(|&k| {
            let r = &regions[k];
            r.xmax - r.xmin < width && is_beside(r, predicted) && in_colours(r, target, bins, p)
        })
        .collect();
    let overlap = |k: usize| iou(&regions[k], predicted);
    let most = parts
        .iter()
        .copied()
        .reduce(|a, b| if overlap(b) > overlap(a) { b } else { a })?;
    let joined = parts.iter().map(|&k| regions[k]).reduce(|a, b| union(&a, &b))?;
    (supports(&joined, predicted, p.support_iou) && joined.xmax - joined.xmin <= PARTS_WIDTH * width)
        .then_some((most, joined))
}

impl MultiTracker {
    /// A tracker with no one tracked for a camera at `fps` frames per second (its waits are
    /// times: [`ParticleParams::destroy_frames_at`]), its randomness seeded with `seed`.
    ///
    /// # Errors
    /// A parameter out of range.
    pub fn new(params: ParticleParams, fps: f64, seed: u64) -> Result<MultiTracker, ParamsError> {
        params.validate()?;
        Ok(MultiTracker {
            destroy_frames: params.destroy_frames_at(fps),
            duplicate_frames: params.duplicate_frames_at(fps),
            params,
            rng: ChaCha8Rng::seed_from_u64(seed),
            image: BinImage::new(),
            frame_size: None,
            people: Vec::new(),
            candidates: Vec::new(),
            shared: Vec::new(),
            next_id: 0,
            counters: TrackerCounters::default(),
        })
    }

    pub fn params(&self) -> &ParticleParams {
        &self.params
    }

    pub fn counters(&self) -> TrackerCounters {
        self.counters
    }

    /// Ids of the people tracked now, oldest first.
    pub fn ids(&self) -> Vec<LocalId> {
        self.people.iter().map(|p| p.id).collect()
    }

    pub fn filter(&self, id: LocalId) -> Option<&ParticleFilter> {
        self.people.iter().find(|p| p.id == id).map(|p| &p.filter)
    }

    /// Drop every filter and candidate and forget the frame size (a source that changed
    /// resolution, a stream that came back). Ids keep counting, so none is reused.
    pub fn reset(&mut self) {
        self.people.clear();
        self.candidates.clear();
        self.shared.clear();
        self.frame_size = None;
    }

    fn check_frame(&self, frame: &Frame) -> Result<(), TrackerError> {
        frame.check()?;
        match self.frame_size {
            Some((w, h)) if (w, h) != (frame.width, frame.height) => Err(FrameError::Mismatch {
                got_w: frame.width,
                got_h: frame.height,
                want_w: w,
                want_h: h,
            }
            .into()),
            _ => Ok(()),
        }
    }

    /// Start a filter on `bbox` (continuous pixel coordinates) of `frame` by hand — the
    /// paper's §2 training by presenting the object. The frame must be the one the next
    /// [`MultiTracker::step`] continues from.
    ///
    /// # Errors
    /// A malformed frame or one of another size, a box without pixels in it, or `max-people`
    /// reached; nothing changes then.
    pub fn start(&mut self, frame: &Frame, bbox: &PixelBox) -> Result<LocalId, TrackerError> {
        self.check_frame(frame)?;
        if self.people.len() >= self.params.max_people {
            return Err(TrackerError::Full(self.people.len()));
        }
        let mut bins = self.image.bind(frame)?;
        let filter = ParticleFilter::new(&mut bins, bbox, &self.params, &mut self.rng)
            .ok_or(TrackerError::EmptyBox(*bbox))?;
        self.frame_size = Some((frame.width, frame.height));
        Ok(self.add(filter))
    }

    fn add(&mut self, filter: ParticleFilter) -> LocalId {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        self.people.push(Person {
            id,
            filter,
            unsupported: 0,
            region: None,
            foreground: None,
        });
        self.counters.started += 1;
        id
    }

    /// Track one frame.
    ///
    /// # Errors
    /// A malformed frame or one of another size than the first, a region box that is not
    /// finite, a foreground grid that does not fit the frame; nothing changes then.
    pub fn step(&mut self, input: &TrackerInput<'_>) -> Result<Vec<PersonEstimate>, TrackerError> {
        self.check_frame(input.frame)?;
        if let Some((index, d)) = input
            .regions
            .iter()
            .enumerate()
            .find(|(_, d)| !is_finite(&d.bbox) || d.bbox.xmin > d.bbox.xmax || d.bbox.ymin > d.bbox.ymax)
        {
            return Err(TrackerError::Region { index, bbox: d.bbox });
        }
        if let Some(fg) = &input.foreground
            && fg.grid.frame_width != input.frame.width as usize
        {
            return Err(TrackerError::MaskGrid {
                grid_width: fg.grid.frame_width,
                frame_width: input.frame.width,
            });
        }
        self.frame_size = Some((input.frame.width, input.frame.height));
        self.counters.frames += 1;
        let regions: Vec<PixelBox> = input.regions.iter().map(region_box).collect();
        let mut bins = self.image.bind(input.frame)?;
        let p = &self.params;
        for person in &mut self.people {
            let mean = person.filter.mean();
            let predicted = State {
                x: mean.x + mean.vx,
                y: mean.y + mean.vy,
                ..mean
            };
            let predicted = predicted.bbox();
            let target = person.filter.target();
            let roi = match best_region(&predicted, &regions, p.support_iou) {
                Some(i) => Some(with_fragments(i, &predicted, &regions, target, &mut bins, p)),
                None => parts_beside(&predicted, &regions, target, &mut bins, p).map(|(_, b)| b),
            };
            person.filter.step(&mut bins, roi.as_ref(), p, &mut self.rng);
            let b = person.filter.mean().bbox();
            // A box across an occluder, between its person's two parts, is supported by both
            // together (`parts_beside`).
            let target = person.filter.target();
            person.region = best_region(&b, &regions, p.support_iou)
                .or_else(|| parts_beside(&b, &regions, target, &mut bins, p).map(|(i, _)| i));
            person.unsupported = if person.region.is_some() {
                0
            } else {
                person.unsupported + 1
            };
            let ml_box = person.filter.ml_state().bbox();
            person.foreground = input.foreground.map(|f| f.fraction(&ml_box));
            let rate = adaptation_rate(p, person.filter.ml_similarity(), person.foreground);
            person.filter.adapt(rate);
        }
        let before = self.people.len();
        self.people.retain(|q| q.unsupported < self.destroy_frames);
        self.counters.destroyed += (before - self.people.len()) as u64;
        self.eliminate_duplicates();
        let births = self.candidates_ready(input.regions, &regions);
        if !births.is_empty() {
            // Re-bound after the filters ran: only the new boxes' tiles are looked up again.
            let mut bins = self.image.bind(input.frame)?;
            let (p, people, rng) = (&self.params, &self.people, &mut self.rng);
            let mut started: Vec<ParticleFilter> = Vec::new();
            for b in &births {
                let Some(target) = box_histogram(&mut bins, b, p) else {
                    continue;
                };
                let live = people.iter().map(|q| &q.filter).chain(&started);
                if is_fragment_of(
                    b,
                    &target,
                    live.map(|f| (f.mean().bbox(), f.target())),
                    p.hs_weight,
                ) {
                    self.counters.refused_fragments += 1;
                    continue;
                }
                if people.len() + started.len() >= p.max_people {
                    self.counters.refused_full += 1;
                    continue;
                }
                started.push(ParticleFilter::with_target(target, b, p, rng));
            }
            for filter in started {
                self.add(filter);
            }
        }
        Ok(self.estimates(input.with_samples))
    }

    /// Count how long each pair of filters with boxes alike (IoU at least `duplicate-iou`) or
    /// nested (the smaller at least [`NESTED_OVERLAP`] inside the larger, or stacked in its
    /// columns: [`STACKED_COLUMNS`]) has shared a region;
    /// of a pair that has for `duplicate-s` (in this camera's frames), eliminate the smaller of a nested
    /// pair (a filter on a fragment of the other's person, which a region split off for a few
    /// frames), else the younger — or the older, if its colours matched clearly worse over
    /// those frames (it drifted onto the other's person). A pair that splits starts over.
    fn eliminate_duplicates(&mut self) {
        let p = &self.params;
        let mut shared = Vec::new();
        // `people` is in id order: `a` is the older of each pair.
        for (i, a) in self.people.iter().enumerate() {
            for b in &self.people[i + 1..] {
                let same = a.region.is_some() && a.region == b.region;
                let (ab, bb) = (a.filter.mean().bbox(), b.filter.mean().bbox());
                let alike = iou(&ab, &bb) >= p.duplicate_iou;
                // A box (nearly) inside a larger one, or above or below it in its columns: the
                // smaller lies on a part of the other's person (a fragment the region split off
                // for a few frames).
                let nested = !alike
                    && (overlap_of_smaller(&ab, &bb) >= NESTED_OVERLAP
                        || column_overlap(&ab, &bb) >= STACKED_COLUMNS);
                if !same || !(alike || nested) {
                    continue;
                }
                let (frames, lead) = self
                    .shared
                    .iter()
                    .find(|s| (s.older, s.younger) == (a.id, b.id))
                    .map_or((0, 0.0), |s| (s.frames, s.older_lead));
                let nested = nested.then(|| if area(&ab) < area(&bb) { a.id } else { b.id });
                shared.push(Shared {
                    older: a.id,
                    younger: b.id,
                    frames: frames + 1,
                    older_lead: lead + a.filter.ml_similarity() - b.filter.ml_similarity(),
                    nested,
                });
            }
        }
        let mut doomed: Vec<LocalId> = Vec::new();
        for s in shared.iter().filter(|s| s.frames >= self.duplicate_frames) {
            if doomed.contains(&s.older) || doomed.contains(&s.younger) {
                continue;
            }
            let drifted = s.older_lead / (s.frames as f32) < -DRIFTED_MARGIN;
            doomed.push(match s.nested {
                Some(smaller) => smaller,
                None if drifted => s.older,
                None => s.younger,
            });
        }
        shared.retain(|s| !doomed.contains(&s.younger) && !doomed.contains(&s.older));
        self.shared = shared;
        let before = self.people.len();
        self.people.retain(|q| !doomed.contains(&q.id));
        self.counters.duplicates_eliminated += (before - self.people.len()) as u64;
    }

    /// Regions no filter explains become (or advance) candidates; returns the boxes of those
    /// seen for `init-frames` consecutive frames, largest first: each starts a filter unless it
    /// is a fragment of a tracked person, up to `max-people`.
    fn candidates_ready(&mut self, detections: &[Detection], regions: &[PixelBox]) -> Vec<PixelBox> {
        let p = &self.params;
        let mut next = Vec::new();
        for (r, d) in regions.iter().zip(detections) {
            let explained = self
                .people
                .iter()
                .any(|q| supports(r, &q.filter.mean().bbox(), p.support_iou));
            if explained || d.area < p.min_init_area || area(r) <= 0.0 {
                continue;
            }
            let seen = self
                .candidates
                .iter()
                .filter(|c| iou(&c.bbox, r) >= CANDIDATE_IOU)
                .map(|c| c.seen)
                .max()
                .unwrap_or(0);
            next.push(Candidate {
                bbox: *r,
                seen: seen + 1,
            });
        }
        let (ready, waiting): (Vec<Candidate>, Vec<Candidate>) =
            next.into_iter().partition(|c| c.seen >= p.init_frames);
        self.candidates = waiting;
        // Largest first, so that of a person and a strip of them both ready this frame the
        // person starts a filter and the strip is its fragment; `step` applies `max-people`
        // after refusing fragments.
        let mut ready: Vec<PixelBox> = ready.into_iter().map(|c| c.bbox).collect();
        ready.sort_by(|a, b| area(b).total_cmp(&area(a)));
        ready
    }

    fn estimates(&self, with_samples: bool) -> Vec<PersonEstimate> {
        self.people
            .iter()
            .map(|q| {
                let f = &q.filter;
                PersonEstimate {
                    id: q.id,
                    mean: f.mean(),
                    ml: f.ml_state(),
                    ml_confidence: f.ml_likelihood(),
                    ml_similarity: f.ml_similarity(),
                    peak_weight: f.peak_weight(),
                    foreground: q.foreground,
                    bbox: f.mean().bbox(),
                    box_covariance: f.box_covariance(),
                    histogram: f.target().clone(),
                    samples: if with_samples {
                        f.samples().collect()
                    } else {
                        Vec::new()
                    },
                    frames_tracked: f.iterations(),
                    unsupported_frames: q.unsupported,
                    region: q.region,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
