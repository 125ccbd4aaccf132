//! Synthetic scenes with known ground truth, shared by the tests and the benchmarks: random
//! cameras, 3D points in front of them, Gaussian pixel noise and gross outliers. All randomness
//! comes from the caller's generator.

use nalgebra::{Matrix3, Point2, Point3, Vector3};
use rand::Rng;

use crate::camera::{Camera, Intrinsics, Pose};
use crate::rotation::axis_angle_to_r;
use crate::two_view::fundamental_from_pose;

/// Image width of the synthetic cameras.
pub const WIDTH: u32 = 1280;
/// Image height of the synthetic cameras.
pub const HEIGHT: u32 = 720;

/// A standard normal sample (Box–Muller).
pub fn gaussian<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A uniformly distributed rotation axis with an angle in [0, max_angle].
pub fn random_rotation<R: Rng + ?Sized>(rng: &mut R, max_angle: f64) -> nalgebra::Matrix3<f64> {
    let axis = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)).normalize();
    axis_angle_to_r(&(axis * rng.random_range(0.0..max_angle)))
}

/// Random intrinsics of a 1280×720 camera: f1 ∈ [800, 1600], f2 = f1(1 ± 2 %), s = 0, principal
/// point within 30 px of the image centre.
pub fn random_intrinsics<R: Rng + ?Sized>(rng: &mut R) -> Intrinsics {
    let f1 = rng.random_range(800.0..1600.0);
    let f2 = f1 * rng.random_range(0.98..1.02);
    let u0 = 639.5 + rng.random_range(-30.0..30.0);
    let v0 = 359.5 + rng.random_range(-30.0..30.0);
    Intrinsics::new(f1, f2, u0, v0).with_size(WIDTH, HEIGHT)
}

/// A random camera looking at the world origin from a distance in [4, 8].
pub fn random_camera<R: Rng + ?Sized>(rng: &mut R) -> Camera {
    let k = random_intrinsics(rng);
    let r = random_rotation(rng, std::f64::consts::PI);
    let t = Vector3::new(
        rng.random_range(-0.3..0.3),
        rng.random_range(-0.3..0.3),
        rng.random_range(4.0..8.0),
    );
    Camera::new(k, r, t)
}

/// `n` points uniform in the cube [−1, 1]³ that project inside the image of `camera` with
/// depth > 0.5.
pub fn random_points_in_front<R: Rng + ?Sized>(
    camera: &Camera,
    n: usize,
    rng: &mut R,
) -> Vec<Point3<f64>> {
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let p = Point3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if visible(camera, &p) {
            out.push(p);
        }
    }
    out
}

/// `n` points filling the view frustum of `camera`: uniform pixels, depth uniform in
/// [`near`, `far`] (a calibration object with strong perspective).
pub fn random_points_in_frustum<R: Rng + ?Sized>(
    camera: &Camera,
    n: usize,
    near: f64,
    far: f64,
    rng: &mut R,
) -> Vec<Point3<f64>> {
    let k = &camera.intrinsics;
    let inv = camera.pose.inverse();
    (0..n)
        .map(|_| {
            let x = Point2::new(
                rng.random_range(0.0..WIDTH as f64 - 1.0),
                rng.random_range(0.0..HEIGHT as f64 - 1.0),
            );
            let d = rng.random_range(near..far);
            let xc = k.unproject(&x) * d;
            Point3::from(inv.transform(&Point3::from(xc)))
        })
        .collect()
}

/// True when `p` is at depth > 0.5 and projects inside the image.
pub fn visible(camera: &Camera, p: &Point3<f64>) -> bool {
    if camera.depth(p) <= 0.5 {
        return false;
    }
    match camera.project(p) {
        Ok(x) => {
            x.x >= 0.0 && x.y >= 0.0 && x.x <= WIDTH as f64 - 1.0 && x.y <= HEIGHT as f64 - 1.0
        }
        Err(_) => false,
    }
}

