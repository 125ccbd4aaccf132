//! DPX, the Digital Picture Exchange file of scanners, film recorders and cinema cameras
//! (SMPTE ST 268-1:2014, "File Format for Digital Moving-Picture Exchange"; the Cineon log
//! encoding it usually carries is Kodak's, "Conversion of 10-bit Log Film Data To 8-bit
//! Linear or Video Data for the Cineon Digital Film System", 1995).
//!
//! Layout: a 2048-byte header (generic file header, image information with up to eight image
//! elements, orientation, film and television headers), then the pixels. The magic `SDPX`
//! says big-endian, `XPDS` little-endian; every field is in that order. This module reads the
//! first image element: luma (descriptor 6), RGB (50), RGBA (51) and ABGR (52) at 8, 10, 12,
//! 16 bits and 32-bit float, with the three packings of the standard — *packed* (datums
//! contiguous in 32-bit words, least significant bits first), *filled method A* (10-bit:
//! three datums a 32-bit word, two padding bits at the bottom, the first datum in the top bits
//! — in the bottom ones for luma, as OpenImageIO and FFmpeg have it; 12-bit: a datum a 16-bit word,
//! in its top bits) and *filled method B* (the padding at the top) — each line starting on a
//! 32-bit word (8-, 16- and filled 12-bit lines too when the file is that long: OpenImageIO
//! writes them unpadded, as this writer does), plus the element's end-of-line padding. Run-length encoded elements are
//! refused by name.
//!
//! Values: [`decode_codes`] gives the code values over [0, 1] (what OpenImageIO reads) and the
//! header's transfer and colorimetric fields; [`decode`] turns them into linear light by the
//! transfer characteristic: printing density and logarithmic by the Cineon curve between the
//! element's reference black and white codes (95 and 685 of 1023 when unset), linear as is,
//! the Rec. 709/601 video transfers by the inverse of their OETF, anything else (user defined,
//! unspecified) by the sRGB curve as 8/16-bit PNG is. The writer ([`encode`]) writes one
//! element, big-endian, filled method A, in any of these transfers (default: 10-bit Cineon
//! log, what a plate is delivered in).

use super::{check_encodable, Format, Values};
use crate::color::{linear_to_srgb, srgb_to_linear};
use crate::error::ImageError;
use crate::image::{sample_count, Image};

/// Bytes of the header this writer emits (and the usual offset to the pixels).
const HEADER: usize = 2048;

fn err(reason: impl Into<String>) -> ImageError {
    ImageError::decode(Format::Dpx, reason)
}

/// The transfer characteristic of an element (SMPTE ST 268 table 5A), as the writer sets it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transfer {
    /// Printing density, Cineon log (code 1): the film scan's and most plates' encoding.
    PrintingDensity,
    /// Linear (code 2).
    Linear,
    /// Rec. ITU-R BT.709 (code 6).
    Bt709,
    /// User defined (code 0), written with the sRGB curve.
    Srgb,
}

impl Transfer {
    /// The header code.
    pub fn code(self) -> u8 {
        match self {
            Transfer::PrintingDensity => 1,
            Transfer::Linear => 2,
            Transfer::Bt709 => 6,
            Transfer::Srgb => 0,
        }
    }
}

/// The name of transfer or colorimetric `code` (SMPTE ST 268 tables 5A/5B).
pub fn characteristic_name(code: u8) -> &'static str {
    match code {
        0 => "user defined",
        1 => "printing density",
        2 => "linear",
        3 => "logarithmic",
        4 => "unspecified video",
        5 => "SMPTE 274M",
        6 => "ITU-R 709-4",
        7 => "ITU-R 601-5 system B or G (625)",
        8 => "ITU-R 601-5 system M (525)",
        9 => "composite video (NTSC)",
        10 => "composite video (PAL)",
        11 => "Z (depth) linear",
        12 => "Z (depth) homogeneous",
        13 => "ADX",
        14 => "ITU-R 2020 NCL",
        15 => "ITU-R 2020 CL",
        16 => "IEC 61966-2-4 xvYCC",
        17 => "ITU-R 2100 NCL/PQ",
        18 => "ITU-R 2100 NCL/HLG",
        255 => "undefined",
        _ => "reserved",
    }
}

