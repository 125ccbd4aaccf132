//! The figures of a solve (the solve report): per-frame reprojection RMS and inlier count,
//! per-track error, overall RMS, time per stage, and the per-fragment figures.

use std::time::Instant;

use nalgebra::{Matrix6, Vector3};
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_klt::Tracks;

pub use crate::adjust::SolvedIntrinsic;
use crate::fragment::FragmentReport;
use crate::score::BookScore;
use crate::structure::reprojection_error;

/// Wall time of one stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageTime {
    /// Stage name.
    pub stage: String,
    /// Seconds.
    pub seconds: f64,
}

impl StageTime {
    /// The time since `start`, named.
    pub fn new(stage: &str, start: Instant) -> Self {
        StageTime {
            stage: stage.to_string(),
            seconds: start.elapsed().as_secs_f64(),
        }
    }
}

/// One frame's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// Frame number.
    pub frame: i64,
    /// Reconstructed points observed in the frame.
    pub observations: usize,
    /// Those within the inlier tolerance.
    pub inliers: usize,
    /// RMS reprojection error of the inliers, pixels.
    pub rms: f64,
    /// The frame's solved focal length, px, when the lens zooms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal_px: Option<f64>,
    /// How well the solve determines the frame's rotation: the standard deviation, degrees, of
    /// its least-determined axis ([`SolveReport::rotation_sd_basis`] says how it was found).
    /// `None` without a camera or with fewer than 4 inliers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_sd_deg: Option<f64>,
}

/// One track's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackReport {
    /// Track id.
    pub id: u64,
    /// Observations in posed frames.
    pub observations: usize,
    /// RMS reprojection error over them, pixels.
    pub rms: f64,
}

/// The report of a solve.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SolveReport {
    /// Inlier tolerance used for the per-frame figures, pixels.
    pub inlier_tolerance: f64,
    /// RMS reprojection error over all inlier observations, pixels.
    pub overall_rms: f64,
    /// Reconstructed points.
    pub points: usize,
    /// Per frame.
    pub frames: Vec<FrameReport>,
    /// Per reconstructed track.
    pub tracks: Vec<TrackReport>,
    /// Time per stage: kept for the caller (logged by the node), not serialized — a report
    /// says what was computed, the same on every machine; how long it took is the run's.
    #[serde(skip_serializing, default)]
    pub stages: Vec<StageTime>,
    /// Per fragment (empty for stages that do not cut fragments).
    pub fragments: Vec<FragmentReport>,
    /// The book-style score over all tracks (see [`crate::score`]), when computed.
    pub score: Option<BookScore>,
    /// Fallbacks taken and other remarks, for a person to read.
    pub notes: Vec<String>,
    /// What makes the solve uncertain (an ambiguous start, frames poorly determined): a
    /// person must look before trusting the cameras.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The camera was solved as a nodal pan: rotations only, every centre at the origin
    /// ([`crate::tripod`]).
    #[serde(default)]
    pub rotation_only: bool,
    /// The intrinsics the solve refined (focal length, distortion), with their standard
    /// deviations ([`vfxgraph_bundle::covariance`]); empty when K was held.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub intrinsics: Vec<SolvedIntrinsic>,
    /// How the frames' `rotation_sd_deg` were found.
    #[serde(default)]
    pub rotation_sd_basis: RotationSdBasis,
}

/// How a [`FrameReport::rotation_sd_deg`] was found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationSdBasis {
    /// From the whole solve's covariance, the points free ([`shot_rotation_sd`]): what the
    /// tracks leave undetermined in the structure every frame shares is in it, and the rotation
    /// shared by every frame (the choice of world) is out of it, as when cameras are compared
    /// after aligning them — the mean rotation error removed, or the first frame's for a
    /// rotation-only solve.
    Shot,
    /// Each frame alone with the points held at their solved positions ([`pose_sd`]): a lower
    /// bound (a frame that sees few points, or points bunched in one part of the image, has a
    /// large one), used where the shot's covariance is not computed (over
    /// [`vfxgraph_bundle::covariance::MAX_DIMENSION`] camera parameters, or singular).
    #[default]
    Frame,
}

