//! A region matched to the previous frame's: its previous point (paper 000 eq. 13) and whether
//! it moved, which decides if a region no prior gated may start a track.

use crate::measure::Measured;

/// Pixels a motion-segmented region's centre must move between consecutive frames to be
/// offered for a new track (a region no prior gated). Paper 004's model only sees what moves,
/// so a region that stands still is where the model's background is wrong: the ghost a target
/// leaves where it stood when the model was (re)started. Two woken cameras' ghosts
/// triangulated into false tracks (Table I, pixel level: with the head's own guards, ghost
/// global ids in 7 of the proposed method's 40 runs, 2 with this).
///
/// Not caught: a ghost while the target is still uncovering it (it grows, so its centre
/// moves), nor, probably, while the model absorbs it (pixels go in the order they were
/// uncovered, so it shrinks along the target's path). Also held back: a target whose region
/// moves less than this (e.g. one walking straight at the camera) or more than its own size
/// (no region of the previous frame within reach); another camera or the next frame offers
/// it. Regions that gate to a prior are always used.
pub const STILL_PX: f32 = 1.0;

/// Which of a frame's regions that no prior gated are offered for new tracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Offer {
    /// Every one: still regions may be targets (colour segmentation sees targets that stand
    /// still; in centralized fusion the head associates every measurement itself; projected
    /// detections have no ghosts).
    All,
    /// Those that moved at least [`STILL_PX`] since the previous frame.
    Moving,
    /// None: motion-segmented, and no previous frame to tell what moved (the first, or one
    /// from before the model restarted).
    Nothing,
}

impl Offer {
    /// Whether `m` is offered, against the previous frame's regions.
    pub fn offers(self, previous: &[Measured], m: &Measured) -> bool {
        match self {
            Offer::All => true,
            Offer::Moving => nearest(previous, m).is_some_and(|(shift, _)| shift >= STILL_PX),
            Offer::Nothing => false,
        }
    }
}

/// The previous frame's point nearest to `m` in the image, if within a box width.
pub fn previous_point(previous: &[Measured], m: &Measured) -> Option<nalgebra::Vector2<f64>> {
    nearest(previous, m).map(|(_, p)| p.point)
}

/// The previous frame's region nearest to `m` within `m`'s extent, with how far (pixels) the
/// centre moved from it.
fn nearest<'a>(previous: &'a [Measured], m: &Measured) -> Option<(f32, &'a Measured)> {
    let b = m.detection.bbox;
    let reach = (b.xmax - b.xmin).max(b.ymax - b.ymin);
    let c = m.detection.centre;
    previous
        .iter()
        .map(|p| {
            let pc = p.detection.centre;
            (((pc[0] - c[0]).powi(2) + (pc[1] - c[1]).powi(2)).sqrt(), p)
        })
        .filter(|(d, _)| *d <= reach)
        .min_by(|a, b| a.0.total_cmp(&b.0))
}
