//! Deterministic synthetic "video-like" bundle adjustment problems: a camera moving along a
//! smooth path, points tracked over a window of consecutive frames (as a KLT tracker gives,
//! book 7.11), Gaussian pixel noise and a fraction of gross outliers. Used by the tests (noise
//! floor σ·√(1 − params/residuals), Hartley & Zisserman 5.1.3) and by the Ceres benchmark.

use nalgebra::{Matrix3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::camera_model::Intrinsics;
use super::problem::{CameraPose, Gauge, Observation, Point, Problem};
use super::rotation::{angle_axis_to_matrix, matrix_to_angle_axis};

type PoseMap = Box<dyn Fn(&Matrix3<f64>, &Vector3<f64>) -> (Matrix3<f64>, Vector3<f64>)>;

/// Which camera model the generated problem uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyntheticModel {
    /// The project's pinhole, one shared fixed intrinsics block, gauge fixed
    /// ([`Gauge::FixFirstCameraAndScale`]).
    Pinhole,
    /// BAL: per-camera free `[f, k1, k2]`, everything free (as Ceres' bundle_adjuster).
    Bal,
}

/// Parameters of [`video_like`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VideoConfig {
    /// Number of frames (cameras).
    pub cameras: usize,
    /// Number of tracked points.
    pub points: usize,
    /// Track length range in frames (inclusive).
    pub track_length: (usize, usize),
    /// Standard deviation of the pixel noise per coordinate.
    pub noise_px: f64,
    /// Fraction of observations replaced by gross outliers (10–60 px off).
    pub outlier_fraction: f64,
    /// Focal length in pixels.
    pub focal: f64,
    /// Image size in pixels.
    pub size: (f64, f64),
    /// Std. dev. of the initial rotation error (radians), translation error and point error
    /// (scene units; depths are 4–12).
    pub perturbation: (f64, f64, f64),
    /// Camera model.
    pub model: SyntheticModel,
    /// PCG seed.
    pub seed: u64,
}

impl Default for VideoConfig {
    fn default() -> Self {
        VideoConfig {
            cameras: 50,
            points: 2000,
            track_length: (6, 20),
            noise_px: 0.5,
            outlier_fraction: 0.0,
            focal: 800.0,
            size: (1280.0, 720.0),
            perturbation: (0.002, 0.02, 0.05),
            model: SyntheticModel::Pinhole,
            seed: 1,
        }
    }
}

/// A generated problem with its ground truth.
#[derive(Debug, Clone)]
pub struct SyntheticProblem {
    /// The perturbed problem to solve.
    pub problem: Problem,
    /// Ground-truth cameras and points (same observations).
    pub truth: Problem,
    /// Which observations are gross outliers.
    pub outliers: Vec<bool>,
}

