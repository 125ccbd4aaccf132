//! Y'CbCr 4:2:0 to linear RGB: the inverse of the stream's matrix (BT.601/709/2020), limited
//! (Y' 16–235, Cb/Cr 16–240) or full range, chroma upsampled bilinearly from H.264's default
//! chroma sample position (type 0: co-sited with even luma columns, half-way between luma
//! rows), and the R'G'B' decoded with the sRGB curve — what a display shows, and the same
//! linear values a PNG export of the frame gives.

use rayon::prelude::*;
use vfxgraph_imaging::color::srgb_to_linear;
use vfxgraph_imaging::Image;

use crate::sps::ColorInfo;

/// One decoded picture: three 8-bit planes with their strides; chroma is half size.
pub struct Planes<'a> {
    /// Width and height of the luma plane (the picture).
    pub width: usize,
    /// Height of the picture.
    pub height: usize,
    /// Luma rows, `y_stride` apart.
    pub y: &'a [u8],
    /// Cb rows, `uv_stride` apart, `(width + 1) / 2` used per row.
    pub u: &'a [u8],
    /// Cr rows, `uv_stride` apart.
    pub v: &'a [u8],
    /// Luma row stride.
    pub y_stride: usize,
    /// Chroma row stride.
    pub uv_stride: usize,
}

/// R'G'B' (0–1, gamma-encoded, unclamped) of one Y'CbCr triple (0–255 code values).
#[inline]
pub fn ycbcr_to_rgb(y: f32, cb: f32, cr: f32, c: &ColorInfo) -> [f32; 3] {
    let (kr, kb) = c.matrix.kr_kb();
    let kg = 1.0 - kr - kb;
    let (yy, pb, pr) = if c.full_range {
        (y / 255.0, (cb - 128.0) / 255.0, (cr - 128.0) / 255.0)
    } else {
        (
            (y - 16.0) / 219.0,
            (cb - 128.0) / 224.0,
            (cr - 128.0) / 224.0,
        )
    };
    let r = yy + 2.0 * (1.0 - kr) * pr;
    let b = yy + 2.0 * (1.0 - kb) * pb;
    let g = (yy - kr * r - kb * b) / kg;
    [r, g, b]
}

/// Converts a picture to a linear-light RGB [`Image`] (values clamped to 0–1 before the
/// sRGB decoding, as a display would).
pub fn to_image(p: &Planes<'_>, c: &ColorInfo) -> Image {
    convert(
        Layout {
            width: p.width,
            height: p.height,
            half_width: true,
            half_height: true,
            y_stride: p.y_stride,
            uv_stride: p.uv_stride,
        },
        [Bytes(p.y), Bytes(p.u), Bytes(p.v)],
        (1.0, 0.0),
        (1.0, 0.0),
        c,
    )
}

/// One decoded picture of any planar Y'CbCr layout FFmpeg delivers: 8 to 16 bits a sample,
/// chroma full size or halved across (4:2:2) or across and down (4:2:0). The planes are the
/// bytes as delivered: one a sample at 8 bits, two (little-endian) above.
pub struct Planar<'a> {
    /// Width of the picture (the luma plane).
    pub width: usize,
    /// Height of the picture.
    pub height: usize,
    /// Bits a sample (8, 10, 12, 16).
    pub bits: u32,
    /// Chroma halved horizontally (4:2:2 and 4:2:0).
    pub half_width: bool,
    /// Chroma halved vertically (4:2:0).
    pub half_height: bool,
    /// Luma, `width` × `height` samples.
    pub y: &'a [u8],
    /// Cb, [`Planar::chroma_size`] samples.
    pub u: &'a [u8],
    /// Cr, [`Planar::chroma_size`] samples.
    pub v: &'a [u8],
}

