//! Bundle adjustment of a tracked sequence (book §7.7): a camera path, a point cloud whose points
//! name their feature tracks, the tracks, and shared intrinsics K, turned into a [`Problem`],
//! solved, and turned back. This is what the `bundle_adjust` node and the matchmove stages call.

use std::collections::HashMap;

use nalgebra::{Vector2, Vector3};
use vfxgraph_params::{Choice, Options};

use super::camera_model::{CameraModel, Intrinsics};
use super::error::BundleError;
use super::linear_solver::LinearSolverKind;
use super::lm::{solve, SolverOptions};
use super::loss::RobustLoss;
use super::problem::{CameraPose, Gauge, Observation, Point, Problem};
use super::report::SolverReport;
use vfxgraph_geometry::camera::Pose;
use vfxgraph_geometry::formats::cameras::{CameraPath, FramePose};
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_klt::Tracks;

/// The linear solver by the short names of the `bundle_adjust` node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Choice)]
pub enum SolverChoice {
    /// [`LinearSolverKind::Auto`].
    Auto,
    /// [`LinearSolverKind::DenseSchur`].
    Dense,
    /// [`LinearSolverKind::SparseSchur`].
    Sparse,
    /// [`LinearSolverKind::IterativeSchur`].
    Iterative,
}

/// The options of [`adjust_sequence`], as the `bundle_adjust` node declares them.
#[derive(Debug, PartialEq, Options)]
pub struct SequenceAdjustOptions {
    /// robust loss on the reprojection error
    pub loss: RobustLoss,
    /// where the robust loss starts to down-weight (pixels)
    #[param(range = 1e-6..=1e6)]
    pub loss_scale_px: f64,
    /// cap on Levenberg–Marquardt steps
    #[param(range = 0..=10_000)]
    pub max_iterations: usize,
    /// also refine f and the principal point (one block shared by all frames)
    pub refine_intrinsics: bool,
    /// linear solver of the reduced camera system
    pub solver: SolverChoice,
}

impl Default for SequenceAdjustOptions {
    fn default() -> Self {
        SequenceAdjustOptions {
            loss: RobustLoss::Huber,
            loss_scale_px: 2.0,
            max_iterations: 50,
            refine_intrinsics: false,
            solver: SolverChoice::Auto,
        }
    }
}

impl SequenceAdjustOptions {
    /// The solver's options.
    pub fn solver_options(&self) -> SolverOptions {
        SolverOptions {
            max_iterations: self.max_iterations,
            loss: self.loss.at(self.loss_scale_px),
            linear_solver: match self.solver {
                SolverChoice::Auto => LinearSolverKind::Auto,
                SolverChoice::Dense => LinearSolverKind::DenseSchur,
                SolverChoice::Sparse => LinearSolverKind::SparseSchur,
                SolverChoice::Iterative => LinearSolverKind::IterativeSchur,
            },
            ..SolverOptions::default()
        }
    }
}

/// What [`adjust_sequence`] returns.
#[derive(Clone, Debug)]
pub struct AdjustedSequence {
    /// The refined path (same frames, same order).
    pub path: CameraPath,
    /// The refined cloud (same points, errors filled in).
    pub cloud: PointCloud,
    /// The refined intrinsics (unchanged unless refined).
    pub intrinsics: vfxgraph_geometry::Intrinsics,
    /// The solver's report.
    pub report: SolverReport,
}

