//! Drift correction for the sequence tracker (an addition to the book's chapter 6, after
//! Matthews, Ishikawa & Baker, "The template update problem", PAMI 2004, strategy 3).
//!
//! Tracking from each frame to the next re-takes the window every frame, so the sub-pixel
//! errors of the steps add up: a feature's track wanders off the physical point by a random
//! walk (the book's own `f.txt` tracks show it — their reprojection error grows with track
//! length). The fix keeps each feature's first window as a template: after the frame-to-frame
//! step lands at `p`, the template is aligned to the new frame by affine Lucas–Kanade (the
//! window deforms as the view changes; Shi & Tomasi's feature monitoring) starting from the
//! last frame's warp moved to `p` (inverse compositional, Baker & Matthews 2004: the
//! steepest-descent images and Hessian are computed once), and the aligned centre `p*`
//! replaces `p` when it moved less than a bound — larger corrections mean the template no
//! longer looks like the feature, and the frame-to-frame position is kept.

use nalgebra::{Matrix3, Matrix6, Vector6};

use super::pyramid::GrayImage;

/// A feature's first window with its steepest-descent images, ready for affine alignment
/// (inverse compositional, Baker & Matthews 2004), and the warp found in the last frame.
#[derive(Clone, Debug)]
pub struct Template {
    half: usize,
    values: Vec<f32>,
    /// Per pixel, ∇T · ∂W/∂p at p = 0 for the affine warp
    /// W(u; p) = ((1 + p₁)u + p₃v + p₅, p₂u + (1 + p₄)v + p₆).
    sd: Vec<[f32; 6]>,
    h_inv: Matrix6<f64>,
    /// Inverse of the translation block of the Hessian: (xx, xy, yy).
    h_inv_translation: [f64; 3],
    /// Window coordinates → image coordinates in the last frame.
    warp: Matrix3<f64>,
}

impl Template {
    /// The `(2·half + 1)²` window of `img` centred at `p` (bilinear), or `None` where it is
    /// too flat to align.
    pub fn capture(img: &GrayImage, p: [f32; 2], half: usize) -> Option<Template> {
        let n = 2 * half + 1;
        // One pixel more on each side for central differences.
        let m = n + 2;
        let r = half as f32 + 1.0;
        let mut big = Vec::with_capacity(m * m);
        for j in 0..m {
            for i in 0..m {
                big.push(img.sample(p[0] - r + i as f32, p[1] - r + j as f32));
            }
        }
        let mut values = Vec::with_capacity(n * n);
        let mut sd = Vec::with_capacity(n * n);
        let mut h = Matrix6::<f64>::zeros();
        let (mut a, mut b, mut c) = (0.0f64, 0.0f64, 0.0f64);
        for j in 1..=n {
            for i in 1..=n {
                let gx = 0.5 * (big[j * m + i + 1] - big[j * m + i - 1]);
                let gy = 0.5 * (big[(j + 1) * m + i] - big[(j - 1) * m + i]);
                let (u, v) = (i as f32 - 1.0 - half as f32, j as f32 - 1.0 - half as f32);
                let row = [gx * u, gy * u, gx * v, gy * v, gx, gy];
                let rv = Vector6::from_iterator(row.iter().map(|&x| x as f64));
                h += rv * rv.transpose();
                values.push(big[j * m + i]);
                sd.push(row);
                a += (gx * gx) as f64;
                b += (gx * gy) as f64;
                c += (gy * gy) as f64;
            }
        }
        // The translation part must show a measurable corner.
        let min_eig = 0.5 * (a + c - ((a - c) * (a - c) + 4.0 * b * b).sqrt());
        if !(min_eig / (n * n) as f64 > 0.1) {
            return None;
        }
        let h_inv = h.try_inverse()?;
        let det = a * c - b * b;
        let h_inv_translation = [c / det, -b / det, a / det];
        let warp = Matrix3::new(1.0, 0.0, p[0] as f64, 0.0, 1.0, p[1] as f64, 0.0, 0.0, 1.0);
        Some(Template {
            half,
            values,
            sd,
            h_inv,
            h_inv_translation,
            warp,
        })
    }

