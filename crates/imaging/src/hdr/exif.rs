//! Exposure settings from a photograph's EXIF metadata (book 10.2: an exposure stack needs the
//! relative exposure of each photograph; cameras record it in EXIF).
//!
//! The exposure a photograph integrates is proportional to `t · S / N²` (shutter time `t`,
//! sensitivity `S` = ISO, f-number `N`). [`relative_exposures`] turns a stack's settings into
//! times in seconds *at the first photograph's aperture and ISO*, so a stack bracketed by shutter
//! time alone keeps its times unchanged, and one bracketed by aperture or ISO gets equivalent
//! times. The EXIF parsing is the `kamadak-exif` crate's (JPEG, TIFF, PNG `eXIf`, HEIF, WebP).

use std::io::Cursor;
use std::path::{Path, PathBuf};

use ::exif::{In, Tag, Value};

use super::HdrError;

/// The exposure settings of one photograph as its EXIF records them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExposureSettings {
    /// `ExposureTime` in seconds.
    pub time: f64,
    /// `FNumber`, if recorded.
    pub f_number: Option<f64>,
    /// `PhotographicSensitivity` (ISO), if recorded.
    pub iso: Option<f64>,
}

/// A field's first value as a finite, positive number (any numeric EXIF type).
pub(crate) fn number(field: Option<&::exif::Field>) -> Option<f64> {
    let v = match &field?.value {
        Value::Rational(r) => r.first().map(|r| r.to_f64()),
        Value::SRational(r) => r.first().map(|r| r.to_f64()),
        Value::Short(v) => v.first().map(|&x| x as f64),
        Value::Long(v) => v.first().map(|&x| x as f64),
        Value::Float(v) => v.first().map(|&x| x as f64),
        Value::Double(v) => v.first().copied(),
        _ => None,
    }?;
    (v.is_finite() && v > 0.0).then_some(v)
}

/// Reads `ExposureTime`, `FNumber` and `PhotographicSensitivity` from an image file's bytes.
/// Errors: no EXIF block, or no usable (finite, positive) `ExposureTime`; `path` names the file.
pub fn exposure_settings(bytes: &[u8], path: &Path) -> Result<ExposureSettings, HdrError> {
    let no = |why: String| HdrError::Exif {
        path: path.to_path_buf(),
        message: why,
    };
    let exif = ::exif::Reader::new()
        .read_from_container(&mut Cursor::new(bytes))
        .map_err(|e| no(format!("no EXIF metadata ({e})")))?;
    let time = number(exif.get_field(Tag::ExposureTime, In::PRIMARY))
        .ok_or_else(|| no("EXIF has no positive ExposureTime".into()))?;
    Ok(ExposureSettings {
        time,
        f_number: number(exif.get_field(Tag::FNumber, In::PRIMARY)),
        iso: number(exif.get_field(Tag::PhotographicSensitivity, In::PRIMARY)),
    })
}

