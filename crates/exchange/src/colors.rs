//! Point colours from the plate: each point's colour is the mean of the plate, sampled
//! bilinearly at the point's projection, over the solved frames where it is in front of the
//! camera and inside the image and — for a cloud that carries the solve's inlier marks — where
//! the solve kept its observation (the frames it believes the point is seen in); returned as
//! 8-bit sRGB.

use nalgebra::Point3;
use vfxgraph_imaging::color::linear_to_srgb8;
use vfxgraph_imaging::Image;

use super::Shot;
use vfxgraph_geometry::Camera;

/// Colours of the shot's points from `plate` (frame number, linear-light image). Points seen in
/// no frame are mid grey.
pub fn sample_point_colors(shot: &Shot, plate: &[(i64, &Image)]) -> Vec<[u8; 3]> {
    let pts = shot.points();
    let cloud = shot.cloud.as_ref();
    let mut sum = vec![[0.0f64; 3]; pts.len()];
    let mut n = vec![0usize; pts.len()];
    for f in &shot.path.frames {
        let Some((_, img)) = plate.iter().find(|(fr, _)| *fr == f.frame as i64) else {
            continue;
        };
        let cam = Camera {
            intrinsics: shot.intrinsics.clone(),
            pose: f.pose.clone(),
        };
        for (j, p) in pts.iter().enumerate() {
            if cam.depth(p) <= 0.0 || !cloud.is_some_and(|c| c.is_inlier(j, f.frame as i64)) {
                continue;
            }
            if let Some(rgb) = cam
                .project(&Point3::from(*p))
                .ok()
                .and_then(|x| bilinear(img, x.x, x.y))
            {
                for c in 0..3 {
                    sum[j][c] += rgb[c] as f64;
                }
                n[j] += 1;
            }
        }
    }
    sum.iter()
        .zip(&n)
        .map(|(s, &k)| {
            if k == 0 {
                [128, 128, 128]
            } else {
                s.map(|v| linear_to_srgb8((v / k as f64) as f32))
            }
        })
        .collect()
}

/// Bilinear sample (pixel centres at integers) of the first three channels (grey repeated),
/// `None` outside the image.
fn bilinear(img: &Image, x: f64, y: f64) -> Option<[f32; 3]> {
    let (w, h) = (img.width as f64, img.height as f64);
    if !(x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let mut out = [0.0f32; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let ch = if img.channels >= 3 { c } else { 0 };
        let g = |xx, yy| img.get(xx, yy, ch);
        let top = g(x0, y0) * (1.0 - fx) + g(x1, y0) * fx;
        let bot = g(x0, y1) * (1.0 - fx) + g(x1, y1) * fx;
        *o = top * (1.0 - fy) + bot * fy;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::super::test_shot::shot;
    use super::*;

    /// A plate whose red channel encodes x and green encodes y: every point's colour is the
    /// mean of its projections, known exactly.
    #[test]
    fn colours_are_means_of_projections() {
        let s = shot();
        let img = Image::from_fn(1280, 720, 3, |x, y, c| match c {
            0 => x as f32 / 1279.0,
            1 => y as f32 / 719.0,
            _ => 0.25,
        });
        let plate: Vec<(i64, &Image)> = s
            .path
            .frames
            .iter()
            .map(|f| (f.frame as i64, &img))
            .collect();
        let mut s = s;
        let mut cols = Vec::new();
        for marked in [false, true] {
            if marked {
                // The solve kept each point's observations in three frames only.
                let c = s.cloud.as_mut().unwrap();
                c.inlier_frames = (0..c.points.len())
                    .map(|j| (0..3).map(|k| 10 + ((j + 4 * k) % 12) as i64).collect())
                    .map(|mut v: Vec<i64>| {
                        v.sort();
                        v
                    })
                    .collect();
            }
            cols.push(check_colours(&s, &plate));
        }
        // The marks matter: most points get another colour from their three frames.
        let changed = cols[0].iter().zip(&cols[1]).filter(|(a, b)| a != b).count();
        assert!(changed > 20, "{changed} of 40 colours changed");
    }

    /// Checks every colour against the mean over the point's inlier frames; returns them.
    fn check_colours(s: &Shot, plate: &[(i64, &Image)]) -> Vec<[u8; 3]> {
        let cols = sample_point_colors(s, plate);
        let c = s.cloud.as_ref().unwrap();
        for (j, p) in s.points().iter().enumerate() {
            let (mut sx, mut n) = (0.0, 0);
            for f in s
                .path
                .frames
                .iter()
                .filter(|f| c.is_inlier(j, f.frame as i64))
            {
                let cam = Camera {
                    intrinsics: s.intrinsics.clone(),
                    pose: f.pose.clone(),
                };
                let x = cam.project(p).unwrap();
                if x.x >= 0.0 && x.x <= 1279.0 && x.y >= 0.0 && x.y <= 719.0 {
                    sx += x.x / 1279.0;
                    n += 1;
                }
            }
            if n > 0 {
                let want = linear_to_srgb8((sx / n as f64) as f32);
                assert!(
                    cols[j][0].abs_diff(want) <= 1,
                    "point {j}: {} vs {want}",
                    cols[j][0]
                );
                assert_eq!(cols[j][2], linear_to_srgb8(0.25));
            } else {
                assert_eq!(cols[j], [128, 128, 128]);
            }
        }
        cols
    }
}
