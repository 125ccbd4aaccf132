//! A Python script for Blender that builds the solved shot: an animated camera (lens, sensor,
//! shift from the principal point, clip planes, one key per solved frame), the point cloud as a
//! mesh of vertices (with a `Col` colour attribute), the plate as the camera's background image
//! sequence, the render size, pixel aspect, fps and frame range.
//!
//! Blender's camera looks down its local −Z with +Y up; the world is Z up. The film back is
//! [`FILM_BACK_MM`](super::FILM_BACK_MM) wide with the sensor fit `HORIZONTAL`, so
//! lens = f1 · 36 / W; the vertical focal length comes from the pixel aspect
//! (aspect_y / aspect_x = f1 / f2), and Blender's shift, in units of the image width, puts the
//! principal point (cx, cy) = (u0 + ½, v0 + ½) (corner origin):
//! shift_x = (W/2 − cx)/W, shift_y = (f1/f2)(cy − H/2)/W.
//! Run it with `blender --python camera.py`, or `exec` it in Blender's Python (or in `bpy`).
//!
//! A lens goes on the movie clip's tracking camera (`MovieTrackingCamera`, what Blender's Movie
//! Distortion node and its solver use): the script loads the plate as a movie clip and calls
//! `tracking_camera(clip)`, which sets focal length and principal point in pixels
//! (`principal_point_pixels` has its origin at the bottom-left corner: (cx, H − cy)) and the
//! model. Conventions measured in bpy 5.0.1 through its Movie Distortion node
//! (`scripts/check/blender_check.py`): `BROWN` is OpenCV's formula on y-up normalized
//! coordinates with the tangential coefficients named the other way round, so ours map as
//! brown_k1..k3 = k1..k3, brown_k4 = 0, **brown_p1 = p2, brown_p2 = −p1**; its `DIVISION` is not
//! Fitzgibbon's (the node's distortion with division_k1, k2 equals the polynomial
//! u · (1 + k1 r² + k2 r⁴) of the *undistorted* radius), so our division lens is written as
//! `BROWN` with its radial refit k1..k4 ([`super::lens_fit`], the fit error in the script). The
//! camera's K and render size stay the plate's: the scene camera renders the undistorted
//! (pinhole) image, the clip's distortion maps it onto the plate. Non-square pixels with a lens
//! are refused (Blender's pixel-aspect handling in the tracking camera did not match any
//! convention we tested).

use std::fmt::Write as _;

use super::{continuous_quaternions, lens_fit, SceneOptions, Shot, TargetUp, FILM_BACK_MM, N};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_lens::Distortion;

/// The lens and film parameters of the Blender camera for a shot (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct BlenderCamera {
    /// Focal length, mm.
    pub lens: f64,
    /// Sensor width, mm (fit `HORIZONTAL`).
    pub sensor_width: f64,
    /// Horizontal shift (fraction of the width).
    pub shift_x: f64,
    /// Vertical shift (fraction of the width).
    pub shift_y: f64,
    /// Pixel aspect (x, y), both ≥ 1 as Blender requires.
    pub pixel_aspect: (f64, f64),
}

/// The Blender camera of a shot's K.
pub fn camera(shot: &Shot) -> Result<BlenderCamera> {
    shot.require_no_skew("Blender")?;
    let (w, h) = shot.size()?;
    let (w, h) = (w as f64, h as f64);
    let k = &shot.intrinsics;
    let ycor = k.f1 / k.f2;
    let (cx, cy) = (k.u0 + 0.5, k.v0 + 0.5);
    Ok(BlenderCamera {
        lens: k.f1 * FILM_BACK_MM / w,
        sensor_width: FILM_BACK_MM,
        shift_x: (w / 2.0 - cx) / w,
        shift_y: ycor * (cy - h / 2.0) / w,
        pixel_aspect: if ycor >= 1.0 {
            (1.0, ycor)
        } else {
            (1.0 / ycor, 1.0)
        },
    })
}

/// The movie clip's tracking camera for a shot's lens (see the module doc); `None` for a
/// pinhole.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackingCamera {
    /// Focal length, px.
    pub focal_pixels: f64,
    /// Principal point, px, origin at the bottom-left corner (Blender's).
    pub principal_point_pixels: (f64, f64),
    /// brown_k1..brown_k4.
    pub k: [f64; 4],
    /// brown_p1, brown_p2 (Blender's names).
    pub p: [f64; 2],
    /// The refit's largest error (px) when our lens had no Blender model.
    pub fit_error_px: Option<f64>,
}

