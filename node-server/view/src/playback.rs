//! Playing a recording back (paper 004 §3.3's log file for playback; `ocelli view RECORDING`):
//! play, pause, seek and speed, with the state at any moment rebuilt from the records.
//!
//! [`RecordingIndex::build`] reads the recording once and keeps a checkpoint — a copy of the
//! view and the byte offset of the next record — every [`CHECKPOINT_NS`] of recording time or
//! [`CHECKPOINT_RECORDS`] records, whichever comes first. Seeking starts from the last
//! checkpoint at or before the target and applies the records after it, so it reads at most one
//! checkpoint interval however long the recording is; records are read from the file, never
//! held in memory.
//!
//! The recording reader skips damage and says where: a torn tail (the writer crashed) ends the
//! recording where the intact records end; damaged stretches and records that do not decode
//! (another build, another protocol version) are skipped and counted; all are named in the
//! view's problems. [`run`] is the producer task: it advances the position
//! with the clock at the chosen speed, takes the page's commands and publishes the view.

use crate::feed::Publisher;
use crate::geo::Geo;
use crate::state::ViewState;
use node_server::recording::{Damage, RecordingError, Skipped};
use node_server::{Reader, Stamped};
use serde::Serialize;
use std::fs::File;
use std::io::{BufReader, Chain, Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;
use tokio::sync::mpsc;
use tokio_util::sync::CancellationToken;

/// Recording time between checkpoints, ns.
pub const CHECKPOINT_NS: i64 = 5_000_000_000;
/// Records between checkpoints at most.
pub const CHECKPOINT_RECORDS: u64 = 20_000;

/// A recording that cannot be played.
#[derive(Debug, Error)]
pub enum PlaybackError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("recording {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("recording {0} holds no records")]
    Empty(PathBuf),
}

/// What the page's controls ask for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    Play,
    Pause,
    /// Go to this many seconds after the recording's first record.
    Seek(f64),
    /// Play at this multiple of real time.
    Speed(f64),
}

/// Where the playback is, for the page's slider.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlaybackInfo {
    pub playing: bool,
    pub speed: f64,
    /// First and last record, and the position, seconds of recording time.
    pub start: f64,
    pub end: f64,
    pub position: f64,
    pub records: u64,
    pub path: String,
}

struct Checkpoint {
    at_ns: i64,
    offset: u64,
    state: ViewState,
}

/// A recording read once, with checkpoints to seek from.
pub struct RecordingIndex {
    path: PathBuf,
    header: Vec<u8>,
    /// Bytes of the file when it was indexed (a reader reads no further).
    len: u64,
    start_ns: i64,
    end_ns: i64,
    records: u64,
    checkpoints: Vec<Checkpoint>,
    /// A torn end (damage reaching the end of the file), if any.
    tail: Option<Skipped>,
}

impl std::fmt::Debug for RecordingIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordingIndex")
            .field("path", &self.path)
            .field("records", &self.records)
            .field("checkpoints", &self.checkpoints.len())
            .finish_non_exhaustive()
    }
}

type RecordReader = Reader<Chain<Cursor<Vec<u8>>, BufReader<File>>>;

/// Whether a skipped stretch is the file's torn end: cut short where the file ends.
fn is_torn_end(s: &Skipped, len: u64) -> bool {
    s.offset + s.bytes >= len && matches!(s.damage, Damage::ShortHeader | Damage::ShortPayload { .. })
}

/// What was wrong with a skipped stretch, for the page.
fn damage_text(d: Damage) -> &'static str {
    match d {
        Damage::ShortHeader | Damage::ShortPayload { .. } => "cut short",
        Damage::BadLength { .. } => "a corrupt length",
        Damage::Checksum => "a checksum mismatch",
        Damage::Undecodable => "records that do not decode: another build or protocol version",
    }
}

/// A damaged stretch inside the recording (at file offset `offset`), worded for the page;
/// undecodable records share one wording, so the page counts them as one problem.
fn skipped_text(s: &Skipped, offset: u64) -> String {
    if s.damage == Damage::Undecodable {
        // One problem however many: the page counts them.
        return "records that do not decode were skipped (another build or protocol version)".into();
    }
    format!(
        "recording damaged at byte {offset}: {} bytes skipped ({}); the records around it play",
        s.bytes,
        damage_text(s.damage)
    )
}

fn torn_text(t: &Skipped) -> String {
    format!(
        "recording is torn at byte {}: {} bytes skipped ({}); everything before plays",
        t.offset,
        t.bytes,
        damage_text(t.damage)
    )
}

/// The stretch a reader skipped in its last read, if it skipped one (a read skips at most one:
/// adjacent damage is merged, and a valid record ends a read).
fn new_skip<R: Read>(reader: &Reader<R>, seen: &mut usize) -> Option<Skipped> {
    let list = reader.skipped();
    (list.len() > *seen).then(|| {
        *seen = list.len();
        list[list.len() - 1]
    })
}

