//! Gray images and the Gaussian image pyramid of pyramidal Lucas–Kanade (book 6.3; Bouguet,
//! "Pyramidal Implementation of the Lucas Kanade Feature Tracker", Intel 2000, section 2.1).
//!
//! A [`GrayImage`] holds brightness on a 0–255 perceptual scale: the tracker works where the
//! book's program did (OpenCV on 8-bit sRGB-encoded gray), so thresholds such as the maximum
//! residual mean the same thing as there. [`GrayImage::from_image`] converts the engine's
//! linear-light images: Rec. 709 luminance, sRGB-encoded, times 255.
//!
//! Pixel convention: the centre of the top-left pixel is (0, 0), x right, y down. Level `l` of
//! a [`Pyramid`] samples the point `p / 2^l` of level 0 at the same place in the scene.

use rayon::prelude::*;
use vfxgraph_imaging::color::{luminance, SrgbEncoder};
use vfxgraph_imaging::Image;

use super::KltError;

/// A single-channel f32 image, row-major, rows top-down, on a 0–255 perceptual scale (book 6.1:
/// an image is a brightness function on a rectangle).
#[derive(Clone, Debug, PartialEq)]
pub struct GrayImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height` brightness values.
    pub data: Vec<f32>,
}

impl GrayImage {
    /// Wraps brightness values; fails when `data.len() != width * height`.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<GrayImage, KltError> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(KltError::BadImage(format!(
                "{width}×{height} image with {} values",
                data.len()
            )));
        }
        Ok(GrayImage {
            width,
            height,
            data,
        })
    }

    /// An image from a function of the pixel (x, y).
    pub fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> f32) -> GrayImage {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        GrayImage {
            width,
            height,
            data,
        }
    }

    /// Converts a linear-light gray/RGB(A) image: Rec. 709 luminance, encoded with the sRGB
    /// transfer curve (a perceptual scale, as 8-bit video is) and scaled to 0–255. Non-finite
    /// values become 0.
    pub fn from_image(img: &Image) -> GrayImage {
        let (w, ch, cc) = (img.width, img.channels.max(1), img.color_channels());
        let mut data = vec![0.0f32; img.width * img.height];
        if w > 0 {
            let srgb = SrgbEncoder::get();
            // One pass per row: the luminance of `Image::luminance`, then the curve.
            data.par_chunks_mut(w)
                .zip(img.data.par_chunks(w * ch))
                .for_each(|(out, row)| {
                    for (o, p) in out.iter_mut().zip(row.chunks_exact(ch)) {
                        let v = if cc == 3 {
                            luminance(p[0], p[1], p[2])
                        } else {
                            p[0]
                        };
                        let v = if v.is_finite() { v } else { 0.0 };
                        *o = 255.0 * srgb.encode(v);
                    }
                });
        }
        GrayImage {
            width: img.width,
            height: img.height,
            data,
        }
    }

    /// Brightness at pixel (x, y) (no bounds check beyond the slice's).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear sample at a point known to lie in the image (0 ≤ x ≤ w − 1, 0 ≤ y ≤ h − 1):
    /// [`GrayImage::sample`] without its clamps (the hot loop of drift correction). A point outside reads a wrong but in-bounds pixel (`as` saturates
    /// at 0 and the indices are capped), never out of the slice.
    #[inline]
    pub fn sample_inside(&self, x: f32, y: f32) -> f32 {
        // Truncation is floor for x ≥ 0.
        let x0 = (x as usize).min(self.width.saturating_sub(2));
        let y0 = (y as usize).min(self.height.saturating_sub(2));
        let x1 = (x0 + 1).min(self.width - 1);
        let y1 = (y0 + 1).min(self.height - 1);
        let (ax, ay) = (x - x0 as f32, y - y0 as f32);
        let top = self.at(x0, y0) * (1.0 - ax) + self.at(x1, y0) * ax;
        let bot = self.at(x0, y1) * (1.0 - ax) + self.at(x1, y1) * ax;
        top * (1.0 - ay) + bot * ay
    }

    /// The image smoothed by the 5-tap binomial filter `[1 4 6 4 1]/16` in x and y (a Gaussian
    /// of σ = 1 px; reflect-101 borders): white noise keeps 0.27 of its standard deviation and
    /// its gradient 0.1, while a feature's texture, several pixels wide, keeps most of its.
    /// Drift correction aligns smoothed windows ([`super::drift`]).
    pub fn binomial_smoothed(&self) -> GrayImage {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return self.clone();
        }
        const K: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
        let mut tmp = vec![0.0f32; w * h];
        tmp.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            let row = &self.data[y * w..][..w];
            for (x, o) in out.iter_mut().enumerate() {
                let mut s = 0.0;
                for (k, c) in K.iter().enumerate() {
                    s += c * row[reflect101(x as isize + k as isize - 2, w)];
                }
                *o = s;
            }
        });
        let mut data = vec![0.0f32; w * h];
        data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
            let rows: [&[f32]; 5] = std::array::from_fn(|k| {
                let r = reflect101(y as isize + k as isize - 2, h);
                &tmp[r * w..][..w]
            });
            for (x, o) in out.iter_mut().enumerate() {
                *o = K[0] * rows[0][x]
                    + K[1] * rows[1][x]
                    + K[2] * rows[2][x]
                    + K[3] * rows[3][x]
                    + K[4] * rows[4][x];
            }
        });
        GrayImage {
            width: w,
            height: h,
            data,
        }
    }

    /// Bilinear sample at a sub-pixel point, coordinates clamped to the image (border
    /// replicated).
    pub fn sample(&self, x: f32, y: f32) -> f32 {
        let xm = (self.width - 1) as f32;
        let ym = (self.height - 1) as f32;
        self.sample_inside(x.clamp(0.0, xm), y.clamp(0.0, ym))
    }
}

/// Reflect-101 index into `0..n` (OpenCV's default border: `dcb|abcd|cba`).
#[inline]
pub(crate) fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    loop {
        if i < 0 {
            i = -i;
        } else if i >= n {
            i = 2 * n - 2 - i;
        } else {
            return i as usize;
        }
    }
}

/// One level of a [`Pyramid`]: the image stored with a border of `pad` pixels on every side
/// (reflect-101) so that a tracking window near the edge reads defined values without
/// per-pixel bounds checks. The Scharr gradient is not stored: the tracker takes it from the
/// bilinearly resampled window (both are convolutions, so they commute), which costs less than
/// filtering and storing two more image-sized planes per level.
#[derive(Clone, Debug)]
pub struct Level {
    /// Width of the level (without the border).
    pub width: usize,
    /// Height of the level (without the border).
    pub height: usize,
    /// Border width in pixels.
    pub pad: usize,
    /// Row stride of the padded buffer: `width + 2 * pad`.
    pub stride: usize,
    /// Padded brightness, `stride * (height + 2 * pad)` values.
    pub img: Vec<f32>,
}

impl Level {
    fn empty() -> Level {
        Level {
            width: 0,
            height: 0,
            pad: 0,
            stride: 0,
            img: Vec::new(),
        }
    }

    /// Sets the size, reusing the buffer's memory (fresh pages cost more than the filtering).
    fn resize(&mut self, w: usize, h: usize, pad: usize) {
        self.width = w;
        self.height = h;
        self.pad = pad;
        self.stride = w + 2 * pad;
        let n = self.stride * (h + 2 * pad);
        self.img.resize(n, 0.0);
    }

    /// Fills the border by reflect-101 from the interior.
    fn finish(&mut self) {
        let (w, h, pad, stride) = (self.width, self.height, self.pad, self.stride);
        self.img[pad * stride..(pad + h) * stride]
            .par_chunks_mut(stride)
            .with_min_len(16)
            .for_each(|row| {
                for px in 0..pad {
                    row[px] = row[pad + reflect101(px as isize - pad as isize, w)];
                    row[pad + w + px] = row[pad + reflect101((w + px) as isize, w)];
                }
            });
        for py in (0..pad).chain(pad + h..h + 2 * pad) {
            let sy = pad + reflect101(py as isize - pad as isize, h);
            self.img
                .copy_within(sy * stride..(sy + 1) * stride, py * stride);
        }
    }

    /// Scharr gradient (3, 10, 3) ⊗ (−1, 0, 1) / 32 at pixel (x, y) of the level, brightness
    /// per pixel, reading the reflect-101 border.
    pub fn scharr_at(&self, x: usize, y: usize) -> [f32; 2] {
        let (s, p) = (self.stride, self.pad);
        let at = |dx: isize, dy: isize| {
            let xx = (x + p) as isize + dx;
            let yy = (y + p) as isize + dy;
            self.img[yy as usize * s + xx as usize]
        };
        let dx = 3.0 * (at(1, -1) - at(-1, -1))
            + 10.0 * (at(1, 0) - at(-1, 0))
            + 3.0 * (at(1, 1) - at(-1, 1));
        let dy = 3.0 * (at(-1, 1) - at(-1, -1))
            + 10.0 * (at(0, 1) - at(0, -1))
            + 3.0 * (at(1, 1) - at(1, -1));
        [dx / 32.0, dy / 32.0]
    }

    fn set_from_gray(&mut self, src: &GrayImage, pad: usize) {
        let w = src.width;
        self.resize(w, src.height, pad);
        let stride = self.stride;
        self.img[pad * stride..(pad + src.height) * stride]
            .par_chunks_mut(stride)
            .with_min_len(16)
            .enumerate()
            .for_each(|(y, row)| row[pad..pad + w].copy_from_slice(&src.data[y * w..][..w]));
        self.finish();
    }

    /// OpenCV's `pyrDown` of `src` (see [`pyr_down`]), read from its reflect-101 border.
    fn set_from_down(&mut self, src: &Level) {
        let (dw, dh) = (src.width.div_ceil(2), src.height.div_ceil(2));
        self.resize(dw, dh, src.pad);
        let (pad, stride, ss, sp) = (self.pad, self.stride, src.stride, src.pad);
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::is_x86_feature_detected!("avx2");
        self.img[pad * stride..(pad + dh) * stride]
            .par_chunks_mut(stride)
            .with_min_len(8)
            .enumerate()
            .for_each_init(
                || vec![0.0f32; 2 * ss],
                |v, (y, row)| {
                    let sy = 2 * y + sp;
                    let rows = &src.img[(sy - 2) * ss..][..5 * ss];
                    let out = &mut row[pad..pad + dw];
                    #[cfg(target_arch = "x86_64")]
                    if avx2 {
                        // SAFETY: the CPU reports AVX2.
                        unsafe { down_row_avx2(rows, ss, sp, v, out) };
                        return;
                    }
                    down_row(rows, ss, sp, v, out);
                },
            );
        self.finish();
    }

    /// The level without its border, as a [`GrayImage`].
    pub fn to_gray(&self) -> GrayImage {
        let mut data = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            let o = (y + self.pad) * self.stride + self.pad;
            data.extend_from_slice(&self.img[o..o + self.width]);
        }
        GrayImage {
            width: self.width,
            height: self.height,
            data,
        }
    }
}

/// One output row of `pyrDown` from the five source rows around it (`rows`, each `ss` long,
/// the centre column of output `x` at `2x + sp`): the vertical 1-4-6-4-1 pass into `v`, then
/// the horizontal one.
#[inline(always)]
fn down_row(rows: &[f32], ss: usize, sp: usize, v: &mut [f32], out: &mut [f32]) {
    let r = |i: usize| &rows[i * ss..][..ss];
    let (a, b, m, d, e) = (r(0), r(1), r(2), r(3), r(4));
    let (v, hbuf) = v.split_at_mut(ss);
    for x in 0..ss {
        v[x] = a[x] + 4.0 * b[x] + 6.0 * m[x] + 4.0 * d[x] + e[x];
    }
    // The horizontal pass at every column (contiguous, so it vectorises), then every other
    // column is kept: output x is centred on column 2x + sp.
    let n = ss - 4;
    let h = &mut hbuf[..n];
    let (v0, v1, v2, v3, v4) = (
        &v[..n],
        &v[1..1 + n],
        &v[2..2 + n],
        &v[3..3 + n],
        &v[4..4 + n],
    );
    for x in 0..n {
        h[x] = (v0[x] + 4.0 * v1[x] + 6.0 * v2[x] + 4.0 * v3[x] + v4[x]) * (1.0 / 256.0);
    }
    for (o, &hv) in out.iter_mut().zip(h[sp - 2..].iter().step_by(2)) {
        *o = hv;
    }
}

/// [`down_row`] compiled for AVX2 (elementwise: the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn down_row_avx2(rows: &[f32], ss: usize, sp: usize, v: &mut [f32], out: &mut [f32]) {
    down_row(rows, ss, sp, v, out)
}

/// Halves an image with OpenCV's `pyrDown`: the 5-tap binomial filter (1 4 6 4 1)/16 in both
/// directions, reflect-101 borders, output `((w + 1) / 2, (h + 1) / 2)`; output pixel (x, y) is
/// centred on input pixel (2x, 2y) (Bouguet 2000, eq. 2.1).
pub fn pyr_down(src: &GrayImage) -> GrayImage {
    let (w, h) = (src.width, src.height);
    let (dw, dh) = (w.div_ceil(2), h.div_ceil(2));
    // Horizontal pass on every source row, keeping only even columns.
    let mut tmp = vec![0.0f32; dw * h];
    tmp.par_chunks_mut(dw).enumerate().for_each(|(y, out)| {
        let row = &src.data[y * w..(y + 1) * w];
        for (x, o) in out.iter_mut().enumerate() {
            let c = 2 * x as isize;
            let v = if c >= 2 && (c as usize) + 2 < w {
                let c = c as usize;
                row[c - 2] + 4.0 * row[c - 1] + 6.0 * row[c] + 4.0 * row[c + 1] + row[c + 2]
            } else {
                let g = |i: isize| row[reflect101(c + i, w)];
                g(-2) + 4.0 * g(-1) + 6.0 * g(0) + 4.0 * g(1) + g(2)
            };
            *o = v;
        }
    });
    let mut data = vec![0.0f32; dw * dh];
    data.par_chunks_mut(dw).enumerate().for_each(|(y, out)| {
        let c = 2 * y as isize;
        let r = |i: isize| &tmp[reflect101(c + i, h) * dw..][..dw];
        let (a, b, m, d, e) = (r(-2), r(-1), r(0), r(1), r(2));
        for x in 0..dw {
            out[x] = (a[x] + 4.0 * b[x] + 6.0 * m[x] + 4.0 * d[x] + e[x]) * (1.0 / 256.0);
        }
    });
    GrayImage {
        width: dw,
        height: dh,
        data,
    }
}

/// A Gaussian pyramid (images only; gradients are taken per window), built once per frame and shared
/// by every feature (Bouguet 2000, section 2.1). Level 0 is the image itself.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Levels from fine (0) to coarse.
    pub levels: Vec<Level>,
}

impl Pyramid {
    /// Builds up to `max_level + 1` levels, stopping early when a level would be narrower
    /// than `2 * pad` pixels; every level has a border of `pad` pixels (at least 2).
    pub fn new(img: &GrayImage, max_level: usize, pad: usize) -> Result<Pyramid, KltError> {
        let mut p = Pyramid { levels: Vec::new() };
        p.rebuild(img, max_level, pad)?;
        Ok(p)
    }

    /// Rebuilds the pyramid for a new image, reusing this pyramid's memory (a tracker keeps
    /// two pyramids and alternates them).
    pub fn rebuild(
        &mut self,
        img: &GrayImage,
        max_level: usize,
        pad: usize,
    ) -> Result<(), KltError> {
        if img.width == 0 || img.height == 0 || img.data.len() != img.width * img.height {
            return Err(KltError::BadImage(format!(
                "empty or inconsistent image ({}×{})",
                img.width, img.height
            )));
        }
        let pad = pad.max(2);
        let mut n = 1;
        let (mut w, mut h) = (img.width, img.height);
        while n <= max_level && w.div_ceil(2) >= 2 * pad.max(4) && h.div_ceil(2) >= 2 * pad.max(4) {
            w = w.div_ceil(2);
            h = h.div_ceil(2);
            n += 1;
        }
        self.levels.truncate(n);
        while self.levels.len() < n {
            self.levels.push(Level::empty());
        }
        self.levels[0].set_from_gray(img, pad);
        for k in 1..n {
            let (done, rest) = self.levels.split_at_mut(k);
            rest[0].set_from_down(&done[k - 1]);
        }
        Ok(())
    }

    /// Width and height of level 0.
    pub fn size(&self) -> (usize, usize) {
        (self.levels[0].width, self.levels[0].height)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_inside_reproduces_a_bilinear_function() {
        // Bilinear interpolation is exact for a + bx + cy + dxy.
        let f = |x: f32, y: f32| 3.0 + 1.5 * x - 2.0 * y + 0.25 * x * y;
        let img = GrayImage::from_fn(7, 5, |x, y| f(x as f32, y as f32));
        for j in 0..=40 {
            for i in 0..=60 {
                let (x, y) = (i as f32 * 0.1, j as f32 * 0.1);
                let v = img.sample_inside(x, y);
                assert!(
                    (v - f(x, y)).abs() < 1e-4,
                    "({x}, {y}): {v} against {}",
                    f(x, y)
                );
                assert_eq!(v.to_bits(), img.sample(x, y).to_bits(), "({x}, {y})");
            }
        }
        // Outside it reads in bounds (no index panic), whatever value it returns.
        assert!(img.sample_inside(-3.0, 99.0).is_finite());
        assert!(img.sample_inside(1e9, -1e9).is_finite());
        let _ = img.sample_inside(f32::NAN, 2.0);
    }

    #[test]
    fn reflect101_matches_opencv() {
        let v: Vec<usize> = (-3..7).map(|i| reflect101(i, 4)).collect();
        assert_eq!(v, vec![3, 2, 1, 0, 1, 2, 3, 2, 1, 0]);
        assert_eq!(reflect101(-5, 1), 0);
    }

    #[test]
    fn pyr_down_keeps_a_linear_ramp_aligned() {
        // A ramp in x: pyrDown of a linear function is the same function at 2x (away from
        // the borders), which checks the (2x, 2y) centring of the convention.
        let img = GrayImage::from_fn(40, 30, |x, y| 2.0 * x as f32 + 0.5 * y as f32);
        let d = pyr_down(&img);
        assert_eq!((d.width, d.height), (20, 15));
        for y in 2..13 {
            for x in 2..18 {
                let want = 2.0 * (2 * x) as f32 + 0.5 * (2 * y) as f32;
                assert!((d.at(x, y) - want).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn scharr_gradient_of_a_ramp_is_exact() {
        let img = GrayImage::from_fn(32, 32, |x, y| 3.0 * x as f32 - 2.0 * y as f32);
        let p = Pyramid::new(&img, 2, 4).unwrap();
        let l = &p.levels[0];
        let [gx, gy] = l.scharr_at(12, 10);
        assert!((gx - 3.0).abs() < 1e-5);
        assert!((gy + 2.0).abs() < 1e-5);
        assert_eq!(l.to_gray(), img);
        assert!(p.levels.len() >= 2);
        // Levels read from the padded buffer equal pyr_down of the unpadded image.
        let d = pyr_down(&img);
        let l1 = p.levels[1].to_gray();
        assert_eq!((l1.width, l1.height), (d.width, d.height));
        for (a, b) in l1.data.iter().zip(&d.data) {
            assert!((a - b).abs() < 1e-3, "{a} {b}");
        }
    }

    #[test]
    fn empty_and_tiny_images() {
        assert!(Pyramid::new(&GrayImage::new(0, 0, vec![]).unwrap(), 3, 4).is_err());
        let p = Pyramid::new(&GrayImage::from_fn(1, 1, |_, _| 7.0), 3, 4).unwrap();
        assert_eq!(p.levels.len(), 1);
        assert_eq!(p.levels[0].to_gray().data, vec![7.0]);
        assert!(GrayImage::new(2, 2, vec![0.0; 3]).is_err());
        let g = GrayImage::from_fn(1, 1, |_, _| 5.0);
        assert_eq!(g.sample(3.0, -2.0), 5.0);
    }
}
