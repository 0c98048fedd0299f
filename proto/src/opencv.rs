//! Import of OpenCV `FileStorage` calibration files (XML), as in MultiviewX's `calibrations/`.
//!
//! An intrinsic file holds `camera_matrix` (3×3) and `distortion_coefficients` (4 or 5:
//! `k1 k2 p1 p2 [k3]`, or a longer vector whose extra terms are all zero); an extrinsic file
//! holds `rvec` (Rodrigues) and `tvec`, world → camera. Both are `opencv-matrix` nodes with
//! `<rows>`, `<cols>`, `<dt>` and `<data>`. OpenCV does not store the image size beside the
//! camera matrix unless the calibration tool wrote `image_width` / `image_height`; when absent
//! it comes from [`ImportOptions::image_size`], else it is estimated as `2·(cx, cy)` (logged).
//!
//! **Handedness.** Some tools (MultiviewX, made in Unity) solve extrinsics in a left-handed
//! world: every visible point then has *negative* camera depth. OpenCV's projection ignores the
//! sign, but our camera model (and back-projection) requires points in front to have positive
//! depth. Such a camera is *mirrored* on import: with `S` the reflection of one world axis,
//! `R' = −R·S`, `t' = −t` is a proper rotation describing the same camera in the reflected world
//! `X' = S·X`; camera coordinates are negated as a whole (`X_c' = −X_c`), so depth becomes
//! positive and every point projects to the same pixel as before. Which axis is a choice
//! ([`MirrorAxis`]): reflecting **y** (the default) keeps the world z-up as `proto` requires
//! (for MultiviewX, whose left-handed world is z-up, a person's head stays at z = +1.8 m) but
//! ground points map `(x, y) → (x, −y)` — convert annotations with [`MirrorAxis::apply`];
//! reflecting **z** keeps ground points unchanged but leaves a z-*down* world. [`Handedness::Auto`]
//! decides per camera: a camera whose optical axis (+z_c) meets the ground plane z = 0 *behind*
//! it — i.e. it sees the ground only at negative depth — is mirrored. When the axis is parallel
//! to the ground the sign of the world origin's depth decides. Auto assumes each camera looks
//! at the ground; pass [`Handedness::AsIs`] or [`Handedness::Mirror`] when that is not so.

use crate::camera::{CameraModel, Distortion, Intrinsics, Pose};
use nalgebra::{Matrix3, Rotation3, Vector3};
use quick_xml::events::Event;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A calibration file that could not be used.
#[derive(Debug, Error)]
pub enum OpenCvError {
    #[error("cannot read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: {problem}")]
    Format { path: String, problem: String },
}

fn format_err(path: &Path, problem: impl Into<String>) -> OpenCvError {
    OpenCvError::Format {
        path: path.display().to_string(),
        problem: problem.into(),
    }
}

/// How to treat the handedness of imported extrinsics (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Handedness {
    /// Mirror a camera exactly when it sees the ground at negative depth.
    #[default]
    Auto,
    /// Use `rvec`, `tvec` unchanged.
    AsIs,
    /// Always mirror: `R' = −R·S`, `t' = −t`.
    Mirror,
}

/// Which world axis a mirrored import reflects (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MirrorAxis {
    /// `(x, y, z) → (x, −y, z)`: the world stays z-up; ground points change sign in y.
    #[default]
    Y,
    /// `(x, y, z) → (x, y, −z)`: ground points are unchanged; up becomes −z.
    Z,
}

impl MirrorAxis {
    /// The reflection `S` as a diagonal.
    pub fn diagonal(self) -> Vector3<f64> {
        match self {
            MirrorAxis::Y => Vector3::new(1.0, -1.0, 1.0),
            MirrorAxis::Z => Vector3::new(1.0, 1.0, -1.0),
        }
    }

    /// A point of the file's world expressed in the mirrored world, `S·X`.
    pub fn apply(self, p: &Vector3<f64>) -> Vector3<f64> {
        p.component_mul(&self.diagonal())
    }
}

/// Options of an import.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImportOptions {
    pub handedness: Handedness,
    pub mirror_axis: MirrorAxis,
    /// Image `(width, height)` when the intrinsic file does not say.
    pub image_size: Option<(u32, u32)>,
}

/// One imported camera, and whether its pose was mirrored into a right-handed world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImportedCamera {
    pub model: CameraModel,
    pub mirrored: bool,
}

/// One `opencv-matrix` node, or a scalar node (`rows = cols = 1`).
#[derive(Clone, Debug, PartialEq)]
struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

