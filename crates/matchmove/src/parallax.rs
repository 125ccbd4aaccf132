//! Nodal pans: a camera that only turns about its optical centre (a tripod pan, or a hand-held
//! pan with no usable parallax). An addition to the book, whose fragments need parallax: a
//! pan's tracks do not define the fundamental matrix of §7.2–7.5 (every F = [e]ₓH of the pan's
//! homography H fits them), so the book's pipeline fails or invents a translation.
//!
//! **Detection** ([`measure_parallax`]): for frame pairs spread over the shot, each pair as far
//! apart as half the tracks of its first frame reach, two models are fitted by RANSAC to the
//! same correspondences: a rotation of the tracks' rays (Kabsch's fit of two rays per sample)
//! and a general fundamental matrix (8 points, Sampson distance). The pair's **parallax** is
//! the median pixel residual the best rotation leaves; the F fit's median residual is the
//! noise the tracks carry whatever the motion. A shot is rotation-only when its largest pair
//! parallax is within `tripod_parallax` px or within [`NOISE_RATIO`] × that noise (a pure
//! rotation leaves 2.5× the median Sampson distance in theory — a 2-D residual against a 1-D
//! one — and 3–3.5× measured, F over-fitting the noise of a pan that does not define it).
//! This is Torr's model selection between a homography and F (GRIC, 1998) reduced to its
//! residuals, with the rotation in place of the homography so that a translating camera over a
//! planar floor — a homography, but not a rotation — is not taken for a pan. With the focal
//! length unknown the rotation needs it first; a shot whose pairs do not even fit homographies
//! ([`rule_out_pan`]; a pan's do, whatever K), or whose pairs' rotation parallax stays well
//! above the threshold at every focal length of the range (`rule_out_pan_at_any_focal`), is a
//! moving camera without that search.
//!
//! [`decide`] turns the measure into the solve's choice of model; the `tripod` module solves a pan.

use nalgebra::Point2;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::ransac::{ransac, Estimator, RansacParams};
use vfxgraph_geometry::two_view::{FundamentalEstimator, HomographyEstimator};
use vfxgraph_klt::Tracks;
use vfxgraph_params::{Choice, Options};

use crate::lens::undistort_tracks;
use crate::rotations::{
    estimate_rotation_focal, ray, rotation_ransac, RotationEstimator, FOCAL_GRID,
    ROTATION_THRESHOLD,
};
use crate::structure::derive_seed;

/// How the matchmove models the camera's motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Choice)]
#[serde(rename_all = "lowercase")]
pub enum SolveMode {
    /// Measure the parallax ([`measure_parallax`]) and solve rotations only when there is none.
    Auto,
    /// The book's solve of a moving camera (it fails on a nodal pan).
    General,
    /// Rotations only: the camera centres at the origin, the points at infinity.
    Tripod,
}

/// The motion part of a matchmove.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct MotionOptions {
    /// the camera's motion: auto (detects nodal pans), general (the book's), tripod (rotations only)
    pub solve: SolveMode,
    /// parallax a nodal pan may leave, px
    ///
    /// `solve: auto` solves rotations only when the largest median residual the best rotation
    /// leaves between frame pairs is within this, or within 6× the tracks' noise.
    #[param(range = 0.0..=1e3)]
    pub tripod_parallax: f64,
}

impl Default for MotionOptions {
    fn default() -> Self {
        MotionOptions {
            solve: SolveMode::Auto,
            tripod_parallax: 1.0,
        }
    }
}

/// A pan leaves at most this many times the tracks' noise (module docs): measured 3–3.5 on
/// synthetic pans, 75 on a moving camera of the same tracks.
pub const NOISE_RATIO: f64 = 6.0;
/// Fewest tracks a frame pair of [`measure_parallax`] shares.
const MIN_COMMON: usize = 20;
/// Frame pairs [`measure_parallax`] measures (spread over the shot).
const PAIRS: usize = 8;

