//! PNG (ISO/IEC 15948) and JPEG (ISO/IEC 10918-1) through the `image` crate.
//!
//! Decoding: 8- and 16-bit gray, gray + alpha, RGB and RGBA. The colour samples are taken to be
//! sRGB-encoded (the web's and the book's assumption; embedded gAMA/iCCP chunks are ignored) and
//! are decoded to linear light with the IEC 61966-2-1 curve; alpha is linear coverage and is only
//! normalised to [0, 1]. Gray + alpha becomes RGBA (the gray replicated), so decoded images have
//! 1, 3 or 4 channels.
//!
//! Encoding: linear light → sRGB 8-bit (or 16-bit PNG with [`encode_png16`]), clamped to [0, 1]
//! with NaN → 0; alpha is quantised without the curve. JPEG cannot store alpha: it is dropped.

use std::io::Cursor;

use image::{DynamicImage, ExtendedColorType, ImageEncoder, ImageFormat, ImageReader, Limits};

use super::{check_encodable, guard, Format, Values};
use crate::color::{
    linear_to_srgb16, linear_to_srgb8, srgb16_to_linear, srgb8_to_linear, unit_to_u16, unit_to_u8,
};
use crate::error::ImageError;
use crate::image::{sample_count, Image, MAX_SAMPLES};

/// JPEG quality used by [`super::encode`].
pub const DEFAULT_JPEG_QUALITY: u8 = 95;

/// Decode PNG or JPEG bytes (`format` must be [`Format::Png`] or [`Format::Jpeg`]).
pub fn decode(bytes: &[u8], format: Format) -> Result<Image, ImageError> {
    decode_values(bytes, format, Values::Linear)
}

/// Decode PNG or JPEG bytes into `values`: linear light (the sRGB curve decoded, [`decode`]) or
/// the code values over [0, 1].
pub(crate) fn decode_values(
    bytes: &[u8],
    format: Format,
    values: Values,
) -> Result<Image, ImageError> {
    if !matches!(format, Format::Png | Format::Jpeg) {
        return Err(ImageError::UnsupportedFormat(format!(
            "{format} is not decoded by the PNG/JPEG codec"
        )));
    }
    let dynamic = guard(format, || {
        let reader = checked_reader(bytes, format)?;
        reader
            .decode()
            .map_err(|e| ImageError::decode(format, e.to_string()))
    })?;
    let (w, h) = (dynamic.width() as usize, dynamic.height() as usize);
    sample_count(w, h, 4)?;
    let codes = values == Values::Codes;
    let c8: fn(u8) -> f32 = if codes {
        |c| c as f32 / 255.0
    } else {
        srgb8_to_linear
    };
    let c16: fn(u16) -> f32 = if codes {
        |c| c as f32 / 65535.0
    } else {
        srgb16_to_linear
    };
    let img = match dynamic {
        DynamicImage::ImageLuma8(b) => convert(w, h, 1, b.as_raw(), c8, |_| 0.0),
        DynamicImage::ImageRgb8(b) => convert(w, h, 3, b.as_raw(), c8, |_| 0.0),
        DynamicImage::ImageRgba8(b) => convert(w, h, 4, b.as_raw(), c8, |a| a as f32 / 255.0),
        DynamicImage::ImageLumaA8(b) => gray_alpha(w, h, b.as_raw(), c8, |a| a as f32 / 255.0),
        DynamicImage::ImageLuma16(b) => convert(w, h, 1, b.as_raw(), c16, |_| 0.0),
        DynamicImage::ImageRgb16(b) => convert(w, h, 3, b.as_raw(), c16, |_| 0.0),
        DynamicImage::ImageRgba16(b) => convert(w, h, 4, b.as_raw(), c16, |a| a as f32 / 65535.0),
        DynamicImage::ImageLumaA16(b) => gray_alpha(w, h, b.as_raw(), c16, |a| a as f32 / 65535.0),
        other => {
            // Float or future layouts: values are display-referred in [0, 1], so sRGB-decode.
            let b = other.to_rgba32f();
            let f: fn(f32) -> f32 = if codes {
                |v| v
            } else {
                crate::color::srgb_to_linear
            };
            convert(w, h, 4, b.as_raw(), f, |a| a)
        }
    };
    Ok(img)
}

