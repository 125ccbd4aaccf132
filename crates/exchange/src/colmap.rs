//! COLMAP's text model (`cameras.txt`, `images.txt`, `points3D.txt`): written from a shot and
//! read back into a camera path, K and a point cloud.
//!
//! Conventions: one camera, in the smallest COLMAP model that holds our lens exactly
//! ([`camera_model`]): `PINHOLE` (fx fy cx cy) for a pinhole; for Brown–Conrady (OpenCV's
//! k1 k2 k3 p1 p2 on normalized coordinates, COLMAP's `OpenCV` models are the same formula)
//! `SIMPLE_RADIAL` (f cx cy k1) or `RADIAL` (f cx cy k1 k2) when the pixels are square and there
//! is no tangential or k3 term, `OPENCV` (fx fy cx cy k1 k2 p1 p2) without k3, `FULL_OPENCV`
//! (fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6, k4..k6 = 0: its rational denominator unused) with k3.
//! A division lens has no COLMAP model: it is refitted as a radial polynomial over the frame
//! ([`super::lens_fit`]), written as the model that holds the fit, with the fit's error in a
//! comment of `cameras.txt`; a fit worse than [`super::lens_fit::MAX_FIT_ERROR_PX`] is an error.
//! A skewed K is refused. Images with the world→camera rotation as a Hamilton
//! quaternion `QW QX QY QZ` and t (x_cam = R X + t, as ours), and pixels whose origin is the
//! top-left *corner* of the image: COLMAP's (cx, cy) and 2-D points are ours + 0.5.
//! Image ids are 1, 2, … in path order; point ids 1, 2, … in cloud order. Each image's 2-D
//! points are the tracks' observations of the cloud's points in that frame: those the solve
//! kept as inliers ([`vfxgraph_geometry::points::PointCloud::inlier_frames`]) are linked to their point and
//! make its track; those it rejected are unassigned (`POINT3D_ID -1`), so a bundle adjustment
//! started from the model is not dragged by them. Reading back, a point's inlier frames are
//! the frames of its track's images. Numbers are written with Rust's shortest round-trip
//! formatting, so a read gives back the same f64s.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::{lens_fit, quaternion_wxyz, rotation_from_wxyz, Shot, N};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::formats::{
    data_lines, number, parse_error, read_text, CameraPath, FramePose,
};
use vfxgraph_geometry::points::PointCloud;
use vfxgraph_lens::Distortion;

/// Offset from our pixel coordinates (origin at the first pixel's centre) to COLMAP's (origin
/// at its corner).
pub const PIXEL_OFFSET: f64 = 0.5;

/// The three files of a text model.
#[derive(Clone, Debug, PartialEq)]
pub struct TextModel {
    /// `cameras.txt`.
    pub cameras: String,
    /// `images.txt`.
    pub images: String,
    /// `points3D.txt`.
    pub points3d: String,
}

/// A model read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// K in our convention, with the image size.
    pub intrinsics: Intrinsics,
    /// One pose per image; the frame number is the last run of digits in the image name, or
    /// the image's position (by id) when a name has none.
    pub path: CameraPath,
    /// Image names, in path order.
    pub names: Vec<String>,
    /// Points (track id = COLMAP point id; error NaN where COLMAP has −1).
    pub cloud: PointCloud,
}

/// A COLMAP camera: model name and parameters (COLMAP's order, its pixel convention), and for a
/// refitted lens the fit's largest error in pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraModel {
    /// `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL`, `OPENCV` or `FULL_OPENCV`.
    pub model: &'static str,
    /// The parameters in COLMAP's order.
    pub params: Vec<f64>,
    /// The refit's largest error (px) when the lens had no COLMAP model (division).
    pub fit_error_px: Option<f64>,
}

