//! The cameras file of the book (output of the matchmove and relaxation programs, read by
//! `rtmatrix_read`/`mmove_read`, §2.10): per frame a line `Frame i`, the 9 entries of R row by
//! row, then the 3 entries of t. The camera maps X to K(RX + t).

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{number, parse_error, read_text, tokens, write_text};
use crate::camera::Pose;
use crate::error::Result;

/// The extrinsics of one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FramePose {
    /// Frame number.
    pub frame: usize,
    /// [R|t] of that frame (JSON: `"R"`, `"t"` flattened into the frame object).
    #[serde(flatten)]
    pub pose: Pose,
    /// This frame's focal length (px, the x one; y keeps the intrinsics' aspect) when the lens
    /// zooms; `None`: the path's intrinsics'. JSON: `"focal"`, omitted when `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal: Option<f64>,
}

/// The extrinsics of a sequence of frames (JSON: `{"frames": [{"frame": i, "R": …, "t": …}, …]}`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraPath {
    /// One pose per frame, in file order.
    pub frames: Vec<FramePose>,
    /// The intrinsics K shared by every frame, when known (the book's cameras file does not carry
    /// them: it is paired with a `g7cam.txt`). JSON: `"intrinsics"`, omitted when unknown.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intrinsics: Option<crate::camera::Intrinsics>,
}

impl CameraPath {
    /// The intrinsics of the `i`-th frame of the path: the path's, with the frame's own focal
    /// length when it has one (a zoom); `None` without intrinsics.
    pub fn intrinsics_at(&self, i: usize) -> Option<crate::camera::Intrinsics> {
        let mut k = self.intrinsics.clone()?;
        if let Some(f) = self.frames.get(i).and_then(|f| f.focal) {
            k.f2 *= f / k.f1;
            k.f1 = f;
        }
        Some(k)
    }

    /// Whether the focal length changes along the path (frames carry their own).
    pub fn zooms(&self) -> bool {
        self.frames.iter().any(|f| f.focal.is_some())
    }
}

/// Parse a cameras file.
pub fn parse_cameras(text: &str, file: &str) -> Result<CameraPath> {
    let toks = tokens(text);
    let mut frames = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let (line, t) = toks[i];
        if t != "Frame" {
            return Err(parse_error(
                file,
                line,
                format!("expected `Frame`, found `{t}`"),
            ));
        }
        let (fl, ft) = *toks
            .get(i + 1)
            .ok_or_else(|| parse_error(file, line, "missing frame number"))?;
        let frame: usize = ft
            .parse()
            .map_err(|_| parse_error(file, fl, format!("bad frame number `{ft}`")))?;
        let mut v = [0.0; 12];
        for (k, slot) in v.iter_mut().enumerate() {
            let (l, tok) = *toks.get(i + 2 + k).ok_or_else(|| {
                parse_error(
                    file,
                    toks.last().map_or(line, |t| t.0),
                    format!("frame {frame}: expected 12 numbers (R, t)"),
                )
            })?;
            *slot = number(file, l, tok)?;
        }
        let r = nalgebra::Matrix3::from_row_slice(&v[..9]);
        let t = nalgebra::Vector3::new(v[9], v[10], v[11]);
        frames.push(FramePose {
            frame,
            pose: Pose::new(r, t),
            focal: None,
        });
        i += 14;
    }
    Ok(CameraPath {
        frames,
        intrinsics: None,
    })
}

/// Format a cameras file as the book writes it.
pub fn format_cameras(path: &CameraPath) -> String {
    let mut s = String::new();
    for f in &path.frames {
        let (r, t) = (&f.pose.r, &f.pose.t);
        let _ = writeln!(s, "Frame {}", f.frame);
        for row in 0..3 {
            let _ = writeln!(s, "{:e} {:e} {:e}", r[(row, 0)], r[(row, 1)], r[(row, 2)]);
        }
        let _ = writeln!(s, "\n{:e} {:e} {:e}\n", t.x, t.y, t.z);
    }
    s
}

/// Read a cameras file (the JSON form when the name ends in `.json`).
pub fn read_cameras(path: &Path) -> Result<CameraPath> {
    if super::is_json(path) {
        return super::read_json(path);
    }
    parse_cameras(&read_text(path)?, &path.display().to_string())
}

/// Write a cameras file (the JSON form when the name ends in `.json`).
pub fn write_cameras(path: &Path, cameras: &CameraPath) -> Result<()> {
    if super::is_json(path) {
        return super::write_json(path, cameras);
    }
    write_text(path, &format_cameras(cameras))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::axis_angle_to_r;
    use nalgebra::Vector3;

    #[test]
    fn round_trip_text_and_json() {
        let cams = CameraPath {
            frames: (0..3)
                .map(|i| FramePose {
                    frame: i * 2,
                    pose: Pose::new(
                        axis_angle_to_r(&Vector3::new(0.1 * i as f64, 0.2, -0.3)),
                        Vector3::new(1.0, i as f64, 3.5),
                    ),
                    focal: None,
                })
                .collect(),
            intrinsics: None,
        };
        let text = format_cameras(&cams);
        assert!(text.starts_with("Frame 0\n"));
        assert_eq!(parse_cameras(&text, "c.txt").unwrap(), cams);
        let json = serde_json::to_string(&cams).unwrap();
        assert!(
            json.starts_with("{\"frames\":[{\"frame\":0,\"R\":[["),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<CameraPath>(&json).unwrap(), cams);
        let e = parse_cameras("Frame 0\n1 0 0\n0 1 0\n0 0 1\n\n1 2\n", "c.txt").unwrap_err();
        assert!(e.to_string().contains("c.txt:"), "{e}");
        let e = parse_cameras("Frame 0\n1 0 0\n0 1 0\n0 0 1\n\n1 2 z\n", "c.txt").unwrap_err();
        assert!(e.to_string().starts_with("c.txt:6:"), "{e}");
    }
}
