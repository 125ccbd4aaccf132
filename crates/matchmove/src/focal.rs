//! The initial focal length of a shot whose focal length is unknown (an addition to the book,
//! whose K comes from a prior calibration, §7.1): a one-dimensional search ([`focal_search`]),
//! as the book's own intrinsics test (§7.6) does with K, for the focal length whose solve of
//! the whole shot (every few frames) fits every observation best, with the principal point at
//! the frame's centre and square pixels. The search's profile also says whether the shot
//! determines the focal length at all (flat, two minima, a best at the end of the range): the
//! report warns when not (the lens rounds of the `general` module).

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;

use crate::grid::{grid_minimum, image_diagonal, log_grid, refine_at};
use crate::options::MatchmoveOptions;
use crate::pipeline::matchmove;

/// Most frames the focal-length search ([`focal_search`]) solves at each focal length: the
/// shot is subsampled to them.
const SEARCH_FRAMES: usize = 40;
/// Largest frame stride of the focal-length search: a track must live 2·stride frames to be
/// seen in three of the solved frames.
const SEARCH_MAX_STRIDE: usize = 5;
/// Most Levenberg–Marquardt iterations of an adjustment in the search ([`focal_search`]; the
/// solve's own default is 30): a focal length far from the lens's never converges, and stopping
/// early scores it as bad as it is.
const SEARCH_BA_ITERATIONS: usize = 8;
/// Focal lengths tried by the search, log-spaced over 0.3–3 image diagonals (×1.33 apart).
const GRID: usize = 9;
/// Most starts of the lens rounds: the search's best focal length and its other minima.
pub(crate) const MAX_FOCAL_STARTS: usize = 2;
/// Two solves from distinct focal lengths whose costs are within this ratio fit the tracks
/// about equally (a warning).
pub const FOCAL_AMBIGUITY_RATIO: f64 = 1.02;
/// Focal lengths further apart than this fraction are distinct.
pub const FOCAL_DISTINCT: f64 = 0.1;
/// A search whose cost at half or double its focal length is within this ratio of its best
/// has not determined the focal length (a warning).
pub const FOCAL_FLAT_RATIO: f64 = 1.02;
/// A separate minimum of the search's profile within this ratio of the best cost is followed
/// too ([`FocalSearch::others`]).
pub const SEARCH_OTHER_RATIO: f64 = 1.25;

/// What the focal-length search found ([`focal_search`]).
#[derive(Clone, Debug, PartialEq)]
pub struct FocalSearch {
    /// The focal length (px) whose solve fits the tracks best.
    pub focal: f64,
    /// Other focal lengths (px) whose solves fit nearly as well (within
    /// [`SEARCH_OTHER_RATIO`] of the best cost) at a separate minimum of the profile: a
    /// planar set's twofold ambiguity, or a motion that does not fix the focal length. The
    /// rounds are run from each to see which fits the whole shot better.
    pub others: Vec<f64>,
    /// How much worse the search's cost is at half and at double the focal length (the
    /// smaller ratio of the two, interpolated on the grid; infinite where both lie outside it
    /// or fail to solve): near 1 when the shot does not fix the focal length.
    pub determinacy: f64,
    /// Whether the best of the search's grid is its first or last point: the focal length
    /// may lie outside the range searched, or the profile falls all the way to one end.
    pub at_edge: bool,
    /// The focal lengths searched, px: the first and last of the grid.
    pub range: [f64; 2],
}

/// The cost of a [`crate::grid::log_grid`] at `x` = ln f, interpolated linearly in ln f; `None` outside the
/// grid or next to a point that did not solve.
fn grid_cost_at(grid: &[(f64, f64)], x: f64) -> Option<f64> {
    let w = grid.windows(2).find(|w| w[0].0 <= x && x <= w[1].0)?;
    let t = (x - w[0].0) / (w[1].0 - w[0].0);
    let c = w[0].1 + t * (w[1].1 - w[0].1);
    c.is_finite().then_some(c)
}

/// The focal length (px) whose solve fits the tracks best ([`focal_search`]'s best).
pub fn estimate_focal(tracks: &Tracks, k: &Intrinsics, options: &MatchmoveOptions) -> Result<f64> {
    focal_search(tracks, k, options).map(|s| s.focal)
}

