//! A zooming lens: one focal length per frame, smoothed by a prior between neighbouring
//! frames (an addition to the book, whose K is fixed, §7.1; what SynthEyes' and PFTrack's
//! zoom solves do).
//!
//! With the principal point fixed, a change of focal length scales the image about it: the
//! tracks of frame i seen at focal length fᵢ are those a lens of focal length f_ref would see,
//! scaled by fᵢ/f_ref. So the solve brings every frame to one focal length and runs the
//! book's fixed-K pipeline on the result:
//!
//! 1. **Initial ratios** ([`zoom_ratios`]): between consecutive frames, the scale of the 2D
//!    similarity that best maps one frame's tracks to the next's; the ratios' running product
//!    is each frame's focal length relative to the first. (A camera moving towards the scene
//!    also enlarges it; the adjustment corrects what the ratios take for zoom.)
//! 2. The tracks **normalised** to the first frame's focal length ([`normalise`]); its value
//!    estimated as an unknown focal length is ([`crate::focal::estimate_focal`]) or taken
//!    from the intrinsics.
//! 3. **Rounds** of: the book's matchmove of the normalised tracks, then a global bundle
//!    adjustment of the observed pixels in which every frame has its own focal length and
//!    the prior `(fᵢ₋₁ − 2fᵢ + fᵢ₊₁)/σ` ([`zoom_priors`]; σ = `zoom_smoothness`, px per frame²)
//!    keeps the zoom smooth without pulling a steady zoom towards a constant (a second
//!    difference is zero on any linear ramp). Triangulation, outlier marking and track weights
//!    work on the normalised tracks with the reference K, which for a pinhole is exact.
//!
//! Focal lengths that vary are determined only by a camera whose centres leave a line and
//! whose optical axes do not all meet (a dolly, an orbit and a pan are critical motions, Kahl,
//! Triggs & Åström 2000); the prior then keeps the path smooth, not right — unless the
//! first frame's focal length is known (`focal: known`), which the adjustment then holds.

use nalgebra::Vector2;
use vfxgraph_bundle::{zoom_priors, Gauge};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;

use crate::lens::FocalMode;
use crate::options::MatchmoveOptions;
use crate::pipeline::{matchmove, Solve};

/// Fewest rounds of a zoom solve: the first round's fixed-focal solve starts from the
/// scale-change ratios, which take a camera moving towards the scene for a zoom, and its poses
/// are bent by that (measured on the synthetic zoom: rotations 5.8° off after one round,
/// 0.04° after two).
pub const MIN_ZOOM_ROUNDS: usize = 2;

/// A zoom whose points' [`thickness`] is below this is warned of: over a plane a change of
/// focal length and a move towards it are nearly confounded. On the rendered corpus's zooms
/// (15 solved, two seeds) the six below 5 % were 0.5–3.2° off (two of them silent before this
/// warning); of the nine above, seven were within 0.7°, two 0.9° and 1.1° off.
pub const FLAT_ZOOM_THICKNESS: f64 = 0.05;

/// Fewest tracks two consecutive frames must share for their zoom ratio
/// ([`zoom_ratios`]); with fewer the ratio is taken as 1.
pub const MIN_SHARED_TRACKS: usize = 8;

/// Per frame index, its focal length relative to the first frame's (module docs, step 1): the
/// running product of the scales of the 2D similarities (least squares, then again without the
/// tracks off by more than three times the median residual) between consecutive frames'
/// tracks, about the principal point of `k`.
pub fn zoom_ratios(tracks: &Tracks, k: &Intrinsics) -> Vec<f64> {
    let n = tracks.frames.len();
    let mut pairs: Vec<Vec<(Vector2<f64>, Vector2<f64>)>> = vec![Vec::new(); n.saturating_sub(1)];
    for t in &tracks.tracks {
        for (j, w) in t.points.windows(2).enumerate() {
            let f = t.first + j;
            if f + 1 < n {
                pairs[f].push((
                    Vector2::new(w[0][0] - k.u0, w[0][1] - k.v0),
                    Vector2::new(w[1][0] - k.u0, w[1][1] - k.v0),
                ));
            }
        }
    }
    let mut ratios = Vec::with_capacity(n);
    let mut s = 1.0;
    if n > 0 {
        ratios.push(1.0);
    }
    for p in &pairs {
        s *= similarity_scale(p).unwrap_or(1.0);
        ratios.push(s);
    }
    ratios
}

