//! The focal length a camera recorded in a photograph's EXIF metadata (CIPA DC-008 "Exif
//! 2.32"), in pixels of the image as it is now: a start for the camera solve that needs no
//! calibration target (Hartley & Zisserman §19 use it the same way; COLMAP and Meshroom take
//! their prior focal from it).
//!
//! Two routes, the first that the file allows:
//! 1. `FocalLength` (mm) with `FocalPlaneXResolution` per `FocalPlaneResolutionUnit` (the
//!    sensor's pixel pitch, for the image the camera wrote: `PixelXDimension` wide) — exact when
//!    the camera records it: f_px = f_mm · resolution / unit_mm · width / PixelXDimension;
//! 2. `FocalLengthIn35mmFilm` — the focal length giving the same diagonal field of view on a
//!    36 × 24 mm frame: f_px = f₃₅ · √(w² + h²) / 43.27 (the phones' route; within the rounding
//!    of f₃₅ to whole millimetres and the diagonal convention's aspect assumption).
//!
//! The EXIF parsing is the `kamadak-exif` crate's (JPEG, TIFF, PNG `eXIf`, HEIF, WebP).

use std::io::Cursor;

use ::exif::{In, Tag};

use crate::hdr::exif::number;

/// The diagonal of a 36 × 24 mm frame.
const FULL_FRAME_DIAGONAL_MM: f64 = 43.266_615_305_567_87;

/// Where a focal length came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FocalSource {
    /// `FocalLength` and the focal plane's resolution.
    FocalPlane,
    /// `FocalLengthIn35mmFilm`.
    Equivalent35mm,
}

/// A focal length from metadata.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CameraFocal {
    /// In pixels of the image (`width` × `height` as given).
    pub pixels: f64,
    /// `FocalLength` in millimetres, when recorded.
    pub millimetres: Option<f64>,
    /// The route taken.
    pub source: FocalSource,
}

/// A 35 mm equivalent focal length `f35` (mm) in pixels of a `width` × `height` picture: the
/// same diagonal field of view, f_px = f₃₅ · √(w² + h²) / 43.27.
pub fn pixels_from_35mm(f35: f64, width: usize, height: usize) -> f64 {
    f35 * (width as f64).hypot(height as f64) / FULL_FRAME_DIAGONAL_MM
}

