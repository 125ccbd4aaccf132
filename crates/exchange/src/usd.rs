//! A `.usda` stage: an animated `UsdGeom.Camera` (one `xformOp:transform` time sample per solved
//! frame) and a `UsdGeom.Points` prim with the cloud.
//!
//! The stage is Y up with `metersPerUnit = 0.01` (USD's fallback); `scale` takes solve units to
//! these scene units. USD gives focal length and apertures in tenths of a scene unit, here
//! millimetres: focalLength = f1 · 36 / W, horizontalAperture = [`FILM_BACK_MM`](super::FILM_BACK_MM),
//! verticalAperture = H · focalLength / f2, and the aperture offsets put the principal point
//! (cx, cy) = (u0 + ½, v0 + ½) (corner origin, y down) where USD's frustum puts the optical axis:
//! horizontalApertureOffset = (W/2 − cx) · hAperture / W, verticalApertureOffset =
//! (cy − H/2) · vAperture / H. Matrices are written in USD's row-vector layout (translation in
//! the last row). The camera looks down −Z with +Y up.
//!
//! USD's camera is an ideal pinhole; a lens is written as custom attributes on the camera prim
//! (USD has no distortion schema), in the namespace `vfxgraph:lens:`:
//!
//! | attribute | type | meaning |
//! | --- | --- | --- |
//! | `vfxgraph:lens:model` | `string` | `brown_conrady` or `division` (absent: a pinhole) |
//! | `vfxgraph:lens:k1`, `k2`, `k3`, `p1`, `p2` | `double` | Brown–Conrady (OpenCV's coefficients) |
//! | `vfxgraph:lens:k1`, `k2` | `double` | division: p = q / (1 + k1 \|q\|² + k2 \|q\|⁴) |
//! | `vfxgraph:lens:focalPixels` | `double2` | (f1, f2), px |
//! | `vfxgraph:lens:principalPointPixels` | `double2` | (cx, cy), px, origin at the top-left *corner*, y down |
//! | `vfxgraph:lens:imageSize` | `int2` | the plate's (W, H) |
//! | `vfxgraph:lens:stMap` | `asset` | optional: an ST-map of the lens, relative to the stage |
//!
//! The plate's pixel of a camera-space point X (looking down −Z, so the normalized undistorted
//! point is p = (X.x / −X.z, −X.y / −X.z) with y down) is (cx, cy) + (f1, f2) ⊙ d(p), d the model
//! on normalized coordinates ([`vfxgraph_lens`]); the frustum above renders the undistorted
//! image, the same K without d.

use std::fmt::Write as _;

use super::{SceneOptions, Shot, TargetUp, FILM_BACK_MM, N};
use vfxgraph_geometry::error::Result;
use vfxgraph_lens::Distortion;

/// The lens parameters of the USD camera (tenths of a scene unit).
#[derive(Clone, Debug, PartialEq)]
pub struct UsdLens {
    /// focalLength.
    pub focal_length: f64,
    /// horizontalAperture.
    pub horizontal_aperture: f64,
    /// verticalAperture.
    pub vertical_aperture: f64,
    /// horizontalApertureOffset.
    pub horizontal_aperture_offset: f64,
    /// verticalApertureOffset.
    pub vertical_aperture_offset: f64,
}

/// The USD lens of a shot's K.
pub fn lens(shot: &Shot) -> Result<UsdLens> {
    shot.require_no_skew("USD")?;
    let (w, h) = shot.size()?;
    let (w, h) = (w as f64, h as f64);
    let k = &shot.intrinsics;
    let focal = k.f1 * FILM_BACK_MM / w;
    let va = h * focal / k.f2;
    Ok(UsdLens {
        focal_length: focal,
        horizontal_aperture: FILM_BACK_MM,
        vertical_aperture: va,
        horizontal_aperture_offset: (w / 2.0 - (k.u0 + 0.5)) * FILM_BACK_MM / w,
        vertical_aperture_offset: ((k.v0 + 0.5) - h / 2.0) * va / h,
    })
}

