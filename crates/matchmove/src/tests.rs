//! Tests of the whole matchmove against known truth.

use nalgebra::Vector3;
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::formats::CameraPath;
use vfxgraph_klt::Tracks;

use super::*;
use crate::structure::{reprojection_error, through};
use crate::synthetic::{synthetic_shot, ShotOptions};

/// Similarity alignment of an estimated path onto the truth: the rotation from the cameras'
/// orientations (R_g ≈ R_e·Rᵀ, averaged and projected onto SO(3)), then scale and translation by
/// least squares on the camera centres. Returns per-frame rotation errors (degrees) and centre
/// errors (scene units) after alignment.
pub(crate) fn aligned_errors(est: &[Pose], truth: &[Pose]) -> (Vec<f64>, Vec<f64>) {
    let mut m = nalgebra::Matrix3::zeros();
    for (e, g) in est.iter().zip(truth) {
        m += g.r.transpose() * e.r;
    }
    let r = vfxgraph_geometry::rotation::nearest_rotation(&m);
    let a: Vec<Vector3<f64>> = est.iter().map(|p| r * p.center().coords).collect();
    let b: Vec<Vector3<f64>> = truth.iter().map(|p| p.center().coords).collect();
    let n = a.len() as f64;
    let ma = a.iter().sum::<Vector3<f64>>() / n;
    let mb = b.iter().sum::<Vector3<f64>>() / n;
    let num: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma).dot(&(y - mb))).sum();
    let den: f64 = a.iter().map(|x| (x - ma).norm_squared()).sum();
    let s = num / den;
    let rot_err = est
        .iter()
        .zip(truth)
        .map(|(e, g)| {
            vfxgraph_geometry::rotation::rotation_angle_between(&(e.r * r.transpose()), &g.r)
                .to_degrees()
        })
        .collect();
    let c_err = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (s * (x - ma) + mb - y).norm())
        .collect();
    (rot_err, c_err)
}

fn path_length(truth: &[Pose]) -> f64 {
    truth
        .windows(2)
        .map(|w| (w[1].center() - w[0].center()).norm())
        .sum()
}

#[test]
fn synthetic_shot_is_recovered_within_tolerance() {
    let mut o = ShotOptions::default();
    if let Ok(v) = std::env::var("MM_OUTLIERS") {
        o.outlier_fraction = v.parse().unwrap();
    }
    let shot = synthetic_shot(&o);
    // One outlier round at 3 px (6σ of these tracks' 0.5 px noise), which the inlier-mark
    // check below reasons with; the default adds a 1.5 px round for grainy footage.
    let options = MatchmoveOptions {
        global: Some(GlobalOptions {
            thresholds: vec![3.0],
            ..GlobalOptions::default()
        }),
        ..MatchmoveOptions::default()
    };
    let solve = matchmove(&shot.tracks, &shot.k, &options, &|_, _, _| {}).unwrap();
    let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
    assert_eq!(est.len(), shot.truth.len());
    let (rot, cen) = aligned_errors(&est, &shot.truth);
    let len = path_length(&shot.truth);
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    let max_c = cen.iter().cloned().fold(0.0, f64::max) / len;
    eprintln!(
        "rot errors: {:?}",
        rot.iter()
            .step_by(10)
            .map(|v| (v * 1000.0).round() / 1000.0)
            .collect::<Vec<_>>()
    );
    eprintln!(
        "max rotation error {max_rot:.4}°, max centre error {:.4} % of the path",
        100.0 * max_c
    );
    assert!(max_rot < 0.1, "rotation error {max_rot}°");
    assert!(max_c < 0.005, "centre error {} of the path length", max_c);
    check_inlier_marks(&shot, &solve);
}

/// The cloud carries the solve's final inlier decision: every kept observation is within the
/// report's tolerance, the report counts exactly the kept observations per frame, the clean
/// tracks' observations (σ = 0.5 px, so beyond 3 px has probability e⁻¹⁸) are all kept, and
/// the rejected ones are the drifting tracks'.
fn check_inlier_marks(shot: &crate::synthetic::SyntheticShot, solve: &Solve) {
    let (cloud, rep) = (&solve.cloud, &solve.report);
    cloud.validate().unwrap();
    assert_eq!(cloud.inlier_frames.len(), cloud.points.len());
    assert_eq!(rep.inlier_tolerance, 3.0);
    let poses: std::collections::HashMap<i64, &Pose> = solve
        .path
        .frames
        .iter()
        .map(|f| (f.frame as i64, &f.pose))
        .collect();
    let mut per_frame: std::collections::HashMap<i64, usize> = Default::default();
    let (mut clean, mut clean_kept, mut rejected, mut rejected_drifting) = (0, 0, 0, 0);
    for (j, id) in cloud.track_ids.iter().enumerate() {
        let t = shot.tracks.tracks.iter().find(|t| t.id == *id).unwrap();
        let x = Vector3::from(cloud.points[j]);
        let drifting = shot.outliers.contains(id);
        for (i, o) in t.points.iter().enumerate() {
            let frame = shot.tracks.frames[t.first + i];
            let e = reprojection_error(&shot.k, poses[&frame], &x, o);
            let kept = cloud.is_inlier(j, frame);
            if kept {
                assert!(
                    e <= rep.inlier_tolerance,
                    "track {id} frame {frame}: {e} px"
                );
                *per_frame.entry(frame).or_default() += 1;
            } else {
                rejected += 1;
                rejected_drifting += usize::from(drifting);
            }
            if !drifting {
                clean += 1;
                clean_kept += usize::from(kept);
            }
        }
    }
    for f in &rep.frames {
        assert_eq!(f.inliers, per_frame.get(&f.frame).copied().unwrap_or(0));
    }
    eprintln!(
        "inlier marks: {clean_kept} of {clean} clean observations kept, {rejected} rejected \
         ({rejected_drifting} of drifting tracks)"
    );
    assert_eq!(clean_kept, clean, "every clean observation is kept");
    assert!(rejected > 0 && rejected_drifting == rejected);
}