/// The tracking camera of a shot's lens (module doc).
pub fn tracking_camera(shot: &Shot) -> Result<Option<TrackingCamera>> {
    let k = &shot.intrinsics;
    if k.is_pinhole() {
        return Ok(None);
    }
    shot.require_no_skew("Blender")?;
    if k.f1 != k.f2 {
        return Err(VisionError::InvalidInput(format!(
            "Blender's tracking camera: a lens with non-square pixels (f1 = {}, f2 = {}) is not \
             supported; export an ST-map instead",
            k.f1, k.f2
        )));
    }
    let (_, h) = shot.size()?;
    let (kk, p, fit_error_px) = match k.distortion {
        Distortion::BrownConrady { k1, k2, k3, p1, p2 } => ([k1, k2, k3, 0.0], [p2, -p1], None),
        Distortion::Division { .. } => {
            let fit = lens_fit::radial_polynomial_within(k, 4, "Blender")?;
            (
                [fit.k[0], fit.k[1], fit.k[2], fit.k[3]],
                [0.0, 0.0],
                Some(fit.max_error_px),
            )
        }
        Distortion::None => return Ok(None),
    };
    Ok(Some(TrackingCamera {
        focal_pixels: k.f1,
        principal_point_pixels: (k.u0 + 0.5, h as f64 - (k.v0 + 0.5)),
        k: kk,
        p,
        fit_error_px,
    }))
}

/// The script.
pub fn script(shot: &Shot, o: &SceneOptions) -> Result<String> {
    shot.validate()?;
    o.validate()?;
    if shot.path.zooms() && !shot.intrinsics.is_pinhole() {
        return Err(vfxgraph_geometry::error::VisionError::InvalidInput(
            "the camera path zooms through a lens: Blender's movie-clip tracking camera holds one \
             focal length, so a zoom with distortion is not exported to Blender"
                .into(),
        ));
    }
    let cam = camera(shot)?;
    let lens = tracking_camera(shot)?;
    let (w, h) = shot.size()?;
    let (near, far) = shot.clip_range();
    let mats: Vec<_> = shot
        .path
        .frames
        .iter()
        .map(|f| o.camera_to_world(TargetUp::Z, &f.pose))
        .collect();
    let rots: Vec<_> = mats
        .iter()
        .map(|m| m.fixed_view::<3, 3>(0, 0).into_owned())
        .collect();
    let quats = continuous_quaternions(&rots);
    let fps_int = o.fps.round().max(1.0);

    let mut s = String::new();
    let _ = write!(
        s,
        r#"# Generated by vfxgraph export_cameras (format blender): the solved camera, points and plate.
# Run: blender --python THIS_FILE   (or exec() it in Blender's Python console / in bpy)
import os

import bpy

try:
    HERE = os.path.dirname(os.path.abspath(__file__))
except NameError:
    HERE = os.getcwd()

WIDTH, HEIGHT = {w}, {h}
PIXEL_ASPECT = ({}, {})
FPS, FPS_BASE = {}, {}
LENS, SENSOR_WIDTH = {}, {}
SHIFT = ({}, {})
CLIP = ({}, {})
# The lens, for the movie clip's tracking camera (None: a pinhole). Blender's BROWN names the
# tangential terms the other way round: brown_p1 = our p2, brown_p2 = -(our p1).
DISTORTION = {}
"#,
        cam.pixel_aspect.0,
        cam.pixel_aspect.1,
        fps_int as i64,
        fps_int / o.fps,
        cam.lens,
        cam.sensor_width,
        cam.shift_x,
        cam.shift_y,
        near * o.scale,
        far * o.scale,
        match &lens {
            None => "None".to_string(),
            Some(l) => format!(
                "{{\"model\": \"BROWN\", \"focal_pixels\": {}, \"principal_point_pixels\": ({}, {}), \
                 \"k\": ({}, {}, {}, {}), \"p\": ({}, {}), \"ours\": {}, \"fit_error_px\": {}}}",
                N(l.focal_pixels),
                N(l.principal_point_pixels.0),
                N(l.principal_point_pixels.1),
                N(l.k[0]),
                N(l.k[1]),
                N(l.k[2]),
                N(l.k[3]),
                N(l.p[0]),
                N(l.p[1]),
                py_str(shot.intrinsics.distortion.name()),
                l.fit_error_px.map_or("None".to_string(), |e| N(e).to_string()),
            ),
        },
    );
    s.push_str(
        "# (frame, location xyz, rotation quaternion wxyz) in Blender's world (Z up)\nKEYS = [\n",
    );
    for ((f, m), q) in shot.path.frames.iter().zip(&mats).zip(&quats) {
        let _ = writeln!(
            s,
            "    ({}, ({}, {}, {}), ({}, {}, {}, {})),",
            o.target_frame(f.frame),
            N(m[(0, 3)]),
            N(m[(1, 3)]),
            N(m[(2, 3)]),
            N(q[0]),
            N(q[1]),
            N(q[2]),
            N(q[3])
        );
    }
    s.push_str(
        "]\n# A zoom: (frame, lens mm) keyframed on the camera (empty: LENS throughout)\n\
         LENS_KEYS = [\n",
    );
    if shot.path.zooms() {
        let (w, _) = shot.size()?;
        for (i, f) in shot.path.frames.iter().enumerate() {
            let mm = shot.intrinsics_at(i).f1 * FILM_BACK_MM / w as f64;
            let _ = writeln!(s, "    ({}, {}),", o.target_frame(f.frame), N(mm));
        }
    }
    s.push_str("]\nPOINTS = [\n");
    for p in shot.points() {
        let x = o.point(TargetUp::Z, &p);
        let _ = writeln!(s, "    ({}, {}, {}),", x.x, x.y, x.z);
    }
    s.push_str("]\nCOLORS = [\n");
    if let Some(cols) = &shot.colors {
        for c in cols {
            let l = c.map(vfxgraph_imaging::color::srgb8_to_linear);
            let _ = writeln!(s, "    ({}, {}, {}),", l[0], l[1], l[2]);
        }
    }
    s.push_str("]\n");
    match shot.path.frames.first() {
        Some(first) => {
            let _ = writeln!(
                s,
                "PLATE = {}  # first image of the plate, relative to this script\nPLATE_FRAMES = {}\nPLATE_START = {}",
                shot.image_name(first.frame)
                    .map_or("None".to_string(), |n| py_str(&n)),
                shot.path.frames.last().map_or(0, |l| l.frame - first.frame + 1),
                o.target_frame(first.frame)
            );
        }
        None => s.push_str("PLATE = None\nPLATE_FRAMES = 0\nPLATE_START = 1\n"),
    }
    s.push_str(BODY);
    Ok(s)
}

