//! Exposure stacks: bracketed photographs of one static scene with their exposure times
//! (book 10.1–10.2; Debevec & Malik 1997, §2).
//!
//! Response recovery needs the *codes* the camera wrote, not linear light: [`read_codes`] reads
//! an 8-bit PNG or JPEG without the sRGB decoding that [`crate::read_image`] applies (16-bit files
//! are reduced to 8 bits by the `image` crate's rounding, `v16 · 255 / 65535`; alpha is dropped,
//! gray stays one channel).

use std::path::{Path, PathBuf};

use image::DynamicImage;
use rayon::prelude::*;

use super::HdrError;
use crate::error::ImageError;
use crate::io::Format;

/// One photograph of a stack: its exposure time and its interleaved 8-bit codes
/// (`width × height × channels`, rows from the top) — `Z_ij` and `Δt_j` of Debevec & Malik 1997.
#[derive(Clone, Debug, PartialEq)]
pub struct Exposure {
    /// Exposure time Δt in seconds (finite, positive). Only ratios matter, so any unit that is
    /// proportional to the exposure (e.g. including aperture and ISO) works.
    pub time: f64,
    /// The codes, `width × height × channels` bytes.
    pub codes: Vec<u8>,
}

/// A validated exposure stack (book 10.2): every exposure has the same size and channel count,
/// times are finite, positive and distinct, and an optional per-pixel mask marks pixels that
/// response recovery must not sample.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureStack {
    width: usize,
    height: usize,
    channels: usize,
    exposures: Vec<Exposure>,
    mask: Option<Vec<bool>>,
}

impl ExposureStack {
    /// Builds and validates a stack (book 10.2). Errors: [`HdrError::EmptyStack`],
    /// [`HdrError::SizeMismatch`] (a code buffer of the wrong length),
    /// [`HdrError::InvalidTime`], [`HdrError::DuplicateExposure`], and
    /// [`HdrError::InvalidArgument`] for a zero size or a channel count outside 1–4.
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        exposures: Vec<Exposure>,
    ) -> Result<ExposureStack, HdrError> {
        if exposures.is_empty() {
            return Err(HdrError::EmptyStack);
        }
        if width == 0 || height == 0 || !(1..=4).contains(&channels) {
            return Err(HdrError::InvalidArgument(format!(
                "stack size {width}x{height}x{channels}: need a non-empty image with 1-4 channels"
            )));
        }
        let n = width
            .checked_mul(height)
            .and_then(|p| p.checked_mul(channels))
            .ok_or_else(|| HdrError::InvalidArgument("stack size overflows".into()))?;
        for (index, e) in exposures.iter().enumerate() {
            if e.codes.len() != n {
                return Err(HdrError::SizeMismatch {
                    index,
                    expected: format!("{width}x{height}x{channels} ({n} codes)"),
                    found: format!("{} codes", e.codes.len()),
                });
            }
            if !(e.time.is_finite() && e.time > 0.0) {
                return Err(HdrError::InvalidTime {
                    index,
                    time: e.time,
                });
            }
            if let Some(first) = exposures[..index].iter().position(|o| o.time == e.time) {
                return Err(HdrError::DuplicateExposure {
                    first,
                    second: index,
                    time: e.time,
                });
            }
        }
        Ok(ExposureStack {
            width,
            height,
            channels,
            exposures,
            mask: None,
        })
    }

    /// Builds a stack from decoded code images, checking that they agree in size
    /// ([`HdrError::SizeMismatch`] names the first one that does not).
    pub fn from_code_images(images: Vec<(CodeImage, f64)>) -> Result<ExposureStack, HdrError> {
        let Some((first, _)) = images.first() else {
            return Err(HdrError::EmptyStack);
        };
        let (w, h, c) = (first.width, first.height, first.channels);
        for (index, (img, _)) in images.iter().enumerate() {
            if (img.width, img.height, img.channels) != (w, h, c) {
                return Err(HdrError::SizeMismatch {
                    index,
                    expected: format!("{w}x{h}x{c}"),
                    found: format!("{}x{}x{}", img.width, img.height, img.channels),
                });
            }
        }
        let exposures = images
            .into_iter()
            .map(|(img, time)| Exposure {
                time,
                codes: img.codes,
            })
            .collect();
        ExposureStack::new(w, h, c, exposures)
    }

    /// Sets the mask of ignored pixels (`true` = ignore), `width × height` entries, row-major.
    pub fn with_mask(mut self, mask: Vec<bool>) -> Result<ExposureStack, HdrError> {
        if mask.len() != self.width * self.height {
            return Err(HdrError::InvalidArgument(format!(
                "mask has {} entries, the stack has {} pixels",
                mask.len(),
                self.width * self.height
            )));
        }
        self.mask = Some(mask);
        Ok(self)
    }

    /// Adds to the mask every pixel whose codes equal `code` (one value per channel) in at
    /// least one exposure, and returns how many pixels are masked in all. The Memorial stack
    /// marks its shifted borders with pure blue `(0, 0, 255)`.
    pub fn mask_code(&mut self, code: &[u8]) -> Result<usize, HdrError> {
        if code.len() != self.channels {
            return Err(HdrError::InvalidArgument(format!(
                "mask colour has {} values, the stack has {} channels",
                code.len(),
                self.channels
            )));
        }
        let c = self.channels;
        let mut mask = self
            .mask
            .take()
            .unwrap_or_else(|| vec![false; self.width * self.height]);
        for e in &self.exposures {
            for (m, px) in mask.iter_mut().zip(e.codes.chunks_exact(c)) {
                *m |= px == code;
            }
        }
        let n = mask.iter().filter(|&&m| m).count();
        self.mask = Some(mask);
        Ok(n)
    }

    /// Columns.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Channels per pixel (1–4; response recovery treats each independently).
    pub fn channels(&self) -> usize {
        self.channels
    }
    /// Pixels per exposure.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }
    /// The exposures, in the order given.
    pub fn exposures(&self) -> &[Exposure] {
        &self.exposures
    }
    /// Number of exposures.
    pub fn len(&self) -> usize {
        self.exposures.len()
    }
    /// Always false: a stack holds at least one exposure.
    pub fn is_empty(&self) -> bool {
        self.exposures.is_empty()
    }
    /// The mask of ignored pixels (`true` = ignore), if any.
    pub fn mask(&self) -> Option<&[bool]> {
        self.mask.as_deref()
    }
    /// Whether pixel `p` (row-major index) is masked.
    pub fn is_masked(&self, p: usize) -> bool {
        self.mask.as_ref().is_some_and(|m| m[p])
    }
    /// Number of distinct exposure times (equal to [`ExposureStack::len`]: times are distinct).
    pub fn distinct_times(&self) -> usize {
        self.exposures.len()
    }
}