/// Same seed, same cameras, whatever the thread count (fragments and pairs run in parallel).
#[test]
fn solve_is_identical_for_any_thread_count() {
    let shot = synthetic_shot(&ShotOptions {
        frames: 70,
        slots: 80,
        mean_track_length: 40.0,
        ..ShotOptions::default()
    });
    let options = MatchmoveOptions {
        fragments: FragmentOptions {
            min_frames: 30,
            ..FragmentOptions::default()
        },
        ..MatchmoveOptions::default()
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| matchmove(&shot.tracks, &shot.k, &options, &|_, _, _| {}).unwrap())
    };
    let (a, b) = (run(1), run(4));
    assert_eq!(a.path, b.path);
    assert_eq!(a.cloud, b.cloud);
}

/// The fragment rule (§7.11): consecutive fragments share exactly one frame, cover the whole
/// sequence, and each keeps only features tracked through all of its frames.
#[test]
fn fragments_share_one_frame_and_keep_features_tracked_throughout() {
    let shot = synthetic_shot(&ShotOptions::default());
    let o = FragmentOptions::default();
    let frags = split_fragments(&shot.tracks, &o).unwrap();
    assert!(frags.len() >= 2, "{} fragments", frags.len());
    assert_eq!(frags[0].first, 0);
    assert_eq!(frags.last().unwrap().last, shot.tracks.frames.len() - 1);
    for w in frags.windows(2) {
        assert_eq!(w[0].last, w[1].first);
    }
    for f in &frags {
        if !f.is_last {
            assert!(f.len() > o.min_frames || f.features.len() < o.min_features + 5);
        }
        for &t in &f.features {
            assert!(through(&shot.tracks.tracks[t], f.first, f.last).is_some());
        }
        // Every track seen throughout is kept.
        let all = shot
            .tracks
            .tracks
            .iter()
            .filter(|t| through(t, f.first, f.last).is_some())
            .count();
        assert_eq!(all, f.features.len());
    }
}

/// The book's own tracks: every one of the 286 frames gets a finite camera, the path is smooth,
/// and on the 240 frames the book's solution covered, our cameras score better than the book's
/// (median 2.40 px, 57.5 % above 2 px, measured on the book's refined cameras).
#[test]
fn book_tracks_every_frame_solved_and_better_than_the_book() {
    let Some([f, g7cam]) = vfxgraph_testdata::paths(["book-demo/f.txt", "book-demo/g7cam.txt"])
    else {
        return;
    };
    let tracks = vfxgraph_klt::Tracks::parse(&std::fs::read_to_string(f).unwrap()).unwrap();
    let k = vfxgraph_geometry::formats::read_intrinsics(&g7cam).unwrap();
    let solve = matchmove(&tracks, &k, &MatchmoveOptions::default(), &|_, _, _| {}).unwrap();
    assert_eq!(solve.path.frames.len(), 286);
    let score = solve.report.score.clone().unwrap();
    eprintln!("book tracks, all 286 frames: {score:?}");
    assert_eq!(score.frames_with_camera, 286);
    assert!(score.max_rotation_step_deg < 3.0, "{score:?}");
    assert!(score.translation_step_ratio < 10.0, "{score:?}");
    let mut first = solve.path.clone();
    first.frames.truncate(240);
    let s240 = score_cameras(&tracks, &k, &first);
    eprintln!("first 240 frames: {s240:?}");
    assert!(s240.median < 2.40, "median {}", s240.median);
    assert!(s240.above_2px < 0.575, "above 2 px {}", s240.above_2px);
}