/// One frame pair of [`measure_parallax`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairParallax {
    /// The pair's frame numbers.
    pub frames: [i64; 2],
    /// Tracks seen in both.
    pub tracks: usize,
    /// Median pixel residual of the best rotation (the parallax; NaN when not fitted).
    pub rotation_px: f64,
    /// Median transfer error of the best homography (a pan's is at the noise whatever K).
    pub homography_px: f64,
    /// Median Sampson distance of the best fundamental matrix (the noise).
    pub epipolar_px: f64,
}

/// What [`measure_parallax`] found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parallax {
    /// The pairs measured.
    pub pairs: Vec<PairParallax>,
    /// The largest pair parallax, px.
    pub parallax_px: f64,
    /// The median of the pairs' epipolar residuals: the tracks' noise, px.
    pub noise_px: f64,
    /// What the parallax is compared with, px.
    pub threshold_px: f64,
    /// The parallax is within the threshold: a nodal pan.
    pub rotation_only: bool,
}

impl Parallax {
    /// One line for a report.
    pub fn describe(&self) -> String {
        format!(
            "parallax {:.2} px over {} frame pairs (tracks' noise {:.2} px; a nodal pan within \
             {:.2} px): {}",
            self.parallax_px,
            self.pairs.len(),
            self.noise_px,
            self.threshold_px,
            if self.rotation_only {
                "rotation-only solve"
            } else {
                "a moving camera"
            }
        )
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Frame-index pairs of [`measure_parallax`]: up to [`PAIRS`] first frames spread over the
/// shot, each with the farthest frame that half its tracks (and at least [`MIN_COMMON`]) reach.
fn frame_pairs(tracks: &Tracks) -> Vec<(usize, usize)> {
    let n = tracks.frames.len();
    let step = (n / PAIRS).max(1);
    let mut out = Vec::new();
    for a in (0..n.saturating_sub(1)).step_by(step) {
        let mut ends: Vec<usize> = tracks
            .tracks
            .iter()
            .filter(|t| t.first <= a && t.end() > a + 1)
            .map(|t| t.end() - 1)
            .collect();
        if ends.len() < MIN_COMMON {
            continue;
        }
        ends.sort_unstable_by(|x, y| y.cmp(x));
        let b = ends[(ends.len() / 2).max(MIN_COMMON) - 1];
        if b > a {
            out.push((a, b));
        }
    }
    out
}

/// The parallax of the shot (module docs): `tracks` as a pinhole `k` sees them (undistorted),
/// `k`'s focal length taken as right.
pub fn measure_parallax(
    tracks: &Tracks,
    k: &Intrinsics,
    options: &MotionOptions,
    seed: u64,
) -> Result<Parallax> {
    let pairs = fit_pairs(tracks, Some(k), seed)?;
    let rotation: Vec<f64> = pairs.iter().map(|p| p.rotation_px).collect();
    Ok(decision(pairs, &rotation, options))
}

/// Whether the shot may be a nodal pan whatever its focal length: every pair's tracks fit a
/// homography (a pan's do, H = K R K⁻¹) within the threshold of [`measure_parallax`]. `None`
/// when they may (a pan, or a moving camera over a plane), else the measure that rules it out.
/// This is what spares a moving camera with an unknown lens the focal search of a pan.
pub fn rule_out_pan(
    tracks: &Tracks,
    options: &MotionOptions,
    seed: u64,
) -> Result<Option<Parallax>> {
    let p = by_homography(fit_pairs(tracks, None, seed)?, options);
    Ok((!p.rotation_only).then_some(p))
}

/// The decision of [`rule_out_pan`] on the pairs of [`fit_pairs`] without K.
fn by_homography(pairs: Vec<PairParallax>, options: &MotionOptions) -> Parallax {
    let homography: Vec<f64> = pairs.iter().map(|p| p.homography_px).collect();
    decision(pairs, &homography, options)
}

/// The decision of [`measure_parallax`] on the pairs' parallaxes `parallax`.
fn decision(pairs: Vec<PairParallax>, parallax: &[f64], options: &MotionOptions) -> Parallax {
    let parallax_px = parallax.iter().copied().fold(0.0, f64::max);
    let noise_px = median(pairs.iter().map(|p| p.epipolar_px).collect());
    let threshold_px = options.tripod_parallax.max(NOISE_RATIO * noise_px);
    Parallax {
        pairs,
        parallax_px,
        noise_px,
        threshold_px,
        rotation_only: parallax_px <= threshold_px,
    }
}

/// The largest, over the frame pairs of [`fit_pairs`], of the median image motion of the
/// tracks seen in both frames, px: at the noise for a camera that does not move.
fn image_motion_px(tracks: &Tracks) -> f64 {
    frame_pairs(tracks)
        .into_iter()
        .map(|(a, b)| {
            let d: Vec<f64> = pair_observations(tracks, a, b)
                .iter()
                .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
                .collect();
            if d.is_empty() {
                0.0
            } else {
                median(d)
            }
        })
        .fold(0.0, f64::max)
}

/// The tracks seen in both frames `a` and `b`: their positions in each.
fn pair_observations(tracks: &Tracks, a: usize, b: usize) -> Vec<([f64; 2], [f64; 2])> {
    tracks
        .tracks
        .iter()
        .filter(|t| t.first <= a && t.end() > b)
        .map(|t| (t.points[a - t.first], t.points[b - t.first]))
        .collect()
}

/// The median pixel residual of the best rotation (RANSAC) between the rays of `obs` seen by
/// the pinhole `k`: the pair's parallax at `k`'s focal length (`None` when RANSAC finds none).
fn rotation_px(
    obs: &[([f64; 2], [f64; 2])],
    k: &Intrinsics,
    params: &RansacParams,
    rng: &mut Pcg64,
) -> Option<f64> {
    let rays: Vec<_> = obs.iter().map(|(p, q)| (ray(k, p), ray(k, q))).collect();
    let est = RotationEstimator { focal: k.f1 };
    let rot = ransac(&est, &rays, params, rng).ok()?;
    Some(median(
        rays.iter().map(|d| est.residual(&rot.model, d)).collect(),
    ))
}

/// The models of [`fit_pairs`] for frames `a`, `b` (`None` when a RANSAC finds none).
fn fit_pair(
    tracks: &Tracks,
    k: Option<&Intrinsics>,
    a: usize,
    b: usize,
    seed: u64,
) -> Option<PairParallax> {
    let obs = pair_observations(tracks, a, b);
    let mut rng = Pcg64::seed_from_u64(seed);
    let rotation_px = match k {
        Some(k) => rotation_px(&obs, k, &rotation_ransac(), &mut rng)?,
        None => f64::NAN,
    };
    let pts: Vec<_> = obs
        .iter()
        .map(|(p, q)| (Point2::new(p[0], p[1]), Point2::new(q[0], q[1])))
        .collect();
    let params = RansacParams::with_threshold(ROTATION_THRESHOLD);
    let Ok(h) = ransac(&HomographyEstimator, &pts, &params, &mut rng) else {
        return None;
    };
    let homography_px = median(
        pts.iter()
            .map(|d| HomographyEstimator.residual(&h.model, d))
            .collect(),
    );
    let fe = FundamentalEstimator::default();
    let Ok(f) = ransac(&fe, &pts, &RansacParams::with_threshold(1.5), &mut rng) else {
        return None;
    };
    let epipolar_px = median(pts.iter().map(|d| fe.residual(&f.model, d)).collect());
    if (rotation_px.is_finite() || k.is_none()) && epipolar_px.is_finite() {
        return Some(PairParallax {
            frames: [tracks.frames[a], tracks.frames[b]],
            tracks: obs.len(),
            rotation_px,
            homography_px,
            epipolar_px,
        });
    }
    None
}

/// Whether the shot may be a nodal pan at *some* focal length, given the pairs `pairs` of
/// [`fit_pairs`] without K (their noise): the pairs' rotation parallax minimised over the
/// focal lengths of [`estimate_rotation_focal`]'s range (a log grid of [`FOCAL_GRID`], the
/// parabola through the best). A pan's parallax at its own focal length is at the noise, so a
/// least parallax above [`PAN_MARGIN`] × the threshold rules a pan out without chaining the
/// rotations at every focal length (the search costs ~40× this on the dev plate). `None` when
/// it may be a pan (then the search decides), else the parallax at the best focal length.
pub(crate) fn rule_out_pan_at_any_focal(
    tracks: &Tracks,
    k: &Intrinsics,
    pairs: &[PairParallax],
    options: &MotionOptions,
    seed: u64,
) -> Result<Option<Parallax>> {
    use rayon::prelude::*;
    let diag = crate::grid::image_diagonal(k)?;
    // The frame pairs `pairs` holds (fit_pairs keeps them in order, dropping those it could
    // not fit), with their index in frame_pairs (their seed).
    let fp: Vec<(usize, (usize, usize))> = frame_pairs(tracks)
        .into_iter()
        .enumerate()
        .filter(|(_, (a, b))| {
            let frames = [tracks.frames[*a], tracks.frames[*b]];
            pairs.iter().any(|p| p.frames == frames)
        })
        .collect();
    let obs: Vec<_> = fp
        .iter()
        .map(|&(_, (a, b))| pair_observations(tracks, a, b))
        .collect();
    // Each pair on the seed fit_pairs gives it, at every focal length. A rotation at a wrong
    // focal length has few inliers, and RANSAC would draw up to its cap of samples for it:
    // [`GRID_ITERATIONS`] measure such a focal length as bad as it is (two rays a sample: a
    // pan's pairs, most tracks inliers, need ~25).
    let capped = RansacParams {
        max_iterations: GRID_ITERATIONS,
        ..rotation_ransac()
    };
    let parallaxes = |f: f64| -> Vec<Option<f64>> {
        let kf = Intrinsics {
            f1: f,
            f2: f * k.f2 / k.f1,
            ..k.pinhole()
        };
        fp.par_iter()
            .zip(&obs)
            .map(|(&(pi, _), o)| {
                let mut rng = Pcg64::seed_from_u64(derive_seed(seed, 11, pi as u64));
                rotation_px(o, &kf, &capped, &mut rng)
            })
            .collect()
    };
    let worst = |f: f64| {
        let r = parallaxes(f);
        match r.iter().all(Option::is_some) {
            true => r.into_iter().flatten().fold(0.0, f64::max),
            false => f64::INFINITY,
        }
    };
    let Some(f) = crate::grid::log_grid_minimum(0.3 * diag, 3.0 * diag, FOCAL_GRID, &worst) else {
        return Ok(None);
    };
    let Some(at_best) = parallaxes(f).into_iter().collect::<Option<Vec<f64>>>() else {
        return Ok(None);
    };
    let with_rotation: Vec<PairParallax> = pairs
        .iter()
        .zip(&at_best)
        .map(|(p, &rotation_px)| PairParallax {
            rotation_px,
            ..p.clone()
        })
        .collect();
    let p = decision(with_rotation, &at_best, options);
    Ok((p.parallax_px > PAN_MARGIN * p.threshold_px).then_some(p))
}

/// RANSAC samples per pair and focal length in [`rule_out_pan_at_any_focal`].
const GRID_ITERATIONS: usize = 300;

/// How far above the pan threshold the least parallax over focal lengths must be for
/// [`rule_out_pan_at_any_focal`] to call the camera moving without the focal search: the
/// grid's parabola only approximates the least parallax, so a pan near its threshold is left
/// to the search.
const PAN_MARGIN: f64 = 2.0;

/// The three models of every pair of [`frame_pairs`]: the rotation (when `k` is given; NaN
/// otherwise), the homography and the fundamental matrix, each by RANSAC, with the median
/// residual of every common track.
pub(crate) fn fit_pairs(
    tracks: &Tracks,
    k: Option<&Intrinsics>,
    seed: u64,
) -> Result<Vec<PairParallax>> {
    use rayon::prelude::*;
    // Each pair on its own seeded generator: the same pairs whatever the thread count.
    let fitted: Vec<Option<PairParallax>> = frame_pairs(tracks)
        .into_par_iter()
        .enumerate()
        .map(|(pi, (a, b))| fit_pair(tracks, k, a, b, derive_seed(seed, 11, pi as u64)))
        .collect();
    let pairs: Vec<PairParallax> = fitted.into_iter().flatten().collect();
    if pairs.is_empty() {
        return Err(VisionError::Degenerate(format!(
            "no two frames share {MIN_COMMON} tracks: the camera's motion cannot be measured"
        )));
    }
    Ok(pairs)
}

/// What `motion` asks for the shot (`seed`: the matchmove's): `Some(parallax)` to solve rotations only (the
/// parallax measured, `None` for `solve: tripod`), `None` for the general solve, with a note
/// for the report. With `focal_unknown` the parallax is measured at the focal length the
/// rotations fit best ([`estimate_rotation_focal`]), returned with the decision.
#[allow(clippy::type_complexity)]
pub fn decide(
    tracks: &Tracks,
    k: &Intrinsics,
    focal_unknown: bool,
    motion: &MotionOptions,
    seed: u64,
) -> Result<(Option<Option<Parallax>>, Option<f64>, Option<String>)> {
    let seed = derive_seed(seed, 14, 0);
    match motion.solve {
        SolveMode::General => Ok((None, None, None)),
        SolveMode::Tripod => {
            let f = if focal_unknown {
                Some(estimate_rotation_focal(
                    &undistort_tracks(tracks, k)?,
                    k,
                    seed,
                )?)
            } else {
                None
            };
            Ok((Some(None), f, None))
        }
        SolveMode::Auto => {
            let und = undistort_tracks(tracks, k)?;
            let mut pan_threshold = None;
            if focal_unknown {
                let pairs = match fit_pairs(&und, None, seed) {
                    Ok(p) => p,
                    Err(e) => return Ok((None, None, Some(format!("parallax not measured: {e}")))),
                };
                let h = by_homography(pairs.clone(), motion);
                if !h.rotation_only {
                    return Ok((None, None, Some(h.describe())));
                }
                pan_threshold = Some((h.threshold_px, h.noise_px));
                if let Some(p) = rule_out_pan_at_any_focal(&und, k, &pairs, motion, seed)? {
                    return Ok((None, None, Some(p.describe())));
                }
            }
            let (kp, f) = if focal_unknown {
                // A camera that hardly turns gives a pan no focal length: the general solve's
                // own search measures it where the shot has parallax (a plane's homographies
                // look like a pan's), and falls back to a rotation-only solve where not.
                let f = match estimate_rotation_focal(&und, k, seed) {
                    Ok(f) => f,
                    Err(e) => {
                        let moved = image_motion_px(&und);
                        if let Some((threshold, noise)) = pan_threshold {
                            if moved <= threshold {
                                return Err(VisionError::NoParallax(format!(
                                    "the camera neither turns nor travels: its tracks move \
                                     {moved:.2} px at most (noise {noise:.2} px)"
                                )));
                            }
                        }
                        return Ok((None, None, Some(format!("not a pan: {e}"))));
                    }
                };
                let kp = Intrinsics {
                    f1: f,
                    f2: f * k.f2 / k.f1,
                    ..k.pinhole()
                };
                (kp, Some(f))
            } else {
                (k.pinhole(), None)
            };
            match measure_parallax(&und, &kp, motion, seed) {
                Ok(p) if p.rotation_only => Ok((Some(Some(p)), f, None)),
                Ok(p) => Ok((None, None, Some(p.describe()))),
                Err(e) => Ok((None, None, Some(format!("parallax not measured: {e}")))),
            }
        }
    }
}
