//! Colour transfer functions: the sRGB curves of IEC 61966-2-1:1999 and Rec. 709 luminance.
//!
//! Everything inside vfxgraph is linear light; sRGB appears only when 8/16-bit files are read or
//! written (the book's convention; ARCHITECTURE.md, "Conventions").

use std::sync::OnceLock;

/// Rec. ITU-R BT.709 luminance weights for linear R, G, B (they sum to 1).
pub const REC709_LUMA: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// sRGB electro-optical decoding, IEC 61966-2-1: `v / 12.92` for `v <= 0.04045`, else
/// `((v + 0.055) / 1.055)^2.4`. Values outside [0, 1] are extended (linearly below 0, by the power
/// law above 1); NaN stays NaN.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB encoding, the inverse of [`srgb_to_linear`] (IEC 61966-2-1): `12.92 v` for
/// `v <= 0.0031308`, else `1.055 v^(1/2.4) - 0.055`. NaN stays NaN.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Entries of [`SrgbEncoder`]'s table (over √v, so the steep start is sampled finely).
const ENCODE_TABLE: usize = 1024;

/// [`linear_to_srgb`] on [0, 1] by a table: within 5·10⁻⁷ of the power function, by linear
/// interpolation in a table over √v, several times faster — for the hot loops that encode whole
/// frames (the tracker's gray frames: 1.3·10⁻⁴ of a gray level). Get it once
/// ([`SrgbEncoder::get`]) and call [`SrgbEncoder::encode`] per pixel.
pub struct SrgbEncoder([f32; ENCODE_TABLE + 1]);

impl SrgbEncoder {
    /// The shared table (built on first use).
    pub fn get() -> &'static SrgbEncoder {
        static TABLE: OnceLock<SrgbEncoder> = OnceLock::new();
        TABLE.get_or_init(|| {
            SrgbEncoder(std::array::from_fn(|i| {
                // The power piece everywhere (the table is read above the linear piece only),
                // so no interval straddles the curve's kink.
                let u = i as f64 / ENCODE_TABLE as f64;
                (1.055 * (u * u).powf(1.0 / 2.4) - 0.055) as f32
            }))
        })
    }

    /// The sRGB encoding of `v` clamped to [0, 1]; NaN gives 0.
    #[inline]
    pub fn encode(&self, v: f32) -> f32 {
        let v = sanitize_unit(v);
        if v <= 0.003_130_8 {
            return v * 12.92;
        }
        let x = v.sqrt() * ENCODE_TABLE as f32;
        let i = (x as usize).min(ENCODE_TABLE - 1);
        let t = x - i as f32;
        let table = &self.0;
        table[i] + t * (table[i + 1] - table[i])
    }
}

/// Linear value → 8-bit sRGB code, clamped to [0, 255] with NaN → 0 (rounding to nearest).
pub fn linear_to_srgb8(v: f32) -> u8 {
    quantize(linear_to_srgb(sanitize_unit(v)), 255.0) as u8
}

/// Linear value → 16-bit sRGB code, clamped to [0, 65535] with NaN → 0 (rounding to nearest).
pub fn linear_to_srgb16(v: f32) -> u16 {
    quantize(linear_to_srgb(sanitize_unit(v)), 65535.0) as u16
}

/// 8-bit sRGB code → linear value (table lookup of [`srgb_to_linear`]).
pub fn srgb8_to_linear(code: u8) -> f32 {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))[code as usize]
}

/// 16-bit sRGB code → linear value.
pub fn srgb16_to_linear(code: u16) -> f32 {
    srgb_to_linear(code as f32 / 65535.0)
}

/// Linear value (an alpha, not curve-encoded) → 8-bit code, clamped, NaN → 0.
pub fn unit_to_u8(v: f32) -> u8 {
    quantize(sanitize_unit(v), 255.0) as u8
}

