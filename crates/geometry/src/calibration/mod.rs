//! Estimating one camera (book chapter 4): the DLT (§4.1–4.2), factoring P = K[R|t] (§4.3),
//! calibration by restricted optimization (§4.4–4.6), Tsai's planar calibration (§4.8) and RANSAC
//! resection (the book's `ransac_singlecam`), with [`calibrate_camera`] tying them together.

pub mod dlt;
pub mod factor;
pub mod p3p;
pub mod resection;
pub mod restricted;
pub mod tsai;

pub use dlt::{dlt, dlt_unnormalized};
pub use factor::factor_camera;
pub use p3p::{p3p, resect_p3p, P3pEstimator};
pub use resection::{
    refine_known_k, resect_known_k, resect_ransac, DltEstimator, PoseEstimate, Resection,
};
pub use restricted::{calibrate_restricted, refine_camera, IntrinsicsModel, ReprojectionProblem};
pub use tsai::{tsai, tsai_refine, TsaiEstimator};

#[cfg(test)]
use crate::synthetic;

use nalgebra::{Point2, Point3};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::{check_pairs, Result, VisionError};
use crate::optimize::{LmOptions, LmReport};
use crate::ransac::{ransac, RansacParams};

/// The calibration methods of chapter 4.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, vfxgraph_params::Choice)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationMethod {
    /// Normalized DLT and factoring (§4.1–4.3): K may have skew.
    Dlt,
    /// DLT start and Levenberg–Marquardt with s = 0 (§4.5).
    Restricted,
    /// Tsai's planar calibration with a known principal point and LM refinement (§4.8).
    Tsai,
}

/// Options of [`calibrate_camera`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationOptions {
    /// The method.
    pub method: CalibrationMethod,
    /// The principal point, required by [`CalibrationMethod::Tsai`].
    pub principal_point: Option<Point2<f64>>,
    /// RANSAC on the matches first (threshold in pixels); `None` uses every match.
    pub ransac: Option<RansacParams>,
    /// Levenberg–Marquardt options.
    pub lm: LmOptions,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            method: CalibrationMethod::Restricted,
            principal_point: None,
            ransac: None,
            lm: LmOptions::default(),
        }
    }
}

/// The `calibrate_camera` node's params: [`CalibrationOptions`] as numbers a graph can hold,
/// and the RANSAC seed.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct CalibrateCameraOptions {
    /// calibration model
    pub method: CalibrationMethod,
    /// [u0, v0] for tsai (pixels)
    pub principal_point: Vec<f64>,
    /// RANSAC inlier threshold in pixels; 0 uses every match
    #[param(range = 0.0..=1e6)]
    pub ransac_threshold_px: Option<f64>,
    /// RANSAC random seed
    #[param(range = 0..=i64::MAX)]
    pub seed: u64,
}

impl Default for CalibrateCameraOptions {
    fn default() -> Self {
        CalibrateCameraOptions {
            method: CalibrationMethod::Restricted,
            principal_point: Vec::new(),
            ransac_threshold_px: None,
            seed: 0,
        }
    }
}

impl CalibrateCameraOptions {
    /// The options of [`calibrate_camera`]; an error when `principal_point` is not `[u0, v0]`
    /// (or empty for a method that does not need it).
    pub fn options(&self) -> Result<CalibrationOptions> {
        let principal_point = match (self.method, self.principal_point.as_slice()) {
            (_, [u, v]) => Some(Point2::new(*u, *v)),
            (CalibrationMethod::Tsai, _) => {
                return Err(VisionError::InvalidInput(
                    "method tsai needs `principal_point: [u0, v0]` (pixels)".into(),
                ))
            }
            (_, []) => None,
            _ => {
                return Err(VisionError::InvalidInput(
                    "`principal_point` is [u0, v0]".into(),
                ))
            }
        };
        Ok(CalibrationOptions {
            method: self.method,
            principal_point,
            ransac: self.ransac_threshold_px.map(RansacParams::with_threshold),
            ..Default::default()
        })
    }

    /// The RANSAC random numbers.
    pub fn rng(&self) -> rand_pcg::Pcg64 {
        rand::SeedableRng::seed_from_u64(self.seed)
    }
}

