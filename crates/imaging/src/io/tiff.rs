//! TIFF (Adobe TIFF 6.0, with the floating-point sample format of Adobe's Photoshop TIFF
//! Technical Notes), through the `tiff` crate (image-rs): the first image of the file,
//! strips or tiles, uncompressed, LZW, Deflate or PackBits, either byte order.
//!
//! Values: 8- and 16-bit integer samples are display-referred (decoded with the sRGB curve,
//! as PNG), 16- and 32-bit float samples linear light as stored; gray, gray + alpha (read as
//! RGBA), RGB and RGBA. Palette, CMYK, YCbCr and Lab files are refused by name. The header's
//! size is checked against [`crate::image::MAX_SAMPLES`] before the pixels are decoded, and
//! the decoder's own buffers are bounded by the same limit.
//!
//! The writer ([`encode`]) writes one RGB(A) or gray image, 8- or 16-bit sRGB or 32-bit
//! float linear, uncompressed, LZW or Deflate (with the horizontal predictor for integers);
//! the default is 16-bit Deflate.

use std::io::Cursor;

use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::encoder::{colortype, Compression, DeflateLevel, Predictor, TiffEncoder};
use tiff::ColorType;

use super::{check_encodable, guard, Format, Values};
use crate::color::{linear_to_srgb, srgb_to_linear};
use crate::error::ImageError;
use crate::image::{sample_count, Image, MAX_SAMPLES};

fn err(reason: impl Into<String>) -> ImageError {
    ImageError::decode(Format::Tiff, reason)
}

fn tiff_err(e: tiff::TiffError) -> ImageError {
    err(e.to_string())
}

/// Decodes the first image of a TIFF file into linear light (module docs).
pub fn decode(bytes: &[u8]) -> Result<Image, ImageError> {
    decode_values(bytes, Values::Linear)
}

/// Decodes the first image of a TIFF file into `values`: linear light ([`decode`]) or the code
/// values (integer samples over [0, 1], floats as stored).
pub(crate) fn decode_values(bytes: &[u8], values: Values) -> Result<Image, ImageError> {
    guard(Format::Tiff, || decode_inner(bytes, values))
}

fn decode_inner(bytes: &[u8], values: Values) -> Result<Image, ImageError> {
    let mut limits = Limits::default();
    limits.decoding_buffer_size = MAX_SAMPLES * 4;
    limits.intermediate_buffer_size = MAX_SAMPLES * 4;
    let mut d = Decoder::new(Cursor::new(bytes))
        .map_err(tiff_err)?
        .with_limits(limits);
    let (w, h) = d.dimensions().map_err(tiff_err)?;
    let (w, h) = (w as usize, h as usize);
    let (stored, out_channels) = match d.colortype().map_err(tiff_err)? {
        ColorType::Gray(_) => (1, 1),
        ColorType::GrayA(_) => (2, 4),
        ColorType::RGB(_) => (3, 3),
        ColorType::RGBA(_) => (4, 4),
        other => {
            return Err(err(format!(
                "{other:?} images are not supported (gray, gray + alpha, RGB, RGBA)"
            )))
        }
    };
    sample_count(w, h, out_channels).map_err(|e| err(e.to_string()))?;
    // Bytes enough to code that many samples at the compression's best ratio, before the
    // decoder sizes its buffer (a 2 KB file declared 4 GB of pixels).
    let bits: u128 = d
        .find_tag(tiff::tags::Tag::BitsPerSample)
        .ok()
        .flatten()
        .and_then(|v| v.into_u16_vec().ok())
        .map_or(8, |v| v.iter().map(|&b| b as u128).max().unwrap_or(8));
    let compression = d
        .find_tag(tiff::tags::Tag::Compression)
        .ok()
        .flatten()
        .and_then(|v| v.into_u16().ok())
        .unwrap_or(1);
    let raw = (w as u128 * h as u128 * stored as u128 * bits).div_ceil(8);
    let ratio = max_expansion(compression);
    if raw > ratio * bytes.len() as u128 + (1 << 16) {
        return Err(err(format!(
            "{w}×{h} pixels of {stored} {bits}-bit samples are {raw} bytes: more than a \
             {}-byte file holds (compression {compression}, {ratio}:1 at most)",
            bytes.len()
        )));
    }
    // Integer samples are display-referred codes, floats linear light.
    let (samples, float): (Vec<f32>, bool) = match d.read_image().map_err(tiff_err)? {
        DecodingResult::U8(v) => (v.iter().map(|&c| c as f32 / 255.0).collect(), false),
        DecodingResult::U16(v) => (v.iter().map(|&c| c as f32 / 65535.0).collect(), false),
        DecodingResult::F16(v) => (v.iter().map(|&c| c.to_f32()).collect(), true),
        DecodingResult::F32(v) => (v, true),
        DecodingResult::F64(v) => (v.iter().map(|&c| c as f32).collect(), true),
        _ => return Err(err("only 8/16-bit integer and 16/32/64-bit float samples")),
    };
    if samples.len() < w * h * stored {
        return Err(err(format!(
            "{w}×{h}×{stored} samples expected, {} decoded",
            samples.len()
        )));
    }
    let mut img = Image::try_new(w, h, out_channels)?;
    for (px, src) in img
        .data
        .chunks_exact_mut(out_channels)
        .zip(samples.chunks_exact(stored))
    {
        let decode = |v: f32| {
            if float || values == Values::Codes {
                v
            } else {
                srgb_to_linear(v)
            }
        };
        match stored {
            2 => {
                let g = decode(src[0]);
                px.copy_from_slice(&[g, g, g, src[1]]);
            }
            4 => {
                for k in 0..3 {
                    px[k] = decode(src[k]);
                }
                px[3] = src[3];
            }
            _ => {
                for (o, &v) in px.iter_mut().zip(src) {
                    *o = decode(v);
                }
            }
        }
    }
    Ok(img)
}

