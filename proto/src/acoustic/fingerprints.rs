//! The fingerprint database (paper 001 §3.3's acoustic cues): the weighted ILD vector
//! surveyed at each of n known positions, with the settings it was analysed with and the room
//! it was surveyed in.
//!
//! File format: JSON, `{"format": "ocelli-fingerprints", "version": 1, "room": "<signature>",
//! "region": [xmin, ymin, xmax, ymax], "settings": {..}, "fingerprints": [{"position": [x, y],
//! "values": [..]}, ..]}`. The header is read first, so a file of another format or version is
//! refused with that reason rather than a field error; a file whose room signature is not the
//! world's is refused by [`FingerprintDb::check_room`]. Positions must lie on a regular lattice
//! (missing nodes allowed), which the B-spline interpolation needs.

use super::spline::{Lattice, SplineSurface};
use super::{AcousticError, IldSettings, IldVector, correlation, invalid, validate_frequencies};
use crate::scenario::World;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;

/// The `format` field of a fingerprint file.
pub const FINGERPRINT_FORMAT: &str = "ocelli-fingerprints";
/// The version this build writes and reads.
pub const FINGERPRINT_VERSION: u32 = 1;
/// How far (m) a survey position may sit from its lattice node.
pub const LATTICE_TOLERANCE_M: f64 = 0.01;

/// A hash of a world's geometry (box and walls, to the millimetre): fingerprints are only
/// valid in the room they were surveyed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub struct RoomSignature(pub u64);

impl RoomSignature {
    /// FNV-1a (64 bit) over the world's min, max and each wall's ends and height, rounded to
    /// millimetres so that the same file parsed twice always agrees.
    pub fn of(world: &World) -> Self {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |v: f64| {
            let mm = (v * 1000.0).round() as i64;
            for b in mm.to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        world.min.iter().chain(&world.max).for_each(|v| eat(*v));
        for w in &world.walls {
            [w.from[0], w.from[1], w.to[0], w.to[1], w.height]
                .into_iter()
                .for_each(&mut eat);
        }
        RoomSignature(h)
    }
}

impl fmt::Display for RoomSignature {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:016x}", self.0)
    }
}

impl From<RoomSignature> for String {
    fn from(s: RoomSignature) -> String {
        s.to_string()
    }
}

impl TryFrom<String> for RoomSignature {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        u64::from_str_radix(&s, 16)
            .map(RoomSignature)
            .map_err(|_| format!("room signature {s:?} is not 16 hex digits"))
    }
}

/// One acoustic cue: the weighted ILD values (at the database's frequencies) surveyed with the
/// source at `position`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fingerprint {
    pub position: [f64; 2],
    pub values: Vec<f64>,
}

#[derive(Deserialize)]
struct Header {
    format: String,
    version: u32,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct FingerprintFile {
    format: String,
    version: u32,
    room: RoomSignature,
    region: [f64; 4],
    settings: IldSettings,
    fingerprints: Vec<Fingerprint>,
}

/// How the correlations at the survey lattice become a surface (eq. 17).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SplineFit {
    /// The correlations are the control points (the paper's eq. 17): smooth, within [0, 1].
    #[default]
    ControlPoints,
    /// The surface passes through the correlations at the survey positions (may overshoot
    /// slightly between them).
    Interpolating,
}

/// The fingerprints of one room, ready to turn an ILD vector into a likelihood surface.
#[derive(Clone, Debug, PartialEq)]
pub struct FingerprintDb {
    room: RoomSignature,
    region: [f64; 4],
    settings: IldSettings,
    frequencies: Vec<f64>,
    fingerprints: Vec<Fingerprint>,
    lattice: Lattice,
    /// Lattice node of each fingerprint.
    nodes: Vec<usize>,
}

impl FingerprintDb {
    /// A database surveyed in `world` (its box is the region, its geometry the signature).
    ///
    /// # Errors
    /// Invalid settings, no fingerprints, a fingerprint with the wrong number of values or a
    /// non-finite one, a position outside the world's box, or positions off a regular lattice.
    pub fn new(
        world: &World,
        settings: IldSettings,
        fingerprints: Vec<Fingerprint>,
    ) -> Result<Self, AcousticError> {
        let region = [world.min[0], world.min[1], world.max[0], world.max[1]];
        Self::from_parts(RoomSignature::of(world), region, settings, fingerprints)
    }

