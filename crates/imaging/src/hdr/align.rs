//! Alignment of hand-held brackets by median threshold bitmaps (book 10.x; Ward, "Fast, Robust
//! Image Registration for Compositing High Dynamic Range Photographs from Hand-Held Exposures",
//! Journal of Graphics Tools 8(2), 2003).
//!
//! Exposures differ by a translation of a few pixels when the camera was held by hand. Ward's
//! method compares exposures through a bitmap that does not depend on the exposure: each pixel's
//! grey level above or below the image's *median* (the median threshold bitmap, MTB), ignoring
//! pixels within `exclusion` codes of the median (the exclusion bitmap), whose bit is noise.
//! The shift is searched on an image pyramid: at the coarsest level the 9 offsets of ±1 pixel,
//! then at each finer level twice the shift found so far ±1 pixel; the cost of an offset is the
//! number of pixels where the two MTBs differ (XOR) and both exclusion bitmaps are set (AND),
//! counted with `popcount` on 64-pixel words. `levels` finer-than-coarsest steps reach shifts of
//! up to `2^(levels+1) − 1` pixels. Translations only (no rotation).
//!
//! Details as in Ward's code: grey = (54 R + 183 G + 19 B) / 256; each pyramid level halves the
//! image by 2×2 box averaging; thresholds and bitmaps are computed per level. Two deliberate
//! differences, both found on the Memorial stack:
//! - Among equal costs the *unchanged* shift wins (then the first offset in row order), where
//!   Ward's and OpenCV's scans keep the first offset, (−1, −1): on tiny coarse levels every cost
//!   can be 0, and that tie-break drifts the shift out of the frame.
//! - The threshold is a percentile chosen per pair (`pair_percentile`): the median unless it
//!   sits in the pile of pixels at the black level or at white of a dark or bright exposure
//!   (Memorial's 1/8 s to 1/1024 s exposures are 16–20 codes almost everywhere), where a
//!   median bitmap is all noise and the search finds no shift.
//!
//! Each exposure is compared with its neighbour towards the reference by default
//! ([`AlignChain::Neighbours`]) and the shifts are summed; [`AlignChain::Reference`] compares
//! each directly with the reference as OpenCV does.

use rayon::prelude::*;

use super::stack::{Exposure, ExposureStack};
use super::HdrError;

/// Which exposure each one is compared with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum AlignChain {
    /// Each exposure against its neighbour towards the reference, shifts accumulated: adjacent
    /// exposures look alike, so this survives wide brackets (Ward 2003, §4).
    Neighbours,
    /// Each exposure directly against the reference (OpenCV's `AlignMTB::process`).
    Reference,
}

/// Options of [`align_exposures`].
#[derive(Clone, Copy, Debug, PartialEq, vfxgraph_params::Options)]
pub struct AlignOptions {
    /// pyramid levels (shifts up to 2^(levels+1) - 1 px; fewer on small images)
    ///
    /// Pyramid levels above full resolution (Ward's `shift_bits`, OpenCV's `max_bits`; default 6:
    /// shifts up to ±127 px). Reduced so that the coarsest level keeps at least 8 pixels on its
    /// short side.
    #[param(range = 0..=16)]
    pub levels: usize,
    /// codes around the threshold left out of the comparison (noise)
    ///
    /// Half-width of the band around the median excluded from comparison, in codes (default 4).
    #[param(range = 0..=64)]
    pub exclusion: u8,
    /// index of the exposure that stays in place; -1 = the middle one
    ///
    /// `None` (−1 as a parameter) = the middle one (`len / 2`).
    #[param(range = -1..=(1 << 20))]
    pub reference: Option<usize>,
    /// compare each exposure with its neighbour towards the reference (shifts summed), or directly with the reference (OpenCV's AlignMTB)
    ///
    /// Neighbour chaining (default) or direct comparison with the reference.
    pub chain: AlignChain,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions {
            levels: 6,
            exclusion: 4,
            reference: None,
            chain: AlignChain::Neighbours,
        }
    }
}

/// A grey image of 8-bit levels.
#[derive(Clone, Debug)]
struct Grey {
    w: usize,
    h: usize,
    v: Vec<u8>,
}

