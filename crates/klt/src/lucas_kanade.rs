//! Following windows (book 6.3): pyramidal Lucas–Kanade (B. D. Lucas and T. Kanade, IJCAI 1981;
//! J.-Y. Bouguet, "Pyramidal Implementation of the Lucas Kanade Feature Tracker", Intel 2000).
//!
//! For a window `w` around a feature `u` of image I, find the disparity `h` minimising
//! `Σ_w [J(x + h) − I(x)]²` (book eq. 6.2). Each step solves the book's 2×2 system
//! `G h = b` with `G = Σ ∇I ∇Iᵀ` (the template's Scharr gradient, fixed for the window) and
//! `b = −Σ (J − I) ∇I`, re-sampling J bilinearly at the moved window, until the step is
//! shorter than `epsilon` or `max_iterations` steps were made. The coarsest pyramid level is
//! solved first and its result, doubled, starts the next finer level (Bouguet, section 2.2).
//!
//! A feature is lost (book 6.5) when its window leaves the image, when `G` is singular (its
//! smaller eigenvalue per window pixel is below `min_eigen`), or — decided by the caller — when
//! the residual exceeds a threshold. The residual reported is the root mean square of
//! `J(x + h) − I(x)` over the window at level 0, in the 0–255 brightness scale.

use rayon::prelude::*;

use super::pyramid::{Level, Pyramid};
use super::tracks::LostReason;
use super::KltError;

/// Parameters of pyramidal Lucas–Kanade (book 6.3; Bouguet 2000). Defaults follow OpenCV's
/// `calcOpticalFlowPyrLK`: a 21×21 window, 3 pyramid levels above the image, 30 iterations or
/// a step below 0.01 px.
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct LkOptions {
    /// LK window side, pixels (odd)
    ///
    /// Side of the square window in pixels (an even value is used as the next odd one).
    #[param(range = 3..=255)]
    pub window: usize,
    /// pyramid levels above the image
    ///
    /// Number of pyramid levels above the image (0 = no pyramid).
    #[param(range = 0..=12)]
    pub levels: usize,
    /// maximum LK iterations per level
    #[param(name = "iterations", range = 1..=1000)]
    pub max_iterations: u32,
    /// LK stops when a step is shorter than this, pixels
    #[param(range = 0.0..=10.0)]
    pub epsilon: f32,
    #[param(skip)]
    /// Smallest accepted eigenvalue of `G` divided by the window area, in (brightness/px)²;
    /// 0.1 here equals OpenCV's default `minEigThreshold` 1e-4 (OpenCV scales by 1/1024).
    pub min_eigen: f32,
}

impl Default for LkOptions {
    fn default() -> Self {
        LkOptions {
            window: 21,
            levels: 3,
            max_iterations: 30,
            epsilon: 0.01,
            min_eigen: 0.1,
        }
    }
}

impl LkOptions {
    /// Half the window side: the window spans `[-half, half]` around the feature.
    pub fn half_window(&self) -> usize {
        self.window.max(3) / 2
    }

    /// Border the pyramids need so that windows of features inside the image (and their
    /// resampled template with its 8-lane rows) never read outside the padded buffers.
    pub fn pad(&self) -> usize {
        let (half, win) = (self.half_window(), 2 * self.half_window() + 1);
        (half + 10).max(win.div_ceil(8) * 8 + 8 - half)
    }

    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), KltError> {
        if self.window < 3 || self.window > 255 {
            return Err(KltError::BadParam(format!(
                "window {} is outside 3..=255",
                self.window
            )));
        }
        if self.levels > 12 {
            return Err(KltError::BadParam(format!(
                "{} pyramid levels (at most 12)",
                self.levels
            )));
        }
        let ok = |v: f32| v.is_finite() && v >= 0.0;
        if !ok(self.epsilon) || !ok(self.min_eigen) {
            return Err(KltError::BadParam(
                "epsilon and min_eigen must be finite and non-negative".into(),
            ));
        }
        Ok(())
    }
}

