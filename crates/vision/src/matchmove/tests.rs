//! Tests of the whole matchmove against known truth.

use super::synthetic::{synthetic_shot, ShotOptions};
use super::*;
use crate::camera::Pose;

/// Similarity alignment of an estimated path onto the truth: the rotation from the cameras'
/// orientations (R_g ≈ R_e·Rᵀ, averaged and projected onto SO(3)), then scale and translation by
/// least squares on the camera centres. Returns per-frame rotation errors (degrees) and centre
/// errors (scene units) after alignment.
pub(crate) fn aligned_errors(est: &[Pose], truth: &[Pose]) -> (Vec<f64>, Vec<f64>) {
    let mut m = nalgebra::Matrix3::zeros();
    for (e, g) in est.iter().zip(truth) {
        m += g.r.transpose() * e.r;
    }
    let r = crate::rotation::nearest_rotation(&m);
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
            crate::rotation::rotation_angle_between(&(e.r * r.transpose()), &g.r).to_degrees()
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
    let solve = matchmove(
        &shot.tracks,
        &shot.k,
        &MatchmoveOptions::default(),
        &|_, _, _| {},
    )
    .unwrap();
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
}
