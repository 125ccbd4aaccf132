//! Marked points (`points2d.txt`, input of the point-cloud calibration, book §8; also the
//! `calib_video_projs.txt` of the HDR camera): blocks `Frame f` / `Npoints n` / n lines `u v`,
//! with the same n scene points in the same order in every block.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use super::{data_lines, number, parse_error, read_text, write_text};
use crate::error::Result;
use crate::points::Points2d;

/// The points marked on one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarkedFrame {
    /// Frame number.
    pub frame: usize,
    /// The marked pixels, in scene-point order.
    pub points: Points2d,
}

/// Marked points on several frames (JSON: `{"frames": [{"frame": f, "points": [[u, v], …]}, …]}`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkedPoints {
    /// The blocks, in file order.
    pub frames: Vec<MarkedFrame>,
}

/// Parse a marked-points file; every block must have the same number of points.
pub fn parse_marked_points(text: &str, file: &str) -> Result<MarkedPoints> {
    let lines = data_lines(text);
    let mut frames = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let (l, t) = &lines[i];
        if t.len() != 2 || t[0] != "Frame" {
            return Err(parse_error(file, *l, "expected `Frame <number>`"));
        }
        let frame: usize = t[1]
            .parse()
            .map_err(|_| parse_error(file, *l, format!("bad frame number `{}`", t[1])))?;
        let (l2, t2) = lines
            .get(i + 1)
            .ok_or_else(|| parse_error(file, *l, "missing `Npoints <n>`"))?;
        if t2.len() != 2 || t2[0] != "Npoints" {
            return Err(parse_error(file, *l2, "expected `Npoints <n>`"));
        }
        let n: usize = t2[1]
            .parse()
            .map_err(|_| parse_error(file, *l2, format!("bad point count `{}`", t2[1])))?;
        // The count is checked against the lines left before it sizes anything.
        if n > lines.len() - (i + 2) {
            return Err(parse_error(
                file,
                *l2,
                format!("frame {frame}: expected {n} points"),
            ));
        }
        let mut pts = Vec::with_capacity(n);
        for k in 0..n {
            let (lk, tk) = lines.get(i + 2 + k).ok_or_else(|| {
                parse_error(file, *l2, format!("frame {frame}: expected {n} points"))
            })?;
            if tk.len() != 2 {
                return Err(parse_error(file, *lk, "expected `u v`"));
            }
            pts.push(Point2::new(
                number(file, *lk, tk[0])?,
                number(file, *lk, tk[1])?,
            ));
        }
        if let Some(first) = frames.first().map(|f: &MarkedFrame| f.points.len()) {
            if first != n {
                return Err(parse_error(
                    file,
                    *l2,
                    format!("frame {frame} has {n} points, the first block {first}"),
                ));
            }
        }
        frames.push(MarkedFrame {
            frame,
            points: Points2d(pts),
        });
        i += 2 + n;
    }
    Ok(MarkedPoints { frames })
}

/// Format marked points as the book writes them.
pub fn format_marked_points(m: &MarkedPoints) -> String {
    let mut s = String::new();
    for f in &m.frames {
        let _ = writeln!(s, "Frame {}\nNpoints {}", f.frame, f.points.len());
        for p in &f.points.0 {
            let _ = writeln!(s, "{} {}", p.x, p.y);
        }
        s.push('\n');
    }
    s
}

/// Read a marked-points file (the JSON form when the name ends in `.json`).
pub fn read_marked_points(path: &Path) -> Result<MarkedPoints> {
    if super::is_json(path) {
        return super::read_json(path);
    }
    parse_marked_points(&read_text(path)?, &path.display().to_string())
}

/// Write a marked-points file (the JSON form when the name ends in `.json`).
pub fn write_marked_points(path: &Path, m: &MarkedPoints) -> Result<()> {
    if super::is_json(path) {
        return super::write_json(path, m);
    }
    write_text(path, &format_marked_points(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn book_demo_files_and_round_trip() {
        for name in ["points2d.txt", "calib_video_projs.txt"] {
            let Some(path) = vfxgraph_testdata::path(&format!("book-demo/{name}")) else {
                continue;
            };
            let m = read_marked_points(&path).unwrap();
            assert!(m.frames.len() >= 4);
            let text = format_marked_points(&m);
            assert_eq!(parse_marked_points(&text, "x").unwrap(), m);
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(serde_json::from_str::<MarkedPoints>(&json).unwrap(), m);
        }
        let e = parse_marked_points("Frame 1\nNpoints 2\n1 2\n", "m.txt").unwrap_err();
        assert!(e.to_string().starts_with("m.txt:2:"), "{e}");
        let e = parse_marked_points(
            "Frame 1\nNpoints 1\n1 2\nFrame 2\nNpoints 2\n1 2\n3 4\n",
            "m.txt",
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("m.txt:5:"), "{e}");
    }

    /// Regression (fuzzing): `Npoints 2147483647` reserved 34 GB before the lines were counted.
    #[test]
    fn a_huge_point_count_is_an_error_without_allocating() {
        let e = parse_marked_points("Frame 68\nNpoints 2147483647\n1 2\n", "m.txt").unwrap_err();
        let m = e.to_string();
        assert!(
            m.starts_with("m.txt:2:") && m.contains("expected 2147483647 points"),
            "{m}"
        );
        let e = parse_marked_points("Frame 1\nNpoints 18446744073709551615\n", "m.txt");
        assert!(e.unwrap_err().to_string().starts_with("m.txt:2:"));
    }
}
