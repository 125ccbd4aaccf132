//! Radiance-map assembly and the inverse conversion (book 10.2–10.6; Debevec & Malik 1997, §2.2).
//!
//! [`merge_debevec`] computes, per pixel and channel, the weighted mean of the log radiances
//! that each exposure implies (the paper's equation 6):
//! `ln E = Σ_j w(Z_j)(g(Z_j) − ln Δt_j) / Σ_j w(Z_j)` with the hat weight.
//!
//! - **Clipped pixels.** The hat weight is 0 at codes 0 and 255, so clipped observations never
//!   contribute. A pixel channel clipped in *every* exposure has no estimate; it takes the bound
//!   the stack gives: if it is bright (code ≥ 128 in the shortest exposure) the value of the
//!   shortest exposure, `g(Z) − ln Δt_min` (the radiance is at least that); otherwise the value of
//!   the longest exposure (at most that).
//! - **Colour balance.** Each channel's curve has its own free scale, fixed by `g(128) = 0`: code
//!   128 means the same exposure in every channel. A pixel the camera recorded as neutral mid-grey
//!   (128, 128, 128) therefore stays neutral in the radiance map — the camera's own white balance
//!   at mid-grey is kept (the paper's and OpenCV's choice). Channels are weighted independently.
//!
//! The result is linear, scene-referred, in the relative units of the curve (multiply by a
//! constant to calibrate absolutely).

use rayon::prelude::*;

use super::response::hat_weight;
use super::{ExposureStack, HdrError, ResponseCurve, LEVELS};
use crate::color::srgb8_to_linear;
use crate::Image;

fn check_channels(stack: &ExposureStack, curve: &ResponseCurve) -> Result<(), HdrError> {
    if curve.channels() != stack.channels() {
        return Err(HdrError::InvalidArgument(format!(
            "the response curve has {} channels, the stack {}",
            curve.channels(),
            stack.channels()
        )));
    }
    Ok(())
}

/// Assembles the linear radiance map of `stack` through `curve` (Debevec & Malik 1997, eq. 6;
/// book 10.4). See the module documentation for clipped pixels and colour balance.
pub fn merge_debevec(stack: &ExposureStack, curve: &ResponseCurve) -> Result<Image, HdrError> {
    check_channels(stack, curve)?;
    let (w, c_n) = (stack.width(), stack.channels());
    let p_n = stack.len();
    let weight: [f64; LEVELS] = std::array::from_fn(|z| hat_weight(z as u8));
    // table[j * c_n + c][z] = g_c(z) − ln Δt_j
    let table: Vec<[f64; LEVELS]> = stack
        .exposures()
        .iter()
        .flat_map(|e| {
            let l = e.time.ln();
            (0..c_n).map(move |c| std::array::from_fn(|z| curve.g(c)[z] - l))
        })
        .collect();
    let shortest = (0..p_n)
        .min_by(|&a, &b| {
            stack.exposures()[a]
                .time
                .total_cmp(&stack.exposures()[b].time)
        })
        .unwrap_or(0);
    let longest = (0..p_n)
        .max_by(|&a, &b| {
            stack.exposures()[a]
                .time
                .total_cmp(&stack.exposures()[b].time)
        })
        .unwrap_or(0);
    let mut out = Image::try_new(w, stack.height(), c_n)?;
    let codes: Vec<&[u8]> = stack
        .exposures()
        .iter()
        .map(|e| e.codes.as_slice())
        .collect();
    out.data
        .par_chunks_mut(w * c_n)
        .enumerate()
        .for_each(|(y, row)| {
            let base = y * w * c_n;
            for (i, o) in row.iter_mut().enumerate() {
                let idx = base + i;
                let c = i % c_n;
                let (mut num, mut den) = (0.0f64, 0.0f64);
                for (j, cj) in codes.iter().enumerate() {
                    let z = cj[idx] as usize;
                    let wz = weight[z];
                    num += wz * table[j * c_n + c][z];
                    den += wz;
                }
                let ln_e = if den > 0.0 {
                    num / den
                } else {
                    let zs = codes[shortest][idx] as usize;
                    if zs >= 128 {
                        table[shortest * c_n + c][zs]
                    } else {
                        table[longest * c_n + c][codes[longest][idx] as usize]
                    }
                };
                *o = ln_e.exp() as f32;
            }
        });
    Ok(out)
}

/// The photograph `hdr_to_ldr` simulates: its exposure time, and the gamma of the curve used
/// when the camera's response is not known.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct LdrOptions {
    /// exposure time in seconds
    #[param(range = 1e-12..=1e12)]
    pub time: f64,
    /// gamma of the curve used when no response is connected (f⁻¹(z) ∝ (z/255)^γ)
    #[param(range = 0.01..=100.0)]
    pub gamma: f64,
}

