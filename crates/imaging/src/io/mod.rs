//! Reading and writing image files: PNG, JPEG, OpenEXR, PFM, Radiance RGBE, DPX and TIFF.
//!
//! All decoders return linear-light `f32` [`Image`]s with pixel `(0, 0)` at the top-left:
//! 8/16-bit sRGB formats (PNG, JPEG) are decoded with the IEC 61966-2-1 curve (alpha stays linear),
//! float formats (EXR, PFM, HDR) are taken as they are. Decoders produce 1 (gray), 3 (RGB) or
//! 4 (RGBA) channels. Encoders accept 1–4 channels and convert as each format requires (see the
//! per-format functions).
//!
//! Decoding never panics on malformed data: errors are [`ImageError`] values. Headers are checked
//! against [`crate::image::MAX_SAMPLES`] before any pixel buffer is allocated, and the third-party
//! decoders (`image`, `exr`) additionally run behind `catch_unwind`, so a bug of theirs on a hostile
//! file surfaces as [`ImageError::Decode`].

pub mod dpx;
pub mod exr;
pub mod hdr;
pub mod pfm;
pub mod png_jpeg;
pub mod tiff;

use std::path::Path;

pub use crate::error::ImageError;
use crate::image::Image;

pub use self::exr::{
    decode_layer as decode_exr_layer, encode_exr, encode_exr_layers, ExrCompression, ExrOptions,
    ExrPrecision, LayersOptions,
};
pub use self::png_jpeg::{encode_jpeg, encode_png16};

/// What an image's values are, relative to a file's numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Values {
    /// Linear light: the format's own curve decoded on read and applied on write (sRGB for
    /// 8/16-bit PNG, JPEG and TIFF; the header's transfer characteristic for DPX; float formats
    /// as stored). What [`decode`] and [`encode`] do.
    #[default]
    Linear,
    /// The file's code values, no curve: integer samples over [0, 1] (code / largest code),
    /// float samples as stored; on write, values quantised as they are (clamped to [0, 1] for
    /// integer samples; a DPX header then says "user defined" transfer). For files in a colour
    /// space a colour-management transform decodes ([`crate::colour`]). Alpha is coverage in
    /// both.
    Codes,
}

/// An image file format this crate reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Portable Network Graphics (ISO/IEC 15948), 8/16-bit sRGB.
    Png,
    /// JPEG (ISO/IEC 10918-1, JFIF), 8-bit sRGB, no alpha.
    Jpeg,
    /// OpenEXR (Kainz, Bogart & Hess; openexr.com file layout), half/float/uint channels.
    Exr,
    /// Portable Float Map (Debevec's HDRShop/`pfstools` format), 32-bit float gray or RGB.
    Pfm,
    /// Radiance RGBE picture (Ward, "Real Pixels", Graphics Gems II, 1991), `.hdr`.
    Hdr,
    /// Digital Picture Exchange (SMPTE ST 268), 8–16-bit codes, Cineon log by default.
    Dpx,
    /// TIFF 6.0, 8/16-bit sRGB or float linear, uncompressed, LZW or Deflate.
    Tiff,
}

impl Format {
    /// All formats, in a fixed order.
    pub const ALL: [Format; 7] = [
        Format::Png,
        Format::Jpeg,
        Format::Exr,
        Format::Pfm,
        Format::Hdr,
        Format::Dpx,
        Format::Tiff,
    ];