/// A reader of PNG or JPEG `bytes` (`format`) whose declared size has been checked
/// ([`check_declared`], from the header alone, before anything is allocated) and whose decoder
/// allocates at most what the image limits allow.
pub(crate) fn checked_reader(
    bytes: &[u8],
    format: Format,
) -> Result<ImageReader<Cursor<&[u8]>>, ImageError> {
    let image_format = match format {
        Format::Png => ImageFormat::Png,
        _ => ImageFormat::Jpeg,
    };
    let (w, h) = ImageReader::with_format(Cursor::new(bytes), image_format)
        .into_dimensions()
        .map_err(|e| ImageError::decode(format, e.to_string()))?;
    check_declared(format, w, h, bytes.len())?;
    let mut reader = ImageReader::with_format(Cursor::new(bytes), image_format);
    let mut limits = Limits::default();
    // 16-bit RGBA: 8 bytes a pixel in the decoder's buffer, 16 in ours.
    limits.max_alloc = Some((MAX_SAMPLES as u64) * 2);
    reader.limits(limits);
    Ok(reader)
}

/// Refuses a declared `width` × `height` that is over the image limits ([`MAX_SAMPLES`]), or
/// that a file of `len` bytes cannot code: a JPEG spends at least one bit on every 8 × 8 block
/// of every component (the Huffman code of its DC difference, ITU-T T.81 F.1.2.1 — also in a
/// progressive file's first scan), and even a component subsampled by the largest factor (4)
/// has ⌈w/32⌉·⌈h/32⌉ blocks; a PNG's image data is deflated, which shrinks at most
/// 1032 : 1 (RFC 1951's longest match, 258 bytes, in a 2-bit code at best, per byte of a row of
/// 1-bit pixels and its filter byte). A few hundred bytes declaring a giant image — a truncated
/// or hostile file — would otherwise be decoded in full, gigabytes of filler.
fn check_declared(format: Format, width: u32, height: u32, len: usize) -> Result<(), ImageError> {
    let (w, h) = (width as u64, height as u64);
    sample_count(width as usize, height as usize, 1).map_err(|_| {
        ImageError::decode(
            format,
            format!(
                "the file declares {width}×{height} pixels, over the limit of {MAX_SAMPLES} \
                 samples"
            ),
        )
    })?;
    let needed = match format {
        Format::Jpeg => (w.div_ceil(32) * h.div_ceil(32)).div_ceil(8),
        _ => (h * (1 + w.div_ceil(8))).div_ceil(1032),
    };
    if (len as u64) < needed {
        return Err(ImageError::decode(
            format,
            format!(
                "the file declares {width}×{height} pixels but holds {len} bytes, and coding \
                 that many pixels takes at least {needed}: it is truncated or corrupt"
            ),
        ));
    }
    Ok(())
}

/// Convert interleaved codes with `channels` channels: the last channel of a 4-channel layout
/// is alpha (`alpha`), the others colour (`color`).
fn convert<T: Copy + Sync>(
    w: usize,
    h: usize,
    channels: usize,
    raw: &[T],
    color: impl Fn(T) -> f32,
    alpha: impl Fn(T) -> f32,
) -> Image {
    let data = raw
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            if channels == 4 && i % 4 == 3 {
                alpha(v)
            } else {
                color(v)
            }
        })
        .collect();
    Image {
        width: w,
        height: h,
        channels,
        data,
    }
}

/// Gray + alpha codes → RGBA.
fn gray_alpha<T: Copy>(
    w: usize,
    h: usize,
    raw: &[T],
    color: impl Fn(T) -> f32,
    alpha: impl Fn(T) -> f32,
) -> Image {
    let mut data = Vec::with_capacity(w * h * 4);
    for p in raw.chunks_exact(2) {
        let g = color(p[0]);
        data.extend_from_slice(&[g, g, g, alpha(p[1])]);
    }
    Image {
        width: w,
        height: h,
        channels: 4,
        data,
    }
}

fn dims_u32(img: &Image, format: Format) -> Result<(u32, u32), ImageError> {
    match (u32::try_from(img.width), u32::try_from(img.height)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(ImageError::encode(format, "dimensions exceed 2^32 - 1")),
    }
}

/// Quantise to 8-bit codes: colour through the sRGB curve (or, for [`Values::Codes`], as
/// code values over [0, 1]), alpha linearly.
fn codes8(img: &Image, keep_alpha: bool, values: Values) -> (Vec<u8>, usize) {
    let cc = img.color_channels();
    let out_ch = if keep_alpha && img.has_alpha() {
        cc + 1
    } else {
        cc
    };
    let mut out = Vec::with_capacity(img.pixel_count() * out_ch);
    for p in img.data.chunks_exact(img.channels) {
        match values {
            Values::Linear => out.extend(p[..cc].iter().map(|&v| linear_to_srgb8(v))),
            Values::Codes => out.extend(p[..cc].iter().map(|&v| unit_to_u8(v))),
        }
        if out_ch > cc {
            out.push(unit_to_u8(p[cc]));
        }
    }
    (out, out_ch)
}