fn gauss(rng: &mut Pcg64Mcg) -> f64 {
    // Box–Muller.
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn gauss3(rng: &mut Pcg64Mcg, s: f64) -> Vector3<f64> {
    Vector3::new(gauss(rng) * s, gauss(rng) * s, gauss(rng) * s)
}

/// Generates a video-like problem (deterministic for a given config).
pub fn video_like(cfg: &VideoConfig) -> SyntheticProblem {
    let mut rng = Pcg64Mcg::seed_from_u64(cfg.seed);
    let n = cfg.cameras.max(2);
    let (w, h) = cfg.size;
    let (cx, cy) = ((w - 1.0) / 2.0, (h - 1.0) / 2.0);
    // Camera path: a dolly along x with gentle sway, yaw and pitch oscillations.
    let mut poses = Vec::with_capacity(n);
    for i in 0..n {
        let s = i as f64;
        let centre = Vector3::new(0.05 * s, 0.3 * (s / 40.0).sin(), 0.4 * (s / 55.0).sin());
        let omega = Vector3::new(
            0.05 * (s / 35.0).sin(),
            0.15 * (s / 60.0).sin(),
            0.02 * (s / 25.0).cos(),
        );
        let r = angle_axis_to_matrix(&omega);
        poses.push((r, -(r * centre)));
    }
    let project = |r: &Matrix3<f64>, t: &Vector3<f64>, x: &Vector3<f64>| {
        let p = r * x + t;
        (
            p.z,
            Vector2::new(cfg.focal * p.x / p.z + cx, cfg.focal * p.y / p.z + cy),
        )
    };
    let inside = |q: &Vector2<f64>| q.x >= 0.0 && q.y >= 0.0 && q.x <= w - 1.0 && q.y <= h - 1.0;

    let mut points = Vec::with_capacity(cfg.points);
    let mut observations = Vec::new();
    let mut outliers = Vec::new();
    let (lmin, lmax) = (
        cfg.track_length.0.max(2),
        cfg.track_length.1.max(cfg.track_length.0.max(2)),
    );
    while points.len() < cfg.points {
        let len = rng.random_range(lmin..=lmax).min(n);
        let first = rng.random_range(0..=n - len);
        let mid = first + len / 2;
        // A point seen near the image centre region of the middle frame.
        let depth = rng.random_range(4.0..12.0);
        let q = Vector2::new(
            rng.random_range(0.1 * w..0.9 * w),
            rng.random_range(0.1 * h..0.9 * h),
        );
        let ray = Vector3::new((q.x - cx) / cfg.focal, (q.y - cy) / cfg.focal, 1.0) * depth;
        let (r, t) = &poses[mid];
        let x = r.transpose() * (ray - t);
        let mut obs = Vec::new();
        for (f, (r, t)) in poses.iter().enumerate().skip(first).take(len) {
            let (z, q) = project(r, t, &x);
            if z > 0.5 && inside(&q) {
                obs.push((f, q));
            }
        }
        if obs.len() < 2 {
            continue;
        }
        let pi = points.len();
        points.push(x);
        for (f, q) in obs {
            let outlier = rng.random::<f64>() < cfg.outlier_fraction;
            let noisy = if outlier {
                let mag = rng.random_range(10.0..60.0);
                let ang = rng.random_range(0.0..std::f64::consts::TAU);
                q + Vector2::new(mag * ang.cos(), mag * ang.sin())
            } else {
                q + Vector2::new(
                    gauss(&mut rng) * cfg.noise_px,
                    gauss(&mut rng) * cfg.noise_px,
                )
            };
            observations.push(Observation {
                camera: f,
                point: pi,
                pixel: noisy,
                weight: 1.0,
            });
            outliers.push(outlier);
        }
    }

    // Express in the requested model.
    let flip = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let (pose_of, intrinsics, gauge): (PoseMap, Vec<Intrinsics>, Gauge) = match cfg.model {
        SyntheticModel::Pinhole => (
            Box::new(|r, t| (*r, *t)),
            vec![Intrinsics::pinhole(cfg.focal, cx, cy, true)],
            Gauge::FixFirstCameraAndScale,
        ),
        SyntheticModel::Bal => (
            // P' = diag(1,−1,−1)·P turns "+z forward, y down" into BAL's "−z forward, y up".
            Box::new(move |r, t| (flip * r, flip * t)),
            (0..n)
                .map(|_| Intrinsics::bal(cfg.focal, 0.0, 0.0, false))
                .collect(),
            Gauge::Free,
        ),
    };
    if cfg.model == SyntheticModel::Bal {
        for o in observations.iter_mut() {
            o.pixel = Vector2::new(o.pixel.x - cx, -(o.pixel.y - cy));
        }
    }
    let truth_cams: Vec<CameraPose> = poses
        .iter()
        .enumerate()
        .map(|(i, (r, t))| {
            let (r, t) = pose_of(r, t);
            CameraPose {
                rotation: matrix_to_angle_axis(&r),
                translation: t,
                intrinsics: if cfg.model == SyntheticModel::Bal {
                    i
                } else {
                    0
                },
                fixed: false,
            }
        })
        .collect();
    let truth = Problem {
        cameras: truth_cams,
        intrinsics,
        points: points
            .iter()
            .map(|x| Point {
                position: *x,
                fixed: false,
            })
            .collect(),
        observations,
        gauge,
        priors: Vec::new(),
    };
    let mut problem = truth.clone();
    let (sr, st, sp) = cfg.perturbation;
    for (i, c) in problem.cameras.iter_mut().enumerate() {
        if i == 0 && gauge == Gauge::FixFirstCameraAndScale {
            continue;
        }
        let r = angle_axis_to_matrix(&gauss3(&mut rng, sr)) * angle_axis_to_matrix(&c.rotation);
        c.rotation = matrix_to_angle_axis(&r);
        c.translation += gauss3(&mut rng, st);
    }
    for p in problem.points.iter_mut() {
        p.position += gauss3(&mut rng, sp);
    }
    SyntheticProblem {
        problem,
        truth,
        outliers,
    }
}