/// The smallest COLMAP camera model holding K and its lens (module docs).
pub fn camera_model(k: &Intrinsics) -> Result<CameraModel> {
    let (cx, cy) = (k.u0 + PIXEL_OFFSET, k.v0 + PIXEL_OFFSET);
    let (mut k1, mut k2, mut k3, mut p1, mut p2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut fit_error_px = None;
    match k.distortion {
        Distortion::None => {}
        Distortion::BrownConrady {
            k1: a,
            k2: b,
            k3: c,
            p1: d,
            p2: e,
        } => (k1, k2, k3, p1, p2) = (a, b, c, d, e),
        Distortion::Division { .. } => {
            let fit = lens_fit::radial_polynomial_within(k, 3, "COLMAP")?;
            (k1, k2, k3) = (fit.k[0], fit.k[1], fit.k[2]);
            fit_error_px = Some(fit.max_error_px);
        }
    }
    let square = k.f1 == k.f2;
    let (model, params) = if k1 == 0.0 && k2 == 0.0 && k3 == 0.0 && p1 == 0.0 && p2 == 0.0 {
        ("PINHOLE", vec![k.f1, k.f2, cx, cy])
    } else if k3 != 0.0 {
        (
            "FULL_OPENCV",
            vec![k.f1, k.f2, cx, cy, k1, k2, p1, p2, k3, 0.0, 0.0, 0.0],
        )
    } else if p1 != 0.0 || p2 != 0.0 || !square {
        ("OPENCV", vec![k.f1, k.f2, cx, cy, k1, k2, p1, p2])
    } else if k2 == 0.0 {
        ("SIMPLE_RADIAL", vec![k.f1, cx, cy, k1])
    } else {
        ("RADIAL", vec![k.f1, cx, cy, k1, k2])
    };
    Ok(CameraModel {
        model,
        params,
        fit_error_px,
    })
}

/// Formats the text model of a shot.
pub fn format(shot: &Shot) -> Result<TextModel> {
    shot.validate()?;
    shot.require_no_skew("COLMAP")?;
    let (w, h) = shot.size()?;
    let cam = camera_model(&shot.intrinsics)?;
    // A zoom: one camera per image (its own focal length), else one for the shot.
    let zoom = shot.path.zooms();
    let n_cameras = if zoom { shot.path.frames.len() } else { 1 };
    let mut cameras = format!(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: {n_cameras}\n",
    );
    if let Some(e) = cam.fit_error_px {
        let _ = writeln!(
            cameras,
            "# vfxgraph: the {} lens has no COLMAP model; {} holds its radial polynomial refit \
             over the frame, within {e:.3e} px of it",
            shot.intrinsics.distortion.name(),
            cam.model
        );
    }
    for id in 0..n_cameras {
        let cam = if zoom {
            camera_model(&shot.intrinsics_at(id))?
        } else {
            cam.clone()
        };
        let params: Vec<String> = cam.params.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(
            cameras,
            "{} {} {w} {h} {}",
            id + 1,
            cam.model,
            params.join(" ")
        );
    }

    // The tracks' observations of the cloud's points, per image: the solve's inliers are
    // linked to their point (and listed in its track), the outliers stay unassigned 2-D
    // points (POINT3D_ID −1).
    let cloud = shot.cloud.as_ref();
    let per_image = shot.observations();
    let mut point_tracks: Vec<Vec<(usize, usize)>> =
        vec![Vec::new(); cloud.map_or(0, |c| c.points.len())];
    for (img, obs) in per_image.iter().enumerate() {
        for (idx, o) in obs.iter().enumerate().filter(|(_, o)| o.inlier) {
            point_tracks[o.point].push((img + 1, idx));
        }
    }

    let n_obs: usize = per_image.iter().map(Vec::len).sum();
    let n_linked: usize = point_tracks.iter().map(Vec::len).sum();
    let mut images = String::new();
    let _ = write!(
        images,
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n\
         # Number of images: {}, mean observations per image: {} (the solve's inliers; \
         {} more 2-D points, POINT3D_ID -1, are observations it rejected)\n",
        shot.path.frames.len(),
        if shot.path.frames.is_empty() {
            0.0
        } else {
            n_linked as f64 / shot.path.frames.len() as f64
        },
        n_obs - n_linked
    );
    for (img, f) in shot.path.frames.iter().enumerate() {
        let q = quaternion_wxyz(&f.pose.r);
        let t = f.pose.t;
        let name = shot
            .image_name(f.frame)
            .unwrap_or_else(|| format!("frame.{:06}.png", f.frame));
        if name.chars().any(char::is_whitespace) || name.is_empty() {
            return Err(VisionError::InvalidInput(format!(
                "COLMAP image names cannot hold spaces: `{name}`"
            )));
        }
        let _ = writeln!(
            images,
            "{} {} {} {} {} {} {} {} {} {name}",
            img + 1,
            N(q[0]),
            N(q[1]),
            N(q[2]),
            N(q[3]),
            N(t.x),
            N(t.y),
            N(t.z),
            if zoom { img + 1 } else { 1 }
        );
        let obs: Vec<String> = per_image[img]
            .iter()
            .map(|o| {
                let id = if o.inlier { o.point as i64 + 1 } else { -1 };
                format!(
                    "{} {} {id}",
                    o.pixel[0] + PIXEL_OFFSET,
                    o.pixel[1] + PIXEL_OFFSET
                )
            })
            .collect();
        let _ = writeln!(images, "{}", obs.join(" "));
    }

    let mut points3d = String::new();
    let n_points = cloud.map_or(0, |c| c.points.len());
    let _ = writeln!(
        points3d,
        "# 3D point list with one line of data per point:\n\
         #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n\
         # Number of points: {n_points}"
    );
    if let Some(c) = cloud {
        for (j, p) in c.points.iter().enumerate() {
            let rgb = shot.colors.as_ref().map_or([128, 128, 128], |col| col[j]);
            let err = c
                .errors
                .get(j)
                .copied()
                .filter(|e| e.is_finite())
                .unwrap_or(-1.0);
            let _ = write!(
                points3d,
                "{} {} {} {} {} {} {} {err}",
                j + 1,
                p[0],
                p[1],
                p[2],
                rgb[0],
                rgb[1],
                rgb[2]
            );
            for (img, idx) in &point_tracks[j] {
                let _ = write!(points3d, " {img} {idx}");
            }
            points3d.push('\n');
        }
    }
    Ok(TextModel {
        cameras,
        images,
        points3d,
    })
}