/// The standard deviation (degrees) of the least-determined rotation axis of a camera whose
/// observations have the normal matrix `a` (JᵀJ in the pose,
/// `crate::structure::pose_jacobian`) and pixel noise `sigma` per coordinate: √λmax of the
/// rotation block of σ²(JᵀJ)⁻¹ (Hartley & Zisserman, §5.2.5). `None` when the pose is not determined (a singular normal matrix).
pub fn pose_sd(a: &Matrix6<f64>, sigma: f64) -> Option<f64> {
    let cov = a.try_inverse()? * (sigma * sigma);
    rotation_sd(&cov)
}

/// √λmax of the rotation block of a pose covariance, degrees.
fn rotation_sd(cov: &Matrix6<f64>) -> Option<f64> {
    let rot = cov.fixed_view::<3, 3>(0, 0).into_owned();
    let rot = (rot + rot.transpose()) * 0.5;
    let lmax = rot.symmetric_eigenvalues().max();
    (lmax.is_finite() && lmax >= 0.0).then(|| lmax.sqrt().to_degrees())
}

/// Per frame, the standard deviation (degrees) of the least-determined axis of its rotation
/// error from the whole solve's covariance ([`RotationSdBasis::Shot`]): a bundle problem of
/// the solve's inlier observations (K held), the points eliminated
/// ([`vfxgraph_bundle::covariance::rotation_covariance`]: the larger of the white-noise and the
/// tracks' sandwich estimates, so a feature that drifts counts), the rotation every frame shares
/// removed — the mean's for a moving camera (as [`vfxgraph_geometry::camera_path::align_poses`] aligns
/// cameras), the first frame's for a rotation-only solve (every centre at the origin; the
/// points are directions). `None` when the covariance is not available (too many frames, too
/// few observations, a singular system). With `free_focal` the focal length is a parameter of
/// the problem too (a solve that estimated it): its uncertainty, and how it trades against
/// the cameras' motion, is then in every frame's figure.
pub fn shot_rotation_sd(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    marks: &[Vec<bool>],
    free_focal: bool,
) -> Option<Vec<Option<f64>>> {
    let rotation_only = poses.iter().flatten().all(|p| p.t == Vector3::zeros());
    let mut block = crate::adjust::pinhole_block(k);
    block.fixed = !free_focal;
    block.held[1] = true;
    block.held[2] = true;
    let gauge = if rotation_only {
        vfxgraph_bundle::Gauge::RotationOnly
    } else {
        vfxgraph_bundle::Gauge::FixFirstCameraAndScale
    };
    // The solve's inliers, unweighted.
    let inlier = |t: usize, f: usize| f64::from(u8::from(marks[t][f - tracks.tracks[t].first]));
    let crate::adjust::IndexedProblem {
        problem, cam_frame, ..
    } = crate::adjust::indexed_problem(
        tracks,
        vec![block],
        Vec::new(),
        gauge,
        poses,
        points,
        &inlier,
    )
    .ok()?;
    let cov = vfxgraph_bundle::covariance::rotation_covariance(&problem).ok()?;
    let reference = rotation_only.then_some(0);
    let white = vfxgraph_bundle::covariance::aligned_rotation_sd(&cov.white, reference);
    let by_tracks = vfxgraph_bundle::covariance::aligned_rotation_sd(&cov.tracks, reference);
    let mut out = vec![None; poses.len()];
    for ((w, t), &f) in white.iter().zip(&by_tracks).zip(&cam_frame) {
        let s = w.max(*t);
        out[f] = s.is_finite().then(|| s.to_degrees());
    }
    Some(out)
}

