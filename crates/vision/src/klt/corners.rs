//! Choosing the windows to track (book 6.4): Shi–Tomasi "good features to track" (J. Shi and
//! C. Tomasi, "Good Features to Track", CVPR 1994), with OpenCV's `goodFeaturesToTrack`
//! semantics, which is what the book's program called.
//!
//! 1. The score of a pixel is the smaller eigenvalue of the gradient structure tensor
//!    summed over a `block_size`² window (3×3 Sobel derivatives, reflect-101 borders) — the
//!    book's min{λ1, λ2}.
//! 2. Pixels scoring at most `quality × best score` are dropped.
//! 3. Non-maximum suppression: a pixel survives only if it is the maximum of its 3×3
//!    neighbourhood; the one-pixel image border is never a corner.
//! 4. Survivors in decreasing score order are kept unless a kept corner (or an `existing`
//!    point, e.g. a live feature) lies closer than `min_distance`; at most `max_corners`.

use rayon::prelude::*;

use super::pyramid::{reflect101, GrayImage};
use super::KltError;

/// Parameters of [`good_features_to_track`] (book 6.4; Shi & Tomasi 1994). The defaults are
/// the book's: 150 corners, quality level 1e-5, minimum distance 10, 3×3 blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct CornerParams {
    /// Maximum number of corners returned.
    pub max_corners: usize,
    /// Minimum score relative to the best score of the image (OpenCV's `qualityLevel`).
    pub quality: f32,
    /// Minimum Euclidean distance between returned corners (and to `existing` points), pixels.
    pub min_distance: f32,
    /// Side of the window over which the structure tensor is summed (OpenCV's `blockSize`).
    pub block_size: usize,
}

impl Default for CornerParams {
    fn default() -> Self {
        CornerParams {
            max_corners: 150,
            quality: 1e-5,
            min_distance: 10.0,
            block_size: 3,
        }
    }
}

/// A detected corner: its pixel position and its Shi–Tomasi score (book 6.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Column of the pixel centre.
    pub x: f32,
    /// Row of the pixel centre.
    pub y: f32,
    /// Smaller eigenvalue of the structure tensor (units: brightness² per pixel², summed).
    pub score: f32,
}

/// The Shi–Tomasi score image: at every pixel the smaller eigenvalue of
/// `Σ_block [Ix², IxIy; IxIy, Iy²]` with 3×3 Sobel derivatives divided by 8 (so a gradient is
/// in brightness per pixel), reflect-101 borders (book 6.4; Shi & Tomasi 1994, OpenCV's
/// `cornerMinEigenVal`).
pub fn min_eigen_map(img: &GrayImage, block_size: usize) -> Vec<f32> {
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let b = block_size.max(1) as isize;
    let (lo, hi) = (-(b / 2), b - 1 - b / 2);
    // Sobel derivatives of row `y` (divided by 8), reflect-101 borders.
    let sobel_row = |y: usize, gx: &mut [f32], gy: &mut [f32]| {
        let yi = y as isize;
        let r0 = &img.data[reflect101(yi - 1, h) * w..][..w];
        let r1 = &img.data[y * w..][..w];
        let r2 = &img.data[reflect101(yi + 1, h) * w..][..w];
        for x in 0..w {
            let (xl, xr) = if x > 0 && x + 1 < w {
                (x - 1, x + 1)
            } else {
                (reflect101(x as isize - 1, w), reflect101(x as isize + 1, w))
            };
            let dx = (r0[xr] - r0[xl]) + 2.0 * (r1[xr] - r1[xl]) + (r2[xr] - r2[xl]);
            let dy = (r2[xl] - r0[xl]) + 2.0 * (r2[x] - r0[x]) + (r2[xr] - r0[xr]);
            gx[x] = dx * 0.125;
            gy[x] = dy * 0.125;
        }
    };
    // Row by row (no image-sized temporaries): vertical sums of the products over the block
    // rows, then horizontal box sums, then the smaller eigenvalue.
    let mut eig = vec![0.0f32; w * h];
    eig.par_chunks_mut(w).enumerate().for_each_init(
        || (vec![0.0f32; w], vec![0.0f32; w], vec![[0.0f32; 3]; w]),
        |(gx, gy, vs), (y, out)| {
            vs.iter_mut().for_each(|v| *v = [0.0; 3]);
            for d in lo..=hi {
                sobel_row(reflect101(y as isize + d, h), gx, gy);
                for ((v, &a), &c) in vs.iter_mut().zip(gx.iter()).zip(gy.iter()) {
                    v[0] += a * a;
                    v[1] += a * c;
                    v[2] += c * c;
                }
            }
            for (x, o) in out.iter_mut().enumerate() {
                let mut acc = [0.0f32; 3];
                let (x0, x1) = (x as isize + lo, x as isize + hi);
                if x0 >= 0 && (x1 as usize) < w {
                    for p in &vs[x0 as usize..=x1 as usize] {
                        acc[0] += p[0];
                        acc[1] += p[1];
                        acc[2] += p[2];
                    }
                } else {
                    for d in lo..=hi {
                        let p = vs[reflect101(x as isize + d, w)];
                        acc[0] += p[0];
                        acc[1] += p[1];
                        acc[2] += p[2];
                    }
                }
                let a = acc[0] * 0.5;
                let c = acc[2] * 0.5;
                let bb = acc[1];
                *o = (a + c) - ((a - c) * (a - c) + bb * bb).sqrt();
            }
        },
    );
    eig
}