/// The outcome for one feature of [`track_points`] (book 6.3, 6.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LkResult {
    /// Position found in the next image (the last estimate when lost).
    pub pos: [f32; 2],
    /// RMS of `J(x + h) − I(x)` over the window at level 0 (brightness, 0–255 scale);
    /// infinite when it could not be evaluated.
    pub residual: f32,
    /// `None` when tracked, else why the feature was lost.
    pub lost: Option<LostReason>,
}

/// Per-thread scratch of one feature's window (structure of arrays, allocated once per
/// thread, not per feature). Rows of the template are `ws` (the window side rounded up to 8)
/// long so that the inner loops run on whole 8-lane blocks; the extra columns hold zero
/// brightness and gradient, so they add nothing to `G` and `b`.
pub(crate) struct Window {
    /// Window side.
    win: usize,
    /// Template row length: `win` rounded up to 8.
    ws: usize,
    /// Patch row length: `ws + 8`.
    pw: usize,
    /// `(win + 2) × pw` bilinear samples of I around the window (one pixel of margin for the
    /// gradient).
    patch: Vec<f32>,
    /// Template brightness, `win × ws`.
    i: Vec<f32>,
    /// Template Scharr gradient, `win × ws` each.
    gx: Vec<f32>,
    gy: Vec<f32>,
    /// 1 in the first `win` columns of a row, 0 after.
    mask: Vec<f32>,
    avx2: bool,
}

impl Window {
    pub(crate) fn new(params: &LkOptions) -> Window {
        let win = 2 * params.half_window() + 1;
        let ws = win.div_ceil(8) * 8;
        let pw = ws + 8;
        Window {
            win,
            ws,
            pw,
            patch: vec![0.0; (win + 2) * pw],
            i: vec![0.0; win * ws],
            gx: vec![0.0; win * ws],
            gy: vec![0.0; win * ws],
            mask: (0..ws).map(|c| if c < win { 1.0 } else { 0.0 }).collect(),
            #[cfg(target_arch = "x86_64")]
            avx2: simd::has_avx2(),
            #[cfg(not(target_arch = "x86_64"))]
            avx2: false,
        }
    }
}

/// Integer corner (padded coordinates) of the `cols × rows` block of pixels read to sample a
/// window centred on `(x, y)` with `margin` extra pixels before it, and the bilinear weights;
/// `None` when that block leaves the padded buffer.
#[inline]
fn locate(
    l: &Level,
    [x, y]: [f32; 2],
    half: usize,
    margin: usize,
    cols: usize,
    rows: usize,
) -> Option<(usize, [f32; 4])> {
    let fx = x - half as f32 + l.pad as f32;
    let fy = y - half as f32 + l.pad as f32;
    if !(fx.is_finite() && fy.is_finite()) || fx < margin as f32 || fy < margin as f32 {
        return None;
    }
    let (ix, iy) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - ix, fy - iy);
    let (ix, iy) = (ix as usize - margin, iy as usize - margin);
    if ix + cols > l.stride || iy + rows > l.height + 2 * l.pad {
        return None;
    }
    Some((
        iy * l.stride + ix,
        [
            (1.0 - ax) * (1.0 - ay),
            ax * (1.0 - ay),
            (1.0 - ax) * ay,
            ax * ay,
        ],
    ))
}

/// Where the template patch of a window at `p` starts (one pixel of margin for the gradient).
#[inline]
fn locate_template(l: &Level, p: [f32; 2], half: usize, t: &Window) -> Option<(usize, [f32; 4])> {
    locate(l, p, half, 1, t.pw + 1, t.win + 3)
}

/// Where the window at `p` of the next image starts.
#[inline]
fn locate_window(l: &Level, p: [f32; 2], half: usize, t: &Window) -> Option<(usize, [f32; 4])> {
    locate(l, p, half, 0, t.ws + 1, t.win + 1)
}

