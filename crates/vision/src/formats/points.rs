//! Plain point lists: one point per line, `u v` for 2D (e.g. `calib_projs.txt`, the VGG
//! `.corners`) and `X Y Z` for 3D (the n×3 matrix of the point-cloud calibration, book §8; the
//! VGG `p3d`).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Point2, Point3};

use super::{data_lines, number, parse_error, read_text, write_text};
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

/// Parse `X Y Z` lines.
pub fn parse_points3d(text: &str, file: &str) -> Result<Points3d> {
    Ok(Points3d(
        parse_rows::<3>(text, file)?
            .into_iter()
            .map(|r| Point3::new(r[0], r[1], r[2]))
            .collect(),
    ))
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
    fn book_calib_projs() {
        let Some(path) = vfxgraph_testdata::path("book-demo/calib_projs.txt") else {
            return;
        };
        let p = read_points2d(&path).unwrap();
        assert_eq!(p.len(), 6);
        assert_eq!(p.0[0], Point2::new(1420.0, 1845.0));
    }
}