/// Project `points` and add Gaussian noise of standard deviation `sigma` pixels; then replace a
/// fraction `outlier_ratio` of them (the first ones after a shuffle) by uniform random pixels.
/// Returns the observations and the true outlier flags.
pub fn observe<R: Rng + ?Sized>(
    camera: &Camera,
    points: &[Point3<f64>],
    sigma: f64,
    outlier_ratio: f64,
    rng: &mut R,
) -> (Vec<Point2<f64>>, Vec<bool>) {
    let mut obs: Vec<Point2<f64>> = points
        .iter()
        .map(|p| {
            let x = camera.project(p).unwrap_or(Point2::origin());
            Point2::new(x.x + sigma * gaussian(rng), x.y + sigma * gaussian(rng))
        })
        .collect();
    let n_out = (outlier_ratio * points.len() as f64).round() as usize;
    let idx = rand::seq::index::sample(rng, points.len(), n_out.min(points.len()));
    let mut outlier = vec![false; points.len()];
    for i in idx {
        // Displace by at least 20 px so that an outlier is a gross error.
        loop {
            let x = Point2::new(
                rng.random_range(0.0..WIDTH as f64),
                rng.random_range(0.0..HEIGHT as f64),
            );
            if (x - obs[i]).norm() > 20.0 {
                obs[i] = x;
                break;
            }
        }
        outlier[i] = true;
    }
    (obs, outlier)
}

/// Two cameras sharing K, 3D points seen by both, and their noisy observations.
#[derive(Clone, Debug)]
pub struct TwoViewScene {
    /// Shared intrinsics.
    pub k: Intrinsics,
    /// Pose of camera B (camera A is [I|0]).
    pub pose_b: Pose,
    /// The 3D points.
    pub points: Vec<Point3<f64>>,
    /// Observations in A.
    pub a: Vec<Point2<f64>>,
    /// Observations in B.
    pub b: Vec<Point2<f64>>,
    /// True outlier flags.
    pub outlier: Vec<bool>,
}

impl TwoViewScene {
    /// Camera A.
    pub fn camera_a(&self) -> Camera {
        Camera::new(self.k.clone(), Matrix3::identity(), Vector3::zeros())
    }
    /// Camera B.
    pub fn camera_b(&self) -> Camera {
        Camera {
            intrinsics: self.k.clone(),
            pose: self.pose_b.clone(),
        }
    }
    /// The true F.
    pub fn fundamental(&self) -> Matrix3<f64> {
        fundamental_from_pose(&self.k, &self.k, &self.pose_b)
    }
}

/// A random scene: camera A at the origin, points at depth 3–10 in A's view, camera B moved
/// by a baseline of length `baseline` in a random direction and turned by up to 15° so that
/// it still sees the points; noise `sigma` px; a fraction `outliers` of matches in B replaced
/// by random pixels.
pub fn two_view_scene_with<R: Rng + ?Sized>(
    rng: &mut R,
    n: usize,
    sigma: f64,
    outliers: f64,
    baseline: f64,
) -> TwoViewScene {
    let k = random_intrinsics(rng);
    let cam_a = Camera::new(k.clone(), Matrix3::identity(), Vector3::zeros());
    let dir = Vector3::new(gaussian(rng), 0.3 * gaussian(rng), 0.3 * gaussian(rng)).normalize();
    let c_b = dir * baseline;
    // Look roughly at the centre of the point cloud (depth 6).
    let target = Vector3::new(0.0, 0.0, 6.0);
    let z = (target - c_b).normalize();
    let x = Vector3::y().cross(&z).normalize();
    let y = z.cross(&x);
    let look = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let r = random_rotation(rng, 5f64.to_radians()) * look;
    let pose_b = Pose::new(r, -(r * c_b));
    let cam_b = Camera {
        intrinsics: k.clone(),
        pose: pose_b.clone(),
    };
    let mut points = Vec::new();
    while points.len() < n {
        let px = Point2::new(rng.random_range(0.0..1279.0), rng.random_range(0.0..719.0));
        let p = Point3::from(k.unproject(&px) * rng.random_range(3.0..10.0));
        if crate::synthetic::visible(&cam_b, &p) {
            points.push(p);
        }
    }
    let (a, _) = observe(&cam_a, &points, sigma, 0.0, rng);
    let (b, outlier) = observe(&cam_b, &points, sigma, outliers, rng);
    TwoViewScene {
        k,
        pose_b,
        points,
        a,
        b,
        outlier,
    }
}