/// How a stack read from `paths` is timed, and which pixels it ignores (the `list` and `paths`
/// themselves are file names a caller resolves).
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
#[param(check)]
pub struct StackOptions {
    /// exposure time in seconds of each of `paths`; [] = read EXIF
    pub times: Vec<f64>,
    /// codes (one per channel, 0-255) marking pixels to ignore in calibration, e.g. [0, 0, 255] for the Memorial stack's blue borders; [] for none
    pub mask_color: Vec<f64>,
}

impl StackOptions {
    /// Every time is a positive number of seconds; every mask code an integer in 0–255.
    pub fn check(&self) -> Result<(), String> {
        if let Some(i) = self.times.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
            return Err(format!(
                "param `times`: value {} ({}) is not a positive number of seconds",
                i + 1,
                self.times[i]
            ));
        }
        if self
            .mask_color
            .iter()
            .any(|v| !(0.0..=255.0).contains(v) || v.fract() != 0.0)
        {
            return Err("param `mask_color`: values must be integers in 0-255".into());
        }
        Ok(())
    }

    /// Masks the pixels of `stack` that have `mask_color` (nothing when it is empty).
    pub fn apply_mask(&self, stack: &mut ExposureStack) -> Result<(), HdrError> {
        if !self.mask_color.is_empty() {
            let code: Vec<u8> = self.mask_color.iter().map(|&v| v as u8).collect();
            stack.mask_code(&code)?;
        }
        Ok(())
    }
}

/// An 8-bit image as the camera stored it: interleaved codes, no transfer function applied.
#[derive(Clone, Debug, PartialEq)]
pub struct CodeImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// 1 (gray) or 3 (RGB).
    pub channels: usize,
    /// `width × height × channels` codes, rows from the top.
    pub codes: Vec<u8>,
}