/// The focal length, in pixels of a `width` × `height` image, that the EXIF metadata of a file
/// (its bytes) records; `Err` says what is missing.
pub fn camera_focal(bytes: &[u8], width: usize, height: usize) -> Result<CameraFocal, String> {
    if width == 0 || height == 0 {
        return Err(format!("a {width}×{height} image"));
    }
    let exif = ::exif::Reader::new()
        .read_from_container(&mut Cursor::new(bytes))
        .map_err(|e| format!("no EXIF metadata ({e})"))?;
    let get = |tag| number(exif.get_field(tag, In::PRIMARY));
    let mm = get(Tag::FocalLength);
    let unit_mm = match get(Tag::FocalPlaneResolutionUnit).map(|u| u as u32) {
        Some(3) => Some(10.0),
        Some(4) => Some(1.0),
        Some(5) => Some(0.001),
        // 2 (inch) is the default when the unit is absent.
        Some(2) | None => Some(25.4),
        Some(_) => None,
    };
    if let (Some(f), Some(res), Some(unit)) = (mm, get(Tag::FocalPlaneXResolution), unit_mm) {
        // The resolution is of the image the camera wrote; a resized file scales it.
        let scale = get(Tag::PixelXDimension).map_or(1.0, |w0| width as f64 / w0);
        return Ok(CameraFocal {
            pixels: f * res / unit * scale,
            millimetres: Some(f),
            source: FocalSource::FocalPlane,
        });
    }
    if let Some(f35) = get(Tag::FocalLengthIn35mmFilm) {
        return Ok(CameraFocal {
            pixels: pixels_from_35mm(f35, width, height),
            millimetres: mm,
            source: FocalSource::Equivalent35mm,
        });
    }
    Err(match mm {
        Some(f) => format!(
            "EXIF has FocalLength ({f} mm) but neither the focal plane's resolution nor \
             FocalLengthIn35mmFilm, so not the sensor's size"
        ),
        None => "EXIF has no FocalLength, FocalPlaneXResolution or FocalLengthIn35mmFilm".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::exif::experimental::Writer;
    use ::exif::{Field, Rational, Value};

    /// A JPEG (SOI, an APP1 Exif segment holding `fields`, EOI): what the reader needs.
    fn jpeg_with(fields: &[Field]) -> Vec<u8> {
        let mut w = Writer::new();
        for f in fields {
            w.push_field(f);
        }
        let mut tiff = Cursor::new(Vec::new());
        w.write(&mut tiff, false).unwrap();
        let tiff = tiff.into_inner();
        let mut app1 = b"Exif\0\0".to_vec();
        app1.extend(&tiff);
        let mut out = vec![0xFF, 0xD8, 0xFF, 0xE1];
        out.extend(((app1.len() + 2) as u16).to_be_bytes());
        out.extend(app1);
        out.extend([0xFF, 0xD9]);
        out
    }

    fn rational(tag: Tag, v: f64) -> Field {
        Field {
            tag,
            ifd_num: In::PRIMARY,
            value: Value::Rational(vec![Rational::from(((v * 1000.0).round() as u32, 1000))]),
        }
    }

    fn short(tag: Tag, v: u16) -> Field {
        Field {
            tag,
            ifd_num: In::PRIMARY,
            value: Value::Short(vec![v]),
        }
    }

    #[test]
    fn the_focal_plane_route_gives_the_sensor_focal_in_pixels_of_the_resized_image() {
        // A 6000 px wide sensor 23.5 mm across (APS-C), a 35 mm lens: 8936.17 px at full size;
        // the file resized to 1500 px wide: a quarter of it.
        let res_per_cm = 6000.0 / 2.35;
        let bytes = jpeg_with(&[
            rational(Tag::FocalLength, 35.0),
            rational(Tag::FocalPlaneXResolution, res_per_cm),
            short(Tag::FocalPlaneResolutionUnit, 3),
            Field {
                tag: Tag::PixelXDimension,
                ifd_num: In::PRIMARY,
                value: Value::Long(vec![6000]),
            },
            short(Tag::FocalLengthIn35mmFilm, 52),
        ]);
        let f = camera_focal(&bytes, 1500, 1000).unwrap();
        assert_eq!(f.source, FocalSource::FocalPlane);
        let want = 35.0 * 6000.0 / 23.5 / 4.0;
        assert!((f.pixels - want).abs() < 1e-3 * want, "{f:?} vs {want}");
        assert_eq!(f.millimetres, Some(35.0));
    }

    #[test]
    fn the_35mm_equivalent_route_matches_the_field_of_view() {
        // A phone: 26 mm equivalent, 4:3 frame 4032 × 3024 (diagonal 5040 px).
        let bytes = jpeg_with(&[
            rational(Tag::FocalLength, 5.1),
            short(Tag::FocalLengthIn35mmFilm, 26),
        ]);
        let f = camera_focal(&bytes, 4032, 3024).unwrap();
        assert_eq!(f.source, FocalSource::Equivalent35mm);
        // The diagonal field of view is the 35 mm frame's at 26 mm.
        let fov = 2.0 * (FULL_FRAME_DIAGONAL_MM / 2.0 / 26.0).atan();
        let ours = 2.0 * (5040.0 / 2.0 / f.pixels).atan();
        assert!((fov - ours).abs() < 1e-9, "{fov} {ours}");
        assert!((f.pixels - 3028.6).abs() < 0.1, "{}", f.pixels);
    }

    #[test]
    fn missing_metadata_says_what_is_missing() {
        let e = camera_focal(&jpeg_with(&[rational(Tag::FocalLength, 5.1)]), 10, 10).unwrap_err();
        assert!(
            e.contains("5.1 mm") && e.contains("FocalLengthIn35mmFilm"),
            "{e}"
        );
        let e = camera_focal(&jpeg_with(&[short(Tag::Orientation, 1)]), 10, 10).unwrap_err();
        assert!(e.contains("no FocalLength"), "{e}");
        assert!(camera_focal(b"\xFF\xD8\xFF\xD9", 10, 10)
            .unwrap_err()
            .contains("no EXIF"));
    }
}
