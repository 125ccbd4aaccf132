//! Relative pose with a known K, for any scene: the five-point essential matrix
//! ([`essential_five_point`]) and the plane-induced homography ([`decompose_homography`]) are
//! both fitted by RANSAC, and when the homography explains nearly as many matches as E does
//! (the inlier-ratio rule of COLMAP's two-view geometry and ORB-SLAM's initializer) its motions
//! replace E's, whose pose coplanar points do not determine: a floor or a wall starts from H, a
//! general scene from E.
//!
//! Each candidate is refined on the Sampson distances of its matches and scored by the matches
//! that triangulate in front of both cameras within the threshold. A planar scene leaves two
//! motions that explain the two views equally well; both are returned, best first, for a third
//! view to tell apart (the fragment's resection does).

use nalgebra::{Matrix3, Point2, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};

use super::essential::decompose_essential;
use super::five_point::essential_five_point;
use super::homography::HomographyEstimator;
use super::homography_pose::decompose_homography;
use super::triangulation::{parallax_angle, triangulate_linear};
use super::{fundamental_from_pose, refine_relative_pose, sampson_distance};
use crate::camera::{Camera, Intrinsics, Pose};
use crate::error::{check_finite, check_pairs, Result, VisionError};
use crate::optimize::LmOptions;
use crate::ransac::{ransac, Estimator, RansacParams};
use crate::rotation::rotation_angle_between;

/// Which model a relative pose came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StartModel {
    /// The five-point essential matrix (a general scene).
    Essential,
    /// A decomposition of the plane-induced homography (a planar scene).
    Homography,
    /// The book's 8-point fundamental matrix and E = KᵀFK (§5.7–5.8).
    Fundamental,
}

/// Options of [`relative_pose_calibrated`].
#[derive(Clone, Debug, PartialEq)]
pub struct CalibratedOptions {
    /// RANSAC: the threshold is a Sampson distance in pixels (a transfer error for H).
    pub ransac: RansacParams,
    /// The homography's motions are the candidates (E's pose dropped) when H keeps at least
    /// this fraction of E's inliers.
    pub homography_ratio: f64,
    /// A candidate with fewer triangulated inliers is dropped.
    pub min_inliers: usize,
    /// Candidates scoring at least this fraction of the best are kept (planar ambiguity).
    pub ambiguity_ratio: f64,
}

impl Default for CalibratedOptions {
    fn default() -> Self {
        CalibratedOptions {
            ransac: RansacParams::with_threshold(1.5),
            homography_ratio: 0.8,
            min_inliers: 12,
            ambiguity_ratio: 0.8,
        }
    }
}

/// One candidate motion of camera b relative to camera a = K[I|0], ‖t‖ = 1.
#[derive(Clone, Debug)]
pub struct RelativePose {
    /// Camera b's pose.
    pub pose: Pose,
    /// The model it came from.
    pub model: StartModel,
    /// Indices of the matches triangulated in front of both cameras within the threshold.
    pub inliers: Vec<usize>,
    /// Their points, in camera a's frame.
    pub points: Vec<Vector3<f64>>,
    /// Median parallax angle of those points, degrees.
    pub median_parallax_deg: f64,
}

/// The result of [`relative_pose_calibrated`].
#[derive(Clone, Debug)]
pub struct CalibratedTwoView {
    /// Candidates, most inliers first (one for a general scene, often two for a planar one).
    pub candidates: Vec<RelativePose>,
    /// Inliers of the essential matrix's RANSAC.
    pub essential_inliers: usize,
    /// Inliers of the homography's RANSAC.
    pub homography_inliers: usize,
}

/// The five-point essential matrix as a RANSAC estimator over pixel matches: models are the
/// fundamental matrices K⁻ᵀEK⁻¹, the residual the Sampson distance in pixels.
struct FivePointEstimator {
    k: Intrinsics,
    k_inv: Matrix3<f64>,
}

impl Estimator for FivePointEstimator {
    type Datum = (Point2<f64>, Point2<f64>);
    type Model = Matrix3<f64>;
    const MIN_SAMPLES: usize = 5;

    fn estimate(&self, data: &[Self::Datum], sample: &[usize]) -> Vec<Matrix3<f64>> {
        let a = [0, 1, 2, 3, 4].map(|i| self.k_inv * data[sample[i]].0.to_homogeneous());
        let b = [0, 1, 2, 3, 4].map(|i| self.k_inv * data[sample[i]].1.to_homogeneous());
        essential_five_point(&a, &b)
            .into_iter()
            .map(|e| self.k_inv.transpose() * e * self.k_inv)
            .collect()
    }

    fn residual(&self, f: &Matrix3<f64>, d: &Self::Datum) -> f64 {
        sampson_distance(f, &d.0, &d.1)
    }

