//! Solving the lens with the cameras: unknown or approximate focal length and radial
//! distortion (an addition to the book, whose K comes from a prior calibration, §7.1, and whose
//! camera is an ideal pinhole, §2.7).
//!
//! Real footage rarely comes with a calibration, and every lens bends lines. The solve here is
//! the one Blender's and libmv's camera solvers use — the lens refined by the bundle
//! adjustment together with the cameras — organised around the book's pinhole pipeline:
//!
//! 1. **Initial focal length** ([`focal_search`], when `focal: unknown`): a one-dimensional
//!    search, as the book's own intrinsics test (§7.6) does with K: the focal length whose
//!    solve of the whole shot (every few frames) fits every observation best, with the
//!    principal point at the frame's centre and square pixels. The search's profile also says
//!    whether the shot determines the focal length at all (flat, two minima, a best at the end
//!    of the range): the report warns when not.
//! 2. **Rounds** of: undistort the tracks with the current lens ([`undistort_tracks`]), solve
//!    them with the book's pinhole matchmove, then a global bundle adjustment of the *original*
//!    (distorted) observations in which the shared block `[f, k1, k2]`
//!    ([`vfxgraph_bundle::CameraModel::Radial`]) is free with every camera and point
//!    ([`crate::global`] with a free lens). The second round starts from a
//!    lens close to the truth, so its fragments are solved as well as a known-K shot's.
//!    When the search found a second minimum nearly as good, the rounds run from it too and
//!    the better fit of the whole shot is kept (a warning when they fit alike).
//!
//! Figures of the returned [`Solve`] (reprojection errors, inliers, the book-style score) are
//! measured on the undistorted tracks with the solved K: pixels of the ideal pinhole the lens
//! is undistorted to, within a few percent of image pixels for moderate distortion.

use serde::{Deserialize, Serialize};
use vfxgraph_params::{Choice, Options};

use super::{matchmove, MatchmoveOptions, Solve};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::CameraPath;
use vfxgraph_klt::Tracks;
use vfxgraph_lens::Distortion;

/// What the solve knows of the focal length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum FocalMode {
    /// The intrinsics' focal length is exact: held.
    Known,
    /// The intrinsics' focal length is a starting value: refined with the cameras.
    Refine,
    /// No focal length is known: estimated from the tracks, then refined.
    Unknown,
}

/// Which distortion the solve estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum DistortionMode {
    /// None is estimated: the intrinsics' own distortion (a pinhole if they carry none) is held.
    None,
    /// Brown–Conrady k1 (OpenCV's model; k2 held).
    K1,
    /// Brown–Conrady k1 and k2.
    K1k2,
    /// Brown–Conrady k1, k2 and the tangential p1, p2 (OpenCV's model; k3 held).
    Brown,
    /// Fitzgibbon's one-parameter division model (wide angles).
    Division,
}

/// Where the principal point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum PrincipalPoint {
    /// Held: the intrinsics' (the image's centre without intrinsics).
    Centre,
    /// Refined with the lens, from the intrinsics' (or the centre).
    Refine,
}

/// The lens part of a matchmove.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct LensOptions {
    /// the focal length: known (held), refine (from the intrinsics) or unknown (estimated)
    pub focal: FocalMode,
    /// the lens distortion solved with the cameras
    ///
    /// `none` holds the intrinsics' own distortion (none for a pinhole); `k1`, `k1k2`:
    /// Brown–Conrady radial terms (OpenCV's model); `brown`: with the tangential p1, p2;
    /// `division`: Fitzgibbon's model.
    pub distortion: DistortionMode,
    /// the principal point: centre (held) or refine (solved with the lens)
    pub principal_point: PrincipalPoint,
    /// rounds of undistort → pinhole solve → lens adjustment, when the lens is solved
    #[param(range = 1..=5)]
    pub lens_rounds: usize,
    /// a focal length per frame (a zooming lens), smoothed by `zoom_smoothness`
    ///
    /// The intrinsics' focal length is the first frame's: held with `focal: known` (what a
    /// shot that orbits or dollies needs: there the absolute focal length of a zoom is not
    /// determined), solved with `refine`; `unknown` estimates it. Needs `distortion: none`
    /// (the intrinsics' own lens is held).
    pub zoom: bool,
    /// the zoom's smoothness: σ of the focal length's second difference, px per frame²
    ///
    /// A frame whose focal length leaves the line through its neighbours' by σ costs what
    /// one observation 1 px off does; a steady zoom (a linear ramp) costs nothing.
    #[param(range = 1e-3..=1e4)]
    pub zoom_smoothness: f64,
    /// image width, px (0: the intrinsics', else the frames the tracks were measured on)
    #[param(range = 0..=100_000)]
    pub width: usize,
    /// image height, px (0: the intrinsics', else the tracked frames')
    #[param(range = 0..=100_000)]
    pub height: usize,
}

