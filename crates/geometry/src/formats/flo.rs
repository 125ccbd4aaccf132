//! Middlebury optical-flow files (`.flo`): the ground-truth motion the KLT tests and the OpenCV
//! cross-check measure tracked features against (book 6.3). Little-endian: the tag 202021.25,
//! width and height as u32, then per pixel (row by row) u and v as f32; values above 1e9 mark
//! unknown flow.

use std::path::Path;

use crate::error::{Result, VisionError};

/// A dense flow field: pixel (x, y) moves by `(u, v)` to the next frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FlowField {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Interleaved u, v per pixel, row by row.
    pub uv: Vec<f32>,
}

impl FlowField {
    /// The flow at pixel (x, y), `None` outside the field or where it is unknown.
    pub fn at(&self, x: usize, y: usize) -> Option<[f32; 2]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 2 * (y * self.width + x);
        let (u, v) = (self.uv[i], self.uv[i + 1]);
        (u.abs() <= 1e9 && v.abs() <= 1e9).then_some([u, v])
    }
}

/// Reads a Middlebury `.flo` file.
pub fn read_flo(path: &Path) -> Result<FlowField> {
    let b = std::fs::read(path).map_err(|source| VisionError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |m: &str| VisionError::InvalidInput(format!("{}: {m}", path.display()));
    let f = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().unwrap_or_default());
    let u = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap_or_default()) as usize;
    if b.len() < 12 || f(0) != 202021.25 {
        return Err(bad("not a Middlebury .flo file (no 202021.25 tag)"));
    }
    let (w, h) = (u(4), u(8));
    if w.checked_mul(h)
        .and_then(|n| n.checked_mul(8))
        .is_none_or(|n| b.len() != 12 + n)
    {
        return Err(bad(&format!("{w}×{h} flow but {} bytes", b.len())));
    }
    Ok(FlowField {
        width: w,
        height: h,
        uv: (0..2 * w * h).map(|k| f(12 + 4 * k)).collect(),
    })
}