/// The most a TIFF compression method can expand: none 1:1, PackBits 128:1, LZW (12-bit codes
/// for strings growing by one byte, the table reset at 4096) under 1400:1, Deflate 1032:1.
fn max_expansion(compression: u16) -> u128 {
    match compression {
        1 => 1,
        32773 => 128,
        5 => 1400,
        _ => 1032,
    }
}

/// The samples [`encode`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TiffDepth {
    /// 8-bit sRGB.
    U8,
    /// 16-bit sRGB.
    U16,
    /// 32-bit float, linear.
    F32,
}

/// The compression [`encode`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TiffCompression {
    /// None.
    None,
    /// LZW.
    Lzw,
    /// Deflate (zlib).
    Deflate,
}

/// How [`encode`] writes a TIFF file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TiffOptions {
    /// Sample type.
    pub depth: TiffDepth,
    /// Compression.
    pub compression: TiffCompression,
}

impl Default for TiffOptions {
    /// 16-bit sRGB, Deflate.
    fn default() -> Self {
        TiffOptions {
            depth: TiffDepth::U16,
            compression: TiffCompression::Deflate,
        }
    }
}

/// Encodes a linear-light image of 1, 3 or 4 channels as a TIFF file (module docs).
pub fn encode(img: &Image, o: &TiffOptions) -> Result<Vec<u8>, ImageError> {
    encode_values(img, o, Values::Linear)
}