impl Planar<'_> {
    /// Width and height of each chroma plane.
    pub fn chroma_size(
        width: usize,
        height: usize,
        half_width: bool,
        half_height: bool,
    ) -> (usize, usize) {
        (
            if half_width { width.div_ceil(2) } else { width },
            if half_height {
                height.div_ceil(2)
            } else {
                height
            },
        )
    }

    /// Bytes of a plane of `samples` samples at `bits` bits.
    pub fn plane_bytes(samples: usize, bits: u32) -> usize {
        if bits > 8 {
            2 * samples
        } else {
            samples
        }
    }

    /// Converts the picture to a linear-light RGB [`Image`] as [`to_image`] does: n-bit code
    /// values brought to the 8-bit scale of [`ycbcr_to_rgb`] (limited range: divided by
    /// 2ⁿ⁻⁸, as BT.709/BT.2100 define the levels; full range: by (2ⁿ − 1)/255 about the
    /// mid-level), chroma upsampled bilinearly from H.264/HEVC's default sample position
    /// (co-sited with even luma columns; half-way between luma rows when halved vertically).
    pub fn to_image(&self, c: &ColorInfo) -> Image {
        let max = ((1u32 << self.bits) - 1) as f32;
        let half = (1u32 << (self.bits - 1)) as f32;
        let scale = (1u32 << (self.bits - 8)) as f32;
        // Code value → 8-bit scale, as (factor, offset).
        let (luma, chroma) = if c.full_range {
            (
                (255.0 / max, 0.0),
                (255.0 / max, 128.0 - half * 255.0 / max),
            )
        } else {
            ((1.0 / scale, 0.0), (1.0 / scale, 0.0))
        };
        let (cw, _) = Self::chroma_size(self.width, self.height, self.half_width, self.half_height);
        let layout = Layout {
            width: self.width,
            height: self.height,
            half_width: self.half_width,
            half_height: self.half_height,
            y_stride: self.width,
            uv_stride: cw,
        };
        if self.bits > 8 {
            let planes = [Le16(self.y), Le16(self.u), Le16(self.v)];
            convert(layout, planes, luma, chroma, c)
        } else {
            let planes = [Bytes(self.y), Bytes(self.u), Bytes(self.v)];
            convert(layout, planes, luma, chroma, c)
        }
    }
}

/// The geometry of a planar picture: its size, which chroma directions are halved, strides.
struct Layout {
    width: usize,
    height: usize,
    half_width: bool,
    half_height: bool,
    y_stride: usize,
    uv_stride: usize,
}

/// A plane's samples, read as code values.
trait Plane: Copy + Sync {
    /// Samples `start..start + out.len()`, each `code · factor + offset`.
    fn read(self, start: usize, out: &mut [f32], factor: f32, offset: f32);
}

/// One byte a sample.
#[derive(Clone, Copy)]
struct Bytes<'a>(&'a [u8]);

impl Plane for Bytes<'_> {
    fn read(self, start: usize, out: &mut [f32], factor: f32, offset: f32) {
        let bytes = &self.0[start..start + out.len()];
        for (v, &b) in out.iter_mut().zip(bytes) {
            *v = b as f32 * factor + offset;
        }
    }
}

/// Two bytes a sample, little-endian (FFmpeg's `…le` formats).
#[derive(Clone, Copy)]
struct Le16<'a>(&'a [u8]);

impl Plane for Le16<'_> {
    fn read(self, start: usize, out: &mut [f32], factor: f32, offset: f32) {
        let bytes = &self.0[2 * start..2 * (start + out.len())];
        for (v, b) in out.iter_mut().zip(bytes.chunks_exact(2)) {
            *v = u16::from_le_bytes([b[0], b[1]]) as f32 * factor + offset;
        }
    }
}

/// The sRGB decoding through a fine table: 4096 cells, each its value and slope, linearly
/// interpolated (within 3·10⁻⁸ of the curve); the input clamped to 0–1, as a display would.
struct Decode {
    value: Vec<f32>,
    slope: Vec<f32>,
}

impl Decode {
    const N: usize = 4096;

    /// The table, built once.
    fn get() -> &'static Decode {
        static TABLE: std::sync::OnceLock<Decode> = std::sync::OnceLock::new();
        TABLE.get_or_init(|| {
            let at = |i: usize| srgb_to_linear(i as f32 / Self::N as f32);
            Decode {
                value: (0..Self::N).map(at).collect(),
                slope: (0..Self::N).map(|i| at(i + 1) - at(i)).collect(),
            }
        })
    }

    #[inline(always)]
    fn decode(&self, v: f32) -> f32 {
        let t = v.clamp(0.0, 1.0) * Self::N as f32;
        let i = (t as usize).min(Self::N - 1);
        self.value[i] + self.slope[i] * (t - i as f32)
    }

    /// One row: `out` (interleaved RGB) from the luma `y` and the per-pixel chroma terms
    /// `terms` (R', G', B' each `y + term`), through [`Decode::decode`].
    fn row(&self, y: &[f32], terms: [&[f32]; 3], out: &mut [f32], avx2: bool) {
        let _ = avx2;
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: `avx2` is true only when the CPU reports AVX2.
            return unsafe { simd::row_avx2(self, y, terms, out) };
        }
        self.row_generic(y, terms, out, 0);
    }

    /// [`Decode::row`] from pixel `from` on, one pixel at a time.
    fn row_generic(&self, y: &[f32], [r, g, b]: [&[f32]; 3], out: &mut [f32], from: usize) {
        let pixels = out[3 * from..]
            .chunks_exact_mut(3)
            .zip(&y[from..])
            .zip(r[from..].iter().zip(&g[from..]).zip(&b[from..]));
        for ((px, &yy), ((&rt, &gt), &bt)) in pixels {
            px[0] = self.decode(yy + rt);
            px[1] = self.decode(yy + gt);
            px[2] = self.decode(yy + bt);
        }
    }
}