/// Shi–Tomasi corners with OpenCV `goodFeaturesToTrack` semantics (book 6.4; Shi & Tomasi
/// 1994). `mask`, if given, has one entry per pixel and excludes pixels where it is `false`;
/// `existing` points (e.g. live features, book 6.5) take part in the minimum-distance test as
/// already kept corners but are not returned. Ties in score are broken by the larger pixel
/// index first (as OpenCV), so the result is deterministic. Corners come best first.
pub fn good_features_to_track(
    img: &GrayImage,
    params: &CornerParams,
    mask: Option<&[bool]>,
    existing: &[[f32; 2]],
) -> Result<Vec<Corner>, KltError> {
    let (w, h) = (img.width, img.height);
    if let Some(m) = mask {
        if m.len() != w * h {
            return Err(KltError::BadImage(format!(
                "mask has {} entries for a {w}×{h} image",
                m.len()
            )));
        }
    }
    if params.block_size == 0 {
        return Err(KltError::BadParam("block_size must be at least 1".into()));
    }
    let ok = |v: f32| v.is_finite() && v >= 0.0;
    if !ok(params.quality) || !ok(params.min_distance) {
        return Err(KltError::BadParam(
            "quality and min_distance must be finite and non-negative".into(),
        ));
    }
    if w < 3 || h < 3 || params.max_corners == 0 {
        return Ok(Vec::new());
    }
    let eig = min_eigen_map(img, params.block_size);
    let max = eig.par_iter().cloned().reduce(|| 0.0f32, f32::max);
    if max <= 0.0 {
        return Ok(Vec::new());
    }
    let thresh = max * params.quality;
    // Candidates: above the threshold and the maximum of their 3×3 neighbourhood.
    let mut cand: Vec<(f32, usize)> = (1..h - 1)
        .into_par_iter()
        .flat_map_iter(|y| {
            let eig = &eig;
            (1..w - 1).filter_map(move |x| {
                let i = y * w + x;
                let v = eig[i];
                if v <= thresh || mask.is_some_and(|m| !m[i]) {
                    return None;
                }
                for dy in [i - w, i, i + w] {
                    if eig[dy - 1] > v || eig[dy] > v || eig[dy + 1] > v {
                        return None;
                    }
                }
                Some((v, i))
            })
        })
        .collect();
    cand.par_sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(b.1.cmp(&a.1)));
    // Minimum distance with a grid of cells of side min_distance.
    let md = params.min_distance;
    let mut out = Vec::new();
    if md < 1.0 {
        for &(v, i) in cand.iter().take(params.max_corners) {
            out.push(Corner {
                x: (i % w) as f32,
                y: (i / w) as f32,
                score: v,
            });
        }
        return Ok(out);
    }
    let cell = md;
    let gw = (w as f32 / cell).ceil() as usize + 1;
    let gh = (h as f32 / cell).ceil() as usize + 1;
    let mut grid: Vec<Vec<[f32; 2]>> = vec![Vec::new(); gw * gh];
    let cell_of = |x: f32, y: f32| -> Option<(usize, usize)> {
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let cx = (x / cell).floor();
        let cy = (y / cell).floor();
        if cx < 0.0 || cy < 0.0 || cx >= gw as f32 || cy >= gh as f32 {
            return None;
        }
        Some((cx as usize, cy as usize))
    };
    let md2 = md * md;
    let near = |grid: &Vec<Vec<[f32; 2]>>, x: f32, y: f32| -> bool {
        let (cx, cy) = match cell_of(x, y) {
            Some(c) => c,
            None => return false,
        };
        for gy in cy.saturating_sub(1)..=(cy + 1).min(gh - 1) {
            for gx in cx.saturating_sub(1)..=(cx + 1).min(gw - 1) {
                for p in &grid[gy * gw + gx] {
                    let (dx, dy) = (p[0] - x, p[1] - y);
                    if dx * dx + dy * dy < md2 {
                        return true;
                    }
                }
            }
        }
        false
    };
    for p in existing {
        // Points outside the image cannot be near a candidate closer than md unless they
        // are within one cell; clamp into the grid for the test.
        let (x, y) = (
            p[0].clamp(-cell * 0.5, w as f32),
            p[1].clamp(-cell * 0.5, h as f32),
        );
        if let Some((cx, cy)) = cell_of(x.max(0.0), y.max(0.0)) {
            grid[cy * gw + cx].push(*p);
        }
    }
    for &(v, i) in &cand {
        let (x, y) = ((i % w) as f32, (i / w) as f32);
        if near(&grid, x, y) {
            continue;
        }
        if let Some((cx, cy)) = cell_of(x, y) {
            grid[cy * gw + cx].push([x, y]);
        }
        out.push(Corner { x, y, score: v });
        if out.len() >= params.max_corners {
            break;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark square on a bright background: its four corners are the best features.
    fn square() -> GrayImage {
        GrayImage::from_fn(64, 64, |x, y| {
            if (20..44).contains(&x) && (20..44).contains(&y) {
                40.0
            } else {
                200.0
            }
        })
    }

    #[test]
    fn finds_the_four_corners_of_a_square() {
        let p = CornerParams {
            max_corners: 4,
            quality: 0.1,
            min_distance: 5.0,
            block_size: 3,
        };
        let c = good_features_to_track(&square(), &p, None, &[]).unwrap();
        assert_eq!(c.len(), 4);
        for k in &c {
            let near = |a: f32, b: f32| (a - b).abs() <= 1.0;
            assert!(
                (near(k.x, 19.5) || near(k.x, 43.5)) && (near(k.y, 19.5) || near(k.y, 43.5)),
                "{k:?}"
            );
        }
        // Scores are non-increasing.
        assert!(c.windows(2).all(|w| w[0].score >= w[1].score));
    }

    #[test]
    fn min_distance_mask_and_existing_points() {
        let img = GrayImage::from_fn(80, 80, |x, y| {
            (((x / 4) + (y / 4)) % 2) as f32 * 200.0 + ((x * 7 + y * 13) % 5) as f32
        });
        let p = CornerParams {
            max_corners: 1000,
            quality: 0.01,
            min_distance: 9.0,
            block_size: 3,
        };
        let c = good_features_to_track(&img, &p, None, &[]).unwrap();
        assert!(c.len() > 20);
        for (i, a) in c.iter().enumerate() {
            for b in &c[i + 1..] {
                let d = ((a.x - b.x).powi(2) + (a.y - b.y).powi(2)).sqrt();
                assert!(d >= 9.0, "{a:?} {b:?}");
            }
        }
        // A mask keeps corners in the left half only.
        let mask: Vec<bool> = (0..80 * 80).map(|i| i % 80 < 40).collect();
        let c2 = good_features_to_track(&img, &p, Some(&mask), &[]).unwrap();
        assert!(!c2.is_empty() && c2.iter().all(|k| k.x < 40.0));
        // Existing points block their neighbourhood.
        let existing: Vec<[f32; 2]> = c.iter().map(|k| [k.x, k.y]).collect();
        let c3 = good_features_to_track(&img, &p, None, &existing).unwrap();
        for k in &c3 {
            for e in &existing {
                assert!((k.x - e[0]).powi(2) + (k.y - e[1]).powi(2) >= 81.0);
            }
        }
        // Bad input is an error, not a panic.
        assert!(good_features_to_track(&img, &p, Some(&mask[..10]), &[]).is_err());
    }

    #[test]
    fn flat_and_tiny_images_have_no_corners() {
        let p = CornerParams::default();
        let flat = GrayImage::from_fn(30, 30, |_, _| 9.0);
        assert!(good_features_to_track(&flat, &p, None, &[])
            .unwrap()
            .is_empty());
        let tiny = GrayImage::from_fn(2, 1, |x, _| x as f32);
        assert!(good_features_to_track(&tiny, &p, None, &[])
            .unwrap()
            .is_empty());
    }
}