impl Grey {
    /// Ward's grey: (54 R + 183 G + 19 B) / 256 (gray and 2-channel images use channel 0).
    fn of(codes: &[u8], w: usize, h: usize, c: usize) -> Grey {
        let v = if c >= 3 {
            codes
                .chunks_exact(c)
                .map(|p| ((54 * p[0] as u32 + 183 * p[1] as u32 + 19 * p[2] as u32) >> 8) as u8)
                .collect()
        } else {
            codes.chunks_exact(c).map(|p| p[0]).collect()
        };
        Grey { w, h, v }
    }

    /// Half size by 2×2 box averaging (rounded); odd last rows/columns are dropped.
    fn shrink(&self) -> Grey {
        let (w, h) = (self.w / 2, self.h / 2);
        let mut v = vec![0u8; w * h];
        for (y, row) in v.chunks_exact_mut(w).enumerate() {
            let (a, b) = (&self.v[2 * y * self.w..], &self.v[(2 * y + 1) * self.w..]);
            for (x, o) in row.iter_mut().enumerate() {
                let s =
                    a[2 * x] as u32 + a[2 * x + 1] as u32 + b[2 * x] as u32 + b[2 * x + 1] as u32;
                *o = ((s + 2) / 4) as u8;
            }
        }
        Grey { w, h, v }
    }

    fn histogram(&self) -> [usize; 256] {
        let mut hist = [0usize; 256];
        for &g in &self.v {
            hist[g as usize] += 1;
        }
        hist
    }

    /// The smallest level with at least a fraction `p` of the pixels at or below it
    /// (`p` = 0.5: the median).
    fn percentile(&self, p: f64) -> u8 {
        percentile(&self.histogram(), self.v.len(), p)
    }

    #[cfg(test)]
    fn median(&self) -> u8 {
        self.percentile(0.5)
    }

    /// How informative a bitmap thresholded at `t` is: the smaller of the fractions of pixels
    /// more than `exclusion` codes below and above `t` (the pixels a comparison can use, on the
    /// rarer side).
    fn balance(&self, hist: &[usize; 256], t: u8, exclusion: u8) -> f64 {
        let (lo, hi) = (t as i32 - exclusion as i32, t as i32 + exclusion as i32);
        let below: usize = hist[..lo.max(0) as usize].iter().sum();
        let above: usize = hist[(hi + 1).min(256) as usize..].iter().sum();
        below.min(above) as f64 / self.v.len().max(1) as f64
    }
}

/// The smallest level with at least a fraction `p` of the `n` pixels of `hist` at or below it.
fn percentile(hist: &[usize; 256], n: usize, p: f64) -> u8 {
    let need = ((p * n as f64).ceil() as usize).max(1);
    let mut acc = 0;
    for (g, &k) in hist.iter().enumerate() {
        acc += k;
        if acc >= need {
            return g as u8;
        }
    }
    255
}

/// Percentiles tried for a pair, nearest to the median first.
const PERCENTILES: [f64; 27] = [
    0.5, 0.45, 0.55, 0.4, 0.6, 0.35, 0.65, 0.3, 0.7, 0.25, 0.75, 0.2, 0.8, 0.15, 0.85, 0.1, 0.9,
    0.05, 0.95, 0.02, 0.98, 0.01, 0.99, 0.005, 0.995, 0.002, 0.998,
];

/// The percentile that thresholds both images of a pair. Ward's median, unless it leaves few
/// usable pixels on one side of the threshold in either image — a dark or bright exposure piles
/// up at the black level or at white, and its median then sits inside that pile — in which case
/// the percentile (0.2 % to 99.8 %) that is best for the worse image of the pair, by the
/// smaller of the fractions of pixels clearly below and clearly above the threshold. A
/// percentile corresponds to the same radiance in both images (the response is monotonic),
/// which is what makes the two bitmaps comparable.
fn pair_percentile(a: &Grey, b: &Grey, exclusion: u8) -> f64 {
    let (ha, hb) = (a.histogram(), b.histogram());
    let score = |p: f64| {
        a.balance(&ha, percentile(&ha, a.v.len(), p), exclusion)
            .min(b.balance(&hb, percentile(&hb, b.v.len(), p), exclusion))
    };
    let median = score(0.5);
    let (mut best, mut best_p) = (median, 0.5);
    for &p in &PERCENTILES[1..] {
        let s = score(p);
        if s > best {
            (best, best_p) = (s, p);
        }
    }
    // Keep the median while it scores at least 3/4 of the best percentile.
    if median >= 0.75 * best {
        0.5
    } else {
        best_p
    }
}