fn color_type8(channels: usize) -> ExtendedColorType {
    match channels {
        1 => ExtendedColorType::L8,
        2 => ExtendedColorType::La8,
        3 => ExtendedColorType::Rgb8,
        _ => ExtendedColorType::Rgba8,
    }
}

/// Encode as an 8-bit sRGB PNG (gray, gray + alpha, RGB or RGBA as the image is).
pub fn encode_png8(img: &Image) -> Result<Vec<u8>, ImageError> {
    encode_png8_values(img, Values::Linear)
}

/// [`encode_png8`] of linear light or of code values over [0, 1] (`values`).
pub(crate) fn encode_png8_values(img: &Image, values: Values) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, Format::Png)?;
    let (w, h) = dims_u32(img, Format::Png)?;
    let (codes, ch) = codes8(img, true, values);
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&codes, w, h, color_type8(ch))
        .map_err(|e| ImageError::encode(Format::Png, e.to_string()))?;
    Ok(out)
}

/// Encode as a 16-bit sRGB PNG (gray, gray + alpha, RGB or RGBA as the image is): the sRGB curve
/// with 65536 levels, for linear data that would band at 8 bits.
pub fn encode_png16(img: &Image) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, Format::Png)?;
    let (w, h) = dims_u32(img, Format::Png)?;
    let cc = img.color_channels();
    let mut bytes = Vec::with_capacity(img.data.len() * 2);
    for p in img.data.chunks_exact(img.channels) {
        for &v in &p[..cc] {
            bytes.extend_from_slice(&linear_to_srgb16(v).to_ne_bytes());
        }
        if img.has_alpha() {
            bytes.extend_from_slice(&unit_to_u16(p[cc]).to_ne_bytes());
        }
    }
    let color = match img.channels {
        1 => ExtendedColorType::L16,
        2 => ExtendedColorType::La16,
        3 => ExtendedColorType::Rgb16,
        _ => ExtendedColorType::Rgba16,
    };
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&bytes, w, h, color)
        .map_err(|e| ImageError::encode(Format::Png, e.to_string()))?;
    Ok(out)
}

/// Encode as a baseline 8-bit sRGB JPEG of the given quality (1–100), gray or RGB; alpha is
/// dropped (JPEG has no alpha channel).
pub fn encode_jpeg(img: &Image, quality: u8) -> Result<Vec<u8>, ImageError> {
    encode_jpeg_values(img, quality, Values::Linear)
}

