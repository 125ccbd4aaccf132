//! Synthetic camera paths with known truth, and the similarity alignment that compares a solved
//! path with the truth (book §7.15: a matchmove is defined up to a similarity — the world frame,
//! orientation and scale of a solve are arbitrary, so its cameras are compared with the true
//! ones after the similarity that best maps the one onto the other).
//!
//! [`orbit_path`] is a smooth dolly/orbit around a target point: the camera centre sweeps an arc
//! of a circle about the vertical axis through the target while its distance changes linearly
//! (a dolly) and its height follows a gentle sine (a crane), always looking at the target — the
//! path a plate for tests is shot along ([`synthetic_path`]: with its intrinsics); and
//! [`project_marks`] simulates a user's clicks on known points along it. The world is y-up (the renderer's convention); camera
//! x ~ K(RX + t) looking down +z with image y down.

use nalgebra::{Matrix3, Point2, Point3, Vector3};

use crate::camera::{Camera, Intrinsics, Pose};
use crate::error::{Result, VisionError};
use crate::formats::{CameraPath, FramePose, MarkedFrame, MarkedPoints};
use crate::points::Points2d;
use crate::rotation::{nearest_rotation, rotation_angle_between};

/// An orbit/dolly around a target (module docs). Angles in degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct Orbit {
    /// The point looked at.
    pub target: Vector3<f64>,
    /// Horizontal distance from the target's vertical axis at the first frame.
    pub radius: f64,
    /// Horizontal distance at the last frame (a dolly in or out; = `radius` for a pure orbit).
    pub radius_end: f64,
    /// Camera height above the target at the first frame.
    pub height: f64,
    /// Amplitude of the height's sine over the shot (one half period).
    pub crane: f64,
    /// Azimuth of the first camera about the vertical axis (0: on +z of the target).
    pub start: f64,
    /// Azimuth swept over the shot (signed).
    pub sweep: f64,
    /// Number of frames.
    pub frames: usize,
    /// Number of the first frame.
    pub first_frame: usize,
}

/// The pose of a camera at `centre` looking at `target` with world +y up (image y down).
pub fn look_at(centre: &Vector3<f64>, target: &Vector3<f64>) -> Result<Pose> {
    let z = target - centre;
    let up = Vector3::new(0.0, 1.0, 0.0);
    let x = z.cross(&up);
    if !(z.norm() > 0.0) || !(x.norm() > 1e-9 * z.norm()) {
        return Err(VisionError::InvalidInput(
            "look_at: the camera is at the target or looks straight up or down".into(),
        ));
    }
    let z = z.normalize();
    let x = x.normalize();
    let y = z.cross(&x);
    let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    Ok(Pose::new(r, -(r * centre)))
}

/// The cameras of an [`Orbit`] with intrinsics `k` (carried by the path).
pub fn orbit_path(o: &Orbit, k: &Intrinsics) -> Result<CameraPath> {
    if o.frames == 0 {
        return Err(VisionError::InvalidInput(
            "orbit: needs at least one frame".into(),
        ));
    }
    if !(o.radius > 0.0 && o.radius_end > 0.0) {
        return Err(VisionError::InvalidInput(
            "orbit: radius and radius_end must be > 0".into(),
        ));
    }
    k.validate()?;
    let mut frames = Vec::with_capacity(o.frames);
    for i in 0..o.frames {
        let s = if o.frames > 1 {
            i as f64 / (o.frames - 1) as f64
        } else {
            0.0
        };
        // Smooth start and stop (ease in/out) so the motion has no velocity jump.
        let e = s * s * (3.0 - 2.0 * s);
        let az = (o.start + o.sweep * e).to_radians();
        let r = o.radius + (o.radius_end - o.radius) * e;
        let h = o.height + o.crane * (std::f64::consts::PI * s).sin();
        let centre = o.target + Vector3::new(r * az.sin(), h, r * az.cos());
        frames.push(FramePose {
            frame: o.first_frame + i,
            pose: look_at(&centre, &o.target)?,
            focal: None,
        });
    }
    Ok(CameraPath {
        frames,
        intrinsics: Some(k.clone()),
    })
}