impl SolveReport {
    /// The largest of the frames' `rotation_sd_deg` (0 when none has one).
    pub fn largest_rotation_sd_deg(&self) -> f64 {
        self.frames
            .iter()
            .filter_map(|f| f.rotation_sd_deg)
            .fold(0.0, f64::max)
    }

    /// Recomputes the frames' `rotation_sd_deg` from the shot's covariance with the focal
    /// length free ([`shot_rotation_sd`]), for a solve that estimated it; `tracks`, `k`,
    /// `poses`, `points` and `inlier_tolerance` as given to [`solve_report`]. Left as it is
    /// when that covariance is not available.
    pub fn with_free_focal_sd(
        &mut self,
        tracks: &Tracks,
        k: &Intrinsics,
        poses: &[Option<Pose>],
        points: &[Option<Vector3<f64>>],
        inlier_tolerance: f64,
    ) {
        let marks = crate::structure::inlier_marks(tracks, k, poses, points, inlier_tolerance);
        if let Some(sd) = shot_rotation_sd(tracks, k, poses, points, &marks, true) {
            for (fr, s) in self.frames.iter_mut().zip(sd) {
                if fr.inliers >= 4 {
                    fr.rotation_sd_deg = s;
                }
            }
            self.rotation_sd_basis = RotationSdBasis::Shot;
        }
    }
}

