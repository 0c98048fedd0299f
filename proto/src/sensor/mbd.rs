//! The `.mbd` format of recorded BLE readings (the Position Annotated BLE RSSI Dataset, Daniş et
//! al. 2022): one received packet a line, `timestamp, sensor MAC, beacon MAC, RSSI dBm, x, y,
//! z, 3×3 orientation`, the position and orientation being where the beacon truly was. One
//! parser for the file radio source (which keeps the packet and drops the position) and the
//! lab's dataset reader (which scores against it).

use crate::ids::TagId;
use std::fmt;
use std::ops::RangeInclusive;

/// Fields of one line: timestamp, sensor MAC, beacon MAC, RSSI, x, y, z, 3×3 orientation.
pub const MBD_FIELDS: usize = 16;

/// RSSI a BLE controller can report, dBm (the Core specification's range of the RSSI
/// parameter; 127 means "not available"). Anything else is not a reading.
pub const BLE_RSSI_DBM: RangeInclusive<f64> = -127.0..=20.0;

/// One recorded packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MbdRecord {
    /// Seconds since the Unix epoch when the sensor received the packet.
    pub time_s: f64,
    /// The receiving sensor's own Bluetooth address (the same 48-bit space as tags).
    pub sensor: TagId,
    /// The beacon heard: the tag.
    pub beacon: TagId,
    pub dbm: f64,
    /// Where the beacon truly was, metres, the dataset's frame (ground truth: scoring only).
    pub position: [f64; 3],
}

/// What is wrong with a line.
#[derive(Clone, Debug, PartialEq)]
pub enum MbdError {
    /// Not [`MBD_FIELDS`] comma-separated fields.
    Fields(usize),
    /// A field that should be a finite number.
    Number {
        what: &'static str,
        field: String,
        finite: bool,
    },
    /// A field that should be a 48-bit MAC address.
    Mac { what: &'static str, field: String },
    /// An RSSI outside [`BLE_RSSI_DBM`].
    Rssi(f64),
}

impl fmt::Display for MbdError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MbdError::Fields(n) => write!(f, "{n} fields, expected {MBD_FIELDS}"),
            MbdError::Number {
                what,
                field,
                finite: false,
            } => write!(f, "{what} {field:?} is not finite"),
            MbdError::Number { what, field, .. } => write!(f, "{what} {field:?} is not a number"),
            MbdError::Mac { what, field } => write!(f, "{what} {field:?} is not a MAC address"),
            MbdError::Rssi(v) => write!(
                f,
                "RSSI {v} dBm out of range ({}..={} dBm)",
                BLE_RSSI_DBM.start(),
                BLE_RSSI_DBM.end()
            ),
        }
    }
}

impl std::error::Error for MbdError {}

fn number(field: &str, what: &'static str) -> Result<f64, MbdError> {
    let v: f64 = field.trim().parse().map_err(|_| MbdError::Number {
        what,
        field: field.into(),
        finite: true,
    })?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(MbdError::Number {
            what,
            field: field.into(),
            finite: false,
        })
    }
}

fn mac(field: &str, what: &'static str) -> Result<TagId, MbdError> {
    TagId::parse_mac(field).ok_or_else(|| MbdError::Mac {
        what,
        field: field.into(),
    })
}

/// Parse one line; `Ok(None)` for a blank one.
///
/// # Errors
/// A wrong field count, a number that does not parse or is not finite, a MAC that is not 48
/// bits, or an RSSI outside [`BLE_RSSI_DBM`].
pub fn parse_line(line: &str) -> Result<Option<MbdRecord>, MbdError> {
    if line.trim().is_empty() {
        return Ok(None);
    }
    let f: Vec<&str> = line.split(',').collect();
    if f.len() != MBD_FIELDS {
        return Err(MbdError::Fields(f.len()));
    }
    let time_s = number(f[0], "timestamp")?;
    let sensor = mac(f[1], "sensor MAC")?;
    let beacon = mac(f[2], "beacon MAC")?;
    let dbm = number(f[3], "RSSI")?;
    if !BLE_RSSI_DBM.contains(&dbm) {
        return Err(MbdError::Rssi(dbm));
    }
    let mut position = [0.0; 3];
    for (a, v) in position.iter_mut().enumerate() {
        *v = number(f[4 + a], "position")?;
    }
    for field in &f[7..] {
        number(field, "orientation")?;
    }
    Ok(Some(MbdRecord {
        time_s,
        sensor,
        beacon,
        dbm,
        position,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIENT: &str = "1,0,0,0,1,0,0,0,1";

    #[test]
    fn a_dataset_line_parses_with_bare_macs() {
        let line = format!("1581252284.779766,b827eb4521b4,e78f135624ce,-84,11.7,4.28,1.79,{ORIENT}");
        let r = parse_line(&line).unwrap().unwrap();
        assert_eq!(r.sensor, TagId(0xb827_eb45_21b4));
        assert_eq!(r.beacon.to_string(), "e7:8f:13:56:24:ce");
        assert_eq!(r.dbm, -84.0);
        assert_eq!(r.position, [11.7, 4.28, 1.79]);
        assert!((r.time_s - 1_581_252_284.779_766).abs() < 1e-6);
        assert_eq!(parse_line("  "), Ok(None));
    }

    #[test]
    fn bad_lines_say_what_is_wrong() {
        let cases = [
            (format!("1,aa,cc,-70,1,2,1.8,{ORIENT}"), "sensor MAC"),
            ("1,b827eb4521b4,e78f135624ce,-70,1,2,1.8".to_string(), "fields"),
            (
                format!("1,b827eb4521b4,e78f135624ce,strong,1,2,1.8,{ORIENT}"),
                "not a number",
            ),
            (
                format!("1,b827eb4521b4,e78f135624ce,-70,1,NaN,1.8,{ORIENT}"),
                "not finite",
            ),
            (
                format!("1,b827eb4521b4,e78f135624ce,-300,1,2,1.8,{ORIENT}"),
                "out of range",
            ),
            (
                format!("1,b827eb4521b4,e78f135624ce,127,1,2,1.8,{ORIENT}"),
                "out of range",
            ),
            (
                "1,b827eb4521b4,e78f135624ce,-70,1,2,1.8,1,0,0,0,x,0,0,0,1".to_string(),
                "orientation",
            ),
        ];
        for (line, what) in cases {
            let e = parse_line(&line).unwrap_err().to_string();
            assert!(e.contains(what), "{e} should mention {what}");
        }
    }
}
