//! The colours a background model held long enough to trust: its *settled* colours.
//!
//! The paper's model takes into the background whatever stays put for τ frames: a person
//! standing, a person walking straight away from the camera (their inside keeps its colour),
//! a person in view when the model restarts, a person the ghost test took for a ghost. When
//! they move on, the place they stood shows up as a ghost for τ more frames, and a particle
//! filter started on it stands there reporting someone who is not (a hall camera's filter stood
//! 2.6 s where a person had entered its view at the image's edge, and the head's track
//! followed it back while the person walked on).
//!
//! Per pixel this keeps the last colour the model had held for `settled_frames` before it
//! changed, and when. A moving pixel whose model colour is younger than that and whose frame
//! shows the settled colour again is background that someone had covered: the model takes it
//! at once. The model's refreshes of a still pixel (it retakes every pixel that stays
//! consistent for τ frames) are not changes: only a new colour farther than the moving
//! threshold's offset from the old is.

/// Per-pixel settled colours of one background model.
#[derive(Debug, Default)]
pub(super) struct Settled {
    /// Frames a colour must have held to settle (0: nothing ever settles).
    frames: u32,
    /// L1 RGB distance above which a new model colour is a change, not a refresh.
    change: u32,
    /// The frame at which each pixel's model colour last changed.
    changed_at: Vec<u32>,
    /// RGB per pixel; meaningful where `known` is set.
    colour: Vec<u8>,
    known: Vec<bool>,
}

#[inline]
fn l1(a: &[u8], b: &[u8]) -> u32 {
    u32::from(a[0].abs_diff(b[0])) + u32::from(a[1].abs_diff(b[1])) + u32::from(a[2].abs_diff(b[2]))
}

impl Settled {
    pub(super) fn new(frames: u32, change: u32) -> Settled {
        Settled {
            frames,
            change,
            ..Settled::default()
        }
    }

    pub(super) fn enabled(&self) -> bool {
        self.frames > 0
    }

    /// Size for `n` pixels, nothing settled yet: the first frame is not trusted (people
    /// stand in it).
    pub(super) fn allocate(&mut self, n: usize) {
        self.changed_at = vec![0; n];
        self.colour = vec![0; n * 3];
        self.known = vec![false; n];
    }

    /// Pixel `k`'s model colour `old` becomes `new` at frame `now`.
    #[inline]
    pub(super) fn replace(&mut self, k: usize, old: &[u8], new: &[u8], now: u32) {
        if !self.enabled() || l1(old, new) <= self.change {
            return;
        }
        if now.wrapping_sub(self.changed_at[k]) >= self.frames {
            self.colour[k * 3..k * 3 + 3].copy_from_slice(old);
            self.known[k] = true;
        }
        self.changed_at[k] = now;
    }

    /// Whether pixel `k` has a settled colour and the model's colour there is younger: the
    /// cheap half of the question whether a moving pixel is background again, asked first
    /// (most moving pixels have none).
    pub(super) fn may_reveal(&self, k: usize, now: u32) -> bool {
        self.known[k] && now.wrapping_sub(self.changed_at[k]) < self.frames
    }

    /// Whether `rgb` is pixel `k`'s settled colour within `threshold`: the other half, for a
    /// pixel [`Settled::may_reveal`] let through.
    pub(super) fn shows_settled(&self, k: usize, rgb: &[u8], threshold: u32) -> bool {
        l1(rgb, &self.colour[k * 3..k * 3 + 3]) <= threshold
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both halves: whether pixel `k`, moving at frame `now` with colour `rgb`, shows its
    /// settled colour (within `threshold`) while the model's colour there is younger.
    fn reveals(s: &Settled, k: usize, rgb: &[u8], now: u32, threshold: u32) -> bool {
        s.may_reveal(k, now) && s.shows_settled(k, rgb, threshold)
    }

    const FLOOR: [u8; 3] = [120, 120, 110];
    const PERSON: [u8; 3] = [200, 40, 60];

    #[test]
    fn a_colour_held_long_enough_settles_when_it_changes() {
        let mut s = Settled::new(10, 24);
        s.allocate(1);
        // Held 4 frames only: not settled.
        s.replace(0, &FLOOR, &PERSON, 4);
        assert!(!reveals(&s, 0, &FLOOR, 5, 30));
        // The person's colour held 3 frames, then the floor again: still nothing settled.
        s.replace(0, &PERSON, &FLOOR, 7);
        // The floor held 20 frames, then someone is taken in: the floor settles.
        s.replace(0, &FLOOR, &PERSON, 27);
        assert!(reveals(&s, 0, &FLOOR, 28, 30));
        assert!(
            !reveals(&s, 0, &PERSON, 28, 30),
            "another colour is not the settled one"
        );
        // Once the model's colour is as old as settled, it is the model's word again.
        assert!(!reveals(&s, 0, &FLOOR, 37, 30));
    }

    #[test]
    fn a_refresh_is_not_a_change() {
        let mut s = Settled::new(10, 24);
        s.allocate(1);
        let refreshed = [125, 118, 112];
        for now in (8..100).step_by(8) {
            s.replace(0, &FLOOR, &refreshed, now);
        }
        // The floor has held since frame 0 through its refreshes: it settles at the change.
        s.replace(0, &FLOOR, &PERSON, 100);
        assert!(reveals(&s, 0, &FLOOR, 101, 30));
    }

    #[test]
    fn disabled_settles_nothing() {
        let mut s = Settled::new(0, 24);
        s.allocate(1);
        s.replace(0, &FLOOR, &PERSON, 100);
        assert!(!reveals(&s, 0, &FLOOR, 101, 30));
    }
}