/// [`encode_jpeg`] of linear light or of code values over [0, 1] (`values`).
pub(crate) fn encode_jpeg_values(
    img: &Image,
    quality: u8,
    values: Values,
) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, Format::Jpeg)?;
    let (w, h) = dims_u32(img, Format::Jpeg)?;
    if w > 65535 || h > 65535 {
        return Err(ImageError::encode(
            Format::Jpeg,
            format!("{w}x{h} exceeds JPEG's 65535x65535 limit"),
        ));
    }
    let (codes, ch) = codes8(img, false, values);
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100))
        .write_image(&codes, w, h, color_type8(ch))
        .map_err(|e| ImageError::encode(Format::Jpeg, e.to_string()))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::{linear_to_srgb, srgb_to_linear};
    use crate::io::{decode as decode_any, encode as encode_any};

    /// A horizontal and vertical gradient, distinct in every channel, in linear light.
    fn gradient(w: usize, h: usize, ch: usize) -> Image {
        Image::from_fn(w, h, ch, |x, y, c| {
            let v = (x as f32 / (w - 1) as f32) * 0.6 + (y as f32 / (h - 1) as f32) * 0.3;
            (v + 0.03 * c as f32).min(1.0)
        })
    }

    /// The largest error of 8-bit sRGB quantisation at linear value v (half a code, through the
    /// derivative of the decoding curve), plus slack.
    fn srgb8_tolerance(v: f32) -> f32 {
        let s = linear_to_srgb(v);
        (srgb_to_linear((s + 0.6 / 255.0).min(1.0)) - v).abs() + 1e-6
    }

    #[test]
    fn png8_round_trip_all_layouts() {
        for ch in 1..=4 {
            let img = gradient(17, 9, ch);
            let back = decode_any(&encode_any(&img, Format::Png).unwrap(), Format::Png).unwrap();
            let expect = if ch == 2 { img.to_rgba() } else { img.clone() };
            assert_eq!(
                (back.width, back.height, back.channels),
                (17, 9, expect.channels)
            );
            for (i, (&a, &b)) in expect.data.iter().zip(&back.data).enumerate() {
                let is_alpha = expect.has_alpha() && i % expect.channels == expect.channels - 1;
                let tol = if is_alpha {
                    0.5 / 255.0 + 1e-6
                } else {
                    srgb8_tolerance(a)
                };
                assert!((a - b).abs() <= tol, "ch {ch} sample {i}: {a} vs {b}");
            }
            // Orientation: (0, 0) is the top-left, the darkest corner of the gradient.
            assert!(back.get(0, 0, 0) < back.get(16, 0, 0));
            assert!(back.get(0, 0, 0) < back.get(0, 8, 0));
        }
    }

    #[test]
    fn png16_round_trip_is_fine() {
        for ch in [1, 2, 3, 4] {
            let img = gradient(31, 7, ch);
            let back = decode(&encode_png16(&img).unwrap(), Format::Png).unwrap();
            let expect = if ch == 2 { img.to_rgba() } else { img.clone() };
            let err = expect.max_abs_diff(&back).unwrap();
            assert!(err < 3e-5, "ch {ch}: max error {err}");
            assert_eq!(back.get(0, 0, 0), expect.get(0, 0, 0).min(1.0));
        }
    }

    #[test]
    fn png_known_values_and_clamping() {
        // 8-bit sRGB 128 must decode to srgb_to_linear(128/255) exactly.
        let img = Image::from_vec(
            4,
            1,
            1,
            vec![srgb_to_linear(128.0 / 255.0), -3.0, 9.0, f32::NAN],
        )
        .unwrap();
        let back = decode(&encode_png8(&img).unwrap(), Format::Png).unwrap();
        assert_eq!(back.data[0], srgb_to_linear(128.0 / 255.0));
        assert_eq!(back.data[1], 0.0, "negative clamps to 0");
        assert_eq!(back.data[2], 1.0, "above 1 clamps to 1");
        assert_eq!(back.data[3], 0.0, "NaN becomes 0");
        // Alpha is linear: 0.5 → code 128 → 128/255, not curve-decoded.
        let rgba = Image::from_vec(1, 1, 4, vec![0.2, 0.2, 0.2, 0.5]).unwrap();
        let back = decode(&encode_png8(&rgba).unwrap(), Format::Png).unwrap();
        assert_eq!(back.data[3], 128.0 / 255.0);
    }

    #[test]
    fn jpeg_round_trip_within_quantisation() {
        let img = gradient(64, 48, 3);
        let bytes = encode_any(&img, Format::Jpeg).unwrap();
        assert_eq!(Format::sniff(&bytes), Some(Format::Jpeg));
        let back = decode(&bytes, Format::Jpeg).unwrap();
        assert_eq!((back.width, back.height, back.channels), (64, 48, 3));
        // Compare in the encoded (sRGB) domain, where JPEG's error is roughly uniform. Chroma is
        // subsampled 2x2, so single samples at colour edges may be off by several codes; the mean
        // error of a smooth gradient at quality 95 stays below a code.
        let mut sum = 0.0;
        let mut max = 0.0f32;
        for (&a, &b) in img.data.iter().zip(&back.data) {
            let e = (linear_to_srgb(a) - linear_to_srgb(b)).abs() * 255.0;
            sum += e;
            max = max.max(e);
        }
        let mean = sum / img.data.len() as f32;
        assert!(mean < 1.0, "mean error {mean} codes");
        assert!(max < 12.0, "max error {max} codes");
        assert!(
            back.get(0, 0, 0) < back.get(63, 47, 0),
            "top-left is darkest"
        );
        // Alpha is dropped; gray stays gray.
        let rgba = gradient(16, 16, 4);
        assert_eq!(
            decode(&encode_any(&rgba, Format::Jpeg).unwrap(), Format::Jpeg)
                .unwrap()
                .channels,
            3
        );
        let gray = gradient(16, 16, 1);
        assert_eq!(
            decode(&encode_any(&gray, Format::Jpeg).unwrap(), Format::Jpeg)
                .unwrap()
                .channels,
            1
        );
    }

    #[test]
    fn truncated_png_and_jpeg_are_errors() {
        let img = gradient(40, 30, 4);
        // PNG: every cut that loses pixel data is an error. (A PNG missing only its 12-byte IEND
        // chunk still holds every pixel and decodes.)
        let png = encode_any(&img, Format::Png).unwrap();
        for len in (0..png.len() - 12).step_by(5) {
            assert!(
                decode(&png[..len], Format::Png).is_err(),
                "PNG cut at {len}"
            );
        }
        // JPEG: like libjpeg, the decoder pads a stream cut inside the entropy-coded scan (with a
        // warning, gray pixels), so only cuts before the scan must fail; later cuts must simply
        // not panic.
        let jpeg = encode_any(&img, Format::Jpeg).unwrap();
        let sos = jpeg.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
        for len in 0..jpeg.len() {
            let r = decode(&jpeg[..len], Format::Jpeg);
            if len <= sos + 2 {
                assert!(r.is_err(), "JPEG cut at {len} (scan at {sos})");
            }
        }
        // Garbage after a valid magic number.
        for (format, bytes) in [(Format::Png, &png), (Format::Jpeg, &jpeg)] {
            let mut junk = bytes[..8].to_vec();
            junk.extend(std::iter::repeat_n(0xAB, 200));
            assert!(decode(&junk, format).is_err());
        }
    }

    #[test]
    fn huge_png_header_is_rejected_without_allocating() {
        // A PNG header claiming 100000 x 100000 RGBA16 (80 GB) with no data.
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend(100_000u32.to_be_bytes());
        ihdr.extend(100_000u32.to_be_bytes());
        ihdr.extend([16, 6, 0, 0, 0]);
        png.extend(13u32.to_be_bytes());
        png.extend(&ihdr);
        png.extend(crc32(&ihdr).to_be_bytes());
        assert!(decode(&png, Format::Png).is_err());
    }

    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = 0xFFFF_FFFFu32;
        for &b in bytes {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// `bytes` with the frame size of its JPEG SOF segment (or PNG IHDR chunk) replaced.
    fn declare(mut bytes: Vec<u8>, format: Format, w: u32, h: u32) -> Vec<u8> {
        match format {
            Format::Jpeg => {
                let sof = bytes
                    .windows(2)
                    .position(|m| m[0] == 0xFF && (0xC0..=0xC2).contains(&m[1]))
                    .expect("a SOF marker");
                // FFCx, length (2), precision (1), height (2), width (2).
                bytes[sof + 5..sof + 7].copy_from_slice(&(h as u16).to_be_bytes());
                bytes[sof + 7..sof + 9].copy_from_slice(&(w as u16).to_be_bytes());
            }
            _ => {
                // Signature (8), IHDR length (4), "IHDR" (4), width (4), height (4), …, CRC.
                bytes[16..20].copy_from_slice(&w.to_be_bytes());
                bytes[20..24].copy_from_slice(&h.to_be_bytes());
                let crc = crc32(&bytes[12..29]);
                bytes[29..33].copy_from_slice(&crc.to_be_bytes());
            }
        }
        bytes
    }

    /// A few hundred bytes declaring a giant image are refused from the header, before the
    /// decoder allocates (the sizes of two fuzzer finds: 36205×7005 used to decode for 16 s
    /// into 8.7 GB, 65535×32767 for 9 s and 2 GB before the size check); the same file with
    /// its true size still reads.
    #[test]
    fn a_short_file_declaring_a_giant_image_is_refused_before_decoding() {
        for format in [Format::Jpeg, Format::Png] {
            let small = encode_any(&gradient(16, 16, 3), format).unwrap();
            assert!(small.len() < 2000, "{format}: {} bytes", small.len());
            assert!(decode_any(&declare(small.clone(), format, 16, 16), format).is_ok());
            for (w, h) in [(36205, 7005), (65535, 32767), (20000, 20000)] {
                let t0 = std::time::Instant::now();
                let err = decode_any(&declare(small.clone(), format, w, h), format)
                    .unwrap_err()
                    .to_string();
                eprintln!("{format} {w}×{h}: {err} ({:?})", t0.elapsed());
                assert!(err.contains(&format!("{w}×{h}")), "{err}");
                assert!(
                    err.contains("truncated or corrupt") || err.contains("over the limit"),
                    "{err}"
                );
            }
        }
    }

    /// The bounds are conservative: real files of a few pixels to a few thousand, flat (the
    /// most compressible), are never refused by them.
    #[test]
    fn the_declared_size_check_accepts_real_flat_files() {
        for format in [Format::Jpeg, Format::Png] {
            for (w, h) in [(1, 1), (7, 3), (640, 1), (1, 480), (2048, 1536)] {
                let flat = Image::from_fn(w, h, 3, |_, _, _| 0.5);
                let bytes = encode_any(&flat, format).unwrap();
                let back = decode_any(&bytes, format).unwrap();
                assert_eq!((back.width, back.height), (w, h), "{format}");
            }
        }
    }
}
