//! Estimating two cameras (book chapter 5): the fundamental matrix, the essential matrix and the
//! relative pose, triangulation, and [`reconstruct_two_view`], which reconstructs a set of
//! homologous points seen by two views with known K.

pub mod calibrated;
pub mod essential;
pub mod five_point;
pub mod fundamental;
pub mod homography;
pub mod homography_pose;
pub mod triangulation;

pub use calibrated::{
    relative_pose_calibrated, CalibratedOptions, CalibratedTwoView, RelativePose, StartModel,
};
pub use essential::{
    choose_pose, decompose_essential, essential_from_fundamental, fundamental_from_pose,
};
pub use five_point::essential_five_point;
pub use fundamental::{
    algebraic_error, enforce_rank2, fundamental_8point, fundamental_8point_unnormalized,
    sampson_distance, EpipolarResidual, FundamentalEstimator,
};
pub use homography::{homography_dlt, HomographyEstimator};
pub use homography_pose::{decompose_homography, PlanarMotion};
pub use triangulation::{
    parallax_angle, triangulate, triangulate_linear, triangulate_linear_n, triangulate_nonlinear,
};

use nalgebra::{DVector, Matrix3, Point2, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::camera::{Camera, Intrinsics, Pose};
use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::optimize::{levenberg_marquardt, LeastSquaresProblem, LmOptions};
use crate::points::Points3d;
use crate::ransac::{ransac, RansacParams};
use crate::rotation::{axis_angle_to_r, r_to_axis_angle};

/// The `two_view` node's params: [`TwoViewOptions`]' RANSAC threshold and residual, and the
/// RANSAC seed.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct TwoViewRansacOptions {
    /// RANSAC inlier threshold (Sampson distance, pixels)
    #[param(range = 0.0..=1e6)]
    pub ransac_threshold_px: Option<f64>,
    /// RANSAC residual
    pub residual: EpipolarResidual,
    /// RANSAC random seed
    #[param(range = 0..=i64::MAX)]
    pub seed: u64,
}

impl Default for TwoViewRansacOptions {
    fn default() -> Self {
        TwoViewRansacOptions {
            ransac_threshold_px: Some(1.0),
            residual: EpipolarResidual::Sampson,
            seed: 0,
        }
    }
}

impl TwoViewRansacOptions {
    /// The options of [`reconstruct_two_view`] (a threshold of 0: the default RANSAC).
    pub fn options(&self) -> TwoViewOptions {
        let d = TwoViewOptions::default();
        TwoViewOptions {
            ransac: self
                .ransac_threshold_px
                .map_or(d.ransac.clone(), RansacParams::with_threshold),
            residual: self.residual,
            ..d
        }
    }

    /// The RANSAC random numbers.
    pub fn rng(&self) -> rand_pcg::Pcg64 {
        rand::SeedableRng::seed_from_u64(self.seed)
    }
}

/// Options of [`reconstruct_two_view`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoViewOptions {
    /// RANSAC on F; the threshold is in pixels for the Sampson residual; for the book's algebraic
    /// residual it bounds |x̂_bᵀF̂x̂_a| on the normalized points (§5.7), ‖F̂‖ = 1 (≈ 1e-3 per pixel
    /// of error in a 1280×720 image).
    pub ransac: RansacParams,
    /// The RANSAC residual.
    pub residual: EpipolarResidual,
    /// Refine (R, t) by Levenberg–Marquardt on the Sampson distances of the inliers.
    pub refine_pose: bool,
    /// Refine every triangulated point on its reprojection error.
    pub refine_points: bool,
    /// Report a zero baseline / planar scene when a homography explains at least this fraction
    /// of the F inliers (within the same threshold).
    pub homography_ratio: f64,
    /// Fewer inliers than this after triangulation is reported as [`VisionError::NoConsensus`].
    pub min_inliers: usize,
}

