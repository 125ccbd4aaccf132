//! The matchmove of real footage, the crate's entry ([`matchmove_with_lens`]): the camera of
//! every frame with the lens solved as far as it is unknown (focal length, radial distortion;
//! an addition to the book, whose K comes from a prior calibration, §7.1, and whose camera is
//! an ideal pinhole, §2.7).
//!
//! Real footage rarely comes with a calibration, and every lens bends lines; not every camera
//! moves as the book's does. The entry decides how the camera moves ([`crate::parallax`]), then
//! solves, each in its own module:
//!
//! - a **zooming lens** ([`crate::zoom`]): one focal length per frame;
//! - a **nodal pan** ([`crate::tripod`]), its focal length from the rotations when unknown —
//!   unless the picture scales over the shot, which no rotation does ([`scaling_pan`]);
//! - a camera with **no parallax** at all: rotations only, its small travel not recovered;
//! - a **moving camera**: the book's pinhole matchmove ([`crate::pipeline`]) on the tracks
//!   undistorted by the intrinsics' own lens when nothing of the lens is solved, else the
//!   rounds of pinhole solve and lens adjustment ([`crate::general`]) from the focal-length
//!   search ([`crate::focal`]).
//!
//! The solve's warnings say what the tracks do not determine: tracks too short to trust
//! ([`SHORT_TRACKS`]), rotations poorly determined ([`UNCERTAIN_ROTATION_DEG`]).
//!
//! Figures of the returned [`Solve`] (reprojection errors, inliers, the book-style score) are
//! measured on the undistorted tracks with the solved K: pixels of the ideal pinhole the lens
//! is undistorted to, within a few percent of image pixels for moderate distortion.

use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::CameraPath;
use vfxgraph_klt::Tracks;
use vfxgraph_params::Choice;

use crate::general::general_with_lens;
use crate::lens::{undistort_tracks, FocalMode, LensOptions, MIN_LENS_TRACKS};
use crate::options::MatchmoveOptions;
use crate::pipeline::Solve;

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
/// its least-determined axis, degrees, [`crate::report::FrameReport::rotation_sd_deg`]) is
/// warned of: on the robustness corpus a plate's worst rotation error is a median 1.9× its
/// largest such deviation, and up to 5× in 99 plates of 100, so from here errors of a degree
/// are to be expected.
pub const UNCERTAIN_ROTATION_DEG: f64 = 0.2;

/// The warning of frames whose rotation is poorly determined ([`UNCERTAIN_ROTATION_DEG`]), if
/// any.
fn uncertain_rotations(report: &crate::report::SolveReport) -> Option<String> {
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
    let decided = crate::parallax::decide(tracks, &k, unknown, &options.motion, options.seed);
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
            crate::tripod::solve_rotations(tracks, &k, held, options, parallax.as_ref(), progress)?;
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
            .insert(0, crate::report::StageTime::new("motion", t0));
        if let Some(f) = focal {
            solve
                .report
                .notes
                .insert(0, format!("initial focal length {f:.1} px from the pan"));
        }
        return Ok(solve);
    }
    let motion = crate::report::StageTime::new("motion", t0);
    let mut solve = match general_with_lens(tracks, k.clone(), held, lens, options, progress) {
        Ok(s) => s,
        // No fragment had parallax although the motion test saw some: the camera barely
        // moved (a slow push, a hand-held hold), which a rotation-only solve models best.
        Err(VisionError::NoParallax(why))
            if options.motion.solve == crate::parallax::SolveMode::Auto =>
        {
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
/// similarities between consecutive frames' tracks ([`crate::zoom::zoom_ratios`]). 1 for a
/// nodal pan, whatever it turns; the scale of a dolly or a zoom.
fn picture_scale(tracks: &Tracks, k: &Intrinsics, pan: &CameraPath) -> Result<f64> {
    let mut und = undistort_tracks(tracks, k)?;
    let kp = k.pinhole();
    let poses = crate::structure::poses_by_index(&und, pan);
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
    Ok(crate::zoom::zoom_ratios(&und, &kp)
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
    held: crate::adjust::Held,
    lens: &LensOptions,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    parallax: Option<&crate::parallax::Parallax>,
    pan: &mut Solve,
) -> Option<Solve> {
    let p = parallax?;
    if options.motion.solve != crate::parallax::SolveMode::Auto {
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
    mut held: crate::adjust::Held,
    unknown: bool,
    options: &MatchmoveOptions,
    progress: &(dyn Fn(&str, usize, usize) + Sync),
    why: &str,
) -> Result<Solve> {
    held[0] |= unknown;
    let mut solve = crate::tripod::solve_rotations(tracks, k, held, options, None, progress)?;
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

/// [`matchmove_with_lens`] of a zooming lens ([`crate::zoom`]), on the tracks undistorted by
/// the intrinsics' own lens (held).
fn solve_zoom_with_lens(
    tracks: &Tracks,
    k: &Intrinsics,
    lens: &LensOptions,
    held: crate::adjust::Held,
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
    let (mut solve, focals) = crate::zoom::solve_zoom(
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
    solve.report.intrinsics = vec![crate::report::SolvedIntrinsic {
        name: "focal_px".into(),
        value: focals[0],
        held: lens.focal == FocalMode::Known,
        sd: None,
    }];
    Ok(solve)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Vector3};
    use vfxgraph_geometry::camera::Pose;
    use vfxgraph_geometry::formats::FramePose;
    use vfxgraph_klt::Track;

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
