//! Point-cloud calibration (book chapter 8): the same n scene points
//! are marked, in the same order, on several frames whose cameras are known. Each point is
//! triangulated from every pair of its marked frames; the candidate with the least total
//! reprojection error over all its marks is kept and refined by Levenberg–Marquardt with the
//! cameras fixed. The result is an n×3 list of world points (the book measures the ground plane,
//! where to put objects, and the points that orient the light dome this way).
//!
//! A lens-carrying K (a path solved with `distortion`, [`crate::lens`]) undistorts the marks
//! first: the triangulation and the report's errors are in the pixels of the ideal pinhole the
//! lens is undistorted to.

use std::collections::HashMap;

use nalgebra::{Matrix3x4, Point2, Point3};
use serde::{Deserialize, Serialize};

use crate::camera::{Intrinsics, Pose};
use crate::error::{Result, VisionError};
use crate::formats::cameras::CameraPath;
use crate::formats::marked_points::MarkedPoints;
use crate::points::Points3d;

/// Figures of a point-cloud calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointCloudReport {
    /// Marked frames used (those with a camera).
    pub frames: Vec<usize>,
    /// Marked frames skipped because the path has no camera for them.
    pub frames_without_camera: Vec<usize>,
    /// Per point: the frame pair it was triangulated from.
    pub pairs: Vec<(usize, usize)>,
    /// Per point: RMS reprojection error over its marks after refinement, pixels.
    pub rms: Vec<f64>,
    /// Per point, per used frame: reprojection error, pixels.
    pub errors: Vec<Vec<f64>>,
}

fn error(p: &Matrix3x4<f64>, x: &Point3<f64>, o: &Point2<f64>) -> f64 {
    crate::calibration::resection::reprojection_error_p(p, x, o)
}

