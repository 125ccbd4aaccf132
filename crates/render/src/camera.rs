//! The camera: a calibrated K[R|t] with an image size (book §2.7–2.8), and the book's
//! `view{from, at, up, fov, imgw, imgh}` mapped onto it; optionally a lens distortion
//! ([`vfxgraph_lens::Distortion`], not in the book) so that a render lines up with a real,
//! distorted plate without resampling it: the primary ray of pixel position x goes through the
//! *undistorted* normalized point of K⁻¹x, and a world point X projects to K·distort(X.xy/X.z).
//! Without a lens (the default) both are the pinhole's, computed exactly as before.
//!
//! Convention of the project (ARCHITECTURE.md, "Conventions"): a world point X projects to x ~ K(RX + t); the
//! camera looks down +z of its frame, x right, y down; pixel coordinates have their origin at
//! the centre of the top-left pixel, so pixel (i, j) covers [i − ½, i + ½] × [j − ½, j + ½].

use serde::{Deserialize, Serialize};
use vfxgraph_lens::Distortion;

use crate::math::Vec3;
use crate::ray::Ray;

/// Why a camera cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    /// A number is NaN or infinite.
    #[error("camera has a non-finite entry")]
    NotFinite,
    /// K is not invertible upper-triangular with K₃₃ ≠ 0.
    #[error("K must be upper triangular with non-zero focal lengths, got {0:?}")]
    BadIntrinsics([[f64; 3]; 3]),
    /// R is not a rotation.
    #[error("R is not a rotation (RᵀR = I, det R = +1 within 1e-6)")]
    NotRotation,
    /// Zero image size.
    #[error("image size {0}×{1} must be positive")]
    BadSize(usize, usize),
    /// The lens cannot be inverted over the frame (it folds over inside it).
    #[error("camera lens: {0}")]
    BadLens(String),
    /// `from`, `at` and `up` do not define a frame.
    #[error("view: from = at, or up is parallel to the viewing direction")]
    DegenerateView,
    /// Field of view outside (0°, 180°).
    #[error("view: fov {0}° must be in (0, 180)")]
    BadFov(f64),
}

/// A calibrated camera x ~ K·distort(RX + t) with its image size (book §2.7.2, §2.8; the lens
/// is the module docs' addition).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Intrinsics K (rows), upper triangular; skew allowed.
    pub k: [[f64; 3]; 3],
    /// Rotation world → camera (rows).
    pub r: [[f64; 3]; 3],
    /// Translation: the camera maps X to RX + t.
    pub t: [f64; 3],
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// The lens on normalized coordinates ([`Distortion::None`]: a pinhole; absent in JSON).
    #[serde(default, skip_serializing_if = "Distortion::is_identity")]
    pub distortion: Distortion,
}

fn mat_vec(m: &[[f64; 3]; 3], v: Vec3) -> Vec3 {
    Vec3::new(
        m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
        m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
        m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
    )
}

fn mat_t_vec(m: &[[f64; 3]; 3], v: Vec3) -> Vec3 {
    Vec3::new(
        m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
        m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
        m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z,
    )
}

impl Camera {
    /// A camera from a calibrated K[R|t] (book §2.8: the matrix V = [R t; 0 1] and the
    /// frustum from K), checked: finite, K upper triangular and invertible, R a rotation.
    pub fn from_krt(
        k: [[f64; 3]; 3],
        r: [[f64; 3]; 3],
        t: [f64; 3],
        width: usize,
        height: usize,
    ) -> Result<Camera, CameraError> {
        let c = Camera {
            k,
            r,
            t,
            width,
            height,
            distortion: Distortion::None,
        };
        c.validate()?;
        Ok(c)
    }