impl Default for LensOptions {
    fn default() -> Self {
        LensOptions {
            focal: FocalMode::Known,
            distortion: DistortionMode::None,
            principal_point: PrincipalPoint::Centre,
            lens_rounds: 1,
            zoom: false,
            zoom_smoothness: 1.0,
            width: 0,
            height: 0,
        }
    }
}

impl LensOptions {
    /// The intrinsics the solve starts from: `k` (when given) with the image size of the
    /// options where set; without `k`, a camera of that size with its principal point at the
    /// centre, which only `focal: unknown` can solve. The size is the options', else `k`'s,
    /// else `tracked` (the frames the tracks were measured on, [`Tracks::image_size`]).
    pub fn initial_intrinsics(
        &self,
        k: Option<&Intrinsics>,
        tracked: Option<[u32; 2]>,
    ) -> Result<Intrinsics> {
        let size = (self.width > 0 && self.height > 0)
            .then_some((self.width, self.height))
            .or_else(|| k.and_then(|k| Some((k.width? as usize, k.height? as usize))))
            .or_else(|| tracked.map(|[w, h]| (w as usize, h as usize)));
        let mut k = match (k, size) {
            (Some(k), _) => k.clone(),
            (None, Some((w, h))) => {
                if self.focal != FocalMode::Unknown {
                    return Err(VisionError::InvalidInput(
                        "without intrinsics the focal length is unknown: set focal: unknown".into(),
                    ));
                }
                let (w, h) = (w as f64, h as f64);
                Intrinsics::new(w.max(h), w.max(h), (w - 1.0) / 2.0, (h - 1.0) / 2.0)
            }
            (None, None) => {
                return Err(VisionError::InvalidInput(
                    "no intrinsics and no image size (the tracks do not record one): connect the \
                     intrinsics, or set focal: unknown with width and height"
                        .into(),
                ))
            }
        };
        if let Some((w, h)) = size {
            let (w, h) = (u32::try_from(w), u32::try_from(h));
            if let (Ok(w), Ok(h)) = (w, h) {
                k = k.with_size(w, h);
            }
        }
        Ok(k)
    }

    /// Whether anything of the lens is solved (otherwise [`matchmove_with_lens`] is the book's
    /// matchmove on the undistorted tracks).
    pub fn solves_lens(&self) -> bool {
        self.focal != FocalMode::Known
            || self.distortion != DistortionMode::None
            || self.principal_point == PrincipalPoint::Refine
    }

    /// The lens whose parameters the adjustment refines, from the intrinsics' own distortion,
    /// and the held flags of the block `[f, k1, k2, p1, p2, cx, cy]`.
    pub fn block(&self, k: &Intrinsics) -> Result<(Distortion, super::Held)> {
        let f_held = self.focal == FocalMode::Known;
        let own = k.distortion;
        let (lens, k1_held, k2_held) = match self.distortion {
            DistortionMode::None => (own, true, true),
            DistortionMode::K1 | DistortionMode::K1k2 | DistortionMode::Brown => {
                let lens = match own {
                    Distortion::BrownConrady { .. } => own,
                    Distortion::None => Distortion::BrownConrady {
                        k1: 0.0,
                        k2: 0.0,
                        k3: 0.0,
                        p1: 0.0,
                        p2: 0.0,
                    },
                    Distortion::Division { .. } => {
                        return Err(VisionError::InvalidInput(format!(
                            "distortion: {} solves a Brown–Conrady lens, but the intrinsics \
                             carry a division one",
                            self.distortion.choice()
                        )))
                    }
                };
                (lens, false, self.distortion == DistortionMode::K1)
            }
            DistortionMode::Division => {
                let lens =
                    match own {
                        Distortion::Division { .. } => own,
                        Distortion::None => Distortion::Division { k1: 0.0, k2: 0.0 },
                        Distortion::BrownConrady { .. } => return Err(VisionError::InvalidInput(
                            "distortion: division, but the intrinsics carry a Brown–Conrady lens"
                                .into(),
                        )),
                    };
                (lens, false, true)
            }
        };
        let p_held = self.distortion != DistortionMode::Brown;
        let c_held = self.principal_point == PrincipalPoint::Centre;
        Ok((
            lens,
            [f_held, k1_held, k2_held, p_held, p_held, c_held, c_held],
        ))
    }
}