/// The camera's `focalLength` line(s): one value, or for a zoom (the path carries per-frame focal lengths) one
/// time sample per frame (the film back is fixed, so the apertures stay).
fn focal_attribute(shot: &Shot, o: &SceneOptions, l: &UsdLens) -> Result<String> {
    if !shot.path.zooms() {
        return Ok(format!("        float focalLength = {}\n", l.focal_length));
    }
    let (w, _) = shot.size()?;
    let mut s = String::from("        float focalLength.timeSamples = {\n");
    for (i, f) in shot.path.frames.iter().enumerate() {
        let mm = shot.intrinsics_at(i).f1 * FILM_BACK_MM / w as f64;
        let _ = writeln!(s, "            {}: {mm},", o.target_frame(f.frame));
    }
    s.push_str("        }\n");
    Ok(s)
}

/// The stage text.
pub fn stage(shot: &Shot, o: &SceneOptions) -> Result<String> {
    shot.validate()?;
    o.validate()?;
    let l = lens(shot)?;
    let (near, far) = shot.clip_range();
    let (first, last) = match (shot.path.frames.first(), shot.path.frames.last()) {
        (Some(a), Some(b)) => (o.target_frame(a.frame), o.target_frame(b.frame)),
        _ => (o.start_frame, o.start_frame),
    };
    let mut s = String::new();
    let _ = write!(
        s,
        r#"#usda 1.0
(
    defaultPrim = "World"
    doc = "vfxgraph export_cameras (format usd): solved camera and point cloud"
    endTimeCode = {last}
    framesPerSecond = {fps}
    metersPerUnit = 0.01
    startTimeCode = {first}
    timeCodesPerSecond = {fps}
    upAxis = "Y"
)

def Xform "World"
{{
    def Camera "camera"
    {{
        float2 clippingRange = ({}, {})
{}        float horizontalAperture = {}
        float horizontalApertureOffset = {}
        token projection = "perspective"
        float verticalAperture = {}
        float verticalApertureOffset = {}
{}        matrix4d xformOp:transform.timeSamples = {{
"#,
        near * o.scale,
        far * o.scale,
        focal_attribute(shot, o, &l)?,
        l.horizontal_aperture,
        l.horizontal_aperture_offset,
        l.vertical_aperture,
        l.vertical_aperture_offset,
        lens_attributes(shot)?,
        fps = o.fps,
    );
    for f in &shot.path.frames {
        let m = o.camera_to_world(TargetUp::Y, &f.pose);
        let row = |c: usize| {
            format!(
                "({}, {}, {}, {})",
                N(m[(0, c)]),
                N(m[(1, c)]),
                N(m[(2, c)]),
                N(m[(3, c)])
            )
        };
        let _ = writeln!(
            s,
            "            {}: ({}, {}, {}, {}),",
            o.target_frame(f.frame),
            row(0),
            row(1),
            row(2),
            row(3)
        );
    }
    s.push_str(
        "        }\n        uniform token[] xformOpOrder = [\"xformOp:transform\"]\n    }\n",
    );
    if let Some(cloud) = &shot.cloud {
        let pts: Vec<String> = shot
            .points()
            .iter()
            .map(|p| {
                let x = o.point(TargetUp::Y, p);
                format!("({}, {}, {})", x.x, x.y, x.z)
            })
            .collect();
        let _ = write!(
            s,
            "\n    def Points \"points\"\n    {{\n        point3f[] points = [{}]\n",
            pts.join(", ")
        );
        let width = 0.002 * (far - near) * o.scale;
        let _ = writeln!(
            s,
            "        float[] widths = [{}]",
            vec![width.to_string(); cloud.points.len()].join(", ")
        );
        if let Some(cols) = &shot.colors {
            let c: Vec<String> = cols
                .iter()
                .map(|c| {
                    let l = c.map(vfxgraph_imaging::color::srgb8_to_linear);
                    format!("({}, {}, {})", l[0], l[1], l[2])
                })
                .collect();
            let _ = writeln!(
                s,
                "        color3f[] primvars:displayColor = [{}] (\n            interpolation = \"vertex\"\n        )",
                c.join(", ")
            );
        }
        s.push_str("    }\n");
    }
    s.push_str("}\n");
    Ok(s)
}

/// The `vfxgraph:lens:*` attributes of the camera prim (module docs); empty for a pinhole
/// without an ST-map.
pub fn lens_attributes(shot: &Shot) -> Result<String> {
    let k = &shot.intrinsics;
    let (w, h) = shot.size()?;
    let mut s = String::new();
    if !k.is_pinhole() {
        let names: &[&str] = match k.distortion {
            Distortion::BrownConrady { .. } => &["k1", "k2", "k3", "p1", "p2"],
            Distortion::Division { .. } => &["k1", "k2"],
            Distortion::None => &[],
        };
        let _ = writeln!(
            s,
            "        custom string vfxgraph:lens:model = \"{}\"",
            k.distortion.name()
        );
        for (n, v) in names.iter().zip(k.distortion.params()) {
            let _ = writeln!(s, "        custom double vfxgraph:lens:{n} = {}", N(v));
        }
        let _ = writeln!(
            s,
            "        custom double2 vfxgraph:lens:focalPixels = ({}, {})\n        \
             custom double2 vfxgraph:lens:principalPointPixels = ({}, {})\n        \
             custom int2 vfxgraph:lens:imageSize = ({w}, {h})",
            N(k.f1),
            N(k.f2),
            N(k.u0 + 0.5),
            N(k.v0 + 0.5)
        );
    }
    if let Some(st) = &shot.st_map {
        if st.contains('@') {
            return Err(vfxgraph_geometry::error::VisionError::InvalidInput(
                format!("an ST-map path cannot hold `@` in USD: {st}"),
            ));
        }
        let _ = writeln!(s, "        custom asset vfxgraph:lens:stMap = @{st}@");
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;

    /// USD's frustum formulas (GfCamera: window = offset ± aperture/2 at distance focal) give
    /// back K.
    #[test]
    fn lens_reproduces_k() {
        let s = shot();
        let l = lens(&s).unwrap();
        let k = &s.intrinsics;
        let (w, h) = (1280.0, 720.0);
        let f1 = l.focal_length / l.horizontal_aperture * w;
        let f2 = l.focal_length / l.vertical_aperture * h;
        assert!((f1 - k.f1).abs() < 1e-9 && (f2 - k.f2).abs() < 1e-9);
        // Optical axis: left edge of the window at (offset − A/2)/focal.
        let cx = (l.horizontal_aperture / 2.0 - l.horizontal_aperture_offset)
            / l.horizontal_aperture
            * w;
        let cy = (l.vertical_aperture_offset + l.vertical_aperture / 2.0) / l.vertical_aperture * h;
        assert!((cx - (k.u0 + 0.5)).abs() < 1e-9 && (cy - (k.v0 + 0.5)).abs() < 1e-9);
        let text = stage(&s, &SceneOptions::default()).unwrap();
        assert!(text.starts_with("#usda 1.0\n"));
        assert_eq!(text.matches("): ((").count(), 0);
        assert_eq!(
            text.lines()
                .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit())
                    && l.contains(": (("))
                .count(),
            12
        );
    }

    /// A zoom's stage animates the focal length: one time sample per frame, each frame's
    /// focal length in millimetres of the fixed film back; Blender's script keyframes the same
    /// lens, Nuke's .chan the vertical field of view.
    #[test]
    fn a_zoom_is_a_time_sampled_focal_length() {
        let mut s = shot();
        for (i, f) in s.path.frames.iter_mut().enumerate() {
            f.focal = Some(1000.0 + 25.0 * i as f64);
        }
        let o = SceneOptions::default();
        let text = stage(&s, &o).unwrap();
        assert!(text.contains("float focalLength.timeSamples = {"), "{text}");
        assert!(!text.contains("float focalLength = "));
        let py = super::super::blender::script(&s, &o).unwrap();
        let chan = super::super::nuke::chan(&s, &o).unwrap();
        for (i, f) in s.path.frames.iter().enumerate() {
            let mm = (1000.0 + 25.0 * i as f64) * FILM_BACK_MM / 1280.0;
            let line = format!("{}: {mm},", o.target_frame(f.frame));
            assert!(text.contains(&line), "{line}");
            let key = format!("    ({}, {}),", o.target_frame(f.frame), N(mm));
            assert!(py.contains(&key), "{key}");
            // vfov = 2 atan(h / 2f₂), f₂ scaled with the frame's focal length.
            let f2 = s.intrinsics.f2 * (1000.0 + 25.0 * i as f64) / s.intrinsics.f1;
            let vfov = 2.0 * (720.0 / (2.0 * f2)).atan().to_degrees();
            let row = chan.lines().nth(i).unwrap();
            let last: f64 = row.split_whitespace().last().unwrap().parse().unwrap();
            assert!((last - vfov).abs() < 1e-9, "{row} vs {vfov}");
        }
    }
}