    fn from_parts(
        room: RoomSignature,
        region: [f64; 4],
        settings: IldSettings,
        fingerprints: Vec<Fingerprint>,
    ) -> Result<Self, AcousticError> {
        settings.validate()?;
        let frequencies = settings.sampled_frequencies();
        validate_frequencies("fingerprint settings", &frequencies)?;
        if fingerprints.is_empty() {
            return Err(invalid("fingerprints", "none: survey at least one position"));
        }
        if !(region.iter().all(|v| v.is_finite()) && region[0] <= region[2] && region[1] <= region[3]) {
            return Err(invalid("fingerprint region", format!("{region:?} is not a box")));
        }
        for (i, f) in fingerprints.iter().enumerate() {
            let [x, y] = f.position;
            if !(x >= region[0] && x <= region[2] && y >= region[1] && y <= region[3]) {
                return Err(invalid(
                    format!("fingerprint {i} at ({x}, {y})"),
                    format!(
                        "outside the world [{}, {}]–[{}, {}]",
                        region[0], region[1], region[2], region[3]
                    ),
                ));
            }
            if f.values.len() != frequencies.len() {
                return Err(invalid(
                    format!("fingerprint {i} at ({x}, {y})"),
                    format!("{} values for {} frequencies", f.values.len(), frequencies.len()),
                ));
            }
            if let Some(v) = f.values.iter().find(|v| !v.is_finite()) {
                return Err(invalid(
                    format!("fingerprint {i} at ({x}, {y})"),
                    format!("value {v} is not finite"),
                ));
            }
        }
        let positions: Vec<[f64; 2]> = fingerprints.iter().map(|f| f.position).collect();
        let (lattice, nodes) = Lattice::fit(&positions, LATTICE_TOLERANCE_M)?;
        Ok(FingerprintDb {
            room,
            region,
            settings,
            frequencies,
            fingerprints,
            lattice,
            nodes,
        })
    }

    pub fn room(&self) -> RoomSignature {
        self.room
    }

    /// `[xmin, ymin, xmax, ymax]` of the world the survey was made in.
    pub fn region(&self) -> [f64; 4] {
        self.region
    }

    pub fn settings(&self) -> &IldSettings {
        &self.settings
    }

    /// Ω, the frequencies every fingerprint and observation is sampled at.
    pub fn frequencies(&self) -> &[f64] {
        &self.frequencies
    }

    pub fn fingerprints(&self) -> &[Fingerprint] {
        &self.fingerprints
    }

    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The file's text.
    pub fn to_json(&self) -> String {
        let file = FingerprintFile {
            format: FINGERPRINT_FORMAT.into(),
            version: FINGERPRINT_VERSION,
            room: self.room,
            region: self.region,
            settings: self.settings.clone(),
            fingerprints: self.fingerprints.clone(),
        };
        serde_json::to_string_pretty(&file).expect("fingerprints always serialize")
    }