/// What the header of a DPX file says of its first image element.
#[derive(Clone, Debug, PartialEq)]
pub struct DpxInfo {
    /// Pixels per line.
    pub width: usize,
    /// Lines.
    pub height: usize,
    /// Channels decoded: 1 (luma), 3 (RGB) or 4 (RGBA).
    pub channels: usize,
    /// Bits per datum: 8, 10, 12, 16 or 32 (float).
    pub bits: u8,
    /// 0 packed, 1 filled method A, 2 filled method B.
    pub packing: u16,
    /// The file's byte order.
    pub big_endian: bool,
    /// Image descriptor (6 luma, 50 RGB, 51 RGBA, 52 ABGR).
    pub descriptor: u8,
    /// Transfer characteristic code (see [`characteristic_name`]).
    pub transfer: u8,
    /// Colorimetric specification code (see [`characteristic_name`]).
    pub colorimetric: u8,
    /// Reference black and white code values, when the header sets them.
    pub reference: Option<(u32, u32)>,
    /// Where the pixels start.
    pub data_offset: usize,
    /// Bytes of padding after each line.
    pub line_padding: usize,
    /// Frames a second, as the film industry header records it (else the television
    /// header's temporal sampling rate), when either is set.
    pub frame_rate: Option<f64>,
}

/// A reader of the header's fields in the file's byte order.
struct Fields<'a> {
    b: &'a [u8],
    be: bool,
}

impl Fields<'_> {
    fn u32(&self, at: usize) -> Result<u32, ImageError> {
        let s: [u8; 4] = self
            .b
            .get(at..at + 4)
            .and_then(|s| s.try_into().ok())
            .ok_or_else(|| err("the header is cut short"))?;
        Ok(if self.be {
            u32::from_be_bytes(s)
        } else {
            u32::from_le_bytes(s)
        })
    }
    fn u16(&self, at: usize) -> Result<u16, ImageError> {
        let s: [u8; 2] = self
            .b
            .get(at..at + 2)
            .and_then(|s| s.try_into().ok())
            .ok_or_else(|| err("the header is cut short"))?;
        Ok(if self.be {
            u16::from_be_bytes(s)
        } else {
            u16::from_le_bytes(s)
        })
    }
    fn u8(&self, at: usize) -> Result<u8, ImageError> {
        self.b
            .get(at)
            .copied()
            .ok_or_else(|| err("the header is cut short"))
    }
}

/// 0xFFFFFFFF, the standard's "undefined", read as `None`.
fn defined(v: u32) -> Option<u32> {
    (v != u32::MAX).then_some(v)
}

/// Reads and checks the header: the first element's geometry, encoding and characteristics.
pub fn read_header(bytes: &[u8]) -> Result<DpxInfo, ImageError> {
    let be = match bytes.get(..4) {
        Some(b"SDPX") => true,
        Some(b"XPDS") => false,
        _ => return Err(err("missing the SDPX/XPDS magic")),
    };
    let f = Fields { b: bytes, be };
    let image_offset = f.u32(4)? as usize;
    let elements = f.u16(770)?;
    if elements == 0 || elements > 8 {
        return Err(err(format!("{elements} image elements (1 to 8)")));
    }
    let width = f.u32(772)? as usize;
    let height = f.u32(776)? as usize;
    // The first image element.
    let e = 780;
    let sign = f.u32(e)?;
    let (low, high) = (defined(f.u32(e + 4)?), defined(f.u32(e + 12)?));
    let descriptor = f.u8(e + 20)?;
    let transfer = f.u8(e + 21)?;
    let colorimetric = f.u8(e + 22)?;
    let bits = f.u8(e + 23)?;
    let packing = f.u16(e + 24)?;
    let encoding = f.u16(e + 26)?;
    let element_offset = defined(f.u32(e + 28)?).unwrap_or(0) as usize;
    let line_padding = defined(f.u32(e + 32)?).unwrap_or(0) as usize;
    let channels = match descriptor {
        6 => 1,
        50 => 3,
        51 | 52 => 4,
        d => {
            return Err(err(format!(
                "image descriptor {d} is not supported (luma 6, RGB 50, RGBA 51, ABGR 52)"
            )))
        }
    };
    if encoding == 1 {
        return Err(err("run-length encoded elements are not supported"));
    }
    if sign == 1 {
        return Err(err("signed data is not supported"));
    }
    if !matches!(bits, 8 | 10 | 12 | 16 | 32) {
        return Err(err(format!("{bits} bits per datum (8, 10, 12, 16 or 32)")));
    }
    if packing > 2 {
        return Err(err(format!("packing {packing} (0 packed, 1 or 2 filled)")));
    }
    if width == 0 || height == 0 {
        return Err(err(format!("{width}×{height} pixels")));
    }
    sample_count(width, height, channels).map_err(|e| err(e.to_string()))?;
    let data_offset = if element_offset != 0 {
        element_offset
    } else {
        image_offset
    };
    if data_offset < 780 + 72 {
        return Err(err(format!(
            "pixels at byte {data_offset}, inside the header"
        )));
    }
    let reference = match (low, high) {
        (Some(l), Some(h)) if h > l && h < (1u32 << bits.min(16)) => Some((l, h)),
        _ => None,
    };
    // A rate field (f32) of the film (byte 1724) or television (byte 1940) header, when the
    // header reaches it and it holds a rate (undefined is all ones: a NaN).
    let rate_at = |at: usize| {
        let v = f32::from_bits(f.u32(at).ok().filter(|_| data_offset >= at + 4)?);
        (v.is_finite() && v > 0.0 && v <= 1000.0).then_some(v as f64)
    };
    let frame_rate = rate_at(1724).or_else(|| rate_at(1940));
    Ok(DpxInfo {
        width,
        height,
        channels,
        bits,
        packing,
        big_endian: be,
        descriptor,
        transfer,
        colorimetric,
        reference,
        data_offset,
        line_padding,
        frame_rate,
    })
}