/// Decodes PNG or JPEG bytes to raw 8-bit codes (book 10.2: response recovery works on the
/// pixel values `Z`, not on linear light). Gray stays 1 channel; everything else becomes RGB
/// (alpha dropped); 16-bit samples are rounded to 8 bits.
pub fn decode_codes(bytes: &[u8]) -> Result<CodeImage, HdrError> {
    let format = match Format::sniff(bytes) {
        Some(f @ (Format::Png | Format::Jpeg)) => f,
        other => {
            return Err(ImageError::UnsupportedFormat(format!(
                "exposure stacks need 8-bit PNG or JPEG photographs, found {}",
                other.map_or("an unknown format".to_string(), |f| f.to_string())
            ))
            .into())
        }
    };
    let dynamic = crate::io::png_jpeg::checked_reader(bytes, format)?
        .decode()
        .map_err(|e| ImageError::UnsupportedFormat(format!("cannot decode: {e}")))?;
    let (width, height) = (dynamic.width() as usize, dynamic.height() as usize);
    let (channels, codes) = match dynamic {
        DynamicImage::ImageLuma8(b) => (1, b.into_raw()),
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageLumaA16(_) => (1, dynamic.to_luma8().into_raw()),
        DynamicImage::ImageRgb8(b) => (3, b.into_raw()),
        other => (3, other.to_rgb8().into_raw()),
    };
    Ok(CodeImage {
        width,
        height,
        channels,
        codes,
    })
}

/// Reads a PNG or JPEG file's raw 8-bit codes (see [`decode_codes`]); errors name the file.
pub fn read_codes(path: &Path) -> Result<CodeImage, HdrError> {
    let bytes = std::fs::read(path).map_err(|source| HdrError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    decode_codes(&bytes).map_err(|e| match e {
        HdrError::Image(ie) => HdrError::Image(ImageError::File {
            path: path.to_path_buf(),
            source: Box::new(ie),
        }),
        other => other,
    })
}

/// One line of an exposure list file: a file name (relative to the list) and its time.
#[derive(Clone, Debug, PartialEq)]
pub struct ListEntry {
    /// The file name as written.
    pub file: String,
    /// Exposure time in seconds.
    pub seconds: f64,
    /// 1-based line number in the list file.
    pub line: usize,
}

/// Parses an exposure time: a decimal (`0.25`, `32`, `1e-3`) or a fraction (`1/1024`).
/// Returns `None` for anything else, including zero, negative, infinite or NaN times.
pub fn parse_seconds(text: &str) -> Option<f64> {
    let v = match text.split_once('/') {
        Some((a, b)) => a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?,
        None => text.trim().parse::<f64>().ok()?,
    };
    (v.is_finite() && v > 0.0).then_some(v)
}

/// Parses an exposure list in the format of Debevec's `memorial.hdr_image_list.txt` (book 10.2):
/// blank lines and lines starting with `#` are ignored; the first other line is the number of
/// images; then one `file seconds` line per image (seconds as in [`parse_seconds`]). Errors carry
/// the 1-based line number and a message.
pub fn parse_exposure_list(text: &str) -> Result<Vec<ListEntry>, (usize, String)> {
    let mut count: Option<usize> = None;
    let mut entries = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let Some(n) = count else {
            let n = t
                .parse::<usize>()
                .map_err(|_| (line, format!("expected the number of images, found `{t}`")))?;
            if n == 0 {
                return Err((line, "the list declares 0 images".into()));
            }
            count = Some(n);
            continue;
        };
        let mut parts = t.split_whitespace();
        let (Some(file), Some(secs), None) = (parts.next(), parts.next(), parts.next()) else {
            return Err((line, format!("expected `file seconds`, found `{t}`")));
        };
        let seconds = parse_seconds(secs).ok_or_else(|| {
            (
                line,
                format!("`{secs}` is not a positive time in seconds (e.g. 0.5 or 1/2)"),
            )
        })?;
        if entries.len() == n {
            return Err((line, format!("more than the declared {n} images")));
        }
        entries.push(ListEntry {
            file: file.to_string(),
            seconds,
            line,
        });
    }
    match count {
        None => Err((text.lines().count().max(1), "the list is empty".into())),
        Some(n) if entries.len() != n => Err((
            text.lines().count().max(1),
            format!("the list declares {n} images but names {}", entries.len()),
        )),
        Some(_) => Ok(entries),
    }
}