/// A synthetic camera path with known truth (the `synthetic_camera_path` node's params): an
/// [`Orbit`] and the intrinsics of its cameras.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct SyntheticPathOptions {
    /// number of frames
    #[param(range = 1..=100_000)]
    pub frames: usize,
    /// number of the first frame
    #[param(range = 0..=1_099_511_627_776_u64)]
    pub first_frame: usize,
    /// the point looked at
    pub target: [f64; 3],
    /// horizontal distance to the target's axis at the first frame
    #[param(range = 1e-6..=1e9)]
    pub radius: f64,
    /// …at the last frame (a dolly)
    #[param(range = 1e-6..=1e9)]
    pub radius_end: f64,
    /// camera height above the target
    #[param(range = -1e9..=1e9)]
    pub height: f64,
    /// extra height at mid-shot (sine over the shot)
    #[param(range = -1e9..=1e9)]
    pub crane: f64,
    /// azimuth of the first camera, degrees (0: on +z of the target)
    #[param(range = -1e4..=1e4)]
    pub start: f64,
    /// azimuth swept over the shot, degrees
    #[param(range = -1e4..=1e4)]
    pub sweep: f64,
    /// focal length, pixels (f1 = f2)
    #[param(range = 1e-3..=1e7)]
    pub focal: f64,
    /// the focal length at the last frame over the first's (a zoom, eased as the motion is;
    /// 1: a prime lens)
    #[param(range = 0.01..=100.0)]
    pub zoom: f64,
    /// image width, pixels
    #[param(range = 1..=65536)]
    pub width: u32,
    /// image height, pixels
    #[param(range = 1..=65536)]
    pub height_px: u32,
}

impl Default for SyntheticPathOptions {
    fn default() -> Self {
        SyntheticPathOptions {
            frames: 40,
            first_frame: 1,
            target: [0.0; 3],
            radius: 4.0,
            radius_end: 4.0,
            height: 1.5,
            crane: 0.0,
            start: 0.0,
            sweep: 30.0,
            focal: 400.0,
            zoom: 1.0,
            width: 320,
            height_px: 240,
        }
    }
}

/// The cameras of `o`'s orbit and their intrinsics (focal `focal` px, principal point at the
/// image centre; with `zoom` ≠ 1 each frame carries its own focal length, from `focal` to
/// `zoom`·`focal` along the motion's ease).
pub fn synthetic_path(o: &SyntheticPathOptions) -> Result<(CameraPath, Intrinsics)> {
    let (w, h, f) = (o.width, o.height_px, o.focal);
    let k = Intrinsics::new(f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0).with_size(w, h);
    let orbit = Orbit {
        target: Vector3::from(o.target),
        radius: o.radius,
        radius_end: o.radius_end,
        height: o.height,
        crane: o.crane,
        start: o.start,
        sweep: o.sweep,
        frames: o.frames,
        first_frame: o.first_frame,
    };
    let mut path = orbit_path(&orbit, &k)?;
    if o.zoom != 1.0 {
        let n = path.frames.len();
        for (i, frame) in path.frames.iter_mut().enumerate() {
            let s = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.0
            };
            let e = s * s * (3.0 - 2.0 * s);
            frame.focal = Some(f * (1.0 + (o.zoom - 1.0) * e));
        }
    }
    Ok((path, k))
}

/// The options of [`project_marks`] besides its points and frames.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct ProjectMarksOptions {
    /// round to whole pixels, as a click is
    pub round: bool,
}

impl Default for ProjectMarksOptions {
    fn default() -> Self {
        ProjectMarksOptions { round: true }
    }
}

/// Simulated user clicks (book chapter 8's marked points): the scene points `coords` (x y z of
/// each in turn) projected by `path`'s cameras (with its K) into each of `frames` (whole
/// numbers), rounded to whole pixels with `o.round`. Every point must be in front of every
/// chosen camera.
pub fn project_marks(
    path: &CameraPath,
    coords: &[f64],
    frames: &[f64],
    o: &ProjectMarksOptions,
) -> Result<MarkedPoints> {
    let invalid = |m: String| VisionError::InvalidInput(m);
    if coords.is_empty() || !coords.len().is_multiple_of(3) {
        return Err(invalid(format!(
            "`points` needs x y z per point: {} numbers is not a positive multiple of 3",
            coords.len()
        )));
    }
    let points: Vec<Point3<f64>> = coords
        .chunks(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let k = path
        .intrinsics
        .clone()
        .ok_or_else(|| invalid("the camera path carries no intrinsics K".into()))?;
    let mut marks = MarkedPoints::default();
    for &f in frames {
        if !(f >= 0.0 && f.fract() == 0.0) {
            return Err(invalid(format!("`frames`: {f} is not a frame number")));
        }
        let f = f as usize;
        let pose = path
            .frames
            .iter()
            .find(|p| p.frame == f)
            .ok_or_else(|| invalid(format!("the camera path has no frame {f}")))?;
        let cam = Camera::new(k.clone(), pose.pose.r, pose.pose.t);
        let mut px = Vec::with_capacity(points.len());
        for (i, x) in points.iter().enumerate() {
            if cam.depth(x) <= 0.0 {
                return Err(invalid(format!(
                    "point {i} is behind the camera of frame {f}"
                )));
            }
            let q = cam.project(x)?;
            px.push(if o.round {
                Point2::new(q.x.round(), q.y.round())
            } else {
                q
            });
        }
        marks.frames.push(MarkedFrame {
            frame: f,
            points: Points2d(px),
        });
    }
    Ok(marks)
}

/// A similarity X ↦ s·R·X + t (from a solve's world to the truth's).
#[derive(Clone, Debug, PartialEq)]
pub struct Similarity {
    /// Scale.
    pub s: f64,
    /// Rotation.
    pub r: Matrix3<f64>,
    /// Translation.
    pub t: Vector3<f64>,
}

impl Similarity {
    /// The image of point `p`.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.s * (self.r * p.coords) + self.t)
    }

    /// The pose, in the target world, of the camera `p` of the source world (the same camera:
    /// it projects every point of the scene to the same pixel; its translation is scaled).
    pub fn apply_pose(&self, p: &Pose) -> Pose {
        let r = p.r * self.r.transpose();
        let c = self.apply(&p.center());
        Pose::new(r, -(r * c.coords))
    }
}

