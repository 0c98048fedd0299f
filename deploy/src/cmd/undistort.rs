//! `ocelli undistort`: check any calibration against OpenCV. Reads CSV rows in the format of
//! `shared/vectors/undistort_opencv.csv` (header line included) on standard input and writes
//! one `x,y` line per row: the exact undistortion of pixel `(u, v)` at full `f64` precision
//! (shortest round-trip formatting), or with `--one-step` paper 000's approximation.
//!
//! Columns are found by header name: `width height f cx cy k1 k2 p1 p2 u v` are required,
//! `k3` is optional (0 when absent); any other column (`camera`, the expected `x y`) is ignored.

use anyhow::{Context, Result, bail};
use nalgebra::Vector2;
use proto::camera::{CameraModel, Distortion, Intrinsics, Pose};
use std::io::{BufRead, Write};
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print paper 000's one-step approximation instead of the exact undistortion.
    #[arg(long)]
    pub one_step: bool,
}

pub fn run(args: Args) -> Result<ExitCode> {
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    match undistort_csv(stdin.lock(), &mut stdout.lock(), args.one_step) {
        // The reader went away (`| head`): not an error of ours.
        Err(e)
            if e.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe) =>
        {
            Ok(ExitCode::SUCCESS)
        }
        other => other.map(|()| ExitCode::SUCCESS),
    }
}

const REQUIRED: [&str; 11] = [
    "width", "height", "f", "cx", "cy", "k1", "k2", "p1", "p2", "u", "v",
];

/// Column positions of the fields we read, from the header line.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    required: [usize; 11],
    k3: Option<usize>,
    count: usize,
}

impl Columns {
    /// Find the columns in a header line.
    ///
    /// # Errors
    /// A required column is missing.
    pub fn from_header(header: &str) -> Result<Columns> {
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let find = |name: &str| names.iter().position(|n| *n == name);
        let mut required = [0; 11];
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            *slot = find(name).with_context(|| {
                format!(
                    "line 1: header has no `{name}` column (expected a header naming {})",
                    REQUIRED.join(",")
                )
            })?;
        }
        Ok(Columns {
            required,
            k3: find("k3"),
            count: names.len(),
        })
    }
}

/// Parse one data row into a camera and a pixel. `line_no` is 1-based, for errors.
///
/// # Errors
/// Wrong number of fields, a field that is not a number, or a camera that makes no sense
/// (non-positive focal length or image size), naming the line and the column.
pub fn parse_row(columns: &Columns, line: &str, line_no: usize) -> Result<(CameraModel, Vector2<f64>)> {
    let fields: Vec<&str> = line.split(',').map(str::trim).collect();
    if fields.len() != columns.count {
        bail!(
            "line {line_no}: expected {} fields, found {}",
            columns.count,
            fields.len()
        );
    }
    let num = |i: usize, name: &str| -> Result<f64> {
        let s = fields[i];
        match s.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => bail!("line {line_no}: column `{name}`: `{s}` is not a finite number"),
        }
    };
    let mut v = [0.0; 11];
    for ((slot, &i), name) in v.iter_mut().zip(&columns.required).zip(REQUIRED) {
        *slot = num(i, name)?;
    }
    let [width, height, f, cx, cy, k1, k2, p1, p2, u, vv] = v;
    let size = |x: f64, name: &str| -> Result<u32> {
        if x >= 1.0 && x <= f64::from(u32::MAX) && x.fract() == 0.0 {
            Ok(x as u32)
        } else {
            bail!("line {line_no}: column `{name}`: {x} is not a positive whole number")
        }
    };
    if f <= 0.0 {
        bail!("line {line_no}: column `f`: focal length {f} is not positive");
    }
    let k3 = match columns.k3 {
        Some(i) => num(i, "k3")?,
        None => 0.0,
    };
    let camera = CameraModel {
        intrinsics: Intrinsics {
            fx: f,
            fy: f,
            cx,
            cy,
            width: size(width, "width")?,
            height: size(height, "height")?,
        },
        distortion: Distortion { k1, k2, p1, p2, k3 },
        pose: Pose::from_rvec_tvec([0.0; 3], [0.0; 3]),
    };
    Ok((camera, Vector2::new(u, vv)))
}

