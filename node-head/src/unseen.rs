//! Tags no camera sees (paper 002's occlusion case, issue 16), when the method asks for it
//! (`[method] unseen-tags = true`): in a cluster with cameras a track starts from cameras, so
//! a tagged person no camera sees — behind a wall, in a corridor the cameras do not cover, or
//! simply not detected — had no track, though the radio nodes heard their tag. Nodes send
//! their readings only in answer to priors, so a cluster holding no track keeps a radio search
//! track (`track::Radio::Search`) whose priors ask for them. A tag that stays unbound for
//! [`UNSEEN_WAIT_S`] while no track's evidence claims it (every track's is below −[`UNSEEN_LLR`]: the tag is clearly elsewhere) gets a
//! *radio track*, started at the RSSI fix of its readings of that wait ([`fix`]) and bound to
//! the tag by the ordinary rules: it takes the tag's readings and is confirmed at once (no
//! camera can confirm it), and its tag moves to a camera track whose evidence leads, or is
//! unbound if the evidence turns against it. Cameras never pair a radio track
//! (`Prior::radio`): a camera that later sees the person starts a camera track of its own,
//! whose evidence for the tag soon claims it, and the radio track is dropped.
//!
//! The wait and the evidence bound keep a tagged person whom cameras do track from getting a
//! second track: binding a seen tag takes a second or two, and a track near the tag gathers
//! positive evidence long before the wait is over. A fix looser than [`MAX_FIX_SIGMA_M`] starts
//! nothing: the tag goes on waiting and the head wakes its sleeping radios to hear it
//! (`HeadNode::activate`). A radio track is never merged with a camera track as a duplicate
//! (its width would merge it with anybody nearby) nor adopted for another head's target (only
//! named by the server); the tag's evidence decides: a radio track that loses its tag, or
//! whose tag a camera track's evidence claims (above +[`UNSEEN_LLR`]), is dropped at once.

use crate::grid::belief::Belief;
use crate::grid::layout::Grid;
use crate::tags::{Heard, TagBook};
use nalgebra::{Matrix2, Vector2, Vector3};
use proto::models::RssiModel;
use proto::scenario::{Wall, World};
use proto::{ClusterTime, TagId};
use std::collections::BTreeMap;
use std::sync::Arc;

/// How long a tag must be heard unbound, with no track claiming it, before it gets a radio
/// track, seconds; also the window of readings its fix is taken from.
pub const UNSEEN_WAIT_S: f64 = 3.0;
/// No track's binding evidence for the tag may exceed −this (natural log): half of
/// [`crate::tags::BIND_LLR`], the tag clearly away from every track.
pub const UNSEEN_LLR: f64 = 3.0;
/// Most readings one waiting tag keeps (21 nodes at 5 Hz for 3 s is 315).
const MAX_WAITING_READINGS: usize = 1024;
/// The fix's grid cell, metres.
pub const FIX_CELL_M: f64 = 0.25;
/// Added to the fix's variance on each floor axis, m²: readings of one place over a few
/// seconds share their multipath, so the grid's spread understates the error.
pub const FIX_FLOOR_VAR_M2: f64 = 0.5 * 0.5;
/// The loosest fix a radio track starts from, √(trace Σ), metres. Looser (few nodes heard
/// the tag: an energy-saving cluster keeps most radios off), the tag goes on waiting and the
/// head wakes its radios to search for it ([`UnseenTags::searching`]); a track that wide
/// would be merged with, or answered by, anybody.
pub const MAX_FIX_SIGMA_M: f64 = 3.0;

/// A tag waiting for a radio track: since when it has been heard unbound, and its readings of
/// the window (node slot, dBm, reception time).
#[derive(Clone, Debug)]
struct Waiting {
    since: ClusterTime,
    readings: Vec<(usize, f64, ClusterTime)>,
}

/// The tags heard unbound, waiting.
#[derive(Clone, Debug, Default)]
pub struct UnseenTags {
    waiting: BTreeMap<TagId, Waiting>,
    /// Waiting tags that were due but gave no usable fix: the head wakes its radios.
    searching: std::collections::BTreeSet<TagId>,
}