/// The threshold and exclusion bitmaps of one level, rows of 64-bit words (padding bits zero).
struct Bitmaps {
    h: usize,
    words: usize,
    tb: Vec<u64>,
    eb: Vec<u64>,
}

impl Bitmaps {
    /// Bitmaps thresholded at percentile `p` of `g` (Ward: the median, `p` = 0.5).
    fn of(g: &Grey, p: f64, exclusion: u8) -> Bitmaps {
        let med = g.percentile(p) as i32;
        let words = g.w.div_ceil(64);
        let mut tb = vec![0u64; words * g.h];
        let mut eb = vec![0u64; words * g.h];
        for y in 0..g.h {
            let row = &g.v[y * g.w..(y + 1) * g.w];
            for (k, chunk) in row.chunks(64).enumerate() {
                let (mut t, mut e) = (0u64, 0u64);
                for (i, &v) in chunk.iter().enumerate() {
                    let v = v as i32;
                    t |= u64::from(v > med) << i;
                    e |= u64::from((v - med).abs() > exclusion as i32) << i;
                }
                tb[y * words + k] = t;
                eb[y * words + k] = e;
            }
        }
        Bitmaps {
            h: g.h,
            words,
            tb,
            eb,
        }
    }

    /// The 64 bits of row `row` starting at bit `start` (may be negative or past the end: zeros).
    fn bits(row: &[u64], start: i64) -> u64 {
        let q = start.div_euclid(64);
        let r = start.rem_euclid(64) as u32;
        let word = |i: i64| {
            if i >= 0 && (i as usize) < row.len() {
                row[i as usize]
            } else {
                0
            }
        };
        if r == 0 {
            word(q)
        } else {
            (word(q) >> r) | (word(q + 1) << (64 - r))
        }
    }

    /// Pixels where `self` and `other` shifted by (dx, dy) (other'(x, y) = other(x − dx, y − dy))
    /// differ and both are outside their exclusion bands.
    fn cost(&self, other: &Bitmaps, dx: i64, dy: i64) -> u64 {
        let mut n = 0u64;
        for y in 0..self.h {
            let ys = y as i64 - dy;
            if ys < 0 || ys >= other.h as i64 {
                continue;
            }
            let (a0, b0) = (y * self.words, ys as usize * other.words);
            let (ta, ea) = (&self.tb[a0..a0 + self.words], &self.eb[a0..a0 + self.words]);
            let (tb, eb) = (
                &other.tb[b0..b0 + other.words],
                &other.eb[b0..b0 + other.words],
            );
            for k in 0..self.words {
                let start = 64 * k as i64 - dx;
                let t = Self::bits(tb, start);
                let e = Self::bits(eb, start);
                n += ((ta[k] ^ t) & ea[k] & e).count_ones() as u64;
            }
        }
        n
    }
}

/// The pyramid of one exposure's grey image, finest first.
fn pyramid(g: Grey, levels: usize) -> Vec<Grey> {
    let mut p = vec![g];
    for _ in 0..levels {
        let s = p.last().expect("non-empty").shrink();
        p.push(s);
    }
    p
}

/// Number of usable pyramid levels: at most `wanted`, keeping ≥ 8 pixels on the short side.
fn usable_levels(w: usize, h: usize, wanted: usize) -> usize {
    let mut n = 0;
    let mut s = w.min(h);
    while n < wanted && s / 2 >= 8 {
        s /= 2;
        n += 1;
    }
    n
}

