//! Writing a camera path in a chosen format: [`write_camera_path`] (what the `write_cameras`
//! node runs).

use std::path::Path;

use super::{is_json, write_cameras, write_json, CameraPath};
use crate::error::Result;

/// The file format of a camera path.
#[derive(Clone, Copy, Debug, PartialEq, vfxgraph_params::Choice)]
pub enum CamerasFormat {
    /// JSON for a `.json` path, else the book's format.
    Auto,
    /// The book's cameras file ([`write_cameras`]).
    Book,
    /// The path's JSON form ([`write_json`]).
    Json,
}

/// The options of [`write_camera_path`].
#[derive(Debug, PartialEq, vfxgraph_params::Options)]
pub struct WriteCamerasOptions {
    /// auto: JSON for a .json path, else the book's format
    pub format: CamerasFormat,
}

impl Default for WriteCamerasOptions {
    fn default() -> Self {
        WriteCamerasOptions {
            format: CamerasFormat::Auto,
        }
    }
}

/// Writes `cameras` to `path` in `format` (atomically, as every writer of this module).
pub fn write_camera_path(path: &Path, cameras: &CameraPath, format: CamerasFormat) -> Result<()> {
    let json = match format {
        CamerasFormat::Json => true,
        CamerasFormat::Book => false,
        CamerasFormat::Auto => is_json(path),
    };
    if json {
        write_json(path, cameras)
    } else {
        write_cameras(path, cameras)
    }
}