impl Default for LdrOptions {
    fn default() -> Self {
        LdrOptions {
            time: 1.0,
            gamma: 2.2,
        }
    }
}

/// [`ldr_from_hdr`] through `response`, or through the gamma curve of `o.gamma` when there is
/// none (book 10.6).
pub fn photograph(
    img: &Image,
    response: Option<&ResponseCurve>,
    o: &LdrOptions,
) -> Result<Image, HdrError> {
    match response {
        Some(r) => ldr_from_hdr(img, r, o.time),
        None => ldr_from_hdr(img, &ResponseCurve::gamma(o.gamma, 1)?, o.time),
    }
}

/// Simulates a photograph of the radiance map `img` with exposure time `time` through `curve`
/// (book 10.6, HDR → LDR): code `z = g⁻¹(ln(E · time))`, clipped to 0–255 (see
/// [`ResponseCurve::code_for`]); use [`ResponseCurve::gamma`] for a plain gamma. The result holds
/// `srgb8_to_linear(z)`, so writing it to an 8-bit PNG or JPEG (which sRGB-encodes) stores the
/// code `z` exactly. Negative and NaN radiance give code 0.
pub fn ldr_from_hdr(img: &Image, curve: &ResponseCurve, time: f64) -> Result<Image, HdrError> {
    if !(time.is_finite() && time > 0.0) {
        return Err(HdrError::InvalidArgument(format!(
            "exposure time {time} must be finite and positive"
        )));
    }
    if curve.channels() != img.channels && curve.channels() != 1 {
        return Err(HdrError::InvalidArgument(format!(
            "the response curve has {} channels, the image {}",
            curve.channels(),
            img.channels
        )));
    }
    let lt = time.ln();
    let c_n = img.channels;
    let mut out = img.clone();
    out.data.par_iter_mut().enumerate().for_each(|(i, v)| {
        let c = if curve.channels() == 1 { 0 } else { i % c_n };
        let e = *v as f64;
        let z = if e > 0.0 {
            curve.code_for(c, e.ln() + lt)
        } else {
            0
        };
        *v = srgb8_to_linear(z);
    });
    Ok(out)
}

/// The exposure-consistency error of a response curve on a stack: for every unmasked pixel and
/// channel, the log radiances `g(Z_j) − ln Δt_j` of the exposures with `lo ≤ Z_j ≤ hi`; their
/// absolute deviations from the pixel's median (mean of the two middle values for an even count;
/// pixels with fewer than 2 such exposures are skipped); the median of all deviations, in natural
/// log units. A perfect curve on a noiseless static scene scores 0. `None` if nothing qualifies.
///
/// It measures how well a curve *explains* the stack (Debevec & Malik's premise, 1997 §2), and
/// is scale-free, so curves from different tools (e.g. OpenCV) compare directly.
pub fn consistency_error(
    stack: &ExposureStack,
    curve: &ResponseCurve,
    lo: u8,
    hi: u8,
) -> Result<Option<f64>, HdrError> {
    check_channels(stack, curve)?;
    let c_n = stack.channels();
    let w = stack.width();
    let lts: Vec<f64> = stack.exposures().iter().map(|e| e.time.ln()).collect();
    let rows: Vec<Vec<f32>> = (0..stack.height())
        .into_par_iter()
        .map(|y| {
            let mut dev = Vec::new();
            let mut v = Vec::with_capacity(stack.len());
            for x in 0..w {
                let p = y * w + x;
                if stack.is_masked(p) {
                    continue;
                }
                for c in 0..c_n {
                    v.clear();
                    for (e, lt) in stack.exposures().iter().zip(&lts) {
                        let z = e.codes[p * c_n + c];
                        if (lo..=hi).contains(&z) {
                            v.push(curve.g(c)[z as usize] - lt);
                        }
                    }
                    if v.len() < 2 {
                        continue;
                    }
                    let m = median(&mut v);
                    dev.extend(v.iter().map(|x| (x - m).abs() as f32));
                }
            }
            dev
        })
        .collect();
    let mut all: Vec<f64> = rows.into_iter().flatten().map(f64::from).collect();
    if all.is_empty() {
        return Ok(None);
    }
    Ok(Some(median(&mut all)))
}