/// The scale of the 2D similarity b ≈ s·R·a + t of matched points (module docs); `None` with
/// fewer than [`MIN_SHARED_TRACKS`] or no spread.
fn similarity_scale(pairs: &[(Vector2<f64>, Vector2<f64>)]) -> Option<f64> {
    let fit = |use_: &dyn Fn(usize) -> bool| -> Option<(f64, f64, Vector2<f64>, Vector2<f64>)> {
        let idx: Vec<usize> = (0..pairs.len()).filter(|&i| use_(i)).collect();
        if idx.len() < MIN_SHARED_TRACKS {
            return None;
        }
        let m = idx.len() as f64;
        let ma = idx.iter().map(|&i| pairs[i].0).sum::<Vector2<f64>>() / m;
        let mb = idx.iter().map(|&i| pairs[i].1).sum::<Vector2<f64>>() / m;
        let (mut aa, mut dot, mut cross) = (0.0, 0.0, 0.0);
        for &i in &idx {
            let (a, b) = (pairs[i].0 - ma, pairs[i].1 - mb);
            aa += a.norm_squared();
            dot += a.dot(&b);
            cross += a.x * b.y - a.y * b.x;
        }
        (aa > 0.0).then(|| (dot / aa, cross / aa, ma, mb))
    };
    let residual = |(c, s, ma, mb): (f64, f64, Vector2<f64>, Vector2<f64>), i: usize| {
        let a = pairs[i].0 - ma;
        let pred = Vector2::new(c * a.x - s * a.y, s * a.x + c * a.y) + mb;
        (pred - pairs[i].1).norm()
    };
    let first = fit(&|_| true)?;
    let mut r: Vec<f64> = (0..pairs.len()).map(|i| residual(first, i)).collect();
    let mut sorted = r.clone();
    sorted.sort_by(f64::total_cmp);
    let cut = 3.0 * sorted[sorted.len() / 2].max(1e-9);
    r.iter_mut()
        .for_each(|e| *e = if *e <= cut { 0.0 } else { 1.0 });
    let (c, s, ..) = fit(&|i| r[i] == 0.0).unwrap_or(first);
    let scale = (c * c + s * s).sqrt();
    (scale.is_finite() && scale > 0.0).then_some(scale)
}

/// The tracks as a lens of focal length `f_ref` would see them: frame i's observations
/// scaled about the principal point of `k` by `f_ref / focals[i]` (module docs).
pub fn normalise(tracks: &Tracks, k: &Intrinsics, focals: &[f64], f_ref: f64) -> Tracks {
    let mut out = tracks.clone();
    for t in &mut out.tracks {
        for (j, p) in t.points.iter_mut().enumerate() {
            let s = f_ref / focals[t.first + j];
            *p = [k.u0 + (p[0] - k.u0) * s, k.v0 + (p[1] - k.v0) * s];
        }
    }
    out
}

/// The pinhole of `k` with focal length `f` (the aspect kept).
fn with_focal(k: &Intrinsics, f: f64) -> Intrinsics {
    Intrinsics {
        f1: f,
        f2: f * k.f2 / k.f1,
        ..k.pinhole()
    }
}

