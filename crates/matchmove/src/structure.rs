//! A solve's cameras and points by frame and track index, and what every stage measures with
//! them: projection and reprojection error (with the pose's Jacobian), triangulation from posed
//! views, the path and cloud they make, the final inlier decision, and the seed streams of the
//! parallel stages.

use nalgebra::{Matrix3x4, Point2, Vector3};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::cameras::{CameraPath, FramePose};
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_klt::Tracks;

/// Poses by frame index (`None`: no camera for that frame).
pub type Poses = Vec<Option<Pose>>;
/// Points by track index (`None`: no point for that track).
pub type TrackPoints = Vec<Option<Vector3<f64>>>;
/// A camera path and its structure, by frame and track index.
pub type Structure = (Poses, TrackPoints);

/// Projects X with K and pose; `None` behind the camera.
#[inline]
pub(crate) fn project(k: &Intrinsics, pose: &Pose, x: &Vector3<f64>) -> Option<[f64; 2]> {
    let c = pose.r * x + pose.t;
    if c.z <= 1e-12 {
        return None;
    }
    let (u, v) = (c.x / c.z, c.y / c.z);
    Some([k.f1 * u + k.s * v + k.u0, k.f2 * v + k.v0])
}

/// X's pixel under K and pose, and the Jacobian of that pixel with respect to the pose as a
/// left rotation increment δω (R ← exp([δω]ₓ)R) and a translation increment δt:
/// ∂pixel/∂c · [−[RX]ₓ | I] with c = RX + t. `None` behind the camera.
#[inline]
pub(crate) fn pose_jacobian(
    k: &Intrinsics,
    pose: &Pose,
    x: &Vector3<f64>,
) -> Option<([f64; 2], nalgebra::Matrix2x6<f64>)> {
    let rx = pose.r * x;
    let c = rx + pose.t;
    if c.z <= 1e-12 {
        return None;
    }
    let iz = 1.0 / c.z;
    let (u, v) = (c.x * iz, c.y * iz);
    let pixel = [k.f1 * u + k.s * v + k.u0, k.f2 * v + k.v0];
    // d(pixel)/d(c).
    let jc = nalgebra::Matrix2x3::new(
        k.f1 * iz,
        k.s * iz,
        -(k.f1 * u + k.s * v) * iz,
        0.0,
        k.f2 * iz,
        -k.f2 * v * iz,
    );
    let jw = jc * (-vfxgraph_geometry::rotation::skew(&rx));
    let mut j = nalgebra::Matrix2x6::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&jw);
    j.fixed_view_mut::<2, 3>(0, 3).copy_from(&jc);
    Some((pixel, j))
}

/// Reprojection error of X seen at `obs`, infinity behind the camera.
#[inline]
pub(crate) fn reprojection_error(
    k: &Intrinsics,
    pose: &Pose,
    x: &Vector3<f64>,
    obs: &[f64; 2],
) -> f64 {
    match project(k, pose, x) {
        Some(p) => ((p[0] - obs[0]).powi(2) + (p[1] - obs[1]).powi(2)).sqrt(),
        None => f64::INFINITY,
    }
}

/// P = K[R|t].
pub(crate) fn p_matrix(k: &Intrinsics, pose: &Pose) -> Matrix3x4<f64> {
    k.k() * pose.matrix3x4()
}

/// Triangulates a point from its observations in posed frames (linear, then Gauss–Newton on the
/// reprojection error); `None` if it lands at infinity or behind a camera.
pub(crate) fn triangulate_views(
    k: &Intrinsics,
    views: &[(&Pose, [f64; 2])],
) -> Option<Vector3<f64>> {
    if views.len() < 2 {
        return None;
    }
    let ps: Vec<Matrix3x4<f64>> = views.iter().map(|(p, _)| p_matrix(k, p)).collect();
    let xs: Vec<Point2<f64>> = views.iter().map(|(_, x)| Point2::new(x[0], x[1])).collect();
    let x0 = vfxgraph_geometry::two_view::triangulate_linear_n(&ps, &xs).ok()?;
    let lm = vfxgraph_geometry::optimize::LmOptions {
        max_iterations: 10,
        ..Default::default()
    };
    let x = vfxgraph_geometry::two_view::triangulate_nonlinear(&ps, &xs, &x0, &lm).unwrap_or(x0);
    let v = x.coords;
    if !v.iter().all(|c| c.is_finite()) {
        return None;
    }
    if views.iter().any(|(p, _)| (p.r * v + p.t).z <= 0.0) {
        return None;
    }
    Some(v)
}

