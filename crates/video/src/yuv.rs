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
        [p.y, p.u, p.v],
        |v| v,
        |v| v,
        c,
    )
}

/// One decoded picture of any planar Y'CbCr layout FFmpeg delivers: 8 to 16 bits a sample
/// (held in `u16`), chroma full size or halved across (4:2:2) or across and down (4:2:0).
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
    /// Luma, `width` × `height`.
    pub y: &'a [u16],
    /// Cb, [`Planar::chroma_size`].
    pub u: &'a [u16],
    /// Cr, [`Planar::chroma_size`].
    pub v: &'a [u16],
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

    /// Converts the picture to a linear-light RGB [`Image`] as [`to_image`] does: n-bit code
    /// values brought to the 8-bit scale of [`ycbcr_to_rgb`] (limited range: divided by
    /// 2ⁿ⁻⁸, as BT.709/BT.2100 define the levels; full range: by (2ⁿ − 1)/255 about the
    /// mid-level), chroma upsampled bilinearly from H.264/HEVC's default sample position
    /// (co-sited with even luma columns; half-way between luma rows when halved vertically).
    pub fn to_image(&self, c: &ColorInfo) -> Image {
        let max = ((1u32 << self.bits) - 1) as f32;
        let half = (1u32 << (self.bits - 1)) as f32;
        let scale = (1u32 << (self.bits - 8)) as f32;
        let full = c.full_range;
        let (cw, _) = Self::chroma_size(self.width, self.height, self.half_width, self.half_height);
        convert(
            Layout {
                width: self.width,
                height: self.height,
                half_width: self.half_width,
                half_height: self.half_height,
                y_stride: self.width,
                uv_stride: cw,
            },
            [self.y, self.u, self.v],
            |v| if full { v * 255.0 / max } else { v / scale },
            |v| {
                if full {
                    128.0 + (v - half) * 255.0 / max
                } else {
                    v / scale
                }
            },
            c,
        )
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

/// The conversion both pictures share: Y', Cb, Cr `planes` of samples brought to 8-bit code
/// values by `luma` and `chroma`, chroma upsampled bilinearly from its sample position
/// (co-sited with even luma columns; half-way between luma rows when halved vertically),
/// [`ycbcr_to_rgb`], clamped to 0–1 and decoded with the sRGB curve through a fine table.
fn convert<S: Copy + Into<f32> + Sync>(
    l: Layout,
    planes: [&[S]; 3],
    luma: impl Fn(f32) -> f32 + Sync,
    chroma: impl Fn(f32) -> f32 + Sync,
    c: &ColorInfo,
) -> Image {
    let (w, h) = (l.width, l.height);
    let cw = if l.half_width { w.div_ceil(2) } else { w };
    let ch = if l.half_height { h.div_ceil(2) } else { h };
    let [py, pu, pv] = planes;
    const N: usize = 4096;
    let lut: Vec<f32> = (0..=N)
        .map(|i| srgb_to_linear(i as f32 / N as f32))
        .collect();
    let decode = |v: f32| {
        let t = v.clamp(0.0, 1.0) * N as f32;
        let i = (t as usize).min(N - 1);
        let f = t - i as f32;
        lut[i] + (lut[i + 1] - lut[i]) * f
    };
    // ycbcr_to_rgb's arithmetic with the matrix and range taken out of the pixel loop.
    let (kr, kb) = c.matrix.kr_kb();
    let kg = 1.0 - kr - kb;
    let (y0, ys, cs) = if c.full_range {
        (0.0, 1.0 / 255.0, 1.0 / 255.0)
    } else {
        (16.0, 1.0 / 219.0, 1.0 / 224.0)
    };
    let (rcr, bcb, inv_kg) = (2.0 * (1.0 - kr), 2.0 * (1.0 - kb), 1.0 / kg);
    let mut data = vec![0.0f32; w * h * 3];
    data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
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
        // This row's chroma, interpolated vertically once per chroma sample and centred
        // (Pb, Pr before the range's scale).
        let at = |plane: &[S], cx: usize| {
            let a: f32 = plane[cy0 * l.uv_stride + cx].into();
            let b: f32 = plane[cy1 * l.uv_stride + cx].into();
            chroma(a + (b - a) * fy) - 128.0
        };
        let pb: Vec<f32> = (0..cw).map(|cx| at(pu, cx)).collect();
        let pr: Vec<f32> = (0..cw).map(|cx| at(pv, cx)).collect();
        let luma_row = &py[y * l.y_stride..y * l.y_stride + w];
        for (x, (out, &yv)) in row.chunks_exact_mut(3).zip(luma_row).enumerate() {
            let (cb, cr) = if !l.half_width {
                (pb[x], pr[x])
            } else {
                // Co-sited horizontally: even columns on a chroma sample, odd ones half-way.
                let cx0 = (x / 2).min(cw - 1);
                if x % 2 == 0 || cx0 + 1 >= cw {
                    (pb[cx0], pr[cx0])
                } else {
                    (0.5 * (pb[cx0] + pb[cx0 + 1]), 0.5 * (pr[cx0] + pr[cx0 + 1]))
                }
            };
            let yy = (luma(yv.into()) - y0) * ys;
            let r = yy + rcr * (cr * cs);
            let b = yy + bcb * (cb * cs);
            let g = (yy - kr * r - kb * b) * inv_kg;
            out[0] = decode(r);
            out[1] = decode(g);
            out[2] = decode(b);
        }
    });
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
        let up = |p: &[u8]| p.iter().map(|&v| 4 * v as u16).collect::<Vec<u16>>();
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
                y: &vec![4 * 120; w * h],
                u: &vec![4 * 140; cw * ch],
                v: &vec![4 * 110; cw * ch],
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
            y: &[1023; 4],
            u: &[512],
            v: &[512],
        }
        .to_image(&full);
        assert!(white.data.iter().all(|v| (v - 1.0).abs() < 1e-5));
    }
}