/// Whether two cameras differ in their focal length only (a zoom's), with the same aspect.
fn same_but_focal(a: &Intrinsics, b: &Intrinsics) -> bool {
    let (ra, rb) = (a.f2 / a.f1, b.f2 / b.f1);
    let mut c = b.clone();
    c.f1 = a.f1;
    c.f2 = a.f2;
    (ra - rb).abs() <= 1e-9 * ra.abs() && &c == a
}

/// The three file paths of a model whose `cameras.txt` is `cameras`.
pub fn model_files(cameras: &Path) -> [PathBuf; 3] {
    let dir = cameras.parent().unwrap_or(Path::new("."));
    [
        dir.join("cameras.txt"),
        dir.join("images.txt"),
        dir.join("points3D.txt"),
    ]
}

/// Writes the model beside `cameras` (which must be named `cameras.txt`), each file atomically.
/// Returns the three paths.
pub fn write(cameras: &Path, shot: &Shot) -> Result<[PathBuf; 3]> {
    check_cameras_name(cameras)?;
    let model = format(shot)?;
    let files = model_files(cameras);
    if let Some(dir) = cameras.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|source| VisionError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
    }
    vfxgraph_geometry::formats::write_text(&files[0], &model.cameras)?;
    vfxgraph_geometry::formats::write_text(&files[1], &model.images)?;
    vfxgraph_geometry::formats::write_text(&files[2], &model.points3d)?;
    Ok(files)
}

fn check_cameras_name(cameras: &Path) -> Result<()> {
    if cameras.file_name().and_then(|n| n.to_str()) != Some("cameras.txt") {
        return Err(VisionError::InvalidInput(format!(
            "a COLMAP text model is named by its cameras.txt (images.txt and points3D.txt sit \
             beside it), got {}",
            cameras.display()
        )));
    }
    Ok(())
}

/// Reads the model whose `cameras.txt` is `cameras`.
pub fn read(cameras: &Path) -> Result<Model> {
    check_cameras_name(cameras)?;
    let [c, i, p] = model_files(cameras);
    parse(
        (&read_text(&c)?, &c.display().to_string()),
        (&read_text(&i)?, &i.display().to_string()),
        (&read_text(&p)?, &p.display().to_string()),
    )
}