/// Calibrates the marked points against the camera path (module docs). `k` is the path's K
/// unless given.
pub fn point_cloud_calibrate(
    marks: &MarkedPoints,
    path: &CameraPath,
    k: Option<&Intrinsics>,
) -> Result<(Points3d, PointCloudReport)> {
    let k = k.or(path.intrinsics.as_ref()).ok_or_else(|| {
        VisionError::InvalidInput(
            "the camera path carries no intrinsics K: connect them explicitly".into(),
        )
    })?;
    k.validate()?;
    let poses: HashMap<usize, &Pose> = path.frames.iter().map(|f| (f.frame, &f.pose)).collect();
    let mut used = Vec::new();
    let mut skipped = Vec::new();
    let mut ps: Vec<Matrix3x4<f64>> = Vec::new();
    let mut obs: Vec<Vec<Point2<f64>>> = Vec::new();
    let n = marks.frames.first().map_or(0, |f| f.points.0.len());
    for mf in &marks.frames {
        if mf.points.0.len() != n {
            return Err(VisionError::InvalidInput(format!(
                "frame {} has {} marked points, the first block {n}",
                mf.frame,
                mf.points.0.len()
            )));
        }
        match poses.get(&mf.frame) {
            Some(p) => {
                used.push(mf.frame);
                ps.push(k.k() * p.matrix3x4());
                let und = mf
                    .points
                    .0
                    .iter()
                    .map(|x| k.undistort_pixel(x))
                    .collect::<Result<Vec<_>>>()
                    .map_err(|e| {
                        VisionError::InvalidInput(format!(
                            "frame {}: a mark cannot be undistorted by the lens: {e}",
                            mf.frame
                        ))
                    })?;
                obs.push(und);
            }
            None => skipped.push(mf.frame),
        }
    }
    if used.len() < 2 {
        return Err(VisionError::InvalidInput(format!(
            "point-cloud calibration needs marks on at least 2 frames with cameras; {} have one \
             (frames without a camera: {skipped:?})",
            used.len()
        )));
    }
    let lm = crate::optimize::LmOptions {
        max_iterations: 100,
        ..Default::default()
    };
    let mut points = Vec::with_capacity(n);
    let mut report = PointCloudReport {
        frames: used.clone(),
        frames_without_camera: skipped,
        pairs: Vec::new(),
        rms: Vec::new(),
        errors: Vec::new(),
    };
    for i in 0..n {
        let marks_i: Vec<Point2<f64>> = obs.iter().map(|o| o[i]).collect();
        let mut best: Option<(f64, Point3<f64>, (usize, usize))> = None;
        for a in 0..ps.len() {
            for b in a + 1..ps.len() {
                let Ok(x) = crate::two_view::triangulate_linear_n(
                    &[ps[a], ps[b]],
                    &[marks_i[a], marks_i[b]],
                ) else {
                    continue;
                };
                let total: f64 = ps.iter().zip(&marks_i).map(|(p, o)| error(p, &x, o)).sum();
                if total.is_finite() && best.as_ref().is_none_or(|bst| total < bst.0) {
                    best = Some((total, x, (used[a], used[b])));
                }
            }
        }
        let (_, x0, pair) = best.ok_or_else(|| {
            VisionError::Degenerate(format!(
                "point {i}: no pair of marked frames triangulates it in front of the cameras"
            ))
        })?;
        let x = crate::two_view::triangulate_nonlinear(&ps, &marks_i, &x0, &lm).unwrap_or(x0);
        let errs: Vec<f64> = ps
            .iter()
            .zip(&marks_i)
            .map(|(p, o)| error(p, &x, o))
            .collect();
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        points.push(x);
        report.pairs.push(pair);
        report.rms.push(rms);
        report.errors.push(errs);
    }
    Ok((Points3d(points), report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::cameras::FramePose;
    use crate::formats::marked_points::MarkedFrame;
    use crate::points::Points2d;
    use crate::rotation::axis_angle_to_r;
    use nalgebra::Vector3;

    /// Known cameras and points, marks with ±0.5 px noise: recovered within a few millimetres at
    /// a few metres, and the RMS reflects the noise.
    #[test]
    fn recovers_known_points_from_noisy_marks() {
        let k = Intrinsics::new(1228.4, 1228.4, 639.5, 359.5);
        let truth = [
            Point3::new(0.2, 0.5, 4.0),
            Point3::new(-0.6, 0.4, 5.0),
            Point3::new(0.9, -0.3, 6.0),
        ];
        let mut frames = Vec::new();
        let mut marks = Vec::new();
        for (j, f) in [10usize, 40, 70, 100].iter().enumerate() {
            let c = Vector3::new(0.4 * j as f64, 0.05 * j as f64, 0.1 * j as f64);
            let r = axis_angle_to_r(&Vector3::new(0.0, -0.08 * j as f64, 0.0));
            let pose = Pose::new(r, -(r * c));
            let pts: Vec<Point2<f64>> = truth
                .iter()
                .enumerate()
                .map(|(i, x)| {
                    let q = k.k() * pose.transform(x);
                    let jitter = 0.5 * (((i * 7 + j * 3) % 5) as f64 / 2.0 - 1.0);
                    Point2::new(q.x / q.z + jitter, q.y / q.z - jitter)
                })
                .collect();
            frames.push(FramePose {
                frame: *f,
                pose,
                focal: None,
            });
            marks.push(MarkedFrame {
                frame: *f,
                points: Points2d(pts),
            });
        }
        let path = CameraPath {
            frames,
            intrinsics: Some(k.clone()),
        };
        let marks_of = |_: &CameraPath| marks.clone();
        let (pts, rep) = point_cloud_calibrate(
            &MarkedPoints {
                frames: marks.clone(),
            },
            &path,
            None,
        )
        .unwrap();
        for (p, t) in pts.0.iter().zip(&truth) {
            assert!((p - t).norm() < 0.02, "{p} vs {t}");
        }
        assert!(rep.rms.iter().all(|r| *r < 1.0), "{:?}", rep.rms);
        // The same marks seen through a barrel lens, with the lens on the path: the same points.
        let lens = crate::lens::Distortion::BrownConrady {
            k1: -0.16,
            k2: 0.045,
            k3: 0.0,
            p1: 0.0008,
            p2: -0.0005,
        };
        let kl = k.clone().with_size(1280, 720).with_distortion(lens);
        let marks_l: Vec<MarkedFrame> = marks_of(&path)
            .iter()
            .map(|m| MarkedFrame {
                frame: m.frame,
                points: Points2d(
                    m.points
                        .0
                        .iter()
                        .map(|x| kl.distort_pixel(x).unwrap())
                        .collect(),
                ),
            })
            .collect();
        let lens_path = CameraPath {
            intrinsics: Some(kl),
            ..path.clone()
        };
        let (pl, _) = point_cloud_calibrate(
            &MarkedPoints {
                frames: marks_l.clone(),
            },
            &lens_path,
            None,
        )
        .unwrap();
        for (a, b) in pl.0.iter().zip(&pts.0) {
            assert!((a - b).norm() < 1e-6, "{a} vs {b}");
        }
        // Ignoring the lens moves them by centimetres.
        let (pp, _) =
            point_cloud_calibrate(&MarkedPoints { frames: marks_l }, &path, None).unwrap();
        let worst =
            pp.0.iter()
                .zip(&pts.0)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
        assert!(worst > 0.02, "{worst}");
        // A path without K and no K given is a clear error.
        let mut no_k = path.clone();
        no_k.intrinsics = None;
        assert!(point_cloud_calibrate(&MarkedPoints::default(), &no_k, None).is_err());
    }
}
