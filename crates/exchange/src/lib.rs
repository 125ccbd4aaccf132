//! vfxgraph-exchange: camera and scene exchange after §7.13 of *Introduction to Visual Effects: A
//! Computational Approach* (Madeira & Velho, 2023). A solved shot (the matchmove's camera path and point cloud, book
//! §7.12–7.14, with the K of §2.7) written for the programs that use it, and read back from
//! COLMAP. The off-line augmented reality of §7.13 maps each solved camera to a render camera
//! (§2.8); here the render camera is another program's.
//!
//! | module | target | conventions of the target |
//! | --- | --- | --- |
//! | [`colmap`] | COLMAP text model | world→camera Hamilton quaternion (w x y z) + t; pixel origin at the top-left *corner*; the lens as `SIMPLE_RADIAL`/`RADIAL`/`OPENCV`/`FULL_OPENCV` |
//! | [`blender`] | a Python script for Blender | Z up; camera looks down −Z, +Y up; lens/sensor in mm; shift in units of the image width |
//! | [`usd`] | `.usda` stage | Y up (stage metadata); camera looks down −Z; focal/aperture in tenths of a scene unit |
//! | [`nuke`] | `.chan` + film-back note | Y up; rotations in degrees, order ZXY (M = Ry·Rx·Rz) |
//! | [`json`] | our JSON | ours: x ~ K(RX + t), pixel origin at the top-left pixel's centre, y down |
//! | [`ply`] | point cloud | the solve's world, sRGB colours |
//!
//! Our conventions (ARCHITECTURE.md, "Conventions"): a world point X maps to x ~ K(RX + t); the camera looks down
//! +z with +y down in the image; pixel coordinates have their origin at the *centre* of the
//! top-left pixel. COLMAP, JSON and PLY stay in the solve's world and units (they carry
//! K, R, t for computation); the scene formats (Blender, USD, Nuke) apply the scene transform
//! [`SceneOptions`]: X' = scale · W · X where W turns the solve's `up` axis into the target's up.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod blender;
pub mod colmap;
pub mod colors;
pub mod files;
pub mod json;
pub mod lens_fit;
pub mod nuke;
pub mod ply;
pub mod usd;

use nalgebra::{Matrix3, Matrix4, Point3, UnitQuaternion, Vector3};
pub use vfxgraph_fsutil::frame_pattern::format_frame;

use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::CameraPath;
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_klt::Tracks;

pub use files::{files, read, ExportFormat, ExportOptions, ImportFormat};

/// The horizontal film back (mm) given to the scene formats; only the ratios focal/aperture
/// matter for the projection, this makes the focal length read like a full-frame lens.
pub const FILM_BACK_MM: f64 = 36.0;

/// A solved shot to export: shared intrinsics, one pose per frame, and optionally the points,
/// the tracks they came from, their colours and the plate's file names.
#[derive(Clone, Debug)]
pub struct Shot {
    /// K, with the image size (required by every format but JSON and PLY).
    pub intrinsics: Intrinsics,
    /// One [R|t] per solved frame.
    pub path: CameraPath,
    /// The point cloud, if any.
    pub cloud: Option<PointCloud>,
    /// The observations the cloud was solved from (COLMAP tracks, per-frame solve error).
    pub tracks: Option<Tracks>,
    /// One sRGB colour per point of the cloud.
    pub colors: Option<Vec<[u8; 3]>>,
    /// The plate's file names as a frame pattern (`%04d` or `####`), relative to the export.
    pub image_pattern: Option<String>,
    /// An ST-map of the lens (written elsewhere, e.g. by `write_st_map`), relative to the
    /// export: referenced by the USD and Nuke exports.
    pub st_map: Option<String>,
}

/// Which world axis of the solve points up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum UpAxis {
    /// −y (the default: image y points down, so a level first camera has world up = −y).
    #[default]
    #[param(name = "-y")]
    NegY,
    /// +y.
    #[param(name = "+y")]
    PosY,
    /// +z.
    #[param(name = "+z")]
    PosZ,
    /// −z.
    #[param(name = "-z")]
    NegZ,
    /// +x.
    #[param(name = "+x")]
    PosX,
    /// −x.
    #[param(name = "-x")]
    NegX,
}