/// Where a listed file is: the name relative to the list's folder; if that file does not exist
/// and the name's extension is one this crate cannot read (Debevec's lists name `.ppm` files),
/// the first existing sibling with the same stem and a `.png`, `.jpg` or `.jpeg` extension.
fn resolve_listed(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    if p.exists() {
        return p;
    }
    for ext in ["png", "jpg", "jpeg", "PNG", "JPG", "JPEG"] {
        let q = p.with_extension(ext);
        if q.exists() {
            return q;
        }
    }
    p
}

/// Reads the stack named by an exposure list file (see [`parse_exposure_list`]); file names are
/// relative to the list's folder (with the `.ppm` → `.png`/`.jpg` fallback described at
/// `resolve_listed`). Images are decoded in parallel. Returns the stack and the paths read.
pub fn read_exposure_list(list: &Path) -> Result<(ExposureStack, Vec<PathBuf>), HdrError> {
    let (paths, times) = exposure_list_files(list)?;
    let stack = read_exposure_files(&paths, &times)?;
    Ok((stack, paths))
}

/// The image paths (resolved as [`read_exposure_list`] does) and times of an exposure list
/// file, without reading the images — e.g. to declare them as inputs before reading.
pub fn exposure_list_files(list: &Path) -> Result<(Vec<PathBuf>, Vec<f64>), HdrError> {
    let text = std::fs::read_to_string(list).map_err(|source| HdrError::Io {
        path: list.to_path_buf(),
        source,
    })?;
    let entries = parse_exposure_list(&text).map_err(|(line, message)| HdrError::ListSyntax {
        path: list.to_path_buf(),
        line,
        message,
    })?;
    let dir = list.parent().unwrap_or(Path::new("."));
    let paths: Vec<PathBuf> = entries
        .iter()
        .map(|e| resolve_listed(dir, &e.file))
        .collect();
    let times: Vec<f64> = entries.iter().map(|e| e.seconds).collect();
    Ok((paths, times))
}

/// Reads a stack from explicit image paths and exposure times in seconds (book 10.2), decoding
/// the files in parallel; the lengths must agree.
pub fn read_exposure_files(paths: &[PathBuf], times: &[f64]) -> Result<ExposureStack, HdrError> {
    if paths.len() != times.len() {
        return Err(HdrError::InvalidArgument(format!(
            "{} image paths but {} exposure times",
            paths.len(),
            times.len()
        )));
    }
    if paths.is_empty() {
        return Err(HdrError::EmptyStack);
    }
    let images = paths
        .par_iter()
        .map(|p| read_codes(p))
        .collect::<Result<Vec<_>, _>>()?;
    ExposureStack::from_code_images(images.into_iter().zip(times.iter().copied()).collect())
}