/// Samples the template of I (brightness and Scharr gradient) at origin `o` with weights `w`
/// and returns `G = Σ ∇I ∇Iᵀ` as (g11, g12, g22). The gradient is the Scharr filter of the
/// bilinearly resampled patch, equal to resampling the Scharr image (both are convolutions).
/// Eight independent accumulator lanes let the compiler vectorise.
#[inline(always)]
fn template_generic(l: &Level, o: usize, w: [f32; 4], t: &mut Window) -> (f32, f32, f32) {
    let (s, win, ws, pw) = (l.stride, t.win, t.ws, t.pw);
    for r in 0..win + 2 {
        let a = &l.img[o + r * s..][..pw + 1];
        let b = &l.img[o + (r + 1) * s..][..pw + 1];
        let d = &mut t.patch[r * pw..][..pw];
        for blk in 0..pw / 8 {
            let c0 = blk * 8;
            let a9: &[f32] = &a[c0..c0 + 9];
            let b9: &[f32] = &b[c0..c0 + 9];
            let d8: &mut [f32] = &mut d[c0..c0 + 8];
            for k in 0..8 {
                d8[k] = w[0] * a9[k] + w[1] * a9[k + 1] + w[2] * b9[k] + w[3] * b9[k + 1];
            }
        }
    }
    let (mut g11, mut g12, mut g22) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
    for r in 0..win {
        let p0 = &t.patch[r * pw..][..pw];
        let p1 = &t.patch[(r + 1) * pw..][..pw];
        let p2 = &t.patch[(r + 2) * pw..][..pw];
        let ti = &mut t.i[r * ws..][..ws];
        let tx = &mut t.gx[r * ws..][..ws];
        let ty = &mut t.gy[r * ws..][..ws];
        for blk in 0..ws / 8 {
            let c0 = blk * 8;
            let (q0, q1, q2) = (&p0[c0..c0 + 10], &p1[c0..c0 + 10], &p2[c0..c0 + 10]);
            let m8 = &t.mask[c0..c0 + 8];
            let (i8, x8, y8) = (
                &mut ti[c0..c0 + 8],
                &mut tx[c0..c0 + 8],
                &mut ty[c0..c0 + 8],
            );
            for k in 0..8 {
                let dx = 3.0 * (q0[k + 2] - q0[k])
                    + 10.0 * (q1[k + 2] - q1[k])
                    + 3.0 * (q2[k + 2] - q2[k]);
                let dy = 3.0 * (q2[k] - q0[k])
                    + 10.0 * (q2[k + 1] - q0[k + 1])
                    + 3.0 * (q2[k + 2] - q0[k + 2]);
                let gx = dx * (1.0 / 32.0) * m8[k];
                let gy = dy * (1.0 / 32.0) * m8[k];
                i8[k] = q1[k + 1] * m8[k];
                x8[k] = gx;
                y8[k] = gy;
                g11[k] += gx * gx;
                g12[k] += gx * gy;
                g22[k] += gy * gy;
            }
        }
    }
    (g11.iter().sum(), g12.iter().sum(), g22.iter().sum())
}

/// Σ (J − I)·Ix and Σ (J − I)·Iy over the window, J sampled at origin `o` with weights `w`
/// (the template's extra columns have zero gradient, so no mask is needed).
#[inline(always)]
fn mismatch_generic(l: &Level, o: usize, w: [f32; 4], t: &Window) -> (f32, f32) {
    let (s, ws) = (l.stride, t.ws);
    let mut b1 = [0.0f32; 8];
    let mut b2 = [0.0f32; 8];
    for r in 0..t.win {
        let a = &l.img[o + r * s..][..ws + 1];
        let b = &l.img[o + (r + 1) * s..][..ws + 1];
        let ti = &t.i[r * ws..][..ws];
        let tx = &t.gx[r * ws..][..ws];
        let ty = &t.gy[r * ws..][..ws];
        for blk in 0..ws / 8 {
            let c0 = blk * 8;
            let a9: &[f32] = &a[c0..c0 + 9];
            let b9: &[f32] = &b[c0..c0 + 9];
            let (i8, x8, y8) = (&ti[c0..c0 + 8], &tx[c0..c0 + 8], &ty[c0..c0 + 8]);
            for k in 0..8 {
                let j = w[0] * a9[k] + w[1] * a9[k + 1] + w[2] * b9[k] + w[3] * b9[k + 1];
                let d = j - i8[k];
                b1[k] += d * x8[k];
                b2[k] += d * y8[k];
            }
        }
    }
    (b1.iter().sum(), b2.iter().sum())
}