/// The matchmove of a zooming lens (module docs). `und` are the tracks through an ideal
/// pinhole (the intrinsics' own lens undistorted), `k` that pinhole, whose focal length is the
/// first frame's: held through the adjustment (`focal` known), its start (refine), or
/// estimated from the tracks (unknown); `sigma` the prior's σ (px per frame²). Returns the solve, whose path carries every frame's focal length, and the
/// focal lengths.
pub(crate) fn solve_zoom(
    und: &Tracks,
    k: &Intrinsics,
    focal: FocalMode,
    sigma: f64,
    rounds: usize,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
) -> Result<(Solve, Vec<f64>)> {
    let Some(global) = &options.global else {
        return Err(VisionError::InvalidInput(
            "a zoom is solved by the global bundle adjustment (global_adjust: true)".into(),
        ));
    };
    if !(sigma > 0.0 && sigma.is_finite()) {
        return Err(VisionError::InvalidInput(format!(
            "zoom_smoothness must be positive, not {sigma}"
        )));
    }
    let mut stages = Vec::new();
    let mut notes = Vec::new();
    let t0 = std::time::Instant::now();
    let ratios = zoom_ratios(und, k);
    let f0 = if focal == FocalMode::Unknown {
        let norm = normalise(und, k, &ratios, 1.0);
        let f = crate::focal::estimate_focal(&norm, k, options)?;
        stages.push(crate::report::StageTime::new("focal estimate", t0));
        notes.push(format!(
            "initial focal length {f:.1} px (first frame) from the tracks"
        ));
        f
    } else {
        k.f1
    };
    let mut focals: Vec<f64> = ratios.iter().map(|r| f0 * r).collect();
    notes.push(format!(
        "zoom: initial focal lengths {:.1} → {:.1} px from the frames' scale changes",
        focals.first().copied().unwrap_or(f0),
        focals.last().copied().unwrap_or(f0)
    ));
    let k_ref = with_focal(k, f0);
    // The rounds start from focal lengths that are still wrong: the book's start (whose DLT
    // estimates each frame's K) tolerates that, where the calibrated one takes K as exact; the
    // calibrated start is the fallback where the book's fails (planar sets).
    let inner = MatchmoveOptions {
        global: None,
        score: false,
        pair: crate::pair::PairOptions {
            init: crate::pair::InitMethod::Book,
            ..options.pair.clone()
        },
        ..options.clone()
    };
    let calibrated = MatchmoveOptions {
        pair: crate::pair::PairOptions {
            init: crate::pair::InitMethod::Calibrated,
            ..options.pair.clone()
        },
        ..inner.clone()
    };
    let mut solved = None;
    for round in 0..rounds.max(MIN_ZOOM_ROUNDS) {
        let t0 = std::time::Instant::now();
        let norm = normalise(und, k, &focals, f0);
        let s = match matchmove(&norm, &k_ref, &inner, progress) {
            Ok(s) => s,
            // The book's start is degenerate on a plane (a floor, a wall): the calibrated one
            // is not, and the ratios' focal lengths are near enough for it to start.
            Err(_) => matchmove(&norm, &k_ref, &calibrated, progress)?,
        };
        stages.push(crate::report::StageTime::new(
            &format!("round {}: fixed-focal solve", round + 1),
            t0,
        ));
        let t0 = std::time::Instant::now();
        let poses = crate::structure::poses_by_index(&norm, &s.path);
        let hold_first = focal == FocalMode::Known;
        let (poses, points, f_new) =
            zoom_adjust(und, k, f0, &focals, &poses, global, sigma, hold_first)?;
        stages.push(crate::report::StageTime::new(
            &format!("round {}: zoom adjustment", round + 1),
            t0,
        ));
        if let Some(bad) = f_new.iter().position(|f| !(*f > 0.0 && f.is_finite())) {
            return Err(VisionError::Degenerate(format!(
                "the zoom solve gave frame {} a focal length of {}",
                und.frames[bad], f_new[bad]
            )));
        }
        focals = f_new;
        solved = Some((poses, points, s));
    }
    let (poses, points, s) = solved.expect("at least one round");
    let norm = normalise(und, k, &focals, f0);
    let mut out = crate::pipeline::finish_solve(
        &norm,
        &k_ref,
        &poses,
        &points,
        global.final_threshold(),
        stages,
        options.score,
    )?;
    out.report.notes = s.report.notes;
    out.report.notes.extend(notes);
    out.report.notes.push(format!(
        "zoom: focal length {:.1} → {:.1} px (min {:.1}, max {:.1}); per-frame figures are in \
         pixels of the first frame's focal length",
        focals[0],
        focals[focals.len() - 1],
        focals.iter().copied().fold(f64::INFINITY, f64::min),
        focals.iter().copied().fold(0.0, f64::max),
    ));
    if let Some(t) = thickness(&out.cloud.points).filter(|t| *t < FLAT_ZOOM_THICKNESS) {
        out.report.warnings.push(format!(
            "a zoom over a nearly flat scene (the points' thinnest spread is {:.1} % of their \
             widest): a change of focal length and a move towards the plane look nearly alike, \
             so the focal lengths and the cameras can be degrees wrong; track features off the \
             plane, or give the focal lengths",
            100.0 * t
        ));
    }
    out.report.fragments = s.report.fragments;
    for (fr, f) in out.report.frames.iter_mut().zip(&focals) {
        fr.focal_px = Some(*f);
    }
    for (fp, f) in out.path.frames.iter_mut().zip(&focals) {
        fp.focal = Some(*f);
    }
    out.path.intrinsics = Some(with_focal(k, focals[0]));
    Ok((out, focals))
}

