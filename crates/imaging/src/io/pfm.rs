//! Portable Float Map (PFM): the 32-bit float format of Debevec's HDRShop, as described in
//! Paul Debevec's PFM notes and `pfstools`.
//!
//! Layout: an ASCII header of three whitespace-separated fields — `PF` (RGB) or `Pf` (gray);
//! `width height`; a scale factor whose **sign gives the byte order** (negative = little endian,
//! positive = big endian; its magnitude is informative only and is ignored) — followed by a single
//! whitespace byte and `width * height * channels` IEEE-754 floats, rows stored **bottom to top**.
//! This reader accepts any ASCII whitespace between the fields. The writer emits
//! `PF\n<w> <h>\n-1.0\n` (or `Pf`) and little-endian floats.

use super::{check_encodable, f32_from, Format};
use crate::error::ImageError;
use crate::image::{sample_count, Image};

fn err(reason: impl Into<String>) -> ImageError {
    ImageError::decode(Format::Pfm, reason)
}

/// A tiny cursor over the ASCII header.
struct Header<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Header<'a> {
    fn skip_whitespace(&mut self) {
        while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    /// The next whitespace-delimited token (at most 64 bytes), not consuming the delimiter.
    fn token(&mut self, what: &str) -> Result<&'a str, ImageError> {
        self.skip_whitespace();
        let start = self.pos;
        while self.pos < self.bytes.len()
            && !self.bytes[self.pos].is_ascii_whitespace()
            && self.pos - start < 64
        {
            self.pos += 1;
        }
        if self.pos == start {
            return Err(err(format!("header ends before the {what}")));
        }
        if self.pos >= self.bytes.len() {
            return Err(err(format!("header ends inside the {what}")));
        }
        std::str::from_utf8(&self.bytes[start..self.pos])
            .map_err(|_| err(format!("the {what} is not ASCII")))
    }
}

/// Decode PFM bytes (either byte order) into a 1- or 3-channel image, top row first.
pub fn decode(bytes: &[u8]) -> Result<Image, ImageError> {
    let channels = match bytes.get(..2) {
        Some(b"PF") => 3,
        Some(b"Pf") => 1,
        _ => return Err(err("missing the PF/Pf magic")),
    };
    let mut h = Header { bytes, pos: 2 };
    if !bytes.get(2).is_some_and(|b| b.is_ascii_whitespace()) {
        return Err(err("the PF/Pf magic is not followed by whitespace"));
    }
    let parse_dim = |s: &str, what: &str| -> Result<usize, ImageError> {
        s.parse::<usize>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| err(format!("{what} {s:?} is not a positive integer")))
    };
    let width = parse_dim(h.token("width")?, "width")?;
    let height = parse_dim(h.token("height")?, "height")?;
    let scale_text = h.token("scale")?;
    let scale: f32 = scale_text
        .parse()
        .map_err(|_| err(format!("scale {scale_text:?} is not a number")))?;
    if !scale.is_finite() || scale == 0.0 {
        return Err(err(format!(
            "scale {scale_text:?} must be a finite non-zero number (its sign gives the byte order)"
        )));
    }
    let little_endian = scale < 0.0;
    // Exactly one whitespace byte ends the header (token() stopped on it).
    let data_start = h.pos + 1;
    let n =
        sample_count(width, height, channels).map_err(|e| err(format!("{width}x{height}: {e}")))?;
    let need = n * 4;
    let data = &bytes[data_start.min(bytes.len())..];
    if data.len() < need {
        return Err(err(format!(
            "{width}x{height} {} needs {need} bytes of pixels, the file has {}",
            if channels == 3 { "RGB" } else { "gray" },
            data.len()
        )));
    }
    let row = width * channels;
    let mut out = Vec::with_capacity(n);
    for y in (0..height).rev() {
        let src = &data[y * row * 4..(y + 1) * row * 4];
        out.extend(
            src.chunks_exact(4)
                .map(|b| f32_from([b[0], b[1], b[2], b[3]], little_endian)),
        );
    }
    Image::from_vec(width, height, channels, out)
}

/// Encode as little-endian PFM: gray images as `Pf`, colour as `PF`. Alpha cannot be stored and is
/// dropped; values (including NaN and ±∞) are written as they are.
pub fn encode(img: &Image) -> Result<Vec<u8>, ImageError> {
    encode_with_byte_order(img, true)
}