/// Builds the per-frame and per-track figures of a solve; `marks` (by track index and
/// observation) are the solve's inliers at `inlier_tolerance` (`crate::structure::inlier_marks`).
pub fn solve_report(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    marks: &[Vec<bool>],
    inlier_tolerance: f64,
) -> SolveReport {
    let n = tracks.frames.len();
    let mut frames: Vec<FrameReport> = tracks
        .frames
        .iter()
        .map(|&f| FrameReport {
            frame: f,
            observations: 0,
            inliers: 0,
            rms: 0.0,
            focal_px: None,
            rotation_sd_deg: None,
        })
        .collect();
    // Per frame, the normal matrix JᵀJ of its inlier observations in its pose.
    let mut normal = vec![Matrix6::<f64>::zeros(); n];
    let mut sq = vec![0.0; n];
    let mut track_reports = Vec::new();
    let (mut total_sq, mut total_n) = (0.0, 0usize);
    for ((t, x), m) in tracks.tracks.iter().zip(points).zip(marks) {
        let Some(x) = x else { continue };
        let (mut s, mut c) = (0.0, 0usize);
        for (j, o) in t.points.iter().enumerate() {
            let f = t.first + j;
            let Some(Some(p)) = poses.get(f) else {
                continue;
            };
            let e = reprojection_error(k, p, x, o);
            frames[f].observations += 1;
            if m[j] {
                if let Some((_, j)) = crate::structure::pose_jacobian(k, p, x) {
                    normal[f] += j.transpose() * j;
                }
                frames[f].inliers += 1;
                sq[f] += e * e;
                total_sq += e * e;
                total_n += 1;
            }
            if e.is_finite() {
                s += e * e;
                c += 1;
            }
        }
        track_reports.push(TrackReport {
            id: t.id,
            observations: c,
            rms: if c > 0 {
                (s / c as f64).sqrt()
            } else {
                f64::NAN
            },
        });
    }
    for (fr, s) in frames.iter_mut().zip(&sq) {
        fr.rms = if fr.inliers > 0 {
            (s / fr.inliers as f64).sqrt()
        } else {
            f64::NAN
        };
    }
    let overall_rms = if total_n > 0 {
        (total_sq / total_n as f64).sqrt()
    } else {
        f64::NAN
    };
    // σ per image coordinate: the overall RMS (a 2-D error) over √2.
    let sigma = overall_rms / std::f64::consts::SQRT_2;
    let shot = shot_rotation_sd(tracks, k, poses, points, marks, false);
    for (f, (fr, a)) in frames.iter_mut().zip(&normal).enumerate() {
        if fr.inliers >= 4 && sigma.is_finite() {
            fr.rotation_sd_deg = match &shot {
                Some(sd) => sd[f],
                None => pose_sd(a, sigma),
            };
        }
    }
    SolveReport {
        inlier_tolerance,
        overall_rms,
        points: track_reports.len(),
        frames,
        tracks: track_reports,
        stages: Vec::new(),
        fragments: Vec::new(),
        score: None,
        notes: Vec::new(),
        warnings: Vec::new(),
        rotation_only: false,
        intrinsics: Vec::new(),
        rotation_sd_basis: if shot.is_some() {
            RotationSdBasis::Shot
        } else {
            RotationSdBasis::Frame
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::structure::pose_jacobian;
    use nalgebra::{Point2, Point3};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;
    use vfxgraph_geometry::calibration::{refine_camera, IntrinsicsModel};
    use vfxgraph_geometry::camera::Camera;
    use vfxgraph_geometry::optimize::LmOptions;
    use vfxgraph_geometry::rotation::{axis_angle_to_r, r_to_axis_angle};
    use vfxgraph_geometry::synthetic::gaussian;

    /// The predicted rotation covariance matches the scatter of poses refined from noisy
    /// observations of fixed points (Monte Carlo), for points spread over the image and for
    /// points bunched in one corner (a much larger σ).
    #[test]
    fn the_rotation_sd_matches_the_scatter_of_refined_poses() {
        let k = Intrinsics::new(800.0, 800.0, 479.5, 269.5);
        let pose = Pose::new(
            axis_angle_to_r(&Vector3::new(0.1, -0.2, 0.05)),
            Vector3::new(0.3, -0.1, 5.0),
        );
        let sigma = 0.5;
        let mut sds = Vec::new();
        for (spread, seed) in [(1.0, 1u64), (0.12, 2)] {
            let mut rng = Pcg64::seed_from_u64(seed);
            let inv = pose.inverse();
            let xs: Vec<Vector3<f64>> = (0..40)
                .map(|_| {
                    let c = Vector3::new(
                        spread * rng.random_range(-2.0..2.0) + (1.0 - spread) * 1.5,
                        spread * rng.random_range(-1.2..1.2) + (1.0 - spread) * 0.9,
                        rng.random_range(4.0..7.0),
                    );
                    inv.r * c + inv.t
                })
                .collect();
            let mut a = Matrix6::zeros();
            for x in &xs {
                let (_, j) = pose_jacobian(&k, &pose, x).unwrap();
                a += j.transpose() * j;
            }
            let cov = a.try_inverse().unwrap() * (sigma * sigma);
            let predicted = cov.fixed_view::<3, 3>(0, 0).trace();
            let cam = Camera {
                intrinsics: k.clone(),
                pose: pose.clone(),
            };
            let p3: Vec<Point3<f64>> = xs.iter().map(|x| Point3::from(*x)).collect();
            let (mut sum, trials) = (0.0, 300);
            for _ in 0..trials {
                let p2: Vec<Point2<f64>> = p3
                    .iter()
                    .map(|x| {
                        let q = cam.project(x).unwrap();
                        Point2::new(
                            q.x + sigma * gaussian(&mut rng),
                            q.y + sigma * gaussian(&mut rng),
                        )
                    })
                    .collect();
                let (est, _) = refine_camera(
                    &p3,
                    &p2,
                    &cam,
                    IntrinsicsModel::Fixed(k.clone()),
                    &LmOptions::default(),
                )
                .unwrap();
                let w = r_to_axis_angle(&(est.pose.r * pose.r.transpose()));
                sum += w.norm_squared();
            }
            let measured = sum / trials as f64;
            let ratio = (measured / predicted).sqrt();
            assert!(
                (ratio - 1.0).abs() < 0.1,
                "spread {spread}: measured/predicted {ratio}"
            );
            sds.push(pose_sd(&a, sigma).unwrap());
        }
        // Bunched points determine the rotation far worse.
        assert!(sds[1] > 3.0 * sds[0], "{sds:?}");
    }
}
