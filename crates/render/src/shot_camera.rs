//! The camera that renders one frame of a shot (book §2.8): the scene's own camera, or a solved
//! camera path's pose of that frame with K from a solved lens, the path or the scene camera,
//! then an [`ImageSize`] override. What the `render`, `differential_render` and `fit_catcher`
//! nodes see through; the render crate knows no camera-path type, so a path comes as
//! [`PathPose`]s and a solved K as [`SolvedK`].

use vfxgraph_lens::Distortion;

use crate::camera::{Camera, CameraError, ImageSize};

/// A solved K from outside the scene (a calibration or a solve), with its image size when
/// known and its lens.
#[derive(Clone, Debug, PartialEq)]
pub struct SolvedK {
    /// K (rows): [[f1, s, u0], [0, f2, v0], [0, 0, 1]].
    pub k: [[f64; 3]; 3],
    /// The image size (width, height) K belongs to, when known.
    pub size: Option<(usize, usize)>,
    /// The solved lens: a render then traces the plate's own (distorted) pixels.
    pub distortion: Distortion,
}

/// One frame's pose of a solved camera path.
#[derive(Clone, Debug, PartialEq)]
pub struct PathPose {
    /// The frame number.
    pub frame: i64,
    /// Rotation world → camera (rows).
    pub r: [[f64; 3]; 3],
    /// Translation: the camera maps X to RX + t.
    pub t: [f64; 3],
    /// This frame's focal length (x, px) when the lens zooms; the aspect f2/f1 is kept.
    pub focal: Option<f64>,
}

/// Why a frame of a shot has no camera.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShotCameraError {
    /// No scene camera and no path.
    #[error(
        "no camera: the scene has no `camera:` and no `cameras` input is connected \
         (connect a camera path, or give the scene a camera)"
    )]
    NoCamera,
    /// No scene camera, and no K for the path.
    #[error(
        "no camera: the scene has no `camera:`, and neither the `cameras` path nor an \
         `intrinsics` input carries K"
    )]
    NoK,
    /// No scene camera, and K has no image size.
    #[error(
        "no camera: the scene has no `camera:` and K carries no image size (give \
         the scene a camera whose `size` is K's image size, or K with its size)"
    )]
    NoSize,
    /// A path, but no frame asked for.
    #[error(
        "the `cameras` input renders one frame per instance: set `per_frame: true` on \
         this render node"
    )]
    NotPerFrame,
    /// The path has no pose of the frame.
    #[error("the camera path has no camera for frame {frame} (it has {range}, {count} cameras)")]
    NoFrame {
        /// The frame asked for.
        frame: i64,
        /// "frames a–b" or "no frames".
        range: String,
        /// The path's number of cameras.
        count: usize,
    },
    /// The camera built is not valid.
    #[error("camera of this frame: {0}")]
    Camera(#[from] CameraError),
}

/// The camera of frame `frame` (`None`: the scene camera, an error when a `path` is given): the
/// scene's camera, or `path`'s pose of that frame with K from `k`, else the scene camera's (a
/// zooming frame's own focal length replacing K's, the aspect kept); then `size` applied. A
/// scene without a camera needs both the path and K with its image size.
pub fn camera_for_frame(
    scene_camera: Option<&Camera>,
    k: Option<&SolvedK>,
    path: Option<&[PathPose]>,
    frame: Option<i64>,
    size: &ImageSize,
) -> Result<Camera, ShotCameraError> {
    let mut camera = match (scene_camera, k, path) {
        (Some(c), _, _) => c.clone(),
        (None, _, None) => return Err(ShotCameraError::NoCamera),
        (None, None, Some(_)) => return Err(ShotCameraError::NoK),
        // K and the pose are set below, from K and the path.
        (None, Some(k), Some(_)) => match k.size {
            Some((width, height)) => Camera {
                k: [[0.0; 3]; 3],
                r: [[0.0; 3]; 3],
                t: [0.0; 3],
                width,
                height,
                distortion: Default::default(),
            },
            None => return Err(ShotCameraError::NoSize),
        },
    };
    if let Some(k) = k {
        camera.k = k.k;
        camera.distortion = k.distortion;
        if let Some((w, h)) = k.size {
            (camera.width, camera.height) = (w, h);
        }
    }
    if let Some(frames) = path {
        let f = frame.ok_or(ShotCameraError::NotPerFrame)?;
        let pose =
            frames
                .iter()
                .find(|p| p.frame == f)
                .ok_or_else(|| ShotCameraError::NoFrame {
                    frame: f,
                    range: match (frames.first(), frames.last()) {
                        (Some(a), Some(b)) => format!("frames {}–{}", a.frame, b.frame),
                        _ => "no frames".into(),
                    },
                    count: frames.len(),
                })?;
        if let Some(focal) = pose.focal {
            // A zoom: the frame's own focal length (the aspect kept).
            let aspect = camera.k[1][1] / camera.k[0][0];
            camera.k[0][0] = focal;
            camera.k[1][1] = focal * aspect;
        }
        (camera.r, camera.t) = (pose.r, pose.t);
    }
    camera.validate()?;
    Ok(size.apply(camera))
}
