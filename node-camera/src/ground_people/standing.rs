//! People standing still kept in the foreground (`[method.particle] hold-still-s`; ours, not
//! paper 004's).
//!
//! Paper 004's background model takes whatever stops into the background after its history and
//! τ (about 2.5 s at 5 fps): a person who stops fades from the foreground, and a camera that
//! reports only the filters a region supports loses them (the crowd's yellow person, who
//! stands 10 s of every 30, was a fifth of its misses; docs/multi-target.md). So while a filter
//! that walked before has stood still, supported by a region, for at least
//! [`STAND_BEFORE_HOLD_NS`] and less than `hold-still-s`, the background model keeps its box's
//! moving pixels out of the background — only those with one of the person's colours
//! ([`HOLD_MIN_BIN_SHARE`]), so a filter stopped on floor or on a ghost keeps less of the floor
//! or the ghost in the foreground (not none: a person's histogram holds some floor). A filter
//! that never moved (one on a ghost, or on someone standing since the model started) is never
//! held, and a person standing longer than `hold-still-s` is taken in as before, so a parked
//! object is not foreground for ever.

use crate::adaptive_background::Hold;
use crate::tracker::histogram::{ColourHistogram, HS_BINS};
use crate::tracker::manager::{LocalId, PersonEstimate};
use proto::ClusterTime;
use std::collections::BTreeMap;

/// How long a filter must have stood before it is held: two frames at 5 fps. A walker's box
/// stands still for a frame now and then; held at once, the trail they leave would be kept.
pub const STAND_BEFORE_HOLD_NS: i64 = 400_000_000;
/// The share of a person's hue–saturation histogram a bin needs for its colour to be held.
pub const HOLD_MIN_BIN_SHARE: f32 = 0.02;
/// A box centre that moved more than this share of the box's width (or 2 pixels) from where it
/// stood is walking.
const STILL_SHARE_OF_WIDTH: f32 = 0.25;

const _: () = assert!(HS_BINS <= u128::BITS as usize);

/// Which filters stand still, since when, and the boxes to hold at the next frame.
#[derive(Clone, Debug, Default)]
pub struct Standing {
    /// `hold-still-s`, ns; 0: nothing is held.
    hold_ns: i64,
    still: BTreeMap<LocalId, Still>,
    held: Vec<Hold>,
}

/// Where a filter's box centre (pixels) has stood since `since`; `walked` once it moved from
/// where it was first seen.
#[derive(Clone, Copy, Debug)]
struct Still {
    centre: [f32; 2],
    since: ClusterTime,
    walked: bool,
}

impl Standing {
    pub fn new(hold_still_s: f64) -> Standing {
        Standing {
            hold_ns: (hold_still_s * 1e9).round() as i64,
            ..Standing::default()
        }
    }

    /// Follow the filters of the frame captured at `captured` and choose whom to hold.
    pub fn update(&mut self, estimates: &[PersonEstimate], captured: ClusterTime) {
        self.held.clear();
        if self.hold_ns <= 0 {
            return;
        }
        self.still.retain(|id, _| estimates.iter().any(|e| e.id == *id));
        for e in estimates.iter().filter(|e| e.unsupported_frames == 0) {
            let centre = e.mean.centre();
            let moved = (STILL_SHARE_OF_WIDTH * e.mean.w).max(2.0);
            let still = self.still.entry(e.id).or_insert(Still {
                centre,
                since: captured,
                walked: false,
            });
            if (still.centre[0] - centre[0]).hypot(still.centre[1] - centre[1]) > moved {
                *still = Still {
                    centre,
                    since: captured,
                    walked: true,
                };
            }
            let stood = captured - still.since;
            if still.walked && (STAND_BEFORE_HOLD_NS..self.hold_ns).contains(&stood) {
                self.held.push(Hold {
                    bbox: e.bbox,
                    hs_bins: person_colours(&e.histogram),
                });
            }
        }
    }

    /// The boxes the background model keeps out of the background at the next frame.
    pub fn held(&self) -> &[Hold] {
        &self.held
    }

    pub fn clear(&mut self) {
        self.still.clear();
        self.held.clear();
    }
}

/// The hue–saturation bins holding at least [`HOLD_MIN_BIN_SHARE`] of the histogram, as bits.
fn person_colours(h: &ColourHistogram) -> u128 {
    h.hs()
        .iter()
        .enumerate()
        .filter(|(_, w)| **w >= HOLD_MIN_BIN_SHARE)
        .fold(0, |bits, (k, _)| bits | 1 << k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::msg::PixelBox;

    fn at(id: u32, x: f32, supported: bool) -> PersonEstimate {
        let bbox = PixelBox {
            xmin: x,
            ymin: 20.0,
            xmax: x + 20.0,
            ymax: 80.0,
        };
        PersonEstimate::at_box(id, bbox, supported.then_some(0))
    }

    fn ms(t: i64) -> ClusterTime {
        ClusterTime::from_millis(t)
    }

    /// Whether the one filter is held at each 200 ms frame of `xs` (its box's left edge and
    /// whether a region supports it), holding for up to 2 s.
    fn held_over(xs: &[(f32, bool)]) -> Vec<bool> {
        let mut s = Standing::new(2.0);
        xs.iter()
            .enumerate()
            .map(|(k, &(x, supported))| {
                s.update(&[at(1, x, supported)], ms(200 * k as i64));
                !s.held().is_empty()
            })
            .collect()
    }

    #[test]
    fn a_person_who_walked_and_stopped_is_held_from_0_4_s_until_hold_still_s() {
        // Walks two frames, then stands from 0.4 s on.
        let mut xs = vec![(10.0, true), (20.0, true), (30.0, true)];
        xs.extend(std::iter::repeat_n((30.0, true), 12));
        let held = held_over(&xs);
        // Stood since frame 2 (0.4 s): held at 0.8 s (frame 4) until it stood 2 s (frame 12).
        let expected: Vec<bool> = (0..held.len()).map(|k| (4..12).contains(&k)).collect();
        assert_eq!(held, expected);
    }

    #[test]
    fn a_filter_that_never_moved_or_that_no_region_supports_is_not_held() {
        assert!(held_over(&[(30.0, true); 10]).iter().all(|h| !h), "never walked");
        let mut xs = vec![(10.0, true), (30.0, true)];
        xs.extend([(30.0, false); 8]);
        assert!(held_over(&xs).iter().all(|h| !h), "unsupported");
        let mut off = Standing::new(0.0);
        for (k, x) in [10.0, 30.0, 30.0, 30.0, 30.0, 30.0].into_iter().enumerate() {
            off.update(&[at(1, x, true)], ms(200 * k as i64));
            assert!(off.held().is_empty(), "hold-still-s = 0 holds no one");
        }
    }

    #[test]
    fn only_the_persons_own_colours_are_held() {
        let mut s = Standing::new(2.0);
        for (k, x) in [10.0, 30.0, 30.0, 30.0].into_iter().enumerate() {
            s.update(&[at(1, x, true)], ms(200 * k as i64));
        }
        // `at_box`'s histogram is all in bin 0.
        assert_eq!(s.held()[0].hs_bins, 1);
        assert_eq!(s.held()[0].bbox.xmin, 30.0);
    }
}