impl Default for TwoViewOptions {
    fn default() -> Self {
        TwoViewOptions {
            ransac: RansacParams::with_threshold(1.0),
            residual: EpipolarResidual::Sampson,
            refine_pose: true,
            refine_points: true,
            homography_ratio: 0.95,
            min_inliers: 15,
        }
    }
}

/// Figures of a two-view reconstruction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoViewReport {
    /// Number of matches given.
    pub num_matches: usize,
    /// Number of inliers (epipolar inliers in front of both cameras).
    pub num_inliers: usize,
    /// RANSAC iterations.
    pub ransac_iterations: usize,
    /// RMS Sampson distance of the inliers, pixels.
    pub sampson_rms: f64,
    /// RMS reprojection error of the inliers' triangulated points in both views, pixels.
    pub reprojection_rms: f64,
    /// Median parallax angle of the inliers, degrees.
    pub median_parallax_deg: f64,
}

/// The result of [`reconstruct_two_view`]: camera A is K_a[I|0], camera B is K_b[R|t] with
/// ‖t‖ = 1 (the scale is not observable).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TwoViewReconstruction {
    /// K_a[I|0].
    pub camera_a: Camera,
    /// K_b[R|t].
    pub camera_b: Camera,
    /// F with x_bᵀFx_a = 0 (from the final pose).
    pub fundamental: [[f64; 3]; 3],
    /// The triangulated inliers, in the order of the matches.
    pub points3d: Points3d,
    /// Index in the input of each triangulated point.
    pub point_indices: Vec<usize>,
    /// Inlier flag of every match.
    pub inliers: Vec<bool>,
    /// Figures.
    pub report: TwoViewReport,
}

/// Sampson residuals of the inliers as a function of the relative pose, parameterized by the
/// axis–angle of R and a tangent update of the unit vector t.
struct PoseProblem<'a> {
    a: Vec<Point2<f64>>,
    b: Vec<Point2<f64>>,
    ka: &'a Intrinsics,
    kb: &'a Intrinsics,
    t0: Vector3<f64>,
    basis: [Vector3<f64>; 2],
}

impl PoseProblem<'_> {
    fn pose(&self, x: &DVector<f64>) -> Pose {
        let r = axis_angle_to_r(&Vector3::new(x[0], x[1], x[2]));
        let t = (self.t0 + self.basis[0] * x[3] + self.basis[1] * x[4]).normalize();
        Pose::new(r, t)
    }
}

impl LeastSquaresProblem for PoseProblem<'_> {
    fn residuals(&self, x: &DVector<f64>) -> DVector<f64> {
        let f = fundamental_from_pose(self.ka, self.kb, &self.pose(x));
        DVector::from_iterator(
            self.a.len(),
            self.a
                .iter()
                .zip(&self.b)
                .map(|(xa, xb)| sampson_signed(&f, xa, xb)),
        )
    }
}

fn sampson_signed(f: &Matrix3<f64>, xa: &Point2<f64>, xb: &Point2<f64>) -> f64 {
    let fa = f * xa.to_homogeneous();
    let fb = f.transpose() * xb.to_homogeneous();
    let num = xb.to_homogeneous().dot(&fa);
    let den = (fa.x * fa.x + fa.y * fa.y + fb.x * fb.x + fb.y * fb.y).sqrt();
    if den > 0.0 {
        num / den
    } else {
        f64::INFINITY
    }
}

/// Refine a relative pose by Levenberg–Marquardt on the Sampson distances of the matches.
pub fn refine_relative_pose(
    pose: &Pose,
    ka: &Intrinsics,
    kb: &Intrinsics,
    a: &[Point2<f64>],
    b: &[Point2<f64>],
    options: &LmOptions,
) -> Result<Pose> {
    check_pairs(a.len(), b.len(), 5)?;
    let t0 = pose.t.normalize();
    let helper = if t0.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let b0 = t0.cross(&helper).normalize();
    let b1 = t0.cross(&b0);
    let problem = PoseProblem {
        a: a.to_vec(),
        b: b.to_vec(),
        ka,
        kb,
        t0,
        basis: [b0, b1],
    };
    let w = r_to_axis_angle(&pose.r);
    let x0 = DVector::from_vec(vec![w.x, w.y, w.z, 0.0, 0.0]);
    let (x, _) = levenberg_marquardt(&problem, x0, options);
    Ok(problem.pose(&x))
}