impl DpxInfo {
    /// Bytes of one line's pixels (before the end-of-line padding); 8-, 16- and filled 12-bit
    /// lines without the padding to a 32-bit word that some writers leave out (see
    /// [`decode_codes`]).
    fn line_bytes(&self) -> Option<usize> {
        let datums = self.width.checked_mul(self.channels)?;
        let words = |bits_per_word_datum: usize| datums.div_ceil(bits_per_word_datum) * 4;
        Some(match (self.bits, self.packing) {
            (8, _) => datums,
            (16, _) => datums * 2,
            (32, _) => datums * 4,
            (10, 0) | (12, 0) => (datums * self.bits as usize).div_ceil(32) * 4,
            (10, _) => words(3),
            (12, _) => datums * 2,
            _ => return None,
        })
    }

    /// The largest code value.
    fn max_code(&self) -> f32 {
        if self.bits == 32 {
            1.0
        } else {
            ((1u32 << self.bits) - 1) as f32
        }
    }
}

/// Decodes the first element's code values, each over [0, 1] (float data as stored), in
/// R, G, B, A order, top line first; with the header's description.
pub fn decode_codes(bytes: &[u8]) -> Result<(Image, DpxInfo), ImageError> {
    let info = read_header(bytes)?;
    let pixels = info
        .line_bytes()
        .ok_or_else(|| err("the line size overflows"))?;
    // Where the last line ends for lines `line` bytes apart (its own padding may be absent).
    let end = |line: usize| {
        line.checked_mul(info.height - 1)
            .and_then(|n| n.checked_add(pixels))
            .and_then(|n| n.checked_add(info.data_offset))
    };
    let mut line = pixels
        .checked_add(info.line_padding)
        .ok_or_else(|| err("the line size overflows"))?;
    // 8-, 16- and filled 12-bit lines start on a 32-bit word when the file is long enough
    // for that (FFmpeg's rule: OpenImageIO writes and reads them unpadded, others pad them).
    let filled12 = info.bits == 12 && info.packing != 0;
    if (matches!(info.bits, 8 | 16) || filled12) && pixels % 4 != 0 {
        let padded = pixels.div_ceil(4) * 4 + info.line_padding;
        if end(padded).is_some_and(|n| n <= bytes.len()) {
            line = padded;
        }
    }
    let need = end(line).ok_or_else(|| err("the image size overflows"))?;
    if need > bytes.len() {
        return Err(err(format!(
            "{}×{} pixels at {} bits need {need} bytes, the file has {}",
            info.width,
            info.height,
            info.bits,
            bytes.len()
        )));
    }
    let mut img = Image::try_new(info.width, info.height, info.channels)?;
    let n = info.width * info.channels;
    let scale = 1.0 / info.max_code();
    let mut datums = vec![0u32; n];
    for y in 0..info.height {
        let start = info.data_offset + y * line;
        let row = &bytes[start..start + pixels];
        unpack_line(row, &info, &mut datums);
        let out = &mut img.data[y * n..(y + 1) * n];
        if info.bits == 32 {
            for (o, &d) in out.iter_mut().zip(&datums) {
                *o = f32::from_bits(d);
            }
        } else {
            for (o, &d) in out.iter_mut().zip(&datums) {
                *o = d as f32 * scale;
            }
        }
        if info.descriptor == 52 {
            for px in out.chunks_exact_mut(4) {
                px.reverse();
            }
        }
    }
    Ok((img, info))
}