/// Encode as PFM in the chosen byte order (`little_endian = false` writes a positive scale and
/// big-endian floats, as older tools do).
pub fn encode_with_byte_order(img: &Image, little_endian: bool) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, Format::Pfm)?;
    let cc = img.color_channels();
    let magic = if cc == 3 { "PF" } else { "Pf" };
    let scale = if little_endian { "-1.0" } else { "1.0" };
    let mut out = format!("{magic}\n{} {}\n{scale}\n", img.width, img.height).into_bytes();
    out.reserve(img.pixel_count() * cc * 4);
    for y in (0..img.height).rev() {
        for p in img.row(y).chunks_exact(img.channels) {
            for &v in &p[..cc] {
                out.extend_from_slice(&if little_endian {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_image(ch: usize) -> Image {
        Image::from_fn(5, 3, ch, |x, y, c| {
            x as f32 * 1.5 - y as f32 * 100.25 + c as f32 * 1e-3 + 1e-30
        })
    }

    #[test]
    fn round_trip_is_exact_in_both_byte_orders() {
        for ch in [1, 3] {
            let mut img = test_image(ch);
            img.data[1] = f32::INFINITY;
            img.data[2] = -0.0;
            img.data[4] = f32::MIN_POSITIVE / 8.0; // a denormal
            for le in [true, false] {
                let bytes = encode_with_byte_order(&img, le).unwrap();
                let back = decode(&bytes).unwrap();
                assert_eq!((back.width, back.height, back.channels), (5, 3, ch));
                let same = img
                    .data
                    .iter()
                    .zip(&back.data)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "ch {ch} le {le}");
            }
        }
        // NaN survives bit-exactly as well.
        let mut img = test_image(1);
        img.data[0] = f32::NAN;
        assert!(decode(&encode(&img).unwrap()).unwrap().data[0].is_nan());
    }

    #[test]
    fn alpha_is_dropped_and_gray_alpha_is_gray() {
        let rgba = test_image(4);
        let back = decode(&encode(&rgba).unwrap()).unwrap();
        assert_eq!(back, rgba.without_alpha());
        let ga = test_image(2);
        assert_eq!(decode(&encode(&ga).unwrap()).unwrap().channels, 1);
    }

    #[test]
    fn hand_built_big_endian_file_bottom_up() {
        // 2x2 RGB, scale +1 (big endian). The first stored row is the bottom one.
        let mut f = b"PF\n2 2\n1.0\n".to_vec();
        let bottom = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
        let top = [10.0f32, 20.0, 30.0, 40.0, 50.0, 60.0];
        for v in bottom.iter().chain(&top) {
            f.extend(v.to_be_bytes());
        }
        let img = decode(&f).unwrap();
        assert_eq!(img.pixel(0, 0), &[10.0, 20.0, 30.0], "(0,0) is top-left");
        assert_eq!(img.pixel(1, 0), &[40.0, 50.0, 60.0]);
        assert_eq!(img.pixel(0, 1), &[1.0, 2.0, 3.0]);
        assert_eq!(img.pixel(1, 1), &[4.0, 5.0, 6.0]);
        // The same in little endian with a scale of -0.5 and CRLF-ish spacing.
        let mut g = b"Pf  2\t1\r\n-0.5\n".to_vec();
        for v in [7.0f32, 8.0] {
            g.extend(v.to_le_bytes());
        }
        let img = decode(&g).unwrap();
        assert_eq!((img.width, img.height, img.channels), (2, 1, 1));
        assert_eq!(img.data, vec![7.0, 8.0]);
    }

    #[test]
    fn writer_header_is_canonical() {
        let bytes = encode(&test_image(3)).unwrap();
        assert!(bytes.starts_with(b"PF\n5 3\n-1.0\n"));
        assert_eq!(bytes.len(), 12 + 5 * 3 * 3 * 4);
        // The first stored value is the bottom-left pixel's red.
        let first = f32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]);
        assert_eq!(first, test_image(3).get(0, 2, 0));
    }

    #[test]
    fn malformed_headers_are_errors() {
        let bad: [&[u8]; 12] = [
            b"",
            b"P",
            b"PX\n1 1\n-1\n\0\0\0\0",
            b"PF1 1\n-1\n",
            b"PF\n0 1\n-1\n",
            b"PF\n-3 1\n-1\n\0\0\0\0",
            b"PF\n1 1\n0\n\0\0\0\0\0\0\0\0\0\0\0\0",
            b"PF\n1 1\nnan\n\0\0\0\0\0\0\0\0\0\0\0\0",
            b"PF\n1 1\nabc\n\0\0\0\0\0\0\0\0\0\0\0\0",
            b"PF\n99999999999 99999999999\n-1\n\0\0\0\0",
            b"PF\n18446744073709551615 2\n-1\n",
            b"Pf\n1 1\n-1",
        ];
        for b in bad {
            assert!(decode(b).is_err(), "{:?}", String::from_utf8_lossy(b));
        }
    }

    #[test]
    fn truncation_at_every_length_is_an_error() {
        let bytes = encode(&test_image(3)).unwrap();
        for len in 0..bytes.len() {
            assert!(decode(&bytes[..len]).is_err(), "length {len}");
        }
        assert!(decode(&bytes).is_ok());
    }
}
