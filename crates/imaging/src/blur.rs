//! Blur as a camera makes it: a Gaussian (a lens slightly out of focus, or the softness of a
//! cheap lens and its sensor's anti-alias filter) and a straight streak (motion blur: the image
//! moving `streak` pixels while the shutter is open). Linear light in, linear light out; the
//! edges repeat (clamp), so a flat image stays flat and no energy leaks in from outside.
//!
//! The Gaussian is separable, truncated at 3σ and normalised; the streak is the mean of the
//! image sampled (bilinearly) at evenly spaced points along a segment of length `streak` centred
//! on the pixel — the box kernel of a constant-velocity exposure.

use rayon::prelude::*;

use crate::error::ImageError;
use crate::image::Image;

/// A Gaussian blur and a motion streak (`blur`); zero leaves that part out.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct BlurOptions {
    /// the Gaussian's standard deviation, pixels (0: none)
    #[param(range = 0.0..=100.0)]
    pub sigma: f64,
    /// the length of the motion streak, pixels (0: none)
    #[param(range = 0.0..=1000.0)]
    pub streak: f64,
    /// the streak's direction, degrees from +x towards +y (image y down)
    #[param(range = -360.0..=360.0)]
    pub angle: f64,
}

impl Default for BlurOptions {
    fn default() -> Self {
        BlurOptions {
            sigma: 1.0,
            streak: 0.0,
            angle: 0.0,
        }
    }
}

/// `img` blurred by the Gaussian then the streak of `o` (module docs).
pub fn blur(img: &Image, o: &BlurOptions) -> Result<Image, ImageError> {
    let finite = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
    if !finite(o.sigma, 0.0, 100.0) || !finite(o.streak, 0.0, 1000.0) || !o.angle.is_finite() {
        return Err(ImageError::InvalidDimensions(format!(
            "blur: sigma {} (0 to 100), streak {} (0 to 1000) and angle {} must be finite",
            o.sigma, o.streak, o.angle
        )));
    }
    let mut out = img.clone();
    if img.is_empty() {
        return Ok(out);
    }
    if o.sigma > 0.0 {
        let k = gaussian_kernel(o.sigma);
        out = convolve_rows(&out, &k);
        out = transpose(&convolve_rows(&transpose(&out), &k));
    }
    if o.streak > 0.0 {
        out = streak(&out, o.streak, o.angle.to_radians());
    }
    Ok(out)
}

/// The normalised Gaussian of standard deviation `sigma`, truncated at 3σ (at least one tap
/// each side).
fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let r = (3.0 * sigma).ceil().max(1.0) as i64;
    let w: Vec<f64> = (-r..=r)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let sum: f64 = w.iter().sum();
    w.iter().map(|v| (v / sum) as f32).collect()
}

/// Every row convolved with the odd-length `kernel` (centred), edges clamped.
fn convolve_rows(img: &Image, kernel: &[f32]) -> Image {
    let (w, h, c) = (img.width, img.height, img.channels);
    let r = (kernel.len() / 2) as i64;
    let mut out = Image::new(w, h, c);
    out.data
        .par_chunks_mut(w * c)
        .enumerate()
        .for_each(|(y, row)| {
            let src = img.row(y);
            for x in 0..w {
                for (i, k) in kernel.iter().enumerate() {
                    let sx = (x as i64 + i as i64 - r).clamp(0, w as i64 - 1) as usize;
                    for ch in 0..c {
                        row[x * c + ch] += k * src[sx * c + ch];
                    }
                }
            }
        });
    out
}

/// `img` with x and y exchanged.
fn transpose(img: &Image) -> Image {
    Image::from_fn(img.height, img.width, img.channels, |x, y, c| {
        img.get(y, x, c)
    })
}

