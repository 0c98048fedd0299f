//! A track that fails over to the other head (its head cut off by a partition) and later comes
//! back to the head it started on keeps its radio contributors there. Before the fix, the first
//! head kept the "down" it had heard of its cameras before they were reassigned (the "up" went
//! to the other head), and the returning track had no contributor there: RSSI contributors 0
//! for the rest of the run (the first case below: 16 of 16 estimates). The returning track is
//! a new track there, whose tag is bound again once the evidence is in: it must be within 2 s,
//! and kept.

use node_server::analysis::Loaded;
use node_server::export::{TrackRow, track_rows};
use proto::scenario::Scenario;
use sim::net::Partition;
use sim::{Level, Sim, SimOptions};

const DURATION_S: f64 = 45.0;

fn owner_rows(seed: u64, partitions: &[Partition]) -> Vec<TrackRow> {
    let mut opts = SimOptions {
        seed,
        duration_s: DURATION_S,
        level: Level::Measurement,
        ..SimOptions::default()
    };
    opts.network.partitions.extend_from_slice(partitions);
    let out = Sim::new(Scenario::default_scenario(), opts)
        .expect("the default scenario simulates")
        .run();
    let loaded = Loaded {
        scenario: out.scenario,
        records: out.records,
        skipped: Vec::new(),
    };
    track_rows(&loaded).into_iter().filter(|r| r.owner).collect()
}

/// Rows of the owner after the track has left `first` and come back to it.
fn rows_after_return(rows: &[TrackRow]) -> (u32, Vec<&TrackRow>) {
    let first = rows.first().expect("the robot is tracked").head;
    let left = rows
        .iter()
        .position(|r| r.head != first)
        .expect("the track moves to the other head");
    let back = rows[left..]
        .iter()
        .position(|r| r.head == first)
        .map(|i| left + i)
        .expect("the track comes back to its first head");
    (first, rows[back..].iter().filter(|r| r.head == first).collect())
}

#[test]
fn a_track_back_on_its_first_head_keeps_its_rssi_contributors() {
    let cut = |isolated: &[u32], from_s: f64, to_s: f64| Partition {
        from_s,
        to_s,
        isolated: isolated.to_vec(),
    };
    let head2_cameras = [10, 11, 12, 24, 25, 26, 27, 28, 29, 30];
    let cases = [
        // Head 2's cameras go down while in its cluster (head 2 hears "down"), head 2 is cut
        // off (failover: they are assigned to head 3), they come back while there (head 3
        // hears "up"), head 2 comes back and takes the track back: its cameras must be up
        // there again.
        (2, vec![cut(&head2_cameras, 2.0, 6.0), cut(&[2], 4.0, 8.0)]),
        // Plain failover and return, both directions.
        (2, vec![cut(&[2], 3.0, 6.0)]),
        (1, vec![cut(&[3], 11.0, 14.0)]),
    ];
    for (seed, partitions) in cases {
        let rows = owner_rows(seed, &partitions);
        let (first, back) = rows_after_return(&rows);
        // A track handed back starts afresh: its tag is bound again once its readings make the
        // evidence (a second or so); from then on it keeps it.
        let returned = back.first().map_or(0.0, |r| r.t);
        let bound = back.iter().position(|r| r.rssi_nodes > 0).unwrap_or_else(|| {
            panic!("seed {seed}: back on head {first}, no estimate has an RSSI contributor")
        });
        assert!(
            back[bound].t - returned <= 2.0,
            "seed {seed}: back on head {first} at {returned:.1} s, the first RSSI contributor only at {:.1} s",
            back[bound].t
        );
        let after = &back[bound..];
        let without = after.iter().filter(|r| r.rssi_nodes == 0).count();
        assert!(
            after.len() >= 10 && without * 10 <= after.len(),
            "seed {seed}: back on head {first}, {without} of {} estimates since the tag was bound again have no RSSI contributor",
            after.len()
        );
    }
}
