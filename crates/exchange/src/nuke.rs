//! Nuke: a `.chan` file (one line per solved frame: frame, translate x y z, rotate x y z in
//! degrees for Nuke's default rotation order ZXY, vertical field of view in degrees) and the
//! film-back note that goes with it (apertures, focal length, principal point).
//!
//! The world is Y up (the scene transform of [`SceneOptions`]); the camera looks down −Z with +Y
//! up. Rotation order ZXY means the camera is turned about Z first, then X, then Y:
//! M = Ry · Rx · Rz (column vectors). Angles are unwrapped from frame to frame so curves do not
//! jump by 360°.
//!
//! A lens is described in the note's `Lens` section ([`lens_note`]): the model, its
//! coefficients and the formula on normalized coordinates (principal point and focal length in
//! pixels, y down), with how they map onto Nuke's LensDistortion and the ST-map to use with an
//! `STMap` node when one is given. The .chan's camera is the pinhole (undistorted) one. No Nuke
//! is available to check the note (unlike the COLMAP, Blender and USD exports, which are run in
//! their programs): the ST-map, whose convention is Nuke's own (STMap: red/green = the source
//! position normalized to 0–1, origin bottom-left), is the exact route.

use std::fmt::Write as _;

use nalgebra::Matrix3;

use super::{SceneOptions, Shot, TargetUp, FILM_BACK_MM, N};
use vfxgraph_geometry::error::Result;
use vfxgraph_lens::Distortion;

/// The angles (x, y, z) in radians of a rotation M = Ry(y) · Rx(x) · Rz(z).
pub fn euler_zxy(m: &Matrix3<f64>) -> [f64; 3] {
    let sx = (-m[(1, 2)]).clamp(-1.0, 1.0);
    let x = sx.asin();
    if sx.abs() < 1.0 - 1e-12 {
        [x, m[(0, 2)].atan2(m[(2, 2)]), m[(1, 0)].atan2(m[(1, 1)])]
    } else {
        // Gimbal lock (x = ±90°): only y ∓ z is defined; take z = 0.
        [x, (-m[(2, 0)]).atan2(m[(0, 0)]), 0.0]
    }
}

/// M = Ry · Rx · Rz of angles (x, y, z) in radians.
pub fn matrix_zxy(a: [f64; 3]) -> Matrix3<f64> {
    let (sx, cx) = a[0].sin_cos();
    let (sy, cy) = a[1].sin_cos();
    let (sz, cz) = a[2].sin_cos();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cx, -sx, 0.0, sx, cx);
    let ry = Matrix3::new(cy, 0.0, sy, 0.0, 1.0, 0.0, -sy, 0.0, cy);
    let rz = Matrix3::new(cz, -sz, 0.0, sz, cz, 0.0, 0.0, 0.0, 1.0);
    ry * rx * rz
}

/// The `.chan` text.
pub fn chan(shot: &Shot, o: &SceneOptions) -> Result<String> {
    shot.validate()?;
    o.validate()?;
    shot.require_no_skew("Nuke")?;
    if shot.path.zooms() && !shot.intrinsics.is_pinhole() {
        shot.require_fixed_focal("Nuke (a zoom through a lens)")?;
    }
    let (_, h) = shot.size()?;
    // A zoom's focal length is the vfov column, frame by frame.
    let vfov_at = |i: usize| {
        2.0 * (h as f64 / (2.0 * shot.intrinsics_at(i).f2))
            .atan()
            .to_degrees()
    };
    let mut s = String::new();
    let mut prev: Option<[f64; 3]> = None;
    for (i, f) in shot.path.frames.iter().enumerate() {
        let m = o.camera_to_world(TargetUp::Y, &f.pose);
        let r = m.fixed_view::<3, 3>(0, 0).into_owned();
        let mut a = euler_zxy(&r).map(f64::to_degrees);
        if let Some(p) = prev {
            for i in 0..3 {
                a[i] += 360.0 * ((p[i] - a[i]) / 360.0).round();
            }
        }
        prev = Some(a);
        let _ = writeln!(
            s,
            "{} {} {} {} {} {} {} {}",
            o.target_frame(f.frame),
            N(m[(0, 3)]),
            N(m[(1, 3)]),
            N(m[(2, 3)]),
            N(a[0]),
            N(a[1]),
            N(a[2]),
            N(vfov_at(i))
        );
    }
    Ok(s)
}