/// What [`calibrate_camera`] reports next to the camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationReport {
    /// Method used.
    pub method: CalibrationMethod,
    /// Number of matches given.
    pub num_points: usize,
    /// Number of inliers used in the final fit.
    pub num_inliers: usize,
    /// Inlier flag of every match (all true without RANSAC).
    pub inliers: Vec<bool>,
    /// Reprojection error in pixels of every match under the final camera.
    pub errors: Vec<f64>,
    /// RMS reprojection error over the inliers, pixels.
    pub rms: f64,
    /// RANSAC iterations (0 without RANSAC).
    pub ransac_iterations: usize,
    /// The Levenberg–Marquardt summary, for the methods that use it.
    pub lm: Option<LmReport>,
}

fn select<T: Copy>(v: &[T], flags: &[bool]) -> Vec<T> {
    v.iter()
        .zip(flags)
        .filter(|(_, &f)| f)
        .map(|(x, _)| *x)
        .collect()
}

/// Calibrate one camera from 3D↔2D matches (book chapter 4) with the chosen method, optionally
/// after RANSAC (6-point DLT, or Tsai's linear step for planar targets). The thin adapter of the
/// `calibrate_camera` node.
pub fn calibrate_camera<R: Rng + ?Sized>(
    points3d: &[Point3<f64>],
    points2d: &[Point2<f64>],
    options: &CalibrationOptions,
    rng: &mut R,
) -> Result<(Camera, CalibrationReport)> {
    check_pairs(points3d.len(), points2d.len(), 6)?;
    let n = points3d.len();
    let pp = match (options.method, options.principal_point) {
        (CalibrationMethod::Tsai, None) => {
            return Err(VisionError::InvalidInput(
                "Tsai's calibration needs the principal point".into(),
            ))
        }
        (_, pp) => pp,
    };
    let mut inliers = vec![true; n];
    let mut ransac_iterations = 0;
    if let Some(params) = &options.ransac {
        let data: Vec<_> = points3d
            .iter()
            .copied()
            .zip(points2d.iter().copied())
            .collect();
        let r = match (options.method, pp) {
            (CalibrationMethod::Tsai, Some(pp)) => {
                let r = ransac(
                    &TsaiEstimator {
                        principal_point: pp,
                    },
                    &data,
                    params,
                    rng,
                )?;
                (r.inliers, r.iterations)
            }
            _ => {
                let r = ransac(&DltEstimator, &data, params, rng)?;
                (r.inliers, r.iterations)
            }
        };
        inliers = r.0;
        ransac_iterations = r.1;
    }
    let fit = |flags: &[bool]| -> Result<(Camera, Option<LmReport>)> {
        let p3 = select(points3d, flags);
        let p2 = select(points2d, flags);
        match (options.method, pp) {
            (CalibrationMethod::Dlt, _) => Ok((factor_camera(&dlt(&p3, &p2)?)?, None)),
            (CalibrationMethod::Restricted, _) => {
                let (c, r) = calibrate_restricted(&p3, &p2, &options.lm)?;
                Ok((c, Some(r)))
            }
            (CalibrationMethod::Tsai, Some(pp)) => {
                let (c, r) = tsai_refine(&p3, &p2, pp, &options.lm)?;
                Ok((c, Some(r)))
            }
            (CalibrationMethod::Tsai, None) => unreachable!("checked above"),
        }
    };
    let (mut camera, mut lm) = fit(&inliers)?;
    if let Some(params) = &options.ransac {
        // Re-mark the inliers with the final camera and refit once if they changed.
        let flags: Vec<bool> = points3d
            .iter()
            .zip(points2d)
            .map(|(p, x)| camera.reprojection_error(p, x) <= params.threshold)
            .collect();
        if flags != inliers && flags.iter().filter(|&&f| f).count() >= 6 {
            if let Ok((c, l)) = fit(&flags) {
                camera = c;
                lm = l;
                inliers = flags;
            }
        }
    }
    let errors: Vec<f64> = points3d
        .iter()
        .zip(points2d)
        .map(|(p, x)| camera.reprojection_error(p, x))
        .collect();
    let num_inliers = inliers.iter().filter(|&&f| f).count();
    let rms = (errors
        .iter()
        .zip(&inliers)
        .filter(|(_, &f)| f)
        .map(|(e, _)| e * e)
        .sum::<f64>()
        / num_inliers as f64)
        .sqrt();
    let report = CalibrationReport {
        method: options.method,
        num_points: n,
        num_inliers,
        inliers,
        errors,
        rms,
        ransac_iterations,
        lm,
    };
    Ok((camera, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::rotation_angle_between;
    use crate::synthetic::{
        observe, random_camera, random_points_in_front, random_points_in_frustum,
    };
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// Must-show with RANSAC: 0.5 px noise and 30 % outliers; f within 0.5 %, principal point
    /// within 2 px, rotation within 0.05°.
    #[test]
    fn restricted_with_ransac_and_outliers() {
        let mut worst = [0.0f64; 3];
        for seed in 0..10u64 {
            let mut rng = Pcg64::seed_from_u64(300 + seed);
            let cam = random_camera(&mut rng);
            let pts = random_points_in_frustum(&cam, 600, 2.0, 10.0, &mut rng);
            let (obs, outlier) = observe(&cam, &pts, 0.5, 0.3, &mut rng);
            let opts = CalibrationOptions {
                ransac: Some(RansacParams::with_threshold(2.0)),
                ..Default::default()
            };
            let (est, rep) =
                calibrate_camera(&pts, &obs, &opts, &mut Pcg64::seed_from_u64(seed)).unwrap();
            let (k, t) = (&est.intrinsics, &cam.intrinsics);
            let ef = ((k.f1 - t.f1) / t.f1)
                .abs()
                .max(((k.f2 - t.f2) / t.f2).abs());
            let epp = ((k.u0 - t.u0).powi(2) + (k.v0 - t.v0).powi(2)).sqrt();
            let er = rotation_angle_between(&est.pose.r, &cam.pose.r).to_degrees();
            worst[0] = worst[0].max(ef);
            worst[1] = worst[1].max(epp);
            worst[2] = worst[2].max(er);
            assert!(
                ef < 0.005 && epp < 2.0 && er < 0.05,
                "seed {seed}: f {ef} pp {epp} R {er}"
            );
            assert!(rep.inliers.iter().zip(&outlier).all(|(i, o)| !(*i && *o)));
            assert!(rep.rms < 1.0, "{}", rep.rms);
        }
        println!("restricted+ransac 30% outliers (f rel, pp px, R deg) worst over seeds: ef {:.4}, epp {:.4}, er {:.4}", worst[0], worst[1], worst[2]);
    }

    #[test]
    fn tsai_and_dlt_methods_with_ransac() {
        let mut rng = Pcg64::seed_from_u64(77);
        let cam = random_camera(&mut rng);
        // Planar target: points of the plane z = 0 in front of the camera.
        let mut p3 = Vec::new();
        while p3.len() < 200 {
            let p = Point3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                0.0,
            );
            if crate::synthetic::visible(&cam, &p) {
                p3.push(p);
            }
        }
        let mut cam = cam;
        cam.intrinsics.f2 = cam.intrinsics.f1;
        let (obs, outlier) = observe(&cam, &p3, 0.5, 0.3, &mut rng);
        let opts = CalibrationOptions {
            method: CalibrationMethod::Tsai,
            principal_point: Some(Point2::new(cam.intrinsics.u0, cam.intrinsics.v0)),
            ransac: Some(RansacParams::with_threshold(2.0)),
            ..Default::default()
        };
        let (est, rep) = calibrate_camera(&p3, &obs, &opts, &mut rng).unwrap();
        assert!(
            ((est.intrinsics.f1 - cam.intrinsics.f1) / cam.intrinsics.f1).abs() < 0.01,
            "{est:?}"
        );
        assert!(rep.inliers.iter().zip(&outlier).all(|(i, o)| !(*i && *o)));
        // DLT method on a non-planar set.
        let pts = random_points_in_frustum(&cam, 200, 2.0, 10.0, &mut rng);
        let (obs, _) = observe(&cam, &pts, 0.5, 0.3, &mut rng);
        let opts = CalibrationOptions {
            method: CalibrationMethod::Dlt,
            ransac: Some(RansacParams::with_threshold(2.0)),
            ..Default::default()
        };
        let (est, rep) = calibrate_camera(&pts, &obs, &opts, &mut rng).unwrap();
        assert!(rep.lm.is_none() && rep.rms < 1.0);
        assert!(rotation_angle_between(&est.pose.r, &cam.pose.r).to_degrees() < 0.2);
    }

    #[test]
    fn tsai_needs_principal_point() {
        let mut rng = Pcg64::seed_from_u64(1);
        let cam = random_camera(&mut rng);
        let pts = random_points_in_front(&cam, 10, &mut rng);
        let (obs, _) = observe(&cam, &pts, 0.0, 0.0, &mut rng);
        let opts = CalibrationOptions {
            method: CalibrationMethod::Tsai,
            ..Default::default()
        };
        assert!(matches!(
            calibrate_camera(&pts, &obs, &opts, &mut rng),
            Err(VisionError::InvalidInput(_))
        ));
    }
}