    /// The format named by the file extension of `p` (case-insensitive): `png`; `jpg`, `jpeg`,
    /// `jpe`; `exr`; `pfm`; `hdr`, `rgbe`; `dpx`; `tif`, `tiff`. `None` for anything else.
    pub fn from_path(p: &Path) -> Option<Format> {
        let ext = p.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(Format::Png),
            "jpg" | "jpeg" | "jpe" => Some(Format::Jpeg),
            "exr" => Some(Format::Exr),
            "pfm" => Some(Format::Pfm),
            "hdr" | "rgbe" => Some(Format::Hdr),
            "dpx" => Some(Format::Dpx),
            "tif" | "tiff" => Some(Format::Tiff),
            _ => None,
        }
    }

    /// The format recognised from the first bytes of a file (its magic number): PNG
    /// `89 50 4E 47`, JPEG `FF D8 FF`, OpenEXR `76 2F 31 01`, PFM `PF`/`Pf` + whitespace,
    /// Radiance `#?RADIANCE` or `#?RGBE`, DPX `SDPX` or `XPDS`, TIFF `II*\0` or `MM\0*` (and
    /// BigTIFF's `II+\0`, `MM\0+`).
    pub fn sniff(bytes: &[u8]) -> Option<Format> {
        if bytes.starts_with(b"\x89PNG") {
            Some(Format::Png)
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some(Format::Jpeg)
        } else if bytes.starts_with(&[0x76, 0x2F, 0x31, 0x01]) {
            Some(Format::Exr)
        } else if (bytes.starts_with(b"PF") || bytes.starts_with(b"Pf"))
            && bytes.get(2).is_some_and(|b| b.is_ascii_whitespace())
        {
            Some(Format::Pfm)
        } else if bytes.starts_with(b"#?RADIANCE") || bytes.starts_with(b"#?RGBE") {
            Some(Format::Hdr)
        } else if bytes.starts_with(b"SDPX") || bytes.starts_with(b"XPDS") {
            Some(Format::Dpx)
        } else if [b"II*\0", b"MM\0*", b"II+\0", b"MM\0+"]
            .iter()
            .any(|m| bytes.starts_with(*m))
        {
            Some(Format::Tiff)
        } else {
            None
        }
    }

    /// The canonical file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Jpeg => "jpg",
            Format::Exr => "exr",
            Format::Pfm => "pfm",
            Format::Hdr => "hdr",
            Format::Dpx => "dpx",
            Format::Tiff => "tif",
        }
    }

    /// The format's usual name ("PNG", "JPEG", "OpenEXR", "PFM", "Radiance HDR", "DPX").
    pub fn name(self) -> &'static str {
        match self {
            Format::Png => "PNG",
            Format::Jpeg => "JPEG",
            Format::Exr => "OpenEXR",
            Format::Pfm => "PFM",
            Format::Hdr => "Radiance HDR",
            Format::Dpx => "DPX",
            Format::Tiff => "TIFF",
        }
    }

    /// True for the formats that store linear floating-point values (EXR, PFM, HDR), false for
    /// the 8/16-bit sRGB ones (PNG, JPEG).
    pub fn is_float(self) -> bool {
        matches!(self, Format::Exr | Format::Pfm | Format::Hdr)
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Decode the bytes of a file of `format` into a linear-light image (see the module docs and
/// the per-format modules for details: [`png_jpeg`], [`exr`], [`pfm`], [`hdr`]).
pub fn decode(bytes: &[u8], format: Format) -> Result<Image, ImageError> {
    match format {
        Format::Png | Format::Jpeg => png_jpeg::decode(bytes, format),
        Format::Exr => exr::decode(bytes),
        Format::Pfm => pfm::decode(bytes),
        Format::Hdr => hdr::decode(bytes),
        Format::Dpx => dpx::decode(bytes),
        Format::Tiff => tiff::decode(bytes),
    }
}

/// Encode a linear-light image as a file of `format` with default options: PNG 8-bit sRGB,
/// JPEG quality 95 sRGB (alpha dropped), EXR 32-bit float ZIP, PFM little-endian, HDR RLE,
/// DPX 10-bit Cineon log, TIFF 16-bit sRGB Deflate.
/// For other choices use [`encode_png16`], [`encode_jpeg`], [`encode_exr`].
pub fn encode(img: &Image, format: Format) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, format)?;
    match format {
        Format::Png => png_jpeg::encode_png8(img),
        Format::Jpeg => encode_jpeg(img, png_jpeg::DEFAULT_JPEG_QUALITY),
        Format::Exr => encode_exr(img, &ExrOptions::default()),
        Format::Pfm => pfm::encode(img),
        Format::Hdr => hdr::encode(img),
        Format::Dpx => dpx::encode(img, &dpx::DpxOptions::default()),
        Format::Tiff => tiff::encode(img, &tiff::TiffOptions::default()),
    }
}