/// How far the points are from lying on one plane: the standard deviation of their scatter's
/// thinnest direction over that of its widest, √(λmin / λmax), over the 95 % of points nearest
/// their median (a few stray points do not thicken a floor); `None` for fewer than 10 points.
pub fn thickness(points: &[[f64; 3]]) -> Option<f64> {
    use nalgebra::{Matrix3, Vector3};
    if points.len() < 10 {
        return None;
    }
    let median = |k: usize| {
        let mut v: Vec<f64> = points.iter().map(|p| p[k]).collect();
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let m = Vector3::new(median(0), median(1), median(2));
    let mut by_distance: Vec<(f64, Vector3<f64>)> = points
        .iter()
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .filter(|p| p.iter().all(|x| x.is_finite()))
        .map(|p| ((p - m).norm(), p))
        .collect();
    by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
    by_distance.truncate((by_distance.len() * 95).div_ceil(100));
    let n = by_distance.len() as f64;
    let c = by_distance.iter().fold(Vector3::zeros(), |a, (_, p)| a + p) / n;
    let s = by_distance.iter().fold(Matrix3::zeros(), |a, (_, p)| {
        let d = p - c;
        a + d * d.transpose()
    });
    let ev = s.symmetric_eigen().eigenvalues;
    let (min, max) = (ev.min().max(0.0), ev.max());
    (max > 0.0).then(|| (min / max).sqrt())
}

/// The global adjustment of a zoom (module docs, step 3): the rounds of
/// [`crate::global::global_bundle_adjust`] with one focal-length block per frame and the
/// smoothness prior; the first frame's focal length held with `hold_first`. Returns the poses,
/// the points and the focal lengths.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn zoom_adjust(
    und: &Tracks,
    k: &Intrinsics,
    f_ref: f64,
    focals: &[f64],
    poses: &[Option<Pose>],
    options: &crate::global::GlobalOptions,
    sigma: f64,
    hold_first: bool,
) -> Result<(
    crate::structure::Poses,
    crate::structure::TrackPoints,
    Vec<f64>,
)> {
    use crate::global::triangulate_all;
    use crate::track_weights::track_weights;
    options.check().map_err(VisionError::InvalidInput)?;
    let k_ref = with_focal(k, f_ref);
    let mut focals = focals.to_vec();
    let mut poses = poses.to_vec();
    let mut norm = normalise(und, k, &focals, f_ref);
    let none = vec![None; und.tracks.len()];
    let (mut points, mut flags) = triangulate_all(
        &norm,
        &k_ref,
        &poses,
        &none,
        options.triangulation_tolerance,
        options.min_observations,
    );
    let mut thresholds = vec![options.triangulation_tolerance];
    thresholds.extend(options.thresholds.iter().copied());
    let mut weights = vec![1.0; und.tracks.len()];
    let priors = zoom_priors(focals.len(), sigma);
    for (round, &threshold) in thresholds.iter().enumerate() {
        if round > 0 {
            let r = triangulate_all(
                &norm,
                &k_ref,
                &poses,
                &points,
                threshold,
                options.min_observations,
            );
            points = r.0;
            flags = r.1;
            if options.track_weighting {
                weights = track_weights(&norm, &k_ref, &poses, &points, &flags);
            }
        }
        let keep = |ti: usize, f: usize| {
            if flags[ti][f - und.tracks[ti].first] {
                weights[ti]
            } else {
                0.0
            }
        };
        let blocks = focals
            .iter()
            .enumerate()
            .map(|(i, &f)| {
                let mut b = vfxgraph_bundle::Intrinsics::pinhole(f, k.u0, k.v0, false);
                b.model = vfxgraph_bundle::CameraModel::Pinhole {
                    aspect: k.f2 / k.f1,
                    skew: k.s,
                };
                b.held[0] = hold_first && i == 0;
                b.held[1] = true;
                b.held[2] = true;
                b
            })
            .collect();
        let (_, blocks, _) = crate::adjust::adjust_with_blocks(
            und,
            blocks,
            priors.clone(),
            Gauge::FixFirstCameraAndScale,
            &mut poses,
            &mut points,
            &keep,
            options.loss(),
            options.max_iterations,
            false,
        )?;
        focals = blocks.iter().map(|b| b.params[0]).collect();
        norm = normalise(und, k, &focals, f_ref);
    }
    Ok((poses, points, focals))
}