/// Σ (J − I)² over the window (the residual's square sum).
fn square_error(l: &Level, o: usize, w: [f32; 4], t: &Window) -> f32 {
    let (s, ws) = (l.stride, t.ws);
    let mut e = 0.0f32;
    for r in 0..t.win {
        let a = &l.img[o + r * s..][..ws + 1];
        let b = &l.img[o + (r + 1) * s..][..ws + 1];
        let ti = &t.i[r * ws..][..ws];
        for c in 0..t.win {
            let j = w[0] * a[c] + w[1] * a[c + 1] + w[2] * b[c] + w[3] * b[c + 1];
            let d = j - ti[c];
            e += d * d;
        }
    }
    e
}

/// The hot loops written with AVX2 intrinsics (eight f32 lanes, chosen at run time). They
/// perform exactly the operations of the portable versions above, lane for lane and in the
/// same order, without FMA, so results do not depend on the CPU.
#[cfg(target_arch = "x86_64")]
mod simd {
    use std::arch::x86_64::*;

    use super::{Level, Window};

    pub(super) fn has_avx2() -> bool {
        std::is_x86_feature_detected!("avx2")
    }

    #[inline(always)]
    unsafe fn hsum(v: __m256) -> f32 {
        let mut a = [0.0f32; 8];
        _mm256_storeu_ps(a.as_mut_ptr(), v);
        a.iter().sum()
    }

    /// `w0·a[k] + w1·a[k+1] + w2·b[k] + w3·b[k+1]` for eight `k`, in that order.
    #[inline(always)]
    unsafe fn bilinear(a: *const f32, b: *const f32, w: &[__m256; 4]) -> __m256 {
        let s = _mm256_add_ps(
            _mm256_mul_ps(w[0], _mm256_loadu_ps(a)),
            _mm256_mul_ps(w[1], _mm256_loadu_ps(a.add(1))),
        );
        let s = _mm256_add_ps(s, _mm256_mul_ps(w[2], _mm256_loadu_ps(b)));
        _mm256_add_ps(s, _mm256_mul_ps(w[3], _mm256_loadu_ps(b.add(1))))
    }

    #[inline(always)]
    unsafe fn weights(w: [f32; 4]) -> [__m256; 4] {
        [
            _mm256_set1_ps(w[0]),
            _mm256_set1_ps(w[1]),
            _mm256_set1_ps(w[2]),
            _mm256_set1_ps(w[3]),
        ]
    }

    /// AVX2 [`super::mismatch_generic`].
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn mismatch_avx2(l: &Level, o: usize, w: [f32; 4], t: &Window) -> (f32, f32) {
        let (s, ws, win) = (l.stride, t.ws, t.win);
        // `locate_window` guarantees this; checked once here instead of per load.
        assert!(o + win * s + ws < l.img.len() && t.i.len() >= win * ws);
        let w = weights(w);
        let (mut b1, mut b2) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        let img = l.img.as_ptr();
        for r in 0..win {
            let a = img.add(o + r * s);
            let b = a.add(s);
            let (ti, tx, ty) = (
                t.i.as_ptr().add(r * ws),
                t.gx.as_ptr().add(r * ws),
                t.gy.as_ptr().add(r * ws),
            );
            let mut c = 0;
            while c < ws {
                let j = bilinear(a.add(c), b.add(c), &w);
                let d = _mm256_sub_ps(j, _mm256_loadu_ps(ti.add(c)));
                b1 = _mm256_add_ps(b1, _mm256_mul_ps(d, _mm256_loadu_ps(tx.add(c))));
                b2 = _mm256_add_ps(b2, _mm256_mul_ps(d, _mm256_loadu_ps(ty.add(c))));
                c += 8;
            }
        }
        (hsum(b1), hsum(b2))
    }

