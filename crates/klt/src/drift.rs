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
//! replaces `p` when it moved less than a bound. A larger correction (or an alignment that
//! breaks down) means the template no longer looks like the feature — Shi & Tomasi's feature
//! monitoring — and the track ends there ([`super::LostReason::Drift`]); its slot is refilled.
//! A window that reaches the image's edge cannot be aligned and keeps its frame-to-frame step.
//!
//! Ending such tracks, rather than keeping their frame-to-frame position, matters most on
//! grainy footage: once a track's correction is refused it drifts freely (the next step starts
//! from the drifted position, so the correction stays refused), and the features at occlusion
//! boundaries — a box's edge over the floor behind it, sliding as the camera moves — drift by
//! pixels over dozens of frames, smoothly enough to pass every frame-to-frame test. On the
//! Blender dev plate (400 features, pinhole; `examples/track_accuracy.rs`) keeping them left
//! 187 of 816 tracks over 1 px RMS against the true cameras (median 0.62 px); ending them,
//! 17 of 747 (median 0.32 px), and the solves' worst rotation error fell from 0.016° to 0.012°
//! (K given) and from 0.092° to 0.034° (lens unknown, distorted plate). Most of the ended
//! tracks are new corners that fail in their first or second frame (edges and grain that the
//! corner detector picks again); the tracks seen ≥ 5 frames fell from 816 to 747.
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
//! 0.51 px (150 features, pinhole plate; `cargo run --release -p vfxgraph-klt --example
//! track_accuracy -- ../shared/data/blender_plate_dev/pinhole 150`).

use nalgebra::{Matrix3, Matrix6, SMatrix, SVector, Vector2, Vector6};

use super::pyramid::GrayImage;

/// Alignment stops when a step moves no window corner by more than this many pixels.
const STEP_EPSILON: f64 = 0.01;

