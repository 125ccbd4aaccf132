//! The image noise of a frame, so the tracker's thresholds follow the footage (an addition to
//! the book, whose thresholds are fixed gray levels for its clean 8-bit video).
//!
//! Immerkær's estimator (J. Immerkær, "Fast noise variance estimation", CVIU 64(2), 1996): the
//! mask `[1 −2 1; −2 4 −2; 1 −2 1]` (the difference of two Laplacians) annihilates locally planar
//! brightness, so its response is mostly noise, with variance 36 σ² for white noise of σ. Instead
//! of Immerkær's mean absolute response we take the median (σ = 1.4826 · median |r| / 6), which
//! edges and fine texture — a minority of pixels, but the ones a mean is most sensitive to —
//! move far less: on the Blender dev plate (σ of the render grain ≈ 10 gray levels) the mean
//! reads 13.5, the median 10.4; on our clean renders 3.7 and 2.5.

use super::pyramid::GrayImage;

/// Standard deviation of the noise of `img`, in its brightness units (0–255 gray levels for
/// [`GrayImage::from_image`]), from every second row and column (the mask is local, so the
/// subsample is unbiased and four times cheaper). Images smaller than 3×3 give 0.
pub fn noise_sigma(img: &GrayImage) -> f32 {
    let (w, h) = (img.width, img.height);
    if w < 3 || h < 3 {
        return 0.0;
    }
    let d = &img.data;
    let mut r: Vec<f32> = Vec::with_capacity((w / 2) * (h / 2));
    for y in (1..h - 1).step_by(2) {
        let (a, b, c) = ((y - 1) * w, y * w, (y + 1) * w);
        for x in (1..w - 1).step_by(2) {
            let v = (d[a + x - 1] + d[a + x + 1] + d[c + x - 1] + d[c + x + 1])
                - 2.0 * (d[a + x] + d[c + x] + d[b + x - 1] + d[b + x + 1])
                + 4.0 * d[b + x];
            if v.is_finite() {
                r.push(v.abs());
            }
        }
    }
    if r.is_empty() {
        return 0.0;
    }
    let mid = r.len() / 2;
    let (_, m, _) = r.select_nth_unstable_by(mid, f32::total_cmp);
    1.4826 * *m / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// A smooth ramp with hard vertical edges every 40 px, plus white Gaussian noise of σ.
    fn image(w: usize, h: usize, sigma: f32, seed: u64) -> GrayImage {
        let mut rng = Pcg64::seed_from_u64(seed);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let step = if (i % w / 40).is_multiple_of(2) {
                    80.0
                } else {
                    0.0
                };
                // Box–Muller.
                let (u, v): (f32, f32) = (rng.random::<f32>().max(1e-12), rng.random());
                let g = (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos();
                60.0 + 0.2 * x + 0.1 * y + step + sigma * g
            })
            .collect();
        GrayImage::new(w, h, data).unwrap()
    }

    #[test]
    fn measures_white_noise_through_ramps_and_edges() {
        for sigma in [1.0f32, 4.0, 12.0] {
            let s = noise_sigma(&image(480, 270, sigma, 3));
            assert!((s / sigma - 1.0).abs() < 0.03, "σ {sigma}: estimated {s}");
        }
        // Noise-free: only the edges respond, and they are a minority of the pixels (what
        // is left is f32 rounding of the ramp).
        let clean = noise_sigma(&image(480, 270, 0.0, 3));
        assert!(clean < 1e-3, "{clean}");
    }

    #[test]
    fn tiny_and_non_finite_images_give_a_number() {
        assert_eq!(
            noise_sigma(&GrayImage::new(2, 2, vec![1.0; 4]).unwrap()),
            0.0
        );
        let mut img = image(40, 30, 5.0, 1);
        img.data[100] = f32::NAN;
        assert!(noise_sigma(&img).is_finite());
    }
}