    /// AVX2 [`super::template_generic`].
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn template_avx2(
        l: &Level,
        o: usize,
        w: [f32; 4],
        t: &mut Window,
    ) -> (f32, f32, f32) {
        let (s, win, ws, pw) = (l.stride, t.win, t.ws, t.pw);
        // `locate_template` guarantees this; checked once here instead of per load.
        assert!(o + (win + 2) * s + pw < l.img.len());
        assert!(t.patch.len() >= (win + 2) * pw && t.i.len() >= win * ws && t.mask.len() >= ws);
        assert!(t.gx.len() >= win * ws && t.gy.len() >= win * ws && ws + 2 <= pw);
        let wv = weights(w);
        let img = l.img.as_ptr();
        let patch = t.patch.as_mut_ptr();
        for r in 0..win + 2 {
            let a = img.add(o + r * s);
            let b = a.add(s);
            let d = patch.add(r * pw);
            let mut c = 0;
            while c < pw {
                _mm256_storeu_ps(d.add(c), bilinear(a.add(c), b.add(c), &wv));
                c += 8;
            }
        }
        let (three, ten, k32) = (
            _mm256_set1_ps(3.0),
            _mm256_set1_ps(10.0),
            _mm256_set1_ps(1.0 / 32.0),
        );
        let (mut g11, mut g12, mut g22) = (
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
            _mm256_setzero_ps(),
        );
        let patch = t.patch.as_ptr();
        for r in 0..win {
            let (p0, p1, p2) = (
                patch.add(r * pw),
                patch.add((r + 1) * pw),
                patch.add((r + 2) * pw),
            );
            let (ti, tx, ty) = (
                t.i.as_mut_ptr().add(r * ws),
                t.gx.as_mut_ptr().add(r * ws),
                t.gy.as_mut_ptr().add(r * ws),
            );
            let mut c = 0;
            while c < ws {
                let ld = |p: *const f32, k: usize| _mm256_loadu_ps(p.add(c + k));
                let m = _mm256_loadu_ps(t.mask.as_ptr().add(c));
                let dx = _mm256_add_ps(
                    _mm256_add_ps(
                        _mm256_mul_ps(three, _mm256_sub_ps(ld(p0, 2), ld(p0, 0))),
                        _mm256_mul_ps(ten, _mm256_sub_ps(ld(p1, 2), ld(p1, 0))),
                    ),
                    _mm256_mul_ps(three, _mm256_sub_ps(ld(p2, 2), ld(p2, 0))),
                );
                let dy = _mm256_add_ps(
                    _mm256_add_ps(
                        _mm256_mul_ps(three, _mm256_sub_ps(ld(p2, 0), ld(p0, 0))),
                        _mm256_mul_ps(ten, _mm256_sub_ps(ld(p2, 1), ld(p0, 1))),
                    ),
                    _mm256_mul_ps(three, _mm256_sub_ps(ld(p2, 2), ld(p0, 2))),
                );
                let gx = _mm256_mul_ps(_mm256_mul_ps(dx, k32), m);
                let gy = _mm256_mul_ps(_mm256_mul_ps(dy, k32), m);
                _mm256_storeu_ps(ti.add(c), _mm256_mul_ps(ld(p1, 1), m));
                _mm256_storeu_ps(tx.add(c), gx);
                _mm256_storeu_ps(ty.add(c), gy);
                g11 = _mm256_add_ps(g11, _mm256_mul_ps(gx, gx));
                g12 = _mm256_add_ps(g12, _mm256_mul_ps(gx, gy));
                g22 = _mm256_add_ps(g22, _mm256_mul_ps(gy, gy));
                c += 8;
            }
        }
        (hsum(g11), hsum(g12), hsum(g22))
    }
}