/// Linear value (an alpha, not curve-encoded) → 16-bit code, clamped, NaN → 0.
pub fn unit_to_u16(v: f32) -> u16 {
    quantize(sanitize_unit(v), 65535.0) as u16
}

/// Rec. 709 luminance `0.2126 R + 0.7152 G + 0.0722 B` of linear RGB.
pub fn luminance(r: f32, g: f32, b: f32) -> f32 {
    REC709_LUMA[0] * r + REC709_LUMA[1] * g + REC709_LUMA[2] * b
}

/// Clamp to [0, 1], mapping NaN to 0.
fn sanitize_unit(v: f32) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, 1.0)
    }
}

fn quantize(v01: f32, max: f32) -> f32 {
    (v01 * max + 0.5).floor().clamp(0.0, max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_known_points() {
        // At the breakpoint both pieces agree: 0.04045 / 12.92 = 0.0031308...
        assert!((srgb_to_linear(0.04045) - 0.003_130_8).abs() < 1e-7);
        // 0.5 sRGB is 0.21404 linear (((0.5 + 0.055) / 1.055)^2.4).
        assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-6);
        assert_eq!(srgb_to_linear(1.0), 1.0);
        assert_eq!(srgb_to_linear(0.0), 0.0);
        // Inverse direction at the same points.
        assert!((linear_to_srgb(0.003_130_8) - 0.04045).abs() < 1e-6);
        assert!((linear_to_srgb(0.214_041_14) - 0.5).abs() < 1e-6);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        // 18% grey encodes to about 0.4614.
        assert!((linear_to_srgb(0.18) - 0.461_356).abs() < 1e-5);
    }

    /// The table encoding is the power function's within 1e-6 over [0, 1] (dense sweep,
    /// both sides of the linear segment's end), clamps outside and maps NaN to 0.
    #[test]
    fn table_encoding_matches_the_curve() {
        let enc = SrgbEncoder::get();
        let mut worst = 0.0f32;
        for i in 0..=200_000 {
            let v = i as f32 / 200_000.0;
            worst = worst.max((enc.encode(v) - linear_to_srgb(v)).abs());
        }
        for v in [0.003_130_7f32, 0.003_130_8, 0.003_131, 1e-7, 0.999_999] {
            worst = worst.max((enc.encode(v) - linear_to_srgb(v)).abs());
        }
        assert!(worst < 1e-6, "worst {worst}");
        assert_eq!(enc.encode(-0.5), 0.0);
        assert!((enc.encode(7.0) - 1.0).abs() < 1e-6);
        assert_eq!(enc.encode(f32::NAN), 0.0);
    }

    #[test]
    fn srgb_inverse_everywhere() {
        for i in 0..=1000 {
            let v = i as f32 / 1000.0;
            assert!(
                (linear_to_srgb(srgb_to_linear(v)) - v).abs() < 2e-6,
                "v = {v}"
            );
            assert!(
                (srgb_to_linear(linear_to_srgb(v)) - v).abs() < 2e-6,
                "v = {v}"
            );
        }
        // The curve is continuous at the breakpoints.
        let below = srgb_to_linear(0.04045 - 1e-6);
        let above = srgb_to_linear(0.04045 + 1e-6);
        assert!((above - below).abs() < 1e-6);
    }

    #[test]
    fn quantization_clamps_and_maps_nan_to_zero() {
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(f32::INFINITY), 255);
        assert_eq!(linear_to_srgb16(1.0), 65535);
        assert_eq!(unit_to_u8(0.5), 128);
        assert_eq!(unit_to_u16(f32::NAN), 0);
        for code in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(code)), code);
        }
        for code in (0..=65535u16).step_by(97) {
            assert_eq!(linear_to_srgb16(srgb16_to_linear(code)), code);
        }
    }

    #[test]
    fn luminance_of_white_is_one() {
        assert!((luminance(1.0, 1.0, 1.0) - 1.0).abs() < 1e-6);
        assert!((luminance(0.0, 1.0, 0.0) - 0.7152).abs() < 1e-7);
    }
}