/// The similarity that best maps the cameras `est` onto `truth` (same length, same frames):
/// the rotation from the cameras' orientations (Rᵀ_truth·R_est summed and projected onto SO(3)),
/// then scale and translation by least squares on the camera centres.
pub fn align_poses(est: &[Pose], truth: &[Pose]) -> Result<Similarity> {
    if est.len() != truth.len() || est.len() < 2 {
        return Err(VisionError::InvalidInput(format!(
            "align: needs two paths of the same length ≥ 2, found {} and {}",
            est.len(),
            truth.len()
        )));
    }
    let mut m = Matrix3::zeros();
    for (e, g) in est.iter().zip(truth) {
        m += g.r.transpose() * e.r;
    }
    let r = nearest_rotation(&m);
    let a: Vec<Vector3<f64>> = est.iter().map(|p| r * p.center().coords).collect();
    let b: Vec<Vector3<f64>> = truth.iter().map(|p| p.center().coords).collect();
    let n = a.len() as f64;
    let ma = a.iter().sum::<Vector3<f64>>() / n;
    let mb = b.iter().sum::<Vector3<f64>>() / n;
    let num: f64 = a.iter().zip(&b).map(|(x, y)| (x - ma).dot(&(y - mb))).sum();
    let den: f64 = a.iter().map(|x| (x - ma).norm_squared()).sum();
    if !(den > 0.0) {
        return Err(VisionError::InvalidInput(
            "align: the estimated cameras all share one centre".into(),
        ));
    }
    let s = num / den;
    Ok(Similarity {
        s,
        r,
        t: mb - s * ma,
    })
}