    /// Checks the invariants of [`Camera::from_krt`] (for cameras that arrive deserialized).
    pub fn validate(&self) -> Result<(), CameraError> {
        let (k, r) = (&self.k, &self.r);
        if !k.iter().chain(r.iter()).flatten().all(|v| v.is_finite())
            || !self.t.iter().all(|v| v.is_finite())
        {
            return Err(CameraError::NotFinite);
        }
        if self.width == 0 || self.height == 0 {
            return Err(CameraError::BadSize(self.width, self.height));
        }
        if k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 || k[0][0] * k[1][1] * k[2][2] == 0.0
        {
            return Err(CameraError::BadIntrinsics(*k));
        }
        if !self.distortion.is_identity() {
            self.check_lens()?;
        }
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|m| r[m][i] * r[m][j]).sum();
                if (d - if i == j { 1.0 } else { 0.0 }).abs() > 1e-6 {
                    return Err(CameraError::NotRotation);
                }
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if (det - 1.0).abs() > 1e-6 {
            return Err(CameraError::NotRotation);
        }
        Ok(())
    }

    /// The same camera with a lens distortion (checked as [`Camera::validate`] does).
    pub fn with_distortion(mut self, distortion: Distortion) -> Result<Camera, CameraError> {
        self.distortion = distortion;
        self.validate()?;
        Ok(self)
    }

    /// The lens must be invertible at the frame's outer corners (pixel edges, where the ray
    /// jitter reaches) and monotonic out to 2 % beyond their largest undistorted radius, so every
    /// primary ray's Newton inverse converges.
    fn check_lens(&self) -> Result<(), CameraError> {
        let kinv = k_inverse(&self.k);
        let r = self
            .distortion
            .frame_radius(self.width as f64, self.height as f64, |[x, y]| {
                let q = mat_vec(&kinv, Vec3::new(x, y, 1.0));
                [q.x / q.z, q.y / q.z]
            })
            .map_err(|e| CameraError::BadLens(e.to_string()))?;
        self.distortion
            .check(r)
            .map_err(|e| CameraError::BadLens(e.to_string()))
    }

    /// The book's `view{from, at, up, fov, imgw, imgh}` (S3D `lookat` + `perspective`): `fov`
    /// is the HORIZONTAL field of view in degrees (S3D sets the window half-width to
    /// tan(fov/2)·near and the half-height to that over the aspect ratio), square pixels, the
    /// principal point at the image centre ((w − 1)/2, (h − 1)/2) in our pixel-centre
    /// convention; the image's up is the projection of `up`.
    pub fn look_at(
        from: Vec3,
        at: Vec3,
        up: Vec3,
        fov_deg: f64,
        width: usize,
        height: usize,
    ) -> Result<Camera, CameraError> {
        if !(from.is_finite() && at.is_finite() && up.is_finite() && fov_deg.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        if !(fov_deg > 0.0 && fov_deg < 180.0) {
            return Err(CameraError::BadFov(fov_deg));
        }
        if width == 0 || height == 0 {
            return Err(CameraError::BadSize(width, height));
        }
        let z = at - from;
        if z.length() == 0.0 {
            return Err(CameraError::DegenerateView);
        }
        let z = z.normalized();
        // Image y points down: minus the part of `up` orthogonal to z.
        let down = -(up - z * up.dot(z));
        if down.length() < 1e-12 * up.length().max(1e-300) || down.length() == 0.0 {
            return Err(CameraError::DegenerateView);
        }
        let y = down.normalized();
        let x = y.cross(z);
        let r = [[x.x, x.y, x.z], [y.x, y.y, y.z], [z.x, z.y, z.z]];
        let c = mat_vec(&r, from);
        let t = [-c.x, -c.y, -c.z];
        let f = (width as f64 / 2.0) / (fov_deg.to_radians() / 2.0).tan();
        let k = [
            [f, 0.0, (width as f64 - 1.0) / 2.0],
            [0.0, f, (height as f64 - 1.0) / 2.0],
            [0.0, 0.0, 1.0],
        ];
        Camera::from_krt(k, r, t, width, height)
    }

    /// The centre of projection −Rᵀt.
    pub fn center(&self) -> Vec3 {
        -mat_t_vec(&self.r, Vec3::from_array(self.t))
    }

    /// Projects a world point to pixel coordinates, through the lens; `None` behind the camera
    /// (or, for a division lens, beyond the radius it can image).
    pub fn project(&self, p: Vec3) -> Option<(f64, f64)> {
        let pc = mat_vec(&self.r, p) + Vec3::from_array(self.t);
        if pc.z <= 0.0 {
            return None;
        }
        if self.distortion.is_identity() {
            let x = mat_vec(&self.k, pc);
            return Some((x.x / x.z, x.y / x.z));
        }
        let q = self.distortion.distort([pc.x / pc.z, pc.y / pc.z]).ok()?;
        let x = mat_vec(&self.k, Vec3::new(q[0], q[1], 1.0));
        Some((x.x / x.z, x.y / x.z))
    }

    /// The same camera for another image size: K is rescaled so the image covers the same
    /// view (pixel-centre convention: x' + ½ = s (x + ½)).
    pub fn resized(&self, width: usize, height: usize) -> Camera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let mut k = self.k;
        // Rows of K scaled, then the half-pixel shift.
        k[0].iter_mut().for_each(|v| *v *= sx);
        k[1].iter_mut().for_each(|v| *v *= sy);
        k[0][2] += 0.5 * sx - 0.5;
        k[1][2] += 0.5 * sy - 0.5;
        Camera {
            k,
            width,
            height,
            ..self.clone()
        }
    }

    /// Precomputes what ray generation needs.
    pub fn rays(&self) -> RayGenerator {
        let kinv = k_inverse(&self.k);
        // M = Rᵀ K⁻¹
        let mut m = [[0.0; 3]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3).map(|l| self.r[l][i] * kinv[l][j]).sum();
            }
        }
        let lens = (!self.distortion.is_identity()).then(|| Lens {
            kinv,
            distortion: self.distortion,
            rt: std::array::from_fn(|i| std::array::from_fn(|j| self.r[j][i])),
        });
        RayGenerator {
            m,
            o: self.center(),
            lens,
        }
    }
}