fn is_conjugate_rotation(h: &Matrix3<f64>, ka: &Intrinsics, kb: &Intrinsics) -> bool {
    let m = kb.k_inv() * h * ka.k();
    let s = m.singular_values();
    let (max, min) = (s.max(), s.min());
    max > 0.0 && min / max > 0.9
}

/// Reconstruct homologous points seen by two views with known intrinsics (book chapter 5):
/// RANSAC on the normalized 8-point F, E = K_bᵀFK_a, the pose that puts the points in front
/// (§5.8), optional LM refinement of the pose, linear triangulation (§5.8.2) with optional
/// nonlinear refinement.
///
/// Errors: fewer than 8 matches, [`VisionError::ZeroBaseline`] when the matches are explained by
/// a rotation about the camera centre, [`VisionError::Degenerate`] for a planar scene or when no
/// consensus is found.
pub fn reconstruct_two_view<R: Rng + ?Sized>(
    a: &[Point2<f64>],
    b: &[Point2<f64>],
    ka: &Intrinsics,
    kb: &Intrinsics,
    options: &TwoViewOptions,
    rng: &mut R,
) -> Result<TwoViewReconstruction> {
    check_pairs(a.len(), b.len(), fundamental::EIGHT_POINT_MIN)?;
    check_finite("2D points", a.iter().chain(b).flat_map(|p| p.coords.iter()))?;
    ka.validate()?;
    kb.validate()?;
    let n = a.len();
    let data: Vec<_> = a.iter().copied().zip(b.iter().copied()).collect();
    let est = FundamentalEstimator {
        residual: options.residual,
    };
    let f_result = match options.residual {
        EpipolarResidual::Sampson => ransac(&est, &data, &options.ransac, rng),
        EpipolarResidual::Algebraic => {
            // The book's algebraic error, measured on the normalized points (§5.7) so that the
            // threshold does not depend on the image size.
            let (ha, _, na) = crate::normalize::normalize_2d(a)?;
            let (hb, _, nb) = crate::normalize::normalize_2d(b)?;
            let data_n: Vec<_> = na.into_iter().zip(nb).collect();
            ransac(&est, &data_n, &options.ransac, rng).map(|mut r| {
                r.model = hb.transpose() * r.model * ha;
                r.model /= r.model.norm();
                r
            })
        }
    };
    // Degeneracy test: does a homography explain (nearly) as much as F?
    let h_threshold = match options.residual {
        EpipolarResidual::Sampson => options.ransac.threshold * 2.0,
        EpipolarResidual::Algebraic => 2.0,
    };
    // F's support measured like H's: Sampson distance within the same pixel threshold.
    let f_inliers = f_result.as_ref().map_or(0, |r| {
        data.iter()
            .filter(|(xa, xb)| sampson_distance(&r.model, xa, xb) <= h_threshold)
            .count()
    });
    // A homography that matters explains ≥ homography_ratio of F's support: sample only as
    // long as needed to find such a one (or half of the matches when F failed).
    let h_ratio = if f_inliers > 0 {
        options.homography_ratio * f_inliers as f64 / n as f64
    } else {
        0.5
    };
    let h_iterations = crate::ransac::adaptive_iterations(h_ratio, 4, options.ransac.confidence);
    let h_params = RansacParams {
        threshold: h_threshold,
        max_iterations: h_iterations.clamp(1, options.ransac.max_iterations),
        min_iterations: 1,
        ..options.ransac.clone()
    };
    let h_result = ransac(&HomographyEstimator, &data, &h_params, rng).ok();
    if let Some(h) = &h_result {
        if h.num_inliers as f64 >= options.homography_ratio * f_inliers as f64 && h.num_inliers >= 8
        {
            return Err(if is_conjugate_rotation(&h.model, ka, kb) {
                VisionError::ZeroBaseline
            } else {
                VisionError::Degenerate(
                    "the matches are explained by a homography (planar scene)".into(),
                )
            });
        }
    }
    let f_result = f_result?;
    let mut inliers = f_result.inliers.clone();
    let sel = |flags: &[bool], v: &[Point2<f64>]| -> Vec<Point2<f64>> {
        v.iter()
            .zip(flags)
            .filter(|(_, &f)| f)
            .map(|(p, _)| *p)
            .collect()
    };
    let e = essential_from_fundamental(&f_result.model, ka, kb);
    let (mut pose, _) = choose_pose(&e, ka, kb, &sel(&inliers, a), &sel(&inliers, b))?;
    let lm = LmOptions {
        max_iterations: 50,
        ..LmOptions::default()
    };
    let threshold_px = match options.residual {
        EpipolarResidual::Sampson => options.ransac.threshold,
        EpipolarResidual::Algebraic => 1.0,
    };
    if options.refine_pose {
        for _ in 0..2 {
            pose = refine_relative_pose(&pose, ka, kb, &sel(&inliers, a), &sel(&inliers, b), &lm)?;
            let f = fundamental_from_pose(ka, kb, &pose);
            let flags: Vec<bool> = a
                .iter()
                .zip(b)
                .map(|(xa, xb)| sampson_distance(&f, xa, xb) <= threshold_px)
                .collect();
            if flags == inliers || flags.iter().filter(|&&x| x).count() < 8 {
                break;
            }
            inliers = flags;
        }
    }
    let camera_a = Camera::new(ka.clone(), Matrix3::identity(), Vector3::zeros());
    let camera_b = Camera {
        intrinsics: kb.clone(),
        pose,
    };
    let (pa, pb) = (camera_a.p_matrix(), camera_b.p_matrix());
    let f = fundamental_from_pose(ka, kb, &camera_b.pose);
    let mut points = Vec::new();
    let mut indices = Vec::new();
    let mut sampson2 = 0.0;
    let mut reproj2 = 0.0;
    let mut parallax = Vec::new();
    let (ca, cb) = (camera_a.center(), camera_b.center());
    for i in 0..n {
        if !inliers[i] {
            continue;
        }
        let cams = [pa, pb];
        let obs = [a[i], b[i]];
        let x = match triangulate_linear_n(&cams, &obs) {
            Ok(x0) if options.refine_points => {
                triangulate_nonlinear(&cams, &obs, &x0, &lm).unwrap_or(x0)
            }
            Ok(x0) => x0,
            Err(_) => {
                inliers[i] = false;
                continue;
            }
        };
        if camera_a.depth(&x) <= 0.0 || camera_b.depth(&x) <= 0.0 {
            inliers[i] = false;
            continue;
        }
        sampson2 += sampson_distance(&f, &a[i], &b[i]).powi(2);
        reproj2 += camera_a.reprojection_error(&x, &a[i]).powi(2)
            + camera_b.reprojection_error(&x, &b[i]).powi(2);
        parallax.push(parallax_angle(&ca, &cb, &x).to_degrees());
        points.push(x);
        indices.push(i);
    }
    let m = points.len();
    let needed = options.min_inliers.max(8);
    if m < needed {
        return Err(VisionError::NoConsensus {
            best: m,
            total: n,
            needed,
        });
    }
    parallax.sort_by(f64::total_cmp);
    let report = TwoViewReport {
        num_matches: n,
        num_inliers: m,
        ransac_iterations: f_result.iterations,
        sampson_rms: (sampson2 / m as f64).sqrt(),
        reprojection_rms: (reproj2 / (2 * m) as f64).sqrt(),
        median_parallax_deg: parallax[m / 2],
    };
    let fm = f / f.norm();
    let fundamental = [
        [fm[(0, 0)], fm[(0, 1)], fm[(0, 2)]],
        [fm[(1, 0)], fm[(1, 1)], fm[(1, 2)]],
        [fm[(2, 0)], fm[(2, 1)], fm[(2, 2)]],
    ];
    Ok(TwoViewReconstruction {
        camera_a,
        camera_b,
        fundamental,
        points3d: Points3d(points),
        point_indices: indices,
        inliers,
        report,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::rotation::rotation_angle_between;
    use crate::synthetic::{two_view_scene_with, TwoViewScene};
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    pub(crate) fn two_view_scene(seed: u64, n: usize, sigma: f64, outliers: f64) -> TwoViewScene {
        two_view_scene_with(&mut Pcg64::seed_from_u64(seed), n, sigma, outliers, 1.0)
    }

    fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
        (a.dot(b) / (a.norm() * b.norm()))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// Must-show: with 0.5 px noise and 30 % outliers the relative pose is recovered within 0.1°
    /// (rotation) and 0.5° (direction of t).
    #[test]
    fn two_view_recovers_pose_with_outliers() {
        let mut worst = [0.0f64; 2];
        for seed in 0..10u64 {
            let s = two_view_scene(400 + seed, 300, 0.5, 0.3);
            let rec = reconstruct_two_view(
                &s.a,
                &s.b,
                &s.k,
                &s.k,
                &TwoViewOptions::default(),
                &mut Pcg64::seed_from_u64(seed),
            )
            .unwrap();
            let er = rotation_angle_between(&rec.camera_b.pose.r, &s.pose_b.r).to_degrees();
            let et = angle_deg(&rec.camera_b.pose.t, &s.pose_b.t);
            worst[0] = worst[0].max(er);
            worst[1] = worst[1].max(et);
            assert!(
                er < 0.1 && et < 0.5,
                "seed {seed}: R {er:.4}° t {et:.4}° {:?}",
                rec.report
            );
            let wrong = rec
                .inliers
                .iter()
                .zip(&s.outlier)
                .filter(|(i, o)| **i && **o)
                .count();
            assert!(wrong <= 3, "{wrong} outliers kept");
            assert!(rec.report.reprojection_rms < 0.8, "{:?}", rec.report);
        }
        println!(
            "two-view 30% outliers (R deg, t deg) worst over seeds: er {:.4}, et {:.4}",
            worst[0], worst[1]
        );
    }

    #[test]
    fn book_algebraic_residual_still_works() {
        let s = two_view_scene(77, 200, 0.5, 0.3);
        let opts = TwoViewOptions {
            residual: EpipolarResidual::Algebraic,
            ransac: RansacParams::with_threshold(2e-3),
            ..Default::default()
        };
        let rec = reconstruct_two_view(&s.a, &s.b, &s.k, &s.k, &opts, &mut Pcg64::seed_from_u64(1))
            .unwrap();
        let er = rotation_angle_between(&rec.camera_b.pose.r, &s.pose_b.r).to_degrees();
        assert!(er < 0.5, "{er}");
    }

    #[test]
    fn zero_baseline_is_an_error() {
        let mut rng = Pcg64::seed_from_u64(9);
        for sigma in [0.0, 0.5] {
            let s = two_view_scene_with(&mut rng, 100, sigma, 0.0, 0.0);
            let e =
                reconstruct_two_view(&s.a, &s.b, &s.k, &s.k, &TwoViewOptions::default(), &mut rng);
            assert!(
                matches!(e, Err(VisionError::ZeroBaseline)),
                "sigma {sigma}: {e:?}"
            );
        }
    }

    #[test]
    fn too_few_matches() {
        let s = two_view_scene(10, 7, 0.0, 0.0);
        let e = reconstruct_two_view(
            &s.a,
            &s.b,
            &s.k,
            &s.k,
            &TwoViewOptions::default(),
            &mut Pcg64::seed_from_u64(1),
        );
        assert!(matches!(
            e,
            Err(VisionError::TooFewPoints { needed: 8, got: 7 })
        ));
    }
}
