//! Solving the lens with the cameras: unknown or approximate focal length and radial
//! distortion (an addition to the book, whose K comes from a prior calibration, §7.1, and whose
//! camera is an ideal pinhole, §2.7).
//!
//! Real footage rarely comes with a calibration, and every lens bends lines. The solve here is
//! the one Blender's and libmv's camera solvers use — the lens refined by the bundle
//! adjustment together with the cameras — organised around the book's pinhole pipeline:
//!
//! 1. **Initial focal length** ([`estimate_focal`], when `focal: unknown`): a one-dimensional
//!    search, as the issue of real cameras suggests and the book's own intrinsics test
//!    (§7.6) does with K: the focal length whose first-fragment solve has the smallest
//!    reprojection error, with the principal point at the frame's centre and square pixels.
//! 2. **Rounds** of: undistort the tracks with the current lens ([`undistort_tracks`]), solve
//!    them with the book's pinhole matchmove, then a global bundle adjustment of the *original*
//!    (distorted) observations in which the shared block `[f, k1, k2]`
//!    ([`crate::bundle::CameraModel::Radial`]) is free with every camera and point
//!    ([`crate::matchmove::global`] with a free lens). The second round starts from a
//!    lens close to the truth, so its fragments are solved as well as a known-K shot's.
//!
//! Figures of the returned [`Solve`] (reprojection errors, inliers, the book-style score) are
//! measured on the undistorted tracks with the solved K: pixels of the ideal pinhole the lens
//! is undistorted to, within a few percent of image pixels for moderate distortion.

use serde::{Deserialize, Serialize};
use vfxgraph_params::{Choice, Options};

use super::{matchmove, MatchmoveOptions, Solve};
use crate::camera::Intrinsics;
use crate::error::{Result, VisionError};
use crate::klt::Tracks;
use crate::lens::Distortion;

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
    /// Needs `focal: refine` (the intrinsics' focal length is the first frame's) or
    /// `unknown`, and `distortion: none` (the intrinsics' own lens is held).
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

/// The focal length (px) whose solve of the first frames fits the tracks best (module docs,
/// step 1): the book's fragment calibration (§7.2–7.9: best pair, resection, refinement
/// cycles) of the first [`SEARCH_FRAMES`] frames with K(f) — the principal point and square
/// pixels of `k`, its focal length ignored — scored by the final RMS reprojection error, on a
/// logarithmic grid of [`GRID`] focal lengths from 0.3 to 3 image diagonals (solved in
/// parallel), then the parabola through the best one and its neighbours. The rounds refine it. A K that is wrong bends the reconstruction, and the refinement cycles cannot
/// fit it: the RMS is smallest near the true focal length.
///
/// Why not from the fundamental matrix (the focal length that makes KᵀFK essential, Bougnoux
/// 1998; Mendonça & Cipolla 1999)? A hand-held orbit around the subject, the commonest
/// matchmove, is the critical motion of two-view self-calibration (optical axes meeting, Sturm
/// 2001): measured on the Blender dev plate it gives 490 px for a 920 px lens.
pub fn estimate_focal(tracks: &Tracks, k: &Intrinsics, options: &MatchmoveOptions) -> Result<f64> {
    let diag = image_diagonal(k)?;
    let fragments = super::split_fragments(tracks, &options.fragments)?;
    let first = fragments.first().ok_or_else(|| {
        VisionError::Degenerate("no fragment to estimate the focal length".into())
    })?;
    // Its first SEARCH_FRAMES frames (and the tracks through them) are enough to tell a lens
    // from another, and fast to solve at many focal lengths.
    let last = first.last.min(first.first + SEARCH_FRAMES - 1);
    let frag = &super::Fragment {
        first: first.first,
        last,
        features: (0..tracks.tracks.len())
            .filter(|&i| super::through(&tracks.tracks[i], first.first, last).is_some())
            .collect(),
        is_last: false,
    };
    // A focal length far from the lens's keeps its adjustments from converging; stopping them
    // at SEARCH_BA_ITERATIONS scores it as bad as it is, for half the work.
    let refine = super::RefineOptions {
        ba_iterations: options.refine.ba_iterations.min(SEARCH_BA_ITERATIONS),
        ..options.refine.clone()
    };
    let cost = |f: f64| -> f64 {
        let kf = Intrinsics {
            f1: f,
            f2: f * k.f2 / k.f1,
            ..k.pinhole()
        };
        let seed = super::derive_seed(options.seed, 1, 0);
        match super::solve_fragment(tracks, &kf, frag, &options.pair, &refine, seed) {
            Ok(s) if s.report.rms.is_finite() && s.report.inliers >= 8 => s.report.rms,
            _ => f64::INFINITY,
        }
    };
    let (lo, hi) = (0.3 * diag, 3.0 * diag);
    log_grid_minimum(lo, hi, GRID, &cost).ok_or_else(|| {
        VisionError::Degenerate(format!(
            "the first frames ({}..{}) solve with no focal length from {lo:.0} to {hi:.0} px: \
             give the intrinsics with focal: refine",
            tracks.frames[frag.first], tracks.frames[frag.last],
        ))
    })
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

/// The minimum of `cost` over `n` focal lengths log-spaced from `lo` to `hi` (evaluated in
/// parallel), refined by the parabola through the best one and its neighbours (in log f);
/// `None` when no cost is finite.
pub(crate) fn log_grid_minimum(
    lo: f64,
    hi: f64,
    n: usize,
    cost: &(dyn Fn(f64) -> f64 + Sync),
) -> Option<f64> {
    use rayon::prelude::*;
    let (lo, hi) = (lo.ln(), hi.ln());
    let step = (hi - lo) / (n - 1) as f64;
    let grid: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|j| cost((lo + step * j as f64).exp()))
        .collect();
    let (jbest, &best) = grid.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    if !best.is_finite() {
        return None;
    }
    let mut x = lo + step * jbest as f64;
    if jbest > 0 && jbest + 1 < n {
        let (a, b, c) = (grid[jbest - 1], best, grid[jbest + 1]);
        let den = a - 2.0 * b + c;
        if a.is_finite() && c.is_finite() && den > 0.0 {
            x += (0.5 * step * (a - c) / den).clamp(-step, step);
        }
    }
    Some(x.exp())
}