fn py_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "None".into())
}

const BODY: &str = r#"

def tracking_camera(clip):
    """Sets the movie clip's tracking camera to DISTORTION (see DISTORTION above)."""
    if DISTORTION is None:
        return
    cam = clip.tracking.camera
    cam.units = "PIXELS"
    cam.pixel_aspect = 1.0
    cam.distortion_model = DISTORTION["model"]
    cam.focal_length_pixels = DISTORTION["focal_pixels"]
    cam.principal_point_pixels = DISTORTION["principal_point_pixels"]
    cam.brown_k1, cam.brown_k2, cam.brown_k3, cam.brown_k4 = DISTORTION["k"]
    cam.brown_p1, cam.brown_p2 = DISTORTION["p"]


def build():
    scene = bpy.context.scene
    for name in ("vfxgraph_camera", "vfxgraph_points"):
        old = bpy.data.objects.get(name)
        if old is not None:
            bpy.data.objects.remove(old, do_unlink=True)
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = PIXEL_ASPECT
    scene.render.fps, scene.render.fps_base = FPS, FPS_BASE
    if KEYS:
        scene.frame_start, scene.frame_end = KEYS[0][0], KEYS[-1][0]

    data = bpy.data.cameras.new("vfxgraph_camera")
    data.type = "PERSP"
    data.lens_unit = "MILLIMETERS"
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = SENSOR_WIDTH
    data.sensor_height = SENSOR_WIDTH * HEIGHT * PIXEL_ASPECT[1] / (WIDTH * PIXEL_ASPECT[0])
    data.lens = LENS
    data.shift_x, data.shift_y = SHIFT
    data.clip_start, data.clip_end = CLIP
    cam = bpy.data.objects.new("vfxgraph_camera", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_mode = "QUATERNION"
    for frame, loc, quat in KEYS:
        cam.location = loc
        cam.rotation_quaternion = quat
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_quaternion", frame=frame)
    for frame, lens in LENS_KEYS:
        data.lens = lens
        data.keyframe_insert("lens", frame=frame)
    for anim in (cam.animation_data, data.animation_data):
        if anim is None or anim.action is None:
            continue
        fcurves = getattr(anim.action, "fcurves", None)
        if fcurves is None:  # Blender 4.4+ layered actions
            fcurves = [fc for layer in anim.action.layers for strip in layer.strips
                       for bag in strip.channelbags for fc in bag.fcurves]
        for fc in fcurves:
            for kp in fc.keyframe_points:
                kp.interpolation = "LINEAR"

    if POINTS:
        mesh = bpy.data.meshes.new("vfxgraph_points")
        mesh.from_pydata(POINTS, [], [])
        if COLORS:
            attr = mesh.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
            attr.data.foreach_set("color", [v for c in COLORS for v in (c[0], c[1], c[2], 1.0)])
        mesh.update()
        pts = bpy.data.objects.new("vfxgraph_points", mesh)
        scene.collection.objects.link(pts)

    if PLATE is not None:
        path = os.path.join(HERE, PLATE)
        if os.path.exists(path):
            img = bpy.data.images.load(path, check_existing=True)
            img.source = "SEQUENCE"
            bg = data.background_images.new()
            bg.image = img
            bg.image_user.frame_start = PLATE_START
            bg.image_user.frame_duration = PLATE_FRAMES
            data.show_background_images = True
            if DISTORTION is not None:
                clip = bpy.data.movieclips.load(path, check_existing=True)
                clip.frame_start = PLATE_START
                tracking_camera(clip)
                scene.active_clip = clip
        else:
            print("vfxgraph: plate image %s not found; no background image" % path)
    return cam


build()
"#;

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;

    /// The camera parameters reproduce K through Blender's view-plane formulas (written out
    /// here from the module doc): f1 = lens·W/sensor, f2 = f1·aspect_x/aspect_y,
    /// cx = W/2 − shift_x·W, cy = H/2 + shift_y·W·aspect_x/aspect_y.
    #[test]
    fn camera_reproduces_k() {
        let s = shot();
        let c = camera(&s).unwrap();
        let k = &s.intrinsics;
        let (w, h) = (1280.0, 720.0);
        let ycor = c.pixel_aspect.1 / c.pixel_aspect.0;
        let f1 = c.lens * w / c.sensor_width;
        assert!((f1 - k.f1).abs() < 1e-9);
        assert!((f1 / ycor - k.f2).abs() < 1e-9);
        assert!((w / 2.0 - c.shift_x * w - (k.u0 + 0.5)).abs() < 1e-9);
        assert!((h / 2.0 + c.shift_y * w / ycor - (k.v0 + 0.5)).abs() < 1e-9);
        assert!(c.pixel_aspect.0 >= 1.0 && c.pixel_aspect.1 >= 1.0);
        let text = script(&s, &SceneOptions::default()).unwrap();
        assert!(text.contains("KEYS = [\n    (11, ("), "{text}");
        assert_eq!(text.matches("\n    (").count(), 12 + 40 + 40);
        assert!(text.contains("PLATE = \"plate/frame.0010.png\""));
        assert!(text.contains("\nDISTORTION = None\n"));
    }

    /// Our Brown–Conrady lens maps to Blender's BROWN with the tangential terms renamed and
    /// the principal point from the bottom; non-square pixels with a lens are refused.
    #[test]
    fn lens_goes_on_the_tracking_camera() {
        let mut s = shot();
        let d = Distortion::BrownConrady {
            k1: -0.16,
            k2: 0.045,
            k3: 0.001,
            p1: 8e-4,
            p2: -5e-4,
        };
        s.intrinsics = s.intrinsics.clone().with_distortion(d);
        assert!(tracking_camera(&s)
            .unwrap_err()
            .to_string()
            .contains("square"));
        s.intrinsics.f2 = s.intrinsics.f1;
        let t = tracking_camera(&s).unwrap().unwrap();
        assert_eq!(t.k, [-0.16, 0.045, 0.001, 0.0]);
        assert_eq!(t.p, [-5e-4, -8e-4]);
        assert_eq!(t.principal_point_pixels, (651.75, 720.0 - 348.25));
        let text = script(&s, &SceneOptions::default()).unwrap();
        assert!(text.contains("\"p\": (-0.0005, -0.0008)"), "{text}");
    }
}