/// Observations of one track in frame indices `range` (all of them, in order), or `None` if the
/// track is not seen in every frame of the range.
pub(crate) fn through(
    track: &vfxgraph_klt::Track,
    first: usize,
    last: usize,
) -> Option<&[[f64; 2]]> {
    if track.first <= first && track.end() > last {
        Some(&track.points[first - track.first..=last - track.first])
    } else {
        None
    }
}

/// A per-purpose seed: the options' seed mixed with a stage tag and an index (splitmix64), so that
/// parallel stages draw independent, reproducible streams.
pub(crate) fn derive_seed(seed: u64, tag: u64, index: u64) -> u64 {
    let mut z =
        seed ^ tag.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A camera path from per-frame-index poses; every frame must have one.
pub(crate) fn path_from_poses(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
) -> Result<CameraPath> {
    let mut frames = Vec::with_capacity(poses.len());
    for (i, p) in poses.iter().enumerate() {
        let Some(p) = p else {
            return Err(VisionError::Degenerate(format!(
                "frame {} has no camera",
                tracks.frames[i]
            )));
        };
        if !(p.r.iter().chain(p.t.iter()).all(|v| v.is_finite())) {
            return Err(VisionError::Degenerate(format!(
                "frame {}: the solved camera is not finite",
                tracks.frames[i]
            )));
        }
        let frame = usize::try_from(tracks.frames[i]).map_err(|_| {
            VisionError::InvalidInput(format!("negative frame number {}", tracks.frames[i]))
        })?;
        frames.push(FramePose {
            frame,
            pose: p.clone(),
            focal: None,
        });
    }
    Ok(CameraPath {
        frames,
        intrinsics: Some(k.clone()),
    })
}

/// Poses of a camera path by frame index of `tracks` (`None` where the path has no camera).
pub fn poses_by_index(tracks: &Tracks, path: &CameraPath) -> Vec<Option<Pose>> {
    let by_frame: std::collections::HashMap<i64, &Pose> = path
        .frames
        .iter()
        .map(|f| (f.frame as i64, &f.pose))
        .collect();
    tracks
        .frames
        .iter()
        .map(|f| by_frame.get(f).map(|p| (*p).clone()))
        .collect()
}

/// The solve's final decision on every observation, by track index and observation: an inlier
/// when its frame has a camera, its track a point, and its reprojection error is at most
/// `tolerance` px in the final cameras and points. This is the rule every outlier-marking
/// stage applies (the relaxation's re-marking of §7.14, the global adjustment's rounds, the
/// refinement cycles of §7.9), applied once more to the result at the stage's last tolerance.
pub(crate) fn inlier_marks(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    tolerance: f64,
) -> Vec<Vec<bool>> {
    tracks
        .tracks
        .iter()
        .zip(points)
        .map(|(t, x)| {
            t.points
                .iter()
                .enumerate()
                .map(|(j, obs)| match (x, poses.get(t.first + j)) {
                    (Some(x), Some(Some(p))) => reprojection_error(k, p, x, obs) <= tolerance,
                    _ => false,
                })
                .collect()
        })
        .collect()
}

/// A point cloud from points keyed by track index, with each point's RMS error over its inlier
/// observations (`marks`, from [`inlier_marks`]) and the frames of those observations.
pub(crate) fn cloud_from_points(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    marks: &[Vec<bool>],
) -> PointCloud {
    let mut cloud = PointCloud::default();
    for ((t, x), m) in tracks.tracks.iter().zip(points).zip(marks) {
        let Some(x) = x else { continue };
        let (mut s, mut frames) = (0.0, Vec::new());
        for (j, obs) in t.points.iter().enumerate() {
            if let (true, Some(Some(p))) = (m[j], poses.get(t.first + j)) {
                s += reprojection_error(k, p, x, obs).powi(2);
                frames.push(tracks.frames[t.first + j]);
            }
        }
        cloud.points.push([x.x, x.y, x.z]);
        cloud.track_ids.push(t.id);
        cloud.errors.push(if frames.is_empty() {
            f64::NAN
        } else {
            (s / frames.len() as f64).sqrt()
        });
        cloud.inlier_frames.push(frames);
    }
    cloud
}

/// Points keyed by track index from a cloud (tracks without a point get `None`).
pub fn points_by_track(tracks: &Tracks, cloud: &PointCloud) -> Vec<Option<Vector3<f64>>> {
    let by_id: std::collections::HashMap<u64, [f64; 3]> = cloud
        .track_ids
        .iter()
        .copied()
        .zip(cloud.points.iter().copied())
        .collect();
    tracks
        .tracks
        .iter()
        .map(|t| by_id.get(&t.id).map(|p| Vector3::new(p[0], p[1], p[2])))
        .collect()
}
