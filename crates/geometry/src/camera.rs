//! The camera model of chapter 2: K (f1, f2, s, u0, v0), [R|t], P = K[R|t] (§2.7), projection,
//! camera centre, change of reference (the book's `calib_change_ref`, §7.12) and the mapping of a
//! calibrated camera to a render camera's frustum (§2.8).
//!
//! Conventions (ARCHITECTURE.md, Conventions): a world point X maps to x ~ K(RX + t); the camera looks down +z;
//! pixel coordinates have their origin at the centre of the top-left pixel, x right, y down.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, VisionError};
use crate::lens::Distortion;

/// Relative depth below which a point is said to lie on a camera's principal plane.
const MIN_DEPTH: f64 = 1e-12;

/// Intrinsic parameters K = [[f1, s, u0], [0, f2, v0], [0, 0, 1]] (book eq. 4.18), the lens's
/// distortion (an addition to the book's ideal pinhole, [`crate::lens`]) and the image size
/// when known. A camera-frame point X maps to the pixel K·d(X.xy / X.z), d the distortion.
///
/// JSON form: `{"K": [[..],[..],[..]], "width": W?, "height": H?, "distortion": {..}?}` (rows
/// first; `distortion` is absent for a pinhole, so a pinhole's JSON is the book's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "IntrinsicsJson", into = "IntrinsicsJson")]
pub struct Intrinsics {
    /// Horizontal focal length in pixels.
    pub f1: f64,
    /// Vertical focal length in pixels.
    pub f2: f64,
    /// Skew.
    pub s: f64,
    /// Principal point, x.
    pub u0: f64,
    /// Principal point, y.
    pub v0: f64,
    /// Image width in pixels, when known.
    pub width: Option<u32>,
    /// Image height in pixels, when known.
    pub height: Option<u32>,
    /// The lens's distortion on normalized coordinates ([`Distortion::None`]: a pinhole).
    pub distortion: Distortion,
}

impl Intrinsics {
    /// Intrinsics with zero skew and unknown image size.
    pub fn new(f1: f64, f2: f64, u0: f64, v0: f64) -> Self {
        Intrinsics {
            f1,
            f2,
            s: 0.0,
            u0,
            v0,
            width: None,
            height: None,
            distortion: Distortion::None,
        }
    }

    /// The same intrinsics with an image size.
    pub fn with_size(mut self, width: u32, height: u32) -> Self {
        self.width = Some(width);
        self.height = Some(height);
        self
    }

    /// The same intrinsics with a lens distortion.
    pub fn with_distortion(mut self, distortion: Distortion) -> Self {
        self.distortion = distortion;
        self
    }

    /// The same intrinsics as an ideal pinhole (K and size kept, no distortion).
    pub fn pinhole(&self) -> Self {
        Intrinsics {
            distortion: Distortion::None,
            ..self.clone()
        }
    }

    /// Whether the lens is an ideal pinhole.
    pub fn is_pinhole(&self) -> bool {
        self.distortion.is_identity()
    }

    /// Check that every parameter is finite and both focal lengths are non-zero, and — when
    /// the image size is known — that the distortion is invertible over the whole frame
    /// ([`Distortion::check`] out to the farthest corner).
    pub fn validate(&self) -> Result<()> {
        let v = [self.f1, self.f2, self.s, self.u0, self.v0];
        if v.iter().any(|x| !x.is_finite()) || self.f1 == 0.0 || self.f2 == 0.0 {
            return Err(VisionError::InvalidInput(format!(
                "intrinsics must be finite with non-zero focal lengths: {v:?}"
            )));
        }
        if !self.is_pinhole() {
            if self.distortion.params().iter().any(|p| !p.is_finite()) {
                return Err(VisionError::InvalidInput(format!(
                    "the lens distortion has a non-finite coefficient: {:?}",
                    self.distortion
                )));
            }
            if let Some(r) = self.undistorted_corner_radius()? {
                self.distortion.check(r)?;
            }
        }
        Ok(())
    }

    /// The largest undistorted normalized radius of the frame's corners (a little beyond), when
    /// the image size is known; an error when the lens cannot be inverted at a corner.
    pub fn undistorted_corner_radius(&self) -> Result<Option<f64>> {
        let (Some(w), Some(h)) = (self.width, self.height) else {
            return Ok(None);
        };
        let kinv = self.k_inv();
        let r = self
            .distortion
            .frame_radius(w as f64, h as f64, |[x, y]| {
                let q = kinv * Vector3::new(x, y, 1.0);
                [q.x / q.z, q.y / q.z]
            })
            .map_err(|e| VisionError::InvalidInput(e.to_string()))?;
        Ok(Some(r))
    }