/// Median (mean of the two middle values for an even length); `v` must be non-empty and NaN-free.
fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (_, &mut hi, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        hi
    } else {
        let lo = v[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hdr::response::tests::{synthetic, true_code, true_g, GAMMAS, TIMES};
    use crate::hdr::{calibrate_debevec, CalibrateOptions, Exposure};

    #[test]
    fn radiance_within_two_percent_on_well_exposed_pixels() {
        let (e, stack) = synthetic();
        let curve = calibrate_debevec(&stack, &CalibrateOptions::default()).unwrap();
        let img = merge_debevec(&stack, &curve).unwrap();
        for (c, &gamma) in GAMMAS.iter().enumerate() {
            // Well exposed = bracketed: the stack shows the pixel both darker than code 96 and
            // brighter than 160, so its best observations are mid-range. (At the stack's ends a
            // pixel is seen well only once, where 8-bit quantization alone costs up to ~5 %.)
            let good: Vec<usize> = (0..e.len())
                .filter(|&p| {
                    let z: Vec<f64> = TIMES.iter().map(|&t| true_code(e[p] * t, gamma)).collect();
                    z.iter().any(|&v| v <= 96.0) && z.iter().any(|&v| v >= 160.0)
                })
                .collect();
            // Free scale: the median ratio recovered / true.
            let mut ratios: Vec<f64> = good
                .iter()
                .map(|&p| img.data[p * 3 + c] as f64 / e[p])
                .collect();
            let scale = median(&mut ratios.clone());
            // Sanity: the scale is what g(128) = 0 implies, within the curve's 1 %.
            let implied = (curve.g(c)[128] - true_g(128, gamma)).exp();
            assert!((scale / implied - 1.0).abs() < 0.01, "{scale} {implied}");
            ratios
                .iter_mut()
                .for_each(|r| *r = (*r / scale - 1.0).abs());
            let worst = ratios.iter().copied().fold(0.0, f64::max);
            let rms = (ratios.iter().map(|r| r * r).sum::<f64>() / ratios.len() as f64).sqrt();
            eprintln!(
                "channel {c}: {} well-exposed pixels, radiance error rms {:.3}% worst {:.3}%",
                good.len(),
                rms * 100.0,
                worst * 100.0
            );
            assert!(good.len() > 2000, "{}", good.len());
            assert!(
                worst < 0.02,
                "channel {c}: radiance off by {:.2}%",
                worst * 100.0
            );
        }
        // The true curve explains the stack almost perfectly; the recovered one nearly as well.
        let truth = ResponseCurve::new(
            GAMMAS
                .iter()
                .map(|&g| std::array::from_fn(|z| true_g(z.clamp(1, 254), g)))
                .collect(),
        )
        .unwrap();
        let et = consistency_error(&stack, &truth, 32, 223).unwrap().unwrap();
        let er = consistency_error(&stack, &curve, 32, 223).unwrap().unwrap();
        let eg = consistency_error(&stack, &ResponseCurve::gamma(2.2, 3).unwrap(), 32, 223)
            .unwrap()
            .unwrap();
        assert!(er < et * 1.5 + 1e-3 && er < eg / 3.0, "{er} {et} {eg}");
    }

    #[test]
    fn clipped_pixels_take_the_bound_of_the_stack() {
        let curve = ResponseCurve::gamma(1.0, 1).unwrap();
        let stack = ExposureStack::new(
            2,
            1,
            1,
            vec![
                Exposure {
                    time: 1.0,
                    codes: vec![255, 0],
                },
                Exposure {
                    time: 2.0,
                    codes: vec![255, 0],
                },
            ],
        )
        .unwrap();
        let img = merge_debevec(&stack, &curve).unwrap();
        assert!(
            (img.data[0] as f64 - 255.0 / 128.0).abs() < 1e-5,
            "{}",
            img.data[0]
        );
        assert!(
            (img.data[1] as f64 - 0.5 / 128.0 / 2.0).abs() < 1e-6,
            "{}",
            img.data[1]
        );
        assert!(merge_debevec(&stack, &ResponseCurve::gamma(1.0, 3).unwrap()).is_err());
    }

    #[test]
    fn ldr_round_trip_through_the_curve() {
        let (_, stack) = synthetic();
        let curve = calibrate_debevec(&stack, &CalibrateOptions::default()).unwrap();
        let img = merge_debevec(&stack, &curve).unwrap();
        let j = 6; // Δt = 1
        let ldr = ldr_from_hdr(&img, &curve, TIMES[j]).unwrap();
        let codes = &stack.exposures()[j].codes;
        let mut close = 0;
        for (v, &z) in ldr.data.iter().zip(codes) {
            let back = crate::color::linear_to_srgb8(*v);
            if (back as i32 - z as i32).abs() <= 2 {
                close += 1;
            }
        }
        assert!(
            close as f64 > 0.98 * codes.len() as f64,
            "{close}/{}",
            codes.len()
        );
        assert!(ldr_from_hdr(&img, &curve, 0.0).is_err());
        assert!(ldr_from_hdr(&img, &curve, f64::NAN).is_err());
    }

    #[test]
    fn median_even_and_odd() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    }
}