/// Reads the exposure settings of an image file (see [`exposure_settings`]).
pub fn read_exposure_settings(path: &Path) -> Result<ExposureSettings, HdrError> {
    let bytes = std::fs::read(path).map_err(|source| HdrError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    exposure_settings(&bytes, path)
}

/// Relative exposures `t · (S / S₀) · (N₀ / N)²`: seconds at the first photograph's f-number
/// `N₀` and ISO `S₀`. An f-number (or ISO) must be recorded in every photograph or in none (then
/// it is taken as constant); a mix is an error naming the first file without it.
pub fn relative_exposures(
    settings: &[ExposureSettings],
    paths: &[PathBuf],
) -> Result<Vec<f64>, HdrError> {
    let Some(first) = settings.first() else {
        return Err(HdrError::EmptyStack);
    };
    let check = |get: fn(&ExposureSettings) -> Option<f64>, name: &str| {
        let have = settings.iter().filter(|s| get(s).is_some()).count();
        if have != 0 && have != settings.len() {
            let i = settings.iter().position(|s| get(s).is_none()).unwrap_or(0);
            return Err(HdrError::Exif {
                path: paths.get(i).cloned().unwrap_or_default(),
                message: format!(
                    "EXIF has no {name} but other photographs of the stack do: cannot compare \
                     their exposures"
                ),
            });
        }
        Ok(())
    };
    check(|s| s.f_number, "FNumber")?;
    check(|s| s.iso, "ISO (PhotographicSensitivity)")?;
    Ok(settings
        .iter()
        .map(|s| {
            let iso = match (s.iso, first.iso) {
                (Some(a), Some(b)) => a / b,
                _ => 1.0,
            };
            let aperture = match (s.f_number, first.f_number) {
                (Some(n), Some(n0)) => (n0 / n) * (n0 / n),
                _ => 1.0,
            };
            s.time * iso * aperture
        })
        .collect())
}

/// The nearest fraction `num/den` to `v` with `den` a power of ten up to 10⁶ (or `1/n` for
/// short shutter times, as cameras write them).
fn rational(v: f64) -> ::exif::Rational {
    if v > 0.0 && v < 1.0 && (1.0 / v - (1.0 / v).round()).abs() < 1e-9 {
        return ::exif::Rational::from((1, (1.0 / v).round() as u32));
    }
    let mut den = 1u32;
    while den < 1_000_000 && (v * den as f64).fract().abs() > 1e-9 {
        den *= 10;
    }
    ::exif::Rational::from(((v * den as f64).round().min(u32::MAX as f64) as u32, den))
}

/// Returns `jpeg` with an EXIF block (APP1, right after SOI) recording `settings` — e.g. for a
/// simulated bracket (book 10.6) that [`read_exposure_settings`] can read back. Times are
/// written as exact fractions when they are `1/n` or have at most six decimals. Errors: `jpeg`
/// does not start with SOI, or the block is too large.
pub fn with_exposure_exif(jpeg: &[u8], settings: &ExposureSettings) -> Result<Vec<u8>, HdrError> {
    if !jpeg.starts_with(&[0xFF, 0xD8]) {
        return Err(HdrError::InvalidArgument(
            "EXIF can only be added to a JPEG (no SOI marker)".into(),
        ));
    }
    let field = |tag, value| ::exif::Field {
        tag,
        ifd_num: In::PRIMARY,
        value,
    };
    let mut fields = vec![field(
        Tag::ExposureTime,
        Value::Rational(vec![rational(settings.time)]),
    )];
    if let Some(n) = settings.f_number {
        fields.push(field(Tag::FNumber, Value::Rational(vec![rational(n)])));
    }
    if let Some(iso) = settings.iso {
        fields.push(field(
            Tag::PhotographicSensitivity,
            Value::Short(vec![iso.round().clamp(1.0, 65535.0) as u16]),
        ));
    }
    let mut writer = ::exif::experimental::Writer::new();
    for f in &fields {
        writer.push_field(f);
    }
    let mut tiff = Cursor::new(Vec::new());
    writer
        .write(&mut tiff, false)
        .map_err(|e| HdrError::InvalidArgument(format!("cannot encode EXIF: {e}")))?;
    let tiff = tiff.into_inner();
    let len = u16::try_from(2 + 6 + tiff.len())
        .map_err(|_| HdrError::InvalidArgument("EXIF block over 64 KiB".into()))?;
    let mut out = Vec::with_capacity(jpeg.len() + len as usize + 2);
    out.extend_from_slice(&jpeg[..2]);
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&len.to_be_bytes());
    out.extend_from_slice(b"Exif\0\0");
    out.extend_from_slice(&tiff);
    out.extend_from_slice(&jpeg[2..]);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(time: f64, f_number: Option<f64>, iso: Option<f64>) -> ExposureSettings {
        ExposureSettings {
            time,
            f_number,
            iso,
        }
    }

    #[test]
    fn relative_exposure_is_time_times_iso_over_n_squared() {
        let p = vec![PathBuf::from("a.jpg"), PathBuf::from("b.jpg")];
        // Half the shutter time, one stop more aperture (N / √2), twice the ISO: 4× in total.
        let s = [
            settings(0.5, Some(8.0), Some(100.0)),
            settings(0.25, Some(8.0 / 2f64.sqrt()), Some(200.0)),
        ];
        let e = relative_exposures(&s, &p).unwrap();
        assert_eq!(e[0], 0.5);
        assert!((e[1] - 1.0).abs() < 1e-12, "{}", e[1]);
        // Neither recorded: times as they are.
        let s = [settings(0.5, None, None), settings(2.0, None, None)];
        assert_eq!(relative_exposures(&s, &p).unwrap(), vec![0.5, 2.0]);
        // A mix cannot be compared.
        let s = [settings(0.5, Some(4.0), None), settings(2.0, None, None)];
        let e = relative_exposures(&s, &p).unwrap_err();
        assert!(e.to_string().contains("b.jpg") && e.to_string().contains("FNumber"));
    }

    #[test]
    fn exif_written_into_a_real_jpeg_reads_back() {
        let img = crate::Image::from_fn(8, 4, 3, |x, y, c| (x + y + c) as f32 / 16.0);
        let jpeg = crate::encode(&img, crate::Format::Jpeg).unwrap();
        assert!(exposure_settings(&jpeg, Path::new("a.jpg")).is_err());
        for s in [
            settings(1.0 / 250.0, Some(5.6), Some(400.0)),
            settings(2.5, None, None),
            settings(0.3, Some(11.0), None),
        ] {
            let tagged = with_exposure_exif(&jpeg, &s).unwrap();
            assert_eq!(exposure_settings(&tagged, Path::new("a.jpg")).unwrap(), s);
            // Still a JPEG whose pixels decode as before.
            let a = crate::decode(&jpeg, crate::Format::Jpeg).unwrap();
            assert_eq!(crate::decode(&tagged, crate::Format::Jpeg).unwrap(), a);
        }
        assert!(with_exposure_exif(b"\x89PNG", &settings(1.0, None, None)).is_err());
    }

    #[test]
    fn files_without_exif_are_named() {
        let e = exposure_settings(b"\xff\xd8\xff\xd9", Path::new("x.jpg")).unwrap_err();
        assert!(e.to_string().starts_with("x.jpg: no EXIF"), "{e}");
    }
}