/// [`decode`] into `values`: linear light ([`Values::Linear`], what [`decode`] gives) or the
/// file's code values ([`Values::Codes`]).
pub fn decode_as(bytes: &[u8], format: Format, values: Values) -> Result<Image, ImageError> {
    match (values, format) {
        (Values::Linear, _) | (_, Format::Exr | Format::Pfm | Format::Hdr) => decode(bytes, format),
        (Values::Codes, Format::Png | Format::Jpeg) => {
            png_jpeg::decode_values(bytes, format, values)
        }
        (Values::Codes, Format::Dpx) => dpx::decode_codes(bytes).map(|(img, _)| img),
        (Values::Codes, Format::Tiff) => tiff::decode_values(bytes, values),
    }
}

/// [`encode`] of `values`: linear light ([`Values::Linear`], what [`encode`] does) or code
/// values ([`Values::Codes`]), with the same default depths.
pub fn encode_as(img: &Image, format: Format, values: Values) -> Result<Vec<u8>, ImageError> {
    check_encodable(img, format)?;
    match (values, format) {
        (Values::Linear, _) | (_, Format::Exr | Format::Pfm | Format::Hdr) => encode(img, format),
        (Values::Codes, Format::Png) => png_jpeg::encode_png8_values(img, values),
        (Values::Codes, Format::Jpeg) => {
            png_jpeg::encode_jpeg_values(img, png_jpeg::DEFAULT_JPEG_QUALITY, values)
        }
        (Values::Codes, Format::Dpx) => {
            dpx::encode_values(img, &dpx::DpxOptions::default(), values)
        }
        (Values::Codes, Format::Tiff) => {
            tiff::encode_values(img, &tiff::TiffOptions::default(), values)
        }
    }
}

/// Read an image file. The format comes from the extension; when the file's magic bytes name a
/// different format the magic bytes win (a mislabelled file still reads), and a file without a
/// known extension is identified by its magic bytes alone. Errors name `path`.
pub fn read_image(path: &Path) -> Result<Image, ImageError> {
    read_image_as(path, Values::Linear)
}

/// [`read_image`] into `values` (see [`decode_as`]).
pub fn read_image_as(path: &Path, values: Values) -> Result<Image, ImageError> {
    let bytes = std::fs::read(path).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let format = match (Format::sniff(&bytes), Format::from_path(path)) {
        (Some(sniffed), _) => sniffed,
        (None, Some(by_ext)) => by_ext,
        (None, None) => {
            return Err(ImageError::UnsupportedFormat(
                "unknown extension and unrecognised magic bytes".into(),
            )
            .at_path(path))
        }
    };
    decode_as(&bytes, format, values).map_err(|e| e.at_path(path))
}

/// Write an image file in the format named by the extension of `path` (see [`encode`]).
///
/// The write is atomic ([`write_atomic`]): a reader never sees a partial file, and a crash leaves
/// either the old file or the new one. The folder must exist (a mistyped output folder is an
/// error, not a new folder; the nodes create their output folders). Errors name `path`.
pub fn write_image(path: &Path, img: &Image) -> Result<(), ImageError> {
    write_image_as(path, img, Values::Linear)
}

/// [`write_image`] of `values` (see [`encode_as`]).
pub fn write_image_as(path: &Path, img: &Image, values: Values) -> Result<(), ImageError> {
    let format = Format::from_path(path).ok_or_else(|| {
        ImageError::UnsupportedFormat(format!(
            "cannot tell the format from the extension (use one of {})",
            Format::ALL.map(|f| f.extension()).join(", ")
        ))
        .at_path(path)
    })?;
    let bytes = encode_as(img, format, values).map_err(|e| e.at_path(path))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            return Err(ImageError::Io {
                path: dir.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such folder"),
            });
        }
    }
    write_atomic(path, &bytes)
}

