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
//! **Solve** ([`solve_rotations`]): the rotations are chained frame by frame (each frame's
//! rotation from the directions of the tracks already seen, RANSAC + Kabsch), then refined by
//! the bundle adjustment with every camera centre held at the origin
//! ([`vfxgraph_bundle::Gauge::RotationOnly`]) and each point a direction (on the unit sphere),
//! in rounds of outlier marking as [`super::global`] does. An unknown focal length comes from a
//! one-dimensional search of the chained rotations' residual over focal lengths
//! ([`estimate_rotation_focal`]; a rotating camera's homographies K R K⁻¹ fix K: Hartley 1997,
//! "Self-calibration of stationary cameras"), then the adjustment refines it with the lens.

use nalgebra::{Matrix3, Point2, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use vfxgraph_params::{Choice, Options};

use super::lens_solve::undistort_tracks;
use super::{derive_seed, reprojection_error, MatchmoveOptions, Solve, StageTime};
use vfxgraph_bundle::Gauge;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;
use vfxgraph_geometry::ransac::{ransac, Estimator, RansacParams};
use vfxgraph_geometry::rotation::nearest_rotation;
use vfxgraph_geometry::two_view::{FundamentalEstimator, HomographyEstimator};

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
/// RANSAC threshold of the rotation fits, px.
const ROTATION_THRESHOLD: f64 = 3.0;
/// Focal lengths tried by [`estimate_rotation_focal`], log-spaced over 0.3–3 diagonals.
const FOCAL_GRID: usize = 16;

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

/// A rotation R with b ≈ R·a between unit rays (a, b), fitted by Kabsch's SVD; residuals in
/// pixels of a camera of focal length `focal` (the chord between rays × f).
struct RotationEstimator {
    focal: f64,
}

impl Estimator for RotationEstimator {
    type Datum = (Vector3<f64>, Vector3<f64>);
    type Model = Matrix3<f64>;
    const MIN_SAMPLES: usize = 2;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Self::Model> {
        let mut m = Matrix3::zeros();
        for &i in sample {
            m += data[i].1 * data[i].0.transpose();
        }
        vec![nearest_rotation(&m)]
    }

    fn residual(&self, r: &Self::Model, d: &Self::Datum) -> f64 {
        self.focal * (d.1 - r * d.0).norm()
    }
}

/// The unit ray of pixel `p` of a pinhole `k`.
fn ray(k: &Intrinsics, p: &[f64; 2]) -> Vector3<f64> {
    let q = k.k_inv() * Vector3::new(p[0], p[1], 1.0);
    q / q.norm()
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
    let diag = super::lens_solve::image_diagonal(k)?;
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
    let Some(f) = super::lens_solve::log_grid_minimum(0.3 * diag, 3.0 * diag, FOCAL_GRID, &worst)
    else {
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

/// The RANSAC of a pair's rotation.
fn rotation_ransac() -> RansacParams {
    RansacParams::with_threshold(ROTATION_THRESHOLD)
}

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

/// Rotations of a pan chained frame by frame, and the tracks' directions.
struct Chain {
    /// R of every frame (a world direction d is seen along the ray R·d).
    rotations: Vec<Matrix3<f64>>,
    /// Direction of each track seen in two frames or more.
    directions: Vec<Option<Vector3<f64>>>,
    /// Inlier flag of every observation (by track and observation).
    inliers: Vec<Vec<bool>>,
}

/// Chains the rotations of `tracks` (seen by the pinhole `k`): frame 0 is the identity; each
/// next frame's rotation is fitted by RANSAC to the directions of the tracks it continues
/// (the mean of their rays so far, rotated back), and its inlier rays join the means.
fn chain(tracks: &Tracks, k: &Intrinsics, seed: u64) -> Result<Chain> {
    let n = tracks.frames.len();
    let rays: Vec<Vec<Vector3<f64>>> = tracks
        .tracks
        .iter()
        .map(|t| t.points.iter().map(|p| ray(k, p)).collect())
        .collect();
    let mut seen: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (ti, t) in tracks.tracks.iter().enumerate() {
        for j in 0..t.points.len() {
            seen[t.first + j].push((ti, j));
        }
    }
    let mut sums = vec![Vector3::zeros(); tracks.tracks.len()];
    let mut counts = vec![0usize; tracks.tracks.len()];
    let mut inliers: Vec<Vec<bool>> = tracks
        .tracks
        .iter()
        .map(|t| vec![false; t.points.len()])
        .collect();
    let mut rotations = vec![Matrix3::identity(); n];
    let est = RotationEstimator { focal: k.f1 };
    for i in 0..n {
        let (known, new): (Vec<_>, Vec<_>) = seen[i].iter().partition(|(ti, _)| counts[*ti] > 0);
        if i > 0 {
            let data: Vec<_> = known
                .iter()
                .map(|&(ti, j)| (sums[ti].normalize(), rays[ti][j]))
                .collect();
            if data.len() < 3 {
                return Err(VisionError::Degenerate(format!(
                    "frame {}: {} tracks continue from the frames before; a rotation needs 3",
                    tracks.frames[i],
                    data.len()
                )));
            }
            let mut rng = Pcg64::seed_from_u64(derive_seed(seed, 12, i as u64));
            let params = RansacParams::with_threshold(ROTATION_THRESHOLD);
            let fit = ransac(&est, &data, &params, &mut rng)?;
            rotations[i] = fit.model;
            for (&(ti, j), &ok) in known.iter().zip(&fit.inliers) {
                if ok {
                    sums[ti] += fit.model.transpose() * rays[ti][j];
                    counts[ti] += 1;
                    inliers[ti][j] = true;
                }
            }
        }
        let r = rotations[i];
        for &(ti, j) in if i == 0 { &seen[0] } else { &new } {
            sums[ti] += r.transpose() * rays[ti][j];
            counts[ti] += 1;
            inliers[ti][j] = true;
        }
    }
    let directions = sums
        .iter()
        .zip(&counts)
        .map(|(s, &c)| (c >= 2).then(|| s.normalize()))
        .collect();
    Ok(Chain {
        rotations,
        directions,
        inliers,
    })
}

/// The focal length (px) whose chained rotations fit the tracks best (module docs): the mean
/// squared pixel residual of [`chain`], each residual truncated at the RANSAC threshold, on a
/// logarithmic grid of [`FOCAL_GRID`] focal lengths from 0.3 to 3 image diagonals (in
/// parallel), then the parabola through the best and its neighbours; the adjustment refines it.
pub fn estimate_rotation_focal(tracks: &Tracks, k: &Intrinsics, seed: u64) -> Result<f64> {
    let diag = super::lens_solve::image_diagonal(k)?;
    let cost = |f: f64| -> f64 {
        let kf = Intrinsics {
            f1: f,
            f2: f * k.f2 / k.f1,
            ..k.pinhole()
        };
        let Ok(c) = chain(tracks, &kf, seed) else {
            return f64::INFINITY;
        };
        let (mut s, mut m) = (0.0, 0usize);
        for (t, d) in tracks.tracks.iter().zip(&c.directions) {
            let Some(d) = d else { continue };
            for (j, p) in t.points.iter().enumerate() {
                let pose = Pose::new(c.rotations[t.first + j], Vector3::zeros());
                let e = reprojection_error(&kf, &pose, d, p).min(ROTATION_THRESHOLD);
                s += e * e;
                m += 1;
            }
        }
        if m == 0 {
            f64::INFINITY
        } else {
            s / m as f64
        }
    };
    let Some(f) = super::lens_solve::log_grid_minimum(0.3 * diag, 3.0 * diag, FOCAL_GRID, &cost)
    else {
        return Err(VisionError::Degenerate(
            "the pan's rotations cannot be chained at any focal length".into(),
        ));
    };
    // A camera that hardly turns fits every focal length alike.
    let kf = Intrinsics {
        f1: f,
        f2: f * k.f2 / k.f1,
        ..k.pinhole()
    };
    let c = chain(tracks, &kf, seed)?;
    let turn = c
        .rotations
        .iter()
        .map(|r| vfxgraph_geometry::rotation::r_to_axis_angle(r).norm().to_degrees())
        .fold(0.0, f64::max);
    if turn < MIN_TURN_DEGREES {
        return Err(VisionError::Degenerate(format!(
            "the camera hardly turns (at most {turn:.2}° from the first frame): a pan's focal \
             length cannot be measured; give it with focal: known or refine"
        )));
    }
    Ok(f)
}

/// The least turn from the first frame that measures a pan's focal length, degrees.
const MIN_TURN_DEGREES: f64 = 2.0;

/// The direction of a track from its inlier observations in the cameras `rotations`: the
/// normalized mean of its rays rotated back (the rotation-only triangulation).
fn direction(
    k: &Intrinsics,
    track: &vfxgraph_klt::Track,
    rotations: &[Matrix3<f64>],
    keep: &[bool],
) -> Option<Vector3<f64>> {
    let mut s = Vector3::zeros();
    let mut c = 0;
    for (j, p) in track.points.iter().enumerate() {
        if keep[j] {
            s += rotations[track.first + j].transpose() * ray(k, p);
            c += 1;
        }
    }
    (c >= 2 && s.norm() > 0.0).then(|| s.normalize())
}

/// Solves a nodal pan (module docs): `tracks` as observed, `k` the starting intrinsics with the
/// lens model to refine (`held`: the flags of the block `[f, k1, k2]`), `parallax` what the
/// detection measured (reported). Every camera centre of the returned path is the origin; the
/// cloud's points are the tracks' directions on the unit sphere.
pub fn solve_rotations(
    tracks: &Tracks,
    k: &Intrinsics,
    held: super::Held,
    options: &MatchmoveOptions,
    parallax: Option<&Parallax>,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<Solve> {
    let t0 = std::time::Instant::now();
    let mut stages = Vec::new();
    let mut k = k.clone();
    let mut und = undistort_tracks(tracks, &k)?;
    progress("rotations", 0, 1);
    let c = chain(&und, &k.pinhole(), derive_seed(options.seed, 13, 0))?;
    let mut rotations = c.rotations;
    let mut points = c.directions;
    let mut flags = c.inliers;
    stages.push(StageTime::new("rotation chain", t0));
    let mut tolerance = ROTATION_THRESHOLD;
    let mut cov = None;
    if let Some(g) = &options.global {
        let t0 = std::time::Instant::now();
        let mut thresholds = vec![g.triangulation_tolerance];
        thresholds.extend(g.thresholds.iter().copied());
        for (round, &threshold) in thresholds.iter().enumerate() {
            progress("rotation adjustment", round, thresholds.len());
            let kp = k.pinhole();
            let mut poses: Vec<Option<Pose>> = rotations
                .iter()
                .map(|r| Some(Pose::new(*r, Vector3::zeros())))
                .collect();
            if round > 0 {
                for (ti, t) in und.tracks.iter().enumerate() {
                    let Some(x) = points[ti] else { continue };
                    let keep: Vec<bool> = t
                        .points
                        .iter()
                        .enumerate()
                        .map(|(j, p)| {
                            let pose = poses[t.first + j].as_ref().expect("every frame posed");
                            reprojection_error(&kp, pose, &x, p) <= threshold
                        })
                        .collect();
                    points[ti] = direction(&kp, t, &rotations, &keep);
                    flags[ti] = keep;
                }
            }
            let keep =
                |ti: usize, f: usize| f64::from(u8::from(flags[ti][f - tracks.tracks[ti].first]));
            let block = super::lens_block(&k, held);
            let last = round + 1 == thresholds.len();
            let (_, b, c) = super::adjust_with_block(
                tracks,
                block,
                Gauge::RotationOnly,
                &mut poses,
                &mut points,
                &keep,
                g.loss(),
                g.max_iterations,
                last && held.iter().any(|h| !h),
            )?;
            cov = c;
            k = super::intrinsics_of_block(&k, &b);
            k.validate().map_err(|e| {
                VisionError::Degenerate(format!("the solved lens is not usable: {e}"))
            })?;
            if !k.is_pinhole() {
                und = undistort_tracks(tracks, &k)?;
            }
            for (r, p) in rotations.iter_mut().zip(&poses) {
                *r = p.as_ref().expect("every frame posed").r;
            }
            // Directions stay unit vectors (the adjustment may slide them along their rays).
            for x in points.iter_mut().flatten() {
                *x = x.normalize();
            }
            tolerance = threshold;
        }
        stages.push(StageTime::new("rotation adjustment", t0));
    }
    progress("rotations", 1, 1);
    let poses: Vec<Option<Pose>> = rotations
        .iter()
        .map(|r| Some(Pose::new(*r, Vector3::zeros())))
        .collect();
    let mut solve = super::finish_solve(
        &und,
        &k.pinhole(),
        &poses,
        &points,
        tolerance,
        stages,
        false,
    )?;
    solve.report.rotation_only = true;
    if !held[0] {
        solve
            .report
            .with_free_focal_sd(&und, &k.pinhole(), &poses, &points, tolerance);
    }
    if held.iter().any(|h| !h) {
        solve.report.intrinsics = super::solved_intrinsics(&k, held, cov.as_ref());
    }
    solve.report.notes.push(match parallax {
        Some(p) => p.describe(),
        None => "rotation-only solve (solve: tripod)".into(),
    });
    solve.report.notes.push(
        "nodal pan: every camera centre is the origin and the points are directions (on the \
         unit sphere); set the scene's scale and ground from marks or a known distance"
            .into(),
    );
    solve.path.intrinsics = Some(k);
    Ok(solve)
}

/// What `options.motion` asks for the shot: `Some(parallax)` to solve rotations only (the
/// parallax measured, `None` for `solve: tripod`), `None` for the general solve, with a note
/// for the report. With `focal_unknown` the parallax is measured at the focal length the
/// rotations fit best ([`estimate_rotation_focal`]), returned with the decision.
#[allow(clippy::type_complexity)]
pub fn decide(
    tracks: &Tracks,
    k: &Intrinsics,
    focal_unknown: bool,
    options: &MatchmoveOptions,
) -> Result<(Option<Option<Parallax>>, Option<f64>, Option<String>)> {
    let seed = derive_seed(options.seed, 14, 0);
    match options.motion.solve {
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
                let h = by_homography(pairs.clone(), &options.motion);
                if !h.rotation_only {
                    return Ok((None, None, Some(h.describe())));
                }
                pan_threshold = Some((h.threshold_px, h.noise_px));
                if let Some(p) = rule_out_pan_at_any_focal(&und, k, &pairs, &options.motion, seed)?
                {
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
            match measure_parallax(&und, &kp, &options.motion, seed) {
                Ok(p) if p.rotation_only => Ok((Some(Some(p)), f, None)),
                Ok(p) => Ok((None, None, Some(p.describe()))),
                Err(e) => Ok((None, None, Some(format!("parallax not measured: {e}")))),
            }
        }
    }
}