/// Where datum `k` (0–2) of a 32-bit word of 10-bit filled data sits, in tens of bits above
/// the padding: the first in the highest bits for RGB(A), in the lowest for luma (as
/// OpenImageIO and FFmpeg read and write single-component files).
fn filled_slot(channels: usize, k: usize) -> usize {
    if channels == 1 {
        k
    } else {
        2 - k
    }
}

/// The datums of one line (`out.len()` of them) in storage order.
fn unpack_line(row: &[u8], info: &DpxInfo, out: &mut [u32]) {
    let be = info.big_endian;
    let word = |i: usize| {
        let s: [u8; 4] = row[4 * i..4 * i + 4].try_into().expect("4 bytes");
        if be {
            u32::from_be_bytes(s)
        } else {
            u32::from_le_bytes(s)
        }
    };
    let half = |i: usize| {
        let s = [row[2 * i], row[2 * i + 1]];
        if be {
            u16::from_be_bytes(s)
        } else {
            u16::from_le_bytes(s)
        }
    };
    match (info.bits, info.packing) {
        (8, _) => {
            for (o, &b) in out.iter_mut().zip(row) {
                *o = b as u32;
            }
        }
        (16, _) => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = half(i) as u32;
            }
        }
        (32, _) => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = word(i);
            }
        }
        (12, 1) => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = (half(i) >> 4) as u32;
            }
        }
        (12, _) if info.packing == 2 => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = (half(i) & 0xFFF) as u32;
            }
        }
        (10, 1 | 2) => {
            let shift = if info.packing == 1 { 2 } else { 0 };
            for (i, o) in out.iter_mut().enumerate() {
                let w = word(i / 3);
                *o = (w >> (shift + 10 * filled_slot(info.channels, i % 3))) & 0x3FF;
            }
        }
        (bits, _) => {
            // Packed: a bit stream through 32-bit words, least significant bits first.
            let bits = bits as usize;
            let mask = (1u64 << bits) - 1;
            for (i, o) in out.iter_mut().enumerate() {
                let at = i * bits;
                let (w, b) = (at / 32, at % 32);
                let lo = word(w) as u64;
                let hi = if b + bits > 32 { word(w + 1) as u64 } else { 0 };
                *o = (((hi << 32 | lo) >> b) & mask) as u32;
            }
        }
    }
}

/// The Cineon curve (Kodak): printing density code `c` (of 1023) to linear light, with
/// reference black `black` and white `white` codes; 0.002 density a code, negative gamma 0.6.
fn cineon_to_linear(c: f32, black: f32, white: f32) -> f32 {
    let k = 0.002 / 0.6;
    let offset = 10f32.powf((black - white) * k);
    (10f32.powf((c - white) * k) - offset) / (1.0 - offset)
}

/// The inverse of [`cineon_to_linear`].
fn linear_to_cineon(v: f32, black: f32, white: f32) -> f32 {
    let k = 0.002 / 0.6;
    let offset = 10f32.powf((black - white) * k);
    let x = (v * (1.0 - offset) + offset).max(1e-10);
    white + x.log10() / k
}

/// The inverse of the Rec. 709 / 601 opto-electronic transfer function.
fn bt709_to_linear(v: f32) -> f32 {
    if v < 0.081 {
        v / 4.5
    } else {
        ((v + 0.099) / 1.099).powf(1.0 / 0.45)
    }
}

/// The Rec. 709 / 601 opto-electronic transfer function.
fn linear_to_bt709(v: f32) -> f32 {
    if v < 0.018 {
        4.5 * v
    } else {
        1.099 * v.powf(0.45) - 0.099
    }
}

/// Decodes a DPX file into linear light by its transfer characteristic (module docs). Alpha
/// stays as stored.
pub fn decode(bytes: &[u8]) -> Result<Image, ImageError> {
    let (mut img, info) = decode_codes(bytes)?;
    if info.bits == 32 {
        return Ok(img);
    }
    let max = info.max_code();
    let alpha = info.channels == 4;
    let curve: Box<dyn Fn(f32) -> f32> = match info.transfer {
        1 | 3 => {
            let (black, white) = info
                .reference
                .map(|(l, h)| (l as f32 * 1023.0 / max, h as f32 * 1023.0 / max))
                .unwrap_or((95.0, 685.0));
            Box::new(move |v| cineon_to_linear(v * 1023.0, black, white))
        }
        2 | 11 => Box::new(|v| v),
        5..=8 => Box::new(bt709_to_linear),
        _ => Box::new(srgb_to_linear),
    };
    let c = img.channels;
    for (i, v) in img.data.iter_mut().enumerate() {
        if !(alpha && i % c == 3) {
            *v = curve(*v);
        }
    }
    Ok(img)
}

