//! Ghosts of a background model: regions where the *model* holds an object that is no longer
//! there (the model was started, or restarted after the camera slept, while a target stood in
//! view). Until the model absorbs them (τ frames), they are segmented like any moving object,
//! and a head tracks them: in the default scenario the cameras woken along the robot's path left
//! ghosts at its start and its corners whose tracks drifted as the model absorbed them from the
//! edges (0.15–0.25 m/s), were confirmed and given global ids of their own.
//!
//! The test is the region's edge. Across the border of a real object the *frame* changes (object
//! inside, background outside) while the model is the same background on both sides; across a
//! ghost's border the frame is background on both sides while the *model* changes (the old
//! object inside). So per border pair — in each scanned row, the region's outermost moving grid
//! pixel on either side and its neighbour that is not moving — the L1 RGB contrast is summed
//! once in the frame and once in the model, and a region whose model contrast is at least
//! [`GHOST_RATIO`] times its frame contrast (and at least [`MIN_GHOST_EDGE`] per pair) is a
//! ghost. (Edge-based ghost tests are the usual remedy of background subtraction; this one
//! needs no gradient image, only the pixels on the border.)
//!
//! Only the outline counts. Inside a ghost on a textured floor, the tiles that match the old
//! object are holes in its mask, and across a hole's sides the *frame* changes (light tile |
//! dark tile) while the model does not: counted, they made ghosts of a uniformly coloured
//! person on the hall's checkered floor look real, and their filters stood in them reporting
//! phantoms (hall seeds 1–16: false positives halved when only the outline was read). A region
//! holding a target beside the ghost it just left mixes the two on its outline and stays a
//! detection; a target still wholly inside its ghost (walking straight away from the camera)
//! is judged by the ghost's outline and joins the model with it. Limits: rows only (top and
//! bottom borders are not sampled), every second row, and a region needs [`MIN_PAIRS`] pairs
//! (about five grid rows) to be judged; a box at the image's side has pairs on one side only.
//! One frame's verdict decides: a target dressed like the floor in front of a strong edge of
//! the background could be taken for a ghost and join the model.

use crate::region::Grid;
use proto::msg::PixelBox;
use proto::sensor::Frame;

/// How many times its frame contrast a region's model contrast must be for a ghost. A real
/// object's model contrast is the background's own texture, a ghost's frame contrast is the
/// frame's noise: either way the other sum is several times smaller.
pub const GHOST_RATIO: u64 = 2;
/// Mean model contrast per border pair (L1 RGB levels) below which a region is never a ghost:
/// where the old object looked like the background, the model's border says nothing.
pub const MIN_GHOST_EDGE: u64 = 24;
/// Border pairs a region needs before it is judged at all.
pub const MIN_PAIRS: u64 = 6;
/// Every how many grid rows of a box are scanned: the sums are a sample of the border, and a
/// person close to a camera is a box of a third of the frame.
pub const ROW_STEP: usize = 2;

/// L1 RGB contrast summed over a region's border pairs, in the frame and in the model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BorderContrast {
    pub frame: u64,
    pub model: u64,
    pub pairs: u64,
}

impl BorderContrast {
    /// Whether the border says the model holds an object the frame does not.
    pub fn is_ghost(&self) -> bool {
        self.pairs >= MIN_PAIRS
            && self.model >= MIN_GHOST_EDGE * self.pairs
            && self.model >= GHOST_RATIO * self.frame
    }
}

/// The grid cells of a detection's box (frame pixels → grid, clamped to the grid).
pub fn grid_box(grid: &Grid, b: &PixelBox) -> (usize, usize, usize, usize) {
    let s = grid.step as f32;
    let clamp = |v: f32, n: usize| ((v / s).max(0.0) as usize).min(n.saturating_sub(1));
    (
        clamp(b.xmin, grid.width),
        clamp(b.ymin, grid.height),
        clamp(b.xmax, grid.width),
        clamp(b.ymax, grid.height),
    )
}

