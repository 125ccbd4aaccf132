//! Readers and writers of the book's text formats (its programs' files, chapters 4–8) and their JSON forms:
//! intrinsics (`g7cam.txt`), cameras files (`Frame i` / R / t), marked points (`Frame f` /
//! `Npoints n` / `u v`…), plain point lists, the Oxford VGG files used by the tests and
//! Middlebury `.flo` ground-truth flow.
//!
//! Parse errors name the file and the 1-based line.

pub mod camera_file;
pub mod cameras;
pub mod flo;
pub mod intrinsics;
pub mod marked_points;
pub mod points;
pub mod vgg;

pub use camera_file::{write_camera_path, CamerasFormat, WriteCamerasOptions};
pub use cameras::{
    format_cameras, parse_cameras, read_cameras, write_cameras, CameraPath, FramePose,
};
pub use intrinsics::{format_intrinsics, parse_intrinsics, read_intrinsics, write_intrinsics};
pub use marked_points::{
    format_marked_points, parse_marked_points, read_marked_points, write_marked_points,
    MarkedFrame, MarkedPoints,
};
pub use points::{
    format_points2d, format_points3d, parse_points2d, parse_points3d, read_points2d, read_points3d,
    write_points2d, write_points3d,
};

use std::path::Path;

use serde::de::DeserializeOwned;
use serde::Serialize;

use crate::error::{Result, VisionError};

/// True when `path` ends in `.json` (case-insensitive): the readers and writers of this module
/// then use the type's JSON form instead of the book's text format.
pub fn is_json(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// Read a whole text file.
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| VisionError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Write a whole text file, atomically: the project's one writer
/// ([`vfxgraph_fsutil::atomic_write`]: folders created, temporary in the same folder, fsync,
/// rename), so readers never see a partial file.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    vfxgraph_fsutil::atomic_write(path, text.as_bytes()).map_err(|source| VisionError::Io {
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
pub fn parse_error(file: &str, line: usize, message: impl Into<String>) -> VisionError {
    VisionError::Parse {
        file: file.to_string(),
        line,
        message: message.into(),
    }
}

/// The whitespace-separated tokens of a text with their 1-based line numbers; `#` starts a comment.
pub fn tokens(text: &str) -> Vec<(usize, &str)> {
    text.lines()
        .enumerate()
        .flat_map(|(i, l)| {
            let l = l.split('#').next().unwrap_or("");
            l.split_whitespace().map(move |t| (i + 1, t))
        })
        .collect()
}

/// Parse a finite number token.
pub fn number(file: &str, line: usize, token: &str) -> Result<f64> {
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
pub fn data_lines(text: &str) -> Vec<(usize, Vec<&str>)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.split('#').next().unwrap_or("");
            let t: Vec<&str> = l.split_whitespace().collect();
            (!t.is_empty()).then_some((i + 1, t))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Intrinsics, Pose};
    use crate::points::{Points2d, Points3d};
    use nalgebra::{Point2, Point3};

    #[test]
    fn files_round_trip_in_text_and_json() {
        let dir =
            std::env::temp_dir().join(format!("vfxgraph-geometry-formats-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let k = Intrinsics::new(1000.0, 1001.0, 640.0, 360.0);
        let p2 = Points2d(vec![Point2::new(1.0, 2.0), Point2::new(3.5, -4.0)]);
        let p3 = Points3d(vec![Point3::new(1.0, 2.0, 3.0)]);
        let cams = CameraPath {
            frames: vec![FramePose {
                frame: 3,
                pose: Pose::identity(),
                focal: None,
            }],
            intrinsics: None,
        };
        let marked = MarkedPoints {
            frames: vec![MarkedFrame {
                frame: 7,
                points: p2.clone(),
            }],
        };
        for ext in ["txt", "json"] {
            let f = |name: &str| dir.join(format!("{name}.{ext}"));
            write_intrinsics(&f("k"), &k).unwrap();
            assert_eq!(read_intrinsics(&f("k")).unwrap(), k);
            write_points2d(&f("p2"), &p2).unwrap();
            assert_eq!(read_points2d(&f("p2")).unwrap(), p2);
            write_points3d(&f("p3"), &p3).unwrap();
            assert_eq!(read_points3d(&f("p3")).unwrap(), p3);
            write_cameras(&f("cams"), &cams).unwrap();
            assert_eq!(read_cameras(&f("cams")).unwrap(), cams);
            write_marked_points(&f("marked"), &marked).unwrap();
            assert_eq!(read_marked_points(&f("marked")).unwrap(), marked);
        }
        // A camera in the `write_camera` JSON form.
        let cam = Camera::new(
            k,
            nalgebra::Matrix3::identity(),
            nalgebra::Vector3::new(0.0, 0.0, 2.0),
        );
        write_json(&dir.join("camera.json"), &cam).unwrap();
        assert_eq!(read_json::<Camera>(&dir.join("camera.json")).unwrap(), cam);
        let e = read_intrinsics(&dir.join("missing.txt")).unwrap_err();
        assert!(matches!(e, VisionError::Io { .. }));
        std::fs::write(dir.join("bad.json"), "{\"K\": [[1, 0]]}").unwrap();
        assert!(matches!(
            read_intrinsics(&dir.join("bad.json")),
            Err(VisionError::Parse { line: 1, .. })
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