    /// The pixel where the lens images the undistorted normalized point `p` (= X.xy / X.z).
    pub fn pixel_of_normalized(&self, p: [f64; 2]) -> Result<Point2<f64>> {
        let q = self.distortion.distort(p)?;
        Ok(Point2::new(
            self.f1 * q[0] + self.s * q[1] + self.u0,
            self.f2 * q[1] + self.v0,
        ))
    }

    /// The undistorted normalized point (ray direction X.xy / X.z) of a pixel: K⁻¹ then the
    /// inverse of the distortion.
    pub fn normalized_of_pixel(&self, x: &Point2<f64>) -> Result<[f64; 2]> {
        let q = self.k_inv() * Vector3::new(x.x, x.y, 1.0);
        self.distortion
            .undistort([q.x, q.y])
            .map_err(VisionError::from)
    }

    /// The pixel an ideal pinhole with the same K would see where this lens images `x`
    /// (undistortion in pixels; the identity for a pinhole).
    pub fn undistort_pixel(&self, x: &Point2<f64>) -> Result<Point2<f64>> {
        if self.is_pinhole() {
            return Ok(*x);
        }
        let p = self.normalized_of_pixel(x)?;
        Ok(Point2::new(
            self.f1 * p[0] + self.s * p[1] + self.u0,
            self.f2 * p[1] + self.v0,
        ))
    }

    /// The pixel this lens images where an ideal pinhole with the same K sees `x`
    /// (distortion in pixels; the inverse of [`Intrinsics::undistort_pixel`]).
    pub fn distort_pixel(&self, x: &Point2<f64>) -> Result<Point2<f64>> {
        if self.is_pinhole() {
            return Ok(*x);
        }
        let p = self.k_inv() * Vector3::new(x.x, x.y, 1.0);
        self.pixel_of_normalized([p.x, p.y])
    }

    /// The matrix K (the book's `calib_kmatrix_alloc`).
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.f1, self.s, self.u0, 0.0, self.f2, self.v0, 0.0, 0.0, 1.0,
        )
    }

    /// Intrinsics from an upper-triangular matrix K, scaled so that K₃₃ = 1.
    pub fn from_k(k: &Matrix3<f64>) -> Result<Self> {
        if k.iter().any(|v| !v.is_finite()) {
            return Err(VisionError::InvalidInput("K has a non-finite entry".into()));
        }
        let scale = k[(2, 2)];
        let tol = 1e-9 * k.abs().max();
        if scale.abs() <= tol
            || k[(1, 0)].abs() > tol
            || k[(2, 0)].abs() > tol
            || k[(2, 1)].abs() > tol
        {
            return Err(VisionError::InvalidInput(
                "K must be upper triangular with K33 != 0".into(),
            ));
        }
        let k = k / scale;
        if k[(0, 0)] == 0.0 || k[(1, 1)] == 0.0 {
            return Err(VisionError::InvalidInput(
                "K has a zero focal length".into(),
            ));
        }
        Ok(Intrinsics {
            f1: k[(0, 0)],
            f2: k[(1, 1)],
            s: k[(0, 1)],
            u0: k[(0, 2)],
            v0: k[(1, 2)],
            width: None,
            height: None,
            distortion: Distortion::None,
        })
    }

    /// Inverse of K.
    pub fn k_inv(&self) -> Matrix3<f64> {
        let (f1, f2, s, u0, v0) = (self.f1, self.f2, self.s, self.u0, self.v0);
        Matrix3::new(
            1.0 / f1,
            -s / (f1 * f2),
            (s * v0 - f2 * u0) / (f1 * f2),
            0.0,
            1.0 / f2,
            -v0 / f2,
            0.0,
            0.0,
            1.0,
        )
    }

    /// Normalized image coordinates K⁻¹x of a pixel (a ray direction with z = 1), ignoring the
    /// distortion (see [`Intrinsics::normalized_of_pixel`] for a lens).
    pub fn unproject(&self, x: &Point2<f64>) -> Vector3<f64> {
        self.k_inv() * Vector3::new(x.x, x.y, 1.0)
    }

    /// Pixel of a point given in camera coordinates (z > 0 in front), through the lens.
    pub fn project_camera_point(&self, xc: &Vector3<f64>) -> Result<Point2<f64>> {
        if xc.z.abs() <= MIN_DEPTH * xc.norm().max(1.0) {
            return Err(VisionError::PointsAtInfinity);
        }
        let x = xc.x / xc.z;
        let y = xc.y / xc.z;
        if self.is_pinhole() {
            return Ok(Point2::new(
                self.f1 * x + self.s * y + self.u0,
                self.f2 * y + self.v0,
            ));
        }
        self.pixel_of_normalized([x, y])
    }
}

