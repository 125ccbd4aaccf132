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
    let (w, h) = (p.width, p.height);
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    // sRGB decoding of the 8-bit-and-between values through a fine table.
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
    let mut data = vec![0.0f32; w * h * 3];
    data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
        // Chroma row position of this luma row: (y − 0.5) / 2.
        let cy = (y as f32 - 0.5) * 0.5;
        let cy0 = cy.floor().max(0.0) as usize;
        let cy0 = cy0.min(ch - 1);
        let cy1 = (cy0 + 1).min(ch - 1);
        let fy = (cy - cy0 as f32).clamp(0.0, 1.0);
        let chroma = |plane: &[u8], cx: usize| {
            let a = plane[cy0 * p.uv_stride + cx] as f32;
            let b = plane[cy1 * p.uv_stride + cx] as f32;
            a + (b - a) * fy
        };
        for x in 0..w {
            let yv = p.y[y * p.y_stride + x] as f32;
            // Co-sited horizontally: even columns on a chroma sample, odd ones half-way.
            let cx0 = (x / 2).min(cw - 1);
            let (cb, cr) = if x % 2 == 0 || cx0 + 1 >= cw {
                (chroma(p.u, cx0), chroma(p.v, cx0))
            } else {
                (
                    0.5 * (chroma(p.u, cx0) + chroma(p.u, cx0 + 1)),
                    0.5 * (chroma(p.v, cx0) + chroma(p.v, cx0 + 1)),
                )
            };
            let rgb = ycbcr_to_rgb(yv, cb, cr, c);
            for k in 0..3 {
                row[3 * x + k] = decode(rgb[k]);
            }
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
}