/// The profile of the fit over the focal length (module docs, step 1): the whole shot, every
/// `s`-th frame so that at most [`SEARCH_FRAMES`] are solved (`s` ≤ [`SEARCH_MAX_STRIDE`], so
/// tracks still span three of them), solved by the pinhole matchmove with K(f) — the
/// principal point and square pixels of `k`, its focal length ignored — and scored by the
/// truncated reprojection cost of *every* observation ([`truncated_cost`]: an observation the
/// solve could not fit counts the inlier tolerance, so a focal length cannot win by fitting
/// fewer points); on a logarithmic grid of [`GRID`] focal lengths from 0.3 to 3 image
/// diagonals (solved in parallel), then the parabola through the best one and its neighbours.
///
/// The whole shot, not its first frames: a shot's opening second often has no parallax (a
/// slow start, a hold), and a wrong K bends a reconstruction only where there is parallax to
/// bend. The calibrated start at each focal length handles planar sets, whose pairs the book's
/// 8-point start cannot begin at any focal length.
///
/// Why not from the fundamental matrix (the focal length that makes KᵀFK essential, Bougnoux
/// 1998; Mendonça & Cipolla 1999)? A hand-held orbit around the subject, the commonest
/// matchmove, is the critical motion of two-view self-calibration (optical axes meeting, Sturm
/// 2001): measured on the Blender dev plate it gives 490 px for a 920 px lens; and a plane
/// gives no fundamental matrix at all.
///
/// Errors: [`VisionError::NoParallax`] when no focal length solves because no part of the shot
/// has parallax (the caller falls back to a rotation-only solve), else
/// [`VisionError::Degenerate`] naming the range tried.
pub fn focal_search(
    tracks: &Tracks,
    k: &Intrinsics,
    options: &MatchmoveOptions,
) -> Result<FocalSearch> {
    let diag = image_diagonal(k)?;
    let n = tracks.frames.len();
    let stride = n.div_ceil(SEARCH_FRAMES).clamp(1, SEARCH_MAX_STRIDE);
    let sub = tracks.every(stride);
    // A focal length far from the lens's keeps its adjustments from converging; stopping them
    // at SEARCH_BA_ITERATIONS scores it as bad as it is, for half the work.
    let search = MatchmoveOptions {
        refine: crate::fragment::RefineOptions {
            ba_iterations: options.refine.ba_iterations.min(SEARCH_BA_ITERATIONS),
            ..options.refine.clone()
        },
        score: false,
        ..options.clone()
    };
    let no_parallax = std::sync::atomic::AtomicUsize::new(0);
    let cost = |f: f64| -> f64 {
        let kf = Intrinsics {
            f1: f,
            f2: f * k.f2 / k.f1,
            ..k.pinhole()
        };
        match matchmove(&sub, &kf, &search, &|_, _, _| {}) {
            Ok(s) => truncated_cost(&sub, &s.report),
            Err(e) => {
                if matches!(e, VisionError::NoParallax(_)) {
                    no_parallax.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                f64::INFINITY
            }
        }
    };
    let (lo, hi) = (0.3 * diag, 3.0 * diag);
    let grid = log_grid(lo, hi, GRID, &cost);
    let Some(focal) = grid_minimum(&grid) else {
        let what = format!(
            "frames {}..{} (every {stride}) solve with no focal length from {lo:.0} to {hi:.0} px",
            tracks.frames[0],
            tracks.frames[n - 1]
        );
        return Err(
            if no_parallax.load(std::sync::atomic::Ordering::Relaxed) == GRID {
                VisionError::NoParallax(what)
            } else {
                VisionError::Degenerate(format!("{what}: give the intrinsics with focal: refine"))
            },
        );
    };
    let best = grid.iter().map(|g| g.1).fold(f64::INFINITY, f64::min);
    let jbest = grid.iter().position(|g| g.1 == best).unwrap_or(0);
    let others = (0..grid.len())
        .filter(|&j| j.abs_diff(jbest) >= 2 && grid[j].1 <= SEARCH_OTHER_RATIO * best)
        .filter(|&j| {
            (j == 0 || grid[j].1 <= grid[j - 1].1)
                && (j + 1 == grid.len() || grid[j].1 <= grid[j + 1].1)
        })
        .filter_map(|j| refine_at(&grid, j))
        .collect();
    let determinacy = [0.5f64, 2.0]
        .iter()
        .filter_map(|m| grid_cost_at(&grid, (focal * m).ln()))
        .map(|c| c / best)
        .fold(f64::INFINITY, f64::min);
    Ok(FocalSearch {
        focal,
        others,
        determinacy,
        at_edge: jbest == 0 || jbest + 1 == grid.len(),
        range: [lo, hi],
    })
}

/// The truncated reprojection cost of a solve over every observation of `tracks`, px: the
/// root mean of the squared error of the inliers and of the inlier tolerance for every other
/// observation (outliers, points not reconstructed, frames not solved) — MSAC's cost (Torr &
/// Zisserman 2000), so a solve cannot score better by fitting fewer observations.
pub(crate) fn truncated_cost(tracks: &Tracks, report: &crate::report::SolveReport) -> f64 {
    let tau2 = report.inlier_tolerance.powi(2);
    let total: usize = tracks.tracks.iter().map(|t| t.points.len()).sum();
    if total == 0 || !tau2.is_finite() {
        return f64::INFINITY;
    }
    let (mut sum, mut counted) = (0.0, 0usize);
    for f in &report.frames {
        sum += f.inliers as f64 * f.rms.powi(2) + (f.observations - f.inliers) as f64 * tau2;
        counted += f.observations;
    }
    sum += total.saturating_sub(counted) as f64 * tau2;
    let c = (sum / total as f64).sqrt();
    if c.is_finite() {
        c
    } else {
        f64::INFINITY
    }
}
