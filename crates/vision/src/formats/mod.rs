//! Readers and writers of the book's text formats (see `book/GAPS.md`) and their JSON forms:
//! intrinsics (`g7cam.txt`), cameras files (`Frame i` / R / t), marked points (`Frame f` /
//! `Npoints n` / `u v`…), plain point lists, and the Oxford VGG files used by the tests.
//!
//! Parse errors name the file and the 1-based line.

pub mod cameras;
pub mod intrinsics;
pub mod marked_points;
pub mod points;
pub mod vgg;

pub use cameras::{
    format_cameras, parse_cameras, read_cameras, write_cameras, CameraPath, FramePose,
};
pub use intrinsics::{format_intrinsics, parse_intrinsics, read_intrinsics, write_intrinsics};
pub use marked_points::{
    format_marked_points, parse_marked_points, read_marked_points, MarkedFrame, MarkedPoints,
};
pub use points::{
    format_points2d, format_points3d, parse_points2d, parse_points3d, read_points2d, read_points3d,
};

use std::path::Path;

use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::error::{Result, VisionError};

/// Read a whole text file.
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| VisionError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Write a whole text file.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).map_err(|source| VisionError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Read any of this crate's types from its JSON form.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path)?;
    serde_json::from_str(&text).map_err(|e| VisionError::Parse {
        file: path.display().to_string(),
        line: e.line(),
        message: e.to_string(),
    })
}

/// Write any of this crate's types in its JSON form (pretty-printed).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    write_text(path, &(text + "\n"))
}

/// A parse error at `line` (1-based) of `file`.
pub(crate) fn parse_error(file: &str, line: usize, message: impl Into<String>) -> VisionError {
    VisionError::Parse {
        file: file.to_string(),
        line,
        message: message.into(),
    }
}

/// The whitespace-separated tokens of a text with their 1-based line numbers; `#` starts a comment.
pub(crate) fn tokens(text: &str) -> Vec<(usize, &str)> {
    text.lines()
        .enumerate()
        .flat_map(|(i, l)| {
            let l = l.split('#').next().unwrap_or("");
            l.split_whitespace().map(move |t| (i + 1, t))
        })
        .collect()
}

/// Parse a finite number token.
pub(crate) fn number(file: &str, line: usize, token: &str) -> Result<f64> {
    match token.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(parse_error(
            file,
            line,
            format!("expected a number, found `{token}`"),
        )),
    }
}

/// The non-empty, non-comment lines of a text with their 1-based numbers, split in tokens.
pub(crate) fn data_lines(text: &str) -> Vec<(usize, Vec<&str>)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.split('#').next().unwrap_or("");
            let t: Vec<&str> = l.split_whitespace().collect();
            (!t.is_empty()).then_some((i + 1, t))
        })
        .collect()
}
