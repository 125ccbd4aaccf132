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
//!
//! Grainy footage (a render at few samples, high-ISO video) needs three more things, measured
//! on the Blender dev plate (σ ≈ 10 gray levels) with `examples/track_accuracy.rs`, which
//! scores tracks against the renderer's cameras:
//! - the windows are aligned on the frame smoothed by a σ = 1 px binomial filter
//!   ([`GrayImage::binomial_smoothed`], done once per frame by the tracker);
//! - the template is the mean of the feature's aligned windows over its first
//!   [`AVERAGED_FRAMES`] frames ([`Template::accept`]): each frame's grain is independent, so
//!   the mean window's gradients carry less noise;
//! - each alignment step corrects the Gauss–Newton Hessian by Broyden's secant rule
//!   (`Secant`).
//!
//! The template's noisy gradients inflate inverse-compositional's Hessian Σ∇T∇Tᵀ above the
//! cost's true curvature, so the plain steps fall short and converge linearly (a ratio of
//! ~0.85 per step on that plate): the alignment took 10 translation and 19 affine steps (the
//! cap is 20) a feature and frame, and stopped short of the optimum. With the three: 5.2 and
//! 10.0 steps, and the median per-track RMS error against the true cameras fell from 0.62 to
//! 0.51 px (150 features, pinhole plate; `cargo run --release -p vfxgraph-vision --example
//! track_accuracy -- ../shared/data/blender_plate_dev/pinhole 150`).

use nalgebra::{Matrix3, Matrix6, SMatrix, SVector, Vector2, Vector6};

use super::pyramid::GrayImage;

/// Alignment stops when a step moves no window corner by more than this many pixels.
const STEP_EPSILON: f64 = 0.01;

/// A feature's first window with its steepest-descent images, ready for affine alignment
/// (inverse compositional, Baker & Matthews 2004), and the warp found in the last frame.
#[derive(Clone, Debug)]
pub struct Template {
    half: usize,
    /// The `(2·half + 3)²` window samples (one pixel of margin for the gradient), the mean
    /// over the first `frames` frames.
    big: Vec<f32>,
    frames: u32,
    values: Vec<f32>,
    /// Per pixel, ∇T · ∂W/∂p at p = 0 for the affine warp
    /// W(u; p) = ((1 + p₁)u + p₃v + p₅, p₂u + (1 + p₄)v + p₆).
    sd: Vec<[f32; 6]>,
    /// Gauss–Newton Hessian of the affine parameters, Σ sd sdᵀ.
    h: Matrix6<f64>,
    /// Window coordinates → image coordinates in the last frame.
    warp: Matrix3<f64>,
}

impl Template {
    /// The `(2·half + 1)²` window of `img` centred at `p` (bilinear), or `None` where it is
    /// too flat to align.
    pub fn capture(img: &GrayImage, p: [f32; 2], half: usize) -> Option<Template> {
        let warp = Matrix3::new(1.0, 0.0, p[0] as f64, 0.0, 1.0, p[1] as f64, 0.0, 0.0, 1.0);
        let big = sample_window(img, &warp, half, true)?;
        let mut t = Template {
            half,
            big,
            frames: 1,
            values: Vec::new(),
            sd: Vec::new(),
            h: Matrix6::zeros(),
            warp,
        };
        t.prepare().then_some(t)
    }