/// Top-level nodes of a `FileStorage` document: for each, its own text and its children's.
#[derive(Default, Debug)]
struct Node {
    text: String,
    children: BTreeMap<String, String>,
}

fn read_text(path: &Path) -> Result<String, OpenCvError> {
    std::fs::read_to_string(path).map_err(|source| OpenCvError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// Parse the XML into the nodes directly under `<opencv_storage>`.
fn parse_storage(path: &Path, text: &str) -> Result<BTreeMap<String, Node>, OpenCvError> {
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().trim_text(true);
    let mut stack: Vec<String> = Vec::new();
    let mut nodes: BTreeMap<String, Node> = BTreeMap::new();
    let mut saw_root = false;
    loop {
        let event = reader
            .read_event()
            .map_err(|e| format_err(path, format!("not well-formed XML: {e}")))?;
        match event {
            Event::Start(e) => {
                let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
                if stack.is_empty() {
                    if name != "opencv_storage" {
                        return Err(format_err(
                            path,
                            format!("expected root element <opencv_storage>, found <{name}>"),
                        ));
                    }
                    saw_root = true;
                } else if stack.len() == 1 {
                    nodes.entry(name.clone()).or_default();
                }
                stack.push(name);
            }
            Event::Text(t) => {
                let s = t
                    .decode()
                    .map_err(|e| format_err(path, format!("bad text encoding: {e}")))?;
                match stack.len() {
                    2 => {
                        if let Some(n) = nodes.get_mut(&stack[1]) {
                            n.text.push_str(&s);
                            n.text.push(' ');
                        }
                    }
                    3 => {
                        if let Some(n) = nodes.get_mut(&stack[1]) {
                            let c = n.children.entry(stack[2].clone()).or_default();
                            c.push_str(&s);
                            c.push(' ');
                        }
                    }
                    _ => {}
                }
            }
            Event::End(_) => {
                stack.pop();
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !saw_root {
        return Err(format_err(path, "no <opencv_storage> element"));
    }
    Ok(nodes)
}

fn parse_numbers(path: &Path, what: &str, text: &str) -> Result<Vec<f64>, OpenCvError> {
    text.split_whitespace()
        .map(|s| {
            s.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format_err(path, format!("{what}: `{s}` is not a finite number")))
        })
        .collect()
}

/// The matrix (or scalar) node `name`, or an error naming the file and the node.
fn matrix(path: &Path, nodes: &BTreeMap<String, Node>, name: &str) -> Result<Matrix, OpenCvError> {
    let node = nodes
        .get(name)
        .ok_or_else(|| format_err(path, format!("missing <{name}>")))?;
    if node.children.is_empty() {
        let data = parse_numbers(path, name, &node.text)?;
        if data.len() != 1 {
            return Err(format_err(
                path,
                format!("<{name}>: expected a matrix or one number"),
            ));
        }
        return Ok(Matrix {
            rows: 1,
            cols: 1,
            data,
        });
    }
    let child = |c: &str| {
        node.children
            .get(c)
            .map(|s| s.trim().to_owned())
            .ok_or_else(|| format_err(path, format!("<{name}>: missing <{c}>")))
    };
    let dim = |c: &str| -> Result<usize, OpenCvError> {
        let s = child(c)?;
        s.parse()
            .map_err(|_| format_err(path, format!("<{name}><{c}>: `{s}` is not a count")))
    };
    let (rows, cols) = (dim("rows")?, dim("cols")?);
    let dt = child("dt")?;
    if !matches!(dt.as_str(), "d" | "f") {
        return Err(format_err(
            path,
            format!("<{name}><dt>: expected `d` or `f` (floating point), found `{dt}`"),
        ));
    }
    let data = parse_numbers(path, name, &child("data")?)?;
    if data.len() != rows * cols {
        return Err(format_err(
            path,
            format!(
                "<{name}>: {rows}×{cols} matrix needs {} numbers, <data> has {}",
                rows * cols,
                data.len()
            ),
        ));
    }
    Ok(Matrix { rows, cols, data })
}

fn vector3(path: &Path, nodes: &BTreeMap<String, Node>, name: &str) -> Result<[f64; 3], OpenCvError> {
    let m = matrix(path, nodes, name)?;
    match m.data[..] {
        [a, b, c] => Ok([a, b, c]),
        _ => Err(format_err(
            path,
            format!(
                "<{name}>: expected 3 numbers, found a {}×{} matrix",
                m.rows, m.cols
            ),
        )),
    }
}

/// Read an intrinsic file: camera matrix and distortion coefficients. The image size comes
/// from `image_width`/`image_height` nodes when present, else is estimated as `2·(cx, cy)`.
///
/// # Errors
/// Unreadable file, or a missing / malformed matrix, naming the file.
pub fn read_intrinsics(path: &Path) -> Result<(Intrinsics, Distortion), OpenCvError> {
    read_intrinsics_with(path, None)
}

/// [`read_intrinsics`], with the image size to use when the file does not give one.
///
/// # Errors
/// Unreadable file, or a missing / malformed matrix, naming the file.
pub fn read_intrinsics_with(
    path: &Path,
    image_size: Option<(u32, u32)>,
) -> Result<(Intrinsics, Distortion), OpenCvError> {
    parse_intrinsics(path, &read_text(path)?, image_size)
}

/// [`read_intrinsics_with`] on the text of a file; `path` names it in errors.
///
/// # Errors
/// A missing / malformed matrix, naming the file.
pub fn parse_intrinsics(
    path: &Path,
    text: &str,
    image_size: Option<(u32, u32)>,
) -> Result<(Intrinsics, Distortion), OpenCvError> {
    let nodes = parse_storage(path, text)?;
    let k = matrix(path, &nodes, "camera_matrix")?;
    if (k.rows, k.cols) != (3, 3) {
        return Err(format_err(
            path,
            format!("<camera_matrix>: expected 3×3, found {}×{}", k.rows, k.cols),
        ));
    }
    let m = &k.data;
    let (fx, skew, cx, fy, cy) = (m[0], m[1], m[2], m[4], m[5]);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(format_err(
            path,
            format!("<camera_matrix>: focal lengths {fx}, {fy} are not positive"),
        ));
    }
    if skew.abs() > 1e-9 * fx || m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] != 1.0 {
        return Err(format_err(
            path,
            "<camera_matrix>: expected [fx 0 cx; 0 fy cy; 0 0 1] (no skew)",
        ));
    }
    let d = matrix(path, &nodes, "distortion_coefficients")?;
    let c = &d.data;
    if !matches!(c.len(), 4 | 5 | 8 | 12 | 14) {
        return Err(format_err(
            path,
            format!(
                "<distortion_coefficients>: expected 4, 5, 8, 12 or 14 numbers, found {}",
                c.len()
            ),
        ));
    }
    if c.iter().skip(5).any(|x| *x != 0.0) {
        return Err(format_err(
            path,
            "<distortion_coefficients>: rational / thin-prism / tilt terms (beyond k3) are not supported",
        ));
    }
    let distortion = Distortion {
        k1: c[0],
        k2: c[1],
        p1: c[2],
        p2: c[3],
        k3: c.get(4).copied().unwrap_or(0.0),
    };
    let size_node = |name: &str| -> Result<Option<u32>, OpenCvError> {
        if !nodes.contains_key(name) {
            return Ok(None);
        }
        let v = matrix(path, &nodes, name)?.data[0];
        if v >= 1.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0 {
            Ok(Some(v as u32))
        } else {
            Err(format_err(
                path,
                format!("<{name}>: {v} is not a positive whole number"),
            ))
        }
    };
    let (width, height) = match (size_node("image_width")?, size_node("image_height")?, image_size) {
        (Some(w), Some(h), _) => (w, h),
        (_, _, Some(size)) => size,
        _ => {
            let size = (
                (2.0 * cx).round().max(1.0) as u32,
                (2.0 * cy).round().max(1.0) as u32,
            );
            tracing::warn!(
                file = %path.display(),
                width = size.0,
                height = size.1,
                "no image size in the calibration; estimated from the principal point"
            );
            size
        }
    };
    Ok((
        Intrinsics {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        },
        distortion,
    ))
}

/// Read an extrinsic file: `rvec` and `tvec`, world → camera, with [`Handedness::Auto`].
///
/// # Errors
/// Unreadable file, or a missing / malformed vector, naming the file.
pub fn read_extrinsics(path: &Path) -> Result<Pose, OpenCvError> {
    Ok(read_extrinsics_with(path, &ImportOptions::default())?.0)
}

/// Read an extrinsic file with an explicit handedness rule; also says whether it mirrored.
///
/// # Errors
/// Unreadable file, or a missing / malformed vector, naming the file.
pub fn read_extrinsics_with(path: &Path, options: &ImportOptions) -> Result<(Pose, bool), OpenCvError> {
    parse_extrinsics(path, &read_text(path)?, options)
}

/// [`read_extrinsics_with`] on the text of a file; `path` names it in errors.
///
/// # Errors
/// A missing / malformed vector, naming the file.
pub fn parse_extrinsics(
    path: &Path,
    text: &str,
    options: &ImportOptions,
) -> Result<(Pose, bool), OpenCvError> {
    let nodes = parse_storage(path, text)?;
    let pose = Pose::from_rvec_tvec(vector3(path, &nodes, "rvec")?, vector3(path, &nodes, "tvec")?);
    let mirror = match options.handedness {
        Handedness::AsIs => false,
        Handedness::Mirror => true,
        Handedness::Auto => sees_ground_behind(&pose),
    };
    Ok(if mirror {
        (mirror_pose(&pose, options.mirror_axis), true)
    } else {
        (pose, false)
    })
}

/// Whether the camera sees the ground plane z = 0 only at negative depth: its optical axis
/// meets the plane behind the centre (or, for an axis parallel to the ground, the world origin
/// has negative depth).
pub fn sees_ground_behind(pose: &Pose) -> bool {
    let centre = pose.centre();
    let axis = pose.rotation.inverse() * Vector3::z();
    if axis.z.abs() > 1e-9 {
        -centre.z / axis.z < 0.0
    } else {
        pose.translation.z < 0.0
    }
}

/// The same camera in the world reflected along `axis` (`X' = S·X`): `R' = −R·S`, `t' = −t`, so
/// `X_c' = −X_c` and depths change sign.
pub fn mirror_pose(pose: &Pose, axis: MirrorAxis) -> Pose {
    let r: Matrix3<f64> = -(pose.rotation.matrix() * Matrix3::from_diagonal(&axis.diagonal()));
    Pose {
        rotation: Rotation3::from_matrix_unchecked(r),
        translation: -pose.translation,
    }
}

/// Read one camera from its intrinsic and extrinsic files.
///
/// # Errors
/// Either file unreadable or malformed, naming it.
pub fn read_camera(
    intrinsic: &Path,
    extrinsic: &Path,
    options: &ImportOptions,
) -> Result<ImportedCamera, OpenCvError> {
    let (intrinsics, distortion) = read_intrinsics_with(intrinsic, options.image_size)?;
    let (pose, mirrored) = read_extrinsics_with(extrinsic, options)?;
    Ok(ImportedCamera {
        model: CameraModel {
            intrinsics,
            distortion,
            pose,
        },
        mirrored,
    })
}

/// Every camera of a calibration directory laid out as MultiviewX's: `intrinsic/intr_<ID>.xml`
/// and `extrinsic/extr_<ID>.xml`, keyed by `<ID>`, with default [`ImportOptions`].
///
/// # Errors
/// See [`read_calibration_dir_with`].
pub fn read_calibration_dir(dir: &Path) -> Result<BTreeMap<String, CameraModel>, OpenCvError> {
    Ok(read_calibration_dir_with(dir, &ImportOptions::default())?
        .into_iter()
        .map(|(id, c)| (id, c.model))
        .collect())
}

/// [`read_calibration_dir`] with explicit options, keeping whether each camera was mirrored.
///
/// # Errors
/// An unreadable directory, no `intr_*.xml` at all, an intrinsic file without its extrinsic
/// partner, or any malformed file — each naming the path.
pub fn read_calibration_dir_with(
    dir: &Path,
    options: &ImportOptions,
) -> Result<BTreeMap<String, ImportedCamera>, OpenCvError> {
    let intrinsic_dir = dir.join("intrinsic");
    let entries = std::fs::read_dir(&intrinsic_dir).map_err(|source| OpenCvError::Io {
        path: intrinsic_dir.display().to_string(),
        source,
    })?;
    let mut ids: Vec<(String, PathBuf)> = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|source| OpenCvError::Io {
            path: intrinsic_dir.display().to_string(),
            source,
        })?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Some(id) = name.strip_prefix("intr_").and_then(|s| s.strip_suffix(".xml"))
            && !id.is_empty()
        {
            ids.push((id.to_owned(), entry.path()));
        }
    }
    if ids.is_empty() {
        return Err(format_err(&intrinsic_dir, "no intr_<ID>.xml files"));
    }
    let mut out = BTreeMap::new();
    for (id, intr) in ids {
        let extr = dir.join("extrinsic").join(format!("extr_{id}.xml"));
        if !extr.is_file() {
            return Err(format_err(
                &extr,
                format!(
                    "missing: camera `{id}` has {} but no extrinsic file",
                    intr.display()
                ),
            ));
        }
        out.insert(id, read_camera(&intr, &extr, options)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
