//! Our JSON export: per frame K, R, t (x ~ K(RX + t), rows first), the camera centre and the
//! solve error when the tracks and points are known: `rms_px`, the RMS reprojection error over
//! the observations the solve kept in that frame (its inliers, `observations` of them), and
//! `outliers`, the observations of the frame's points that it rejected (not in `rms_px`). A lens
//! is the top-level `distortion` (our [`Distortion`](vfxgraph_lens::Distortion) JSON, absent for a
//! pinhole): a camera point X then images at K · d(X.xy / X.z), d the distortion on normalized
//! coordinates.

use serde_json::{json, Value};

use super::Shot;
use vfxgraph_geometry::error::Result;

/// The format tag of the document.
pub const FORMAT: &str = "vfxgraph-camera-export";

/// The document's `convention` for a pinhole.
const CONVENTION: &str = "x ~ K (R X + t); pixel origin at the centre of the top-left pixel, x right, y down; the camera looks down +z; matrices rows first; center = -R^T t";

/// The export as a JSON value.
pub fn to_value(shot: &Shot, fps: f64) -> Result<Value> {
    shot.validate()?;
    let k_rows = |i: usize| -> Vec<[f64; 3]> {
        let k = shot.intrinsics_at(i).k();
        (0..3).map(|r| [k[(r, 0)], k[(r, 1)], k[(r, 2)]]).collect()
    };
    let errors = shot.frame_errors();
    let frames: Vec<Value> = shot
        .path
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let r = &f.pose.r;
            let c = f.pose.center();
            let e = errors.as_ref().map(|e| e[i]);
            let mut o = json!({
                "frame": f.frame,
                "K": k_rows(i),
                "R": (0..3).map(|row| [r[(row, 0)], r[(row, 1)], r[(row, 2)]]).collect::<Vec<_>>(),
                "t": [f.pose.t.x, f.pose.t.y, f.pose.t.z],
                "center": [c.x, c.y, c.z],
                "rms_px": e.map(|e| e.rms_px).filter(|v| v.is_finite()),
            });
            if let Some(e) = e {
                o["observations"] = json!(e.inliers);
                o["outliers"] = json!(e.outliers);
            }
            if let Some(name) = shot.image_name(f.frame) {
                o["image"] = json!(name);
            }
            o
        })
        .collect();
    let mut doc = json!({
        "format": FORMAT,
        "version": 1,
        "convention": CONVENTION,
        "width": shot.intrinsics.width,
        "height": shot.intrinsics.height,
        "fps": fps,
        "points": shot.cloud.as_ref().map_or(0, |c| c.points.len()),
        "frames": frames,
    });
    if !shot.intrinsics.is_pinhole() {
        doc["distortion"] = serde_json::to_value(shot.intrinsics.distortion)?;
        doc["convention"] = json!(format!(
            "{}; the lens: x = K d(X_c.xy / X_c.z), d the distortion on normalized coordinates",
            CONVENTION
        ));
    }
    Ok(doc)
}