/// Per-frame errors of `est` against `truth` after [`align_poses`]: rotation (degrees) and
/// camera centre (truth units).
pub fn aligned_pose_errors(
    est: &[Pose],
    truth: &[Pose],
) -> Result<(Similarity, Vec<f64>, Vec<f64>)> {
    let sim = align_poses(est, truth)?;
    let mut rot = Vec::with_capacity(est.len());
    let mut cen = Vec::with_capacity(est.len());
    for (e, g) in est.iter().zip(truth) {
        let a = sim.apply_pose(e);
        rot.push(rotation_angle_between(&a.r, &g.r).to_degrees());
        cen.push((a.center() - g.center()).norm());
    }
    Ok((sim, rot, cen))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::axis_angle_to_r;

    fn orbit() -> Orbit {
        Orbit {
            target: Vector3::new(0.0, 0.3, 0.0),
            radius: 4.0,
            radius_end: 3.0,
            height: 1.5,
            crane: 0.3,
            start: -20.0,
            sweep: 40.0,
            frames: 30,
            first_frame: 1,
        }
    }

    fn k() -> Intrinsics {
        Intrinsics::new(300.0, 300.0, 159.5, 119.5).with_size(320, 240)
    }

    #[test]
    fn the_orbit_looks_at_its_target_and_moves_smoothly() {
        let o = orbit();
        let path = orbit_path(&o, &k()).unwrap();
        assert_eq!(path.frames.len(), 30);
        assert_eq!(path.frames[0].frame, 1);
        assert_eq!(path.frames[29].frame, 30);
        let cam = |i: usize| crate::Camera::new(k(), path.frames[i].pose.r, path.frames[i].pose.t);
        let step =
            |i: usize| (path.frames[i + 1].pose.center() - path.frames[i].pose.center()).norm();
        for i in 0..30 {
            // The target projects to the principal point; the vertical stays vertical.
            let x = cam(i).project(&Point3::from(o.target)).unwrap();
            assert!((x.x - 159.5).abs() < 1e-9 && (x.y - 119.5).abs() < 1e-9);
            let above = cam(i)
                .project(&Point3::from(o.target + Vector3::y()))
                .unwrap();
            assert!((above.x - 159.5).abs() < 1e-9 && above.y < 119.5);
            let r = &path.frames[i].pose.r;
            assert!((r * r.transpose() - Matrix3::identity()).norm() < 1e-12);
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            if i + 2 < 30 {
                // Steps change slowly (no jumps).
                assert!((step(i + 1) - step(i)).abs() < 0.02, "{i}");
            }
        }
        // First and last centres: azimuth −20° at radius 4, +20° at radius 3.
        let c0 = path.frames[0].pose.center().coords - o.target;
        let c1 = path.frames[29].pose.center().coords - o.target;
        assert!((c0.x.hypot(c0.z) - 4.0).abs() < 1e-12 && (c1.x.hypot(c1.z) - 3.0).abs() < 1e-12);
        assert!((c0.x.atan2(c0.z).to_degrees() + 20.0).abs() < 1e-9);
        assert!((c1.x.atan2(c1.z).to_degrees() - 20.0).abs() < 1e-9);
        assert!((c0.y - 1.5).abs() < 1e-12 && (c1.y - 1.5).abs() < 1e-9);
        let mut bad = orbit();
        bad.frames = 0;
        assert!(orbit_path(&bad, &k()).is_err());
        assert!(look_at(&Vector3::new(0.0, 5.0, 0.0), &Vector3::zeros()).is_err());
    }

    #[test]
    fn a_zoom_goes_from_focal_to_zoom_times_focal_smoothly() {
        let o = SyntheticPathOptions {
            frames: 21,
            zoom: 1.5,
            ..Default::default()
        };
        let (path, k) = synthetic_path(&o).unwrap();
        assert_eq!(k.f1, 400.0);
        let f: Vec<f64> = path.frames.iter().map(|p| p.focal.unwrap()).collect();
        assert_eq!((f[0], f[20]), (400.0, 600.0));
        // Eased: monotone, slow at both ends, the middle frame halfway.
        assert!(f.windows(2).all(|w| w[1] > w[0]));
        assert!((f[10] - 500.0).abs() < 1e-9);
        assert!(f[1] - f[0] < (f[11] - f[10]) / 4.0);
        // A prime lens carries no focal length per frame.
        let (prime, _) = synthetic_path(&SyntheticPathOptions::default()).unwrap();
        assert!(prime.frames.iter().all(|p| p.focal.is_none()));
    }

    #[test]
    fn alignment_undoes_a_similarity() {
        let truth: Vec<Pose> = orbit_path(&orbit(), &k())
            .unwrap()
            .frames
            .into_iter()
            .map(|f| f.pose)
            .collect();
        // A solve in another frame: X_est = s'·R'·X + t' (the inverse of what align finds).
        let g = Similarity {
            s: 0.37,
            r: axis_angle_to_r(&Vector3::new(0.3, -1.1, 0.5)),
            t: Vector3::new(2.0, -1.0, 0.5),
        };
        let est: Vec<Pose> = truth.iter().map(|p| g.apply_pose(p)).collect();
        let (sim, rot, cen) = aligned_pose_errors(&est, &truth).unwrap();
        assert!(rot.iter().all(|e| *e < 1e-6), "{rot:?}");
        assert!(cen.iter().all(|e| *e < 1e-9), "{cen:?}");
        assert!((sim.s - 1.0 / 0.37).abs() < 1e-9);
        // A point maps back too.
        let p = Point3::new(0.4, -0.2, 1.0);
        let q = sim.apply(&g.apply(&p));
        assert!((q - p).norm() < 1e-9);
        // A projection is unchanged by moving camera and point together.
        let cam = crate::Camera::new(k(), truth[3].r, truth[3].t);
        let moved = g.apply_pose(&truth[3]);
        let cam2 = crate::Camera::new(k(), moved.r, moved.t);
        let x = Point3::new(0.1, 0.2, 0.3);
        assert!((cam.project(&x).unwrap() - cam2.project(&g.apply(&x)).unwrap()).norm() < 1e-9);
        assert!(align_poses(&est[..1], &truth[..1]).is_err());
    }
}