/// The film-back note: what to set on Nuke's Camera so the `.chan` projects as our K.
pub fn filmback_note(shot: &Shot, o: &SceneOptions) -> Result<String> {
    shot.require_no_skew("Nuke")?;
    let (w, h) = shot.size()?;
    let (wf, hf) = (w as f64, h as f64);
    let k = &shot.intrinsics;
    let focal = k.f1 * FILM_BACK_MM / wf;
    let vap = hf * focal / k.f2;
    let (cx, cy) = (k.u0 + 0.5, k.v0 + 0.5);
    Ok(format!(
        "vfxgraph export_cameras (format nuke): film back for the .chan file\n\
         \n\
         Camera node: rot_order ZXY, transform order SRT; import the .chan (File > Import chan file).\n\
         Its columns: frame, translate x y z, rotate x y z (degrees), vertical field of view (degrees).\n\
         \n\
         image size            {w} x {h} (pixel aspect {pa})\n\
         haperture (mm)        {FILM_BACK_MM}\n\
         vaperture (mm)        {vap}\n\
         focal (mm)            {focal}   (= vaperture / (2 tan(vfov/2))){zoom}\n\
         principal point (px)  {cx}, {cy}   (origin at the top-left corner, y down)\n\
         win_translate         {wu}, {wv}   (principal point offset in half-apertures; 0, 0 when centred)\n\
         \n\
         World: Y up; 1 solve unit = {scale} scene units; frame = {start} + solve frame; {fps} fps.\n\
         {lens}",
        lens = lens_note(shot)?,
        zoom = if shot.path.zooms() {
            "; the first frame's: the lens zooms, the .chan's vfov column animates it"
        } else {
            ""
        },
        pa = k.f2 / k.f1,
        wu = 2.0 * (cx - wf / 2.0) / wf,
        wv = -2.0 * (cy - hf / 2.0) / hf + 0.0,
        scale = o.scale,
        start = o.start_frame,
        fps = o.fps,
    ))
}

