//! Where a launch's files go: its own folder per run (`ocelli-runs/<UTC time>/`, or the one
//! the user names), holding the effective scenario, the node list, each node's log and the
//! server's recording. Nothing that exists is overwritten, renamed or deleted unless the user
//! says `--force`.

use std::io;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Where default run folders are made, under the current directory.
pub const RUNS: &str = "ocelli-runs";

/// A run's folder that cannot be used.
#[derive(Debug, Error)]
pub enum RunDirError {
    #[error("run folder {0} already holds files; name another with --run-dir, or --force to write over them")]
    NotEmpty(PathBuf),
    #[error("recording {0} already exists; name another with --record, or --force to replace it")]
    RecordingExists(PathBuf),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: io::Error },
}

fn io_at(path: &Path) -> impl FnOnce(io::Error) -> RunDirError + '_ {
    move |source| RunDirError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A run's folder and recording, claimed for this run.
#[derive(Clone, Debug)]
pub struct RunDir {
    pub dir: PathBuf,
    pub recording: PathBuf,
}

impl RunDir {
    /// Claim the run's folder and recording path. `dir`: the user's folder (it must be empty
    /// or absent), else a new time-stamped one under [`RUNS`]. `recording`: the user's path
    /// (it must not exist), else `recording.ocrec` in the folder. With `force`, existing files
    /// are written over (an existing recording is removed, not resumed).
    ///
    /// # Errors
    /// A folder that holds files or a recording that exists (without `force`), or an IO error
    /// naming the path.
    pub fn claim(
        dir: Option<&Path>,
        recording: Option<&Path>,
        force: bool,
        now_unix_s: i64,
    ) -> Result<RunDir, RunDirError> {
        // An explicit recording that exists is refused before any folder is made.
        if let Some(r) = recording
            && r.exists()
            && !force
        {
            return Err(RunDirError::RecordingExists(r.to_path_buf()));
        }
        let dir = match dir {
            Some(d) => {
                let busy = std::fs::read_dir(d).is_ok_and(|mut e| e.next().is_some());
                if busy && !force {
                    return Err(RunDirError::NotEmpty(d.to_path_buf()));
                }
                std::fs::create_dir_all(d).map_err(io_at(d))?;
                d.to_path_buf()
            }
            None => new_stamped(Path::new(RUNS), now_unix_s)?,
        };
        let recording = recording.map_or_else(|| dir.join("recording.ocrec"), Path::to_path_buf);
        if recording.exists() {
            if !force {
                return Err(RunDirError::RecordingExists(recording));
            }
            std::fs::remove_file(&recording).map_err(io_at(&recording))?;
        }
        Ok(RunDir { dir, recording })
    }

    /// A node's log file.
    pub fn log(&self, node: &str) -> PathBuf {
        self.dir.join(format!("{node}.log"))
    }

    /// Where `node` appends its links' account each time it stops (`--exit-summary`).
    pub fn exit_summary(&self, node: &str) -> PathBuf {
        self.dir.join(format!("{node}.exit.jsonl"))
    }
}

/// A new folder under `base` named for the UTC time (`2026-11-25T16-07-37Z`, then `…Z-2` when
/// two runs start in one second): created, never reused.
fn new_stamped(base: &Path, unix_s: i64) -> Result<PathBuf, RunDirError> {
    std::fs::create_dir_all(base).map_err(io_at(base))?;
    let stamp = utc_stamp(unix_s);
    for n in 1.. {
        let name = if n == 1 {
            stamp.clone()
        } else {
            format!("{stamp}-{n}")
        };
        let path = base.join(name);
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(io_at(&path)(e)),
        }
    }
    unreachable!("an unbounded counter ends only by returning")
}

/// `YYYY-MM-DDTHH-MM-SSZ` for seconds since the Unix epoch (colons left out: they are awkward
/// in file names). The civil date is Howard Hinnant's `civil_from_days`; a date-time crate for
/// one folder name would be more code to build than this.
pub fn utc_stamp(unix_s: i64) -> String {
    let (days, secs) = (unix_s.div_euclid(86_400), unix_s.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}-{:02}-{:02}Z",
        secs / 3600,
        secs / 60 % 60,
        secs % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_are_utc_civil_times() {
        assert_eq!(utc_stamp(0), "1970-01-01T00-00-00Z");
        assert_eq!(utc_stamp(951_782_400), "2000-02-29T00-00-00Z");
        assert_eq!(utc_stamp(1_795_622_857), "2026-11-25T16-07-37Z");
        assert_eq!(utc_stamp(-1), "1969-12-31T23-59-59Z");
    }

    #[test]
    fn runs_never_share_or_overwrite_a_folder() {
        let base = std::env::temp_dir().join(format!("ocelli-rundir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let a = new_stamped(&base, 10).unwrap();
        let b = new_stamped(&base, 10).unwrap();
        assert_ne!(a, b);
        assert!(b.to_string_lossy().ends_with("T00-00-10Z-2"), "{}", b.display());
        // A named folder that holds files is refused, then accepted with --force; so is a
        // recording that exists, which --force removes.
        std::fs::write(a.join("x.log"), "x").unwrap();
        let e = RunDir::claim(Some(&a), None, false, 0).unwrap_err().to_string();
        assert!(
            e.contains("already holds files") && e.contains(&a.display().to_string()),
            "{e}"
        );
        let rec = b.join("r.ocrec");
        std::fs::write(&rec, "old").unwrap();
        let empty = base.join("empty");
        let e = RunDir::claim(Some(&empty), Some(&rec), false, 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("already exists") && e.contains("r.ocrec"), "{e}");
        let run = RunDir::claim(Some(&a), Some(&rec), true, 0).unwrap_or_else(|e| panic!("{e}"));
        assert!(!rec.exists() && a.join("x.log").exists());
        assert_eq!(run.recording, rec);
        let _ = std::fs::remove_dir_all(&base);
    }
}
