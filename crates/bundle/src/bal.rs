//! The "Bundle Adjustment in the Large" text format (Agarwal et al., ECCV 2010;
//! grail.cs.washington.edu/projects/bal).
//!
//! ```text
//! <num_cameras> <num_points> <num_observations>
//! <camera> <point> <x> <y>            × num_observations  (centred pixels, y up)
//! rx ry rz tx ty tz f k1 k2           × num_cameras       (one value per line)
//! X Y Z                               × num_points
//! ```
//! Every camera gets its own [`CameraModel::Bal`] intrinsics block; nothing is fixed and the gauge
//! is [`Gauge::Free`], as in Ceres' `bundle_adjuster`.

use std::io::Write;
use std::path::Path;

use nalgebra::{Vector2, Vector3};

use super::camera_model::{CameraModel, Intrinsics};
use super::error::BundleError;
use super::problem::{CameraPose, Gauge, Observation, Point, Problem};

struct Tokens<'a> {
    iter: std::str::SplitAsciiWhitespace<'a>,
    text: &'a str,
    index: usize,
}

impl<'a> Tokens<'a> {
    fn line_of(&self, tok: &str) -> usize {
        let off = tok.as_ptr() as usize - self.text.as_ptr() as usize;
        self.text[..off].bytes().filter(|&b| b == b'\n').count() + 1
    }

    fn err(&self, line: usize, message: String) -> BundleError {
        BundleError::Parse {
            line,
            token: self.index,
            message,
        }
    }

    fn next_str(&mut self, what: &str) -> Result<&'a str, BundleError> {
        match self.iter.next() {
            Some(t) => {
                self.index += 1;
                Ok(t)
            }
            None => {
                let line = self.text.lines().count();
                Err(self.err(line, format!("unexpected end of file, expected {what}")))
            }
        }
    }

    fn usize(&mut self, what: &str) -> Result<usize, BundleError> {
        let t = self.next_str(what)?;
        t.parse().map_err(|_| {
            self.err(
                self.line_of(t),
                format!("expected {what} (an integer), got {t:?}"),
            )
        })
    }

    fn f64(&mut self, what: &str) -> Result<f64, BundleError> {
        let t = self.next_str(what)?;
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(self.err(self.line_of(t), format!("non-finite {what}: {t:?}"))),
            Err(_) => Err(self.err(
                self.line_of(t),
                format!("expected {what} (a number), got {t:?}"),
            )),
        }
    }
}

/// Parses a BAL problem from text (see the module documentation for the format).
pub fn read_bal_str(text: &str) -> Result<Problem, BundleError> {
    let mut tk = Tokens {
        iter: text.split_ascii_whitespace(),
        text,
        index: 0,
    };
    let nc = tk.usize("number of cameras")?;
    let np = tk.usize("number of points")?;
    let no = tk.usize("number of observations")?;
    // Guard against absurd headers before allocating.
    let max = text.len() / 2 + 1;
    if nc > max || np > max || no > max {
        return Err(tk.err(1, "header counts exceed the file size".into()));
    }
    let mut observations = Vec::with_capacity(no);
    for _ in 0..no {
        let camera = tk.usize("camera index")?;
        let point = tk.usize("point index")?;
        let x = tk.f64("observation x")?;
        let y = tk.f64("observation y")?;
        if camera >= nc || point >= np {
            return Err(BundleError::IndexOutOfRange {
                what: format!(
                    "observation {} refers to camera {camera} of {nc}, point {point} of {np}",
                    observations.len()
                ),
            });
        }
        observations.push(Observation {
            camera,
            point,
            pixel: Vector2::new(x, y),
            weight: 1.0,
        });
    }
    let mut cameras = Vec::with_capacity(nc);
    let mut intrinsics = Vec::with_capacity(nc);
    for i in 0..nc {
        let mut v = [0.0; 9];
        for x in v.iter_mut() {
            *x = tk.f64("camera parameter")?;
        }
        cameras.push(CameraPose {
            rotation: Vector3::new(v[0], v[1], v[2]),
            translation: Vector3::new(v[3], v[4], v[5]),
            intrinsics: i,
            fixed: false,
        });
        intrinsics.push(Intrinsics::bal(v[6], v[7], v[8], false));
    }
    let mut points = Vec::with_capacity(np);
    for _ in 0..np {
        let x = tk.f64("point coordinate")?;
        let y = tk.f64("point coordinate")?;
        let z = tk.f64("point coordinate")?;
        points.push(Point {
            position: Vector3::new(x, y, z),
            fixed: false,
        });
    }
    if let Some(t) = tk.iter.next() {
        let line = tk.line_of(t);
        return Err(tk.err(line, format!("trailing data {t:?}")));
    }
    Ok(Problem {
        cameras,
        intrinsics,
        points,
        observations,
        gauge: Gauge::Free,
        priors: Vec::new(),
    })
}

