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
