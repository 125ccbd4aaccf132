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
#[derive(Clone, Debug, PartialEq)]
pub struct LkParams {
    /// Side of the square window in pixels (odd; an even value is used as the next odd one).
    pub window: usize,
    /// Number of pyramid levels above the image (0 = no pyramid).
    pub levels: usize,
    /// Maximum number of refinement steps per level.
    pub max_iterations: u32,
    /// A level stops when the step is shorter than this (pixels).
    pub epsilon: f32,
    /// Smallest accepted eigenvalue of `G` divided by the window area, in (brightness/px)²;
    /// 0.1 here equals OpenCV's default `minEigThreshold` 1e-4 (OpenCV scales by 1/1024).
    pub min_eigen: f32,
}

impl Default for LkParams {
    fn default() -> Self {
        LkParams {
            window: 21,
            levels: 3,
            max_iterations: 30,
            epsilon: 0.01,
            min_eigen: 0.1,
        }
    }
}

impl LkParams {
    /// Half the window side: the window spans `[-half, half]` around the feature.
    pub fn half_window(&self) -> usize {
        self.window.max(3) / 2
    }

    /// Border the pyramids need so that windows of features inside the image never read
    /// outside the padded buffers.
    pub fn pad(&self) -> usize {
        self.half_window() + 10
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

/// Template of one window: brightness and gradient, bilinearly sampled (structure of
/// arrays). Rows are `ws` (the window side rounded up to 8) long so that the inner loops run
/// on whole 8-lane blocks; the extra columns have zero gradient and a zero mask.
struct Template {
    ws: usize,
    i: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    mask: Vec<f32>,
    avx2: bool,
}

/// Top-left integer corner (padded coordinates) and bilinear weights of a window centred on
/// `(x, y)`; `None` when the window (plus one pixel for interpolation) leaves the buffer.
#[inline]
fn window_origin(
    l: &Level,
    x: f32,
    y: f32,
    half: usize,
    win: usize,
    ws: usize,
) -> Option<(usize, [f32; 4])> {
    let fx = x - half as f32 + l.pad as f32;
    let fy = y - half as f32 + l.pad as f32;
    if !(fx.is_finite() && fy.is_finite()) || fx < 0.0 || fy < 0.0 {
        return None;
    }
    let (ix, iy) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - ix, fy - iy);
    let (ix, iy) = (ix as usize, iy as usize);
    if ix + ws + 1 > l.stride || iy + win + 1 > l.height + 2 * l.pad {
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

/// Bilinear resampling of `win` rows of one plane into a template plane (rows of `ws`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn sample_plane(
    src: &[f32],
    s: usize,
    o: usize,
    w: [f32; 4],
    win: usize,
    ws: usize,
    dst: &mut [f32],
    mask: &[f32],
) {
    for r in 0..win {
        let a = &src[o + r * s..][..ws + 1];
        let b = &src[o + (r + 1) * s..][..ws + 1];
        let d = &mut dst[r * ws..][..ws];
        let m = &mask[r * ws..][..ws];
        for blk in 0..ws / 8 {
            let c0 = blk * 8;
            let a9: &[f32] = &a[c0..c0 + 9];
            let b9: &[f32] = &b[c0..c0 + 9];
            let d8: &mut [f32] = &mut d[c0..c0 + 8];
            let m8: &[f32] = &m[c0..c0 + 8];
            for k in 0..8 {
                d8[k] = (w[0] * a9[k] + w[1] * a9[k + 1] + w[2] * b9[k] + w[3] * b9[k + 1]) * m8[k];
            }
        }
    }
}

#[inline(always)]
fn sample_template_generic(l: &Level, o: usize, w: [f32; 4], win: usize, t: &mut Template) {
    let (s, ws) = (l.stride, t.ws);
    sample_plane(&l.img, s, o, w, win, ws, &mut t.i, &t.mask);
    sample_plane(&l.gx, s, o, w, win, ws, &mut t.gx, &t.mask);
    sample_plane(&l.gy, s, o, w, win, ws, &mut t.gy, &t.mask);
}

/// Σ (J − I)·Ix, Σ (J − I)·Iy and Σ (J − I)² over the window, J sampled at origin `o` with
/// weights `w`. Eight independent accumulator lanes let the compiler vectorise.
#[inline(always)]
fn mismatch_generic(l: &Level, o: usize, w: [f32; 4], win: usize, t: &Template) -> (f32, f32, f32) {
    let (s, ws) = (l.stride, t.ws);
    let mut b1 = [0.0f32; 8];
    let mut b2 = [0.0f32; 8];
    let mut e = [0.0f32; 8];
    for r in 0..win {
        let a = &l.img[o + r * s..][..ws + 1];
        let b = &l.img[o + (r + 1) * s..][..ws + 1];
        let ti = &t.i[r * ws..][..ws];
        let tx = &t.gx[r * ws..][..ws];
        let ty = &t.gy[r * ws..][..ws];
        let tm = &t.mask[r * ws..][..ws];
        for blk in 0..ws / 8 {
            let c0 = blk * 8;
            let a9: &[f32] = &a[c0..c0 + 9];
            let b9: &[f32] = &b[c0..c0 + 9];
            let (i8, x8, y8, m8) = (
                &ti[c0..c0 + 8],
                &tx[c0..c0 + 8],
                &ty[c0..c0 + 8],
                &tm[c0..c0 + 8],
            );
            for k in 0..8 {
                let j = w[0] * a9[k] + w[1] * a9[k + 1] + w[2] * b9[k] + w[3] * b9[k + 1];
                let d = (j - i8[k]) * m8[k];
                b1[k] += d * x8[k];
                b2[k] += d * y8[k];
                e[k] += d * d;
            }
        }
    }
    (b1.iter().sum(), b2.iter().sum(), e.iter().sum())
}

/// The hot loops compiled twice: for the baseline target and with AVX2 (eight f32 lanes,
/// chosen at run time). Without FMA both compute exactly the same sums in the same order,
/// so results do not depend on the CPU.
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{mismatch_generic, sample_template_generic, Level, Template};

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn mismatch_avx2(
        l: &Level,
        o: usize,
        w: [f32; 4],
        win: usize,
        t: &Template,
    ) -> (f32, f32, f32) {
        mismatch_generic(l, o, w, win, t)
    }

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sample_template_avx2(
        l: &Level,
        o: usize,
        w: [f32; 4],
        win: usize,
        t: &mut Template,
    ) {
        sample_template_generic(l, o, w, win, t)
    }

    pub(super) fn has_avx2() -> bool {
        std::is_x86_feature_detected!("avx2")
    }
}

#[inline]
fn mismatch(l: &Level, o: usize, w: [f32; 4], win: usize, t: &Template) -> (f32, f32, f32) {
    #[cfg(target_arch = "x86_64")]
    if t.avx2 {
        // SAFETY: `t.avx2` is set only when the CPU reports AVX2.
        return unsafe { simd::mismatch_avx2(l, o, w, win, t) };
    }
    mismatch_generic(l, o, w, win, t)
}

#[inline]
fn sample_template(l: &Level, o: usize, w: [f32; 4], win: usize, t: &mut Template) {
    #[cfg(target_arch = "x86_64")]
    if t.avx2 {
        // SAFETY: `t.avx2` is set only when the CPU reports AVX2.
        return unsafe { simd::sample_template_avx2(l, o, w, win, t) };
    }
    sample_template_generic(l, o, w, win, t)
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
    params: &LkParams,
) -> LkResult {
    let half = params.half_window();
    let win = 2 * half + 1;
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
    let ws = win.div_ceil(8) * 8;
    let mut t = Template {
        ws,
        i: vec![0.0; ws * win],
        gx: vec![0.0; ws * win],
        gy: vec![0.0; ws * win],
        mask: (0..ws * win)
            .map(|k| if k % ws < win { 1.0 } else { 0.0 })
            .collect(),
        #[cfg(target_arch = "x86_64")]
        avx2: simd::has_avx2(),
        #[cfg(not(target_arch = "x86_64"))]
        avx2: false,
    };
    let top = n_levels - 1;
    let scale = 1.0 / (1u32 << top) as f32;
    let g = guess.unwrap_or(p);
    let mut next_pt = [g[0] * scale, g[1] * scale];
    let area = (win * win) as f32;
    for level in (0..n_levels).rev() {
        let s = 1.0 / (1u32 << level) as f32;
        let (lp, ln) = (&prev.levels[level], &next.levels[level]);
        let prev_pt = [p[0] * s, p[1] * s];
        let Some((o, w)) = window_origin(lp, prev_pt[0], prev_pt[1], half, win, ws) else {
            if level == 0 {
                return lost(p, LostReason::LeftImage);
            }
            next_pt = [next_pt[0] * 2.0, next_pt[1] * 2.0];
            continue;
        };
        sample_template(lp, o, w, win, &mut t);
        let (mut g11, mut g12, mut g22) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
        for (x8, y8) in t.gx.chunks_exact(8).zip(t.gy.chunks_exact(8)) {
            for k in 0..8 {
                g11[k] += x8[k] * x8[k];
                g12[k] += x8[k] * y8[k];
                g22[k] += y8[k] * y8[k];
            }
        }
        let a11: f32 = g11.iter().sum();
        let a12: f32 = g12.iter().sum();
        let a22: f32 = g22.iter().sum();
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
            let Some((oj, wj)) = window_origin(ln, next_pt[0], next_pt[1], half, win, ws) else {
                inside = false;
                break;
            };
            let (b1, b2, _) = mismatch(ln, oj, wj, win, &t);
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
            let Some((oj, wj)) = window_origin(ln, x[0], x[1], half, win, ws) else {
                return lost(x, LostReason::LeftImage);
            };
            let (_, _, e) = mismatch(ln, oj, wj, win, &t);
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
    params: &LkParams,
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
        .map(|(i, &p)| track_point(prev, next, p, guesses.map(|g| g[i]), params))
        .collect())
}
