//! Exposure and display tone mapping (the book's chapter on HDR imaging and image-based lighting
//! ends with showing radiance maps on a display; Reinhard et al. 2002 for the operator).

use crate::color;
use crate::image::Image;

/// Largest value fed to a tone curve: non-finite and huge inputs are clamped here so that
/// luminance sums cannot overflow to ∞ (see [`tonemap`]).
const LARGE: f32 = 1e30;

/// Photographic exposure: multiply the colour channels by `2^stops` (alpha untouched).
/// `+1` doubles, `-1` halves. NaN and infinite samples stay as they are (and a non-finite
/// `stops` gives non-finite samples: validate parameters before calling).
pub fn exposure(img: &Image, stops: f32) -> Image {
    let k = stops.exp2();
    img.map_color(|v| v * k)
}

/// A display tone-mapping operator (serialised in lowercase: `"srgb"`, `"reinhard"`).
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Hash,
    Default,
    serde::Serialize,
    serde::Deserialize,
    vfxgraph_params::Choice,
)]
#[serde(rename_all = "lowercase")]
pub enum Operator {
    /// Clip to [0, 1]: what an sRGB display shows of a linear image (the sRGB curve itself is
    /// applied by the 8/16-bit encoders, IEC 61966-2-1).
    #[default]
    Srgb,
    /// The global "simple" operator of Reinhard, Stark, Shirley & Ferwerda, *Photographic Tone
    /// Reproduction for Digital Images*, SIGGRAPH 2002, eq. 3: `L_d = L / (1 + L)` applied to the
    /// Rec. 709 luminance `L`, each colour channel scaled by `L_d / L = 1 / (1 + L)` so chroma
    /// (the ratios R:G:B) is preserved. The paper's key scaling `a / L̄_w` (eq. 2) is not
    /// automatic here: the `exposure_stops` of [`tonemap`] plays its role.
    Reinhard,
}

impl Operator {
    /// The lowercase name used in graph files.
    pub fn name(self) -> &'static str {
        match self {
            Operator::Srgb => "srgb",
            Operator::Reinhard => "reinhard",
        }
    }
}

impl std::fmt::Display for Operator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Operator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "srgb" => Ok(Operator::Srgb),
            "reinhard" => Ok(Operator::Reinhard),
            other => Err(format!(
                "unknown tone-mapping operator {other:?} (expected srgb or reinhard)"
            )),
        }
    }
}

/// Tone map a linear HDR image for display: apply `exposure_stops` (as [`exposure`]), then `op`.
///
/// The result is still **linear light**, every sample in [0, 1] and finite, ready for an sRGB
/// encoder ([`crate::io::encode`] to PNG/JPEG). Non-finite input is made finite first: NaN → 0,
/// +∞ → a very large value (so it maps to white), negative values and −∞ → 0 (a display emits no
/// negative light). A non-finite `exposure_stops` is treated as 0. Alpha is not exposed or tone
/// mapped, only clamped to [0, 1] (NaN → 0).
pub fn tonemap(img: &Image, op: Operator, exposure_stops: f32) -> Image {
    let k = if exposure_stops.is_finite() {
        exposure_stops.exp2()
    } else {
        1.0
    };
    let cc = img.color_channels();
    let mut out = img.clone();
    out.for_each_pixel_mut(|px| {
        let (color, alpha) = px.split_at_mut(cc.min(px.len()));
        for v in color.iter_mut() {
            *v = sanitize(*v * k);
        }
        match op {
            Operator::Srgb => {}
            Operator::Reinhard => {
                let l = if color.len() == 3 {
                    color::luminance(color[0], color[1], color[2])
                } else {
                    color[0]
                };
                let s = 1.0 / (1.0 + l);
                for v in color.iter_mut() {
                    *v *= s;
                }
            }
        }
        // Saturated colours can leave a channel above 1 after the luminance scaling: clip.
        for v in color.iter_mut() {
            *v = v.clamp(0.0, 1.0);
        }
        for a in alpha.iter_mut() {
            *a = if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) };
        }
    });
    out
}

fn sanitize(v: f32) -> f32 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(0.0, LARGE)
    }
}

/// The `exposure` node's options.
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct ExposureOptions {
    /// exposure change in stops
    #[param(range = -64.0..=64.0)]
    pub stops: f64,
}