/// The synthetic shot seen through `lens`: every observation moved where the lens images it.
fn distorted_shot(
    lens: vfxgraph_lens::Distortion,
) -> (crate::synthetic::SyntheticShot, Intrinsics) {
    let shot = synthetic_shot(&ShotOptions {
        frames: 60,
        outlier_fraction: 0.05,
        ..ShotOptions::default()
    });
    let k = shot.k.clone().with_size(1280, 720).with_distortion(lens);
    let mut s = shot.clone();
    for t in &mut s.tracks.tracks {
        for p in &mut t.points {
            let q = k.distort_pixel(&nalgebra::Point2::new(p[0], p[1])).unwrap();
            *p = [q.x, q.y];
        }
    }
    (s, k)
}

/// An unknown focal length and Brown–Conrady k1, k2 are recovered from the tracks alone (the
/// image size and principal point known): the synthetic shot (0.5 px noise, 5 % drifting tracks)
/// through a strong barrel lens (≈ 40 px at the corners). Measured (the track weighting on, the
/// default; the focal search over 12 frames): focal 0.005 % high, k1 within 0.0022, k2 within
/// 0.0037, rotation max 0.038°, centre max 0.15 % of the path; with the search over 16 frames
/// 0.10 %, 0.0018, 0.0034, 0.029°, 0.15 %. Unweighted (before it was the default): focal 0.52 %
/// high, k1 within 0.0014, rotation 0.026°, centre 0.25 %, the focal error the noise's (0.04 % at
/// 0.05 px, 0.34 % at 0.25 px): this shot constrains f weakly, so the focal bound (0.25 %) is
/// the noise's scale, not 2× today's 0.005 %.
#[test]
fn unknown_focal_and_radial_distortion_are_recovered() {
    let lens = vfxgraph_lens::Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: 0.0,
        p1: 0.0,
        p2: 0.0,
    };
    let (shot, k_true) = distorted_shot(lens);
    let start = Intrinsics::new(1000.0, 1000.0, k_true.u0, k_true.v0).with_size(1280, 720);
    let lens_options = LensOptions {
        focal: FocalMode::Unknown,
        distortion: DistortionMode::K1k2,
        ..LensOptions::default()
    };
    let solve = matchmove_with_lens(
        &shot.tracks,
        &start,
        &lens_options,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let k = solve.path.intrinsics.clone().unwrap();
    let vfxgraph_lens::Distortion::BrownConrady { k1, k2, .. } = k.distortion else {
        panic!("solved {:?}", k.distortion)
    };
    let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
    let (rot, cen) = aligned_errors(&est, &shot.truth);
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    let max_c = cen.iter().cloned().fold(0.0, f64::max) / path_length(&shot.truth);
    let f_err = (k.f1 / k_true.f1 - 1.0).abs();
    eprintln!(
        "focal {:.2} (true {:.2}, {:.3} %), k1 {k1:.4}, k2 {k2:.4}, rotation max {max_rot:.4}°, \
         centre max {:.3} %; {:?}",
        k.f1,
        k_true.f1,
        100.0 * f_err,
        100.0 * max_c,
        solve.report.notes
    );
    assert!(f_err < 0.0025, "focal {} vs {}", k.f1, k_true.f1);
    assert!((k1 + 0.16).abs() < 0.003, "k1 {k1}");
    assert!((k2 - 0.045).abs() < 0.006, "k2 {k2}");
    assert!(max_rot < 0.06, "rotation error {max_rot}°");
    assert!(max_c < 0.003, "centre error {max_c}");
}

/// The synthetic shot (seeded by `seed`) through a Brown–Conrady lens with tangential terms
/// (p1 = 0.002, p2 = −0.0015, ≈ 3 px at the corners), pixel noise σ = `noise` and its principal
/// point moved by `shift` px: the shot, the true lens, the observed tracks and the 1000 px
/// start the solves begin from.
fn tangential_shot(
    noise: f64,
    shift: (f64, f64),
    seed: u64,
) -> (
    crate::synthetic::SyntheticShot,
    Intrinsics,
    Tracks,
    Intrinsics,
) {
    let lens = vfxgraph_lens::Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: 0.0,
        p1: 0.002,
        p2: -0.0015,
    };
    let shot = synthetic_shot(&ShotOptions {
        frames: 60,
        outlier_fraction: 0.05,
        noise,
        seed,
        ..ShotOptions::default()
    });
    let mut k_true = shot.k.clone().with_size(1280, 720).with_distortion(lens);
    k_true.u0 += shift.0;
    k_true.v0 += shift.1;
    let mut tracks = shot.tracks.clone();
    for t in &mut tracks.tracks {
        for p in &mut t.points {
            // The shot's pixels are the pinhole's about the centre: move them to the shifted
            // principal point, then through the lens.
            let u = nalgebra::Point2::new(p[0] + shift.0, p[1] + shift.1);
            let q = k_true.distort_pixel(&u).unwrap();
            *p = [q.x, q.y];
        }
    }
    let start = Intrinsics::new(1000.0, 1000.0, shot.k.u0, shot.k.v0).with_size(1280, 720);
    (shot, k_true, tracks, start)
}

