//! The intrinsics file of the book (`g7cam.txt`, written by the calibration program of §4.11 and
//! read by `kmatrix_read`, §2.10): the 9 entries of K row by row.

use std::path::Path;

use super::{number, parse_error, read_text, tokens, write_text};
use crate::camera::Intrinsics;
use crate::error::Result;

/// Parse the 9 numbers of K, row by row. `file` names the source in errors.
pub fn parse_intrinsics(text: &str, file: &str) -> Result<Intrinsics> {
    let toks = tokens(text);
    if toks.len() != 9 {
        let line = toks.get(9).map_or(toks.last().map_or(1, |t| t.0), |t| t.0);
        return Err(parse_error(
            file,
            line,
            format!("expected the 9 entries of K, found {} numbers", toks.len()),
        ));
    }
    let mut k = nalgebra::Matrix3::zeros();
    for (i, (line, t)) in toks.iter().enumerate() {
        k[(i / 3, i % 3)] = number(file, *line, t)?;
    }
    Intrinsics::from_k(&k).map_err(|e| parse_error(file, toks[0].0, e.to_string()))
}

/// Format K as the book writes it: three lines of three numbers.
pub fn format_intrinsics(k: &Intrinsics) -> String {
    let m = k.k();
    (0..3)
        .map(|r| format!("{:e} {:e} {:e}\n", m[(r, 0)], m[(r, 1)], m[(r, 2)]))
        .collect()
}

/// Read an intrinsics file (the JSON form when the name ends in `.json`).
pub fn read_intrinsics(path: &Path) -> Result<Intrinsics> {
    if super::is_json(path) {
        return super::read_json(path);
    }
    parse_intrinsics(&read_text(path)?, &path.display().to_string())
}

/// Write an intrinsics file (the JSON form when the name ends in `.json`).
pub fn write_intrinsics(path: &Path, k: &Intrinsics) -> Result<()> {
    if super::is_json(path) {
        return super::write_json(path, k);
    }
    write_text(path, &format_intrinsics(k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::VisionError;

    #[test]
    fn round_trip_and_errors() {
        let k = Intrinsics {
            f1: 1228.4,
            f2: 1228.4,
            s: 0.25,
            u0: 639.5,
            v0: 359.5,
            width: None,
            height: None,
            distortion: crate::lens::Distortion::None,
        };
        let back = parse_intrinsics(&format_intrinsics(&k), "k.txt").unwrap();
        assert_eq!(back, k);
        let e = parse_intrinsics("1 0 2\n0 1 x\n0 0 1\n", "k.txt").unwrap_err();
        assert!(matches!(e, VisionError::Parse { line: 2, .. }), "{e}");
        assert!(e.to_string().starts_with("k.txt:2:"));
        assert!(parse_intrinsics("1 0 2\n0 1 3\n", "k.txt").is_err());
        assert!(parse_intrinsics("1 0 2\n5 1 3\n0 0 1", "k.txt").is_err());
    }

    #[test]
    fn book_demo_file() {
        let Some(path) = vfxgraph_testdata::path("book-demo/g7cam.txt") else {
            return;
        };
        let k = read_intrinsics(&path).unwrap();
        assert!((k.f1 - 1228.4022637363655).abs() < 1e-9);
        assert_eq!((k.u0, k.v0, k.s), (639.5, 359.5, 0.0));
    }
}