/// The mean of `img` along a segment of `length` px at `angle` (radians) centred on each pixel:
/// the midpoints of `n` equal pieces of it (half a pixel long or shorter), sampled bilinearly,
/// edges clamped.
fn streak(img: &Image, length: f64, angle: f64) -> Image {
    let (w, h, c) = (img.width, img.height, img.channels);
    let n = (2.0 * length).ceil().max(1.0) as usize;
    let (dx, dy) = (angle.cos(), angle.sin());
    let offsets: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let t = length * ((i as f64 + 0.5) / n as f64 - 0.5);
            (t * dx, t * dy)
        })
        .collect();
    let sample = |x: f64, y: f64, ch: usize| -> f32 {
        let x = x.clamp(0.0, (w - 1) as f64);
        let y = y.clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let top = img.get(x0, y0, ch) * (1.0 - fx) + img.get(x1, y0, ch) * fx;
        let bottom = img.get(x0, y1, ch) * (1.0 - fx) + img.get(x1, y1, ch) * fx;
        top * (1.0 - fy) + bottom * fy
    };
    let mut out = Image::new(w, h, c);
    let scale = 1.0 / n as f32;
    out.data
        .par_chunks_mut(w * c)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..w {
                for &(ox, oy) in &offsets {
                    for ch in 0..c {
                        row[x * c + ch] += scale * sample(x as f64 + ox, y as f64 + oy, ch);
                    }
                }
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single bright pixel at (cx, cy) on black, one channel.
    fn point(w: usize, h: usize, cx: usize, cy: usize) -> Image {
        Image::from_fn(
            w,
            h,
            1,
            |x, y, _| if (x, y) == (cx, cy) { 1.0 } else { 0.0 },
        )
    }

    /// Sum, mean position and variance along x and y of a one-channel image.
    fn moments(img: &Image) -> (f64, [f64; 2], [f64; 2]) {
        let (mut s, mut m, mut v) = (0.0, [0.0; 2], [0.0; 2]);
        for y in 0..img.height {
            for x in 0..img.width {
                let p = img.get(x, y, 0) as f64;
                s += p;
                m[0] += p * x as f64;
                m[1] += p * y as f64;
            }
        }
        m = [m[0] / s, m[1] / s];
        for y in 0..img.height {
            for x in 0..img.width {
                let p = img.get(x, y, 0) as f64;
                v[0] += p * (x as f64 - m[0]).powi(2);
                v[1] += p * (y as f64 - m[1]).powi(2);
            }
        }
        (s, m, [v[0] / s, v[1] / s])
    }

    #[test]
    fn a_point_spreads_into_a_gaussian_of_variance_sigma_squared() {
        let o = BlurOptions {
            sigma: 2.0,
            ..Default::default()
        };
        let out = blur(&point(41, 31, 20, 15), &o).unwrap();
        let (sum, mean, var) = moments(&out);
        assert!((sum - 1.0).abs() < 1e-5, "energy {sum}");
        assert!((mean[0] - 20.0).abs() < 1e-6 && (mean[1] - 15.0).abs() < 1e-6);
        // Truncation at 3σ loses 0.27 % of the tails: the variance is 4 within 3 %.
        for v in var {
            assert!((v - 4.0).abs() < 0.12, "variance {v}");
        }
        // Isotropic: the value 2 px right equals the value 2 px down.
        assert!((out.get(22, 15, 0) - out.get(20, 17, 0)).abs() < 1e-7);
    }

    #[test]
    fn a_streak_spreads_a_point_along_its_direction_only() {
        let o = BlurOptions {
            sigma: 0.0,
            streak: 12.0,
            angle: 90.0,
        };
        let out = blur(&point(31, 41, 15, 20), &o).unwrap();
        let (sum, mean, var) = moments(&out);
        assert!((sum - 1.0).abs() < 1e-5, "energy {sum}");
        assert!((mean[1] - 20.0).abs() < 1e-6);
        // A box of length L has variance L²/12 = 12, the bilinear sampling adds 1/6.
        assert!(
            (var[1] - 12.0 - 1.0 / 6.0).abs() < 0.05,
            "variance along {}",
            var[1]
        );
        assert!(var[0] < 1e-9, "across {}", var[0]);
        // Nothing beyond half the streak's length.
        assert_eq!(out.get(15, 20 + 8, 0), 0.0);
        assert!(out.get(15, 20 + 5, 0) > 0.0);
    }

    #[test]
    fn a_flat_image_stays_flat_and_nothing_blurs_nothing() {
        let flat = Image::from_fn(17, 9, 3, |_, _, c| 0.25 * (c + 1) as f32);
        let o = BlurOptions {
            sigma: 3.0,
            streak: 7.5,
            angle: 30.0,
        };
        let out = blur(&flat, &o).unwrap();
        assert!(out.max_abs_diff(&flat).unwrap() < 1e-6);
        let none = BlurOptions {
            sigma: 0.0,
            streak: 0.0,
            angle: 0.0,
        };
        let img = point(5, 5, 2, 2);
        assert_eq!(blur(&img, &none).unwrap(), img);
        assert!(blur(&Image::new(0, 0, 3), &o).unwrap().is_empty());
    }

    #[test]
    fn bad_options_are_refused() {
        let img = point(4, 4, 1, 1);
        for o in [
            BlurOptions {
                sigma: f64::NAN,
                ..Default::default()
            },
            BlurOptions {
                streak: -1.0,
                ..Default::default()
            },
            BlurOptions {
                angle: f64::INFINITY,
                ..Default::default()
            },
        ] {
            assert!(blur(&img, &o).is_err(), "{o:?}");
        }
    }
}