    /// Parse a fingerprint file's text; `origin` names it in errors.
    ///
    /// # Errors
    /// Not JSON, another format, another version, a missing or wrong field, or any problem
    /// [`FingerprintDb::new`] reports.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, AcousticError> {
        let parse = |e: serde_json::Error| AcousticError::Parse {
            origin: origin.into(),
            message: e.to_string(),
        };
        let header: Header = serde_json::from_str(text).map_err(parse)?;
        if header.format != FINGERPRINT_FORMAT {
            return Err(AcousticError::Format {
                origin: origin.into(),
                found: header.format,
                expected: FINGERPRINT_FORMAT,
            });
        }
        if header.version != FINGERPRINT_VERSION {
            return Err(AcousticError::Version {
                origin: origin.into(),
                found: header.version,
                expected: FINGERPRINT_VERSION,
            });
        }
        let file: FingerprintFile = serde_json::from_str(text).map_err(parse)?;
        Self::from_parts(file.room, file.region, file.settings, file.fingerprints).map_err(|e| match e {
            AcousticError::Invalid { what, problem } => AcousticError::Parse {
                origin: origin.into(),
                message: format!("{what}: {problem}"),
            },
            AcousticError::Lattice(m) => AcousticError::Parse {
                origin: origin.into(),
                message: format!("fingerprint positions: {m}"),
            },
            other => other,
        })
    }

    /// Read a fingerprint file.
    ///
    /// # Errors
    /// The file cannot be read, or any problem [`FingerprintDb::from_json`] reports.
    pub fn load(path: &Path) -> Result<Self, AcousticError> {
        let text = std::fs::read_to_string(path).map_err(|error| AcousticError::Io {
            path: path.into(),
            error,
        })?;
        Self::from_json(&text, &path.display().to_string())
    }

    /// Write the file.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn save(&self, path: &Path) -> Result<(), AcousticError> {
        std::fs::write(path, self.to_json()).map_err(|error| AcousticError::Io {
            path: path.into(),
            error,
        })
    }

    /// Refuse a database surveyed in another room than `world`; `origin` names the database.
    ///
    /// # Errors
    /// [`AcousticError::RoomMismatch`] with both signatures.
    pub fn check_room(&self, world: &World, origin: &str) -> Result<(), AcousticError> {
        let expected = RoomSignature::of(world);
        if self.room == expected {
            Ok(())
        } else {
            Err(AcousticError::RoomMismatch {
                origin: origin.into(),
                found: self.room,
                expected,
            })
        }
    }

    /// Check an observation is sampled at the database's frequencies.
    ///
    /// # Errors
    /// Another count or another frequency (beyond 1e-6 relative).
    pub fn check_frequencies(&self, observed: &IldVector) -> Result<(), AcousticError> {
        observed.validate()?;
        if observed.frequencies_hz.len() != self.frequencies.len() {
            return Err(AcousticError::FrequencyCount {
                found: observed.frequencies_hz.len(),
                expected: self.frequencies.len(),
            });
        }
        for (index, (&found, &expected)) in observed.frequencies_hz.iter().zip(&self.frequencies).enumerate()
        {
            if (found - expected).abs() > 1e-6 * expected.abs().max(1.0) {
                return Err(AcousticError::FrequencyMismatch {
                    index,
                    found,
                    expected,
                });
            }
        }
        Ok(())
    }

    /// eq. 16 against every fingerprint, in fingerprint order.
    ///
    /// # Errors
    /// As [`FingerprintDb::check_frequencies`].
    pub fn correlations(&self, observed: &IldVector) -> Result<Vec<f64>, AcousticError> {
        self.check_frequencies(observed)?;
        Ok(self
            .fingerprints
            .iter()
            .map(|f| correlation(&observed.values, &f.values))
            .collect())
    }

    /// eq. 17: the correlations at the lattice nodes, through the cubic B-spline basis (`fit`
    /// says whether they are the control points, as the paper prints it, or interpolated). A
    /// node no fingerprint was taken at gets the inverse-square-distance weighted mean of the
    /// fingerprints' correlations.
    ///
    /// # Errors
    /// As [`FingerprintDb::check_frequencies`].
    pub fn likelihood_surface(
        &self,
        observed: &IldVector,
        fit: SplineFit,
    ) -> Result<SplineSurface, AcousticError> {
        let x = self.correlations(observed)?;
        let values = self.node_values(&x);
        match fit {
            SplineFit::ControlPoints => SplineSurface::from_control_points(&self.lattice, &values),
            SplineFit::Interpolating => SplineSurface::interpolate(&self.lattice, &values),
        }
    }

    /// One value per lattice node from one value per fingerprint (missing nodes filled).
    pub fn node_values(&self, per_fingerprint: &[f64]) -> Vec<f64> {
        let mut values = vec![f64::NAN; self.lattice.len()];
        for (&node, &v) in self.nodes.iter().zip(per_fingerprint) {
            values[node] = v;
        }
        for (node, v) in values.iter_mut().enumerate() {
            if v.is_nan() {
                let [x, y] = self.lattice.node_position(node);
                let (mut sum, mut weight) = (0.0, 0.0);
                for (f, &c) in self.fingerprints.iter().zip(per_fingerprint) {
                    let d2 = (f.position[0] - x).powi(2) + (f.position[1] - y).powi(2);
                    sum += c / d2;
                    weight += 1.0 / d2;
                }
                *v = sum / weight;
            }
        }
        values
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn world() -> World {
        toml::from_str("min = [0.0, 0.0, 0.0]\nmax = [4.0, 3.0, 2.5]\nwalls = [{ from = [2.0, 0.0], to = [2.0, 1.5], height = 2.5 }]").unwrap()
    }

    fn settings() -> IldSettings {
        IldSettings {
            f_min_hz: 100.0,
            f_max_hz: 400.0,
            frequencies: 4,
            ..IldSettings::default()
        }
    }

    /// A 3×2 lattice, each fingerprint a distinct direction in ILD space.
    fn db() -> FingerprintDb {
        let mut fps = Vec::new();
        for j in 0..2 {
            for i in 0..3 {
                let k = (j * 3 + i) as f64;
                fps.push(Fingerprint {
                    position: [0.5 + i as f64, 0.5 + j as f64],
                    values: vec![k.cos(), k.sin(), (2.0 * k).cos(), 1.0],
                });
            }
        }
        FingerprintDb::new(&world(), settings(), fps).unwrap()
    }

    #[test]
    fn correlation_peaks_at_the_source_fingerprint() {
        let db = db();
        let source = 4; // (1.5, 1.5)
        let obs = IldVector::new(
            db.frequencies().to_vec(),
            db.fingerprints()[source].values.clone(),
        )
        .unwrap();
        let x = db.correlations(&obs).unwrap();
        let best = (0..x.len()).max_by(|a, b| x[*a].total_cmp(&x[*b])).unwrap();
        assert_eq!(best, source);
        assert_abs_diff_eq!(x[source], 1.0, epsilon = 1e-12);
        // The interpolated surface peaks there too, at the knot, among a fine sweep.
        let s = db.likelihood_surface(&obs, SplineFit::Interpolating).unwrap();
        let mut peak = (f64::MIN, 0.0, 0.0);
        for a in 0..=40 {
            for b in 0..=20 {
                let (px, py) = (0.5 + a as f64 * 0.05, 0.5 + b as f64 * 0.05);
                let v = s.eval(px, py);
                if v > peak.0 {
                    peak = (v, px, py);
                }
            }
        }
        assert!(
            (peak.1 - 1.5).abs() <= 0.1 && (peak.2 - 1.5).abs() <= 0.1,
            "peak at {peak:?}"
        );
    }

    #[test]
    fn round_trips_through_its_file_format() {
        let db = db();
        let back = FingerprintDb::from_json(&db.to_json(), "mem").unwrap();
        assert_eq!(back, db);
        back.check_room(&world(), "mem").unwrap();
    }

    #[test]
    fn another_room_version_or_format_is_refused_clearly() {
        let db = db();
        let mut other = world();
        other.walls[0].to = [2.0, 2.0];
        let e = db.check_room(&other, "fp.json").unwrap_err();
        assert!(matches!(e, AcousticError::RoomMismatch { .. }));
        assert!(e.to_string().contains("another room"), "{e}");
        let text = db.to_json().replace("\"version\": 1", "\"version\": 7");
        let e = FingerprintDb::from_json(&text, "fp.json").unwrap_err();
        assert!(
            e.to_string().contains("version 7") && e.to_string().contains("fp.json"),
            "{e}"
        );
        let e = FingerprintDb::from_json("{\"format\": \"wav\", \"version\": 1}", "x.json").unwrap_err();
        assert!(e.to_string().contains("not an Ocelli fingerprint file"), "{e}");
        let e = FingerprintDb::from_json("not json", "x.json").unwrap_err();
        assert!(e.to_string().contains("x.json"), "{e}");
    }

    #[test]
    fn bad_fingerprints_are_refused() {
        let outside = vec![Fingerprint {
            position: [5.0, 1.0],
            values: vec![0.0; 4],
        }];
        let e = FingerprintDb::new(&world(), settings(), outside).unwrap_err();
        assert!(e.to_string().contains("outside the world"), "{e}");
        let short = vec![Fingerprint {
            position: [1.0, 1.0],
            values: vec![0.0; 3],
        }];
        let e = FingerprintDb::new(&world(), settings(), short).unwrap_err();
        assert!(e.to_string().contains("3 values for 4"), "{e}");
        let obs = IldVector::new(vec![1.0, 2.0], vec![0.0, 0.0]).unwrap();
        assert!(matches!(
            db().correlations(&obs),
            Err(AcousticError::FrequencyCount { .. })
        ));
    }

    #[test]
    fn signature_depends_on_geometry_only_to_the_millimetre() {
        let a = world();
        let mut b = world();
        b.max[0] += 1e-5;
        assert_eq!(RoomSignature::of(&a), RoomSignature::of(&b));
        b.max[0] += 0.01;
        assert_ne!(RoomSignature::of(&a), RoomSignature::of(&b));
        let s = RoomSignature::of(&a);
        assert_eq!(RoomSignature::try_from(s.to_string()).unwrap(), s);
    }
}