    /// Local optimization: the cheiral pose of E refined on the inliers' Sampson distances.
    fn refit(
        &self,
        data: &[Self::Datum],
        inliers: &[usize],
        f: &Matrix3<f64>,
    ) -> Option<Self::Model> {
        if inliers.len() < 6 {
            return None;
        }
        let kk = self.k.k();
        let e = kk.transpose() * f * kk;
        let a: Vec<_> = inliers.iter().map(|&i| data[i].0).collect();
        let b: Vec<_> = inliers.iter().map(|&i| data[i].1).collect();
        let pose = cheiral_pose(&e, &self.k, &a, &b)?;
        let lm = LmOptions {
            max_iterations: 8,
            ..LmOptions::default()
        };
        let pose = refine_relative_pose(&pose, &self.k, &self.k, &a, &b, &lm).ok()?;
        Some(fundamental_from_pose(&self.k, &self.k, &pose))
    }
}

/// The decomposition of E that puts the most matches in front of both cameras.
fn cheiral_pose(
    e: &Matrix3<f64>,
    k: &Intrinsics,
    a: &[Point2<f64>],
    b: &[Point2<f64>],
) -> Option<Pose> {
    let poses = decompose_essential(e).ok()?;
    poses
        .into_iter()
        .map(|p| {
            let n = in_front(k, &p, a, b);
            (n, p)
        })
        .max_by_key(|(n, _)| *n)
        .map(|(_, p)| p)
}

fn in_front(k: &Intrinsics, pose: &Pose, a: &[Point2<f64>], b: &[Point2<f64>]) -> usize {
    let ca = Camera::new(k.clone(), Matrix3::identity(), Vector3::zeros());
    let cb = Camera {
        intrinsics: k.clone(),
        pose: pose.clone(),
    };
    let (pa, pb) = (ca.p_matrix(), cb.p_matrix());
    a.iter()
        .zip(b)
        .filter(|(xa, xb)| match triangulate_linear(&pa, &pb, xa, xb) {
            Ok(x) => ca.depth(&x) > 0.0 && cb.depth(&x) > 0.0,
            Err(_) => false,
        })
        .count()
}

/// Relative pose of two views with the same known (pinhole) K (module docs). Errors:
/// [`VisionError::ZeroBaseline`] when the best candidate has no parallax (a pure rotation),
/// [`VisionError::NoConsensus`] / [`VisionError::Degenerate`] when no candidate has
/// `min_inliers` triangulated matches.
pub fn relative_pose_calibrated<R: Rng + ?Sized>(
    a: &[Point2<f64>],
    b: &[Point2<f64>],
    k: &Intrinsics,
    options: &CalibratedOptions,
    min_parallax_deg: f64,
    rng: &mut R,
) -> Result<CalibratedTwoView> {
    check_pairs(a.len(), b.len(), 5)?;
    check_finite("2D points", a.iter().chain(b).flat_map(|p| p.coords.iter()))?;
    k.validate()?;
    let data: Vec<_> = a.iter().copied().zip(b.iter().copied()).collect();
    let thr = options.ransac.threshold;
    let est = FivePointEstimator {
        k: k.clone(),
        k_inv: k.k_inv(),
    };
    let e_fit = ransac(&est, &data, &options.ransac, rng).ok();
    let h_params = RansacParams {
        threshold: thr * 2.0,
        ..options.ransac.clone()
    };
    let h_fit = if data.len() >= 4 {
        ransac(&HomographyEstimator, &data, &h_params, rng).ok()
    } else {
        None
    };
    let essential_inliers = e_fit.as_ref().map_or(0, |r| r.num_inliers);
    let homography_inliers = h_fit.as_ref().map_or(0, |r| r.num_inliers);

    // (pose, model, the matches it was fitted on)
    let mut seeds: Vec<(Pose, StartModel, Vec<bool>)> = Vec::new();
    let kk = k.k();
    // A pair the homography explains (nearly) as well is planar: its essential matrix is not
    // determined by the matches (coplanar points fit a family of motions, and RANSAC returns
    // one of them), so its pose is left out and the plane's motions stand alone (COLMAP's
    // planar case; ORB-SLAM's initializer). Off-plane points, if any, still triangulate with
    // the true motion, which is among the plane's two.
    let planar = homography_inliers as f64 >= options.homography_ratio * essential_inliers as f64
        && homography_inliers >= options.min_inliers;
    if let Some(r) = e_fit.as_ref().filter(|_| !planar) {
        let e = kk.transpose() * r.model * kk;
        let (sa, sb) = select(&r.inliers, a, b);
        if let Some(p) = cheiral_pose(&e, k, &sa, &sb) {
            seeds.push((p, StartModel::Essential, r.inliers.clone()));
        }
    }
    if let Some(r) = &h_fit {
        if r.num_inliers as f64 >= options.homography_ratio * essential_inliers as f64 {
            let hn = k.k_inv() * r.model * kk;
            let (sa, sb) = select(&r.inliers, a, b);
            for m in decompose_homography(&hn) {
                if m.t.norm() < 1e-9 {
                    continue;
                }
                let pose = Pose::new(m.r, m.t.normalize());
                if in_front(k, &pose, &sa, &sb) * 10 >= sa.len() * 9 {
                    seeds.push((pose, StartModel::Homography, r.inliers.clone()));
                }
            }
        }
    }
    let lm = LmOptions {
        max_iterations: 30,
        ..LmOptions::default()
    };
    let mut candidates: Vec<RelativePose> = Vec::new();
    for (pose, model, fitted) in seeds {
        let (sa, sb) = select(&fitted, a, b);
        let pose = refine_relative_pose(&pose, k, k, &sa, &sb, &lm).unwrap_or(pose);
        let cand = triangulated(k, &pose, model, a, b, thr);
        if cand.inliers.len() < options.min_inliers {
            continue;
        }
        // The same motion reached from two models: keep the one with more inliers.
        if let Some(same) = candidates.iter_mut().find(|c| {
            rotation_angle_between(&c.pose.r, &cand.pose.r) < 0.2f64.to_radians()
                && c.pose.t.dot(&cand.pose.t) > 0.999
        }) {
            if cand.inliers.len() > same.inliers.len() {
                *same = cand;
            }
            continue;
        }
        candidates.push(cand);
    }
    candidates.sort_by_key(|c| std::cmp::Reverse(c.inliers.len()));
    let Some(best) = candidates.first() else {
        return Err(VisionError::NoConsensus {
            best: essential_inliers.max(homography_inliers),
            total: data.len(),
            needed: options.min_inliers,
        });
    };
    let floor = options.ambiguity_ratio * best.inliers.len() as f64;
    candidates.retain(|c| c.inliers.len() as f64 >= floor);
    // A planar pair's two motions see different parallax in the same image motion (a small
    // push read as a sideways move has more): the pair has a baseline when any of them does,
    // and none is dropped for its own, which would favour the wrong one.
    let parallax = candidates
        .iter()
        .map(|c| c.median_parallax_deg)
        .fold(0.0, f64::max);
    if !(parallax >= min_parallax_deg) {
        return Err(VisionError::ZeroBaseline);
    }
    Ok(CalibratedTwoView {
        candidates,
        essential_inliers,
        homography_inliers,
    })
}