#[inline]
fn mismatch(l: &Level, o: usize, w: [f32; 4], t: &Window) -> (f32, f32) {
    #[cfg(target_arch = "x86_64")]
    if t.avx2 {
        // SAFETY: `t.avx2` is set only when the CPU reports AVX2.
        return unsafe { simd::mismatch_avx2(l, o, w, t) };
    }
    mismatch_generic(l, o, w, t)
}

#[inline]
fn template(l: &Level, o: usize, w: [f32; 4], t: &mut Window) -> (f32, f32, f32) {
    #[cfg(target_arch = "x86_64")]
    if t.avx2 {
        // SAFETY: `t.avx2` is set only when the CPU reports AVX2.
        return unsafe { simd::template_avx2(l, o, w, t) };
    }
    template_generic(l, o, w, t)
}

/// For a window reaching past the image edge (`p` at level `l`): sets the template gradient
/// to the bilinear interpolation of the Scharr image extended by zeros, as OpenCV does, so
/// that the mirrored border — which moves the wrong way — adds nothing to `G` and `b`, and
/// returns the new `G`. `None` (nothing to do) when every sample lies inside the image.
fn zero_gradient_outside(
    l: &Level,
    p: [f32; 2],
    half: usize,
    t: &mut Window,
) -> Option<(f32, f32, f32)> {
    let (fx, fy) = (p[0] - half as f32, p[1] - half as f32);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0, fy - y0);
    let (x0, y0) = (x0 as isize, y0 as isize);
    let (w, h, win) = (l.width as isize, l.height as isize, t.win as isize);
    if x0 >= 0 && y0 >= 0 && x0 + win < w && y0 + win < h {
        return None;
    }
    let wts = [
        (0, 0, (1.0 - ax) * (1.0 - ay)),
        (1, 0, ax * (1.0 - ay)),
        (0, 1, (1.0 - ax) * ay),
        (1, 1, ax * ay),
    ];
    let inside = |x: isize, y: isize| x >= 0 && y >= 0 && x < w && y < h;
    for r in 0..win {
        for c in 0..win {
            let (x, y) = (x0 + c, y0 + r);
            if inside(x, y) && inside(x + 1, y + 1) {
                continue;
            }
            let mut g = [0.0f32; 2];
            for &(dx, dy, wt) in &wts {
                if inside(x + dx, y + dy) {
                    let s = l.scharr_at((x + dx) as usize, (y + dy) as usize);
                    g[0] += wt * s[0];
                    g[1] += wt * s[1];
                }
            }
            let k = r as usize * t.ws + c as usize;
            t.gx[k] = g[0];
            t.gy[k] = g[1];
        }
    }
    let (mut a11, mut a12, mut a22) = (0.0f32, 0.0f32, 0.0f32);
    for (&gx, &gy) in t.gx.iter().zip(&t.gy) {
        a11 += gx * gx;
        a12 += gx * gy;
        a22 += gy * gy;
    }
    Some((a11, a12, a22))
}

/// Tracks one feature from `prev` to `next` (book 6.3; Bouguet 2000, section 2.4). `guess`
/// is an initial estimate of the position in `next` (default: the same position). Both
/// pyramids must come from images of the same size, built with at least `params.pad()`
/// border pixels; the number of levels used is the smaller of the two pyramids' and
/// `params.levels + 1`.
pub fn track_point(
    prev: &Pyramid,
    next: &Pyramid,
    p: [f32; 2],
    guess: Option<[f32; 2]>,
    params: &LkOptions,
) -> LkResult {
    track_point_in(&mut Window::new(params), prev, next, p, guess, params)
}