/// [`Decode::row`] with AVX2 (eight pixels a step, the table read by gathers), chosen at run
/// time. Lane for lane it performs exactly the operations of [`Decode::row_generic`], in the
/// same order and without FMA, so a frame's values do not depend on the CPU.
#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::*;

    use super::Decode;

    pub(super) fn has_avx2() -> bool {
        std::is_x86_feature_detected!("avx2")
    }

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn row_avx2(d: &Decode, y: &[f32], terms: [&[f32]; 3], out: &mut [f32]) {
        let n = y.len();
        assert!(terms.iter().all(|t| t.len() >= n) && out.len() >= 3 * n);
        assert!(d.value.len() == Decode::N && d.slope.len() == Decode::N);
        let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
        let cells = _mm256_set1_ps(Decode::N as f32);
        let last = _mm256_set1_epi32(Decode::N as i32 - 1);
        let (value, slope) = (d.value.as_ptr(), d.slope.as_ptr());
        let mut x = 0;
        let mut lanes = [[0.0f32; 8]; 3];
        while x + 8 <= n {
            let yy = _mm256_loadu_ps(y.as_ptr().add(x));
            for (k, t) in terms.iter().enumerate() {
                let v = _mm256_add_ps(yy, _mm256_loadu_ps(t.as_ptr().add(x)));
                let t = _mm256_mul_ps(_mm256_min_ps(_mm256_max_ps(v, zero), one), cells);
                let i = _mm256_min_epi32(_mm256_cvttps_epi32(t), last);
                let f = _mm256_sub_ps(t, _mm256_cvtepi32_ps(i));
                let a = _mm256_i32gather_ps::<4>(value, i);
                let s = _mm256_i32gather_ps::<4>(slope, i);
                _mm256_storeu_ps(lanes[k].as_mut_ptr(), _mm256_add_ps(a, _mm256_mul_ps(s, f)));
            }
            for (j, px) in out[3 * x..3 * x + 24].chunks_exact_mut(3).enumerate() {
                px[0] = lanes[0][j];
                px[1] = lanes[1][j];
                px[2] = lanes[2][j];
            }
            x += 8;
        }
        d.row_generic(y, terms, out, x);
    }
}

/// A zeroed buffer of `n` samples for a frame, which the kernel is asked to back with huge
/// pages where it can: a 4K frame is 100 MB, as 4 KB pages 24 000 faults a frame, each
/// clearing its page, as 2 MB pages fifty.
fn frame_buffer(n: usize) -> Vec<f32> {
    let v = vec![0.0f32; n];
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let start = v.as_ptr() as usize;
        let (a, b) = (start.next_multiple_of(HUGE), (start + 4 * n) / HUGE * HUGE);
        if b > a {
            // SAFETY: [a, b) lies inside `v`'s allocation, owned here; MADV_HUGEPAGE only
            // advises how its pages are backed and leaves their contents as they are.
            unsafe { libc::madvise(a as *mut libc::c_void, b - a, libc::MADV_HUGEPAGE) };
        }
    }
    v
}