impl UpAxis {
    /// Parses `+x`, `x`, `-x`, … .
    pub fn parse(s: &str) -> Option<UpAxis> {
        Some(match s {
            "+x" | "x" => UpAxis::PosX,
            "-x" => UpAxis::NegX,
            "+y" | "y" => UpAxis::PosY,
            "-y" => UpAxis::NegY,
            "+z" | "z" => UpAxis::PosZ,
            "-z" => UpAxis::NegZ,
            _ => return None,
        })
    }

    /// The rotation that takes this axis to +Y (a Y-up world), keeping a right-handed frame.
    /// For −y it is the 180° turn about x that takes OpenCV's camera frame to OpenGL's.
    pub fn to_y_up(self) -> Matrix3<f64> {
        match self {
            UpAxis::PosY => Matrix3::identity(),
            UpAxis::NegY => Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0),
            UpAxis::PosZ => Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0),
            UpAxis::NegZ => Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0),
            UpAxis::PosX => Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            UpAxis::NegX => Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        }
    }
}

/// The target's up axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetUp {
    /// Y up (USD's default, Nuke, Maya).
    Y,
    /// Z up (Blender).
    Z,
}

/// Scene options of the DCC formats.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct SceneOptions {
    /// frames per second of the scene
    #[param(range = 1e-3..=1e4)]
    pub fps: f64,
    /// the target's frame number of our frame 0 (target frame = start_frame + frame)
    #[param(range = -1_000_000..=1_000_000)]
    pub start_frame: i64,
    /// scene units per solve unit (blender, usd, nuke)
    #[param(range = 1e-12..=1e12)]
    pub scale: f64,
    /// the solve's world axis that points up (blender, usd, nuke); -y for a level first camera
    #[param(name = "up_axis")]
    pub up: UpAxis,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            fps: 24.0,
            start_frame: 1,
            scale: 1.0,
            up: UpAxis::NegY,
        }
    }
}

impl SceneOptions {
    /// Checks the options.
    pub fn validate(&self) -> Result<()> {
        if !(self.fps > 0.0 && self.fps.is_finite()) {
            return Err(VisionError::InvalidInput(format!(
                "fps must be positive, got {}",
                self.fps
            )));
        }
        if !(self.scale > 0.0 && self.scale.is_finite()) {
            return Err(VisionError::InvalidInput(format!(
                "scale must be positive, got {}",
                self.scale
            )));
        }
        Ok(())
    }

    /// W: solve world → target world rotation (before scaling).
    pub fn world_rotation(&self, target: TargetUp) -> Matrix3<f64> {
        let y_up = self.up.to_y_up();
        match target {
            TargetUp::Y => y_up,
            // Y-up → Z-up: +90° about x (Y → Z, Z → −Y).
            TargetUp::Z => Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0) * y_up,
        }
    }

    /// A solve-world point in the target world: scale · W · X.
    pub fn point(&self, target: TargetUp, x: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.world_rotation(target) * x.coords * self.scale)
    }

    /// The camera-to-world matrix, in the target world, of a camera that looks down −Z with +Y
    /// up (OpenGL, Blender, USD, Nuke): rotation W·Rᵀ·F with F = diag(1, −1, −1), translation
    /// scale · W · c with c = −Rᵀt the camera centre.
    pub fn camera_to_world(&self, target: TargetUp, pose: &Pose) -> Matrix4<f64> {
        let w = self.world_rotation(target);
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
        let rot = w * pose.r.transpose() * f;
        let c = w * pose.center().coords * self.scale;
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&rot);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&c);
        m
    }

    /// The target frame number of our frame `frame`.
    pub fn target_frame(&self, frame: usize) -> i64 {
        self.start_frame + frame as i64
    }
}