/// How [`encode`] writes a DPX file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DpxOptions {
    /// Bits per datum: 8, 10, 12 or 16.
    pub bits: u8,
    /// The transfer characteristic the values are encoded with.
    pub transfer: Transfer,
}

impl Default for DpxOptions {
    /// 10-bit printing density (Cineon log): what plates are delivered in.
    fn default() -> Self {
        DpxOptions {
            bits: 10,
            transfer: Transfer::PrintingDensity,
        }
    }
}

/// Encodes a linear-light image (1, 3 or 4 channels; 2 are written as luma + nothing, so
/// refused) as a big-endian, filled-method-A DPX file of one element.
pub fn encode(img: &Image, o: &DpxOptions) -> Result<Vec<u8>, ImageError> {
    encode_values(img, o, Values::Linear)
}

/// [`encode`] of linear light, or of code values over [0, 1] (`values`): those are quantised
/// to `o.bits` with no curve, and the header says "user defined" transfer (the colour space
/// is the one a colour-managed reader is told).
pub(crate) fn encode_values(
    img: &Image,
    o: &DpxOptions,
    values: Values,
) -> Result<Vec<u8>, ImageError> {
    let codes = values == Values::Codes;
    let user = DpxOptions {
        bits: o.bits,
        transfer: Transfer::Srgb,
    };
    let o = if codes { &user } else { o };
    check_encodable(img, Format::Dpx)?;
    let descriptor = match img.channels {
        1 => 6u8,
        3 => 50,
        4 => 51,
        c => {
            return Err(ImageError::encode(
                Format::Dpx,
                format!("{c} channels (1, 3 or 4)"),
            ))
        }
    };
    if !matches!(o.bits, 8 | 10 | 12 | 16) {
        return Err(ImageError::encode(
            Format::Dpx,
            format!("{} bits (8, 10, 12 or 16)", o.bits),
        ));
    }
    let max = ((1u32 << o.bits) - 1) as f32;
    // The reference codes as written (in this depth's codes), so the reader's curve is this.
    let (low, high) = reference_codes(o);
    let (black, white) = (low as f32 * 1023.0 / max, high as f32 * 1023.0 / max);
    let code = |v: f32| -> u32 {
        let e = match o.transfer {
            _ if codes => v,
            Transfer::PrintingDensity => linear_to_cineon(v, black, white) / 1023.0,
            Transfer::Linear => v,
            Transfer::Bt709 => linear_to_bt709(v.max(0.0)),
            Transfer::Srgb => linear_to_srgb(v.max(0.0)),
        };
        let e = if e.is_nan() { 0.0 } else { e };
        (e * max).round().clamp(0.0, max) as u32
    };
    let alpha_code = |v: f32| (v.clamp(0.0, 1.0) * max).round() as u32;
    let info = DpxInfo {
        width: img.width,
        height: img.height,
        channels: img.channels,
        bits: o.bits,
        packing: if matches!(o.bits, 10 | 12) { 1 } else { 0 },
        big_endian: true,
        descriptor,
        transfer: o.transfer.code(),
        colorimetric: 0,
        reference: None,
        data_offset: HEADER,
        line_padding: 0,
        frame_rate: None,
    };
    let line = info
        .line_bytes()
        .ok_or_else(|| ImageError::encode(Format::Dpx, "the line size overflows"))?;
    let size = HEADER + line * img.height;
    let mut out = vec![0u8; size];
    header(&mut out, &info, o, size);
    let n = img.width * img.channels;
    let mut datums = vec![0u32; n];
    for y in 0..img.height {
        for (i, (d, &v)) in datums
            .iter_mut()
            .zip(&img.data[y * n..(y + 1) * n])
            .enumerate()
        {
            *d = if img.channels == 4 && i % 4 == 3 {
                alpha_code(v)
            } else {
                code(v)
            };
        }
        let row = &mut out[HEADER + y * line..HEADER + (y + 1) * line];
        match o.bits {
            8 => {
                for (b, &d) in row.iter_mut().zip(&datums) {
                    *b = d as u8;
                }
            }
            10 => {
                for (w, chunk) in datums.chunks(3).enumerate() {
                    let mut word = 0u32;
                    for (k, &d) in chunk.iter().enumerate() {
                        word |= d << (2 + 10 * filled_slot(img.channels, k));
                    }
                    row[4 * w..4 * w + 4].copy_from_slice(&word.to_be_bytes());
                }
            }
            12 => {
                for (i, &d) in datums.iter().enumerate() {
                    row[2 * i..2 * i + 2].copy_from_slice(&((d as u16) << 4).to_be_bytes());
                }
            }
            _ => {
                for (i, &d) in datums.iter().enumerate() {
                    row[2 * i..2 * i + 2].copy_from_slice(&(d as u16).to_be_bytes());
                }
            }
        }
    }
    Ok(out)
}