/// [`track_point`] with caller-provided scratch.
fn track_point_in(
    t: &mut Window,
    prev: &Pyramid,
    next: &Pyramid,
    p: [f32; 2],
    guess: Option<[f32; 2]>,
    params: &LkOptions,
) -> LkResult {
    let half = params.half_window();
    let win = t.win;
    let n_levels = prev
        .levels
        .len()
        .min(next.levels.len())
        .min(params.levels + 1);
    let (w0, h0) = prev.size();
    let lost = |pos: [f32; 2], why| LkResult {
        pos,
        residual: f32::INFINITY,
        lost: Some(why),
    };
    if !(p[0].is_finite() && p[1].is_finite()) {
        return lost(p, LostReason::LeftImage);
    }
    let top = n_levels - 1;
    let scale = 1.0 / (1u32 << top) as f32;
    let g = guess.unwrap_or(p);
    let mut next_pt = [g[0] * scale, g[1] * scale];
    let area = (win * win) as f32;
    for level in (0..n_levels).rev() {
        let s = 1.0 / (1u32 << level) as f32;
        let (lp, ln) = (&prev.levels[level], &next.levels[level]);
        let prev_pt = [p[0] * s, p[1] * s];
        let Some((o, w)) = locate_template(lp, prev_pt, half, t) else {
            if level == 0 {
                return lost(p, LostReason::LeftImage);
            }
            next_pt = [next_pt[0] * 2.0, next_pt[1] * 2.0];
            continue;
        };
        let (mut a11, mut a12, mut a22) = template(lp, o, w, t);
        if let Some(g) = zero_gradient_outside(lp, prev_pt, half, t) {
            (a11, a12, a22) = g;
        }
        let det = a11 * a22 - a12 * a12;
        let min_eig =
            (a11 + a22 - ((a11 - a22) * (a11 - a22) + 4.0 * a12 * a12).sqrt()) / (2.0 * area);
        if min_eig.is_nan()
            || min_eig < params.min_eigen
            || det < f32::EPSILON * a11.max(a22).max(1.0).powi(2)
        {
            if level == 0 {
                return lost(next_pt, LostReason::Singular);
            }
            next_pt = [next_pt[0] * 2.0, next_pt[1] * 2.0];
            continue;
        }
        let inv = 1.0 / det;
        let mut prev_delta = [0.0f32; 2];
        let mut inside = true;
        for it in 0..params.max_iterations {
            let Some((oj, wj)) = locate_window(ln, next_pt, half, t) else {
                inside = false;
                break;
            };
            let (b1, b2) = mismatch(ln, oj, wj, t);
            let delta = [(a12 * b2 - a22 * b1) * inv, (a12 * b1 - a11 * b2) * inv];
            next_pt[0] += delta[0];
            next_pt[1] += delta[1];
            if delta[0] * delta[0] + delta[1] * delta[1] <= params.epsilon * params.epsilon {
                break;
            }
            if it > 0
                && (delta[0] + prev_delta[0]).abs() < 0.01
                && (delta[1] + prev_delta[1]).abs() < 0.01
            {
                // Oscillating between two positions: take the middle (as OpenCV).
                next_pt[0] -= delta[0] * 0.5;
                next_pt[1] -= delta[1] * 0.5;
                break;
            }
            prev_delta = delta;
        }
        if level == 0 {
            let x = next_pt;
            let in_image =
                x[0] >= 0.0 && x[1] >= 0.0 && x[0] <= (w0 - 1) as f32 && x[1] <= (h0 - 1) as f32;
            if !(inside && in_image) {
                return lost(x, LostReason::LeftImage);
            }
            let Some((oj, wj)) = locate_window(ln, x, half, t) else {
                return lost(x, LostReason::LeftImage);
            };
            let e = square_error(ln, oj, wj, t);
            return LkResult {
                pos: x,
                residual: (e / area).sqrt(),
                lost: None,
            };
        }
        next_pt = [next_pt[0] * 2.0, next_pt[1] * 2.0];
    }
    lost(next_pt, LostReason::LeftImage)
}