/// Write `bytes` to `path` atomically with the project's one writer
/// ([`vfxgraph_fsutil::atomic_write`]: folders created, temporary in the same folder, fsync,
/// rename, folder fsync). Errors name `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    vfxgraph_fsutil::atomic_write(path, bytes).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reject images no encoder can take (channel counts outside 1–4, data length mismatch).
fn check_encodable(img: &Image, format: Format) -> Result<(), ImageError> {
    let n = crate::image::sample_count(img.width, img.height, img.channels)
        .map_err(|e| ImageError::encode(format, e.to_string()))?;
    if img.data.len() != n {
        return Err(ImageError::encode(
            format,
            format!(
                "{}x{}x{} image holds {} samples",
                img.width,
                img.height,
                img.channels,
                img.data.len()
            ),
        ));
    }
    if img.is_empty() {
        return Err(ImageError::encode(format, "the image has no pixels"));
    }
    Ok(())
}

/// Run a third-party decoder, turning a panic into [`ImageError::Decode`].
pub(crate) fn guard<T>(
    format: Format,
    f: impl FnOnce() -> Result<T, ImageError>,
) -> Result<T, ImageError> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(ImageError::decode(format, format!("decoder failed: {msg}")))
        }
    }
}

/// Read a big- or little-endian `f32` from 4 bytes.
pub(crate) fn f32_from(bytes: [u8; 4], little_endian: bool) -> f32 {
    if little_endian {
        f32::from_le_bytes(bytes)
    } else {
        f32::from_be_bytes(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn gradient() -> Image {
        Image::from_fn(24, 16, 3, |x, y, c| {
            (x as f32 / 23.0) * 0.5 + (y as f32 / 15.0) * 0.4 + c as f32 * 0.05
        })
    }

    #[test]
    fn format_from_path_sniff_and_extension_agree() {
        for f in Format::ALL {
            let p = PathBuf::from(format!("dir.x/frame.0001.{}", f.extension()));
            assert_eq!(Format::from_path(&p), Some(f));
            let bytes = encode(&gradient(), f).unwrap();
            assert_eq!(Format::sniff(&bytes), Some(f), "{f}");
        }
        assert_eq!(Format::from_path(Path::new("A.JPEG")), Some(Format::Jpeg));
        assert_eq!(Format::from_path(Path::new("a.Hdr")), Some(Format::Hdr));
        assert_eq!(Format::from_path(Path::new("a.TIFF")), Some(Format::Tiff));
        assert_eq!(Format::from_path(Path::new("a.bmp")), None);
        assert_eq!(Format::from_path(Path::new("exr")), None);
        assert_eq!(Format::sniff(b"Pf\n1 1\n-1\n"), Some(Format::Pfm));
        assert_eq!(Format::sniff(b"#?RGBE\n"), Some(Format::Hdr));
        assert_eq!(Format::sniff(b"PFX"), None);
        assert_eq!(Format::sniff(b""), None);
        assert_eq!(Format::sniff(&[0xFF, 0xD8]), None);
    }

    #[test]
    fn write_then_read_every_format_through_files() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        for f in Format::ALL {
            let path = dir.path().join(format!("out.{}", f.extension()));
            write_image(&path, &img).unwrap();
            let back = read_image(&path).unwrap();
            assert_eq!((back.width, back.height, back.channels), (24, 16, 3), "{f}");
            let tol = match f {
                Format::Exr | Format::Pfm => 0.0,
                Format::Hdr => 0.01,
                Format::Png => 0.005,
                Format::Jpeg => 0.03,
                // Half a 10-bit Cineon code at white (0.0078 a code there).
                Format::Dpx => 0.004,
                Format::Tiff => 0.0002,
            };
            let err = img.max_abs_diff(&back).unwrap();
            assert!(err <= tol, "{f}: error {err}");
            // Orientation: (0, 0) is the top-left, darkest pixel.
            assert!(
                back.get(0, 0, 0) < back.get(23, 0, 0) && back.get(0, 0, 0) < back.get(0, 15, 0)
            );
        }
        // Only the written files remain: no temporary files left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names.len(), Format::ALL.len(), "{names:?}");
    }

    #[test]
    fn write_replaces_existing_file_atomically() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.pfm");
        write_image(&path, &gradient()).unwrap();
        let other = Image::new(2, 2, 1);
        write_image(&path, &other).unwrap();
        assert_eq!(read_image(&path).unwrap(), other);
    }

    #[test]
    fn magic_bytes_win_over_a_wrong_extension() {
        let dir = tempfile::tempdir().unwrap();
        let exr_bytes = encode(&gradient(), Format::Exr).unwrap();
        let mislabelled = dir.path().join("really_exr.png");
        std::fs::write(&mislabelled, &exr_bytes).unwrap();
        assert_eq!(read_image(&mislabelled).unwrap(), gradient());
        let no_ext = dir.path().join("noext");
        std::fs::write(&no_ext, &exr_bytes).unwrap();
        assert_eq!(read_image(&no_ext).unwrap(), gradient());
    }

    #[test]
    fn errors_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        // Missing file.
        let missing = dir.path().join("missing.exr");
        let e = read_image(&missing).unwrap_err();
        assert!(matches!(e, ImageError::Io { .. }));
        assert!(e.to_string().contains("missing.exr"), "{e}");
        // Corrupt content.
        let bad = dir.path().join("bad.pfm");
        std::fs::write(&bad, b"PF\n2 2\n-1\n\x00\x01").unwrap();
        let e = read_image(&bad).unwrap_err();
        assert!(e.to_string().contains("bad.pfm"), "{e}");
        assert!(
            matches!(
                e.kind(),
                ImageError::Decode {
                    format: Format::Pfm,
                    ..
                }
            ),
            "{e:?}"
        );
        // Unknown extension and unknown content.
        let unknown = dir.path().join("notes.txt");
        std::fs::write(&unknown, b"hello").unwrap();
        let e = read_image(&unknown).unwrap_err();
        assert!(matches!(e.kind(), ImageError::UnsupportedFormat(_)));
        assert!(e.to_string().contains("notes.txt"), "{e}");
        // Writing: unknown extension, missing directory.
        let e = write_image(&dir.path().join("out.bmp"), &gradient()).unwrap_err();
        assert!(matches!(e.kind(), ImageError::UnsupportedFormat(_)));
        assert!(e.to_string().contains("out.bmp"), "{e}");
        let e = write_image(&dir.path().join("no/such/dir/out.png"), &gradient()).unwrap_err();
        assert!(matches!(e, ImageError::Io { .. }), "{e:?}");
        assert!(e.to_string().contains("no/such/dir"), "{e}");
        // Writing an image that no format can hold.
        let broken = Image {
            width: 3,
            height: 3,
            channels: 3,
            data: vec![0.0; 5],
        };
        let e = write_image(&dir.path().join("broken.exr"), &broken).unwrap_err();
        assert!(matches!(e.kind(), ImageError::Encode(_)), "{e:?}");
        assert!(!dir.path().join("broken.exr").exists());
    }

    #[test]
    fn truncated_files_of_every_format_are_errors_not_panics() {
        let img = Image::from_fn(33, 21, 4, |x, y, c| (x * y + c) as f32 * 0.01);
        for f in Format::ALL {
            let bytes = encode(&img, f).unwrap();
            for frac in [0.0, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9] {
                let len = (bytes.len() as f64 * frac) as usize;
                let r = decode(&bytes[..len], f);
                // JPEG decoders pad a cut entropy-coded scan (see png_jpeg's tests).
                if f != Format::Jpeg || frac < 0.1 {
                    assert!(r.is_err(), "{f} cut at {len} of {}", bytes.len());
                }
            }
            // Random-looking garbage behind each magic number.
            let mut junk = bytes[..4.min(bytes.len())].to_vec();
            junk.extend((0..500u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
            assert!(decode(&junk, f).is_err(), "{f} garbage");
        }
    }

    #[test]
    fn corrupted_bytes_never_panic() {
        // Deterministic byte corruption (a 64-bit LCG): every decode returns Ok or Err.
        let img = Image::from_fn(20, 12, 4, |x, y, c| (x + 2 * y + c) as f32 * 0.05);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        for f in Format::ALL {
            let bytes = encode(&img, f).unwrap();
            for _ in 0..300 {
                let mut b = bytes.clone();
                for _ in 0..1 + next() % 4 {
                    let i = next() % b.len();
                    b[i] = next() as u8;
                }
                let result = std::panic::catch_unwind(|| decode(&b, f).is_ok());
                assert!(result.is_ok(), "{f}: decoder panicked on corrupted input");
            }
        }
    }
}