/// [`encode`] of linear light or of code values over [0, 1] (`values`: integer samples are
/// then the values quantised, with no curve).
pub(crate) fn encode_values(
    img: &Image,
    o: &TiffOptions,
    values: Values,
) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, Format::Tiff)?;
    if !matches!(img.channels, 1 | 3 | 4) {
        return Err(ImageError::encode(
            Format::Tiff,
            format!("{} channels (1, 3 or 4)", img.channels),
        ));
    }
    let c = img.channels;
    let encoded = |i: usize, v: f32| -> f32 {
        if (c == 4 && i % 4 == 3) || values == Values::Codes {
            if v.is_nan() {
                0.0
            } else {
                v.clamp(0.0, 1.0)
            }
        } else {
            linear_to_srgb(v.max(0.0)).min(1.0)
        }
    };
    let enc = |e: tiff::TiffError| ImageError::encode(Format::Tiff, e.to_string());
    let mut out = Cursor::new(Vec::new());
    {
        let mut t = TiffEncoder::new(&mut out).map_err(enc)?;
        t = t.with_compression(match o.compression {
            TiffCompression::None => Compression::Uncompressed,
            TiffCompression::Lzw => Compression::Lzw,
            TiffCompression::Deflate => Compression::Deflate(DeflateLevel::Balanced),
        });
        if o.depth != TiffDepth::F32 && o.compression != TiffCompression::None {
            t = t.with_predictor(Predictor::Horizontal);
        }
        let (w, h) = (img.width as u32, img.height as u32);
        match o.depth {
            TiffDepth::U8 => {
                let v: Vec<u8> = img
                    .data
                    .iter()
                    .enumerate()
                    .map(|(i, &x)| (encoded(i, x) * 255.0).round() as u8)
                    .collect();
                match c {
                    1 => t.write_image::<colortype::Gray8>(w, h, &v),
                    3 => t.write_image::<colortype::RGB8>(w, h, &v),
                    _ => t.write_image::<colortype::RGBA8>(w, h, &v),
                }
            }
            TiffDepth::U16 => {
                let v: Vec<u16> = img
                    .data
                    .iter()
                    .enumerate()
                    .map(|(i, &x)| (encoded(i, x) * 65535.0).round() as u16)
                    .collect();
                match c {
                    1 => t.write_image::<colortype::Gray16>(w, h, &v),
                    3 => t.write_image::<colortype::RGB16>(w, h, &v),
                    _ => t.write_image::<colortype::RGBA16>(w, h, &v),
                }
            }
            TiffDepth::F32 => match c {
                1 => t.write_image::<colortype::Gray32Float>(w, h, &img.data),
                3 => t.write_image::<colortype::RGB32Float>(w, h, &img.data),
                _ => t.write_image::<colortype::RGBA32Float>(w, h, &img.data),
            },
        }
        .map_err(enc)?;
    }
    Ok(out.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(channels: usize) -> Image {
        let mut img = Image::new(11, 5, channels);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = (i % 53) as f32 / 52.0;
        }
        img
    }

    #[test]
    fn every_depth_compression_and_channel_count_round_trips() {
        for depth in [TiffDepth::U8, TiffDepth::U16, TiffDepth::F32] {
            for compression in [
                TiffCompression::None,
                TiffCompression::Lzw,
                TiffCompression::Deflate,
            ] {
                for channels in [1, 3, 4] {
                    let img = ramp(channels);
                    let bytes = encode(&img, &TiffOptions { depth, compression }).unwrap();
                    assert_eq!(Format::sniff(&bytes), Some(Format::Tiff));
                    let back = decode(&bytes).unwrap();
                    assert_eq!((back.width, back.height, back.channels), (11, 5, channels));
                    let tol = match depth {
                        TiffDepth::U8 => 0.5 / 255.0 * 2.5,
                        TiffDepth::U16 => 0.5 / 65535.0 * 13.0,
                        TiffDepth::F32 => 0.0,
                    };
                    let e = img.max_abs_diff(&back).unwrap();
                    assert!(e <= tol, "{depth:?} {compression:?} {channels}: {e}");
                }
            }
        }
    }

    #[test]
    fn floats_beyond_one_stay_linear() {
        let mut img = ramp(3);
        img.data[0] = 12.5;
        let o = TiffOptions {
            depth: TiffDepth::F32,
            compression: TiffCompression::Deflate,
        };
        let back = decode(&encode(&img, &o).unwrap()).unwrap();
        assert_eq!(back.data[0], 12.5);
        assert_eq!(back.data, img.data);
    }

    #[test]
    fn hostile_and_truncated_files_are_errors() {
        let bytes = encode(&ramp(3), &TiffOptions::default()).unwrap();
        for n in [0, 4, 8, 16, bytes.len() / 2, bytes.len() - 1] {
            assert!(decode(&bytes[..n]).is_err(), "{n} bytes");
        }
        assert!(decode(b"II*\0\xff\xff\xff\x7f").is_err());
        // A small file declaring a huge image is refused before decoding.
        let w = 11u32.to_le_bytes();
        let at = bytes
            .windows(12)
            .position(|x| x[..2] == [0, 1] && x[8..12] == w)
            .expect("the ImageWidth entry");
        let mut big = bytes.clone();
        // A LONG width of 60000 (the entry's type set to LONG, 4).
        big[at + 2..at + 4].copy_from_slice(&4u16.to_le_bytes());
        big[at + 8..at + 12].copy_from_slice(&60000u32.to_le_bytes());
        let e = decode(&big).unwrap_err().to_string();
        assert!(e.contains("more than a"), "{e}");
    }
}