/// Tracks every point from `prev` to `next` in parallel (rayon); results are in the order of
/// `points` and do not depend on the number of threads (book 6.3; Bouguet 2000).
pub fn track_points(
    prev: &Pyramid,
    next: &Pyramid,
    points: &[[f32; 2]],
    guesses: Option<&[[f32; 2]]>,
    params: &LkOptions,
) -> Result<Vec<LkResult>, KltError> {
    params.validate()?;
    if prev.size() != next.size() {
        return Err(KltError::SizeMismatch {
            expected: prev.size(),
            found: next.size(),
        });
    }
    let pad = params.pad();
    if prev.levels[0].pad < pad || next.levels[0].pad < pad {
        return Err(KltError::BadParam(format!(
            "pyramids need a border of {pad} pixels for a {}-pixel window",
            params.window
        )));
    }
    if let Some(g) = guesses {
        if g.len() != points.len() {
            return Err(KltError::BadParam(format!(
                "{} guesses for {} points",
                g.len(),
                points.len()
            )));
        }
    }
    Ok(points
        .par_iter()
        .enumerate()
        .with_min_len(8)
        .map_init(
            || Window::new(params),
            |t, (i, &p)| track_point_in(t, prev, next, p, guesses.map(|g| g[i]), params),
        )
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GrayImage;

    /// The AVX2 loops and the portable ones give the same bits (no FMA, same order), so the
    /// tracks do not depend on the CPU. (Without AVX2 the test says so and checks only the
    /// gradient.)
    #[test]
    fn simd_and_portable_loops_agree_bit_for_bit() {
        let simd = crate::has_avx2_or_say_so("simd_and_portable_loops_agree_bit_for_bit");
        let img = GrayImage::from_fn(90, 70, |x, y| {
            let (x, y) = (x as f32, y as f32);
            120.0 + 50.0 * (0.31 * x).sin() * (0.23 * y).cos() + 30.0 * (0.07 * x * y).sin()
        });
        let params = LkOptions::default();
        let pyr = Pyramid::new(&img, 1, params.pad()).unwrap();
        let l = &pyr.levels[0];
        let mut a = Window::new(&params);
        let mut b = Window::new(&params);
        assert_eq!(
            a.avx2, simd,
            "the window takes the AVX2 loops when the CPU has them"
        );
        b.avx2 = false;
        let half = params.half_window();
        for p in [[20.3f32, 31.7], [45.0, 12.25], [0.6, 69.4], [89.0, 0.0]] {
            let (o, w) = locate_template(l, p, half, &a).unwrap();
            let ga = template(l, o, w, &mut a);
            let gb = template_generic(l, o, w, &mut b);
            if simd {
                assert_eq!(ga, gb);
                assert_eq!((&a.i, &a.gx, &a.gy), (&b.i, &b.gx, &b.gy));
                let q = [p[0] + 0.37, p[1] - 0.61];
                let (oj, wj) = locate_window(l, q, half, &a).unwrap();
                assert_eq!(mismatch(l, oj, wj, &a), mismatch_generic(l, oj, wj, &b));
            }
            // The template's gradient is the image's Scharr gradient resampled.
            let (x, y) = (p[0].floor() as usize, p[1].floor() as usize);
            if (p[0] - x as f32).abs() < 1e-6 && (p[1] - y as f32).abs() < 1e-6 {
                let g = l.scharr_at(x, y);
                let c = half * a.ws + half;
                assert!((a.gx[c] - g[0]).abs() < 1e-4 && (a.gy[c] - g[1]).abs() < 1e-4);
            }
        }
    }
}