/// The note's lens section: empty for a pinhole without an ST-map (module docs).
pub fn lens_note(shot: &Shot) -> Result<String> {
    let k = &shot.intrinsics;
    let mut s = String::new();
    if !k.is_pinhole() {
        let (cx, cy) = (k.u0 + 0.5, k.v0 + 0.5);
        let _ = write!(
            s,
            "\nLens ({model}): the plate is distorted; the .chan camera renders the undistorted image.\n\
             focal (px)            {f1}, {f2}\n\
             centre (px)           {cx}, {cy}   (origin at the top-left corner, y down)\n\
             normalized point      x = (u - cx) / f1, y = (v - cy) / f2 (u, v: pixel, corner origin)\n",
            model = k.distortion.name(),
            f1 = N(k.f1),
            f2 = N(k.f2),
            cx = N(cx),
            cy = N(cy),
        );
        match k.distortion {
            Distortion::BrownConrady { k1, k2, k3, p1, p2 } => {
                let _ = write!(
                    s,
                    "coefficients          k1 {} k2 {} k3 {} p1 {} p2 {}\n\
                     model (undistorted p = (x, y) -> distorted q, OpenCV's):\n  \
                     r2 = x^2 + y^2, rho = 1 + k1 r2 + k2 r2^2 + k3 r2^3\n  \
                     q = rho p + (2 p1 x y + p2 (r2 + 2 x^2), p1 (r2 + 2 y^2) + 2 p2 x y)\n\
                     Nuke LensDistortion: a radial-tangential (Brown-Conrady) model with these \
                     coefficients, normalized by the focal length in pixels and centred on the \
                     principal point, applied undistorted -> distorted. Nuke's presets normalize \
                     differently and measure y up (flip the sign of p1 for y up); check the \
                     mapping on a grid before use, or use the ST-map below.\n",
                    N(k1),
                    N(k2),
                    N(k3),
                    N(p1),
                    N(p2)
                );
            }
            Distortion::Division { k1, k2 } => {
                let _ = write!(
                    s,
                    "coefficients          k1 {} k2 {}\n\
                     model (Fitzgibbon's division, distorted q -> undistorted p):\n  \
                     p = q / (1 + k1 |q|^2 + k2 |q|^4)\n\
                     Nuke LensDistortion: the same rational radial form as its distorted -> \
                     undistorted division model (denominator coefficients k1, k2, numerator 0) \
                     once normalized by the focal length in pixels about the principal point; \
                     Nuke's presets normalize differently: check on a grid, or use the ST-map.\n",
                    N(k1),
                    N(k2)
                );
            }
            Distortion::None => {}
        }
    }
    if let Some(st) = &shot.st_map {
        let _ = write!(
            s,
            "\nST-map                {st}\n\
             Use: Read the ST-map, then STMap (its stmap input the Read, uv = rgb) on the \
             undistorted render to put it through the lens (red/green hold the source position \
             normalized to 0-1, origin bottom-left: Nuke's STMap convention).\n"
        );
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;

    /// The chan's angles rebuild the camera-to-world rotation, its translation is the camera
    /// centre, and its vertical FOV gives f2.
    #[test]
    fn chan_rebuilds_the_camera() {
        let s = shot();
        let o = SceneOptions::default();
        let text = chan(&s, &o).unwrap();
        let lines: Vec<Vec<f64>> = text
            .lines()
            .map(|l| l.split(' ').map(|t| t.parse().unwrap()).collect())
            .collect();
        assert_eq!(lines.len(), 12);
        for (l, f) in lines.iter().zip(&s.path.frames) {
            assert_eq!(l[0] as i64, o.target_frame(f.frame));
            let m = o.camera_to_world(TargetUp::Y, &f.pose);
            let r = matrix_zxy([l[4].to_radians(), l[5].to_radians(), l[6].to_radians()]);
            assert!((r - m.fixed_view::<3, 3>(0, 0)).norm() < 1e-12);
            assert!((l[1] - m[(0, 3)]).abs() < 1e-12);
            let f2 = 360.0 / (l[7].to_radians() / 2.0).tan();
            assert!((f2 - s.intrinsics.f2).abs() < 1e-9);
        }
        assert!(filmback_note(&s, &o)
            .unwrap()
            .contains("haperture (mm)        36"));
    }

    /// The note carries the lens's model and coefficients (they read back as the same f64s)
    /// and the ST-map reference; a pinhole has no lens section.
    #[test]
    fn note_carries_the_lens_and_the_st_map() {
        let mut s = shot();
        let o = SceneOptions::default();
        assert!(!filmback_note(&s, &o).unwrap().contains("Lens"));
        s.intrinsics = s
            .intrinsics
            .clone()
            .with_distortion(Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: 0.0,
                p1: 8e-4,
                p2: -5e-4,
            });
        s.st_map = Some("lens/st_distort.exr".into());
        let note = filmback_note(&s, &o).unwrap();
        let line = note
            .lines()
            .find(|l| l.starts_with("coefficients"))
            .unwrap();
        let v: Vec<f64> = line
            .split_whitespace()
            .skip(1)
            .collect::<Vec<_>>()
            .chunks(2)
            .map(|c| c[1].parse().unwrap())
            .collect();
        assert_eq!(v, s.intrinsics.distortion.params());
        assert!(
            note.contains("ST-map                lens/st_distort.exr"),
            "{note}"
        );
        assert!(
            note.contains("centre (px)           651.75, 348.25"),
            "{note}"
        );
    }

    #[test]
    fn euler_round_trip_and_gimbal() {
        for a in [[0.3, -2.5, 1.0], [-1.2, 3.0, -0.2], [0.0, 0.0, 0.0]] {
            let m = matrix_zxy(a);
            let b = euler_zxy(&m);
            assert!((matrix_zxy(b) - m).norm() < 1e-12);
        }
        let m = matrix_zxy([std::f64::consts::FRAC_PI_2, 0.4, 0.7]);
        assert!((matrix_zxy(euler_zxy(&m)) - m).norm() < 1e-9);
    }
}
