//! [`RecordedRadio`]: a [`RadioSource`] replaying the readings one sensor recorded in an `.mbd`
//! file (`proto::sensor::mbd`; the beacon's MAC is the tag id) at real time. The file's first
//! packet, of any sensor, plays at the epoch the node is given, so every node of a deployment
//! replaying the same file hears it as it was heard. The file's ground-truth columns are read
//! and dropped. Bad lines are skipped and counted with their numbers; impossible RSSI is
//! refused and counted.

use proto::sensor::mbd::{self, MbdError};
use proto::sensor::{RadioSource, SourceError, TagReading};
use proto::{ClusterTime, TagId};
use std::path::{Path, PathBuf};
use tracing::{info, warn};

/// How many skipped lines are kept (and logged) by number; the rest are only counted.
pub const SKIPPED_KEPT: usize = 20;

/// What reading the file found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FileCounts {
    /// Lines of any sensor that parsed.
    pub lines: u64,
    /// This sensor's readings to replay.
    pub readings: u64,
    /// Lines that did not parse (an RSSI out of range is counted in `refused` instead).
    pub skipped: u64,
    /// Lines refused for an impossible RSSI.
    pub refused: u64,
    /// The first [`SKIPPED_KEPT`] skipped or refused lines: (line number, what was wrong).
    pub first_skipped: Vec<(usize, String)>,
}

/// One sensor's recorded readings, replayed at real time.
#[derive(Debug)]
pub struct RecordedRadio {
    path: PathBuf,
    /// (offset from the file's first packet ns, tag, dBm), in time order.
    readings: Vec<(i64, TagId, f64)>,
    next: usize,
    epoch: ClusterTime,
    counts: FileCounts,
}

impl RecordedRadio {
    /// The readings of `sensor` in the `.mbd` file at `path`, the file's first packet playing at
    /// cluster time `epoch`.
    ///
    /// # Errors
    /// The file cannot be read, or holds no reading of `sensor`.
    pub fn open(path: &Path, sensor: TagId, epoch: ClusterTime) -> Result<RecordedRadio, SourceError> {
        let text = std::fs::read_to_string(path).map_err(|source| SourceError::Io {
            path: path.into(),
            source,
        })?;
        let radio = RecordedRadio::from_text(path, &text, sensor, epoch);
        if radio.readings.is_empty() {
            return Err(SourceError::NoReadings {
                path: path.into(),
                sensor,
            });
        }
        let c = &radio.counts;
        info!(file = %path.display(), %sensor, readings = c.readings, lines = c.lines, skipped = c.skipped, refused = c.refused, "recorded radio opened");
        Ok(radio)
    }

    /// As [`RecordedRadio::open`], from the file's text (`path` names it in logs).
    pub fn from_text(path: &Path, text: &str, sensor: TagId, epoch: ClusterTime) -> RecordedRadio {
        let mut counts = FileCounts::default();
        let mut mine = Vec::new();
        let mut first: Option<f64> = None;
        for (i, line) in text.lines().enumerate() {
            let n = i + 1;
            let r = match mbd::parse_line(line) {
                Ok(Some(r)) => r,
                Ok(None) => continue,
                Err(e) => {
                    if matches!(e, MbdError::Rssi(_)) {
                        counts.refused += 1;
                    } else {
                        counts.skipped += 1;
                    }
                    if counts.first_skipped.len() < SKIPPED_KEPT {
                        warn!(file = %path.display(), line = n, problem = %e, "recorded radio line skipped");
                        counts.first_skipped.push((n, e.to_string()));
                    }
                    continue;
                }
            };
            counts.lines += 1;
            first = Some(first.map_or(r.time_s, |t: f64| t.min(r.time_s)));
            if r.sensor == sensor {
                mine.push((r.time_s, r.beacon, r.dbm));
            }
        }
        let t0 = first.unwrap_or(0.0);
        let mut readings: Vec<(i64, TagId, f64)> = mine
            .into_iter()
            .map(|(t, tag, dbm)| (((t - t0) * 1e9).round() as i64, tag, dbm))
            .collect();
        readings.sort_by_key(|r| r.0);
        counts.readings = readings.len() as u64;
        if counts.skipped + counts.refused > SKIPPED_KEPT as u64 {
            warn!(file = %path.display(), skipped = counts.skipped, refused = counts.refused, "more recorded radio lines skipped than logged");
        }
        RecordedRadio {
            path: path.into(),
            readings,
            next: 0,
            epoch,
            counts,
        }
    }