/// Parses a text model (text, file name for errors) × 3. Every image must use the same camera
/// intrinsics (one K per shot). `SIMPLE_PINHOLE`, `PINHOLE`, `SIMPLE_RADIAL`, `RADIAL`, `OPENCV`
/// and `FULL_OPENCV` (with k4 = k5 = k6 = 0: the rational denominator has no model here) are
/// read, the distortion as Brown–Conrady (a pinhole when every coefficient is 0); a lens that
/// folds over inside the frame is an error naming the line.
pub fn parse(cameras: (&str, &str), images: (&str, &str), points3d: (&str, &str)) -> Result<Model> {
    // cameras.txt
    let (text, file) = cameras;
    let mut cams: BTreeMap<u64, (usize, Intrinsics)> = BTreeMap::new();
    for (line, t) in data_lines(text) {
        if t.len() < 4 {
            return Err(parse_error(
                file,
                line,
                "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS…",
            ));
        }
        let id = int(file, line, t[0])?;
        let w = int(file, line, t[2])? as u32;
        let h = int(file, line, t[3])? as u32;
        let v = t[4..]
            .iter()
            .map(|s| number(file, line, s))
            .collect::<Result<Vec<f64>>>()?;
        let need = |n: usize| -> Result<()> {
            if v.len() != n {
                return Err(parse_error(
                    file,
                    line,
                    format!(
                        "camera model {} takes {n} parameters, found {}",
                        t[1],
                        v.len()
                    ),
                ));
            }
            Ok(())
        };
        let zero_tail = |from: usize| -> Result<()> {
            if v[from..].iter().any(|d| *d != 0.0) {
                return Err(parse_error(
                    file,
                    line,
                    format!(
                        "camera model {} with non-zero k4..k6 (the rational denominator): \
                         our lens models have no equivalent",
                        t[1]
                    ),
                ));
            }
            Ok(())
        };
        // (f1, f2, cx, cy, [k1, k2, k3, p1, p2])
        let (f1, f2, cx, cy, d) = match t[1] {
            "SIMPLE_PINHOLE" => {
                need(3)?;
                (v[0], v[0], v[1], v[2], [0.0; 5])
            }
            "PINHOLE" => {
                need(4)?;
                (v[0], v[1], v[2], v[3], [0.0; 5])
            }
            "SIMPLE_RADIAL" => {
                need(4)?;
                (v[0], v[0], v[1], v[2], [v[3], 0.0, 0.0, 0.0, 0.0])
            }
            "RADIAL" => {
                need(5)?;
                (v[0], v[0], v[1], v[2], [v[3], v[4], 0.0, 0.0, 0.0])
            }
            "OPENCV" => {
                need(8)?;
                (v[0], v[1], v[2], v[3], [v[4], v[5], 0.0, v[6], v[7]])
            }
            "FULL_OPENCV" => {
                need(12)?;
                zero_tail(9)?;
                (v[0], v[1], v[2], v[3], [v[4], v[5], v[8], v[6], v[7]])
            }
            m => {
                return Err(parse_error(
                    file,
                    line,
                    format!("unsupported camera model `{m}`"),
                ))
            }
        };
        let distortion = if d.iter().all(|c| *c == 0.0) {
            Distortion::None
        } else {
            Distortion::BrownConrady {
                k1: d[0],
                k2: d[1],
                k3: d[2],
                p1: d[3],
                p2: d[4],
            }
        };
        let k = Intrinsics::new(f1, f2, cx - PIXEL_OFFSET, cy - PIXEL_OFFSET)
            .with_size(w, h)
            .with_distortion(distortion);
        k.validate()
            .map_err(|e| parse_error(file, line, e.to_string()))?;
        cams.insert(id, (line, k));
    }

    // images.txt: pairs of lines; the second (the 2-D points) may be empty.
    let (text, ifile) = images;
    let mut rows: Vec<(usize, Vec<&str>)> = Vec::new();
    let mut expect_header = true;
    for (i, l) in text.lines().enumerate() {
        if l.trim_start().starts_with('#') {
            continue;
        }
        let toks: Vec<&str> = l.split_whitespace().collect();
        if expect_header && toks.is_empty() {
            continue;
        }
        if expect_header {
            rows.push((i + 1, toks));
        }
        expect_header = !expect_header;
    }
    let mut k_shot: Option<Intrinsics> = None;
    let mut entries: Vec<(u64, String, Pose, f64)> = Vec::new();
    for (line, t) in rows {
        if t.len() != 10 {
            return Err(parse_error(
                ifile,
                line,
                format!(
                    "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found {} fields",
                    t.len()
                ),
            ));
        }
        let id = int(ifile, line, t[0])?;
        let mut v = [0.0; 7];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = number(ifile, line, t[1 + k])?;
        }
        let r = rotation_from_wxyz([v[0], v[1], v[2], v[3]])
            .map_err(|e| parse_error(ifile, line, e.to_string()))?;
        let cam = int(ifile, line, t[8])?;
        let (_, k) = cams
            .get(&cam)
            .ok_or_else(|| parse_error(ifile, line, format!("unknown camera id {cam}")))?;
        match &k_shot {
            None => k_shot = Some(k.clone()),
            // A zoom: cameras that differ in their focal length only (the aspect kept).
            Some(k0) if k0 != k && !same_but_focal(k0, k) => {
                return Err(parse_error(
                    ifile,
                    line,
                    format!("image {id} uses camera {cam} whose intrinsics differ from the first image's in more than the focal length: one lens per shot"),
                ))
            }
            _ => {}
        }
        entries.push((
            id,
            t[9].to_string(),
            Pose::new(r, Vector3::new(v[4], v[5], v[6])),
            k.f1,
        ));
    }
    entries.sort_by_key(|e| e.0);
    let intrinsics = match k_shot {
        Some(k) => k,
        None => match cams.values().next() {
            Some((_, k)) => k.clone(),
            None => return Err(parse_error(file, 1, "no camera in the model")),
        },
    };
    let mut frames = Vec::with_capacity(entries.len());
    let mut names = Vec::with_capacity(entries.len());
    let mut seen = std::collections::BTreeSet::new();
    let mut frame_of_image: HashMap<u64, i64> = HashMap::new();
    let zooms = entries.iter().any(|e| e.3 != intrinsics.f1);
    for (pos, (id, name, pose, f)) in entries.into_iter().enumerate() {
        let frame = frame_number(&name).unwrap_or(pos);
        frame_of_image.insert(id, frame as i64);
        if !seen.insert(frame) {
            return Err(parse_error(
                ifile,
                1,
                format!("image {id} ({name}) has frame number {frame}, which another image has"),
            ));
        }
        frames.push(FramePose {
            frame,
            pose,
            focal: zooms.then_some(f),
        });
        names.push(name);
    }

    // points3D.txt
    let (text, pfile) = points3d;
    let mut cloud = PointCloud::default();
    for (line, t) in data_lines(text) {
        if t.len() < 8 || (t.len() - 8) % 2 != 0 {
            return Err(parse_error(
                pfile,
                line,
                "expected POINT3D_ID X Y Z R G B ERROR (IMAGE_ID POINT2D_IDX)…",
            ));
        }
        let id = int(pfile, line, t[0])?;
        let mut p = [0.0; 3];
        for (k, slot) in p.iter_mut().enumerate() {
            *slot = number(pfile, line, t[1 + k])?;
        }
        let e = number(pfile, line, t[7])?;
        let mut track = Vec::with_capacity((t.len() - 8) / 2);
        for el in t[8..].chunks(2) {
            let image = int(pfile, line, el[0])?;
            let frame = frame_of_image.get(&image).ok_or_else(|| {
                parse_error(pfile, line, format!("point {id}: unknown image id {image}"))
            })?;
            track.push(*frame);
        }
        track.sort_unstable();
        track.dedup();
        cloud.points.push(p);
        cloud.track_ids.push(id);
        cloud.errors.push(if e < 0.0 { f64::NAN } else { e });
        cloud.inlier_frames.push(track);
    }
    // A model without any track made no inlier decision.
    if cloud.inlier_frames.iter().all(Vec::is_empty) {
        cloud.inlier_frames.clear();
    }
    Ok(Model {
        path: CameraPath {
            frames,
            intrinsics: Some(intrinsics.clone()),
        },
        intrinsics,
        names,
        cloud,
    })
}