/// Ward's shift search: the translation (dx, dy) that, applied to `moving`
/// (moved(x, y) = moving(x − dx, y − dy)), best matches `fixed`.
fn mtb_shift(fixed: &[Grey], moving: &[Grey], exclusion: u8) -> (i64, i64) {
    let p = pair_percentile(&fixed[0], &moving[0], exclusion);
    let (mut sx, mut sy) = (0i64, 0i64);
    for level in (0..fixed.len()).rev() {
        sx *= 2;
        sy *= 2;
        let a = Bitmaps::of(&fixed[level], p, exclusion);
        let b = Bitmaps::of(&moving[level], p, exclusion);
        // The centre first: it keeps ties (Ward's and OpenCV's scans keep the first offset,
        // (−1, −1), which runs away on featureless coarse levels where every cost is 0).
        let mut best = (a.cost(&b, sx, sy), sx, sy);
        for dy in -1..=1 {
            for dx in -1..=1 {
                if (dx, dy) == (0, 0) {
                    continue;
                }
                let c = a.cost(&b, sx + dx, sy + dy);
                if c < best.0 {
                    best = (c, sx + dx, sy + dy);
                }
            }
        }
        (sx, sy) = (best.1, best.2);
    }
    (sx, sy)
}

/// The translation of each exposure that aligns it with the reference exposure (book 10.x;
/// Ward 2003): `(dx, dy)` in pixels, to be applied as `aligned(x, y) = exposure(x − dx, y − dy)`;
/// the reference's is `(0, 0)`. Exposures are analysed in parallel; the result does not depend
/// on the thread count.
pub fn mtb_shifts(stack: &ExposureStack, opts: &AlignOptions) -> Result<Vec<(i64, i64)>, HdrError> {
    let n = stack.len();
    let r = opts.reference.unwrap_or(n / 2);
    if r >= n {
        return Err(HdrError::InvalidArgument(format!(
            "`reference`: exposure {r} does not exist (the stack has {n})"
        )));
    }
    let (w, h, c) = (stack.width(), stack.height(), stack.channels());
    let levels = usable_levels(w, h, opts.levels);
    let pyramids: Vec<Vec<Grey>> = stack
        .exposures()
        .par_iter()
        .map(|e| pyramid(Grey::of(&e.codes, w, h, c), levels))
        .collect();
    // Each exposure is compared with its partner: the reference, or the next one towards it.
    let partner = |i: usize| match opts.chain {
        AlignChain::Reference => r,
        AlignChain::Neighbours if i < r => i + 1,
        AlignChain::Neighbours => i - 1,
    };
    let pairwise: Vec<(i64, i64)> = (0..n)
        .into_par_iter()
        .map(|i| {
            if i == r {
                (0, 0)
            } else {
                mtb_shift(&pyramids[partner(i)], &pyramids[i], opts.exclusion)
            }
        })
        .collect();
    // Accumulate along the chain towards the reference.
    let mut shifts = vec![(0i64, 0i64); n];
    for i in (0..r).rev().chain(r + 1..n) {
        let p = partner(i);
        let base = if p == r { (0, 0) } else { shifts[p] };
        shifts[i] = (base.0 + pairwise[i].0, base.1 + pairwise[i].1);
    }
    Ok(shifts)
}

/// Translates every exposure by its shift (`out(x, y) = in(x − dx, y − dy)`). Pixels that come
/// from outside the frame get code 0 — weight 0 in the merge's hat function, so they do not
/// count there — and are added to the stack's mask so response recovery does not sample them.
pub fn apply_shifts(
    stack: &ExposureStack,
    shifts: &[(i64, i64)],
) -> Result<ExposureStack, HdrError> {
    if shifts.len() != stack.len() {
        return Err(HdrError::InvalidArgument(format!(
            "{} shifts for {} exposures",
            shifts.len(),
            stack.len()
        )));
    }
    let (w, h, c) = (stack.width(), stack.height(), stack.channels());
    let mut mask: Vec<bool> = stack
        .mask()
        .map(<[bool]>::to_vec)
        .unwrap_or_else(|| vec![false; w * h]);
    let mut exposures = Vec::with_capacity(stack.len());
    for (e, &(dx, dy)) in stack.exposures().iter().zip(shifts) {
        let mut codes = vec![0u8; e.codes.len()];
        // Columns x with 0 ≤ x − dx < w, rows likewise; everything else comes from outside.
        let (x0, x1) = (
            (dx.max(0) as usize).min(w),
            ((w as i64 + dx).clamp(0, w as i64)) as usize,
        );
        for y in 0..h {
            let ys = y as i64 - dy;
            let inside_row = ys >= 0 && ys < h as i64;
            for (x, m) in mask[y * w..(y + 1) * w].iter_mut().enumerate() {
                if !inside_row || x < x0 || x >= x1 {
                    *m = true;
                }
            }
            if inside_row && x0 < x1 {
                let src = (ys as usize * w + (x0 as i64 - dx) as usize) * c;
                let dst = (y * w + x0) * c;
                let len = (x1 - x0) * c;
                codes[dst..dst + len].copy_from_slice(&e.codes[src..src + len]);
            }
        }
        exposures.push(Exposure {
            time: e.time,
            codes,
        });
    }
    let out = ExposureStack::new(w, h, c, exposures)?;
    if mask.iter().any(|&m| m) {
        out.with_mask(mask)
    } else {
        Ok(out)
    }
}