#[cfg(test)]
mod tests {
    use super::*;
    use vfxgraph_klt::Track;

    /// A camera that only zooms (1.5 % a frame about the principal point, the tracks turned a
    /// little as well): the ratios are the zoom's, to rounding.
    /// A floor 10 × 6 units with 1 % of relief reads about 0.01 whatever stray points are
    /// added; the same points over a 3-unit-deep box read far above the warning's 5 %.
    #[test]
    fn thickness_of_a_floor_and_of_a_box() {
        let grid = |depth: f64| -> Vec<[f64; 3]> {
            (0..400)
                .map(|i| {
                    let (x, y) = ((i % 20) as f64 * 0.5, (i / 20) as f64 * 0.3);
                    let z = depth * (((i * 7919) % 101) as f64 / 100.0 - 0.5) * 2.0;
                    [x, y, z]
                })
                .collect()
        };
        let mut floor = grid(0.05);
        let t = thickness(&floor).unwrap();
        assert!(t > 0.002 && t < 0.02, "{t}");
        floor.extend((0..10).map(|i| [5.0, 3.0, 50.0 + i as f64]));
        let with_strays = thickness(&floor).unwrap();
        assert!(
            (with_strays / t - 1.0).abs() < 0.2,
            "{with_strays} against {t}"
        );
        assert!(thickness(&grid(1.5)).unwrap() > 4.0 * FLAT_ZOOM_THICKNESS);
        assert_eq!(thickness(&floor[..9]), None);
    }

    #[test]
    fn ratios_of_a_pure_zoom_are_its_scale_changes() {
        let k = Intrinsics::new(1000.0, 1000.0, 640.0, 360.0);
        let n = 10;
        let zoom = |i: usize| 1.015f64.powi(i as i32);
        let tracks = (0..40)
            .map(|j| {
                let a = Vector2::new(
                    ((j * 37) % 400) as f64 - 200.0,
                    ((j * 53) % 300) as f64 - 150.0,
                );
                Track {
                    id: j as u64,
                    slot: j,
                    first: 0,
                    points: (0..n)
                        .map(|i| {
                            let (s, c) = (0.002 * i as f64).sin_cos();
                            let b = Vector2::new(c * a.x - s * a.y, s * a.x + c * a.y) * zoom(i);
                            [k.u0 + b.x, k.v0 + b.y]
                        })
                        .collect(),
                    lost: None,
                }
            })
            .collect();
        let tracks = Tracks {
            frames: (0..n as i64).collect(),
            slots: 40,
            image_size: None,
            tracks,
        };
        let r = zoom_ratios(&tracks, &k);
        assert_eq!(r.len(), n);
        for (i, r) in r.iter().enumerate() {
            assert!((r / zoom(i) - 1.0).abs() < 1e-12, "frame {i}: {r}");
        }
        // Normalised to the first frame's focal length, every frame's tracks are the first's
        // turned (the scale gone).
        let focals: Vec<f64> = (0..n).map(|i| 1000.0 * zoom(i)).collect();
        let norm = normalise(&tracks, &k, &focals, 1000.0);
        let t = &norm.tracks[5];
        let d = |p: [f64; 2]| ((p[0] - k.u0).powi(2) + (p[1] - k.v0).powi(2)).sqrt();
        assert!((d(t.points[9]) - d(t.points[0])).abs() < 1e-9);
    }

    /// The prior is zero on a steady zoom and weighs a kink by 1/σ.
    #[test]
    fn the_prior_is_zero_on_a_linear_zoom() {
        let blocks: Vec<vfxgraph_bundle::Intrinsics> = (0..5)
            .map(|i| vfxgraph_bundle::Intrinsics::pinhole(900.0 + 10.0 * i as f64, 0.0, 0.0, false))
            .collect();
        let p = zoom_priors(5, 2.0);
        assert_eq!(p.len(), 3);
        assert!(p.iter().all(|p| p.residual(&blocks).abs() < 1e-12));
        let mut kinked = blocks.clone();
        kinked[2].params[0] += 4.0;
        // f₁ − 2f₂ + f₃ = −8 px, over σ = 2.
        assert!((p[1].residual(&kinked) + 4.0).abs() < 1e-12);
    }
}