/// Why [`Template::align`] found no position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlignFailure {
    /// The warped window reached the image's edge: the frame cannot tell (a feature at the
    /// border, not one that drifted).
    LeftImage,
    /// The iteration broke down (a singular or non-finite step): the window does not look like
    /// the feature.
    Diverged,
}

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
    /// ∇T · ∂W/∂p at p = 0 for the affine warp W(u; p) = ((1 + p₁)u + p₃v + p₅,
    /// p₂u + (1 + p₄)v + p₆): one image per parameter, each row by row over the window (laid
    /// out by parameter so the gradient's sums are plain dot products).
    sd: [Vec<f32>; 6],
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
            sd: Default::default(),
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
        self.values.resize(n * n, 0.0);
        for s in &mut self.sd {
            s.resize(n * n, 0.0);
        }
        for j in 1..=n {
            let v = j as f32 - 1.0 - half as f32;
            for i in 1..=n {
                let k = (j - 1) * n + i - 1;
                let gx = 0.5 * (big[j * m + i + 1] - big[j * m + i - 1]);
                let gy = 0.5 * (big[(j + 1) * m + i] - big[(j - 1) * m + i]);
                let u = i as f32 - 1.0 - half as f32;
                self.values[k] = big[j * m + i];
                self.sd[0][k] = gx * u;
                self.sd[1][k] = gy * u;
                self.sd[2][k] = gx * v;
                self.sd[3][k] = gy * v;
                self.sd[4][k] = gx;
                self.sd[5][k] = gy;
            }
        }
        // Σ sd sdᵀ, one vectorized dot product per entry of the upper triangle.
        let mut h = Matrix6::<f64>::zeros();
        for r in 0..6 {
            for c in r..6 {
                h[(r, c)] = dot(&self.sd[r], &self.sd[c]);
                h[(c, r)] = h[(r, c)];
            }
        }
        self.h = h;
        // The structure tensor of the window: the translation block.
        let (a, b, c) = (h[(4, 4)], h[(4, 5)], h[(5, 5)]);
        // The translation part must show a measurable corner.
        let min_eig = 0.5 * (a + c - ((a - c) * (a - c) + 4.0 * b * b).sqrt());
        min_eig / (n * n) as f64 > 0.1 && h.try_inverse().is_some()
    }

    /// Aligns the template to `img` with the last frame's warp moved to `start`; returns the
    /// window centre's position, the RMS residual (0–255 gray levels) and the warp, or why
    /// there is none. [`Template::accept`] keeps the warp for the next frame.
    pub fn align(
        &self,
        img: &GrayImage,
        start: [f32; 2],
        max_iterations: u32,
    ) -> Result<([f32; 2], f32, Matrix3<f64>), AlignFailure> {
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
        let mut e = vec![0.0f32; n * n];
        let mut secant = Secant::new(self.h.fixed_view::<2, 2>(4, 4).into_owned());
        let mut base = w;
        for _ in 0..max_iterations {
            if !inside(&w) {
                return Err(AlignFailure::LeftImage);
            }
            self.residuals(img, &w, &mut e);
            let g = Vector2::new(dot(&self.sd[4], &e), dot(&self.sd[5], &e));
            let ss = dot(&e, &e);
            let (d, retry) = secant
                .step(g, ss, |m, g| m.try_inverse().map(|i| i * g))
                .ok_or(AlignFailure::Diverged)?;
            if retry {
                w = base;
            }
            base = w;
            // W ∘ W(Δ)⁻¹ moves the centre by the linear part applied to −Δ.
            w[(0, 2)] -= w[(0, 0)] * d[0] + w[(0, 1)] * d[1];
            w[(1, 2)] -= w[(1, 0)] * d[0] + w[(1, 1)] * d[1];
            if !(w[(0, 2)].is_finite() && w[(1, 2)].is_finite()) {
                return Err(AlignFailure::Diverged);
            }
            if d[0].hypot(d[1]) < STEP_EPSILON {
                break;
            }
        }
        let mut secant = Secant::new(self.h);
        let mut base = w;
        for _ in 0..max_iterations {
            if !inside(&w) {
                return Err(AlignFailure::LeftImage);
            }
            self.residuals(img, &w, &mut e);
            let g = Vector6::from_fn(|l, _| dot(&self.sd[l], &e));
            let ss = dot(&e, &e);
            let (d, retry) = secant
                .step(g, ss, |m, g| m.lu().solve(g))
                .ok_or(AlignFailure::Diverged)?;
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
            w *= dw.try_inverse().ok_or(AlignFailure::Diverged)?;
            if !w.iter().all(|x| x.is_finite()) {
                return Err(AlignFailure::Diverged);
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
            return Err(AlignFailure::LeftImage);
        }
        self.residuals(img, &w, &mut e);
        let ss = dot(&e, &e);
        Ok((
            [w[(0, 2)] as f32, w[(1, 2)] as f32],
            (ss / (n * n) as f64).sqrt() as f32,
            w,
        ))
    }

    /// The residuals `e_k = I(W(u_k)) − T(u_k)` of every window pixel k under the warp `w`,
    /// row by row. Every sample of a warp that passed `align`'s `inside` lies in the image (the
    /// window's corners do, and the warped window is their convex hull), so no clamping. The
    /// sample positions are stepped along each row in `f32` from the row's start, computed in
    /// `f64` (a window is at most a few dozen pixels wide: the error stays below 1e-5 px).
    #[inline]
    fn residuals(&self, img: &GrayImage, w: &Matrix3<f64>, e: &mut [f32]) {
        let n = 2 * self.half + 1;
        let h = self.half as f64;
        let (ax, ay) = (w[(0, 0)] as f32, w[(1, 0)] as f32);
        for (j, (row, t)) in e
            .chunks_exact_mut(n)
            .zip(self.values.chunks_exact(n))
            .enumerate()
        {
            let v = j as f64 - h;
            let x0 = (w[(0, 1)] * v + w[(0, 2)] - w[(0, 0)] * h) as f32;
            let y0 = (w[(1, 1)] * v + w[(1, 2)] - w[(1, 0)] * h) as f32;
            let mut done = 0;
            #[cfg(target_arch = "x86_64")]
            if simd::usable(img) {
                // SAFETY: `usable` checked AVX2 and the image's size.
                done = unsafe { simd::row_residuals(img, [x0, y0], [ax, ay], t, row) };
            }
            for i in done..n {
                let fi = i as f32;
                row[i] = img.sample_inside(x0 + ax * fi, y0 + ay * fi) - t[i];
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

/// The residual row of [`Template::residuals`] with AVX2 gathers: eight samples at a time,
/// each computed by exactly the operations of [`GrayImage::sample_inside`] in the same order
/// (no FMA), so the results are the portable loop's to the bit.
#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::*;

    use super::GrayImage;

    /// AVX2 is there and every pixel index fits the gathers' 32-bit offsets.
    pub(super) fn usable(img: &GrayImage) -> bool {
        std::is_x86_feature_detected!("avx2")
            && img.width >= 2
            && img.height >= 2
            && img.width * img.height < i32::MAX as usize / 2
    }

    /// `row[i] = I(start + i·step) − t[i]` for every `i` of a row of at least eight (a last
    /// partial chunk is done as the row's last eight, overlapping the one before: the same
    /// samples, computed again); returns how many were done (0 for a shorter row). Positions
    /// are clamped into the image (as `sample_inside` does), so a gather never reads outside
    /// it.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn row_residuals(
        img: &GrayImage,
        start: [f32; 2],
        step: [f32; 2],
        t: &[f32],
        row: &mut [f32],
    ) -> usize {
        let n = row.len().min(t.len());
        if n < 8 {
            return 0;
        }
        let (wd, ht) = (img.width as i32, img.height as i32);
        let data = img.data.as_ptr();
        let (x0, y0) = (_mm256_set1_ps(start[0]), _mm256_set1_ps(start[1]));
        let (ax, ay) = (_mm256_set1_ps(step[0]), _mm256_set1_ps(step[1]));
        let (xmax, ymax) = (_mm256_set1_epi32(wd - 2), _mm256_set1_epi32(ht - 2));
        let (zero, one, width) = (
            _mm256_setzero_si256(),
            _mm256_set1_ps(1.0),
            _mm256_set1_epi32(wd),
        );
        let mut next = 0;
        while next < n {
            // The chunk's first sample: the next one, or the row's last eight.
            let i = next.min(n - 8);
            let fi = _mm256_setr_ps(
                i as f32,
                (i + 1) as f32,
                (i + 2) as f32,
                (i + 3) as f32,
                (i + 4) as f32,
                (i + 5) as f32,
                (i + 6) as f32,
                (i + 7) as f32,
            );
            let x = _mm256_add_ps(x0, _mm256_mul_ps(ax, fi));
            let y = _mm256_add_ps(y0, _mm256_mul_ps(ay, fi));
            // Truncation is floor for x ≥ 0; NaN or negative becomes 0, as `as usize` does.
            let xi = _mm256_max_epi32(_mm256_min_epi32(_mm256_cvttps_epi32(x), xmax), zero);
            let yi = _mm256_max_epi32(_mm256_min_epi32(_mm256_cvttps_epi32(y), ymax), zero);
            let fx = _mm256_sub_ps(x, _mm256_cvtepi32_ps(xi));
            let fy = _mm256_sub_ps(y, _mm256_cvtepi32_ps(yi));
            let k = _mm256_add_epi32(_mm256_mullo_epi32(yi, width), xi);
            let p00 = _mm256_i32gather_ps::<4>(data, k);
            let p10 = _mm256_i32gather_ps::<4>(data.add(1), k);
            let p01 = _mm256_i32gather_ps::<4>(data.add(img.width), k);
            let p11 = _mm256_i32gather_ps::<4>(data.add(img.width + 1), k);
            let gx = _mm256_sub_ps(one, fx);
            let top = _mm256_add_ps(_mm256_mul_ps(p00, gx), _mm256_mul_ps(p10, fx));
            let bot = _mm256_add_ps(_mm256_mul_ps(p01, gx), _mm256_mul_ps(p11, fx));
            let v = _mm256_add_ps(
                _mm256_mul_ps(top, _mm256_sub_ps(one, fy)),
                _mm256_mul_ps(bot, fy),
            );
            let r = _mm256_sub_ps(v, _mm256_loadu_ps(t.as_ptr().add(i)));
            _mm256_storeu_ps(row.as_mut_ptr().add(i), r);
            next = i + 8;
        }
        n
    }
}

/// Σ aₖbₖ in eight `f32` lanes (so the compiler vectorizes it), summed in `f64`.
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f64 {
    let mut lanes = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            lanes[l] += x[l] * y[l];
        }
    }
    lanes.iter().map(|&l| l as f64).sum::<f64>() + tail as f64
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

    /// The AVX2 residual rows are the portable samples to the bit, over sheared, rotated and
    /// scaled warps, including windows touching the image's last row and column.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn simd_residuals_equal_the_portable_samples() {
        let img = GrayImage::from_fn(61, 47, |x, y| {
            ((x * 37 + y * 91) % 256) as f32 * 0.7 + (x as f32 * 0.3).sin()
        });
        if !simd::usable(&img) {
            eprintln!("no AVX2 here: nothing to compare");
            return;
        }
        let t: Vec<f32> = (0..29).map(|i| i as f32 * 1.5).collect();
        for (start, step) in [
            ([0.0f32, 0.0f32], [1.0f32, 0.0f32]),
            ([3.3, 40.9], [1.07, 0.21]),
            ([31.0, 45.99], [1.0, 0.0]),
            ([59.5, 2.25], [-0.93, 0.37]),
            ([1.2, 1.7], [2.05, 1.5]),
        ] {
            let mut row = vec![0.0f32; 29];
            let done = unsafe { simd::row_residuals(&img, start, step, &t, &mut row) };
            assert_eq!(done, 29);
            for i in 0..done {
                let fi = i as f32;
                let (x, y) = (start[0] + step[0] * fi, start[1] + step[1] * fi);
                let want = img.sample_inside(x, y) - t[i];
                assert_eq!(
                    row[i].to_bits(),
                    want.to_bits(),
                    "{start:?} {step:?} sample {i}"
                );
            }
        }
    }
}
