//! Fragments of a tracked person: a foreground region that is a thin strip beside a filter's
//! box, or a small piece inside it, in that filter's colours, is a part of its person that
//! something in front (a pillar, a post, a door frame) or the background model cut off from
//! the rest, not a new person. Segmentation alone gives such a part an id of its own; a filter
//! started on it would report the same person twice, a few decimetres apart, for as long as
//! the occluder splits them (paper 004's partial-occlusion case, `ocelli experiment paper004`).
//! So a fragment starts no filter, and it joins its person's region of interest
//! (`manager`).
//!
//! Ours, not the paper's: §3.2.1 starts a filter on every region no filter explains.

use crate::tracker::boxes::{area, overlap_of_smaller};
use crate::tracker::histogram::ColourHistogram;
use proto::msg::PixelBox;

/// A strip is under this share of its neighbour's aspect (width over height): the strip a
/// pillar leaves of a person is 0.05–0.13 as wide as tall while they stand mostly behind it,
/// the person about 0.3; someone standing further away beside them keeps a person's shape.
/// The neighbour is the filter's box, so a box grown wide admits wider strips.
pub const STRIP_ASPECT: f32 = 0.5;
/// A strip is at least this share of its neighbour's height (it stands beside them, whole
/// height; someone further away is smaller).
pub const STRIP_HEIGHT: f32 = 0.6;
/// Share of the strip's rows its neighbour's box must span (beside, not above).
pub const STRIP_ROWS: f32 = 0.5;
/// A piece is at least this share inside its neighbour's box ...
pub const PIECE_INSIDE: f32 = 0.9;
/// ... and under this share of its area.
pub const PIECE_AREA: f32 = 0.5;
/// Blended Bhattacharyya similarity of a fragment's colours to its person's target at least.
/// Strips of the same person measured 0.78–0.99; people of different colours are far below.
pub const FRAGMENT_SIMILARITY: f32 = 0.7;

/// Whether `region` is, by shape and place, a fragment of the person whose filter's box is
/// `neighbour`: a strip beside it (much thinner for its height than they are, nearly as tall,
/// sharing [`STRIP_ROWS`] of its rows, no further sideways than they are wide) or a small
/// piece inside it.
pub fn is_fragment(region: &PixelBox, neighbour: &PixelBox) -> bool {
    let (w, h) = (region.xmax - region.xmin, region.ymax - region.ymin);
    let (width, height) = (neighbour.xmax - neighbour.xmin, neighbour.ymax - neighbour.ymin);
    if !(w > 0.0 && h > 0.0 && width > 0.0 && height > 0.0) {
        return false;
    }
    if area(region) < PIECE_AREA * area(neighbour) && overlap_of_smaller(region, neighbour) >= PIECE_INSIDE {
        return true;
    }
    let thin = w / h < STRIP_ASPECT * width / height && h >= STRIP_HEIGHT * height;
    thin && is_beside(region, neighbour)
}

/// Whether `region` stands beside `neighbour`: sharing [`STRIP_ROWS`] of its rows with it and
/// no further from it sideways than it is wide (overlapping counts).
pub fn is_beside(region: &PixelBox, neighbour: &PixelBox) -> bool {
    let h = region.ymax - region.ymin;
    let rows = (region.ymax.min(neighbour.ymax) - region.ymin.max(neighbour.ymin)).max(0.0);
    let gap = (region.xmin - neighbour.xmax)
        .max(neighbour.xmin - region.xmax)
        .max(0.0);
    h > 0.0 && rows >= STRIP_ROWS * h && gap <= neighbour.xmax - neighbour.xmin
}

/// Whether a region's `colours` are a filter's `target`'s: their blended similarity at least
/// [`FRAGMENT_SIMILARITY`].
pub fn same_colours(colours: &ColourHistogram, target: &ColourHistogram, hs_weight: f32) -> bool {
    colours.similarity(target, hs_weight) >= FRAGMENT_SIMILARITY
}

/// Whether a region with box `region` and colours `colours` is a fragment of one of the
/// `filters` (each its box and target): [`is_fragment`] of it, in its colours.
pub fn is_fragment_of<'a>(
    region: &PixelBox,
    colours: &ColourHistogram,
    filters: impl IntoIterator<Item = (PixelBox, &'a ColourHistogram)>,
    hs_weight: f32,
) -> bool {
    filters
        .into_iter()
        .any(|(b, target)| is_fragment(region, &b) && same_colours(colours, target, hs_weight))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::boxes::from_sides as b;

    #[test]
    fn a_strip_beside_a_person_or_a_piece_inside_is_a_fragment_and_a_person_beside_is_not() {
        let person = b(100.0, 20.0, 150.0, 170.0);
        // The strip a pillar leaves on the right, 7 px wide, and one touching the box.
        assert!(is_fragment(&b(168.0, 25.0, 175.0, 160.0), &person));
        assert!(is_fragment(&b(150.0, 25.0, 160.0, 160.0), &person));
        // A piece of them inside their box (an arm the background model cut off).
        assert!(is_fragment(&b(140.0, 70.0, 150.0, 90.0), &person));
        // Someone side on beside them, and someone further away: a person's shape.
        assert!(!is_fragment(&b(160.0, 25.0, 185.0, 165.0), &person));
        assert!(!is_fragment(&b(155.0, 40.0, 175.0, 120.0), &person));
        // Further sideways than the person is wide.
        assert!(!is_fragment(&b(201.0, 25.0, 208.0, 160.0), &person));
        // Above them (a lamp, a raised hand): under half its rows beside the person.
        assert!(!is_fragment(&b(160.0, -60.0, 167.0, 40.0), &person));
        // Degenerate boxes are nothing's fragments.
        assert!(!is_fragment(&b(160.0, 25.0, 167.0, 25.0), &person));
        assert!(!is_fragment(
            &b(160.0, 25.0, 167.0, 160.0),
            &b(100.0, 20.0, 100.0, 170.0)
        ));
    }
}