/// Bundle-adjusts `path` and `cloud` against the observations in `tracks`. Frames of `tracks`
/// without a camera in `path`, and tracks without a point in `cloud`, are ignored. The gauge is
/// fixed by the first camera and the scale of the first baseline. With `refine_intrinsics`, one
/// shared (f, u0, v0) block is refined; the aspect ratio f2/f1 and the skew stay as given.
pub fn adjust_sequence(
    path: &CameraPath,
    cloud: &PointCloud,
    tracks: &Tracks,
    k: &vfxgraph_geometry::Intrinsics,
    refine_intrinsics: bool,
    options: &SolverOptions,
) -> Result<AdjustedSequence, BundleError> {
    if cloud.points.len() != cloud.track_ids.len() {
        return Err(BundleError::InvalidProblem(format!(
            "point cloud has {} points but {} track ids",
            cloud.points.len(),
            cloud.track_ids.len()
        )));
    }
    if !(k.f1 > 0.0 && k.f1.is_finite()) {
        return Err(BundleError::InvalidProblem(format!(
            "focal length {} is not positive",
            k.f1
        )));
    }
    let mut intrinsics = Intrinsics::pinhole(k.f1, k.u0, k.v0, !refine_intrinsics);
    intrinsics.model = CameraModel::Pinhole {
        aspect: k.f2 / k.f1,
        skew: k.s,
    };
    let cameras: Vec<CameraPose> = path
        .frames
        .iter()
        .map(|f| CameraPose::from_rt(&f.pose.r, &f.pose.t, 0))
        .collect();
    let camera_of_frame: HashMap<i64, usize> = path
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| (f.frame as i64, i))
        .collect();
    let point_of_track: HashMap<u64, usize> = cloud
        .track_ids
        .iter()
        .enumerate()
        .map(|(i, id)| (*id, i))
        .collect();
    let points: Vec<Point> = cloud
        .points
        .iter()
        .map(|p| Point {
            position: Vector3::new(p[0], p[1], p[2]),
            fixed: false,
        })
        .collect();
    let mut observations = Vec::new();
    for t in &tracks.tracks {
        let Some(&point) = point_of_track.get(&t.id) else {
            continue;
        };
        for (k, xy) in t.points.iter().enumerate() {
            let Some(&frame) = tracks.frames.get(t.first + k) else {
                continue;
            };
            if let Some(&camera) = camera_of_frame.get(&frame) {
                observations.push(Observation {
                    camera,
                    point,
                    pixel: Vector2::new(xy[0], xy[1]),
                    weight: 1.0,
                });
            }
        }
    }
    let mut problem = Problem {
        cameras,
        intrinsics: vec![intrinsics],
        points,
        observations,
        gauge: if path.frames.len() > 1 {
            Gauge::FixFirstCameraAndScale
        } else {
            Gauge::Free
        },
        priors: Vec::new(),
    };
    let report = solve(&mut problem, options)?;
    let [f, u0, v0, ..] = problem.intrinsics[0].params;
    let mut k_out = k.clone();
    k_out.f2 = f * k.f2 / k.f1;
    k_out.f1 = f;
    k_out.u0 = u0;
    k_out.v0 = v0;
    let out_path = CameraPath {
        frames: path
            .frames
            .iter()
            .zip(&problem.cameras)
            .map(|(f, c)| FramePose {
                frame: f.frame,
                pose: Pose {
                    r: c.rotation_matrix(),
                    t: c.translation,
                },
                focal: None,
            })
            .collect(),
        intrinsics: Some(k_out.clone()),
    };
    let out_cloud = PointCloud {
        points: problem
            .points
            .iter()
            .map(|p| [p.position.x, p.position.y, p.position.z])
            .collect(),
        track_ids: cloud.track_ids.clone(),
        errors: report.point_rms.clone(),
        // Every observation was adjusted: no outlier decision.
        inlier_frames: Vec::new(),
    };
    Ok(AdjustedSequence {
        path: out_path,
        cloud: out_cloud,
        intrinsics: k_out,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;
    use vfxgraph_geometry::synthetic::gaussian;
    use vfxgraph_klt::Track;

    /// A camera moving along x looking at points ahead, tracks from projections with 0.5 px
    /// noise; poses and points perturbed; BA must return to the noise floor.
    #[test]
    fn sequence_returns_to_the_noise_floor() {
        let mut rng = Pcg64::seed_from_u64(3);
        let k = vfxgraph_geometry::Intrinsics::new(800.0, 800.0, 320.0, 240.0);
        let n_frames = 12;
        let truth: Vec<Pose> = (0..n_frames)
            .map(|i| {
                let c = Vector3::new(0.1 * i as f64, 0.0, 0.0);
                let r = vfxgraph_geometry::rotation::axis_angle_to_r(&Vector3::new(
                    0.0,
                    0.01 * i as f64,
                    0.0,
                ));
                Pose { r, t: -(r * c) }
            })
            .collect();
        let world: Vec<Vector3<f64>> = (0..150)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-2.0..3.0),
                    rng.random_range(-1.5..1.5),
                    rng.random_range(4.0..8.0),
                )
            })
            .collect();
        let sigma = 0.5;
        let tracks = Tracks {
            frames: (0..n_frames as i64).collect(),
            slots: world.len(),
            image_size: None,
            tracks: world
                .iter()
                .enumerate()
                .map(|(id, x)| Track {
                    id: id as u64,
                    slot: id,
                    first: 0,
                    points: truth
                        .iter()
                        .map(|p| {
                            let c = p.r * x + p.t;
                            [
                                k.f1 * c.x / c.z + k.u0 + sigma * gaussian(&mut rng),
                                k.f2 * c.y / c.z + k.v0 + sigma * gaussian(&mut rng),
                            ]
                        })
                        .collect(),
                    lost: None,
                })
                .collect(),
        };
        let path = CameraPath {
            frames: truth
                .iter()
                .enumerate()
                .map(|(i, p)| FramePose {
                    frame: i,
                    pose: if i == 0 {
                        p.clone()
                    } else {
                        Pose {
                            r: vfxgraph_geometry::rotation::axis_angle_to_r(&Vector3::new(
                                0.01, -0.01, 0.005,
                            )) * p.r,
                            t: p.t + Vector3::new(0.02, -0.01, 0.01),
                        }
                    },
                    focal: None,
                })
                .collect(),
            intrinsics: None,
        };
        let cloud = PointCloud {
            points: world
                .iter()
                .map(|x| [x.x + 0.05, x.y - 0.05, x.z + 0.1])
                .collect(),
            track_ids: (0..world.len() as u64).collect(),
            errors: vec![],
            ..Default::default()
        };
        let out =
            adjust_sequence(&path, &cloud, &tracks, &k, false, &SolverOptions::default()).unwrap();
        let obs = (n_frames * world.len()) as f64;
        let params = ((n_frames - 1) * 6 - 1 + world.len() * 3) as f64;
        let floor = sigma * (1.0 - params / (2.0 * obs)).sqrt();
        // RMS per coordinate.
        let rms = (2.0 * out.report.final_cost / (2.0 * obs)).sqrt();
        assert!(
            out.report.initial_rms > 5.0,
            "perturbed start {}",
            out.report.initial_rms
        );
        assert!(
            (rms - floor).abs() < 0.05 * floor,
            "rms {rms} vs floor {floor}"
        );
        assert_eq!(out.cloud.errors.len(), world.len());
        assert_eq!(out.path.frames.len(), n_frames);
        // Mismatched cloud is a typed error.
        let bad = PointCloud {
            points: cloud.points.clone(),
            track_ids: vec![0],
            errors: vec![],
            ..Default::default()
        };
        assert!(
            adjust_sequence(&path, &bad, &tracks, &k, false, &SolverOptions::default()).is_err()
        );
    }
}