/// Inverse of an upper-triangular K.
fn k_inverse(k: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let (a, b, c, d, e, f) = (k[0][0], k[0][1], k[0][2], k[1][1], k[1][2], k[2][2]);
    [
        [1.0 / a, -b / (a * d), (b * e - c * d) / (a * d * f)],
        [0.0, 1.0 / d, -e / (d * f)],
        [0.0, 0.0, 1.0 / f],
    ]
}

/// What a lens adds to ray generation: K⁻¹, the model and Rᵀ.
#[derive(Clone, Debug)]
struct Lens {
    kinv: [[f64; 3]; 3],
    distortion: Distortion,
    rt: [[f64; 3]; 3],
}

/// Ray generation for one camera: the world ray through a pixel position (book §2.5–2.6).
#[derive(Clone, Debug)]
pub struct RayGenerator {
    m: [[f64; 3]; 3],
    o: Vec3,
    lens: Option<Lens>,
}

impl RayGenerator {
    /// The ray through the pixel position (x, y) (pixel-centre convention; fractional positions
    /// allowed): direction Rᵀ K⁻¹ (x, y, 1), normalized; through a lens, Rᵀ (p, 1) with p the
    /// undistorted point of K⁻¹ (x, y, 1). A validated camera's lens inverts over its frame;
    /// far outside it, where Newton's method may not converge, the ray is the pinhole's.
    #[inline]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        if let Some(lens) = &self.lens {
            let q = mat_vec(&lens.kinv, Vec3::new(x, y, 1.0));
            if let Ok(p) = lens.distortion.undistort([q.x / q.z, q.y / q.z]) {
                let d = mat_vec(&lens.rt, Vec3::new(p[0], p[1], 1.0)).normalized();
                return Ray::new(self.o, d);
            }
        }
        let d = mat_vec(&self.m, Vec3::new(x, y, 1.0)).normalized();
        Ray::new(self.o, d)
    }
}

/// An image size override of a render: 0 keeps the camera's side.
#[derive(Clone, Copy, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct ImageSize {
    /// image width override (0 = the camera's; K is rescaled)
    #[param(range = 0..=65536)]
    pub width: usize,
    /// image height override (0 = the camera's)
    #[param(range = 0..=65536)]
    pub height: usize,
}