/// Extrinsic parameters [R|t]: a world point X has camera coordinates RX + t.
///
/// JSON form: `{"R": [[..],[..],[..]], "t": [t1, t2, t3]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "PoseJson", into = "PoseJson")]
pub struct Pose {
    /// Rotation world → camera.
    pub r: Matrix3<f64>,
    /// Translation world → camera.
    pub t: Vector3<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Pose::identity()
    }
}

impl Pose {
    /// [R|t].
    pub fn new(r: Matrix3<f64>, t: Vector3<f64>) -> Self {
        Pose { r, t }
    }

    /// [I|0].
    pub fn identity() -> Self {
        Pose {
            r: Matrix3::identity(),
            t: Vector3::zeros(),
        }
    }

    /// The 4×4 matrix [[R, t], [0ᵀ, 1]] (the S3D `V` field, book §2.8.1).
    pub fn matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.t);
        m
    }

    /// The 3×4 matrix [R|t].
    pub fn matrix3x4(&self) -> Matrix3x4<f64> {
        let mut m = Matrix3x4::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.r);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.t);
        m
    }

    /// Camera coordinates RX + t of a world point.
    pub fn transform(&self, x: &Point3<f64>) -> Vector3<f64> {
        self.r * x.coords + self.t
    }

    /// The camera centre c = −Rᵀt (book §2.7.2: t = −Rc).
    pub fn center(&self) -> Point3<f64> {
        Point3::from(-(self.r.transpose() * self.t))
    }

    /// The inverse rigid motion [Rᵀ | −Rᵀt].
    pub fn inverse(&self) -> Pose {
        let rt = self.r.transpose();
        Pose {
            r: rt,
            t: -(rt * self.t),
        }
    }

    /// The composition `self ∘ other`: first `other`, then `self`.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            r: self.r * other.r,
            t: self.r * other.t + self.t,
        }
    }

    /// Change of reference (the book's `calib_change_ref`, used in §7.12 to join fragments):
    /// the world frame is changed so that camera `a1` becomes `a2`; returns what camera `b1`
    /// (expressed in the same world as `a1`) becomes in the new world: `b1 · a1⁻¹ · a2`.
    pub fn change_reference(a1: &Pose, a2: &Pose, b1: &Pose) -> Pose {
        b1.compose(&a1.inverse()).compose(a2)
    }

    /// The pose of this camera relative to `reference`: `self · reference⁻¹`, i.e. the pose
    /// when `reference` is moved to [I|0].
    pub fn relative_to(&self, reference: &Pose) -> Pose {
        self.compose(&reference.inverse())
    }
}

/// A camera K[R|t] (book §2.7.2).
///
/// JSON form (the `write_camera` node's): `{"K": [[3×3]], "R": [[3×3]], "t": [3], "width": W?,
/// "height": H?}`, rows first.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraJson", into = "CameraJson")]
pub struct Camera {
    /// K.
    pub intrinsics: Intrinsics,
    /// [R|t].
    pub pose: Pose,
}

/// The view frustum of a render camera (book §2.8.2): the near-plane window corners
/// (l, b, near) and (r, t, near) in camera coordinates, and the clipping distances.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frustum {
    /// Left edge of the window on the near plane.
    pub left: f64,
    /// Right edge.
    pub right: f64,
    /// Bottom edge (`−v0/my`; the book's pixel rows grow with camera y).
    pub bottom: f64,
    /// Top edge (`(h − v0)/my`).
    pub top: f64,
    /// Near plane distance (= focal distance of the window).
    pub near: f64,
    /// Far plane distance.
    pub far: f64,
}

impl Camera {
    /// A camera from K, R and t.
    pub fn new(intrinsics: Intrinsics, r: Matrix3<f64>, t: Vector3<f64>) -> Self {
        Camera {
            intrinsics,
            pose: Pose { r, t },
        }
    }

    /// P = K[R|t] (the book's `calib_pmatrix_make`).
    pub fn p_matrix(&self) -> Matrix3x4<f64> {
        self.intrinsics.k() * self.pose.matrix3x4()
    }

    /// Depth of a world point along the optical axis (positive in front).
    pub fn depth(&self, x: &Point3<f64>) -> f64 {
        self.pose.transform(x).z
    }