/// The border contrast of the moving pixels (`mask` ≠ 0) in the grid box `(x0, y0, x1, y1)`:
/// along every [`ROW_STEP`]-th row (one pixel beyond the box on either side), the first pair
/// of horizontal neighbours going from still to moving and the last going from moving to
/// still. `background` is the model, RGB per grid pixel.
///
/// Rows only: a person's border is mostly its two sides, and a row is scanned as one slice
/// (the pairs found first, colours read only at them). Visiting every moving pixel and its
/// four neighbours cost 40–90% of the segmentation itself (`ocelli bench camera`, 640×480).
pub fn border_contrast(
    grid: &Grid,
    mask: &[u8],
    frame: &Frame,
    background: &[u8],
    (x0, y0, x1, y1): (usize, usize, usize, usize),
) -> BorderContrast {
    let (w, h) = (grid.width, grid.height);
    let mut c = BorderContrast::default();
    if w < 2 || h == 0 {
        return c;
    }
    let l1 = |a: [u8; 3], b: [u8; 3]| (0..3).map(|c| u64::from(a[c].abs_diff(b[c]))).sum::<u64>();
    let model = |k: usize| [background[k * 3], background[k * 3 + 1], background[k * 3 + 2]];
    let (a, b) = (x0.saturating_sub(1), (x1 + 1).min(w - 1));
    for y in (y0..=y1.min(h - 1)).step_by(ROW_STEP) {
        let row = &mask[y * w..(y + 1) * w];
        let mut pairs = row[a..b]
            .iter()
            .zip(&row[a + 1..=b])
            .enumerate()
            .filter(|(_, (l, r))| (**l == 0) != (**r == 0))
            .map(|(i, _)| a + i);
        // The outline's left side is a still→moving change, its right side moving→still; a
        // region at the image's edge has no such change on that side, and the first change
        // found there is a hole's.
        let first = pairs.next();
        let last = pairs.next_back().or(first);
        let left = first.filter(|&x| row[x] == 0);
        let right = last.filter(|&x| row[x] != 0);
        for x in left.into_iter().chain(right) {
            let (inside, outside) = if row[x] != 0 { (x, x + 1) } else { (x + 1, x) };
            c.frame += l1(grid.rgb(frame, inside, y), grid.rgb(frame, outside, y));
            c.model += l1(model(y * w + inside), model(y * w + outside));
            c.pairs += 1;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::ClusterTime;
    use std::ops::Range;

    /// A 40×30 frame of `floor` with a 10×10 square of `inside` at (15, 10).
    fn picture(floor: [u8; 3], inside: [u8; 3]) -> Frame {
        let mut f = Frame::new(40, 30, ClusterTime::ZERO);
        for y in 0..30 {
            for x in 0..40 {
                let rgb = if (15..25).contains(&x) && (10..20).contains(&y) {
                    inside
                } else {
                    floor
                };
                f.data[(y * 40 + x) * 3..(y * 40 + x) * 3 + 3].copy_from_slice(&rgb);
            }
        }
        f
    }

    fn square_mask() -> Vec<u8> {
        (0..30 * 40)
            .map(|k| u8::from((15..25).contains(&(k % 40)) && (10..20).contains(&(k / 40))))
            .collect()
    }

    #[test]
    fn an_object_in_the_frame_is_no_ghost_and_its_trace_in_the_model_is() {
        let grid = Grid::new(40, 30, 1);
        let (floor, red) = ([90, 100, 80], [200, 30, 40]);
        let empty = picture(floor, floor).data;
        let with_object = picture(floor, red);
        let mask = square_mask();
        let bx = (15, 10, 24, 19);
        // The object stands where the model has floor: the frame's border changes.
        let real = border_contrast(&grid, &mask, &with_object, &empty, bx);
        assert_eq!(real.pairs, 10, "5 of the 10 rows, each crossing two sides");
        assert_eq!(real.model, 0);
        assert!(real.frame > 0 && !real.is_ghost(), "{real:?}");
        // The model still holds the object, the frame shows floor: a ghost.
        let ghost = border_contrast(&grid, &mask, &picture(floor, floor), &with_object.data, bx);
        assert_eq!(ghost.frame, 0);
        assert!(ghost.is_ghost(), "{ghost:?}");
    }

    /// A 40×30 light floor with a dark tile over the columns `tile`, and a model that holds a
    /// dark object that has left over `cols` × `rows`. Where the dark tile lies under it,
    /// frame and model agree, so the ghost's mask has a hole there, and across the hole's
    /// sides the *frame* changes (light | dark) while the model does not. Returns the frame,
    /// the model and the mask.
    fn holed_ghost(cols: Range<usize>, rows: Range<usize>, tile: Range<usize>) -> (Frame, Vec<u8>, Vec<u8>) {
        let (light, dark, old) = ([150, 150, 150], [60, 60, 60], [62, 58, 60]);
        let floor = |x: usize| if tile.contains(&x) { dark } else { light };
        let mut frame = Frame::new(40, 30, ClusterTime::ZERO);
        let mut model = vec![0u8; 40 * 30 * 3];
        let mut mask = vec![0u8; 40 * 30];
        for y in 0..30 {
            for x in 0..40 {
                let k = y * 40 + x;
                let in_object = cols.contains(&x) && rows.contains(&y);
                frame.data[k * 3..k * 3 + 3].copy_from_slice(&floor(x));
                model[k * 3..k * 3 + 3].copy_from_slice(&if in_object { old } else { floor(x) });
                mask[k] = u8::from(in_object && floor(x) == light);
            }
        }
        (frame, model, mask)
    }

    #[test]
    fn a_ghost_with_holes_where_the_floor_matches_the_old_object_is_a_ghost() {
        // The hole's sides, counted, would make the ghost look like a real object. Only the
        // outline (columns 14|15 and 24|25) is read.
        let (frame, model, mask) = holed_ghost(15..25, 10..20, 18..22);
        let c = border_contrast(&Grid::new(40, 30, 1), &mask, &frame, &model, (15, 10, 24, 19));
        assert_eq!(c.pairs, 10, "the outline only: two pairs in each of 5 rows");
        assert_eq!(c.frame, 0);
        assert!(c.is_ghost(), "{c:?}");
    }

    #[test]
    fn a_holed_ghost_at_the_images_edge_is_judged_by_its_one_outline_side() {
        // At the image's left edge: the row's first change is the hole's left side, which is
        // no outline.
        let (frame, model, mask) = holed_ghost(0..10, 5..25, 3..7);
        let c = border_contrast(&Grid::new(40, 30, 1), &mask, &frame, &model, (0, 5, 9, 24));
        assert_eq!(c.pairs, 10, "the right side only, in 10 rows");
        assert_eq!(c.frame, 0);
        assert!(c.is_ghost(), "{c:?}");
    }

    #[test]
    fn a_model_border_like_the_background_or_a_mixed_region_is_no_ghost() {
        let grid = Grid::new(40, 30, 1);
        let floor = [90, 100, 80];
        let mask = square_mask();
        let bx = (15, 10, 24, 19);
        // The old object looked almost like the floor: too faint to say.
        let faint = picture(floor, [95, 104, 86]);
        let c = border_contrast(&grid, &mask, &picture(floor, floor), &faint.data, bx);
        assert!(!c.is_ghost(), "{c:?}");
        // A target standing in its own ghost: both borders change, neither twice the other.
        let c = border_contrast(
            &grid,
            &mask,
            &picture(floor, [20, 20, 200]),
            &picture(floor, [200, 30, 40]).data,
            bx,
        );
        assert!(c.frame > 0 && c.model > 0 && !c.is_ghost(), "{c:?}");
        // Nothing moving in the box: nothing to judge.
        let c = border_contrast(&grid, &vec![0; 1200], &faint, &faint.data, bx);
        assert_eq!(c, BorderContrast::default());
        assert!(!c.is_ghost());
    }

    #[test]
    fn the_box_is_mapped_to_the_grid_and_clamped() {
        let grid = Grid::new(40, 30, 2);
        let b = PixelBox {
            xmin: 4.0,
            ymin: 6.0,
            xmax: 11.0,
            ymax: 99.0,
        };
        assert_eq!(grid_box(&grid, &b), (2, 3, 5, 14));
    }
}