/// [`tangential_shot`] (seed 1) solved with `distortion: brown` and `principal_point`: the
/// true lens, the solve and the rotation and centre errors.
fn solve_tangential_shot(
    noise: f64,
    shift: (f64, f64),
    principal_point: crate::lens::PrincipalPoint,
) -> (Intrinsics, Solve, f64, f64) {
    let (shot, k_true, tracks, start) = tangential_shot(noise, shift, 1);
    let lens_options = LensOptions {
        focal: FocalMode::Unknown,
        distortion: DistortionMode::Brown,
        principal_point,
        ..LensOptions::default()
    };
    let solve = matchmove_with_lens(
        &tracks,
        &start,
        &lens_options,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
    let (rot, cen) = aligned_errors(&est, &shot.truth);
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    let max_c = cen.iter().cloned().fold(0.0, f64::max) / path_length(&shot.truth);
    let k = solve.path.intrinsics.clone().unwrap();
    eprintln!(
        "focal {:.2} (true {:.2}), {:?}, principal point ({:.2}, {:.2}) (true ({:.2}, \
         {:.2})), rotation max {max_rot:.4}°, centre max {:.3} %; {:?}",
        k.f1,
        k_true.f1,
        k.distortion,
        k.u0,
        k.v0,
        k_true.u0,
        k_true.v0,
        100.0 * max_c,
        solve.report.intrinsics
    );
    (k_true, solve, max_rot, max_c)
}

/// `distortion: brown` recovers the tangential terms with the radial ones and the focal length
/// (principal point known), on tracks of 0.1 px noise: the tangential terms move a pixel by a
/// few pixels at most, and at the default 0.5 px this shot determines them to ±0.0005–0.0012
/// only (as the report's standard deviations say). Measured: focal 0.38 % low (1.76 px
/// standard deviation reported), k1 −0.1600, p1 0.00208, p2 −0.00167, rotation max 0.023°,
/// centre max 0.13 % of the path. (Unweighted, as before the track weighting became the
/// default: 0.14 %, 0.012°, 0.083 % — this seed is the unweighted adjustment's luckiest of six;
/// `track_weighting_beats_the_unweighted_adjustment` compares the two over all six.)
#[test]
fn tangential_distortion_is_recovered() {
    let (k_true, solve, max_rot, max_c) =
        solve_tangential_shot(0.1, (0.0, 0.0), crate::lens::PrincipalPoint::Centre);
    let k = solve.path.intrinsics.clone().unwrap();
    let vfxgraph_lens::Distortion::BrownConrady { k1, p1, p2, .. } = k.distortion else {
        panic!("solved {:?}", k.distortion)
    };
    assert!((k.f1 / k_true.f1 - 1.0).abs() < 0.0075, "focal {}", k.f1);
    assert!((k1 + 0.16).abs() < 0.0025, "k1 {k1}");
    assert!((p1 - 0.002).abs() < 0.0003, "p1 {p1}");
    assert!((p2 + 0.0015).abs() < 0.0003, "p2 {p2}");
    assert!(max_rot < 0.045, "rotation error {max_rot}°");
    assert!(max_c < 0.0026, "centre error {max_c}");
}

/// `principal_point: refine` moves the principal point towards the truth (12 px right, 8 px
/// up) and says how well the shot determines it: a hand-held shot constrains the principal
/// point weakly (it trades with the rotations), so the test checks that every solved
/// parameter is within 3 reported standard deviations of the truth — the estimate and its
/// uncertainty agree. Measured: principal point (671.6, 340.8) for (651.5, 351.5), focal
/// 1111 px for 1100 (± 10.9), p1 0.0023, p2 −0.0003 for −0.0015: each within 3 of its reported
/// standard deviations.
#[test]
fn a_refined_principal_point_agrees_with_its_reported_uncertainty() {
    let (k_true, solve, _, _) =
        solve_tangential_shot(0.5, (12.0, -8.0), crate::lens::PrincipalPoint::Refine);
    let truth = [
        ("focal_px", k_true.f1),
        ("k1", -0.16),
        ("k2", 0.045),
        ("p1", 0.002),
        ("p2", -0.0015),
        ("cx_px", k_true.u0),
        ("cy_px", k_true.v0),
    ];
    for (name, value) in truth {
        let s = solve
            .report
            .intrinsics
            .iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| panic!("{name} is reported"));
        let sd = s.sd.expect("a standard deviation");
        assert!(
            (s.value - value).abs() < 3.0 * sd,
            "{name} {} ± {sd}, true {value}",
            s.value
        );
    }
}

/// With the lens given and `focal: known, distortion: none`, the solve runs the book's pinhole
/// matchmove on the undistorted tracks and returns the given lens with the cameras.
#[test]
fn a_given_lens_is_undistorted_before_the_pinhole_solve() {
    let lens = vfxgraph_lens::Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: 0.0,
        p1: 0.001,
        p2: -0.0005,
    };
    let (shot, k_true) = distorted_shot(lens);
    let solve = matchmove_with_lens(
        &shot.tracks,
        &k_true,
        &LensOptions::default(),
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    assert_eq!(solve.path.intrinsics.as_ref(), Some(&k_true));
    let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
    let (rot, _) = aligned_errors(&est, &shot.truth);
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    assert!(max_rot < 0.1, "rotation error {max_rot}°");
}