    /// Pixel of a world point (the book's `calib_apply_P`). A point on the principal plane gives
    /// [`VisionError::PointsAtInfinity`].
    pub fn project(&self, x: &Point3<f64>) -> Result<Point2<f64>> {
        self.intrinsics
            .project_camera_point(&self.pose.transform(x))
    }

    /// The camera centre c = −Rᵀt.
    pub fn center(&self) -> Point3<f64> {
        self.pose.center()
    }

    /// Reprojection error in pixels of the match X ↔ x (∞ for a point on the principal plane).
    pub fn reprojection_error(&self, x3: &Point3<f64>, x2: &Point2<f64>) -> f64 {
        match self.project(x3) {
            Ok(p) => (p - x2).norm(),
            Err(_) => f64::INFINITY,
        }
    }

    /// The frustum of the render camera equivalent to this calibrated camera (book §2.8.2):
    /// mx = f1/near, my = f2/near, l = −u0/mx, r = (w − u0)/mx, b = −v0/my, t = (h − v0)/my.
    ///
    /// Needs the image size and zero skew (a render camera has no shear): call it on the result
    /// of the restricted calibration (§4.5) or Tsai's (§4.8).
    pub fn render_frustum(&self, near: f64, far: f64) -> Result<Frustum> {
        let k = &self.intrinsics;
        let (w, h) = match (k.width, k.height) {
            (Some(w), Some(h)) => (w as f64, h as f64),
            _ => {
                return Err(VisionError::InvalidInput(
                    "the image size is unknown".into(),
                ))
            }
        };
        if k.s.abs() > 1e-9 * k.f1.abs() {
            return Err(VisionError::InvalidInput(format!(
                "a render camera has zero skew (s = {})",
                k.s
            )));
        }
        if !(near > 0.0 && far > near && near.is_finite() && far.is_finite()) {
            return Err(VisionError::InvalidInput(format!(
                "need 0 < near < far, got {near}, {far}"
            )));
        }
        let mx = k.f1 / near;
        let my = k.f2 / near;
        Ok(Frustum {
            left: -k.u0 / mx,
            right: (w - k.u0) / mx,
            bottom: -k.v0 / my,
            top: (h - k.v0) / my,
            near,
            far,
        })
    }
}

// ---- JSON proxies (rows first) -------------------------------------------------------------

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

fn from_rows(r: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::new(
        r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
    )
}