impl Shot {
    /// A shot with no points.
    pub fn new(intrinsics: Intrinsics, path: CameraPath) -> Self {
        Shot {
            intrinsics,
            path,
            cloud: None,
            tracks: None,
            colors: None,
            image_pattern: None,
            st_map: None,
        }
    }

    /// Checks what every format needs: valid K, poses that are rotations, a cloud whose lists
    /// agree, colours for every point.
    pub fn validate(&self) -> Result<()> {
        self.intrinsics.validate()?;
        for f in &self.path.frames {
            let r = &f.pose.r;
            let err = (r.transpose() * r - Matrix3::identity()).norm();
            if !(err < 1e-6) || !(r.determinant() > 0.0) || f.pose.t.iter().any(|v| !v.is_finite())
            {
                return Err(VisionError::InvalidInput(format!(
                    "frame {}: R is not a rotation (|RᵀR − I| = {err:e}) or t is not finite",
                    f.frame
                )));
            }
        }
        let mut seen = std::collections::BTreeSet::new();
        for f in &self.path.frames {
            if !seen.insert(f.frame) {
                return Err(VisionError::InvalidInput(format!(
                    "frame {} appears twice in the camera path",
                    f.frame
                )));
            }
        }
        if let Some(c) = &self.cloud {
            c.validate().map_err(VisionError::InvalidInput)?;
            if c.points.iter().flatten().any(|v| !v.is_finite()) {
                return Err(VisionError::InvalidInput(
                    "point cloud has a non-finite coordinate".into(),
                ));
            }
            if let Some(col) = &self.colors {
                if col.len() != c.points.len() {
                    return Err(VisionError::LengthMismatch {
                        first: c.points.len(),
                        second: col.len(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The image size, required by the camera formats.
    pub fn size(&self) -> Result<(u32, u32)> {
        match (self.intrinsics.width, self.intrinsics.height) {
            (Some(w), Some(h)) if w > 0 && h > 0 => Ok((w, h)),
            _ => Err(VisionError::InvalidInput(
                "the image size is unknown: give K with width/height or connect the plate".into(),
            )),
        }
    }

    /// The intrinsics of the path's `i`-th frame: the shot's, with the frame's own focal length
    /// when the path zooms ([`CameraPath::intrinsics_at`]).
    pub fn intrinsics_at(&self, i: usize) -> Intrinsics {
        let mut k = self.intrinsics.clone();
        if let Some(f) = self.path.frames.get(i).and_then(|f| f.focal) {
            k.f2 *= f / k.f1;
            k.f1 = f;
        }
        k
    }

    /// A fixed focal length, for the formats whose export of a zoom (a focal length per frame)
    /// is not written yet: an error naming the formats that carry it.
    pub fn require_fixed_focal(&self, target: &str) -> Result<()> {
        if self.path.zooms() {
            return Err(VisionError::InvalidInput(format!(
                "the camera path zooms (a focal length per frame): the {target} export of it is \
                 not written; json, usd and colmap carry every frame's focal length (blender and \
                 nuke that of a pinhole zoom)"
            )));
        }
        Ok(())
    }

    /// Zero skew, required by every render camera (§2.8) and by COLMAP's pinhole models.
    pub fn require_no_skew(&self, target: &str) -> Result<()> {
        if self.intrinsics.s.abs() > 1e-9 * self.intrinsics.f1.abs() {
            return Err(VisionError::InvalidInput(format!(
                "{target} cameras have no skew, but K has s = {}",
                self.intrinsics.s
            )));
        }
        Ok(())
    }

    /// The cloud's points (empty without a cloud).
    pub fn points(&self) -> Vec<Point3<f64>> {
        self.cloud
            .as_ref()
            .map(|c| {
                c.points
                    .iter()
                    .map(|p| Point3::new(p[0], p[1], p[2]))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The plate's file name of frame `frame`, if a pattern was given.
    pub fn image_name(&self, frame: usize) -> Option<String> {
        self.image_pattern
            .as_ref()
            .map(|p| format_frame(p, frame as i64))
    }

    /// Near and far clipping distances (solve units) that hold every point of the cloud in
    /// every frame where it is in front: half the least depth, twice the largest. Without
    /// points: 0.01 and 10 000.
    pub fn clip_range(&self) -> (f64, f64) {
        let pts = self.points();
        let mut lo = f64::INFINITY;
        let mut hi: f64 = 0.0;
        for f in &self.path.frames {
            for p in &pts {
                let z = f.pose.transform(p).z;
                if z > 0.0 {
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
        }
        if lo.is_finite() && hi > lo {
            (0.5 * lo, 2.0 * hi)
        } else {
            (0.01, 10_000.0)
        }
    }

    /// Per frame of the path (in path order), the tracks' observations of the cloud's points
    /// in that frame, each with whether the solve kept it ([`PointCloud::is_inlier`]); empty
    /// lists without tracks or cloud. Observations of tracks that have no point are left out.
    pub fn observations(&self) -> Vec<Vec<Observation>> {
        let mut out = vec![Vec::new(); self.path.frames.len()];
        let (Some(tracks), Some(cloud)) = (&self.tracks, &self.cloud) else {
            return out;
        };
        let point_of: std::collections::HashMap<u64, usize> = cloud
            .track_ids
            .iter()
            .enumerate()
            .map(|(i, id)| (*id, i))
            .collect();
        for (img, f) in self.path.frames.iter().enumerate() {
            let frame = f.frame as i64;
            let Some(fi) = tracks.frames.iter().position(|&n| n == frame) else {
                continue;
            };
            for (id, x) in tracks.observations(fi) {
                if let Some(&point) = point_of.get(&id) {
                    out[img].push(Observation {
                        pixel: x,
                        point,
                        inlier: cloud.is_inlier(point, frame),
                    });
                }
            }
        }
        out
    }

    /// Per frame of the path, the solve error over the observations the solve kept: RMS
    /// reprojection error (px; NaN with none), the number of inlier observations and the
    /// number of outliers (observations of a point the solve rejected); `None` without tracks
    /// or cloud.
    pub fn frame_errors(&self) -> Option<Vec<FrameError>> {
        self.cloud.as_ref()?;
        self.tracks.as_ref()?;
        let points = self.points();
        Some(
            self.path
                .frames
                .iter()
                .zip(self.observations())
                .enumerate()
                .map(|(i, (f, obs))| {
                    let c = vfxgraph_geometry::Camera {
                        intrinsics: self.intrinsics_at(i),
                        pose: f.pose.clone(),
                    };
                    let (mut sum, mut inliers) = (0.0, 0usize);
                    for o in obs.iter().filter(|o| o.inlier) {
                        let e = c.reprojection_error(
                            &points[o.point],
                            &nalgebra::Point2::new(o.pixel[0], o.pixel[1]),
                        );
                        sum += e * e;
                        inliers += 1;
                    }
                    FrameError {
                        rms_px: if inliers == 0 {
                            f64::NAN
                        } else {
                            (sum / inliers as f64).sqrt()
                        },
                        inliers,
                        outliers: obs.len() - inliers,
                    }
                })
                .collect(),
        )
    }
}

/// One observation of a cloud point in a frame (see [`Shot::observations`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The tracked position, our pixel convention.
    pub pixel: [f64; 2],
    /// The point's index in the cloud.
    pub point: usize,
    /// Whether the solve kept this observation.
    pub inlier: bool,
}

/// One frame's solve error (see [`Shot::frame_errors`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameError {
    /// RMS reprojection error over the inlier observations, px (NaN without any).
    pub rms_px: f64,
    /// Inlier observations.
    pub inliers: usize,
    /// Observations of the frame's points that the solve rejected.
    pub outliers: usize,
}

/// The Hamilton quaternion (w, x, y, z) of a rotation matrix, with w ≥ 0.
pub fn quaternion_wxyz(r: &Matrix3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_matrix(r);
    let (w, v) = (q.scalar(), q.vector());
    let s = if w < 0.0 { -1.0 } else { 1.0 };
    [s * w, s * v.x, s * v.y, s * v.z]
}

/// The rotation matrix of a Hamilton quaternion (w, x, y, z), normalized first.
pub fn rotation_from_wxyz(q: [f64; 4]) -> Result<Matrix3<f64>> {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n > 1e-12 && n.is_finite()) {
        return Err(VisionError::InvalidInput(format!(
            "quaternion {q:?} has no direction"
        )));
    }
    let u = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]));
    Ok(*u.to_rotation_matrix().matrix())
}

/// A number as the exporters write it: the shortest text that reads back as the same f64, in
/// scientific notation when tiny or huge (so float noise like 1.3e-23 stays short).
#[derive(Clone, Copy, Debug)]
pub(crate) struct N(pub f64);

impl std::fmt::Display for N {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.0.abs();
        if a != 0.0 && !(1e-4..1e15).contains(&a) {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

/// Quaternions (w, x, y, z) of successive rotations with signs chosen so that neighbours have
/// a positive dot product (interpolation between keys takes the short way).
pub(crate) fn continuous_quaternions(rs: &[Matrix3<f64>]) -> Vec<[f64; 4]> {
    let mut out: Vec<[f64; 4]> = Vec::with_capacity(rs.len());
    for r in rs {
        let mut q = quaternion_wxyz(r);
        if let Some(p) = out.last() {
            let dot: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
            if dot < 0.0 {
                q = q.map(|v| -v);
            }
        }
        out.push(q);
    }
    out
}

#[cfg(test)]
pub(crate) mod test_shot {
    //! A synthetic shot with known truth, shared by the exporters' tests.
    use super::*;
    use vfxgraph_geometry::formats::FramePose;
    use vfxgraph_geometry::rotation::axis_angle_to_r;

    /// A dolly + pan around points near the origin; K with f1 ≠ f2 and an off-centre principal
    /// point, 1280×720.
    pub fn shot() -> Shot {
        let k = Intrinsics::new(1228.4, 1210.0, 651.25, 347.75).with_size(1280, 720);
        let frames = (0..12)
            .map(|i| {
                let a = i as f64;
                let r = axis_angle_to_r(&Vector3::new(0.05 * a.sin(), 0.3 - 0.06 * a, 0.02 * a));
                let c = Vector3::new(-1.0 + 0.2 * a, -0.3 + 0.01 * a * a, -6.0 + 0.1 * a);
                FramePose {
                    frame: 10 + i,
                    pose: Pose::new(r, -(r * c)),
                    focal: None,
                }
            })
            .collect();
        let points: Vec<[f64; 3]> = (0..40)
            .map(|j| {
                let b = j as f64;
                [(b * 0.37).sin() * 1.5, (b * 0.71).cos(), (b * 0.13).sin()]
            })
            .collect();
        let n = points.len();
        Shot {
            intrinsics: k,
            path: CameraPath {
                frames,
                intrinsics: None,
            },
            cloud: Some(PointCloud {
                points,
                track_ids: (0..n as u64).map(|i| 500 + i).collect(),
                errors: (0..n).map(|i| 0.01 * i as f64).collect(),
                inlier_frames: Vec::new(),
            }),
            tracks: None,
            colors: Some(
                (0..n)
                    .map(|i| [i as u8, 2 * i as u8, 255 - i as u8])
                    .collect(),
            ),
            image_pattern: Some("plate/frame.%04d.png".into()),
            st_map: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For every up axis and target, the camera-to-world matrix is rigid and maps the camera's
    /// −Z axis to the direction of its optical axis in the target world; points go through
    /// the same transform, so a point straight ahead stays straight ahead.
    #[test]
    fn camera_to_world_keeps_the_view() {
        let shot = test_shot::shot();
        for up in ["+x", "-x", "+y", "-y", "+z", "-z"] {
            for target in [TargetUp::Y, TargetUp::Z] {
                let o = SceneOptions {
                    up: UpAxis::parse(up).unwrap(),
                    scale: 2.5,
                    ..SceneOptions::default()
                };
                let w = o.world_rotation(target);
                assert!((w.transpose() * w - Matrix3::identity()).norm() < 1e-15);
                assert!((w.determinant() - 1.0).abs() < 1e-15);
                // Our up axis lands on the target's up.
                let u = match UpAxis::parse(up).unwrap() {
                    UpAxis::PosX => Vector3::x(),
                    UpAxis::NegX => -Vector3::x(),
                    UpAxis::PosY => Vector3::y(),
                    UpAxis::NegY => -Vector3::y(),
                    UpAxis::PosZ => Vector3::z(),
                    UpAxis::NegZ => -Vector3::z(),
                };
                let want = match target {
                    TargetUp::Y => Vector3::y(),
                    TargetUp::Z => Vector3::z(),
                };
                assert!((w * u - want).norm() < 1e-15, "{up} {target:?}");
                for f in &shot.path.frames {
                    let m = o.camera_to_world(target, &f.pose);
                    let inv = m.try_inverse().unwrap();
                    for p in shot.points() {
                        let ours = f.pose.transform(&p);
                        let pt = o.point(target, &p);
                        let local = inv.transform_point(&pt);
                        // GL camera coordinates = scale · (x, −y, −z) of ours.
                        let expect = Vector3::new(ours.x, -ours.y, -ours.z) * 2.5;
                        assert!((local.coords - expect).norm() < 1e-12);
                    }
                }
            }
        }
    }

    #[test]
    fn quaternions_round_trip_and_continuity() {
        let shot = test_shot::shot();
        let rs: Vec<Matrix3<f64>> = shot.path.frames.iter().map(|f| f.pose.r).collect();
        for r in &rs {
            let q = quaternion_wxyz(r);
            assert!(q[0] >= 0.0);
            assert!((rotation_from_wxyz(q).unwrap() - r).norm() < 1e-15);
        }
        // Hamilton convention: a quarter turn about z maps x to y.
        let rz = rotation_from_wxyz([0.5f64.sqrt(), 0.0, 0.0, 0.5f64.sqrt()]).unwrap();
        assert!((rz * Vector3::x() - Vector3::y()).norm() < 1e-15);
        let flip = [rs[0], -rs[0] * -1.0, rs[0]];
        let q = continuous_quaternions(&flip);
        assert!(q
            .windows(2)
            .all(|w| w[0].iter().zip(&w[1]).map(|(a, b)| a * b).sum::<f64>() > 0.0));
        assert!(rotation_from_wxyz([0.0; 4]).is_err());
    }

    #[test]
    fn numbers_read_back_exactly() {
        for v in [
            1.3234892447826845e-23,
            -0.5,
            0.0,
            1228.4022637363655,
            2e20,
            -7.5e-5,
        ] {
            let s = N(v).to_string();
            assert_eq!(s.parse::<f64>().unwrap(), v, "{s}");
            assert!(s.len() < 25, "{s}");
        }
    }

    #[test]
    fn frame_patterns() {
        assert_eq!(format_frame("a.%04d.png", 7), "a.0007.png");
        assert_eq!(format_frame("a.####.png", 12), "a.0012.png");
        assert_eq!(format_frame("a%d.jpg", 3), "a3.jpg");
        assert_eq!(format_frame("naïve.png", 3), "naïve.png");
    }

    #[test]
    fn validation_names_the_problem() {
        let mut s = test_shot::shot();
        s.validate().unwrap();
        s.path.frames[3].pose.r[(0, 0)] = 3.0;
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("frame 13"), "{e}");
        let mut s = test_shot::shot();
        s.colors.as_mut().unwrap().pop();
        assert!(s.validate().is_err());
        let mut s = test_shot::shot();
        s.intrinsics.width = None;
        assert!(s.size().unwrap_err().to_string().contains("image size"));
        s.intrinsics.s = 2.0;
        assert!(s.require_no_skew("COLMAP").is_err());
    }
}