/// The whole command on any reader and writer.
///
/// # Errors
/// An empty input, a bad header or row (naming the line), a pixel whose undistortion does not
/// converge, or a write failure.
pub fn undistort_csv(input: impl BufRead, out: &mut impl Write, one_step: bool) -> Result<()> {
    let mut lines = input.lines();
    let header = lines
        .next()
        .context("line 1: empty input, expected a CSV header")?
        .context("line 1")?;
    let columns = Columns::from_header(&header)?;
    for (i, line) in lines.enumerate() {
        let line_no = i + 2;
        let line = line.with_context(|| format!("line {line_no}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let (camera, px) = parse_row(&columns, &line, line_no)?;
        let p = if one_step {
            camera.undistort_one_step(&px)
        } else {
            camera.undistort(&px).with_context(|| format!("line {line_no}"))?
        };
        writeln!(out, "{},{}", p.x, p.y)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vectors() -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/vectors/undistort_opencv.csv");
        std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("reference vectors missing at {} ({e})", path.display()))
    }

    fn run(input: &str, one_step: bool) -> Result<String> {
        let mut out = Vec::new();
        undistort_csv(input.as_bytes(), &mut out, one_step)?;
        Ok(String::from_utf8(out).unwrap())
    }

    /// Errors between the command's output and the vectors' expected `x, y` columns.
    fn errors(input: &str, output: &str) -> Vec<f64> {
        let header: Vec<&str> = input.lines().next().unwrap().split(',').collect();
        let (xi, yi) = (
            header.iter().position(|h| *h == "x").unwrap(),
            header.iter().position(|h| *h == "y").unwrap(),
        );
        input
            .lines()
            .skip(1)
            .zip(output.lines())
            .map(|(row, got)| {
                let f: Vec<f64> = row.split(',').map(|s| s.parse().unwrap()).collect();
                let g: Vec<f64> = got.split(',').map(|s| s.parse().unwrap()).collect();
                assert_eq!(g.len(), 2, "output line `{got}`");
                ((g[0] - f[xi]).powi(2) + (g[1] - f[yi]).powi(2)).sqrt()
            })
            .collect()
    }

    #[test]
    fn reproduces_the_opencv_vectors() {
        let input = vectors();
        let out = run(&input, false).unwrap();
        assert_eq!(out.lines().count(), input.lines().count() - 1);
        let worst = errors(&input, &out).into_iter().fold(0.0, f64::max);
        assert!(worst <= 1e-7, "worst exact error {worst:e}");
    }

    #[test]
    fn one_step_prints_the_approximation() {
        let input = vectors();
        let out = run(&input, true).unwrap();
        assert_eq!(out.lines().count(), input.lines().count() - 1);
        let worst = errors(&input, &out).into_iter().fold(0.0, f64::max);
        assert!(worst > 1e-4, "one-step unexpectedly exact ({worst:e})");
    }

    #[test]
    fn output_is_shortest_round_trip() {
        let input = "camera,width,height,f,cx,cy,k1,k2,p1,p2,u,v\n0,640,480,400,320,240,0,0,0,0,420,240\n";
        assert_eq!(run(input, false).unwrap(), "0.25,0\n");
        // k3 is read when present.
        let with_k3 = "width,height,f,cx,cy,k1,k2,p1,p2,k3,u,v\n640,480,400,320,240,0,0,0,0,0.5,720,240\n";
        let got: Vec<f64> = run(with_k3, false)
            .unwrap()
            .trim()
            .split(',')
            .map(|s| s.parse().unwrap())
            .collect();
        // Distorted x = 1 must come from an undistorted x with x (1 + 0.5 x⁶) = 1.
        assert!(
            (got[0] * (1.0 + 0.5 * got[0].powi(6)) - 1.0).abs() < 1e-12,
            "{got:?}"
        );
    }

    #[test]
    fn bad_rows_name_the_line() {
        let header = "camera,width,height,f,cx,cy,k1,k2,p1,p2,u,v,x,y\n";
        let good = "0,640,480,400,320,240,-0.2,0.05,0,0,100,100,0,0\n";
        let cases = [
            (
                "0,640,480,400,320,240,-0.2,0.05,0,0,abc,100,0,0\n",
                "line 3: column `u`: `abc` is not a finite number",
            ),
            (
                "0,640,480,400,320,240,-0.2,0.05,0,0,100\n",
                "line 3: expected 14 fields, found 11",
            ),
            (
                "0,640,480,0,320,240,-0.2,0.05,0,0,100,100,0,0\n",
                "line 3: column `f`",
            ),
            (
                "0,640.5,480,400,320,240,-0.2,0.05,0,0,100,100,0,0\n",
                "line 3: column `width`",
            ),
            (
                "0,640,480,400,320,240,-0.2,0.05,0,0,NaN,100,0,0\n",
                "line 3: column `u`",
            ),
        ];
        for (bad, want) in cases {
            let e = format!("{:#}", run(&format!("{header}{good}{bad}"), false).unwrap_err());
            assert!(e.contains(want), "expected `{want}` in `{e}`");
        }
        let e = format!("{:#}", run("camera,u,v\n1,2,3\n", false).unwrap_err());
        assert!(e.contains("line 1") && e.contains("`width`"), "{e}");
        let e = format!("{:#}", run("", false).unwrap_err());
        assert!(e.contains("line 1: empty input"), "{e}");
    }
}
