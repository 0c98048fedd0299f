//! Export of tracks from a recording: one row per track report the server bound to a global id,
//! as CSV or JSON Lines.
//!
//! Columns: `t` (report time, s), `global`, `head`, `local`, `step`, `x y z vx vy vz` (m, m/s),
//! `sigma_m` (√ trace of the position covariance, m), `owner` (whether this report became the global
//! track's posterior, i.e. came from its owner; one owner row per global and step), `cameras` and `rssi_nodes`
//! (contributors with a camera measurement / an RSSI reading).

use crate::analysis::{Loaded, rebuild};
use crate::core::ServerNode;
use crate::record::{Record, Stamped};
use proto::msg::Message;
use serde::Serialize;
use std::io::Write;

/// One exported track sample.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackRow {
    pub t: f64,
    pub global: u32,
    pub head: u32,
    pub local: u32,
    pub step: u64,
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub vx: f64,
    pub vy: f64,
    pub vz: f64,
    pub sigma_m: f64,
    pub owner: bool,
    /// Contributors with a camera measurement, and with an RSSI reading.
    pub cameras: u32,
    pub rssi_nodes: u32,
}

/// Export format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Csv,
    JsonLines,
}

/// Track rows of a recording, in recording order.
pub fn track_rows(loaded: &Loaded) -> Vec<TrackRow> {
    let mut rows = Vec::new();
    rebuild(loaded, |node, s| rows.extend(track_row(node, s)));
    rows
}

/// The row of one record, if it is a track report `node` (a server that has just been fed that
/// record) bound to a global id. For following a recording as it grows.
pub fn track_row(node: &ServerNode, s: &Stamped) -> Option<TrackRow> {
    let Record::Received(env) = &s.record else {
        return None;
    };
    let Message::TrackReport(r) = &env.body else {
        return None;
    };
    let g = node.global_of(env.source, r.target)?;
    // Owner rows are the ones that became the global's posterior (the owner's reports,
    // including the one that triggered a handover away from it).
    let owner = node
        .globals()
        .find(|(id, _)| *id == g)
        .is_some_and(|(_, gt)| gt.time == r.time && gt.mean == r.mean);
    Some(TrackRow {
        t: r.time.as_secs_f64(),
        global: g.0,
        head: env.source.0,
        local: r.target.0,
        step: r.step,
        x: r.mean[0],
        y: r.mean[1],
        z: r.mean[2],
        vx: r.mean[3],
        vy: r.mean[4],
        vz: r.mean[5],
        sigma_m: (r.cov[0][0] + r.cov[1][1] + r.cov[2][2]).max(0.0).sqrt(),
        owner,
        cameras: r.contributors.iter().filter(|c| c.camera()).count() as u32,
        rssi_nodes: r.contributors.iter().filter(|c| c.rssi()).count() as u32,
    })
}

/// Write rows in a format.
///
/// # Errors
/// IO errors of the writer.
pub fn write_rows(rows: &[TrackRow], format: Format, out: &mut impl Write) -> std::io::Result<()> {
    match format {
        Format::Csv => {
            writeln!(
                out,
                "t,global,head,local,step,x,y,z,vx,vy,vz,sigma_m,owner,cameras,rssi_nodes"
            )?;
            for r in rows {
                writeln!(
                    out,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    r.t,
                    r.global,
                    r.head,
                    r.local,
                    r.step,
                    r.x,
                    r.y,
                    r.z,
                    r.vx,
                    r.vy,
                    r.vz,
                    r.sigma_m,
                    r.owner,
                    r.cameras,
                    r.rssi_nodes
                )?;
            }
        }
        Format::JsonLines => {
            for r in rows {
                serde_json::to_writer(&mut *out, r)?;
                writeln!(out)?;
            }
        }
    }
    Ok(())
}