/// The `tonemap` node's options.
#[derive(Clone, Debug, Default, PartialEq, vfxgraph_params::Options)]
pub struct TonemapOptions {
    /// tone curve
    pub operator: Operator,
    /// exposure in stops applied before the curve
    #[param(range = -64.0..=64.0)]
    pub exposure: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exposure_doubles_per_stop_and_keeps_alpha() {
        let img = Image::from_vec(2, 1, 4, vec![0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 3.0, 1.0]).unwrap();
        let up = exposure(&img, 1.0);
        assert_eq!(up.data, vec![0.2, 0.4, 0.6, 0.5, 2.0, 4.0, 6.0, 1.0]);
        let down2 = exposure(&img, -2.0);
        assert_eq!(down2.get(1, 0, 2), 0.75);
        assert_eq!(down2.get(0, 0, 3), 0.5);
        assert_eq!(exposure(&img, 0.0), img);
        let three = exposure(&img, 3.0);
        assert!((three.get(1, 0, 0) - 8.0).abs() < 1e-6);
    }

    #[test]
    fn reinhard_maps_luminance_l_to_l_over_1_plus_l() {
        // Gray pixels: L is the value itself.
        for &l in &[0.0f32, 0.25, 1.0, 3.0, 99.0] {
            let img = Image::from_vec(1, 1, 1, vec![l]).unwrap();
            let out = tonemap(&img, Operator::Reinhard, 0.0);
            assert!((out.data[0] - l / (1.0 + l)).abs() < 1e-6, "L = {l}");
        }
        // A coloured pixel: the output luminance is L/(1+L) and the chroma ratios are kept.
        let (r, g, b) = (0.8f32, 0.4, 0.2);
        let img = Image::from_vec(1, 1, 3, vec![r, g, b]).unwrap();
        let out = tonemap(&img, Operator::Reinhard, 0.0);
        let l = color::luminance(r, g, b);
        let lo = color::luminance(out.data[0], out.data[1], out.data[2]);
        assert!((lo - l / (1.0 + l)).abs() < 1e-6);
        assert!((out.data[0] / out.data[1] - r / g).abs() < 1e-5);
        assert!((out.data[1] / out.data[2] - g / b).abs() < 1e-5);
        // Exposure is applied before the curve: +1 stop on 0.5 gives L = 1 → 0.5.
        let half = Image::from_vec(1, 1, 1, vec![0.5]).unwrap();
        assert!((tonemap(&half, Operator::Reinhard, 1.0).data[0] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn srgb_operator_clips_to_unit_range() {
        let img = Image::from_vec(3, 1, 1, vec![-1.0, 0.5, 4.0]).unwrap();
        assert_eq!(tonemap(&img, Operator::Srgb, 0.0).data, vec![0.0, 0.5, 1.0]);
        assert_eq!(
            tonemap(&img, Operator::Srgb, -3.0).data,
            vec![0.0, 0.0625, 0.5]
        );
    }

    #[test]
    fn output_is_finite_for_nan_and_infinite_input() {
        let img = Image::from_vec(
            2,
            2,
            4,
            vec![
                f32::NAN,
                0.5,
                0.5,
                f32::NAN,
                f32::INFINITY,
                f32::INFINITY,
                f32::INFINITY,
                2.0,
                f32::NEG_INFINITY,
                1.0,
                0.0,
                1.0,
                f32::MAX,
                f32::MAX,
                f32::MAX,
                1.0,
            ],
        )
        .unwrap();
        for op in [Operator::Srgb, Operator::Reinhard] {
            for stops in [0.0, 10.0, f32::NAN, f32::INFINITY] {
                let out = tonemap(&img, op, stops);
                assert!(
                    out.data
                        .iter()
                        .all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
                    "{op} {stops}: {:?}",
                    out.data
                );
            }
        }
        let out = tonemap(&img, Operator::Reinhard, 0.0);
        assert_eq!(out.pixel(0, 0)[0], 0.0, "NaN becomes black");
        assert_eq!(out.pixel(0, 0)[3], 0.0, "NaN alpha becomes 0");
        assert!(
            (out.pixel(1, 0)[0] - 1.0).abs() < 1e-6,
            "+inf becomes white"
        );
        assert_eq!(out.pixel(1, 0)[3], 1.0, "alpha clamped");
        assert_eq!(out.pixel(0, 1)[0], 0.0, "-inf becomes black");
    }

    #[test]
    fn operator_names_round_trip() {
        for op in [Operator::Srgb, Operator::Reinhard] {
            assert_eq!(op.name().parse::<Operator>().unwrap(), op);
        }
        assert!("filmic".parse::<Operator>().is_err());
    }
}