impl UnseenTags {
    /// Note the step's readings at `now`: a bound tag stops waiting; an unbound one heard
    /// starts (or goes on) waiting and keeps the window's readings; one not heard for the
    /// whole window starts again when it is.
    pub fn note(&mut self, heard: &[Heard], book: &TagBook, now: ClusterTime) {
        let window_ns = (UNSEEN_WAIT_S * 1e9) as i64;
        for h in heard {
            let tag = h.reading.tag;
            if book.track_of(tag).is_some() {
                continue;
            }
            let w = self.waiting.entry(tag).or_insert(Waiting {
                since: now,
                readings: Vec::new(),
            });
            if w.readings.len() < MAX_WAITING_READINGS {
                w.readings.push((h.slot, h.reading.dbm, h.reading.time));
            }
        }
        self.waiting.retain(|tag, w| {
            w.readings.retain(|r| now - r.2 <= window_ns);
            book.track_of(*tag).is_none() && !w.readings.is_empty()
        });
        let waiting = &self.waiting;
        self.searching.retain(|tag| waiting.contains_key(tag));
    }

    /// Tag `tag` was due at `now` but its fix was too loose: it waits another
    /// [`UNSEEN_WAIT_S`] (readings of radios woken meanwhile make the next fix, and a grid is
    /// not computed every step), and the head searches for it.
    pub fn search(&mut self, tag: TagId, now: ClusterTime) {
        if let Some(w) = self.waiting.get_mut(&tag) {
            w.since = now;
        }
        self.searching.insert(tag);
    }

    /// Whether a tag is being searched for: the head keeps its radios on.
    pub fn searching(&self) -> bool {
        !self.searching.is_empty()
    }

    /// Tags that waited [`UNSEEN_WAIT_S`], that no track's evidence claims and whose home is
    /// not another head, with the mean
    /// reading of each node that heard them in the window: (tag, [(slot, mean dBm)]).
    pub fn due(&self, book: &TagBook, now: ClusterTime) -> Vec<(TagId, Vec<(usize, f64)>)> {
        self.waiting
            .iter()
            .filter(|(tag, w)| {
                now.secs_since(w.since) >= UNSEEN_WAIT_S
                    && book.strongest_claim(**tag) < -UNSEEN_LLR
                    && !book.away(**tag)
            })
            .map(|(tag, w)| {
                let mut per_node: BTreeMap<usize, (f64, u32)> = BTreeMap::new();
                for &(slot, dbm, _) in &w.readings {
                    let e = per_node.entry(slot).or_insert((0.0, 0));
                    e.0 += dbm;
                    e.1 += 1;
                }
                let means = per_node
                    .into_iter()
                    .map(|(slot, (sum, n))| (slot, sum / f64::from(n)))
                    .collect();
                (*tag, means)
            })
            .collect()
    }

    /// Tag `tag` got its track (or was refused one): it waits afresh if still unbound.
    pub fn done(&mut self, tag: TagId) {
        self.waiting.remove(&tag);
        self.searching.remove(&tag);
    }
}