/// Fewest tracks (seen in 3 frames or more) a distortion solve accepts: the lens's radial
/// curve needs points spread over the frame, and fewer make k1, k2 noise.
pub const MIN_LENS_TRACKS: usize = 30;

/// Frames of the focal-length search ([`estimate_focal`]). Measured on the distorted dev plate
/// (400 features), with [`SEARCH_BA_ITERATIONS`]: 12 frames and 8 iterations estimate 934.5 px
/// in 0.07 s, 16 and 15 928.7 px in 0.15 s, and the solved lens is the same to 7 digits
/// (921.51 px): the rounds refine any start within a grid step.
const SEARCH_FRAMES: usize = 12;
/// Most Levenberg–Marquardt iterations of an adjustment in the search ([`estimate_focal`]; the
/// solve's own default is 30): a focal length far from the lens's never converges, and stopping
/// early scores it as bad as it is.
const SEARCH_BA_ITERATIONS: usize = 8;
/// Focal lengths tried by the search, log-spaced over 0.3–3 image diagonals (×1.58 apart).
const GRID: usize = 6;

/// The matchmove of real cameras (module docs): the book's matchmove when nothing of the lens
/// is solved (on the tracks undistorted by the intrinsics' own lens), else the rounds of
/// step 2 from the focal length of step 1. The returned path carries the solved intrinsics
/// (focal length and distortion).
pub fn matchmove_with_lens(
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
    let (tripod, focal, note) = super::tripod::decide(tracks, &k, unknown, options)?;
    if let Some(parallax) = tripod {
        if let Some(f) = focal {
            k.f1 = f;
            k.f2 = f;
        }
        let mut solve =
            super::tripod::solve_rotations(tracks, &k, held, options, parallax.as_ref(), progress)?;
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
            let mut solve =
                super::tripod::solve_rotations(tracks, &k, held, options, None, progress)?;
            solve.report.warnings.push(format!(
                "no part of the shot has parallax enough to reconstruct in 3D ({why}); solved \
                 as a nodal pan: the rotations hold, the camera's small travel is not recovered"
            ));
            solve
        }
        Err(e) => return Err(e),
    };
    if let Some(note) = note {
        solve.report.stages.insert(0, motion);
        solve.report.notes.push(note);
    }
    warn_undetermined_focal(&mut solve.report);
    Ok(solve)
}

/// A solved focal length whose standard deviation exceeds this fraction of it is not
/// determined by the shot (a warning).
pub const FOCAL_SD_WARNING: f64 = 0.05;

/// Warns when the solve's focal length is poorly determined: a camera that travels without
/// turning (a dolly, a truck, a push) is a critical motion for self-calibration (Sturm 1997;
/// Kahl, Triggs & Åström 2000) — the tracks fit a wide range of focal lengths, and the cameras
/// of a wrong one are wrong too.
fn warn_undetermined_focal(report: &mut super::SolveReport) {
    let Some(f) = report
        .intrinsics
        .iter()
        .find(|i| i.name == "focal_px" && !i.held)
    else {
        return;
    };
    if let Some(sd) = f.sd.filter(|sd| !(*sd <= FOCAL_SD_WARNING * f.value)) {
        report.warnings.push(format!(
            "the focal length is poorly determined: {:.0} ± {:.0} px ({:.0} %); this camera \
             motion (travel without turning) does not fix it, and the cameras of a wrong focal \
             length are wrong too: give the focal length (focal: known or refine)",
            f.value,
            sd,
            100.0 * sd / f.value
        ));
    }
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
    if lens.focal == FocalMode::Known {
        return Err(VisionError::InvalidInput(
            "zoom: true solves the focal length of every frame: set focal: refine (the \
             intrinsics' focal length is the first frame's) or focal: unknown"
                .into(),
        ));
    }
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
    let unknown = lens.focal == FocalMode::Unknown;
    let (mut solve, focals) = super::zoom::solve_zoom(
        &und,
        &k.pinhole(),
        unknown,
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
        held: false,
        sd: None,
    }];
    Ok(solve)
}

/// [`matchmove_with_lens`] of a moving camera.
fn general_with_lens(
    tracks: &Tracks,
    mut k: Intrinsics,
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
    if lens.focal == FocalMode::Unknown {
        let t0 = std::time::Instant::now();
        let f = estimate_focal(tracks, &k, options)?;
        stages.push(super::StageTime::new("focal estimate", t0));
        notes.push(format!("initial focal length {f:.1} px from the tracks"));
        k.f1 = f;
        k.f2 = f;
    }
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
        stages,
        options.score,
    )?;
    out.report.notes = s.report.notes;
    out.report.notes.extend(notes);
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
