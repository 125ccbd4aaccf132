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
///
/// As the tracker's params (`klt_track`): `features` (the tracker's slots, 0 = from the frame
/// size), `min_distance`, `quality`.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct CornerOptions {
    /// Maximum number of corners returned.
    #[param(
        name = "features",
        range = 0..=100_000,
        doc = "feature slots per frame (the book's N: 150); 0 = from the frame size, one per 36 × 36 px block and at least 150 (400 at 960 × 540)"
    )]
    pub max_corners: usize,
    /// minimum distance between features, pixels
    ///
    /// Minimum Euclidean distance between returned corners (and to `existing` points).
    #[param(range = 0.0..=10_000.0)]
    pub min_distance: f32,
    /// corner score threshold relative to the best corner (OpenCV qualityLevel)
    #[param(range = 0.0..=1.0)]
    pub quality: f32,
    /// Side of the window over which the structure tensor is summed (OpenCV's `blockSize`).
    #[param(skip)]
    pub block_size: usize,
}

impl Default for CornerOptions {
    fn default() -> Self {
        CornerOptions {
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

/// Per-thread scratch of the row pipeline of the Shi–Tomasi score: Sobel products of the
/// last `block_size` image rows (tagged by row), the vertical and horizontal block sums, and
/// the last three score rows with their horizontal 3-maxima for non-maximum suppression.
struct Rows {
    w: usize,
    /// Image row held by each product slot (`usize::MAX`: none).
    tags: Vec<usize>,
    /// Ix², IxIy, Iy² of the row in each slot (slot `q % block_size` holds row `q`).
    prod: Vec<[Vec<f32>; 3]>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    vs: [Vec<f32>; 3],
    hs: [Vec<f32>; 3],
    /// Score rows `y % 3`.
    eig: [Vec<f32>; 3],
    /// Horizontal 3-maximum of the score rows `y % 3`.
    hmax: [Vec<f32>; 3],
    /// Local-maximum flags of one row.
    flags: Vec<u8>,
}

impl Rows {
    fn new(w: usize, b: usize) -> Rows {
        let v = || vec![0.0f32; w];
        Rows {
            w,
            tags: vec![usize::MAX; b],
            prod: (0..b).map(|_| [v(), v(), v()]).collect(),
            gx: v(),
            gy: v(),
            vs: [v(), v(), v()],
            hs: [v(), v(), v()],
            eig: [v(), v(), v()],
            hmax: [v(), v(), v()],
            flags: vec![0; w],
        }
    }

    /// Sobel derivatives / 8 of image row `y` (reflect-101 borders) into `gx`, `gy`, and their
    /// products into slot `y % b`.
    #[inline(always)]
    fn products(&mut self, img: &GrayImage, y: usize) {
        let (w, h) = (img.width, img.height);
        let b = self.tags.len();
        let r0 = &img.data[reflect101(y as isize - 1, h) * w..][..w];
        let r1 = &img.data[y * w..][..w];
        let r2 = &img.data[reflect101(y as isize + 1, h) * w..][..w];
        let (gx, gy) = (&mut self.gx[..w], &mut self.gy[..w]);
        let edge = |x: usize| {
            let (xl, xr) = (reflect101(x as isize - 1, w), reflect101(x as isize + 1, w));
            let dx = (r0[xr] - r0[xl]) + 2.0 * (r1[xr] - r1[xl]) + (r2[xr] - r2[xl]);
            let dy = (r2[xl] - r0[xl]) + 2.0 * (r2[x] - r0[x]) + (r2[xr] - r0[xr]);
            (dx * 0.125, dy * 0.125)
        };
        (gx[0], gy[0]) = edge(0);
        if w > 1 {
            (gx[w - 1], gy[w - 1]) = edge(w - 1);
        }
        if w > 2 {
            let n = w - 2;
            let (a0, a1, a2) = (&r0[..n], &r1[..n], &r2[..n]);
            let (m0, m2) = (&r0[1..1 + n], &r2[1..1 + n]);
            let (c0, c1, c2) = (&r0[2..2 + n], &r1[2..2 + n], &r2[2..2 + n]);
            let (ox, oy) = (&mut gx[1..1 + n], &mut gy[1..1 + n]);
            for x in 0..n {
                let dx = (c0[x] - a0[x]) + 2.0 * (c1[x] - a1[x]) + (c2[x] - a2[x]);
                let dy = (a2[x] - a0[x]) + 2.0 * (m2[x] - m0[x]) + (c2[x] - c0[x]);
                ox[x] = dx * 0.125;
                oy[x] = dy * 0.125;
            }
        }
        let slot = y % b;
        self.tags[slot] = y;
        let [xx, xy, yy] = &mut self.prod[slot];
        let (xx, xy, yy) = (&mut xx[..w], &mut xy[..w], &mut yy[..w]);
        let (gx, gy) = (&self.gx[..w], &self.gy[..w]);
        for x in 0..w {
            xx[x] = gx[x] * gx[x];
            xy[x] = gx[x] * gy[x];
            yy[x] = gy[x] * gy[x];
        }
    }

    /// Score row `y` into `eig[y % 3]` and its horizontal 3-maximum into `hmax[y % 3]`;
    /// returns the row's largest score.
    #[inline(always)]
    fn score_row(&mut self, img: &GrayImage, y: usize) -> f32 {
        let (w, h) = (self.w, img.height);
        let b = self.tags.len() as isize;
        let (lo, hi) = (-(b / 2), b - 1 - b / 2);
        // Vertical block sums of the products.
        let mut srcs = [0usize; 64];
        let nb = (hi - lo + 1) as usize;
        for (k, d) in (lo..=hi).enumerate() {
            let q = reflect101(y as isize + d, h);
            if self.tags[q % b as usize] != q {
                self.products(img, q);
            }
            if k < srcs.len() {
                srcs[k] = q % b as usize;
            }
        }
        for c in 0..3 {
            let v = &mut self.vs[c][..w];
            let s0 = &self.prod[srcs[0]][c][..w];
            if nb == 1 {
                v.copy_from_slice(s0);
                continue;
            }
            let s1 = &self.prod[srcs[1]][c][..w];
            for x in 0..w {
                v[x] = s0[x] + s1[x];
            }
            for k in 2..nb {
                let q = if k < srcs.len() {
                    srcs[k]
                } else {
                    reflect101(y as isize + lo + k as isize, h) % b as usize
                };
                let sk = &self.prod[q][c][..w];
                for x in 0..w {
                    v[x] += sk[x];
                }
            }
        }
        // Horizontal block sums: interior by shifted slices, borders by reflection.
        let (x0, x1) = ((-lo) as usize, w.saturating_sub(hi as usize));
        for c in 0..3 {
            let (v, o) = (&self.vs[c][..w], &mut self.hs[c][..w]);
            if x1 > x0 {
                let n = x1 - x0;
                if b >= 2 {
                    let (dst, s0, s1) = (&mut o[x0..x1], &v[..n], &v[1..1 + n]);
                    for x in 0..n {
                        dst[x] = s0[x] + s1[x];
                    }
                } else {
                    o[x0..x1].copy_from_slice(&v[..n]);
                }
                for d in 2..b as usize {
                    let (dst, src) = (&mut o[x0..x1], &v[d..d + n]);
                    for x in 0..n {
                        dst[x] += src[x];
                    }
                }
            }
            for x in (0..x0.min(w)).chain(x1.max(x0).min(w)..w) {
                let mut acc = 0.0f32;
                for d in lo..=hi {
                    acc += v[reflect101(x as isize + d, w)];
                }
                o[x] = acc;
            }
        }
        // The smaller eigenvalue of [a b; b c] times 2: (a + c) − √((a − c)² + b²) with the
        // halved diagonal (as OpenCV's cornerMinEigenVal).
        let e = &mut self.eig[y % 3][..w];
        let (sxx, sxy, syy) = (&self.hs[0][..w], &self.hs[1][..w], &self.hs[2][..w]);
        for x in 0..w {
            let a = sxx[x] * 0.5;
            let c = syy[x] * 0.5;
            let bb = sxy[x];
            e[x] = (a + c) - ((a - c) * (a - c) + bb * bb).sqrt();
        }
        // Scores are finite (finite brightness), so a plain compare is the maximum.
        let mx = |a: f32, b: f32| if a > b { a } else { b };
        let mut lanes = [0.0f32; 8];
        let mut it = e.chunks_exact(8);
        for ch in &mut it {
            for k in 0..8 {
                lanes[k] = mx(lanes[k], ch[k]);
            }
        }
        let best = it
            .remainder()
            .iter()
            .chain(&lanes)
            .fold(0.0f32, |a, &b| mx(a, b));
        let m = &mut self.hmax[y % 3][..w];
        m[0] = e[0];
        m[w - 1] = e[w - 1];
        if w > 2 {
            let n = w - 2;
            let (l, c, r, o) = (&e[..n], &e[1..1 + n], &e[2..2 + n], &mut m[1..1 + n]);
            for x in 0..n {
                let m = if l[x] > c[x] { l[x] } else { c[x] };
                o[x] = if r[x] > m { r[x] } else { m };
            }
        }
        best
    }

    /// Local maxima of row `y` (rows `y − 1`, `y`, `y + 1` are in the rings): pixels with a
    /// positive score not below any of their eight neighbours, not on the image border and
    /// inside the mask, pushed as (score, pixel index).
    #[inline(always)]
    fn maxima(&mut self, y: usize, mask: Option<&[bool]>, out: &mut Vec<(f32, usize)>) {
        let w = self.w;
        let e = &self.eig[y % 3][..w];
        let (m0, m1, m2) = (
            &self.hmax[(y + 2) % 3][..w],
            &self.hmax[y % 3][..w],
            &self.hmax[(y + 1) % 3][..w],
        );
        // Flags first (a branch-free loop the compiler vectorises), then a scan that skips
        // eight flags at a time: local maxima are sparse.
        let f = &mut self.flags[..w];
        for x in 0..w {
            let v = e[x];
            let d = if m0[x] > m1[x] { m0[x] } else { m1[x] };
            let d = if m2[x] > d { m2[x] } else { d };
            f[x] = ((v > 0.0) & (v >= d)) as u8;
        }
        f[0] = 0;
        f[w - 1] = 0;
        let mut push = |x: usize| {
            let i = y * w + x;
            if mask.is_none_or(|m| m[i]) {
                out.push((e[x], i));
            }
        };
        let mut it = f.chunks_exact(8);
        let mut x0 = 0;
        for ch in &mut it {
            if u64::from_ne_bytes(ch.try_into().unwrap_or([0; 8])) != 0 {
                for (k, &v) in ch.iter().enumerate() {
                    if v != 0 {
                        push(x0 + k);
                    }
                }
            }
            x0 += 8;
        }
        for (k, &v) in it.remainder().iter().enumerate() {
            if v != 0 {
                push(x0 + k);
            }
        }
    }
}

/// Rows per parallel band of the corner detector.
const BAND: usize = 32;

/// Scores rows `y0..y1` (and the rows next to them that non-maximum suppression needs);
/// returns the largest score of rows `y0..y1`, the local maxima among them, and, if `map` is
/// given, the rows' scores.
#[inline(always)]
fn band_generic(
    img: &GrayImage,
    rows: &mut Rows,
    (y0, y1): (usize, usize),
    mask: Option<&[bool]>,
    mut map: Option<&mut [f32]>,
    out: &mut Vec<(f32, usize)>,
) -> f32 {
    let (w, h) = (img.width, img.height);
    rows.tags.iter_mut().for_each(|t| *t = usize::MAX);
    let mut best = 0.0f32;
    let find = map.is_none();
    let first = if find { y0.saturating_sub(1) } else { y0 };
    let last = if find { (y1 + 1).min(h) } else { y1 };
    for y in first..last {
        let m = rows.score_row(img, y);
        if (y0..y1).contains(&y) {
            best = best.max(m);
            if let Some(map) = map.as_deref_mut() {
                map[(y - y0) * w..][..w].copy_from_slice(&rows.eig[y % 3][..w]);
            }
        }
        if find && y >= 1 {
            let c = y - 1;
            if c >= y0.max(1) && c < y1 && c + 1 < h && w >= 3 {
                rows.maxima(c, mask, out);
            }
        }
    }
    best
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn band_avx2(
    img: &GrayImage,
    rows: &mut Rows,
    ys: (usize, usize),
    mask: Option<&[bool]>,
    map: Option<&mut [f32]>,
    out: &mut Vec<(f32, usize)>,
) -> f32 {
    band_generic(img, rows, ys, mask, map, out)
}

/// [`band_generic`], compiled for AVX2 when the CPU has it (elementwise loops only, so the
/// result is the same bit for bit).
fn band(
    img: &GrayImage,
    rows: &mut Rows,
    ys: (usize, usize),
    mask: Option<&[bool]>,
    map: Option<&mut [f32]>,
    out: &mut Vec<(f32, usize)>,
) -> f32 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU reports AVX2.
        return unsafe { band_avx2(img, rows, ys, mask, map, out) };
    }
    band_generic(img, rows, ys, mask, map, out)
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
    let b = block_size.max(1);
    let mut eig = vec![0.0f32; w * h];
    eig.par_chunks_mut(w * BAND).enumerate().for_each_init(
        || Rows::new(w, b),
        |rows, (k, chunk)| {
            let y0 = k * BAND;
            let y1 = (y0 + BAND).min(h);
            band(img, rows, (y0, y1), None, Some(chunk), &mut Vec::new());
        },
    );
    eig
}

/// Shi–Tomasi corners with OpenCV `goodFeaturesToTrack` semantics (book 6.4; Shi & Tomasi
/// 1994). `mask`, if given, has one entry per pixel and excludes pixels where it is `false`;
/// `existing` points (e.g. live features, book 6.5) take part in the minimum-distance test as
/// already kept corners but are not returned. Ties in score are broken by the larger pixel
/// index first (as OpenCV), so the result is deterministic. Corners come best first.
///
/// The score image is never stored: bands of rows are scored in parallel, each keeping only
/// the local maxima of its rows, and only as many of the best candidates are sorted as the
/// minimum-distance pass needs.
pub fn good_features_to_track(
    img: &GrayImage,
    params: &CornerOptions,
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
    let b = params.block_size;
    let bands: Vec<(f32, Vec<(f32, usize)>)> = (0..h.div_ceil(BAND))
        .into_par_iter()
        .map_init(
            || Rows::new(w, b),
            |rows, k| {
                let y0 = k * BAND;
                let mut out = Vec::new();
                let m = band(img, rows, (y0, (y0 + BAND).min(h)), mask, None, &mut out);
                (m, out)
            },
        )
        .collect();
    let max = bands.iter().map(|b| b.0).fold(0.0f32, f32::max);
    if max <= 0.0 {
        return Ok(Vec::new());
    }
    let thresh = max * params.quality;
    // Candidates: above the threshold and the maximum of their 3×3 neighbourhood.
    let mut cand: Vec<(f32, usize)> = bands
        .into_iter()
        .flat_map(|b| b.1)
        .filter(|c| c.0 > thresh)
        .collect();
    let order = |a: &(f32, usize), b: &(f32, usize)| b.0.total_cmp(&a.0).then(b.1.cmp(&a.1));
    // Minimum distance with a grid of cells of side min_distance.
    let md = params.min_distance;
    let mut out = Vec::new();
    if md < 1.0 {
        let k = params.max_corners.min(cand.len());
        if k < cand.len() {
            cand.select_nth_unstable_by(k, order);
        }
        cand.truncate(k);
        cand.sort_unstable_by(order);
        for &(v, i) in &cand {
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
    // Best first, sorting only a head of the candidates at a time: the order is total
    // (scores, then distinct pixel indices), so this is the full sort's order.
    let mut rest = &mut cand[..];
    'outer: while !rest.is_empty() {
        let need = params.max_corners - out.len();
        let m = (4 * need + 256).min(rest.len());
        if m < rest.len() {
            rest.select_nth_unstable_by(m - 1, order);
        }
        let (head, tail) = rest.split_at_mut(m);
        head.sort_unstable_by(order);
        for &(v, i) in head.iter() {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if near(&grid, x, y) {
                continue;
            }
            if let Some((cx, cy)) = cell_of(x, y) {
                grid[cy * gw + cx].push([x, y]);
            }
            out.push(Corner { x, y, score: v });
            if out.len() >= params.max_corners {
                break 'outer;
            }
        }
        rest = tail;
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
        let p = CornerOptions {
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
        let p = CornerOptions {
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

    /// A seeded noisy texture (no ties to speak of).
    fn noise(w: usize, h: usize, seed: u64) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            let st = (seed ^ ((y * w + x) as u64).wrapping_mul(0x9E3779B97F4A7C15))
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let st = (st ^ (st >> 29)).wrapping_mul(0xBF58476D1CE4E5B9);
            let r = (st >> 40) as f32 / (1u64 << 24) as f32;
            100.0 + 60.0 * ((x as f32 * 0.3).sin() * (y as f32 * 0.2).cos()) + 40.0 * r
        })
    }

    /// The score straight from its definition, one pixel at a time.
    fn direct_score(img: &GrayImage, b: usize, x: usize, y: usize) -> f32 {
        let (w, h) = (img.width, img.height);
        let at = |x: isize, y: isize| img.at(reflect101(x, w), reflect101(y, h));
        let (lo, hi) = (-(b as isize / 2), b as isize - 1 - b as isize / 2);
        let (mut sxx, mut sxy, mut syy) = (0.0f64, 0.0f64, 0.0f64);
        for dy in lo..=hi {
            for dx in lo..=hi {
                let (px, py) = (
                    reflect101(x as isize + dx, w) as isize,
                    reflect101(y as isize + dy, h) as isize,
                );
                let gx = ((at(px + 1, py - 1) - at(px - 1, py - 1))
                    + 2.0 * (at(px + 1, py) - at(px - 1, py))
                    + (at(px + 1, py + 1) - at(px - 1, py + 1))) as f64
                    / 8.0;
                let gy = ((at(px - 1, py + 1) - at(px - 1, py - 1))
                    + 2.0 * (at(px, py + 1) - at(px, py - 1))
                    + (at(px + 1, py + 1) - at(px + 1, py - 1))) as f64
                    / 8.0;
                sxx += gx * gx;
                sxy += gx * gy;
                syy += gy * gy;
            }
        }
        let (a, c) = (sxx * 0.5, syy * 0.5);
        ((a + c) - ((a - c) * (a - c) + sxy * sxy).sqrt()) as f32
    }

    #[test]
    fn score_map_matches_its_definition() {
        // Sizes that exercise band edges (32 rows), 8-lane tails and block sizes 1–5.
        for (w, h, b) in [(37, 70, 3), (9, 5, 1), (16, 33, 2), (23, 41, 5), (3, 3, 3)] {
            let img = noise(w, h, (w * h + b) as u64);
            let map = min_eigen_map(&img, b);
            let scale = map.iter().fold(0.0f32, |a, &v| a.max(v.abs())).max(1.0);
            for y in 0..h {
                for x in 0..w {
                    let want = direct_score(&img, b, x, y);
                    let got = map[y * w + x];
                    assert!(
                        (got - want).abs() <= 1e-4 * scale,
                        "{w}x{h} b{b} ({x},{y}): {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn corners_match_a_brute_force_reference() {
        let img = noise(150, 97, 7);
        let p = CornerOptions {
            max_corners: 120,
            quality: 0.05,
            min_distance: 6.0,
            block_size: 3,
        };
        let got = good_features_to_track(&img, &p, None, &[]).unwrap();
        // Reference: every non-border pixel that is the maximum of its 3×3 neighbourhood and
        // above the threshold, fully sorted, then a quadratic minimum-distance pass.
        let (w, h) = (img.width, img.height);
        let map = min_eigen_map(&img, 3);
        let max = map.iter().fold(0.0f32, |a, &v| a.max(v));
        let mut cand = Vec::new();
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let v = map[y * w + x];
                let is_max =
                    (0..3).all(|dy| (0..3).all(|dx| map[(y + dy - 1) * w + x + dx - 1] <= v));
                if v > max * p.quality && is_max {
                    cand.push((v, y * w + x));
                }
            }
        }
        cand.sort_by(|a, b| b.0.total_cmp(&a.0).then(b.1.cmp(&a.1)));
        let mut want: Vec<(f32, f32)> = Vec::new();
        for (_, i) in cand {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if want
                .iter()
                .all(|q| (q.0 - x).powi(2) + (q.1 - y).powi(2) >= 36.0)
            {
                want.push((x, y));
            }
            if want.len() == p.max_corners {
                break;
            }
        }
        assert!(want.len() > 50);
        let got: Vec<(f32, f32)> = got.iter().map(|c| (c.x, c.y)).collect();
        assert_eq!(got, want);
    }

    #[test]
    fn compiled_for_avx2_or_not_the_scores_are_the_same() {
        if !crate::has_avx2_or_say_so("compiled_for_avx2_or_not_the_scores_are_the_same") {
            return;
        }
        let img = noise(77, 40, 3);
        let (mut a, mut b) = (vec![0.0; 77 * 32], vec![0.0; 77 * 32]);
        let (mut ra, mut rb) = (Rows::new(77, 3), Rows::new(77, 3));
        band(&img, &mut ra, (0, 32), None, Some(&mut a), &mut Vec::new());
        band_generic(&img, &mut rb, (0, 32), None, Some(&mut b), &mut Vec::new());
        assert_eq!(a, b);
        let (mut ca, mut cb) = (Vec::new(), Vec::new());
        band(&img, &mut ra, (8, 40), None, None, &mut ca);
        band_generic(&img, &mut rb, (8, 40), None, None, &mut cb);
        assert!(!ca.is_empty());
        assert_eq!(ca, cb);
    }

    #[test]
    fn flat_and_tiny_images_have_no_corners() {
        let p = CornerOptions::default();
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