/// The tracks as an ideal pinhole with the same K would see them (every observation through
/// [`Intrinsics::undistort_pixel`]); the tracks themselves when `k` is a pinhole.
pub fn undistort_tracks(tracks: &Tracks, k: &Intrinsics) -> Result<Tracks> {
    let mut out = tracks.clone();
    if k.is_pinhole() {
        return Ok(out);
    }
    for t in &mut out.tracks {
        for p in &mut t.points {
            let u = k
                .undistort_pixel(&nalgebra::Point2::new(p[0], p[1]))
                .map_err(|e| {
                    VisionError::InvalidInput(format!(
                        "track {} at ({:.1}, {:.1}): the lens cannot undistort it: {e}",
                        t.id, p[0], p[1]
                    ))
                })?;
            *p = [u.x, u.y];
        }
    }
    Ok(out)
}

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

/// The cost of a [`log_grid`] at `x` = ln f, interpolated linearly in ln f; `None` outside the
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
        refine: super::RefineOptions {
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
pub(crate) fn truncated_cost(tracks: &Tracks, report: &super::SolveReport) -> f64 {
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

/// Fewest tracks (seen in 3 frames or more) a distortion solve accepts: the lens's radial
/// curve needs points spread over the frame, and fewer make k1, k2 noise.
pub const MIN_LENS_TRACKS: usize = 30;

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
const MAX_FOCAL_STARTS: usize = 2;
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

/// A shot whose tracks live fewer frames than this (their median) gets a warning: each camera
/// then rests on features seen in two or three frames, chained from pair to pair. Measured on
/// the rendered corpus: of its plates with a median under 4 frames, three of five were 2–5.5°
/// wrong; none from 4 frames up was over 0.7° without a warning.
pub const SHORT_TRACKS: usize = 4;

/// The matchmove of real cameras (module docs): the book's matchmove when nothing of the lens
/// is solved (on the tracks undistorted by the intrinsics' own lens), else the rounds of
/// step 2 from the focal length of step 1. The returned path carries the solved intrinsics
/// (focal length and distortion). Tracks too short to trust ([`SHORT_TRACKS`]) are warned of.
pub fn matchmove_with_lens(
    tracks: &Tracks,
    k: &Intrinsics,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    let mut solve = solve_with_lens(tracks, k, lens, options, progress)?;
    solve.report.warnings.extend(short_tracks(tracks));
    solve
        .report
        .warnings
        .extend(uncertain_rotations(&solve.report));
    Ok(solve)
}

/// A frame whose rotation the solve determines worse than this (one standard deviation of
/// its least-determined axis, degrees, [`super::report::FrameReport::rotation_sd_deg`]) is
/// warned of: on the robustness corpus a plate's worst rotation error is a median 1.9× its
/// largest such deviation, and up to 5× in 99 plates of 100, so from here errors of a degree
/// are to be expected.
pub const UNCERTAIN_ROTATION_DEG: f64 = 0.2;

/// The warning of frames whose rotation is poorly determined ([`UNCERTAIN_ROTATION_DEG`]), if
/// any.
fn uncertain_rotations(report: &super::SolveReport) -> Option<String> {
    let uncertain: Vec<(i64, f64)> = report
        .frames
        .iter()
        .filter_map(|f| Some((f.frame, f.rotation_sd_deg?)))
        .filter(|&(_, sd)| sd >= UNCERTAIN_ROTATION_DEG)
        .collect();
    let (&(first, _), &(last, _)) = (uncertain.first()?, uncertain.last()?);
    let worst = uncertain.iter().map(|u| u.1).fold(0.0, f64::max);
    let focal_solved = report
        .intrinsics
        .iter()
        .any(|i| i.name == "focal_px" && !i.held);
    Some(format!(
        "the tracks determine the rotation of {} frame{} ({first}–{last}) only to ±{worst:.2}° \
         (the worst frame's standard deviation, from the whole solve's covariance; errors of \
         2–3 times that are usual): the scene is far or shallow for the camera's travel, or the \
         tracks are few or short — {}track more features, or check the solve against the plate",
        uncertain.len(),
        if uncertain.len() == 1 { "" } else { "s" },
        if focal_solved {
            "give the focal length if it is known, "
        } else {
            ""
        },
    ))
}

/// The warning of tracks too short to trust ([`SHORT_TRACKS`]), if they are.
fn short_tracks(tracks: &Tracks) -> Option<String> {
    let mut lengths: Vec<usize> = tracks.tracks.iter().map(|t| t.points.len()).collect();
    lengths.sort_unstable();
    let median = lengths.get(lengths.len() / 2).copied().unwrap_or(0);
    (median < SHORT_TRACKS && tracks.frames.len() >= SHORT_TRACKS).then(|| {
        format!(
            "the tracks are short: half of them live {median} frame{} or fewer over a \
             {}-frame shot, so every camera rests on features seen in a few frames, chained \
             from one to the next, and can be degrees wrong: track with less noise or more \
             texture (a larger window, a lower threshold), or check the solve against the plate",
            if median == 1 { "" } else { "s" },
            tracks.frames.len()
        )
    })
}

/// [`matchmove_with_lens`] before its check of the tracks' length.
fn solve_with_lens(
    tracks: &Tracks,
    k: &Intrinsics,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    k.validate()?;
    let (lens_model, held) = lens.block(k)?;
    let mut k = k.clone().with_distortion(lens_model);
    if !held[1] || !held[2] {
        let n = tracks.tracks.iter().filter(|t| t.points.len() >= 3).count();
        if n < MIN_LENS_TRACKS {
            return Err(VisionError::InvalidInput(format!(
                "distortion: {} needs at least {MIN_LENS_TRACKS} tracks seen in 3 frames or \
                 more, the tracks have {n}: track more features, or solve with distortion: none",
                lens.distortion.choice()
            )));
        }
    }
    let unknown = lens.focal == FocalMode::Unknown;
    if lens.zoom {
        return solve_zoom_with_lens(tracks, &k, lens, held, options, progress);
    }
    let t0 = std::time::Instant::now();
    let decided = super::tripod::decide(tracks, &k, unknown, options);
    let (tripod, focal, note) = match decided {
        Err(VisionError::NoParallax(why)) => {
            return static_fallback(tracks, &k, held, unknown, options, progress, &why)
        }
        r => r?,
    };
    if let Some(parallax) = tripod {
        let k_start = k.clone();
        if let Some(f) = focal {
            k.f1 = f;
            k.f2 = f;
        }
        let mut solve =
            super::tripod::solve_rotations(tracks, &k, held, options, parallax.as_ref(), progress)?;
        if let Some(general) = scaling_pan(
            tracks,
            &k_start,
            held,
            lens,
            options,
            progress,
            parallax.as_ref(),
            &mut solve,
        ) {
            return Ok(general);
        }
        solve
            .report
            .stages
            .insert(0, super::StageTime::new("motion", t0));
        if let Some(f) = focal {
            solve
                .report
                .notes
                .insert(0, format!("initial focal length {f:.1} px from the pan"));
        }
        return Ok(solve);
    }
    let motion = super::StageTime::new("motion", t0);
    let mut solve = match general_with_lens(tracks, k.clone(), held, lens, options, progress) {
        Ok(s) => s,
        // No fragment had parallax although the motion test saw some: the camera barely
        // moved (a slow push, a hand-held hold), which a rotation-only solve models best.
        Err(VisionError::NoParallax(why)) if options.motion.solve == super::SolveMode::Auto => {
            static_fallback(tracks, &k, held, unknown, options, progress, &why)?
        }
        Err(e) => return Err(e),
    };
    if let Some(note) = note {
        solve.report.stages.insert(0, motion);
        solve.report.notes.push(note);
    }
    Ok(solve)
}

/// A shot solved as a pan whose picture grows or shrinks by more than this fraction over the
/// shot ([`scaling_pan`]) is not a pan: a rotation does not scale the picture, a camera
/// moving along its view (or a zooming lens) does. Measured on the nodal pans of a synthetic
/// corpus: 0.2 % at most.
pub const PAN_SCALE_LIMIT: f64 = 0.02;

/// The general solve of the tracks must fit them this much better (overall rms) than the
/// rotation-only one to replace it: a nodal pan's rotation model is exact, so a general solve
/// (more freedom) fits no better than its noise.
pub const GENERAL_OVER_PAN_RMS: f64 = 0.8;

/// How much the picture scales from the first frame to the last once the pan's rotations are
/// taken out: every observation (undistorted by `k`) turned by the `pan`'s rotation of its
/// frame back to the first frame's orientation, then the product of the scales of the 2-D
/// similarities between consecutive frames' tracks ([`super::zoom::zoom_ratios`]). 1 for a
/// nodal pan, whatever it turns; the scale of a dolly or a zoom.
fn picture_scale(tracks: &Tracks, k: &Intrinsics, pan: &CameraPath) -> Result<f64> {
    let mut und = undistort_tracks(tracks, k)?;
    let kp = k.pinhole();
    let poses = super::poses_by_index(&und, pan);
    let Some(r0) = poses.iter().flatten().next().map(|p| p.r) else {
        return Ok(1.0);
    };
    for t in &mut und.tracks {
        for (j, p) in t.points.iter_mut().enumerate() {
            let Some(pose) = &poses[t.first + j] else {
                continue;
            };
            let ray = nalgebra::Vector3::new((p[0] - kp.u0) / kp.f1, (p[1] - kp.v0) / kp.f2, 1.0);
            let d = r0 * pose.r.transpose() * ray;
            if d.z > 1e-9 {
                *p = [kp.u0 + kp.f1 * d.x / d.z, kp.v0 + kp.f2 * d.y / d.z];
            }
        }
    }
    Ok(super::zoom::zoom_ratios(&und, &kp)
        .last()
        .copied()
        .unwrap_or(1.0))
}

/// The general solve of a shot the parallax test took for a pan whose picture nevertheless
/// scales (by more than [`PAN_SCALE_LIMIT`] over the shot, the test automatic), when it fits
/// the tracks clearly better (rms under [`GENERAL_OVER_PAN_RMS`] × the pan's): a dolly along
/// the view axis through a long lens, its tracks short-lived, moves them little between the
/// frames the test compares, and a rotation-only solve of it is degrees wrong. When the general
/// solve fails or fits no better, the pan stands with a warning.
#[allow(clippy::too_many_arguments)]
fn scaling_pan(
    tracks: &Tracks,
    k: &Intrinsics,
    held: super::Held,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    parallax: Option<&super::tripod::Parallax>,
    pan: &mut Solve,
) -> Option<Solve> {
    let p = parallax?;
    if options.motion.solve != super::SolveMode::Auto {
        return None;
    }
    let scale = picture_scale(tracks, k, &pan.path).ok()?;
    if !(scale.ln().abs() > PAN_SCALE_LIMIT.ln_1p()) {
        return None;
    }
    let r = pan.report.overall_rms;
    let may_travel = format!(
        "the picture {} by {:.1} % over the shot, which no rotation does: the camera moves \
         along its view (or the lens zooms), yet the shot was solved as a nodal pan ({}), \
         which is then wrong by degrees",
        if scale > 1.0 { "grows" } else { "shrinks" },
        100.0 * (scale.max(1.0 / scale) - 1.0),
        p.describe()
    );
    let general = general_with_lens(tracks, k.clone(), held, lens, options, progress);
    let better = match general {
        Ok(g) if g.report.overall_rms < GENERAL_OVER_PAN_RMS * r => Some(g),
        Ok(g) => {
            pan.report.warnings.push(format!(
                "{may_travel}; a general solve fits the tracks no better (rms {:.2} px against \
                 the pan's {r:.2} px): check the solve against the plate, give motion solve: \
                 general, or zoom: true for a zooming lens",
                g.report.overall_rms
            ));
            None
        }
        Err(_) => {
            pan.report.warnings.push(format!(
                "{may_travel}; no general solve could start from these tracks (longer tracks, \
                 from more texture or less noise, would tell; zoom: true for a zooming lens)"
            ));
            None
        }
    };
    let mut general = better?;
    let g = general.report.overall_rms;
    general.report.notes.push(format!(
        "{}; but the picture scales by {:.1} % over the shot and the general solve fits the \
         tracks better (rms {g:.2} px against the pan's {r:.2} px): a camera that travels",
        p.describe(),
        100.0 * (scale - 1.0)
    ));
    Some(general)
}

/// The rotation-only solve of a shot in which nothing has parallax (`why`): the camera
/// barely moved (a slow push, a hand-held hold, a locked-off camera), which a rotation-only
/// solve models best. Without parallax nor turn, nothing measures an unknown focal length: it
/// is held at its starting value, and the report says so.
fn static_fallback(
    tracks: &Tracks,
    k: &Intrinsics,
    mut held: super::Held,
    unknown: bool,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    why: &str,
) -> Result<Solve> {
    held[0] |= unknown;
    let mut solve = super::tripod::solve_rotations(tracks, k, held, options, None, progress)?;
    solve.report.warnings.push(format!(
        "no part of the shot has parallax enough to reconstruct in 3D ({why}); solved as a \
         nodal pan: the rotations hold, the camera's small travel is not recovered"
    ));
    if unknown {
        solve.report.warnings.push(format!(
            "the focal length is not measured (the camera neither turns nor travels enough): \
             {:.0} px is a guess; give the focal length (focal: known)",
            k.f1
        ));
    }
    Ok(solve)
}

/// A solved focal length whose standard deviation exceeds this fraction of it is not
/// determined by the shot (a warning).
pub const FOCAL_SD_WARNING: f64 = 0.05;

/// The reasons the solve's focal length is not determined by the shot, as one warning (none
/// when there is none): its standard deviation over [`FOCAL_SD_WARNING`], and `more` (the
/// search's flat profile, a second focal length that fits as well, a best at the edge of the
/// search). A camera that travels without turning (a dolly, a truck, a push) is a critical
/// motion for self-calibration (Sturm 1997; Kahl, Triggs & Åström 2000), and a plane seen from
/// two mirror-image viewpoints fits two focal lengths: the tracks fit a wide range of focal
/// lengths, and the cameras of a wrong one are wrong too.
fn warn_undetermined_focal(report: &mut super::SolveReport, mut more: Vec<String>) {
    let Some(f) = report
        .intrinsics
        .iter()
        .find(|i| i.name == "focal_px" && !i.held)
    else {
        return;
    };
    if let Some(sd) = f.sd.filter(|sd| !(*sd <= FOCAL_SD_WARNING * f.value)) {
        more.insert(
            0,
            format!(
                "its standard deviation is {sd:.0} px ({:.0} %)",
                100.0 * sd / f.value
            ),
        );
    }
    if more.is_empty() {
        return;
    }
    report.warnings.push(format!(
        "the focal length ({:.0} px) is not determined by the shot: {}; a camera that travels \
         without turning, or a plane seen from a symmetric viewpoint, fits many focal lengths, \
         and the cameras of a wrong one are wrong too: give the focal length (focal: known or \
         refine)",
        f.value,
        more.join("; ")
    ));
}

/// [`matchmove_with_lens`] of a zooming lens ([`super::zoom`]), on the tracks undistorted by
/// the intrinsics' own lens (held).
fn solve_zoom_with_lens(
    tracks: &Tracks,
    k: &Intrinsics,
    lens: &LensOptions,
    held: super::Held,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    if held[1..].iter().any(|h| !h) {
        return Err(VisionError::InvalidInput(format!(
            "zoom: true solves the focal length only: set distortion: none and principal_point: \
             centre (the intrinsics' lens is held; distortion: {}, principal_point: {} are not \
             solved with a zoom yet)",
            lens.distortion.choice(),
            lens.principal_point.choice()
        )));
    }
    let und = undistort_tracks(tracks, k)?;
    let (mut solve, focals) = super::zoom::solve_zoom(
        &und,
        &k.pinhole(),
        lens.focal,
        lens.zoom_smoothness,
        lens.lens_rounds,
        options,
        progress,
    )?;
    if let Some(out) = &mut solve.path.intrinsics {
        out.distortion = k.distortion;
    }
    solve.report.intrinsics = vec![super::report::SolvedIntrinsic {
        name: "focal_px".into(),
        value: focals[0],
        held: lens.focal == FocalMode::Known,
        sd: None,
    }];
    Ok(solve)
}

/// [`matchmove_with_lens`] of a moving camera.
fn general_with_lens(
    tracks: &Tracks,
    k: Intrinsics,
    held: super::Held,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    if !lens.solves_lens() {
        if k.is_pinhole() {
            // The book's case: no copy of the tracks.
            return matchmove(tracks, &k, options, progress);
        }
        let und = undistort_tracks(tracks, &k)?;
        let mut solve = matchmove(&und, &k.pinhole(), options, progress)?;
        solve.path.intrinsics = Some(k);
        return Ok(solve);
    }
    let Some(global) = &options.global else {
        return Err(VisionError::InvalidInput(
            "solving the lens needs the global bundle adjustment (global_adjust: true)".into(),
        ));
    };
    let mut notes = Vec::new();
    let mut stages = Vec::new();
    let mut starts = vec![k.clone()];
    let mut search = None;
    if lens.focal == FocalMode::Unknown {
        let t0 = std::time::Instant::now();
        let found = focal_search(tracks, &k, options)?;
        stages.push(super::StageTime::new("focal estimate", t0));
        notes.push(format!(
            "initial focal length {:.1} px from the tracks (the search's cost ×{:.3} at half \
             and double it)",
            found.focal, found.determinacy
        ));
        starts = std::iter::once(found.focal)
            .chain(found.others.iter().copied().take(MAX_FOCAL_STARTS - 1))
            .map(|f| Intrinsics {
                f1: f,
                f2: f * k.f2 / k.f1,
                ..k.clone()
            })
            .collect();
        search = Some(found);
    }
    // The rounds from every start; the one that fits the whole shot best is kept.
    let mut finished: Vec<(Solve, f64)> = Vec::new();
    for (i, k0) in starts.iter().enumerate() {
        let mut st = Vec::new();
        let mut nt = Vec::new();
        let r = lens_rounds(
            tracks,
            k0.clone(),
            held,
            lens,
            global,
            options,
            progress,
            &mut st,
            &mut nt,
        );
        match r {
            Ok(mut out) => {
                out.report.stages = stages.iter().cloned().chain(st).collect();
                out.report.notes.extend(notes.iter().cloned());
                out.report.notes.extend(nt);
                // The fit of the whole shot, to choose between starts (one start: no choice).
                let c = if starts.len() > 1 {
                    let lens = out.path.intrinsics.as_ref().unwrap_or(k0);
                    truncated_cost(&undistort_tracks(tracks, lens)?, &out.report)
                } else {
                    0.0
                };
                finished.push((out, c));
            }
            Err(e) if i == 0 && starts.len() == 1 => return Err(e),
            Err(_) => {}
        }
    }
    finished.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut it = finished.into_iter();
    let Some((mut out, cost)) = it.next() else {
        return Err(VisionError::Degenerate(
            "the lens rounds failed from every focal length the search found".into(),
        ));
    };
    let f = out.path.intrinsics.as_ref().map_or(k.f1, |k| k.f1);
    let mut reasons = Vec::new();
    for (other, c) in it {
        let f2 = other.path.intrinsics.as_ref().map_or(k.f1, |k| k.f1);
        out.report.notes.push(format!(
            "from the search's other minimum: focal {f2:.1} px, cost {c:.4} px (kept: {f:.1} \
             px, {cost:.4} px)"
        ));
        if c <= cost * FOCAL_AMBIGUITY_RATIO && (f2 / f).ln().abs() > FOCAL_DISTINCT.ln_1p() {
            reasons.push(format!(
                "{f2:.0} px fits the tracks as well ({c:.3} px against {cost:.3} px)"
            ));
        }
    }
    if let Some(search) = &search {
        if search.determinacy < FOCAL_FLAT_RATIO {
            reasons.push(format!(
                "its search fits half and double it within {:.1} %",
                100.0 * (search.determinacy - 1.0)
            ));
        }
        if search.at_edge {
            reasons.push(format!(
                "its search's best lies at the end of its range ({:.0} to {:.0} px)",
                search.range[0], search.range[1]
            ));
        }
    }
    warn_undetermined_focal(&mut out.report, reasons);
    Ok(out)
}

/// The rounds of the lens solve (module docs, step 2) from the intrinsics `k`: the pinhole
/// matchmove of the tracks undistorted by the current lens, then the global adjustment with
/// the lens free; the solve of the last round with the solved intrinsics.
#[allow(clippy::too_many_arguments)]
fn lens_rounds(
    tracks: &Tracks,
    mut k: Intrinsics,
    held: super::Held,
    lens: &LensOptions,
    global: &super::GlobalOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    stages: &mut Vec<super::StageTime>,
    notes: &mut Vec<String>,
) -> Result<Solve> {
    // The rounds' lens adjustment replaces the pinhole matchmove's own global adjustment.
    let inner = MatchmoveOptions {
        global: None,
        score: false,
        ..options.clone()
    };
    let mut solve = None;
    let mut cov = None;
    for round in 0..lens.lens_rounds {
        let t0 = std::time::Instant::now();
        let und = undistort_tracks(tracks, &k)?;
        let s = matchmove(&und, &k.pinhole(), &inner, progress)?;
        stages.push(super::StageTime::new(
            &format!("round {}: pinhole solve", round + 1),
            t0,
        ));
        let t0 = std::time::Instant::now();
        let poses = super::poses_by_index(&und, &s.path);
        let (poses, points, k_new, c) =
            super::global::global_lens_adjust(tracks, &k, &poses, global, held)?;
        cov = c;
        stages.push(super::StageTime::new(
            &format!("round {}: lens adjustment", round + 1),
            t0,
        ));
        notes.push(format!(
            "round {}: focal {:.2} px, {:?}",
            round + 1,
            k_new.f1,
            k_new.distortion
        ));
        k_new
            .validate()
            .map_err(|e| VisionError::Degenerate(format!("the solved lens is not usable: {e}")))?;
        k = k_new;
        solve = Some((poses, points, s));
    }
    let (poses, points, s) = solve.expect("at least one round");
    let und = undistort_tracks(tracks, &k)?;
    let mut out = super::finish_solve(
        &und,
        &k.pinhole(),
        &poses,
        &points,
        global.final_threshold(),
        Vec::new(),
        options.score,
    )?;
    if !held[0] {
        out.report.with_free_focal_sd(
            &und,
            &k.pinhole(),
            &poses,
            &points,
            global.final_threshold(),
        );
    }
    out.report.notes = s.report.notes;
    out.report.fragments = s.report.fragments;
    out.report.intrinsics = super::solved_intrinsics(&k, held, cov.as_ref());
    if let Some(Err(why)) = &cov {
        out.report
            .notes
            .push(format!("no standard deviations of the intrinsics: {why}"));
    }
    out.path.intrinsics = Some(k);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_geometry::camera::Pose;
    use vfxgraph_geometry::formats::FramePose;
    use vfxgraph_klt::Track;
    use nalgebra::{Matrix3, Rotation3, Vector3};

    /// Tracks of 150 points 8–12 units ahead seen by `poses`, 3 frames each (short-lived, as a
    /// noisy plate's are), and the path of `rotations` (the pan a solve would give).
    fn shot(poses: &[Pose], rotations: &[Matrix3<f64>]) -> (Tracks, CameraPath, Intrinsics) {
        let k = Intrinsics::new(900.0, 900.0, 239.5, 134.5).with_size(480, 270);
        let n = poses.len();
        let mut tracks = Vec::new();
        for j in 0..150usize {
            let x = Vector3::new(
                ((j * 37) % 11) as f64 * 0.25 - 1.25,
                ((j * 53) % 7) as f64 * 0.2 - 0.6,
                8.0 + ((j * 29) % 5) as f64,
            );
            let first = (j * 5) % (n - 2);
            let points = (first..first + 3)
                .map(|i| {
                    let c = poses[i].r * x + poses[i].t;
                    [k.u0 + k.f1 * c.x / c.z, k.v0 + k.f2 * c.y / c.z]
                })
                .collect();
            tracks.push(Track {
                id: j as u64,
                slot: j,
                first,
                points,
                lost: None,
            });
        }
        let tracks = Tracks {
            frames: (0..n as i64).collect(),
            slots: 150,
            image_size: Some([480, 270]),
            tracks,
        };
        let path = CameraPath {
            frames: rotations
                .iter()
                .enumerate()
                .map(|(i, r)| FramePose {
                    frame: i,
                    pose: Pose::new(*r, Vector3::zeros()),
                    focal: None,
                })
                .collect(),
            intrinsics: Some(k.clone()),
        };
        (tracks, path, k)
    }

    /// Tracks of 3 frames (the test's own) are short; the same tracks doubled in length are
    /// not; a clip of 3 frames cannot have longer ones and is not warned of.
    #[test]
    fn short_tracks_are_warned_of() {
        let n = 30;
        let still: Vec<Pose> = (0..n).map(|_| Pose::default()).collect();
        let (mut tracks, ..) = shot(&still, &vec![Matrix3::identity(); n]);
        let w = short_tracks(&tracks).unwrap();
        assert!(
            w.contains("live 3 frames or fewer over a 30-frame shot"),
            "{w}"
        );
        for t in &mut tracks.tracks {
            let more = t.points.clone();
            t.points.extend(more);
            t.first = t.first.min(n - t.points.len());
        }
        assert_eq!(short_tracks(&tracks), None);
        tracks.frames.truncate(3);
        for t in &mut tracks.tracks {
            t.first = 0;
            t.points.truncate(3);
        }
        assert_eq!(short_tracks(&tracks), None);
    }

    /// A nodal pan turning 12° leaves the picture's scale alone; a dolly out by 2 units along
    /// the view shrinks it by what the depths say.
    #[test]
    fn a_dolly_scales_the_picture_and_a_pan_does_not() {
        let n = 30;
        let turn = |i: usize| {
            *Rotation3::from_euler_angles(
                0.01 * i as f64 / n as f64,
                0.21 * i as f64 / n as f64,
                0.0,
            )
            .matrix()
        };
        let pan: Vec<Pose> = (0..n)
            .map(|i| Pose::new(turn(i), Vector3::zeros()))
            .collect();
        let rotations: Vec<Matrix3<f64>> = (0..n).map(turn).collect();
        let (tracks, path, k) = shot(&pan, &rotations);
        let s = picture_scale(&tracks, &k, &path).unwrap();
        assert!((s - 1.0).abs() < 1e-6, "pan: {s}");
        let back = |i: usize| 2.0 * i as f64 / (n - 1) as f64;
        let dolly: Vec<Pose> = (0..n)
            .map(|i| Pose::new(Matrix3::identity(), Vector3::new(0.0, 0.0, back(i))))
            .collect();
        let (tracks, path, k) = shot(&dolly, &vec![Matrix3::identity(); n]);
        let s = picture_scale(&tracks, &k, &path).unwrap();
        // Depths 8–12 (mean 10.0) moving to 10–14: 10/12 = 0.833 for the mean; 0.838 measured.
        assert!((s - 10.0 / 12.0).abs() < 0.02, "dolly: {s}");
    }
}
