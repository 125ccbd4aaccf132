//! Plain point lists: `u v` per line for 2D (e.g. `calib_projs.txt`, the VGG `.corners`), and
//! for 3D the 3·n numbers of n points `X Y Z` in any whitespace layout — one point per line (the
//! n×3 matrix of the point-cloud calibration, book §8; the VGG `p3d`) or one number per line, as
//! the book's `singlecam` and `pclcalib` programs read and write `calib_points.txt` and
//! `points3d.txt` (GSL's `gsl_matrix_fscanf`/`fprintf` of an n×3 matrix).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Point2, Point3};

use super::{data_lines, number, parse_error, read_text, tokens, write_text};
use crate::error::Result;
use crate::points::{Points2d, Points3d};

fn parse_rows<const N: usize>(text: &str, file: &str) -> Result<Vec<[f64; N]>> {
    data_lines(text)
        .into_iter()
        .map(|(l, t)| {
            if t.len() != N {
                return Err(parse_error(
                    file,
                    l,
                    format!("expected {N} numbers, found {}", t.len()),
                ));
            }
            let mut row = [0.0; N];
            for (k, tok) in t.iter().enumerate() {
                row[k] = number(file, l, tok)?;
            }
            Ok(row)
        })
        .collect()
}

/// Parse `u v` lines.
pub fn parse_points2d(text: &str, file: &str) -> Result<Points2d> {
    Ok(Points2d(
        parse_rows::<2>(text, file)?
            .into_iter()
            .map(|r| Point2::new(r[0], r[1]))
            .collect(),
    ))
}

/// Parse 3·n numbers as n points `X Y Z`, in any whitespace layout (see the module doc); a count
/// that is not a multiple of 3 is an error naming the count and the line of the incomplete point.
pub fn parse_points3d(text: &str, file: &str) -> Result<Points3d> {
    let toks = tokens(text);
    if !toks.len().is_multiple_of(3) {
        let first_left = toks[toks.len() - toks.len() % 3].0;
        return Err(parse_error(
            file,
            first_left,
            format!(
                "expected 3 numbers (X Y Z) per point, found {} numbers: {} point(s) and {} left over",
                toks.len(),
                toks.len() / 3,
                toks.len() % 3
            ),
        ));
    }
    let mut points = Vec::with_capacity(toks.len() / 3);
    for p in toks.chunks_exact(3) {
        let v = |k: usize| number(file, p[k].0, p[k].1);
        points.push(Point3::new(v(0)?, v(1)?, v(2)?));
    }
    Ok(Points3d(points))
}

/// Read a 2D point list (the JSON form `[[u, v], …]` when the name ends in `.json`).
pub fn read_points2d(path: &Path) -> Result<Points2d> {
    if super::is_json(path) {
        return super::read_json(path);
    }
    parse_points2d(&read_text(path)?, &path.display().to_string())
}

/// Read a 3D point list (the JSON form `[[x, y, z], …]` when the name ends in `.json`).
pub fn read_points3d(path: &Path) -> Result<Points3d> {
    if super::is_json(path) {
        return super::read_json(path);
    }
    parse_points3d(&read_text(path)?, &path.display().to_string())
}

/// Format a 2D point list.
pub fn format_points2d(p: &Points2d) -> String {
    let mut s = String::new();
    for x in &p.0 {
        let _ = writeln!(s, "{} {}", x.x, x.y);
    }
    s
}

/// Format a 3D point list.
pub fn format_points3d(p: &Points3d) -> String {
    let mut s = String::new();
    for x in &p.0 {
        let _ = writeln!(s, "{} {} {}", x.x, x.y, x.z);
    }
    s
}

/// Write a 2D point list (JSON when the name ends in `.json`).
pub fn write_points2d(path: &Path, p: &Points2d) -> Result<()> {
    if super::is_json(path) {
        return super::write_json(path, p);
    }
    write_text(path, &format_points2d(p))
}

/// Write a 3D point list (JSON when the name ends in `.json`).
pub fn write_points3d(path: &Path, p: &Points3d) -> Result<()> {
    if super::is_json(path) {
        return super::write_json(path, p);
    }
    write_text(path, &format_points3d(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_errors() {
        let p = Points3d(vec![
            Point3::new(1.5, -2.0, 3.25),
            Point3::new(0.0, 1e-3, 7.0),
        ]);
        assert_eq!(parse_points3d(&format_points3d(&p), "p").unwrap(), p);
        let q = Points2d(vec![Point2::new(1420.0, 1845.0)]);
        assert_eq!(parse_points2d(&format_points2d(&q), "q").unwrap(), q);
        let e = parse_points2d("1 2\n\n3 4 5\n", "q.txt").unwrap_err();
        assert!(e.to_string().starts_with("q.txt:3:"), "{e}");
        assert!(parse_points2d("1 nan\n", "q").is_err());
    }

    #[test]
    fn points3d_in_any_layout() {
        let p = Points3d(vec![
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(-4.5, 0.0, 6e2),
        ]);
        for text in [
            "1 2 3\n-4.5 0 6e2\n",
            "1\n2\n3\n-4.5\n0\n600\n",
            "1 2 3 -4.5 0 600",
            "# X Y Z\n1 2\n3 -4.5\n\n0 600 # last\n",
        ] {
            assert_eq!(parse_points3d(text, "p").unwrap(), p, "{text:?}");
        }
        assert_eq!(parse_points3d("", "p").unwrap(), Points3d(vec![]));
        let e = parse_points3d("1\n2\n3\n4\n5\n", "calib_points.txt").unwrap_err();
        let m = e.to_string();
        assert!(m.starts_with("calib_points.txt:4:"), "{m}");
        assert!(m.contains("found 5 numbers"), "{m}");
        let e = parse_points3d("1 2 3\n4\n", "p.txt")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.txt:2:") && e.contains("found 4 numbers"),
            "{e}"
        );
        let e = parse_points3d("1 2 3\n4 inf 6\n", "p.txt")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.txt:2:") && e.contains("`inf`"), "{e}");
    }

    #[test]
    fn book_calib_projs() {
        let Some(path) = vfxgraph_testdata::path("book-demo/calib_projs.txt") else {
            return;
        };
        let p = read_points2d(&path).unwrap();
        assert_eq!(p.len(), 6);
        assert_eq!(p.0[0], Point2::new(1420.0, 1845.0));
    }
}