/// The conversion both pictures share: Y', Cb, Cr `planes` brought to 8-bit code values by
/// the affine maps `luma` and `chroma` (factor, offset), chroma upsampled bilinearly from its
/// sample position (co-sited with even luma columns; half-way between luma rows when halved
/// vertically), [`ycbcr_to_rgb`], clamped to 0–1 and decoded with the sRGB curve.
///
/// [`ycbcr_to_rgb`]'s arithmetic is rearranged so a pixel costs an add per channel:
/// R' = Y + r(Cr), B' = Y + b(Cb), G' = Y − (K_R·r + K_B·b)/K_G, the chroma terms computed
/// once per chroma sample of a row and spread over its pixels, then decoded a row at a time
/// ([`Decode::row`]).
fn convert<P: Plane>(
    l: Layout,
    planes: [P; 3],
    luma: (f32, f32),
    chroma: (f32, f32),
    c: &ColorInfo,
) -> Image {
    let (w, h) = (l.width, l.height);
    let cw = if l.half_width { w.div_ceil(2) } else { w };
    let ch = if l.half_height { h.div_ceil(2) } else { h };
    let [py, pu, pv] = planes;
    let decode = Decode::get();
    #[cfg(target_arch = "x86_64")]
    let avx2 = simd::has_avx2();
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    let (kr, kb) = c.matrix.kr_kb();
    let kg = 1.0 - kr - kb;
    let (y0, ys, cs) = if c.full_range {
        (0.0, 1.0 / 255.0, 1.0 / 255.0)
    } else {
        (16.0, 1.0 / 219.0, 1.0 / 224.0)
    };
    // Y = code · ly + lo; chroma term p = (code · cf + co) · cs.
    let (ly, lo) = (luma.0 * ys, (luma.1 - y0) * ys);
    let (cf, co) = (chroma.0, chroma.1 - 128.0);
    let (rcr, bcb, inv_kg) = (2.0 * (1.0 - kr), 2.0 * (1.0 - kb), 1.0 / kg);
    let mut data = frame_buffer(w * h * 3);
    // A row's scratch: its luma, its two chroma rows' samples, each chroma sample's three
    // terms, each pixel's.
    let scratch = || {
        (
            vec![0.0f32; w],
            [(); 4].map(|_| vec![0.0f32; cw]),
            [(); 3].map(|_| vec![0.0f32; cw]),
            [(); 3].map(|_| vec![0.0f32; w]),
        )
    };
    data.par_chunks_mut(w * 3).enumerate().for_each_init(
        scratch,
        |(yrow, [u0, u1, v0, v1], sample, pixel), (y, row)| {
            let (cy0, cy1, fy) = if l.half_height {
                // Chroma row position of this luma row: (y − 0.5) / 2.
                let cy = (y as f32 - 0.5) * 0.5;
                let cy0 = (cy.floor().max(0.0) as usize).min(ch - 1);
                (
                    cy0,
                    (cy0 + 1).min(ch - 1),
                    (cy - cy0 as f32).clamp(0.0, 1.0),
                )
            } else {
                (y, y, 0.0)
            };
            // Each chroma sample's terms for R', G', B', interpolated vertically once.
            let (r0, r1) = (cy0 * l.uv_stride, cy1 * l.uv_stride);
            pu.read(r0, u0, 1.0, 0.0);
            pu.read(r1, u1, 1.0, 0.0);
            pv.read(r0, v0, 1.0, 0.0);
            pv.read(r1, v1, 1.0, 0.0);
            let [sr, sg, sb] = sample;
            let chroma_rows = u0.iter().zip(&*u1).zip(v0.iter().zip(&*v1));
            let terms = sr.iter_mut().zip(sg.iter_mut()).zip(sb.iter_mut());
            for (((&ua, &ub), (&va, &vb)), ((rt, gt), bt)) in chroma_rows.zip(terms) {
                let pb = ((ua + (ub - ua) * fy) * cf + co) * cs;
                let pr = ((va + (vb - va) * fy) * cf + co) * cs;
                *rt = rcr * pr;
                *bt = bcb * pb;
                *gt = -(kr * *rt + kb * *bt) * inv_kg;
            }
            for (s, p) in [&*sr, &*sg, &*sb].into_iter().zip(pixel.iter_mut()) {
                if !l.half_width {
                    p.copy_from_slice(s);
                } else {
                    // Co-sited horizontally: even columns on a chroma sample, odd ones
                    // half-way to the next (the last, on it).
                    for (pair, next) in p.chunks_exact_mut(2).zip(s.windows(2)) {
                        pair[0] = next[0];
                        pair[1] = 0.5 * (next[0] + next[1]);
                    }
                    let done = 2 * (cw - 1);
                    for q in &mut p[done..] {
                        *q = s[cw - 1];
                    }
                }
            }
            py.read(y * l.y_stride, yrow, ly, lo);
            let [pr, pg, pb] = &*pixel;
            decode.row(yrow, [pr, pg, pb], row, avx2);
        },
    );
    Image {
        width: w,
        height: h,
        channels: 3,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sps::Matrix;

    /// Samples as FFmpeg's `…le` formats deliver them.
    fn le(samples: &[u16]) -> Vec<u8> {
        samples.iter().flat_map(|s| s.to_le_bytes()).collect()
    }

    /// The conversion against [`ycbcr_to_rgb`] and the sRGB curve applied pixel by pixel,
    /// the chroma interpolated at each pixel's own position, on pictures of odd sizes in
    /// every subsampling, bit depth and range.
    #[test]
    fn every_pixel_is_the_matrix_and_curve_of_its_interpolated_chroma() {
        // Two eight-pixel steps of the vector path and five pixels after them.
        let (w, h) = (21, 5);
        let mut seed = 12345u32;
        let mut next = |bits: u32| {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            ((seed >> 8) % (1 << bits)) as u16
        };
        for bits in [8, 10, 12] {
            for (hw, hh) in [(true, true), (true, false), (false, false)] {
                for full_range in [false, true] {
                    let c = ColorInfo {
                        matrix: Matrix::Bt2020,
                        full_range,
                        matrix_from_stream: true,
                    };
                    let (cw, ch) = Planar::chroma_size(w, h, hw, hh);
                    let y: Vec<u16> = (0..w * h).map(|_| next(bits)).collect();
                    let u: Vec<u16> = (0..cw * ch).map(|_| next(bits)).collect();
                    let v: Vec<u16> = (0..cw * ch).map(|_| next(bits)).collect();
                    let bytes = |p: &[u16]| {
                        if bits > 8 {
                            le(p)
                        } else {
                            p.iter().map(|&s| s as u8).collect()
                        }
                    };
                    let img = Planar {
                        width: w,
                        height: h,
                        bits,
                        half_width: hw,
                        half_height: hh,
                        y: &bytes(&y),
                        u: &bytes(&u),
                        v: &bytes(&v),
                    }
                    .to_image(&c);
                    // Code values on the 8-bit scale.
                    let max = ((1u32 << bits) - 1) as f32;
                    let to8 = |s: u16, centre: bool| {
                        if full_range {
                            let v = s as f32 * 255.0 / max;
                            if centre {
                                128.0 + (s as f32 - (1 << (bits - 1)) as f32) * 255.0 / max
                            } else {
                                v
                            }
                        } else {
                            s as f32 / (1u32 << (bits - 8)) as f32
                        }
                    };
                    // A chroma plane at a luma pixel's position.
                    let sample = |p: &[u16], x: usize, y: usize| {
                        let (fx, fy) = (
                            if hw { x as f32 / 2.0 } else { x as f32 },
                            if hh {
                                ((y as f32 - 0.5) / 2.0).max(0.0)
                            } else {
                                y as f32
                            },
                        );
                        let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
                        let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
                        let (ax, ay) = (fx - x0 as f32, (fy - y0 as f32).min(1.0));
                        let at = |x: usize, y: usize| to8(p[y * cw + x], true);
                        let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * ax;
                        let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * ax;
                        top + (bottom - top) * ay
                    };
                    for py in 0..h {
                        for px in 0..w {
                            let rgb = ycbcr_to_rgb(
                                to8(y[py * w + px], false),
                                sample(&u, px, py),
                                sample(&v, px, py),
                                &c,
                            )
                            .map(|v| srgb_to_linear(v.clamp(0.0, 1.0)));
                            let got = &img.data[3 * (py * w + px)..][..3];
                            for k in 0..3 {
                                assert!(
                                    (got[k] - rgb[k]).abs() < 2e-5,
                                    "{bits} bits, halves {hw} {hh}, full {full_range}, \
                                     ({px}, {py}) channel {k}: {} against {}",
                                    got[k],
                                    rgb[k]
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn limited_range_black_white_and_primaries() {
        let c709 = ColorInfo {
            matrix: Matrix::Bt709,
            full_range: false,
            matrix_from_stream: true,
        };
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 2e-3);
        assert!(close(ycbcr_to_rgb(16.0, 128.0, 128.0, &c709), [0.0; 3]));
        assert!(close(ycbcr_to_rgb(235.0, 128.0, 128.0, &c709), [1.0; 3]));
        // BT.709 pure red: Y' = 0.2126, Pb = −0.2126/1.8556, Pr = 0.5.
        let y = 16.0 + 219.0 * 0.2126;
        let cb = 128.0 + 224.0 * (-0.2126 / 1.8556);
        let cr = 128.0 + 224.0 * 0.5;
        assert!(close(ycbcr_to_rgb(y, cb, cr, &c709), [1.0, 0.0, 0.0]));
        // The same code values read with BT.601 are visibly not pure red.
        let c601 = ColorInfo {
            matrix: Matrix::Bt601,
            ..c709
        };
        assert!(!close(ycbcr_to_rgb(y, cb, cr, &c601), [1.0, 0.0, 0.0]));
        let full = ColorInfo {
            full_range: true,
            ..c709
        };
        assert!(close(ycbcr_to_rgb(255.0, 128.0, 128.0, &full), [1.0; 3]));
    }

    /// The vector row and the portable one give the same bits, over the whole 0–1 range,
    /// past both ends of it, and on the cells' edges.
    #[test]
    fn the_vector_row_is_the_portable_row_bit_for_bit() {
        let d = Decode::get();
        let n = 1000;
        let y: Vec<f32> = (0..n).map(|i| -0.1 + 1.2 * i as f32 / n as f32).collect();
        let edges: Vec<f32> = (0..n).map(|i| (i % 40) as f32 / 4096.0 - 0.2).collect();
        let terms = [
            vec![0.0f32; n],
            edges,
            (0..n).map(|i| 1e-3 * ((i * 7919) % 13) as f32).collect(),
        ];
        let terms = [&terms[0][..], &terms[1][..], &terms[2][..]];
        let mut portable = vec![0.0f32; 3 * n];
        d.row(&y, terms, &mut portable, false);
        #[cfg(target_arch = "x86_64")]
        let avx2 = simd::has_avx2();
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        if !avx2 {
            eprintln!("no AVX2 on this CPU: the portable row only");
        }
        let mut vector = vec![0.0f32; 3 * n];
        d.row(&y, terms, &mut vector, avx2);
        assert!(portable
            .iter()
            .zip(&vector)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(portable.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    /// 10-bit 4:2:0 limited range is the 8-bit picture at 4× the code values; 4:2:2 and
    /// 4:4:4 of flat colour give that colour; full range 10-bit reaches white at 1023.
    #[test]
    fn ten_bit_and_every_subsampling_agree_with_eight_bit() {
        let c = ColorInfo {
            matrix: Matrix::Bt709,
            full_range: false,
            matrix_from_stream: true,
        };
        let (w, h) = (6, 4);
        let y8: Vec<u8> = (0..w * h).map(|i| (20 + 9 * i) as u8).collect();
        let (cw, ch) = (3, 2);
        let u8_: Vec<u8> = (0..cw * ch).map(|i| (100 + 11 * i) as u8).collect();
        let v8: Vec<u8> = (0..cw * ch).map(|i| (150 - 7 * i) as u8).collect();
        let eight = to_image(
            &Planes {
                width: w,
                height: h,
                y: &y8,
                u: &u8_,
                v: &v8,
                y_stride: w,
                uv_stride: cw,
            },
            &c,
        );
        let up = |p: &[u8]| le(&p.iter().map(|&v| 4 * v as u16).collect::<Vec<u16>>());
        let ten = Planar {
            width: w,
            height: h,
            bits: 10,
            half_width: true,
            half_height: true,
            y: &up(&y8),
            u: &up(&u8_),
            v: &up(&v8),
        }
        .to_image(&c);
        assert!(ten.max_abs_diff(&eight).unwrap() < 2e-4);
        // Flat 18 % grey-ish colour in 4:2:2 and 4:4:4: every pixel the same.
        for (hw, hh) in [(true, false), (false, false)] {
            let (cw, ch) = Planar::chroma_size(w, h, hw, hh);
            let p = Planar {
                width: w,
                height: h,
                bits: 10,
                half_width: hw,
                half_height: hh,
                y: &le(&vec![4 * 120; w * h]),
                u: &le(&vec![4 * 140; cw * ch]),
                v: &le(&vec![4 * 110; cw * ch]),
            }
            .to_image(&c);
            let want = ycbcr_to_rgb(120.0, 140.0, 110.0, &c).map(srgb_to_linear);
            for px in p.data.chunks(3) {
                assert!(px.iter().zip(&want).all(|(a, b)| (a - b).abs() < 1e-5));
            }
        }
        let full = ColorInfo {
            full_range: true,
            ..c
        };
        let white = Planar {
            width: 2,
            height: 2,
            bits: 10,
            half_width: true,
            half_height: true,
            y: &le(&[1023; 4]),
            u: &le(&[512]),
            v: &le(&[512]),
        }
        .to_image(&full);
        assert!(white.data.iter().all(|v| (v - 1.0).abs() < 1e-5));
    }
}
