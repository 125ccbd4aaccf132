//! The one-dimensional searches over focal lengths: a cost on a log-spaced grid of focal
//! lengths (a range of image diagonals), its best point refined by the parabola through it and
//! its neighbours. The focal-length search of a moving camera ([`crate::focal`]) and the pan's
//! ([`crate::rotations`], [`crate::parallax`]) use them.

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};

/// The image diagonal of `k`, px; an error naming what is missing without an image size.
pub(crate) fn image_diagonal(k: &Intrinsics) -> Result<f64> {
    let (Some(w), Some(h)) = (k.width, k.height) else {
        return Err(VisionError::InvalidInput(
            "an unknown focal length needs the image size (width and height of the intrinsics)"
                .into(),
        ));
    };
    Ok(((w as f64).powi(2) + (h as f64).powi(2)).sqrt())
}

/// `cost` at `n` focal lengths log-spaced from `lo` to `hi` (evaluated in parallel): pairs
/// of ln f and the cost.
pub(crate) fn log_grid(
    lo: f64,
    hi: f64,
    n: usize,
    cost: &(dyn Fn(f64) -> f64 + Sync),
) -> Vec<(f64, f64)> {
    use rayon::prelude::*;
    let (lo, hi) = (lo.ln(), hi.ln());
    let step = (hi - lo) / (n.max(2) - 1) as f64;
    (0..n)
        .into_par_iter()
        .map(|j| {
            let x = lo + step * j as f64;
            (x, cost(x.exp()))
        })
        .collect()
}

/// The focal length at the best point of a [`log_grid`], refined by the parabola through it
/// and its neighbours ([`refine_at`]); `None` when no cost is finite.
pub(crate) fn grid_minimum(grid: &[(f64, f64)]) -> Option<f64> {
    let (j, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    refine_at(grid, j)
}

/// The focal length at grid point `j` of a [`log_grid`], refined by the parabola through it
/// and its neighbours (in ln f, by at most a grid step); `None` when its cost is not finite.
pub(crate) fn refine_at(grid: &[(f64, f64)], j: usize) -> Option<f64> {
    let &(x0, best) = grid.get(j)?;
    if !best.is_finite() {
        return None;
    }
    let mut x = x0;
    if j > 0 && j + 1 < grid.len() {
        let step = grid[j + 1].0 - x0;
        let (a, b, c) = (grid[j - 1].1, best, grid[j + 1].1);
        let den = a - 2.0 * b + c;
        if a.is_finite() && c.is_finite() && den > 0.0 {
            x += (0.5 * step * (a - c) / den).clamp(-step, step);
        }
    }
    Some(x.exp())
}

/// The minimum of `cost` over `n` focal lengths log-spaced from `lo` to `hi` (evaluated in
/// parallel), refined by the parabola through the best one and its neighbours (in log f);
/// `None` when no cost is finite.
pub(crate) fn log_grid_minimum(
    lo: f64,
    hi: f64,
    n: usize,
    cost: &(dyn Fn(f64) -> f64 + Sync),
) -> Option<f64> {
    grid_minimum(&log_grid(lo, hi, n, cost))
}