/// Reads a BAL file (see [`read_bal_str`]).
pub fn read_bal(path: impl AsRef<Path>) -> Result<Problem, BundleError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| BundleError::Io {
        path: path.display().to_string(),
        source,
    })?;
    read_bal_str(&text)
}

/// Writes a problem whose cameras all use [`CameraModel::Bal`] intrinsics as a BAL file, with
/// full precision (round-trips exactly through [`read_bal`]).
pub fn write_bal(problem: &Problem, path: impl AsRef<Path>) -> Result<(), BundleError> {
    let path = path.as_ref();
    for (i, c) in problem.cameras.iter().enumerate() {
        match problem.intrinsics.get(c.intrinsics) {
            Some(k) if k.model == CameraModel::Bal => {}
            _ => {
                return Err(BundleError::InvalidProblem(format!(
                    "camera {i} does not use a BAL intrinsics block"
                )))
            }
        }
    }
    let io = |source| BundleError::Io {
        path: path.display().to_string(),
        source,
    };
    // Formatted in memory, then written atomically (no half-written file on an error).
    let mut w: Vec<u8> = Vec::new();
    let mut body = || -> std::io::Result<()> {
        writeln!(
            w,
            "{} {} {}",
            problem.cameras.len(),
            problem.points.len(),
            problem.observations.len()
        )?;
        for o in &problem.observations {
            writeln!(
                w,
                "{} {} {:e} {:e}",
                o.camera, o.point, o.pixel.x, o.pixel.y
            )?;
        }
        for c in &problem.cameras {
            let k = &problem.intrinsics[c.intrinsics].params[..3];
            for v in c
                .rotation
                .iter()
                .chain(c.translation.iter())
                .chain(k.iter())
            {
                writeln!(w, "{v:e}")?;
            }
        }
        for p in &problem.points {
            for v in p.position.iter() {
                writeln!(w, "{v:e}")?;
            }
        }
        Ok(())
    };
    body().map_err(io)?;
    vfxgraph_fsutil::atomic_write(path, &w).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TINY: &str = "2 2 3\n0 0 1.0 2.0\n1 0 -1.0 0.5\n1 1 0.25 0.5\n\
        0.01\n0.02\n0.03\n0.1\n0.2\n-5\n500\n0.01\n0.0\n\
        0\n0\n0\n0\n0\n-6\n600\n0\n0\n\
        0.1\n0.2\n0.3\n-0.1\n0.2\n0.1\n";

    #[test]
    fn parses_and_round_trips() {
        let p = read_bal_str(TINY).unwrap();
        assert_eq!(p.cameras.len(), 2);
        assert_eq!(p.observations.len(), 3);
        assert_eq!(
            p.intrinsics[1].params,
            [600.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        );
        let dir = std::env::temp_dir().join(format!("bal_rt_{}.txt", std::process::id()));
        write_bal(&p, &dir).unwrap();
        let q = read_bal(&dir).unwrap();
        std::fs::remove_file(&dir).ok();
        assert_eq!(p, q);
    }

    #[test]
    fn rejects_bad_input() {
        assert!(matches!(
            read_bal_str("2 2"),
            Err(BundleError::Parse { .. })
        ));
        assert!(matches!(
            read_bal_str(&TINY.replace("0.25", "nan")),
            Err(BundleError::Parse { .. })
        ));
        assert!(matches!(
            read_bal_str(&TINY.replace("1 1 0.25", "1 7 0.25")),
            Err(BundleError::IndexOutOfRange { .. })
        ));
        assert!(matches!(
            read_bal_str(&format!("{TINY} 4")),
            Err(BundleError::Parse { .. })
        ));
        assert!(read_bal("/nonexistent/bal.txt").is_err());
    }
}