    /// Aligns the template to `img` with the last frame's warp moved to `start`; returns the
    /// window centre's position and the RMS residual (0–255 gray levels), or `None` if the
    /// iteration diverges or leaves the image. [`Template::accept`] keeps the warp for the
    /// next frame.
    pub fn align(
        &self,
        img: &GrayImage,
        start: [f32; 2],
        max_iterations: u32,
    ) -> Option<([f32; 2], f32, Matrix3<f64>)> {
        let n = 2 * self.half + 1;
        let h = self.half as f64;
        let mut w = self.warp;
        w[(0, 2)] = start[0] as f64;
        w[(1, 2)] = start[1] as f64;
        let (wd, ht) = ((img.width - 1) as f64, (img.height - 1) as f64);
        let inside = |w: &Matrix3<f64>| {
            [(-h, -h), (h, -h), (-h, h), (h, h)].iter().all(|&(u, v)| {
                let x = w[(0, 0)] * u + w[(0, 1)] * v + w[(0, 2)];
                let y = w[(1, 0)] * u + w[(1, 1)] * v + w[(1, 2)];
                x >= 0.0 && y >= 0.0 && x <= wd && y <= ht
            })
        };
        // Translation first (the frame-to-frame step left the shape right and the position
        // nearly so), then the whole affine warp.
        let ht = self.h_inv_translation;
        for _ in 0..max_iterations {
            if !inside(&w) {
                return None;
            }
            let (mut gx, mut gy) = (0.0f64, 0.0f64);
            self.residuals(img, &w, |k, e| {
                gx += (self.sd[k][4] * e) as f64;
                gy += (self.sd[k][5] * e) as f64;
            });
            let d = [ht[0] * gx + ht[1] * gy, ht[1] * gx + ht[2] * gy];
            // W ∘ W(Δ)⁻¹ moves the centre by the linear part applied to −Δ.
            w[(0, 2)] -= w[(0, 0)] * d[0] + w[(0, 1)] * d[1];
            w[(1, 2)] -= w[(1, 0)] * d[0] + w[(1, 1)] * d[1];
            if !(w[(0, 2)].is_finite() && w[(1, 2)].is_finite()) {
                return None;
            }
            if d[0].hypot(d[1]) < 0.01 {
                break;
            }
        }
        for _ in 0..max_iterations {
            if !inside(&w) {
                return None;
            }
            let mut g = Vector6::<f64>::zeros();
            self.residuals(img, &w, |k, e| {
                for (gi, s) in g.iter_mut().zip(&self.sd[k]) {
                    *gi += (s * e) as f64;
                }
            });
            let d = self.h_inv * g;
            let dw = Matrix3::new(
                1.0 + d[0],
                d[2],
                d[4],
                d[1],
                1.0 + d[3],
                d[5],
                0.0,
                0.0,
                1.0,
            );
            w *= dw.try_inverse()?;
            if !w.iter().all(|x| x.is_finite()) {
                return None;
            }
            if d[4].hypot(d[5]) < 0.005 && d.fixed_rows::<4>(0).norm() < 1e-4 {
                break;
            }
        }
        if !inside(&w) {
            return None;
        }
        let mut ss = 0.0f32;
        self.residuals(img, &w, |_, e| ss += e * e);
        Some((
            [w[(0, 2)] as f32, w[(1, 2)] as f32],
            (ss / (n * n) as f32).sqrt(),
            w,
        ))
    }

    /// Calls `each(k, I(W(u_k)) − T(u_k))` for every window pixel k under the warp `w`.
    /// Every sample of a warp that passed `align`'s `inside` lies in the image (the window's
    /// corners do, and the warped window is their convex hull), so no clamping.
    #[inline]
    fn residuals(&self, img: &GrayImage, w: &Matrix3<f64>, mut each: impl FnMut(usize, f32)) {
        let n = 2 * self.half + 1;
        let h = self.half as f64;
        for j in 0..n {
            let v = j as f64 - h;
            for i in 0..n {
                let u = i as f64 - h;
                let x = w[(0, 0)] * u + w[(0, 1)] * v + w[(0, 2)];
                let y = w[(1, 0)] * u + w[(1, 1)] * v + w[(1, 2)];
                let k = j * n + i;
                each(k, img.sample_inside(x as f32, y as f32) - self.values[k]);
            }
        }
    }

    /// Keeps `warp` (from [`Template::align`]) as the starting shape for the next frame.
    pub fn accept(&mut self, warp: Matrix3<f64>) {
        self.warp = warp;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob(cx: f32, cy: f32) -> GrayImage {
        GrayImage::from_fn(64, 64, |x, y| {
            let (dx, dy) = (x as f32 - cx, y as f32 - cy);
            200.0 * (-(dx * dx + 2.0 * dy * dy + dx * dy) / 30.0).exp() + 20.0
        })
    }

    /// The template of a smooth blob finds the blob again after a sub-pixel shift, from a start
    /// a pixel and a half away, and refuses a flat window.
    #[test]
    fn aligns_a_shifted_window_and_refuses_flat_ones() {
        let t = Template::capture(&blob(30.0, 31.0), [30.0, 31.0], 7).unwrap();
        let moved = blob(32.3, 30.4);
        let (p, res, _) = t.align(&moved, [31.0, 31.5], 50).unwrap();
        assert!(
            (p[0] - 32.3).abs() < 0.02 && (p[1] - 30.4).abs() < 0.02,
            "{p:?}"
        );
        assert!(res < 2.0, "residual {res}");
        let flat = GrayImage::from_fn(64, 64, |_, _| 100.0);
        assert!(Template::capture(&flat, [30.0, 30.0], 7).is_none());
    }
}
