//! The step's tag readings: every fresh reading a member radio node sent goes into the head's
//! [`TagBook`](crate::tags::TagBook) as it arrives, whichever track's answer or detection
//! carried it; when the step closes they are weighed against the tracks, tags are bound,
//! moved or unbound, and each track takes the readings of its own tag only.

use super::HeadNode;
use crate::tags::{Change, Heard};
use proto::ClusterTime;
use proto::observation::{Kinds, ObservationKind, RssiReading};
use tracing::{info, warn};

impl HeadNode {
    /// Queue node `slot`'s tag readings for the step: those of a radio node, stamped near now.
    pub(super) fn offer_readings<'a>(
        &mut self,
        now: ClusterTime,
        slot: usize,
        readings: impl IntoIterator<Item = &'a RssiReading>,
    ) {
        if !self.nodes[slot].info.rssi {
            return;
        }
        let refused = self.tags.refused;
        for r in readings {
            if self.fresh(now, r.time, slot, "RSSI packet") {
                self.tags.offer(slot, *r, now);
            }
        }
        let more_refused = self.tags.refused - refused;
        if more_refused > 0 {
            self.counters.tag_readings_refused += more_refused;
            if let Some(more) = self.log.admit(now.0, "tag book full") {
                warn!(
                    node = %self.nodes[slot].info.id,
                    tags = crate::tags::MAX_TAGS,
                    more,
                    "readings of a tag beyond the tags the head keeps; ignored"
                );
            }
        }
    }

    /// Weigh the step's readings, bind tags by the evidence, and hand each track its tag's
    /// readings (a radio-only cluster's tracks first take the tags no track holds, and a tag
    /// no track claims for a while gets a radio track: `crate::unseen`).
    pub(super) fn hand_readings_to_tracks(&mut self, now: ClusterTime) {
        let heard = self.tags.take_step(now);
        let nodes = &self.cfg.nodes;
        self.tags.weigh(
            &heard,
            &self.tracks,
            now,
            |t, slot| t.rssi_noise.weighed(&t.trainers[slot].model()),
            |slot| nodes[slot].position,
        );
        let mut changes = self.tags.refresh_homes(now);
        changes.extend(
            self.tags
                .decide(&self.tracks, |t| t.past_tentative() && t.camera_steps > 0),
        );
        for c in changes {
            match c {
                Change::Bound { tag, track } => info!(tag = %tag, target = %track, "tag bound to a track"),
                Change::Moved { tag, from, to } => {
                    info!(tag = %tag, from = %from, to = %to, "tag moved to the track that explains it")
                }
                Change::Unbound { tag, track } => info!(tag = %tag, target = %track, "tag unbound"),
                Change::Away { tag, track, home } => {
                    info!(tag = %tag, target = %track, home = %home, "tag's readings held back: another cluster is its home")
                }
            }
        }
        self.drop_superseded_radio_tracks();
        self.radio_tracks_for(&heard, now);
        self.unseen_tag_tracks(&heard, now);
        for t in &mut self.tracks {
            let Some(tag) = self.tags.fused_tag_of(t.local) else {
                continue;
            };
            for h in heard.iter().filter(|h| h.reading.tag == tag) {
                let Heard { slot, reading } = *h;
                if t.hear(slot, reading.dbm, t.time.secs_since(reading.time)) {
                    t.note(self.nodes[slot].info.id, Kinds::of(ObservationKind::Rssi));
                }
            }
        }
    }
}
