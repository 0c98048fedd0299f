//! The colours this camera gave each of the head's tracks: which of its people answers a
//! prior weighs how alike that person looks to the one it gave the track before.
//!
//! A camera answers a step's priors by pairing them with its people on the floor jointly
//! ([`crate::measure::joint_choices`]). Two people who cross or meet come within each other's
//! gates, the two tracks draw together, and after the crossing the pairing by distance alone
//! may give each track the other person: a swap of identities that the camera's own filters,
//! which follow each person by colour, did not make (a generated 10 × 8 m hall, seed 1: two
//! people in brown and in purple passed 0.2 m apart and their global ids swapped).
//!
//! So the pairing's cost of a person for a prior is the gated distance plus
//! [`COLOUR_CHANGE_COST`] times how unlike (1 − the blended Bhattacharyya coefficient,
//! `proto::appearance`) the person's colours are to those of the person this camera last gave
//! the same track. Two people in other colours then keep their tracks; two in alike colours
//! cost nearly the same as before, and distance decides, as it did. The colours are the last
//! answer's, not a blend: a blend keeps a track's first, polluted colours (a box with floor in
//! it, or a neighbour) longer, and was no better (`docs/multi-target.md`).

use proto::observation::GroundPoint;
use proto::{ClusterTime, TargetId};
use std::collections::BTreeMap;

/// Added to a pair's squared gate distance per unit of unlikeness (1 − similarity). Two of a
/// crowd's people in other colours are about 0.55 alike, so the other person costs about 2.7
/// more than the same one: about what a person 1.6 σ farther off costs. Measured (`ocelli sim`,
/// 60 s, pixel level; docs/multi-target.md): 6 raised IDF1 in the hall (over 16 seeds) and the
/// generated halls, and left the crowd, whose people share colours, as it was; 12 raised the
/// hall's more and cost the crowd 140 misses a run.
pub const COLOUR_CHANGE_COST: f64 = 6.0;

/// A track not asked about for this long is forgotten, ns: its colours may be another
/// person's by the time a track of that id is asked about again (ids are the head's).
pub const FORGET_NS: i64 = 10_000_000_000;

/// What this camera last gave each track.
#[derive(Debug, Default)]
pub struct TrackColours {
    given: BTreeMap<TargetId, Given>,
}

#[derive(Debug)]
struct Given {
    histogram: Vec<f32>,
    asked: ClusterTime,
}

impl TrackColours {
    /// The cost of giving `person` to the track `target`, whose gated squared distance to the
    /// person is `d2`: `d2` plus the colour change, when both this camera's last answer to the
    /// track and the person have colours.
    pub fn cost(&self, target: TargetId, person: &GroundPoint, d2: f64) -> f64 {
        let unlike = self
            .given
            .get(&target)
            .and_then(|g| proto::appearance::similarity(&g.histogram, &person.histogram))
            .map_or(0.0, |s| f64::from(1.0 - s).max(0.0));
        d2 + COLOUR_CHANGE_COST * unlike
    }

    /// Note this step's answers: `answers` pairs each prior asked at `now` with the person it
    /// was given, if any. A track given nobody keeps its colours (its person is hidden for a
    /// moment); one not asked about for [`FORGET_NS`] is forgotten.
    pub fn note<'a>(
        &mut self,
        now: ClusterTime,
        answers: impl IntoIterator<Item = (TargetId, Option<&'a GroundPoint>)>,
    ) {
        for (target, person) in answers {
            match (person, self.given.get_mut(&target)) {
                (Some(p), Some(g)) => {
                    if !p.histogram.is_empty() {
                        g.histogram.clone_from(&p.histogram);
                    }
                    g.asked = now;
                }
                (Some(p), None) if !p.histogram.is_empty() => {
                    self.given.insert(
                        target,
                        Given {
                            histogram: p.histogram.clone(),
                            asked: now,
                        },
                    );
                }
                (None, Some(g)) => g.asked = now,
                _ => {}
            }
        }
        self.given.retain(|_, g| now.0 - g.asked.0 < FORGET_NS);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::observation::{HISTOGRAM_BINS, HISTOGRAM_HS_BINS};

    /// A person at `x` on the floor all in HS bin `hs` and V bin `v`.
    fn person(local: u32, x: f64, hs: usize, v: usize) -> GroundPoint {
        let mut histogram = vec![0.0; HISTOGRAM_BINS];
        histogram[hs] = 1.0;
        histogram[HISTOGRAM_HS_BINS + v] = 1.0;
        GroundPoint {
            local,
            position: [x, 0.0],
            cov: [0.01, 0.0, 0.01],
            width_m: 0.5,
            height_m: 1.7,
            confidence: 1.0,
            histogram,
            captured: ClusterTime(0),
            ml_position: [x, 0.0],
        }
    }

    #[test]
    fn the_person_in_the_colours_given_before_costs_less() {
        let (red, blue) = (person(1, 0.0, 3, 5), person(2, 0.3, 70, 2));
        let mut c = TrackColours::default();
        let t = TargetId(7);
        // Nothing given yet: distance alone.
        assert_eq!(c.cost(t, &blue, 1.0), 1.0);
        c.note(ClusterTime(0), [(t, Some(&red))]);
        assert_eq!(c.cost(t, &red, 1.0), 1.0, "the same colours cost nothing more");
        // The blue person, a little nearer, costs more than the red one a little farther.
        assert!(c.cost(t, &blue, 1.0) > c.cost(t, &red, 2.0));
        assert!((c.cost(t, &blue, 1.0) - (1.0 + COLOUR_CHANGE_COST)).abs() < 1e-6);
        // Another track is not concerned.
        assert_eq!(c.cost(TargetId(8), &blue, 1.0), 1.0);
    }

    #[test]
    fn the_last_answer_counts_and_a_hidden_person_keeps_the_colours() {
        let (red, blue) = (person(1, 0.0, 3, 5), person(2, 0.3, 70, 2));
        let mut c = TrackColours::default();
        let t = TargetId(7);
        c.note(ClusterTime(0), [(t, Some(&red))]);
        c.note(ClusterTime(1), [(t, None)]);
        assert!(c.cost(t, &blue, 0.0) > 0.0, "kept while the person is hidden");
        c.note(ClusterTime(2), [(t, Some(&blue))]);
        assert_eq!(c.cost(t, &blue, 0.0), 0.0);
        assert!(c.cost(t, &red, 0.0) > 0.0);
        // A person with no colours leaves the track's as they were.
        let mut plain = person(3, 0.0, 0, 0);
        plain.histogram.clear();
        c.note(ClusterTime(3), [(t, Some(&plain))]);
        assert_eq!(c.cost(t, &blue, 0.0), 0.0);
        assert_eq!(c.cost(t, &plain, 0.5), 0.5, "no colours, distance alone");
    }

    #[test]
    fn a_track_not_asked_about_is_forgotten() {
        let red = person(1, 0.0, 3, 5);
        let mut c = TrackColours::default();
        c.note(
            ClusterTime(0),
            [(TargetId(1), Some(&red)), (TargetId(2), Some(&red))],
        );
        // Track 2 is asked about (a part of the step's priors), track 1 is not.
        c.note(ClusterTime(FORGET_NS / 2), [(TargetId(2), None)]);
        assert_eq!(c.given.len(), 2);
        c.note(ClusterTime(FORGET_NS + 1), [(TargetId(2), None)]);
        assert_eq!(c.given.len(), 1, "track 1 forgotten, track 2 kept");
    }
}