    /// Values, steepest-descent images and Hessian from `big`; false where the window is too
    /// flat to align.
    fn prepare(&mut self) -> bool {
        let half = self.half;
        let n = 2 * half + 1;
        // One pixel more on each side for central differences.
        let m = n + 2;
        let big = &self.big;
        self.values.clear();
        self.sd.clear();
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
                self.values.push(big[j * m + i]);
                self.sd.push(row);
                a += (gx * gx) as f64;
                b += (gx * gy) as f64;
                c += (gy * gy) as f64;
            }
        }
        self.h = h;
        // The translation part must show a measurable corner.
        let min_eig = 0.5 * (a + c - ((a - c) * (a - c) + 4.0 * b * b).sqrt());
        min_eig / (n * n) as f64 > 0.1 && h.try_inverse().is_some()
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
        // Both stages update the Gauss–Newton Hessian by Broyden's rank-one secant rule from
        // the gradients they compute anyway: the template's Hessian Σ∇T∇Tᵀ overstates the
        // cost's curvature where the template's gradients carry noise or the frame's window
        // has changed, so plain inverse-compositional steps fall short and converge linearly.
        let mut secant = Secant::new(self.h.fixed_view::<2, 2>(4, 4).into_owned());
        let mut base = w;
        for _ in 0..max_iterations {
            if !inside(&w) {
                return None;
            }
            let (mut g, mut ss) = (Vector2::<f64>::zeros(), 0.0f64);
            self.residuals(img, &w, |k, e| {
                g[0] += (self.sd[k][4] * e) as f64;
                g[1] += (self.sd[k][5] * e) as f64;
                ss += (e * e) as f64;
            });
            let (d, retry) = secant.step(g, ss, |m, g| m.try_inverse().map(|i| i * g))?;
            if retry {
                w = base;
            }
            base = w;
            // W ∘ W(Δ)⁻¹ moves the centre by the linear part applied to −Δ.
            w[(0, 2)] -= w[(0, 0)] * d[0] + w[(0, 1)] * d[1];
            w[(1, 2)] -= w[(1, 0)] * d[0] + w[(1, 1)] * d[1];
            if !(w[(0, 2)].is_finite() && w[(1, 2)].is_finite()) {
                return None;
            }
            if d[0].hypot(d[1]) < STEP_EPSILON {
                break;
            }
        }
        let mut secant = Secant::new(self.h);
        let mut base = w;
        for _ in 0..max_iterations {
            if !inside(&w) {
                return None;
            }
            let (mut g, mut ss) = (Vector6::<f64>::zeros(), 0.0f64);
            self.residuals(img, &w, |k, e| {
                for (gi, s) in g.iter_mut().zip(&self.sd[k]) {
                    *gi += (s * e) as f64;
                }
                ss += (e * e) as f64;
            });
            let (d, retry) = secant.step(g, ss, |m, g| m.lu().solve(g))?;
            if retry {
                w = base;
            }
            base = w;
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
            // The step's largest motion of a window corner, in template pixels.
            let corner = [(-h, -h), (h, -h), (-h, h), (h, h)]
                .iter()
                .map(|&(u, v)| (d[0] * u + d[2] * v + d[4]).hypot(d[1] * u + d[3] * v + d[5]))
                .fold(0.0f64, f64::max);
            if corner < STEP_EPSILON {
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

    /// Keeps `warp` (from [`Template::align`]) as the starting shape for the next frame and,
    /// for the template's first [`AVERAGED_FRAMES`] frames, averages the frame's window under
    /// that warp into the template: the render grain of one frame is independent of the
    /// next's, so the mean window's gradients carry less noise, its Hessian overstates the
    /// cost's curvature less and alignment converges in fewer steps.
    pub fn accept(&mut self, warp: Matrix3<f64>, img: &GrayImage) {
        self.warp = warp;
        if self.frames >= AVERAGED_FRAMES {
            return;
        }
        let Some(new) = sample_window(img, &warp, self.half, false) else {
            return;
        };
        let k = self.frames as f32;
        let old = std::mem::take(&mut self.big);
        self.big = old
            .iter()
            .zip(&new)
            .map(|(a, b)| (k * a + b) / (k + 1.0))
            .collect();
        self.frames += 1;
        if !self.prepare() {
            // Cannot happen for a window that aligned, but keep the template usable.
            self.big = old;
            self.frames -= 1;
            self.prepare();
        }
    }
}

/// How many frames' windows a template averages ([`Template::accept`]).
pub const AVERAGED_FRAMES: u32 = 16;

/// The `(2·half + 3)²` samples of `img` under `warp` (window coordinates → image), row by
/// row, or `None` when the window leaves the image (`clamp`: sample at the border instead).
fn sample_window(
    img: &GrayImage,
    warp: &Matrix3<f64>,
    half: usize,
    clamp: bool,
) -> Option<Vec<f32>> {
    let m = 2 * half + 3;
    let r = half as f64 + 1.0;
    let (wd, ht) = ((img.width - 1) as f64, (img.height - 1) as f64);
    let at = |u: f64, v: f64| {
        (
            warp[(0, 0)] * u + warp[(0, 1)] * v + warp[(0, 2)],
            warp[(1, 0)] * u + warp[(1, 1)] * v + warp[(1, 2)],
        )
    };
    if !clamp {
        for (u, v) in [(-r, -r), (r, -r), (-r, r), (r, r)] {
            let (x, y) = at(u, v);
            if !(x >= 0.0 && y >= 0.0 && x <= wd && y <= ht) {
                return None;
            }
        }
    }
    let mut big = Vec::with_capacity(m * m);
    for j in 0..m {
        for i in 0..m {
            let (x, y) = at(i as f64 - r, j as f64 - r);
            big.push(img.sample(x as f32, y as f32));
        }
    }
    Some(big)
}

/// Quasi-Newton steps `B⁻¹ g` of the root finding `g(p) = 0` (the alignment's gradient),
/// whose Jacobian `B` starts at the Gauss–Newton Hessian `h` and is corrected by Broyden's
/// rank-one rule from the last step `s` and gradient change `y`: `B ← B + (y − B s) sᵀ / sᵀs`.
/// A corrected step that raised the window's square error is taken back and replaced by the
/// Gauss–Newton step from the same point (with `B` reset to `h`), as is a `B` that stops being
/// invertible or steps more than four times as far as Gauss–Newton would, so the alignment
/// never does worse than plain inverse-compositional steps.
struct Secant<const N: usize> {
    h: SMatrix<f64, N, N>,
    b: SMatrix<f64, N, N>,
    /// The last step taken, and the gradient and square error where it was taken.
    last: Option<(SVector<f64, N>, SVector<f64, N>, f64)>,
}

impl<const N: usize> Secant<N> {
    fn new(h: SMatrix<f64, N, N>) -> Self {
        Secant {
            h,
            b: h,
            last: None,
        }
    }

    /// The next step from the point with gradient `g` and square error `ss`, and whether the
    /// caller must first take the last step back (the step is then from the point before it).
    fn step(
        &mut self,
        g: SVector<f64, N>,
        ss: f64,
        solve: impl Fn(&SMatrix<f64, N, N>, &SVector<f64, N>) -> Option<SVector<f64, N>>,
    ) -> Option<(SVector<f64, N>, bool)> {
        if let Some((s, g_prev, ss_prev)) = self.last.take() {
            if ss > ss_prev && self.b != self.h {
                self.b = self.h;
                let d = solve(&self.h, &g_prev)?;
                self.last = Some((-d, g_prev, ss_prev));
                return Some((d, true));
            }
            let sn = s.dot(&s);
            if sn > 0.0 {
                let y = g - g_prev;
                self.b += (y - self.b * s) * s.transpose() / sn;
            }
        }
        let gn = solve(&self.h, &g)?;
        let d = match solve(&self.b, &g) {
            Some(d) if d.iter().all(|x| x.is_finite()) && d.norm() <= 4.0 * gn.norm() => d,
            _ => {
                self.b = self.h;
                gn
            }
        };
        self.last = Some((-d, g, ss));
        Some((d, false))
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