impl RecordingIndex {
    /// Read a recording once and index it; `geo` places the site on Earth.
    ///
    /// # Errors
    /// The file cannot be read, is not a recording or is of another format version, or holds no
    /// record at all.
    pub fn build(path: &Path, geo: Option<Geo>) -> Result<RecordingIndex, PlaybackError> {
        let io = |source| PlaybackError::Io {
            path: path.into(),
            source,
        };
        let mut reader = Reader::open(path)?;
        let header_len = reader.offset();
        let len = std::fs::metadata(path).map_err(io)?.len();
        let mut header = vec![0u8; usize::try_from(header_len).unwrap_or(0)];
        File::open(path)
            .and_then(|mut f| f.read_exact(&mut header))
            .map_err(io)?;
        let mut state = ViewState::new();
        state.set_geo(geo);
        let mut checkpoints = vec![Checkpoint {
            at_ns: i64::MIN,
            offset: header_len,
            state: state.clone(),
        }];
        let (mut start_ns, mut end_ns, mut records, mut since) = (None, i64::MIN, 0u64, 0u64);
        let mut seen = 0;
        loop {
            let offset = reader.offset();
            let item = reader.next();
            if let Some(skip) = new_skip(&reader, &mut seen).filter(|s| !is_torn_end(s, len)) {
                state.undecodable(state.time_ns, skipped_text(&skip, skip.offset));
            }
            let Some(item) = item else { break };
            match item {
                Ok(s) => {
                    let last = checkpoints.last().map_or(i64::MIN, |c| c.at_ns);
                    if records > 0
                        && (s.at.0 >= last.saturating_add(CHECKPOINT_NS) || since >= CHECKPOINT_RECORDS)
                    {
                        checkpoints.push(Checkpoint {
                            at_ns: state.time_ns,
                            offset,
                            state: state.clone(),
                        });
                        since = 0;
                    }
                    start_ns.get_or_insert(s.at.0);
                    end_ns = end_ns.max(s.at.0);
                    records += 1;
                    since += 1;
                    state.apply(&s);
                }
                Err(e) => return Err(e.into()),
            }
        }
        let Some(start_ns) = start_ns else {
            return Err(PlaybackError::Empty(path.into()));
        };
        // Say it from the first moment on, wherever the page seeks to.
        let tail = reader.skipped().last().filter(|s| is_torn_end(s, len)).copied();
        if let Some(t) = &tail {
            for c in &mut checkpoints {
                c.state.note_problem(start_ns, torn_text(t));
            }
        }
        Ok(RecordingIndex {
            path: path.into(),
            header,
            len,
            start_ns,
            end_ns,
            records,
            checkpoints,
            tail,
        })
    }

    /// First and last record's time, ns.
    pub fn span_ns(&self) -> (i64, i64) {
        (self.start_ns, self.end_ns)
    }

    /// Where the recording is torn, if it is.
    pub fn tail(&self) -> Option<&Skipped> {
        self.tail.as_ref()
    }

    /// Records and checkpoints.
    pub fn counts(&self) -> (u64, usize) {
        (self.records, self.checkpoints.len())
    }

    /// A reader of the records from byte `offset` on (the header is replayed in front of it).
    fn reader_at(&self, offset: u64) -> Result<RecordReader, PlaybackError> {
        let io = |source| PlaybackError::Io {
            path: self.path.clone(),
            source,
        };
        let mut f = File::open(&self.path).map_err(io)?;
        f.seek(SeekFrom::Start(offset)).map_err(io)?;
        let len = self.header.len() as u64 + self.len.saturating_sub(offset);
        let inner = Cursor::new(self.header.clone()).chain(BufReader::new(f));
        Ok(Reader::new(inner, len, &self.path)?)
    }
}

/// A position in a recording: the view there and the records after it.
pub struct Player {
    index: Arc<RecordingIndex>,
    state: ViewState,
    reader: RecordReader,
    /// File offset the reader started at (its offsets count the replayed header first).
    base: u64,
    /// Skipped stretches of the reader already counted.
    seen: usize,
    /// The first record after the position, read but not applied.
    pending: Option<Stamped>,
    position_ns: i64,
    pub playing: bool,
    pub speed: f64,
}

impl std::fmt::Debug for Player {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Player")
            .field("position_ns", &self.position_ns)
            .field("playing", &self.playing)
            .finish_non_exhaustive()
    }
}

impl Player {
    /// A player at the recording's first record, paused.
    ///
    /// # Errors
    /// The recording cannot be opened again.
    pub fn new(index: Arc<RecordingIndex>) -> Result<Player, PlaybackError> {
        let first = &index.checkpoints[0];
        let reader = index.reader_at(first.offset)?;
        let mut p = Player {
            state: first.state.clone(),
            base: first.offset,
            seen: 0,
            index,
            reader,
            pending: None,
            position_ns: i64::MIN,
            playing: false,
            speed: 1.0,
        };
        let start = p.index.start_ns;
        p.advance_to(start)?;
        Ok(p)
    }

    /// The view at the position.
    pub fn state(&self) -> &ViewState {
        &self.state
    }

