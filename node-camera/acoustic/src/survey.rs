//! Building the fingerprint database (paper 001's acoustic cues) from recordings made with
//! the source at known positions: `ocelli acoustic survey --positions FILE.csv`.
//!
//! The CSV has a header `x,y,wav` and one row per position: metres, and a 2-channel WAV path
//! relative to the CSV (the path is the rest of the line, so it may contain commas; blank
//! lines and `#` comments are skipped). Every position is checked against the world before any
//! audio is read. Each recording's fingerprint is the ILD vector of all its good blocks
//! averaged (silent and clipped blocks are skipped and counted).

use crate::ild::{IldAnalyzer, IldError, block_starts};
use crate::wav::{FrameQuality, WavError, frame_quality, read_stereo};
use proto::acoustic::{AcousticError, Fingerprint, FingerprintDb, IldSettings};
use proto::scenario::{RadioWorld, World};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a survey failed; each names the file (and line) at fault.
#[derive(Debug, Error)]
pub enum SurveyError {
    #[error("cannot read survey positions {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}:{line}: {problem}")]
    Csv {
        path: PathBuf,
        line: usize,
        problem: String,
    },
    #[error("{path}:{line}: position ({x}, {y}) is outside the world [{}, {}]–[{}, {}]", min[0], min[1], max[0], max[1])]
    Outside {
        path: PathBuf,
        line: usize,
        x: f64,
        y: f64,
        min: [f64; 2],
        max: [f64; 2],
    },
    #[error("{path}:{line}: recording {wav} does not exist")]
    Missing {
        path: PathBuf,
        line: usize,
        wav: PathBuf,
    },
    #[error(transparent)]
    Wav(#[from] WavError),
    #[error("{wav}: no block is free of silence and clipping")]
    NoGoodAudio { wav: PathBuf },
    #[error("{wav}: {source}")]
    Ild { wav: PathBuf, source: IldError },
    #[error(transparent)]
    Fingerprints(#[from] AcousticError),
}

/// One row of the positions file.
#[derive(Clone, Debug, PartialEq)]
pub struct SurveyRow {
    /// 1-based line number in the CSV.
    pub line: usize,
    pub position: [f64; 2],
    /// Resolved against the CSV's folder.
    pub wav: PathBuf,
}

/// Parse the positions file.
///
/// # Errors
/// The file cannot be read, the header is not `x,y,wav`, a row lacks a field or has a
/// coordinate that is not a finite number, or there is no row.
pub fn read_positions(csv: &Path) -> Result<Vec<SurveyRow>, SurveyError> {
    let text = std::fs::read_to_string(csv).map_err(|source| SurveyError::Io {
        path: csv.into(),
        source,
    })?;
    let base = csv.parent().unwrap_or(Path::new("."));
    let bad = |line: usize, problem: String| SurveyError::Csv {
        path: csv.into(),
        line,
        problem,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (line, header) = lines
        .next()
        .ok_or_else(|| bad(1, "empty file; expected a header `x,y,wav`".into()))?;
    let names: Vec<String> = header.split(',').map(|h| h.trim().to_ascii_lowercase()).collect();
    if names != ["x", "y", "wav"] {
        return Err(bad(line, format!("header is {header:?}; expected `x,y,wav`")));
    }
    let mut rows = Vec::new();
    for (line, text) in lines {
        let mut fields = text.splitn(3, ',').map(str::trim);
        let (Some(x), Some(y), Some(wav)) = (fields.next(), fields.next(), fields.next()) else {
            return Err(bad(line, format!("{text:?} has fewer than 3 fields (x,y,wav)")));
        };
        let number = |name: &str, v: &str| -> Result<f64, SurveyError> {
            v.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(line, format!("{name} = {v:?} is not a number of metres")))
        };
        let position = [number("x", x)?, number("y", y)?];
        if wav.is_empty() {
            return Err(bad(line, "the wav field is empty".into()));
        }
        rows.push(SurveyRow {
            line,
            position,
            wav: base.join(wav),
        });
    }
    if rows.is_empty() {
        return Err(bad(line, "no positions after the header".into()));
    }
    Ok(rows)
}

/// The world a survey defines on its own: the positions' bounding box, grown by `margin`
/// metres, no walls.
pub fn bounding_world(rows: &[SurveyRow], margin: f64) -> World {
    let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for r in rows {
        for a in 0..2 {
            min[a] = min[a].min(r.position[a] - margin);
            max[a] = max[a].max(r.position[a] + margin);
        }
    }
    World {
        min: [min[0], min[1], 0.0],
        max: [max[0], max[1], 3.0],
        walls: Vec::new(),
        radio: RadioWorld::default(),
        geo: None,
    }
}

/// The fingerprint of one recording: the ILD of all its good blocks.
///
/// # Errors
/// The WAV's errors, or no good block.
pub fn fingerprint_of(wav: &Path, analyzer: &mut IldAnalyzer) -> Result<Vec<f64>, SurveyError> {
    let settings = analyzer.settings().clone();
    let clip = read_stereo(wav, settings.sample_rate)?;
    let n = settings.block_len;
    let mut skipped = 0;
    for start in block_starts(clip.left.len(), n) {
        let (l, r) = (&clip.left[start..start + n], &clip.right[start..start + n]);
        if frame_quality(l, r) == FrameQuality::Good {
            analyzer.accumulate(l, r).map_err(|source| SurveyError::Ild {
                wav: wav.into(),
                source,
            })?;
        } else {
            skipped += 1;
        }
    }
    if analyzer.blocks() == 0 {
        return Err(SurveyError::NoGoodAudio { wav: wav.into() });
    }
    if skipped > 0 {
        tracing::warn!(file = %wav.display(), skipped, used = analyzer.blocks(), "silent or clipped blocks skipped");
    }
    let ild = analyzer.finish().map_err(|source| SurveyError::Ild {
        wav: wav.into(),
        source,
    })?;
    Ok(ild.values)
}

/// Survey: read the positions, check them against `world`, fingerprint every recording.
///
/// # Errors
/// Any [`SurveyError`], the first one met; positions are all checked before audio is read.
pub fn survey(csv: &Path, world: &World, settings: &IldSettings) -> Result<FingerprintDb, SurveyError> {
    let rows = read_positions(csv)?;
    for r in &rows {
        let [x, y] = r.position;
        if !(x >= world.min[0] && x <= world.max[0] && y >= world.min[1] && y <= world.max[1]) {
            return Err(SurveyError::Outside {
                path: csv.into(),
                line: r.line,
                x,
                y,
                min: [world.min[0], world.min[1]],
                max: [world.max[0], world.max[1]],
            });
        }
        if !r.wav.exists() {
            return Err(SurveyError::Missing {
                path: csv.into(),
                line: r.line,
                wav: r.wav.clone(),
            });
        }
    }
    let mut analyzer = IldAnalyzer::new(settings).map_err(|source| SurveyError::Ild {
        wav: csv.into(),
        source,
    })?;
    let mut fingerprints = Vec::with_capacity(rows.len());
    for r in &rows {
        fingerprints.push(Fingerprint {
            position: r.position,
            values: fingerprint_of(&r.wav, &mut analyzer)?,
        });
    }
    Ok(FingerprintDb::new(world, settings.clone(), fingerprints)?)
}

#[cfg(test)]
mod tests;