/// The export as pretty JSON text.
pub fn format(shot: &Shot, fps: f64) -> Result<String> {
    Ok(serde_json::to_string_pretty(&to_value(shot, fps)?)? + "\n")
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;
    use nalgebra::{Matrix3, Point3, Vector3};

    /// K, R, t read back from the JSON project the points where our cameras do, and the
    /// centre is −Rᵀt.
    #[test]
    fn json_reprojects_like_ours() {
        let s = shot();
        let v: Value = serde_json::from_str(&format(&s, 25.0).unwrap()).unwrap();
        assert_eq!(v["format"], FORMAT);
        assert_eq!(v["frames"].as_array().unwrap().len(), 12);
        let m3 = |a: &Value| Matrix3::from_fn(|r, c| a[r][c].as_f64().unwrap());
        for (fj, f) in v["frames"].as_array().unwrap().iter().zip(&s.path.frames) {
            let (k, r) = (m3(&fj["K"]), m3(&fj["R"]));
            let t = Vector3::from_fn(|i, _| fj["t"][i].as_f64().unwrap());
            let c = Vector3::from_fn(|i, _| fj["center"][i].as_f64().unwrap());
            assert!((c + r.transpose() * t).norm() < 1e-12);
            let cam = vfxgraph_geometry::Camera {
                intrinsics: s.intrinsics.clone(),
                pose: f.pose.clone(),
            };
            for p in s.points() {
                let h = k * (r * p.coords + t);
                let ours = cam.project(&Point3::from(p)).unwrap();
                assert!((h.x / h.z - ours.x).abs() < 1e-9 && (h.y / h.z - ours.y).abs() < 1e-9);
            }
            assert!(fj["rms_px"].is_null());
        }
    }

    /// With tracks, each frame's solve error is the RMS distance between the tracked positions
    /// and the projections: exact tracks give 0, a track 3-4-5 px off in one frame gives that
    /// frame sqrt(25 / n).
    #[test]
    fn solve_error_per_frame_from_tracks() {
        use vfxgraph_klt::{Track, Tracks};
        let mut s = shot();
        let cloud = s.cloud.clone().unwrap();
        let frames: Vec<i64> = s.path.frames.iter().map(|f| f.frame as i64).collect();
        let tracks: Vec<Track> = cloud
            .points
            .iter()
            .zip(&cloud.track_ids)
            .enumerate()
            .map(|(slot, (p, id))| Track {
                id: *id,
                slot,
                first: 0,
                points: s
                    .path
                    .frames
                    .iter()
                    .map(|f| {
                        let cam = vfxgraph_geometry::Camera {
                            intrinsics: s.intrinsics.clone(),
                            pose: f.pose.clone(),
                        };
                        let x = cam.project(&Point3::new(p[0], p[1], p[2])).unwrap();
                        [x.x, x.y]
                    })
                    .collect(),
                lost: None,
            })
            .collect();
        let mut t = Tracks {
            frames,
            slots: tracks.len(),
            image_size: None,
            tracks,
        };
        t.tracks[7].points[2][0] += 3.0;
        t.tracks[7].points[2][1] += 4.0;
        let n = t.tracks.len();
        s.tracks = Some(t);
        let v = to_value(&s, 24.0).unwrap();
        for (i, fj) in v["frames"].as_array().unwrap().iter().enumerate() {
            assert_eq!(fj["observations"], n);
            let rms = fj["rms_px"].as_f64().unwrap();
            let want = if i == 2 {
                (25.0 / n as f64).sqrt()
            } else {
                0.0
            };
            assert!((rms - want).abs() < 1e-9, "frame {i}: {rms} vs {want}");
            assert_eq!(fj["outliers"], 0);
        }
        // The solve rejected the displaced observation: it leaves the frame's error and count
        // and is counted as an outlier.
        let c = s.cloud.as_mut().unwrap();
        c.inlier_frames = vec![frames_of(&s.path); c.points.len()];
        c.inlier_frames[7].retain(|&f| f != s.path.frames[2].frame as i64);
        let v = to_value(&s, 24.0).unwrap();
        for (i, fj) in v["frames"].as_array().unwrap().iter().enumerate() {
            let bad = usize::from(i == 2);
            assert_eq!(fj["observations"], n - bad);
            assert_eq!(fj["outliers"], bad);
            assert!(fj["rms_px"].as_f64().unwrap() < 1e-9, "frame {i}: {fj}");
        }
    }

    /// A lens travels as the top-level `distortion`: it reads back as the same model, and K, R, t
    /// with it project the points where our cameras do (the distorted pixels); a pinhole has
    /// none.
    #[test]
    fn distortion_round_trips() {
        use vfxgraph_lens::Distortion;
        let mut s = shot();
        assert!(to_value(&s, 24.0).unwrap().get("distortion").is_none());
        for d in [
            Distortion::BrownConrady {
                k1: -0.16,
                k2: 0.045,
                k3: -0.004,
                p1: 8e-4,
                p2: -5e-4,
            },
            Distortion::Division { k1: -0.1, k2: 0.01 },
        ] {
            s.intrinsics = s.intrinsics.clone().with_distortion(d);
            let v: Value = serde_json::from_str(&format(&s, 24.0).unwrap()).unwrap();
            let back: Distortion = serde_json::from_value(v["distortion"].clone()).unwrap();
            assert_eq!(back, d);
            let f0 = &v["frames"][0];
            let k = vfxgraph_geometry::Intrinsics::from_k(&Matrix3::from_fn(|r, c| {
                f0["K"][r][c].as_f64().unwrap()
            }))
            .unwrap()
            .with_distortion(back);
            let r = Matrix3::from_fn(|i, j| f0["R"][i][j].as_f64().unwrap());
            let t = Vector3::from_fn(|i, _| f0["t"][i].as_f64().unwrap());
            let cam = vfxgraph_geometry::Camera {
                intrinsics: s.intrinsics.clone(),
                pose: s.path.frames[0].pose.clone(),
            };
            for p in s.points() {
                let theirs = k.project_camera_point(&(r * p.coords + t)).unwrap();
                let ours = cam.project(&p).unwrap();
                assert!((theirs - ours).norm() < 1e-9, "{theirs} vs {ours}");
            }
        }
    }

    fn frames_of(path: &vfxgraph_geometry::formats::CameraPath) -> Vec<i64> {
        path.frames.iter().map(|f| f.frame as i64).collect()
    }
}