/// The reference black and white codes the writer sets: Cineon's 95 and 685 (of 1023) in the
/// file's depth for printing density, else 0 and the largest code.
fn reference_codes(o: &DpxOptions) -> (u32, u32) {
    let max = (1u32 << o.bits) - 1;
    match o.transfer {
        Transfer::PrintingDensity => {
            let s = max as f32 / 1023.0;
            ((95.0 * s).round() as u32, (685.0 * s).round() as u32)
        }
        _ => (0, max),
    }
}

/// Writes the 2048-byte big-endian header of a one-element file of `size` bytes.
fn header(out: &mut [u8], info: &DpxInfo, o: &DpxOptions, size: usize) {
    let put32 =
        |out: &mut [u8], at: usize, v: u32| out[at..at + 4].copy_from_slice(&v.to_be_bytes());
    let put16 =
        |out: &mut [u8], at: usize, v: u16| out[at..at + 2].copy_from_slice(&v.to_be_bytes());
    let text =
        |out: &mut [u8], at: usize, s: &str| out[at..at + s.len()].copy_from_slice(s.as_bytes());
    // Everything the writer does not set is "undefined" (all ones) ...
    out[..HEADER].fill(0xFF);
    // ... but for the text fields, which are empty.
    for (at, len) in [
        (8, 8),
        (36, 100),
        (136, 24),
        (160, 100),
        (260, 200),
        (460, 200),
    ] {
        out[at..at + len].fill(0);
    }
    out[..4].copy_from_slice(b"SDPX");
    put32(out, 4, HEADER as u32);
    text(out, 8, "V2.0");
    put32(out, 16, size as u32);
    put32(out, 20, 1); // ditto key: new
    put32(out, 24, 1664); // generic header size
    put32(out, 28, 384); // industry header size
    put32(out, 32, 0); // user data size
    text(out, 160, "vfxgraph");
    put16(out, 768, 0); // orientation: left to right, top to bottom
    put16(out, 770, 1); // elements
    put32(out, 772, info.width as u32);
    put32(out, 776, info.height as u32);
    let e = 780;
    put32(out, e, 0); // unsigned
    let (low, high) = reference_codes(o);
    put32(out, e + 4, low);
    put32(out, e + 12, high);
    if o.transfer == Transfer::PrintingDensity {
        // Reference high quantity: the density of the white code.
        out[e + 16..e + 20].copy_from_slice(&2.047f32.to_be_bytes());
    }
    out[e + 20] = info.descriptor;
    out[e + 21] = info.transfer;
    out[e + 22] = match o.transfer {
        Transfer::PrintingDensity => 1,
        Transfer::Bt709 => 6,
        _ => 0,
    };
    out[e + 23] = o.bits;
    put16(out, e + 24, info.packing);
    put16(out, e + 26, 0); // no run-length encoding
    put32(out, e + 28, HEADER as u32);
    put32(out, e + 32, 0); // end-of-line padding
    put32(out, e + 36, 0); // end-of-image padding
    out[e + 40..e + 72].fill(0); // description
                                 // The other seven elements stay undefined; the orientation, film and television
                                 // headers (1408..2048) too.
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(channels: usize, w: usize, h: usize) -> Image {
        let mut img = Image::new(w, h, channels);
        for (i, v) in img.data.iter_mut().enumerate() {
            *v = (i % 97) as f32 / 60.0;
        }
        img
    }

    #[test]
    fn every_depth_and_transfer_round_trips_within_its_quantisation() {
        for transfer in [
            Transfer::PrintingDensity,
            Transfer::Linear,
            Transfer::Bt709,
            Transfer::Srgb,
        ] {
            for bits in [8u8, 10, 12, 16] {
                for channels in [1, 3, 4] {
                    let mut img = ramp(channels, 7, 3);
                    if transfer != Transfer::PrintingDensity {
                        for v in &mut img.data {
                            *v = v.min(1.0);
                        }
                    }
                    if channels == 4 {
                        for px in img.data.chunks_exact_mut(4) {
                            px[3] = px[3].min(1.0);
                        }
                    }
                    let o = DpxOptions { bits, transfer };
                    let bytes = encode(&img, &o).unwrap();
                    let (codes, info) = decode_codes(&bytes).unwrap();
                    assert_eq!((info.width, info.height, info.channels), (7, 3, channels));
                    assert_eq!((info.bits, info.transfer), (bits, transfer.code()));
                    assert!(codes.data.iter().all(|v| (0.0..=1.0).contains(v)));
                    let back = decode(&bytes).unwrap();
                    let step = 1.0 / ((1u32 << bits) - 1) as f32;
                    for (i, (a, b)) in img.data.iter().zip(&back.data).enumerate() {
                        // One code step through the curve's slope at `a`.
                        let slope = match transfer {
                            _ if channels == 4 && i % 4 == 3 => 1.0,
                            Transfer::PrintingDensity => (a + 0.011) * 1023.0 * 0.002 / 0.6 * 2.303,
                            Transfer::Linear => 1.0,
                            Transfer::Bt709 | Transfer::Srgb => 2.5 * a.max(0.05).powf(0.6),
                        };
                        assert!(
                            (a - b).abs() <= 0.51 * step * slope + 1e-6,
                            "{transfer:?} {bits} bits {channels} ch: {a} → {b}"
                        );
                    }
                }
            }
        }
    }

    /// The frame rate is the film header's, else the television header's; undefined (all
    /// ones), zero or absurd fields give none, and a header too short to hold them too.
    #[test]
    fn the_frame_rate_comes_from_the_film_or_television_header() {
        let img = ramp(3, 4, 2);
        let bytes = encode(&img, &DpxOptions::default()).unwrap();
        assert_eq!(read_header(&bytes).unwrap().frame_rate, None);
        let put =
            |b: &mut Vec<u8>, at: usize, v: f32| b[at..at + 4].copy_from_slice(&v.to_be_bytes());
        let mut tv = bytes.clone();
        put(&mut tv, 1940, 29.97);
        let r = read_header(&tv).unwrap().frame_rate.unwrap();
        assert!((r - 29.97).abs() < 1e-5, "{r}");
        let mut film = tv.clone();
        put(&mut film, 1724, 24.0);
        assert_eq!(read_header(&film).unwrap().frame_rate, Some(24.0));
        for bad in [0.0, -24.0, f32::INFINITY, 1e6] {
            let mut b = bytes.clone();
            put(&mut b, 1724, bad);
            assert_eq!(read_header(&b).unwrap().frame_rate, None, "{bad}");
        }
        // Little-endian files hold it in their own byte order.
        let mut le = bytes.clone();
        le[..4].copy_from_slice(b"XPDS");
        for at in [4usize, 772, 776, 780, 784, 792, 808, 812] {
            le[at..at + 4].reverse();
        }
        for at in [770usize, 804, 806] {
            le[at..at + 2].reverse();
        }
        le[1724..1728].copy_from_slice(&25.0f32.to_le_bytes());
        let info = read_header(&le).unwrap();
        assert_eq!(
            (info.width, info.height, info.frame_rate),
            (4, 2, Some(25.0))
        );
    }

    #[test]
    fn the_cineon_curve_puts_white_at_685_and_black_at_95() {
        assert!((cineon_to_linear(685.0, 95.0, 685.0) - 1.0).abs() < 1e-6);
        assert!(cineon_to_linear(95.0, 95.0, 685.0).abs() < 1e-6);
        // 18 % grey near code 470 (Kodak's LAD is 445 for 18 % on the negative's printing
        // density with the standard offset; the curve without soft clip puts it here).
        let grey = linear_to_cineon(0.18, 95.0, 685.0);
        assert!((grey - 470.0).abs() < 5.0, "{grey}");
        for v in [0.0, 0.01, 0.18, 1.0, 5.0] {
            let c = linear_to_cineon(v, 95.0, 685.0);
            assert!((cineon_to_linear(c, 95.0, 685.0) - v).abs() < 1e-4 * v.max(1.0));
        }
    }

    /// Both byte orders and all three packings of 10- and 12-bit datums, built by hand from
    /// the standard's bit layouts, decode to the same codes.
    #[test]
    fn packings_and_byte_orders_decode_alike() {
        let codes: Vec<u32> = (0..15).map(|i| (i * 67 + 5) % 1024).collect();
        let mk = |be: bool, bits: u8, packing: u16, payload: Vec<u8>| {
            let mut b = vec![0u8; HEADER];
            let w32 = |b: &mut [u8], at: usize, v: u32| {
                b[at..at + 4].copy_from_slice(&if be { v.to_be_bytes() } else { v.to_le_bytes() })
            };
            let w16 = |b: &mut [u8], at: usize, v: u16| {
                b[at..at + 2].copy_from_slice(&if be { v.to_be_bytes() } else { v.to_le_bytes() })
            };
            b[..4].copy_from_slice(if be { b"SDPX" } else { b"XPDS" });
            w32(&mut b, 4, HEADER as u32);
            w16(&mut b, 770, 1);
            w32(&mut b, 772, 5);
            w32(&mut b, 776, 1);
            w32(&mut b, 784, u32::MAX);
            w32(&mut b, 792, u32::MAX);
            b[800] = 50;
            b[801] = 2;
            b[803] = bits;
            w16(&mut b, 804, packing);
            w32(&mut b, 808, HEADER as u32);
            b.extend(payload);
            b
        };
        for be in [true, false] {
            let word = |v: u32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
            let half = |v: u16| if be { v.to_be_bytes() } else { v.to_le_bytes() };
            let mut files = Vec::new();
            // 10-bit filled A and B.
            for packing in [1u16, 2] {
                let shift = if packing == 1 { 2 } else { 0 };
                let mut p = Vec::new();
                for c in codes.chunks(3) {
                    let w = c[0] << (shift + 20) | c[1] << (shift + 10) | c[2] << shift;
                    p.extend(word(w));
                }
                files.push((10, mk(be, 10, packing, p)));
            }
            // 10-bit packed, least significant bits first.
            let mut words = [0u32; 5];
            for (i, &c) in codes.iter().enumerate() {
                for bit in 0..10 {
                    let at = 10 * i + bit;
                    words[at / 32] |= ((c >> bit) & 1) << (at % 32);
                }
            }
            let p: Vec<u8> = words.iter().flat_map(|&w| word(w)).collect();
            files.push((10, mk(be, 10, 0, p)));
            // 12-bit filled A and B (the same codes × 4).
            for packing in [1u16, 2] {
                let mut p = Vec::new();
                for &c in &codes {
                    let v = (c * 4) as u16;
                    p.extend(half(if packing == 1 { v << 4 } else { v }));
                }
                p.extend([0, 0]);
                files.push((12, mk(be, 12, packing, p)));
            }
            for (bits, f) in files {
                let (img, info) = decode_codes(&f).unwrap();
                assert_eq!(info.big_endian, be);
                let max = ((1u32 << bits) - 1) as f32;
                let got: Vec<u32> = img.data.iter().map(|v| (v * max).round() as u32).collect();
                let want: Vec<u32> = codes
                    .iter()
                    .map(|&c| if bits == 12 { c * 4 } else { c })
                    .collect();
                assert_eq!(got, want, "{bits} bits, packing {}, be {be}", info.packing);
            }
        }
    }

    #[test]
    fn hostile_headers_are_refused_before_allocating() {
        let img = ramp(3, 4, 2);
        let good = encode(&img, &DpxOptions::default()).unwrap();
        let mut huge = good.clone();
        huge[772..776].copy_from_slice(&40000u32.to_be_bytes());
        huge[776..780].copy_from_slice(&40000u32.to_be_bytes());
        let e = decode(&huge).unwrap_err().to_string();
        assert!(e.contains("need") || e.contains("limit"), "{e}");
        let mut short = good.clone();
        short.truncate(good.len() - 1);
        assert!(decode(&short)
            .unwrap_err()
            .to_string()
            .contains("the file has"));
        let mut rle = good.clone();
        rle[806..808].copy_from_slice(&1u16.to_be_bytes());
        assert!(decode(&rle).unwrap_err().to_string().contains("run-length"));
        let mut ycbcr = good;
        ycbcr[800] = 100;
        assert!(decode(&ycbcr)
            .unwrap_err()
            .to_string()
            .contains("descriptor 100"));
        assert!(decode(b"SDPX").is_err());
        assert!(decode(b"").is_err());
    }
}