/// Where a tag is from each node's mean reading alone: the mean and covariance of the floor
/// grid's posterior (uniform prior over the world's box, [`FIX_CELL_M`] cells, walls blocked)
/// under `model`, the tag at height `z`, plus [`FIX_FLOOR_VAR_M2`] per axis. `None` with
/// fewer than three nodes (a ring or two crossing rings are no fix), readings no cell
/// explains, or a box without floor.
pub fn fix(
    bounds: ([f64; 3], [f64; 3]),
    walls: &[Wall],
    model: &RssiModel,
    z: f64,
    readings: &[(Vector3<f64>, f64)],
) -> Option<(Vector2<f64>, Matrix2<f64>)> {
    if readings.len() < 3 {
        return None;
    }
    let world = World {
        min: bounds.0,
        max: bounds.1,
        walls: walls.to_vec(),
        radio: Default::default(),
        geo: None,
    };
    let grid = Arc::new(Grid::new(&world, FIX_CELL_M).ok()?);
    // In log space, then one exponent: the product of twenty Gaussians underflows far from
    // the tag.
    let mut log_l = vec![0.0f64; grid.len()];
    for (node, dbm) in readings {
        crate::grid::rssi::add_log(&grid, node, model, *dbm, z, &mut log_l).ok()?;
    }
    let best = log_l
        .iter()
        .enumerate()
        .filter(|(k, _)| grid.is_free(*k))
        .map(|(_, l)| *l)
        .fold(f64::NEG_INFINITY, f64::max);
    if !best.is_finite() {
        return None;
    }
    let likelihood: Vec<f64> = log_l
        .iter()
        .enumerate()
        .map(|(k, v)| if grid.is_free(k) { (v - best).exp() } else { 0.0 })
        .collect();
    let mut belief = Belief::uniform(grid);
    belief.correct(&likelihood).ok()?;
    let e = belief.estimate();
    let cov = Matrix2::new(
        e.covariance[0][0] + FIX_FLOOR_VAR_M2,
        e.covariance[0][1],
        e.covariance[1][0],
        e.covariance[1][1] + FIX_FLOOR_VAR_M2,
    );
    Some((Vector2::new(e.mean[0], e.mean[1]), cov))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proto::observation::RssiReading;

    const ROOM: ([f64; 3], [f64; 3]) = ([0.0, 0.0, 0.0], [12.0, 8.0, 3.0]);

    fn nodes() -> Vec<Vector3<f64>> {
        let mut v = Vec::new();
        for x in [0.5, 6.0, 11.5] {
            for y in [0.5, 7.5] {
                v.push(Vector3::new(x, y, 2.5));
            }
        }
        v
    }

    #[test]
    fn the_fix_of_noiseless_readings_lies_on_the_tag() {
        // The literature model (paper 002 eq. 2), as the crowd scenario's `rssi-default`.
        let model = RssiModel::default();
        let tag = Vector3::new(8.0, 3.0, 0.9);
        let readings: Vec<(Vector3<f64>, f64)> = nodes()
            .into_iter()
            .map(|n| (n, model.predict((tag - n).norm())))
            .collect();
        let (p, cov) = fix(ROOM, &[], &model, 0.9, &readings).unwrap();
        assert!((p - Vector2::new(8.0, 3.0)).norm() < 0.3, "fix {p:?}");
        assert!(cov[(0, 0)] >= FIX_FLOOR_VAR_M2 && cov[(1, 1)] >= FIX_FLOOR_VAR_M2);
        // σ about 1.5 m: six nodes at 4 dB place a tag no better.
        assert!(cov[(0, 0)] < 4.0 && cov[(1, 1)] < 4.0, "{cov:?}");
        // Two nodes are no fix.
        assert!(fix(ROOM, &[], &model, 0.9, &readings[..2]).is_none());
    }

    fn heard(slot: usize, tag: u64, dbm: f64, ms: i64) -> Heard {
        Heard {
            slot,
            reading: RssiReading {
                tag: TagId(tag),
                dbm,
                time: ClusterTime::from_millis(ms),
            },
        }
    }

    #[test]
    fn a_tag_heard_unbound_and_unclaimed_is_due_after_the_wait_with_mean_readings() {
        let book = TagBook::default();
        let mut u = UnseenTags::default();
        let mut ms = 0;
        while ms <= 3000 {
            let now = ClusterTime::from_millis(ms);
            u.note(
                &[
                    heard(0, 7, -60.0, ms),
                    heard(1, 7, -70.0 - (ms % 400) as f64 / 100.0, ms),
                ],
                &book,
                now,
            );
            if ms < 3000 {
                assert!(u.due(&book, now).is_empty(), "due at {ms} ms");
            }
            ms += 200;
        }
        let due = u.due(&book, ClusterTime::from_millis(3000));
        assert_eq!(due.len(), 1);
        let (tag, means) = &due[0];
        assert_eq!(*tag, TagId(7));
        assert_eq!(means.len(), 2);
        assert_eq!(means[0], (0, -60.0));
        assert!((means[1].1 - -71.0).abs() < 0.2, "{means:?}");
        // A fix too loose: the tag searches and waits another window before the next try.
        u.search(TagId(7), ClusterTime::from_millis(3000));
        assert!(u.searching());
        assert!(u.due(&book, ClusterTime::from_millis(3200)).is_empty());
        let mut ms = 3200;
        while ms <= 6000 {
            let now = ClusterTime::from_millis(ms);
            u.note(&[heard(0, 7, -60.0, ms), heard(1, 7, -71.0, ms)], &book, now);
            ms += 200;
        }
        assert_eq!(u.due(&book, ClusterTime::from_millis(6000)).len(), 1);
        u.done(TagId(7));
        assert!(!u.searching());
        assert!(u.due(&book, ClusterTime::from_millis(3000)).is_empty());
        // Unheard for a whole window, a tag waits afresh.
        u.note(&[heard(0, 8, -60.0, 3000)], &book, ClusterTime::from_millis(3000));
        u.note(&[], &book, ClusterTime::from_millis(6100));
        u.note(&[heard(0, 8, -60.0, 6200)], &book, ClusterTime::from_millis(6200));
        assert!(u.due(&book, ClusterTime::from_millis(6400)).is_empty());
    }
}