fn select(
    flags: &[bool],
    a: &[Point2<f64>],
    b: &[Point2<f64>],
) -> (Vec<Point2<f64>>, Vec<Point2<f64>>) {
    flags
        .iter()
        .zip(a.iter().zip(b))
        .filter(|(f, _)| **f)
        .map(|(_, (x, y))| (*x, *y))
        .unzip()
}

/// The matches of `pose` (Sampson distance within `thr`) triangulated, kept when in front of
/// both cameras and reprojecting within 2·`thr` in both.
fn triangulated(
    k: &Intrinsics,
    pose: &Pose,
    model: StartModel,
    a: &[Point2<f64>],
    b: &[Point2<f64>],
    thr: f64,
) -> RelativePose {
    let f = fundamental_from_pose(k, k, pose);
    let ca = Camera::new(k.clone(), Matrix3::identity(), Vector3::zeros());
    let cb = Camera {
        intrinsics: k.clone(),
        pose: pose.clone(),
    };
    let (pa, pb) = (ca.p_matrix(), cb.p_matrix());
    let (oa, ob) = (ca.center(), cb.center());
    let mut inliers = Vec::new();
    let mut points = Vec::new();
    let mut parallax = Vec::new();
    for (i, (xa, xb)) in a.iter().zip(b).enumerate() {
        if !(sampson_distance(&f, xa, xb) <= thr) {
            continue;
        }
        let Ok(x) = triangulate_linear(&pa, &pb, xa, xb) else {
            continue;
        };
        if !(ca.depth(&x) > 0.0 && cb.depth(&x) > 0.0) {
            continue;
        }
        if !(ca.reprojection_error(&x, xa) <= 2.0 * thr
            && cb.reprojection_error(&x, xb) <= 2.0 * thr)
        {
            continue;
        }
        parallax.push(parallax_angle(&oa, &ob, &x).to_degrees());
        inliers.push(i);
        points.push(x.coords);
    }
    parallax.sort_by(f64::total_cmp);
    let median_parallax_deg = parallax.get(parallax.len() / 2).copied().unwrap_or(0.0);
    RelativePose {
        pose: pose.clone(),
        model,
        inliers,
        points,
        median_parallax_deg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::axis_angle_to_r;
    use crate::synthetic::gaussian;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    /// Matches of points on a floor (`planar`) or in a volume seen by [I|0] and a moved camera,
    /// with noise and 20 % outliers; returns them and the true pose (‖t‖ = 1).
    fn scene(seed: u64, planar: bool) -> (Vec<Point2<f64>>, Vec<Point2<f64>>, Pose, Intrinsics) {
        let mut rng = Pcg64::seed_from_u64(seed);
        let k = Intrinsics::new(800.0, 800.0, 480.0, 270.0);
        let r = axis_angle_to_r(&Vector3::new(0.05, -0.2, 0.02));
        let c = Vector3::new(1.0, 0.1, 0.3);
        let t = -r * c;
        let pose = Pose::new(r, t.normalize());
        let truth = Pose::new(r, t);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        while a.len() < 200 {
            let (x, z) = (rng.random_range(-4.0..4.0), rng.random_range(4.0..10.0));
            let y = if planar {
                1.5
            } else {
                rng.random_range(-2.0..1.5)
            };
            let p = Vector3::new(x, y, z);
            let q = truth.r * p + truth.t;
            if q.z <= 0.1 {
                continue;
            }
            let pa = Point2::new(800.0 * x / z + 480.0, 800.0 * y / z + 270.0);
            let mut pb = Point2::new(800.0 * q.x / q.z + 480.0, 800.0 * q.y / q.z + 270.0);
            if !(0.0..960.0).contains(&pa.x) || !(0.0..540.0).contains(&pa.y) {
                continue;
            }
            pb.x += 0.3 * gaussian(&mut rng);
            pb.y += 0.3 * gaussian(&mut rng);
            if a.len() % 5 == 0 {
                pb.x += rng.random_range(20.0..60.0);
            }
            a.push(pa);
            b.push(pb);
        }
        (a, b, pose, k)
    }

    #[test]
    /// Two views only: the rotation within 0.03–0.14° and the direction of travel within
    /// 0.15–1.4° over these seeds (0.3 px noise), which the fragment's adjustment then refines.
    fn general_and_planar_scenes_give_the_true_motion() {
        for planar in [false, true] {
            for seed in 0..5 {
                let (a, b, truth, k) = scene(seed, planar);
                let mut rng = Pcg64::seed_from_u64(seed);
                let r = relative_pose_calibrated(
                    &a,
                    &b,
                    &k,
                    &CalibratedOptions::default(),
                    0.5,
                    &mut rng,
                )
                .unwrap();
                let best = r
                    .candidates
                    .iter()
                    .map(|c| {
                        (
                            rotation_angle_between(&c.pose.r, &truth.r).to_degrees(),
                            c.pose.t.angle(&truth.t).to_degrees(),
                        )
                    })
                    .fold((f64::INFINITY, f64::INFINITY), |x, y| {
                        if y.0 < x.0 {
                            y
                        } else {
                            x
                        }
                    });
                assert!(
                    best.0 < 0.3 && best.1 < 3.0,
                    "planar {planar} seed {seed}: {best:?}°"
                );
                assert!(r.candidates.len() <= 2);
                if planar {
                    assert!(r.homography_inliers as f64 >= 0.8 * r.essential_inliers as f64);
                } else {
                    assert_eq!(r.candidates.len(), 1);
                    assert_eq!(r.candidates[0].model, StartModel::Essential);
                }
                // An outlier (every fifth match) moved along its epipolar line cannot be told
                // from an inlier by two views; the others are all rejected.
                let f = fundamental_from_pose(&k, &k, &truth);
                for c in &r.candidates {
                    let kept = c
                        .inliers
                        .iter()
                        .filter(|&&i| i % 5 == 0 && sampson_distance(&f, &a[i], &b[i]) > 3.0)
                        .count();
                    assert_eq!(kept, 0, "planar {planar} seed {seed}");
                }
            }
        }
    }

    #[test]
    fn a_pure_rotation_is_a_zero_baseline() {
        let mut rng = Pcg64::seed_from_u64(1);
        let k = Intrinsics::new(800.0, 800.0, 480.0, 270.0);
        let r = axis_angle_to_r(&Vector3::new(0.0, 0.1, 0.0));
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..100 {
            let p = Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(4.0..9.0),
            );
            let q = r * p;
            a.push(Point2::new(
                800.0 * p.x / p.z + 480.0,
                800.0 * p.y / p.z + 270.0,
            ));
            b.push(Point2::new(
                800.0 * q.x / q.z + 480.0 + 0.2 * gaussian(&mut rng),
                800.0 * q.y / q.z + 270.0 + 0.2 * gaussian(&mut rng),
            ));
        }
        let e = relative_pose_calibrated(&a, &b, &k, &CalibratedOptions::default(), 0.5, &mut rng);
        assert!(
            matches!(
                e,
                Err(VisionError::ZeroBaseline) | Err(VisionError::NoConsensus { .. })
            ),
            "{e:?}"
        );
    }
}