fn int(file: &str, line: usize, tok: &str) -> Result<u64> {
    tok.parse().map_err(|_| {
        parse_error(
            file,
            line,
            format!("expected a non-negative integer, found `{tok}`"),
        )
    })
}

/// The frame number in an image name: the last run of ASCII digits of its file stem.
pub fn frame_number(name: &str) -> Option<usize> {
    let base = name.rsplit(['/', '\\']).next().unwrap_or(name);
    let stem = base.rsplit_once('.').map_or(base, |(s, _)| s);
    let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
    // Bytes, not chars: every byte of a multi-byte character is a non-digit, so the byte after
    // the last one is a character boundary.
    let start = stem.as_bytes()[..end]
        .iter()
        .rposition(|b| !b.is_ascii_digit())
        .map_or(0, |i| i + 1);
    stem[start..end].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;
    use vfxgraph_klt::{Track, Tracks};

    /// import(export(shot)) gives back K, every pose and every point within 1e-9 (in fact to
    /// the last bit for K, t and the points; R through the quaternion to ~1e-16).
    #[test]
    fn round_trip_within_1e9() {
        let s = shot();
        let m = format(&s).unwrap();
        let back = parse(
            (&m.cameras, "cameras.txt"),
            (&m.images, "images.txt"),
            (&m.points3d, "points3D.txt"),
        )
        .unwrap();
        assert_eq!(back.intrinsics, s.intrinsics);
        assert_eq!(back.path.frames.len(), s.path.frames.len());
        for (a, b) in s.path.frames.iter().zip(&back.path.frames) {
            assert_eq!(a.frame, b.frame);
            assert!((a.pose.r - b.pose.r).abs().max() < 1e-9);
            assert!((a.pose.t - b.pose.t).abs().max() < 1e-9);
        }
        let c = s.cloud.as_ref().unwrap();
        assert_eq!(back.cloud.points, c.points);
        assert_eq!(back.names[0], "plate/frame.0010.png");
        assert!(back.cloud.errors[0] == 0.0 && (back.cloud.errors[5] - 0.05).abs() < 1e-15);
    }

    /// A zoom is one COLMAP camera per image, read back as every frame's focal length (the
    /// first image's camera the shot's K); cameras that differ in more than their focal length
    /// stay an error.
    #[test]
    fn a_zoom_round_trips_as_a_camera_per_image() {
        let mut s = shot();
        for (i, f) in s.path.frames.iter_mut().enumerate() {
            f.focal = Some(1100.0 + 20.0 * i as f64);
        }
        let m = format(&s).unwrap();
        assert!(m.cameras.contains("# Number of cameras: 12"));
        let back = parse(
            (&m.cameras, "cameras.txt"),
            (&m.images, "images.txt"),
            (&m.points3d, "points3D.txt"),
        )
        .unwrap();
        for (i, (a, b)) in s.path.frames.iter().zip(&back.path.frames).enumerate() {
            assert_eq!(b.focal, a.focal, "frame {i}");
            let (ka, kb) = (s.intrinsics_at(i), back.path.intrinsics_at(i).unwrap());
            assert!((ka.f2 - kb.f2).abs() < 1e-9 && ka.u0 == kb.u0, "frame {i}");
        }
        // The second camera with another principal point: not a zoom.
        let cams = m.cameras.replacen(" 651.75 ", " 660 ", 2);
        assert_ne!(cams, m.cameras);
        let e = parse(
            (&cams, "cameras.txt"),
            (&m.images, "images.txt"),
            (&m.points3d, "points3D.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("more than the focal length"), "{e}");
    }

    /// Each lens is written in the smallest COLMAP model that holds it and reads back exactly
    /// (every f64 to the last bit); a zero lens stays a pinhole; a division lens is written as
    /// its refit, whose error the header states.
    #[test]
    fn lenses_round_trip_in_their_models() {
        let brown = |k1, k2, k3, p1, p2| Distortion::BrownConrady { k1, k2, k3, p1, p2 };
        let square = Intrinsics::new(1210.0, 1210.0, 651.25, 347.75).with_size(1280, 720);
        let cases = [
            (
                square.clone(),
                brown(-0.16, 0.0, 0.0, 0.0, 0.0),
                "SIMPLE_RADIAL",
                4,
            ),
            (
                square.clone(),
                brown(-0.16, 0.045, 0.0, 0.0, 0.0),
                "RADIAL",
                5,
            ),
            (
                square.clone(),
                brown(-0.16, 0.045, 0.0, 8e-4, -5e-4),
                "OPENCV",
                8,
            ),
            (
                shot().intrinsics,
                brown(-0.16, 0.0, 0.0, 0.0, 0.0),
                "OPENCV",
                8,
            ),
            (
                square.clone(),
                brown(-0.16, 0.045, -0.004, 8e-4, -5e-4),
                "FULL_OPENCV",
                12,
            ),
        ];
        for (k, d, model, n) in cases {
            let mut s = shot();
            s.intrinsics = k.with_distortion(d);
            let m = format(&s).unwrap();
            let line = m.cameras.lines().find(|l| l.starts_with("1 ")).unwrap();
            assert_eq!(line.split(' ').nth(1), Some(model), "{line}");
            assert_eq!(line.split(' ').count(), 4 + n, "{line}");
            let back = parse(
                (&m.cameras, "cameras.txt"),
                (&m.images, "images.txt"),
                (&m.points3d, "points3D.txt"),
            )
            .unwrap();
            assert_eq!(back.intrinsics, s.intrinsics, "{model}");
            assert_eq!(back.path.intrinsics.as_ref(), Some(&s.intrinsics));
        }
        let mut s = shot();
        s.intrinsics = square.with_distortion(brown(0.0, 0.0, 0.0, 0.0, 0.0));
        let m = format(&s).unwrap();
        assert!(m.cameras.contains("\n1 PINHOLE "), "{}", m.cameras);
        s.intrinsics = s
            .intrinsics
            .with_distortion(Distortion::Division { k1: 0.1, k2: 0.0 });
        let cam = camera_model(&s.intrinsics).unwrap();
        assert_eq!(cam.model, "FULL_OPENCV");
        let e = cam.fit_error_px.unwrap();
        let m = format(&s).unwrap();
        assert!(m.cameras.contains("refit") && m.cameras.contains(&format!("{e:.3e} px")));
    }

    /// The test shot with tracks (id, first frame index, positions), one slot each.
    fn shot_with_tracks(tracks: &[(u64, usize, &[[f64; 2]])]) -> Shot {
        let mut s = shot();
        s.tracks = Some(Tracks {
            frames: s.path.frames.iter().map(|f| f.frame as i64).collect(),
            slots: tracks.len(),
            image_size: None,
            tracks: tracks
                .iter()
                .enumerate()
                .map(|(slot, (id, first, points))| Track {
                    id: *id,
                    slot,
                    first: *first,
                    points: points.to_vec(),
                    lost: None,
                })
                .collect(),
        });
        s
    }

    /// Tracks become 2-D points (+0.5 px) and point tracks that index them.
    #[test]
    fn tracks_become_observations() {
        // Track 9999 has no point in the cloud: ignored.
        let s = shot_with_tracks(&[
            (501, 1, &[[10.0, 20.0], [11.0, 21.0]]),
            (9999, 0, &[[1.0, 2.0]]),
        ]);
        let m = format(&s).unwrap();
        let img: Vec<&str> = m.images.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(img[1], "");
        assert_eq!(img[3], "10.5 20.5 2");
        assert_eq!(img[5], "11.5 21.5 2");
        let p2 = m.points3d.lines().find(|l| l.starts_with("2 ")).unwrap();
        assert!(p2.ends_with(" 2 0 3 0"), "{p2}");
    }

    /// With the solve's inlier marks, a rejected observation is an unassigned 2-D point
    /// (POINT3D_ID −1) and is not in its point's track; the others stay linked; reading the
    /// model back gives the marks again (the frames of each point's track).
    #[test]
    fn only_inliers_are_linked() {
        // Track 501 (point 2) is seen in images 2, 3, 4 (frames 11, 12, 13); the solve
        // rejected its observation in frame 12. Track 500 (point 1) has no inlier at all.
        let mut s = shot_with_tracks(&[
            (501, 1, &[[10.0, 20.0], [11.0, 21.0], [12.0, 22.0]]),
            (500, 1, &[[30.0, 40.0]]),
        ]);
        let cloud = s.cloud.as_mut().unwrap();
        cloud.inlier_frames = vec![Vec::new(); cloud.points.len()];
        cloud.inlier_frames[1] = vec![11, 13];
        let m = format(&s).unwrap();
        let img: Vec<&str> = m.images.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(img[3], "10.5 20.5 2 30.5 40.5 -1");
        assert_eq!(img[5], "11.5 21.5 -1");
        assert_eq!(img[7], "12.5 22.5 2");
        let p2 = m.points3d.lines().find(|l| l.starts_with("2 ")).unwrap();
        assert!(p2.ends_with(" 2 0 4 0"), "{p2}");
        let p1 = m.points3d.lines().find(|l| l.starts_with("1 ")).unwrap();
        assert_eq!(p1.split(' ').count(), 8, "point 1 has an empty track: {p1}");
        let back = parse(
            (&m.cameras, "cameras.txt"),
            (&m.images, "images.txt"),
            (&m.points3d, "points3D.txt"),
        )
        .unwrap();
        assert_eq!(back.cloud.inlier_frames.len(), 40);
        assert_eq!(back.cloud.inlier_frames[1], [11, 13]);
        assert!(back.cloud.inlier_frames[0].is_empty());
        assert!(back.cloud.is_inlier(1, 13) && !back.cloud.is_inlier(1, 12));
        // Without marks, every observation is linked; a model without tracks reads back
        // with no inlier decision.
        s.cloud.as_mut().unwrap().inlier_frames.clear();
        let read = |s: &Shot| {
            let m = format(s).unwrap();
            let back = parse(
                (&m.cameras, "cameras.txt"),
                (&m.images, "images.txt"),
                (&m.points3d, "points3D.txt"),
            );
            (m, back.unwrap())
        };
        let (m, back) = read(&s);
        let point_lines = m.images.lines().filter(|l| !l.starts_with('#')).skip(1);
        assert!(
            point_lines
                .step_by(2)
                .all(|l| !l.split(' ').any(|t| t == "-1")),
            "{}",
            m.images
        );
        assert_eq!(back.cloud.inlier_frames[1], [11, 12, 13]);
        s.tracks = None;
        let (_, back) = read(&s);
        assert!(back.cloud.inlier_frames.is_empty());
    }

    #[test]
    fn errors_name_file_and_line() {
        let s = shot();
        let m = format(&s).unwrap();
        let bad = m.images.replacen(" 1 plate", " 7 plate", 1);
        let e = parse(
            (&m.cameras, "c.txt"),
            (&bad, "i.txt"),
            (&m.points3d, "p.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("i.txt:5:") && e.contains("unknown camera id 7"),
            "{e}"
        );
        let e = parse(
            ("1 FULL_OPENCV 10 10 5 5 4 4 0.1 0 0 0 0 0.2 0 0", "c.txt"),
            ("", "i.txt"),
            ("", "p.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("c.txt:1:") && e.contains("k4..k6"), "{e}");
        // A lens that folds over inside its frame.
        let e = parse(
            ("# c\n1 SIMPLE_RADIAL 640 480 500 320 240 -0.9", "c.txt"),
            ("", "i.txt"),
            ("", "p.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("c.txt:2:") && e.contains("lens"), "{e}");
        let e = parse(("1 PINHOLE 10 10 5 5 4", "c.txt"), ("", "i"), ("", "p"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("4 parameters"), "{e}");
        let mut skew = s.clone();
        skew.intrinsics.s = 1.0;
        assert!(format(&skew).is_err());
        assert!(write(Path::new("/tmp/x/model.txt"), &s).is_err());
    }

    #[test]
    fn frame_numbers_from_names() {
        assert_eq!(frame_number("plate/frame.0012.png"), Some(12));
        assert_eq!(frame_number("cam2/img_0007.jpg"), Some(7));
        assert_eq!(frame_number("a.png"), None);
        assert_eq!(frame_number("0042"), Some(42));
        // Regression (fuzzing): a multi-byte character before the digits panicked (slicing
        // inside it).
        assert_eq!(frame_number("frame.0002C\u{fffd}20.png"), Some(20));
        assert_eq!(frame_number("naïve_é7.png"), Some(7));
        assert_eq!(frame_number("日本12"), Some(12));
    }
}