/// Reads a stack from image paths alone, taking each exposure from the file's EXIF
/// (`ExposureTime`, with `FNumber` and ISO when recorded; see [`super::exif::relative_exposures`]:
/// seconds at the first photograph's aperture and ISO). Each file is read once. Returns the
/// stack and the times used. Errors name the file without usable EXIF.
pub fn read_exposure_files_exif(paths: &[PathBuf]) -> Result<(ExposureStack, Vec<f64>), HdrError> {
    if paths.is_empty() {
        return Err(HdrError::EmptyStack);
    }
    let read = paths
        .par_iter()
        .map(|p| {
            let bytes = std::fs::read(p).map_err(|source| HdrError::Io {
                path: p.clone(),
                source,
            })?;
            let settings = super::exif::exposure_settings(&bytes, p)?;
            let codes = decode_codes(&bytes).map_err(|e| match e {
                HdrError::Image(ie) => HdrError::Image(ImageError::File {
                    path: p.clone(),
                    source: Box::new(ie),
                }),
                other => other,
            })?;
            Ok((codes, settings))
        })
        .collect::<Result<Vec<_>, HdrError>>()?;
    let settings: Vec<_> = read.iter().map(|(_, s)| *s).collect();
    let times = super::exif::relative_exposures(&settings, paths)?;
    let stack = ExposureStack::from_code_images(
        read.into_iter()
            .map(|(c, _)| c)
            .zip(times.iter().copied())
            .collect(),
    )?;
    Ok((stack, times))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exp(time: f64, codes: Vec<u8>) -> Exposure {
        Exposure { time, codes }
    }

    #[test]
    fn validation_rejects_bad_stacks() {
        assert!(matches!(
            ExposureStack::new(2, 1, 1, vec![]),
            Err(HdrError::EmptyStack)
        ));
        assert!(matches!(
            ExposureStack::new(2, 1, 1, vec![exp(1.0, vec![1, 2]), exp(2.0, vec![1])]),
            Err(HdrError::SizeMismatch { index: 1, .. })
        ));
        for t in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                ExposureStack::new(1, 1, 1, vec![exp(t, vec![1])]),
                Err(HdrError::InvalidTime { index: 0, .. })
            ));
        }
        assert!(matches!(
            ExposureStack::new(1, 1, 1, vec![exp(0.5, vec![1]), exp(0.5, vec![2])]),
            Err(HdrError::DuplicateExposure {
                first: 0,
                second: 1,
                ..
            })
        ));
        assert!(ExposureStack::new(0, 1, 1, vec![exp(1.0, vec![])]).is_err());
        let s = ExposureStack::new(2, 1, 1, vec![exp(1.0, vec![1, 2]), exp(2.0, vec![3, 4])]);
        assert!(s.unwrap().with_mask(vec![true]).is_err());
    }

    #[test]
    fn mask_code_marks_pixels_of_that_colour_in_any_exposure() {
        let mut s = ExposureStack::new(
            3,
            1,
            3,
            vec![
                exp(1.0, vec![0, 0, 255, 1, 2, 3, 9, 9, 9]),
                exp(2.0, vec![5, 5, 5, 0, 0, 255, 9, 9, 9]),
            ],
        )
        .unwrap();
        assert_eq!(s.mask_code(&[0, 0, 255]).unwrap(), 2);
        assert_eq!(s.mask().unwrap(), &[true, true, false]);
        assert!(s.mask_code(&[0, 0]).is_err());
    }

    #[test]
    fn list_files_parse_with_comments_fractions_and_errors() {
        let text = "# comment\n3\n# The format\n\na.ppm 32\nb.ppm 1/2\n  c.png   0.25 \n";
        let e = parse_exposure_list(text).unwrap();
        assert_eq!(e.len(), 3);
        assert_eq!(
            (e[1].file.as_str(), e[1].seconds, e[1].line),
            ("b.ppm", 0.5, 6)
        );
        assert_eq!(e[2].seconds, 0.25);
        assert_eq!(parse_exposure_list("2\na 1\n").unwrap_err().0, 2);
        assert_eq!(parse_exposure_list("x\n").unwrap_err().0, 1);
        assert_eq!(parse_exposure_list("1\na 1/0\n").unwrap_err().0, 2);
        assert_eq!(parse_exposure_list("1\na -1\n").unwrap_err().0, 2);
        assert_eq!(parse_exposure_list("1\na 1 extra\n").unwrap_err().0, 2);
        assert_eq!(parse_exposure_list("1\na 1\nb 2\n").unwrap_err().0, 3);
        assert!(parse_exposure_list("# only comments\n").is_err());
        assert!(parse_exposure_list("").is_err());
        assert_eq!(parse_seconds("1/1024"), Some(1.0 / 1024.0));
        assert_eq!(parse_seconds("nan"), None);
    }

    #[test]
    fn codes_are_read_raw_not_srgb_decoded() {
        let dir = tempfile::tempdir().unwrap();
        let codes: Vec<u8> = (0..=255u8).flat_map(|v| [v, 255 - v, v / 2]).collect();
        let buf = image::RgbImage::from_raw(16, 16, codes.clone()).unwrap();
        let path = dir.path().join("a.png");
        buf.save(&path).unwrap();
        let img = read_codes(&path).unwrap();
        assert_eq!((img.width, img.height, img.channels), (16, 16, 3));
        assert_eq!(img.codes, codes);
        // A list naming .ppm files finds the .png beside it; a missing file names itself.
        std::fs::write(dir.path().join("list.txt"), "2\na.ppm 1\nmissing.ppm 1/2\n").unwrap();
        let e = read_exposure_list(&dir.path().join("list.txt")).unwrap_err();
        assert!(e.to_string().contains("missing.ppm"), "{e}");
        let buf2 = image::GrayImage::from_raw(16, 16, vec![7; 256]).unwrap();
        buf2.save(dir.path().join("missing.png")).unwrap();
        let e = read_exposure_list(&dir.path().join("list.txt")).unwrap_err();
        assert!(matches!(e, HdrError::SizeMismatch { index: 1, .. }), "{e}");
        std::fs::write(dir.path().join("bad.png"), b"\x89PNG\r\n\x1a\nnope").unwrap();
        assert!(read_codes(&dir.path().join("bad.png")).is_err());
    }
}
