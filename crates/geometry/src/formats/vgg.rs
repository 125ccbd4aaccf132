//! Files of the Oxford VGG multi-view data sets (used as ground truth by the tests): 3×4 camera
//! matrices (`*.P`) and the n-view correspondence table (`nview-corners`: one row per 3D point,
//! one column per view, a 0-based corner index or `*`).

use std::path::Path;

use nalgebra::Matrix3x4;

use super::{data_lines, number, parse_error, read_text};
use crate::error::Result;

/// Parse a 3×4 camera matrix (3 lines of 4 numbers).
pub fn parse_p_matrix(text: &str, file: &str) -> Result<Matrix3x4<f64>> {
    let lines = data_lines(text);
    if lines.len() != 3 {
        return Err(parse_error(
            file,
            lines.last().map_or(1, |l| l.0),
            format!("expected 3 rows, found {}", lines.len()),
        ));
    }
    let mut p = Matrix3x4::zeros();
    for (r, (l, t)) in lines.iter().enumerate() {
        if t.len() != 4 {
            return Err(parse_error(file, *l, "expected 4 numbers"));
        }
        for c in 0..4 {
            p[(r, c)] = number(file, *l, t[c])?;
        }
    }
    Ok(p)
}

/// Read a 3×4 camera matrix file.
pub fn read_p_matrix(path: &Path) -> Result<Matrix3x4<f64>> {
    parse_p_matrix(&read_text(path)?, &path.display().to_string())
}

/// Parse an n-view correspondence table: `None` where the point is not seen.
pub fn parse_nview(text: &str, file: &str) -> Result<Vec<Vec<Option<usize>>>> {
    let lines = data_lines(text);
    let width = lines.first().map_or(0, |l| l.1.len());
    lines
        .into_iter()
        .map(|(l, t)| {
            if t.len() != width {
                return Err(parse_error(
                    file,
                    l,
                    format!("expected {width} columns, found {}", t.len()),
                ));
            }
            t.iter()
                .map(|tok| match *tok {
                    "*" => Ok(None),
                    s => s
                        .parse::<usize>()
                        .map(Some)
                        .map_err(|_| parse_error(file, l, format!("bad index `{s}`"))),
                })
                .collect()
        })
        .collect()
}

/// Read an n-view correspondence table.
pub fn read_nview(path: &Path) -> Result<Vec<Vec<Option<usize>>>> {
    parse_nview(&read_text(path)?, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses() {
        let p = parse_p_matrix("1 2 3 4\n5 6 7 8\n9 10 11 12\n", "p").unwrap();
        assert_eq!(p[(2, 3)], 12.0);
        assert!(parse_p_matrix("1 2 3\n5 6 7 8\n9 10 11 12\n", "p").is_err());
        let t = parse_nview("0 * 3\n* 1 2\n", "n").unwrap();
        assert_eq!(t[0], vec![Some(0), None, Some(3)]);
        assert!(parse_nview("0 * 3\n* 1\n", "n").is_err());
    }
}