/// Aligns a hand-held bracket (book 10.x; Ward 2003): finds each exposure's translation with
/// [`mtb_shifts`] and applies it with [`apply_shifts`]. Returns the aligned stack and the shifts.
pub fn align_exposures(
    stack: &ExposureStack,
    opts: &AlignOptions,
) -> Result<(ExposureStack, Vec<(i64, i64)>), HdrError> {
    let shifts = mtb_shifts(stack, opts)?;
    Ok((apply_shifts(stack, &shifts)?, shifts))
}

/// The `align_exposures` report: the reference exposure and each exposure's shift `[dx, dy]`,
/// `aligned(x, y) = exposure(x - dx, y - dy)`.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct AlignReport {
    /// The exposure the others are aligned to.
    pub reference: usize,
    /// Per exposure, `[dx, dy]`.
    pub shifts: Vec<[i64; 2]>,
}

/// The report of `shifts` found on a stack of `len` exposures.
pub fn align_report(opts: &AlignOptions, len: usize, shifts: &[(i64, i64)]) -> AlignReport {
    AlignReport {
        reference: opts.reference.unwrap_or(len / 2),
        shifts: shifts.iter().map(|&(x, y)| [x, y]).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_extraction_and_cost_match_a_direct_count() {
        // Two random-ish grey images; the word-level cost equals a per-pixel count.
        let (w, h) = (150usize, 37usize);
        let mut s = 12345u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 56) as u8
        };
        let a = Grey {
            w,
            h,
            v: (0..w * h).map(|_| next()).collect(),
        };
        let b = Grey {
            w,
            h,
            v: (0..w * h).map(|_| next()).collect(),
        };
        let (ba, bb) = (Bitmaps::of(&a, 0.5, 4), Bitmaps::of(&b, 0.5, 4));
        let (ma, mb) = (a.median() as i32, b.median() as i32);
        for (dx, dy) in [(0, 0), (3, -2), (-70, 5), (64, 1), (-1, -36), (149, 0)] {
            let mut n = 0;
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let (xs, ys) = (x - dx, y - dy);
                    if xs < 0 || ys < 0 || xs >= w as i64 || ys >= h as i64 {
                        continue;
                    }
                    let va = a.v[(y as usize) * w + x as usize] as i32;
                    let vb = b.v[(ys as usize) * w + xs as usize] as i32;
                    if (va > ma) != (vb > mb) && (va - ma).abs() > 4 && (vb - mb).abs() > 4 {
                        n += 1;
                    }
                }
            }
            assert_eq!(ba.cost(&bb, dx, dy), n, "({dx}, {dy})");
        }
    }

    #[test]
    fn median_and_shrink() {
        let g = Grey {
            w: 4,
            h: 2,
            v: vec![0, 10, 20, 30, 2, 4, 100, 200],
        };
        assert_eq!(g.median(), 10);
        let s = g.shrink();
        assert_eq!((s.w, s.h, s.v.clone()), (2, 1, vec![4, 88]));
        assert_eq!(usable_levels(768, 512, 6), 6);
        assert_eq!(usable_levels(40, 30, 6), 1);
    }
}