    pub fn position_ns(&self) -> i64 {
        self.position_ns
    }

    /// Apply every record up to `t_ns` (recording time); returns whether any was applied.
    ///
    /// # Errors
    /// IO errors reading the recording.
    pub fn advance_to(&mut self, t_ns: i64) -> Result<bool, PlaybackError> {
        let t_ns = t_ns.min(self.index.end_ns);
        let mut any = false;
        loop {
            if let Some(s) = self.pending.take() {
                if s.at.0 > t_ns {
                    self.pending = Some(s);
                    break;
                }
                self.state.apply(&s);
                any = true;
            }
            let item = self.reader.next();
            if let Some(skip) = new_skip(&self.reader, &mut self.seen) {
                // Back to file offsets: the reader read the header, then the file from `base`.
                let offset = skip.offset - self.index.header.len() as u64 + self.base;
                if !is_torn_end(&Skipped { offset, ..skip }, self.index.len) {
                    self.state
                        .undecodable(self.state.time_ns, skipped_text(&skip, offset));
                }
            }
            match item {
                None => break,
                Some(Ok(s)) => self.pending = Some(s),
                Some(Err(e)) => return Err(e.into()),
            }
        }
        self.position_ns = self.position_ns.max(t_ns);
        Ok(any)
    }

    /// Go to `t_ns` (recording time, clamped to the recording): from the last checkpoint at or
    /// before it, applying the records in between.
    ///
    /// # Errors
    /// IO errors reading the recording.
    pub fn seek(&mut self, t_ns: i64) -> Result<(), PlaybackError> {
        let t_ns = t_ns.clamp(self.index.start_ns, self.index.end_ns);
        let i = self.index.checkpoints.partition_point(|c| c.at_ns <= t_ns).max(1) - 1;
        let c = &self.index.checkpoints[i];
        self.reader = self.index.reader_at(c.offset)?;
        self.base = c.offset;
        self.seen = 0;
        self.state = c.state.clone();
        self.pending = None;
        self.position_ns = i64::MIN;
        self.advance_to(t_ns).map(|_| ())
    }

    /// Take a page's command.
    ///
    /// # Errors
    /// IO errors of a seek.
    pub fn command(&mut self, c: Command) -> Result<(), PlaybackError> {
        match c {
            Command::Play => {
                if self.position_ns >= self.index.end_ns {
                    self.seek(self.index.start_ns)?;
                }
                self.playing = true;
            }
            Command::Pause => self.playing = false,
            Command::Seek(s) => {
                let t = self.index.start_ns.saturating_add((s.max(0.0) * 1e9) as i64);
                self.seek(t)?;
            }
            Command::Speed(x) => self.speed = x.clamp(0.05, 100.0),
        }
        Ok(())
    }

    /// Where the player is.
    pub fn info(&self) -> PlaybackInfo {
        let s = |ns: i64| ns as f64 * 1e-9;
        PlaybackInfo {
            playing: self.playing,
            speed: self.speed,
            start: s(self.index.start_ns),
            end: s(self.index.end_ns),
            position: s(self.position_ns),
            records: self.index.records,
            path: self.index.path.display().to_string(),
        }
    }
}

/// The playback producer: every `tick` it moves a playing position forward by the elapsed time
/// times the speed (stopping at the end), takes the page's commands, and publishes the view.
/// File reading runs on tokio's blocking pool, off the HTTP tasks' threads.
///
/// # Errors
/// IO errors reading the recording.
pub async fn run(
    mut player: Player,
    mut publisher: Publisher,
    mut commands: mpsc::Receiver<Command>,
    tick: Duration,
    shutdown: CancellationToken,
) -> Result<(), PlaybackError> {
    let mut timer = tokio::time::interval(tick);
    timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut last = tokio::time::Instant::now();
    publisher.publish_with(Arc::new(player.state().clone()), Some(player.info()));
    loop {
        let command = tokio::select! {
            () = shutdown.cancelled() => return Ok(()),
            _ = timer.tick() => None,
            c = commands.recv() => c,
        };
        let now = tokio::time::Instant::now();
        let elapsed = now.duration_since(last);
        last = now;
        let moved = command.is_some() || player.playing;
        player = tokio::task::spawn_blocking(move || -> Result<Player, PlaybackError> {
            match command {
                Some(c) => player.command(c)?,
                None if player.playing => {
                    let step = (elapsed.as_secs_f64() * player.speed * 1e9) as i64;
                    let to = player.position_ns.saturating_add(step);
                    player.advance_to(to)?;
                    if player.position_ns >= player.index.end_ns {
                        player.playing = false;
                    }
                }
                None => {}
            }
            Ok(player)
        })
        .await
        .map_err(|e| PlaybackError::Io {
            path: PathBuf::from("<playback task>"),
            source: std::io::Error::other(e.to_string()),
        })??;
        if moved {
            publisher.publish_with(Arc::new(player.state().clone()), Some(player.info()));
        }
    }
}

#[cfg(test)]
mod tests;