/// A nodal pan of 60 frames (34° about the vertical, 0.5 px noise, 5 % drifting tracks, the
/// camera centre fixed): the tracks and their truth.
fn pan_shot(pan: f64) -> crate::synthetic::SyntheticShot {
    synthetic_shot(&ShotOptions {
        frames: 60,
        travel: 0.0,
        bob: 0.0,
        pan,
        outlier_fraction: 0.05,
        ..ShotOptions::default()
    })
}

fn max_rotation_error(solve: &Solve, truth: &[Pose]) -> f64 {
    solve
        .path
        .frames
        .iter()
        .zip(truth)
        .map(|(f, g)| {
            vfxgraph_geometry::rotation::rotation_angle_between(&f.pose.r, &g.r).to_degrees()
        })
        .fold(0.0, f64::max)
}

/// `solve: auto` (the default) tells a nodal pan from a moving camera by its parallax, and
/// solves the pan as rotations: every rotation against the truth (frame 0 is the identity in
/// both), no translation, a report that says so. Measured: parallax 1.13 px against a threshold
/// of 1.98 px (noise 0.33 px); rotation max 0.016°.
#[test]
fn a_nodal_pan_is_detected_and_solved_as_rotations() {
    let shot = pan_shot(0.6);
    let solve = matchmove_with_lens(
        &shot.tracks,
        &shot.k,
        &LensOptions::default(),
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let max_rot = max_rotation_error(&solve, &shot.truth);
    eprintln!("rotation max {max_rot:.4}°; {:?}", solve.report.notes);
    assert!(solve.report.rotation_only);
    assert!(solve
        .report
        .notes
        .iter()
        .any(|n| n.contains("rotation-only")));
    assert_eq!(solve.path.frames.len(), 60);
    assert!(solve
        .path
        .frames
        .iter()
        .all(|f| f.pose.t == Vector3::zeros()));
    assert!(max_rot < 0.035, "rotation error {max_rot}°");
    assert!(
        solve.report.overall_rms < 1.0,
        "rms {}",
        solve.report.overall_rms
    );
}

/// The parallax measure on a moving camera (the default synthetic shot: 3 units of travel)
/// is far above the pan threshold, and on the pan it is at the noise: measured 1.20 px (pan,
/// threshold 2.2 px) against 28.4 px (moving, threshold 2.2 px).
#[test]
fn parallax_tells_a_pan_from_a_moving_camera() {
    let opts = MotionOptions::default();
    let moving = synthetic_shot(&ShotOptions {
        frames: 60,
        ..ShotOptions::default()
    });
    let p = measure_parallax(&moving.tracks, &moving.k, &opts, 1).unwrap();
    eprintln!("moving: {}", p.describe());
    assert!(!p.rotation_only);
    assert!(p.parallax_px > 6.0 * p.threshold_px, "{}", p.describe());
    let pan = pan_shot(0.6);
    let p = measure_parallax(&pan.tracks, &pan.k, &opts, 1).unwrap();
    eprintln!("pan: {}", p.describe());
    assert!(p.rotation_only, "{}", p.describe());
    // Without K: homographies rule the moving camera out, not the pan.
    let h = parallax::rule_out_pan(&moving.tracks, &opts, 1).unwrap();
    eprintln!(
        "moving, homographies: {:?}",
        h.as_ref().map(Parallax::describe)
    );
    assert!(h.is_some());
    assert!(parallax::rule_out_pan(&pan.tracks, &opts, 1)
        .unwrap()
        .is_none());
}

/// With the focal length unknown, the least rotation parallax over the focal lengths of the
/// search range rules the moving camera out (far above twice the threshold) and leaves the pan
/// to the focal search (its parallax at the best focal length is at the noise). Measured on the
/// moving shot: 29.7 px against a threshold of 2.24 px.
#[test]
fn the_least_parallax_over_focal_lengths_rules_out_only_the_moving_camera() {
    let opts = MotionOptions::default();
    let unknown = |k: &Intrinsics| Intrinsics {
        f1: 0.5 * k.f1,
        f2: 0.5 * k.f2,
        ..k.clone()
    };
    let moving = synthetic_shot(&ShotOptions {
        frames: 60,
        ..ShotOptions::default()
    });
    let pairs = parallax::fit_pairs(&moving.tracks, None, 1).unwrap();
    let k = unknown(&moving.k);
    let p = parallax::rule_out_pan_at_any_focal(&moving.tracks, &k, &pairs, &opts, 1).unwrap();
    let p = p.expect("a moving camera is ruled out");
    eprintln!("moving: {}", p.describe());
    assert!(p.parallax_px > 6.0 * p.threshold_px, "{}", p.describe());
    let pan = pan_shot(0.6);
    let pairs = parallax::fit_pairs(&pan.tracks, None, 1).unwrap();
    let k = unknown(&pan.k);
    let p = parallax::rule_out_pan_at_any_focal(&pan.tracks, &k, &pairs, &opts, 1).unwrap();
    assert!(
        p.is_none(),
        "a pan was ruled out: {}",
        p.unwrap().describe()
    );
}

/// A pan with the focal length unknown (only the image size given): the focal length from the
/// rotations, refined with them. Measured: 1099.7 px for 1100 (−0.03 %; 1113 px from the
/// search); rotation max 0.018°.
/// `focal: unknown` needs no size typed in: the frames the tracks were measured on give it.
#[test]
fn an_unknown_focal_takes_the_image_size_from_the_tracks() {
    let lens = LensOptions {
        focal: FocalMode::Unknown,
        ..LensOptions::default()
    };
    let k = lens.initial_intrinsics(None, Some([960, 540])).unwrap();
    assert_eq!((k.width, k.height), (Some(960), Some(540)));
    assert_eq!((k.u0, k.v0, k.f1), (479.5, 269.5, 960.0));
    let typed = LensOptions {
        width: 1280,
        height: 720,
        ..lens.clone()
    };
    let k = typed.initial_intrinsics(None, Some([960, 540])).unwrap();
    assert_eq!((k.width, k.height), (Some(1280), Some(720)));
    let err = lens.initial_intrinsics(None, None).unwrap_err().to_string();
    assert!(err.contains("image size"), "{err}");
}

#[test]
fn a_pan_solves_its_unknown_focal_length() {
    let shot = pan_shot(0.6);
    let lens = LensOptions {
        focal: FocalMode::Unknown,
        width: 1280,
        height: 720,
        ..LensOptions::default()
    };
    let k0 = lens.initial_intrinsics(None, None).unwrap();
    let solve = matchmove_with_lens(
        &shot.tracks,
        &k0,
        &lens,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let f = solve.path.intrinsics.as_ref().unwrap().f1;
    let max_rot = max_rotation_error(&solve, &shot.truth);
    eprintln!(
        "focal {f:.2} (true 1100), rotation max {max_rot:.4}°; {:?}",
        solve.report.notes
    );
    assert!(solve.report.rotation_only);
    assert!((f / 1100.0 - 1.0).abs() < 0.002, "focal {f}");
    assert!(max_rot < 0.05, "rotation error {max_rot}°");
}

/// A camera that does not travel and barely turns (1.4°) is a (degenerate) pan: with K its
/// rotations are solved; its focal length cannot be measured, and without K the tracks fit a
/// plane's travel as well as a pan (both are homographies at the noise): whichever the solve
/// returns, the report must say the focal length is not determined — never a quiet camera.
#[test]
fn a_static_camera_is_a_pan_without_a_measurable_focal_length() {
    let shot = pan_shot(0.0);
    let solve = matchmove_with_lens(
        &shot.tracks,
        &shot.k,
        &LensOptions::default(),
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    assert!(solve.report.rotation_only);
    let max_rot = max_rotation_error(&solve, &shot.truth);
    assert!(max_rot < 0.05, "rotation error {max_rot}°");
    let lens = LensOptions {
        focal: FocalMode::Unknown,
        width: 1280,
        height: 720,
        ..LensOptions::default()
    };
    let k0 = lens.initial_intrinsics(None, None).unwrap();
    let solve = matchmove_with_lens(
        &shot.tracks,
        &k0,
        &lens,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    eprintln!("{:?}", solve.report.warnings);
    assert!(
        solve
            .report
            .warnings
            .iter()
            .any(|w| w.contains("focal length")
                && (w.contains("not determined") || w.contains("not measured"))),
        "{:?}",
        solve.report.warnings
    );
}

/// `global_bundle_adjust` and the relaxation of a path solved through a lens: the tracks are
/// undistorted with the lens of the intrinsics (as the matchmove did), so the adjusted cameras
/// keep the solve's accuracy and the lens comes back with them. Treating the distorted pixels
/// as a pinhole's instead bends the solve (measured: 0.02° → 0.5°).
#[test]
fn adjusting_a_path_solved_through_a_lens_keeps_the_lens() {
    let lens = vfxgraph_lens::Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: 0.0,
        p1: 0.0,
        p2: 0.0,
    };
    let (shot, k_true) = distorted_shot(lens);
    let solve = matchmove_with_lens(
        &shot.tracks,
        &k_true,
        &LensOptions::default(),
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let err = |path: &CameraPath| {
        let est: Vec<Pose> = path.frames.iter().map(|f| f.pose.clone()).collect();
        aligned_errors(&est, &shot.truth)
            .0
            .into_iter()
            .fold(0.0, f64::max)
    };
    let before = err(&solve.path);
    let adjusted = adjust_path(
        &shot.tracks,
        &k_true,
        &solve.path,
        &GlobalOptions::default(),
        false,
    )
    .unwrap();
    let after = err(&adjusted.path);
    let as_pinhole = adjust_path(
        &shot.tracks,
        &k_true.pinhole(),
        &solve.path,
        &GlobalOptions::default(),
        false,
    )
    .map(|s| err(&s.path))
    .unwrap_or(f64::INFINITY);
    eprintln!(
        "rotation max: solve {before:.4}°, adjusted {after:.4}°, as a pinhole {as_pinhole:.4}°"
    );
    assert_eq!(adjusted.path.intrinsics.as_ref(), Some(&k_true));
    assert!(
        after < 1.5 * before.max(0.01),
        "{after}° after, {before}° before"
    );
    assert!(
        as_pinhole > 3.0 * after,
        "a pinhole view of distorted tracks: {as_pinhole}°"
    );
    let relaxed = relax_path(
        &shot.tracks,
        &k_true,
        &solve.path,
        &RelaxOptions::default(),
        false,
        &|_, _| {},
    )
    .unwrap();
    assert_eq!(relaxed.path.intrinsics.as_ref(), Some(&k_true));
    let r = err(&relaxed.path);
    eprintln!("relaxed {r:.4}°");
    assert!(r < 0.1, "relaxed {r}°");
}

/// Distortion asked of too few tracks is a clear error before any solving.
#[test]
fn distortion_from_too_few_tracks_is_a_clear_error() {
    let shot = synthetic_shot(&ShotOptions {
        frames: 30,
        slots: 12,
        ..ShotOptions::default()
    });
    let lens = LensOptions {
        distortion: DistortionMode::K1,
        ..LensOptions::default()
    };
    let err = matchmove_with_lens(
        &shot.tracks,
        &shot.k,
        &lens,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("needs at least 30 tracks"), "{err}");
}

/// A zoom: 60 frames whose focal length runs 900 → 1400 px, the
/// camera on a curved path (a zoom along a straight track or an orbit is not determined,
/// [`crate::zoom`]), 0.5 px noise and 5 % drifting tracks, solved with `zoom: true` and the
/// focal length unknown (only the image size given). Measured: every frame's focal length
/// within 0.16 % (the goal: 1 %), rotation max 0.038°, centre max 0.21 % of the path.
#[test]
fn a_zoom_is_solved_frame_by_frame() {
    let shot = synthetic_shot(&ShotOptions {
        frames: 60,
        outlier_fraction: 0.05,
        focal: (900.0, 1400.0),
        arc: 1.0,
        ..ShotOptions::default()
    });
    let start = Intrinsics::new(1000.0, 1000.0, 639.5, 359.5).with_size(1280, 720);
    let lens = LensOptions {
        focal: FocalMode::Unknown,
        zoom: true,
        ..LensOptions::default()
    };
    let solve = matchmove_with_lens(
        &shot.tracks,
        &start,
        &lens,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
    let focal_err: Vec<f64> = solve
        .path
        .frames
        .iter()
        .zip(&shot.focals)
        .map(|(f, t)| f.focal.unwrap() / t - 1.0)
        .collect();
    let worst = focal_err.iter().map(|e| e.abs()).fold(0.0, f64::max);
    let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
    let (rot, cen) = aligned_errors(&est, &shot.truth);
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    let max_c = cen.iter().cloned().fold(0.0, f64::max) / path_length(&shot.truth);
    eprintln!(
        "zoom: worst focal error {:.3} % (first {:.3} %, last {:.3} %), rotation max \
         {max_rot:.4}°, centre max {:.3} %; {:?}",
        100.0 * worst,
        100.0 * focal_err[0],
        100.0 * focal_err[59],
        100.0 * max_c,
        solve.report.notes
    );
    assert!(worst < 0.004, "focal error {worst}");
    assert!(max_rot < 0.08, "rotation error {max_rot}°");
    assert!(max_c < 0.004, "centre error {max_c}");
    assert_eq!(
        solve.report.frames[30].focal_px,
        solve.path.frames[30].focal
    );
    assert!(solve.path.zooms());
}

/// A zoom along a straight track (a critical motion: the focal lengths are not determined by
/// the tracks, [`crate::zoom`]) whose first focal length is known: `focal: known` holds it and
/// the zoom and the cameras come out right; `refine` lets the whole zoom drift. 40 frames,
/// 900 → 1300 px, 0.3 px noise. Measured: held, worst focal error 0.076 %, rotation max
/// 0.022°; refined, 0.17 % and 0.031°. (On a rendered orbit zooming 1.5× the difference is
/// larger: refined 18 % low and 1.5°, held 0.4 % and 0.12°.)
#[test]
fn a_zoom_whose_first_focal_length_is_known_holds_it() {
    let shot = synthetic_shot(&ShotOptions {
        frames: 40,
        noise: 0.3,
        focal: (900.0, 1300.0),
        arc: 0.0,
        ..ShotOptions::default()
    });
    let solve = |focal| {
        let lens = LensOptions {
            focal,
            zoom: true,
            ..LensOptions::default()
        };
        let s = matchmove_with_lens(
            &shot.tracks,
            &shot.k,
            &lens,
            &MatchmoveOptions::default(),
            &|_, _, _| {},
        )
        .unwrap();
        let worst_focal = s
            .path
            .frames
            .iter()
            .zip(&shot.focals)
            .map(|(f, t)| (f.focal.unwrap() / t - 1.0).abs())
            .fold(0.0, f64::max);
        let est: Vec<Pose> = s.path.frames.iter().map(|f| f.pose.clone()).collect();
        let (rot, _) = aligned_errors(&est, &shot.truth);
        (s, worst_focal, rot.iter().cloned().fold(0.0, f64::max))
    };
    let (held, held_focal, held_rot) = solve(FocalMode::Known);
    let (_, free_focal, free_rot) = solve(FocalMode::Refine);
    eprintln!(
        "zoom on a straight track: held first focal length: worst {:.3} %, rotation {held_rot:.4}°; \
         refined: {:.3} %, {free_rot:.4}°",
        100.0 * held_focal,
        100.0 * free_focal
    );
    assert_eq!(held.path.frames[0].focal, Some(shot.focals[0]));
    assert!(held.report.intrinsics[0].held);
    assert!(held_focal < 0.0015, "focal error {held_focal}");
    assert!(held_rot < 0.04, "rotation error {held_rot}°");
    assert!(held_focal < free_focal && held_rot < free_rot);
}

/// A zoom with a lens to solve is a clear error.
#[test]
fn a_zoom_with_a_lens_to_solve_is_refused() {
    let shot = synthetic_shot(&ShotOptions {
        frames: 20,
        ..ShotOptions::default()
    });
    let lens = LensOptions {
        focal: FocalMode::Refine,
        distortion: DistortionMode::K1,
        zoom: true,
        ..LensOptions::default()
    };
    let e = matchmove_with_lens(
        &shot.tracks,
        &shot.k,
        &lens,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("distortion: none"), "{e}");
}

/// The global adjustment's track weighting (`track_weighting`, on by default) against the
/// unweighted adjustment over six seeded synthetic shots through a lens (0.1 px noise, 5 %
/// drifting tracks, focal length and Brown–Conrady lens unknown, as
/// [`tangential_distortion_is_recovered`]): one shot can favour either (seed 1 does the
/// unweighted), the mean does not. Measured: mean |focal error| 0.18 % weighted against 0.36 %
/// unweighted, mean worst rotation 0.015° against 0.041° (0.37×); at 0.5 px noise (not run
/// here) 0.57 % against 0.85 % and 0.062° against 0.085°.
#[test]
fn track_weighting_beats_the_unweighted_adjustment() {
    let lens_options = LensOptions {
        focal: FocalMode::Unknown,
        distortion: DistortionMode::Brown,
        ..LensOptions::default()
    };
    // (mean |focal error|, mean worst rotation) unweighted, then weighted.
    let mut sums = [[0.0f64; 2]; 2];
    let seeds = 1..=6u64;
    for seed in seeds.clone() {
        let (shot, k_true, tracks, start) = tangential_shot(0.1, (0.0, 0.0), seed);
        for (i, weighted) in [false, true].into_iter().enumerate() {
            let mut options = MatchmoveOptions::default();
            options.global.as_mut().unwrap().track_weighting = weighted;
            let solve =
                matchmove_with_lens(&tracks, &start, &lens_options, &options, &|_, _, _| {})
                    .unwrap();
            let est: Vec<Pose> = solve.path.frames.iter().map(|f| f.pose.clone()).collect();
            let (rot, _) = aligned_errors(&est, &shot.truth);
            let f = solve.path.intrinsics.clone().unwrap().f1;
            let max_rot = rot.iter().cloned().fold(0.0, f64::max);
            eprintln!(
                "seed {seed}, weighted {weighted}: focal {f:.2} (1100), rotation max {max_rot:.4}°"
            );
            sums[i][0] += (f / k_true.f1 - 1.0).abs();
            sums[i][1] += max_rot;
        }
    }
    let n = seeds.count() as f64;
    let [unweighted, weighted] = sums.map(|s| s.map(|v| v / n));
    eprintln!(
        "mean |focal error| {:.3} % weighted, {:.3} % unweighted; mean worst rotation {:.4}° \
         weighted, {:.4}° unweighted",
        100.0 * weighted[0],
        100.0 * unweighted[0],
        weighted[1],
        unweighted[1]
    );
    assert!(
        weighted[0] < 0.75 * unweighted[0],
        "focal: {weighted:?} vs {unweighted:?}"
    );
    assert!(
        weighted[1] < 0.6 * unweighted[1],
        "rotation: {weighted:?} vs {unweighted:?}"
    );
}