#[derive(Serialize, Deserialize)]
struct IntrinsicsJson {
    #[serde(rename = "K")]
    k: [[f64; 3]; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    width: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    height: Option<u32>,
    #[serde(default, skip_serializing_if = "Distortion::is_identity")]
    distortion: Distortion,
}

impl From<Intrinsics> for IntrinsicsJson {
    fn from(k: Intrinsics) -> Self {
        IntrinsicsJson {
            k: rows(&k.k()),
            width: k.width,
            height: k.height,
            distortion: k.distortion,
        }
    }
}

impl TryFrom<IntrinsicsJson> for Intrinsics {
    type Error = VisionError;
    fn try_from(j: IntrinsicsJson) -> Result<Self> {
        let mut k = Intrinsics::from_k(&from_rows(&j.k))?;
        k.width = j.width;
        k.height = j.height;
        k.distortion = j.distortion;
        Ok(k)
    }
}

#[derive(Serialize, Deserialize)]
struct PoseJson {
    #[serde(rename = "R")]
    r: [[f64; 3]; 3],
    t: [f64; 3],
}

impl From<Pose> for PoseJson {
    fn from(p: Pose) -> Self {
        PoseJson {
            r: rows(&p.r),
            t: [p.t.x, p.t.y, p.t.z],
        }
    }
}

impl From<PoseJson> for Pose {
    fn from(j: PoseJson) -> Self {
        Pose {
            r: from_rows(&j.r),
            t: Vector3::new(j.t[0], j.t[1], j.t[2]),
        }
    }
}

#[derive(Serialize, Deserialize)]
struct CameraJson {
    #[serde(rename = "K")]
    k: [[f64; 3]; 3],
    #[serde(rename = "R")]
    r: [[f64; 3]; 3],
    t: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    width: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    height: Option<u32>,
    #[serde(default, skip_serializing_if = "Distortion::is_identity")]
    distortion: Distortion,
}

impl From<Camera> for CameraJson {
    fn from(c: Camera) -> Self {
        CameraJson {
            k: rows(&c.intrinsics.k()),
            r: rows(&c.pose.r),
            t: [c.pose.t.x, c.pose.t.y, c.pose.t.z],
            width: c.intrinsics.width,
            height: c.intrinsics.height,
            distortion: c.intrinsics.distortion,
        }
    }
}

impl TryFrom<CameraJson> for Camera {
    type Error = VisionError;
    fn try_from(j: CameraJson) -> Result<Self> {
        let intrinsics = Intrinsics::try_from(IntrinsicsJson {
            k: j.k,
            width: j.width,
            height: j.height,
            distortion: j.distortion,
        })?;
        Ok(Camera {
            intrinsics,
            pose: Pose::from(PoseJson { r: j.r, t: j.t }),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::axis_angle_to_r;

    fn camera() -> Camera {
        let k = Intrinsics {
            f1: 800.0,
            f2: 780.0,
            s: 1.5,
            u0: 320.0,
            v0: 240.0,
            width: Some(640),
            height: Some(480),
            distortion: crate::lens::Distortion::None,
        };
        Camera::new(
            k,
            axis_angle_to_r(&Vector3::new(0.1, -0.2, 0.3)),
            Vector3::new(0.5, -0.1, 4.0),
        )
    }

    #[test]
    fn projection_matches_p_matrix() {
        let c = camera();
        let p = c.p_matrix();
        let x = Point3::new(0.3, -0.4, 1.2);
        let h = p * x.to_homogeneous();
        let expected = Point2::new(h.x / h.z, h.y / h.z);
        assert!((c.project(&x).unwrap() - expected).norm() < 1e-10);
        // The centre is P's null vector.
        let cc = c.center();
        assert!((p * cc.to_homogeneous()).norm() < 1e-9);
        // A point on the principal plane has no projection.
        let on_plane = Point3::from(cc.coords + c.pose.r.transpose() * Vector3::new(1.0, 0.0, 0.0));
        assert!(matches!(
            c.project(&on_plane),
            Err(VisionError::PointsAtInfinity)
        ));
    }

    #[test]
    fn k_inverse() {
        let k = camera().intrinsics;
        assert!((k.k() * k.k_inv() - Matrix3::identity()).norm() < 1e-12);
        assert_eq!(Intrinsics::from_k(&(k.k() * 3.0)).unwrap().f1, 800.0);
        assert!(Intrinsics::from_k(&Matrix3::repeat(1.0)).is_err());
    }

    #[test]
    fn change_of_reference_maps_a1_to_a2_and_keeps_relative_motion() {
        let a1 = Pose::new(
            axis_angle_to_r(&Vector3::new(0.2, 0.1, -0.3)),
            Vector3::new(1.0, 2.0, 3.0),
        );
        let a2 = Pose::new(
            axis_angle_to_r(&Vector3::new(-0.5, 0.4, 0.1)),
            Vector3::new(-1.0, 0.0, 2.0),
        );
        let b1 = Pose::new(
            axis_angle_to_r(&Vector3::new(0.0, 0.7, 0.2)),
            Vector3::new(0.3, 0.2, 0.1),
        );
        let a1_new = Pose::change_reference(&a1, &a2, &a1);
        assert!((a1_new.r - a2.r).norm() < 1e-12 && (a1_new.t - a2.t).norm() < 1e-12);
        let b2 = Pose::change_reference(&a1, &a2, &b1);
        let rel1 = b1.relative_to(&a1);
        let rel2 = b2.relative_to(&a2);
        assert!((rel1.r - rel2.r).norm() < 1e-12 && (rel1.t - rel2.t).norm() < 1e-12);
    }

    #[test]
    fn frustum_follows_book_2_8() {
        let mut c = camera();
        assert!(
            c.render_frustum(1.0, 100.0).is_err(),
            "skewed camera rejected"
        );
        c.intrinsics.s = 0.0;
        let f = c.render_frustum(2.0, 100.0).unwrap();
        // The window spans the image: w pixels = (r - l) * mx.
        assert!(((f.right - f.left) * 800.0 / 2.0 - 640.0).abs() < 1e-9);
        assert!(((f.top - f.bottom) * 780.0 / 2.0 - 480.0).abs() < 1e-9);
        // A ray through pixel (u, v) hits the near plane at l + u/mx.
        assert!((f.left + 320.0 * 2.0 / 800.0).abs() < 1e-12);
    }

    #[test]
    fn json_rows_first() {
        let c = camera();
        let s = serde_json::to_string(&c).unwrap();
        assert!(s.starts_with("{\"K\":[[800.0,1.5,320.0],"), "{s}");
        assert!(s.contains("\"width\":640"));
        let back: Camera = serde_json::from_str(&s).unwrap();
        assert!((back.p_matrix() - c.p_matrix()).norm() < 1e-9);
    }
}