    pub fn counts(&self) -> &FileCounts {
        &self.counts
    }

    /// Seconds from the file's first packet to this sensor's last.
    pub fn duration_s(&self) -> f64 {
        self.readings.last().map_or(0.0, |r| r.0 as f64 * 1e-9)
    }
}

impl RadioSource for RecordedRadio {
    /// Every reading due by `now` (its recorded time past the epoch), stamped with that time;
    /// `Ok(false)` once the file is replayed.
    fn read(&mut self, now: ClusterTime, out: &mut Vec<TagReading>) -> Result<bool, SourceError> {
        while let Some(&(offset, tag, dbm)) = self.readings.get(self.next) {
            let time = self.epoch + offset;
            if time > now {
                break;
            }
            out.push(TagReading { tag, dbm, time });
            self.next += 1;
        }
        if self.next == self.readings.len() {
            info!(file = %self.path.display(), "recorded radio replayed to its end");
            return Ok(false);
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ORIENT: &str = "1,0,0,0,1,0,0,0,1";
    const ME: &str = "b827eb4521b4";
    const OTHER: &str = "000000000101";
    const BEACON: &str = "e78f135624ce";

    fn line(t: f64, sensor: &str, dbm: &str) -> String {
        format!("{t},{sensor},{BEACON},{dbm},1,2,1.8,{ORIENT}")
    }

    fn radio(text: &str, epoch: ClusterTime) -> RecordedRadio {
        RecordedRadio::from_text(Path::new("t.mbd"), text, TagId::parse_mac(ME).unwrap(), epoch)
    }

    #[test]
    fn replays_one_sensors_readings_at_real_time_from_the_files_first_packet() {
        let text = [
            line(100.0, OTHER, "-80"),
            line(100.25, ME, "-70"),
            line(100.5, OTHER, "-81"),
            line(101.0, ME, "-72"),
        ]
        .join("\n");
        let epoch = ClusterTime::from_secs_f64(50.0);
        let mut r = radio(&text, epoch);
        assert_eq!(r.counts().readings, 2);
        assert_eq!(r.counts().lines, 4);
        let mut out = Vec::new();
        assert!(r.read(epoch + 200_000_000, &mut out).unwrap());
        assert!(out.is_empty(), "the first of mine plays 0.25 s after the epoch");
        assert!(r.read(epoch + 500_000_000, &mut out).unwrap());
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].time, epoch + 250_000_000, "stamped with its recorded time");
        assert_eq!(out[0].tag, TagId::parse_mac(BEACON).unwrap());
        assert_eq!(out[0].dbm, -70.0);
        assert!(
            !r.read(epoch + 2_000_000_000, &mut out).unwrap(),
            "then the file ends"
        );
        assert_eq!(out.len(), 2);
        assert!((r.duration_s() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn bad_lines_are_skipped_and_counted_with_their_numbers() {
        let text = [
            line(1.0, ME, "-70"),
            "garbage".to_string(),
            line(2.0, ME, "127"),
            String::new(),
            line(3.0, ME, "NaN"),
            line(4.0, ME, "-60"),
        ]
        .join("\n");
        let r = radio(&text, ClusterTime::ZERO);
        let c = r.counts();
        assert_eq!((c.readings, c.skipped, c.refused), (2, 2, 1));
        let lines: Vec<usize> = c.first_skipped.iter().map(|s| s.0).collect();
        assert_eq!(lines, vec![2, 3, 5]);
        assert!(
            c.first_skipped[1].1.contains("out of range"),
            "{:?}",
            c.first_skipped
        );
    }

    #[test]
    fn a_file_without_the_sensor_or_missing_is_an_error_naming_it() {
        let dir = std::env::temp_dir().join(format!("ocelli-radio-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("other.mbd");
        std::fs::write(&path, line(1.0, OTHER, "-70")).unwrap();
        let me = TagId::parse_mac(ME).unwrap();
        let e = RecordedRadio::open(&path, me, ClusterTime::ZERO)
            .unwrap_err()
            .to_string();
        assert!(e.contains("other.mbd") && e.contains("b8:27:eb:45:21:b4"), "{e}");
        let e = RecordedRadio::open(&dir.join("absent.mbd"), me, ClusterTime::ZERO)
            .unwrap_err()
            .to_string();
        assert!(e.contains("absent.mbd"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