impl ImageSize {
    /// `camera` [resized](Camera::resized) when a side is set (the other keeps the camera's).
    pub fn apply(&self, camera: Camera) -> Camera {
        if self.width == 0 && self.height == 0 {
            return camera;
        }
        let w = if self.width > 0 {
            self.width
        } else {
            camera.width
        };
        let h = if self.height > 0 {
            self.height
        } else {
            camera.height
        };
        camera.resized(w, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn look_at_projects_the_target_to_the_centre_and_up_is_up() {
        let cam = Camera::look_at(
            Vec3::new(5.0, 20.0, 5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(0.0, 0.0, 1.0),
            60.0,
            640,
            480,
        )
        .unwrap();
        let (x, y) = cam.project(Vec3::new(5.0, 0.0, 5.0)).unwrap();
        assert!((x - 319.5).abs() < 1e-9 && (y - 239.5).abs() < 1e-9);
        // A point above the target is higher in the image (smaller y).
        let (_, y2) = cam.project(Vec3::new(5.0, 0.0, 6.0)).unwrap();
        assert!(y2 < y);
        // Horizontal fov: a point at the edge of the 60° cone lands on the image border.
        let half = 20.0 * (30f64).to_radians().tan();
        let (xe, _) = cam.project(Vec3::new(5.0 - half, 0.0, 5.0)).unwrap();
        assert!(
            (xe - (-0.5)).abs() < 1e-9 || (xe - 639.5).abs() < 1e-9,
            "{xe}"
        );
        assert!((cam.center() - Vec3::new(5.0, 20.0, 5.0)).length() < 1e-12);
    }

    #[test]
    fn rays_invert_projection_for_a_general_krt() {
        let (a, b) = (0.3f64, -0.7f64);
        let r = [
            [a.cos(), 0.0, a.sin()],
            [0.0, 1.0, 0.0],
            [-a.sin(), 0.0, a.cos()],
        ];
        let rb = [
            [1.0, 0.0, 0.0],
            [0.0, b.cos(), -b.sin()],
            [0.0, b.sin(), b.cos()],
        ];
        let mut rr = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                rr[i][j] = (0..3).map(|l| r[i][l] * rb[l][j]).sum();
            }
        }
        let k = [[1228.4, 2.0, 639.5], [0.0, 1220.0, 359.5], [0.0, 0.0, 1.0]];
        let cam = Camera::from_krt(k, rr, [0.5, -1.0, 3.0], 1280, 720).unwrap();
        let gen = cam.rays();
        for (x, y) in [(0.0, 0.0), (100.25, 600.5), (1279.0, 719.0)] {
            let ray = gen.ray(x, y);
            let p = ray.at(7.3);
            let (px, py) = cam.project(p).unwrap();
            assert!((px - x).abs() < 1e-7 && (py - y).abs() < 1e-7, "{px} {py}");
        }
    }

    #[test]
    fn resizing_keeps_the_view() {
        let cam = Camera::look_at(
            Vec3::ZERO,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            90.0,
            64,
            48,
        )
        .unwrap();
        let small = cam.resized(32, 24);
        let p = Vec3::new(0.3, 2.0, -0.4);
        let (x, y) = cam.project(p).unwrap();
        let (xs, ys) = small.project(p).unwrap();
        assert!(((xs + 0.5) * 2.0 - (x + 0.5)).abs() < 1e-9);
        assert!(((ys + 0.5) * 2.0 - (y + 0.5)).abs() < 1e-9);
    }

    #[test]
    fn bad_cameras_are_errors() {
        let up = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(
            Camera::look_at(Vec3::ZERO, Vec3::ZERO, up, 60.0, 4, 4),
            Err(CameraError::DegenerateView)
        );
        assert_eq!(
            Camera::look_at(Vec3::ZERO, up, up, 60.0, 4, 4),
            Err(CameraError::DegenerateView)
        );
        assert!(Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), up, 180.0, 4, 4).is_err());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), up, f64::NAN, 4, 4).is_err());
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut flip = id;
        flip[2][2] = -1.0;
        assert_eq!(
            Camera::from_krt(id, flip, [0.0; 3], 4, 4),
            Err(CameraError::NotRotation)
        );
        let mut k = id;
        k[0][0] = 0.0;
        assert!(Camera::from_krt(k, id, [0.0; 3], 4, 4).is_err());
        assert!(Camera::from_krt(id, id, [0.0; 3], 0, 4).is_err());
    }
}
