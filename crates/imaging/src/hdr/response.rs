//! Camera response recovery by Debevec & Malik (SIGGRAPH 1997), book 10.2–10.4.
//!
//! A pixel value is `Z = f(E Δt)`; with `g = ln f⁻¹` every observation gives
//! `g(Z_ij) = ln E_i + ln Δt_j`. [`calibrate_debevec`] samples pixels `i` of the stack and solves,
//! per channel, the weighted linear least-squares problem of the paper's equation (3) exactly as
//! its `gsolve` listing builds it (weights inside the square, so `λ` is comparable with the
//! paper's and with OpenCV's `CalibrateDebevec`):
//!
//! ```text
//! minimise  Σ_ij [w(Z_ij)(g(Z_ij) − ln E_i − ln Δt_j)]²  +  Σ_{z=1}^{254} [λ w(z) g''(z)]²
//! subject to g(128) = 0  (one equation of weight 1)
//! ```
//!
//! with the hat weight [`hat_weight`]. The unknowns are the 256 values of `g` and one `ln E_i`
//! per sample. Instead of an SVD of the tall system, the normal equations are reduced by a Schur
//! complement on the `ln E_i` (each couples only with the codes of its own pixel, so that block is
//! diagonal): the 256 × 256 system that remains is solved by Cholesky. The cost is
//! `O(samples × exposures²) + O(256³)`, so thousands of samples are cheap.

use rand::Rng;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

use super::{ExposureStack, HdrError, LEVELS};

/// The response of a camera: `g(z) = ln f⁻¹(z)`, the log exposure that produces code `z`, 256
/// values per channel (Debevec & Malik 1997; book 10.2–10.3). Defined up to one additive constant
/// per channel; curves made here are normalised to `g(128) = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseCurve {
    g: Vec<[f64; LEVELS]>,
}

impl ResponseCurve {
    /// Wraps per-channel curves (1–4 channels, every value finite).
    pub fn new(g: Vec<[f64; LEVELS]>) -> Result<ResponseCurve, HdrError> {
        if !(1..=4).contains(&g.len()) {
            return Err(HdrError::InvalidArgument(format!(
                "a response curve has 1-4 channels, got {}",
                g.len()
            )));
        }
        if g.iter().flatten().any(|v| !v.is_finite()) {
            return Err(HdrError::InvalidArgument(
                "response curve values must be finite".into(),
            ));
        }
        Ok(ResponseCurve { g })
    }

    /// The curve of a display gamma (book 10.6): `f⁻¹(z) = (z/255)^γ`, normalised so that
    /// `g(128) = 0`; code 0 is treated as 0.5 so that `g(0)` stays finite.
    pub fn gamma(gamma: f64, channels: usize) -> Result<ResponseCurve, HdrError> {
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(HdrError::InvalidArgument(format!(
                "gamma {gamma} must be finite and positive"
            )));
        }
        let one: [f64; LEVELS] =
            std::array::from_fn(|z| gamma * ((z as f64).max(0.5) / 128.0).ln());
        ResponseCurve::new(vec![one; channels])
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.g.len()
    }

    /// `g` of channel `c` (panics if `c` is out of range).
    pub fn g(&self, c: usize) -> &[f64; LEVELS] {
        &self.g[c]
    }

    /// All channels.
    pub fn curves(&self) -> &[[f64; LEVELS]] {
        &self.g
    }

    /// The linear exposure `f⁻¹(z) = exp(g(z))` of code `z` in channel `c` — the value OpenCV's
    /// `CalibrateDebevec` returns and [`crate::hdr`]'s CSV writer stores.
    pub fn exposure(&self, c: usize, z: u8) -> f64 {
        self.g[c][z as usize].exp()
    }

    /// The curve as CSV: 256 rows (z = 0…255), one column per channel, holding the linear
    /// exposure f⁻¹(z) = exp(g(z)) — OpenCV's debevec.csv layout, no header.
    pub fn to_csv(&self) -> String {
        let mut s = String::new();
        for z in 0..=255u8 {
            let row: Vec<String> = (0..self.channels())
                .map(|c| format!("{:.9e}", self.exposure(c, z)))
                .collect();
            s.push_str(&row.join(","));
            s.push('\n');
        }
        s
    }

    /// Whether channel `c`'s curve is non-decreasing over `lo..=hi`.
    pub fn is_monotonic(&self, c: usize, lo: u8, hi: u8) -> bool {
        self.g[c][lo as usize..=hi as usize]
            .windows(2)
            .all(|w| w[1] >= w[0])
    }

    /// Largest absolute second difference `|g(z−1) − 2g(z) + g(z+1)|` over `lo < z < hi`: a
    /// smoothness figure in log-exposure units.
    pub fn roughness(&self, c: usize, lo: u8, hi: u8) -> f64 {
        let g = &self.g[c];
        (lo as usize + 1..hi as usize)
            .map(|z| (g[z - 1] - 2.0 * g[z] + g[z + 1]).abs())
            .fold(0.0, f64::max)
    }

    /// The code the camera would write for log exposure `ln_x` in channel `c` (book 10.6): the
    /// `z` whose `g(z)` is nearest, searching the curve made non-decreasing (a running maximum),
    /// so exposures below `g(0)` give 0 and above `g(255)` give 255. NaN gives 0.
    pub fn code_for(&self, c: usize, ln_x: f64) -> u8 {
        if ln_x.is_nan() {
            return 0;
        }
        let g = &self.g[c];
        let mut mono = [0.0; LEVELS];
        let mut m = f64::NEG_INFINITY;
        for (o, &v) in mono.iter_mut().zip(g) {
            m = m.max(v);
            *o = m;
        }
        let i = mono.partition_point(|&v| v < ln_x);
        if i == 0 {
            0
        } else if i >= LEVELS {
            255
        } else if (ln_x - mono[i - 1]) <= (mono[i] - ln_x) {
            (i - 1) as u8
        } else {
            i as u8
        }
    }
}

/// The hat weighting function of Debevec & Malik 1997 (eq. 4; book 10.2): `w(z) = z − Z_min` for
/// `z ≤ ½(Z_min + Z_max)`, `Z_max − z` above, with `Z_min = 0`, `Z_max = 255` — 0 at both ends,
/// 127 in the middle. It trusts mid-range codes and ignores clipped ones.
pub fn hat_weight(z: u8) -> f64 {
    let z = z as f64;
    if z <= 127.5 {
        z
    } else {
        255.0 - z
    }
}

/// How [`calibrate_debevec`] picks the pixels whose codes enter the least-squares system.
/// Masked pixels are never picked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, vfxgraph_params::Choice)]
pub enum Sampling {
    /// One random pixel in each cell of the grid of [`Sampling::Grid`] (jittered; seeded PCG).
    /// The default: even coverage without the grid's aliasing.
    Stratified,
    /// Uniformly random pixels (seeded PCG).
    Random,
    /// The centres of a regular grid of about `samples` cells (deterministic; OpenCV's
    /// non-random mode does the same).
    Grid,
}

/// Options of [`calibrate_debevec`].
#[derive(Clone, Debug, PartialEq, vfxgraph_params::Options)]
pub struct CalibrateOptions {
    /// pixel locations sampled (same for every channel)
    ///
    /// Debevec & Malik note `N(P − 1) > 255` is needed; more samples average out noise and
    /// misregistration.
    #[param(range = 1..=1_000_000)]
    pub samples: usize,
    /// smoothness weight λ (as in the paper's gsolve and OpenCV)
    ///
    /// OpenCV's default is 10.
    #[param(range = 0.0..=1e6)]
    pub lambda: f64,
    /// pixel selection: jittered grid, uniform random, or regular grid
    pub sampling: Sampling,
    /// Seed of the PCG stream for random strategies: equal seeds give equal curves (the
    /// graph's seed, not a parameter).
    #[param(skip)]
    pub seed: u64,
    /// constrain g to be non-decreasing (least squares over monotonic curves, active-set); false = the paper's unconstrained solution
    ///
    /// `g(z+1) ≥ g(z)` for every z; see [`solve_debevec_monotonic`]. The default: a camera's
    /// response is monotonic, and without the constraint the rarely observed codes (Memorial's
    /// below ≈ 16) wiggle.
    pub monotonic: bool,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            samples: 1000,
            lambda: 10.0,
            sampling: Sampling::Stratified,
            seed: 0,
            monotonic: true,
        }
    }
}

/// Picks sample pixels (row-major indices) as `opts` says, skipping masked pixels.
pub fn sample_pixels(stack: &ExposureStack, opts: &CalibrateOptions) -> Vec<usize> {
    let (w, h) = (stack.width(), stack.height());
    let n = opts.samples.min(w * h);
    let mut rng = Pcg64::seed_from_u64(opts.seed);
    let mut out = Vec::with_capacity(n);
    match opts.sampling {
        Sampling::Random => {
            let mut tries = 0usize;
            while out.len() < n && tries < 20 * n + 100 {
                tries += 1;
                let p = rng.random_range(0..w * h);
                if !stack.is_masked(p) {
                    out.push(p);
                }
            }
        }
        Sampling::Grid | Sampling::Stratified => {
            let nx = ((n as f64 * w as f64 / h as f64).sqrt().round() as usize).clamp(1, w);
            let ny = n.div_ceil(nx).clamp(1, h);
            let (cw, ch) = (w as f64 / nx as f64, h as f64 / ny as f64);
            for j in 0..ny {
                for i in 0..nx {
                    // Stratified: up to 7 jittered tries to land on an unmasked pixel, then the centre.
                    let tries = if opts.sampling == Sampling::Grid {
                        1
                    } else {
                        8
                    };
                    for t in 0..tries {
                        let (fx, fy) = if opts.sampling == Sampling::Grid || t + 1 == tries {
                            (0.5, 0.5)
                        } else {
                            (rng.random::<f64>(), rng.random::<f64>())
                        };
                        let x = (((i as f64 + fx) * cw) as usize).min(w - 1);
                        let y = (((j as f64 + fy) * ch) as usize).min(h - 1);
                        let p = y * w + x;
                        if !stack.is_masked(p) {
                            out.push(p);
                            break;
                        }
                    }
                }
            }
        }
    }
    out
}

/// Recovers the response curve of every channel of `stack` (Debevec & Malik 1997; book 10.2–10.4),
/// normalised to `g(128) = 0` per channel. Deterministic for a given seed, whatever the number of
/// threads. Errors: fewer than 2 exposures, a non-finite or negative λ, zero samples, or a
/// singular system (every sample clipped, or too few distinct codes).
pub fn calibrate_debevec(
    stack: &ExposureStack,
    opts: &CalibrateOptions,
) -> Result<ResponseCurve, HdrError> {
    if stack.len() < 2 {
        return Err(HdrError::InvalidArgument(
            "response recovery needs at least 2 exposures with different times".into(),
        ));
    }
    if !(opts.lambda.is_finite() && opts.lambda >= 0.0) {
        return Err(HdrError::InvalidArgument(format!(
            "lambda {} must be finite and non-negative",
            opts.lambda
        )));
    }
    if opts.samples == 0 {
        return Err(HdrError::InvalidArgument("samples must be positive".into()));
    }
    let pixels = sample_pixels(stack, opts);
    if pixels.is_empty() {
        return Err(HdrError::Singular("no unmasked pixel to sample".into()));
    }
    let ln_dt: Vec<f64> = stack.exposures().iter().map(|e| e.time.ln()).collect();
    let c_n = stack.channels();
    let p_n = stack.len();
    let curves = (0..c_n)
        .into_par_iter()
        .map(|c| {
            let mut z = Vec::with_capacity(pixels.len() * p_n);
            for &p in &pixels {
                for e in stack.exposures() {
                    z.push(e.codes[p * c_n + c]);
                }
            }
            let solved = if opts.monotonic {
                solve_debevec_monotonic(&z, p_n, &ln_dt, opts.lambda)
            } else {
                solve_debevec(&z, p_n, &ln_dt, opts.lambda)
            };
            solved.map_err(|e| HdrError::Singular(format!("channel {c}: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    ResponseCurve::new(curves)
}

/// The core of Debevec & Malik's `gsolve` for one channel: `z` holds `samples × exposures` codes
/// (row-major, one row per sample pixel), `ln_dt` the log exposure times. Returns `g` with
/// `g(128) = 0`. See the module documentation for the system and how it is solved.
pub fn solve_debevec(
    z: &[u8],
    exposures: usize,
    ln_dt: &[f64],
    lambda: f64,
) -> Result<[f64; LEVELS], String> {
    let (mut s, r, used) = normal_equations(z, exposures, ln_dt, lambda)?;
    if !cholesky_factor(&mut s, LEVELS) {
        return Err(singular(used));
    }
    normalise(&cholesky_apply(&s, &r, LEVELS))
}

/// [`solve_debevec`] under the constraints `g(z+1) ≥ g(z)` for z = 0…254: the same least-squares
/// objective minimised over non-decreasing curves, so the result is the best monotonic curve for
/// the data, not a patched one. Solved by a primal active-set method on the reduced 256-unknown
/// system: the unconstrained minimum first (usually every constraint is inactive but a few among
/// the rarely seen codes); then, repeatedly, the most violated constraint becomes an equality and
/// the constraint with the most negative Lagrange multiplier is released, the equality-
/// constrained minimum coming from the same Cholesky factor (`g = S⁻¹(r + Aᵀμ)`, with
/// `(A S⁻¹ Aᵀ) μ = −A S⁻¹ r`), until every constraint holds and every multiplier is ≥ 0 (the KKT
/// conditions). Codes the data never constrain simply follow the smoothness term.
pub fn solve_debevec_monotonic(
    z: &[u8],
    exposures: usize,
    ln_dt: &[f64],
    lambda: f64,
) -> Result<[f64; LEVELS], String> {
    const N: usize = LEVELS;
    let (mut s, r, used) = normal_equations(z, exposures, ln_dt, lambda)?;
    if !cholesky_factor(&mut s, N) {
        return Err(singular(used));
    }
    let g0 = cholesky_apply(&s, &r, N);
    // x_k = S⁻¹ a_k for the constraint rows a_k = e_{k+1} − e_k, computed when first needed.
    let mut x: Vec<Option<Vec<f64>>> = vec![None; N - 1];
    let diff = |g: &[f64], k: usize| g[k + 1] - g[k];
    let scale = g0.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
    let tol = 1e-10 * scale;
    let mut active: Vec<usize> = Vec::new();
    let mut g = g0.clone();
    for _ in 0..4 * N {
        // Equality-constrained minimum for the active set.
        let mut mu = vec![0.0; active.len()];
        if !active.is_empty() {
            for &k in &active {
                if x[k].is_none() {
                    let mut a = vec![0.0; N];
                    a[k] = -1.0;
                    a[k + 1] = 1.0;
                    x[k] = Some(cholesky_apply(&s, &a, N));
                }
            }
            let m = active.len();
            let mut mm = vec![0.0; m * m];
            let mut rhs = vec![0.0; m];
            for (i, &ki) in active.iter().enumerate() {
                for (j, &kj) in active.iter().enumerate() {
                    mm[i * m + j] = diff(x[kj].as_ref().expect("computed"), ki);
                }
                rhs[i] = -diff(&g0, ki);
            }
            if !cholesky_factor(&mut mm, m) {
                return Err("monotonic solve: dependent constraints (a bug)".into());
            }
            mu = cholesky_apply(&mm, &rhs, m);
            g.copy_from_slice(&g0);
            for (&k, &mk) in active.iter().zip(&mu) {
                for (gi, xi) in g.iter_mut().zip(x[k].as_ref().expect("computed")) {
                    *gi += mk * xi;
                }
            }
        }
        // Release the constraint that pulls the wrong way, else add the most violated one.
        if let Some((i, _)) = mu
            .iter()
            .enumerate()
            .filter(|(_, &m)| m < -tol)
            .min_by(|a, b| a.1.total_cmp(b.1))
        {
            active.remove(i);
            continue;
        }
        let worst = (0..N - 1)
            .filter(|k| !active.contains(k))
            .map(|k| (k, diff(&g, k)))
            .filter(|&(_, d)| d < -tol)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match worst {
            Some((k, _)) => active.push(k),
            None => break,
        }
    }
    // Equalities hold to rounding: make them exact so the curve is non-decreasing bit for bit.
    for k in 1..N {
        g[k] = g[k].max(g[k - 1]);
    }
    normalise(&g)
}

/// The value of Debevec & Malik's objective (module documentation) at curve `g`, minimised over
/// the `ln E_i`, up to a constant that does not depend on `g`: `gᵀSg − 2rᵀg` of the reduced
/// normal equations. Lets callers compare curves on the same data (e.g. a constrained solution
/// with a patched one).
pub fn debevec_objective(
    z: &[u8],
    exposures: usize,
    ln_dt: &[f64],
    lambda: f64,
    g: &[f64; LEVELS],
) -> Result<f64, String> {
    let (s, r, _) = normal_equations(z, exposures, ln_dt, lambda)?;
    let mut q = 0.0;
    for i in 0..LEVELS {
        let si: f64 = (0..LEVELS).map(|j| s[i * LEVELS + j] * g[j]).sum();
        q += g[i] * si - 2.0 * r[i] * g[i];
    }
    Ok(q)
}

fn singular(used: usize) -> String {
    format!("the system is singular ({used} usable samples; use more samples or exposures)")
}

/// `g − g(128)`, checked finite.
fn normalise(g: &[f64]) -> Result<[f64; LEVELS], String> {
    let mut out = [0.0; LEVELS];
    let g128 = g[128];
    for (o, v) in out.iter_mut().zip(g) {
        *o = v - g128;
    }
    if out.iter().any(|v| !v.is_finite()) {
        return Err("the solution is not finite".into());
    }
    Ok(out)
}

/// The normal equations `S g = r` of the g block after eliminating every `ln E_i` (Schur
/// complement), with the `g(128) = 0` row and the smoothness term; and the number of usable
/// samples.
fn normal_equations(
    z: &[u8],
    exposures: usize,
    ln_dt: &[f64],
    lambda: f64,
) -> Result<(Vec<f64>, Vec<f64>, usize), String> {
    if exposures == 0 || ln_dt.len() != exposures || !z.len().is_multiple_of(exposures) {
        return Err("codes and exposure times disagree in length".into());
    }
    const N: usize = LEVELS;
    let mut s = vec![0.0f64; N * N];
    let mut r = vec![0.0f64; N];
    let mut used = 0usize;
    let mut b: Vec<(usize, f64)> = Vec::with_capacity(exposures);
    for row in z.chunks_exact(exposures) {
        b.clear();
        let (mut d, mut rhs_e) = (0.0, 0.0);
        for (&zij, &l) in row.iter().zip(ln_dt) {
            let w = hat_weight(zij);
            if w == 0.0 {
                continue;
            }
            let w2 = w * w;
            let k = zij as usize;
            s[k * N + k] += w2;
            r[k] += w2 * l;
            d += w2;
            rhs_e -= w2 * l;
            match b.iter_mut().find(|(kk, _)| *kk == k) {
                Some((_, v)) => *v -= w2,
                None => b.push((k, -w2)),
            }
        }
        if d == 0.0 {
            continue;
        }
        used += 1;
        for &(k1, v1) in &b {
            r[k1] -= v1 * rhs_e / d;
            for &(k2, v2) in &b {
                s[k1 * N + k2] -= v1 * v2 / d;
            }
        }
    }
    if used == 0 {
        return Err("every sampled pixel is clipped (code 0 or 255) in every exposure".into());
    }
    s[128 * N + 128] += 1.0;
    for k in 1..N - 1 {
        let a = lambda * hat_weight(k as u8);
        let v = [(k - 1, a), (k, -2.0 * a), (k + 1, a)];
        for &(i, vi) in &v {
            for &(j, vj) in &v {
                s[i * N + j] += vi * vj;
            }
        }
    }
    Ok((s, r, used))
}

/// Factors a symmetric positive-definite `n × n` matrix `a` (row-major) in place into its
/// Cholesky factor `L` (lower triangle). False if a pivot is not positive (relative to the
/// matrix's scale).
fn cholesky_factor(a: &mut [f64], n: usize) -> bool {
    let scale = (0..n).map(|i| a[i * n + i].abs()).fold(0.0, f64::max);
    let tiny = scale * 1e-13;
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= tiny {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    true
}

/// Solves `L Lᵀ x = b` with the factor from [`cholesky_factor`].
fn cholesky_apply(l: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut y = b.to_vec();
    for i in 0..n {
        for k in 0..i {
            y[i] -= l[i * n + k] * y[k];
        }
        y[i] /= l[i * n + i];
    }
    for i in (0..n).rev() {
        for k in i + 1..n {
            y[i] -= l[k * n + i] * y[k];
        }
        y[i] /= l[i * n + i];
    }
    y
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::hdr::Exposure;

    /// A camera with a known response: `f(X) = 255 X^γ / (X^γ + 1)` (an S-curve in log
    /// exposure), one γ per channel.
    pub(crate) fn true_code(x: f64, gamma: f64) -> f64 {
        let a = x.powf(gamma);
        255.0 * a / (a + 1.0)
    }
    pub(crate) fn true_g(z: usize, gamma: f64) -> f64 {
        let z = z as f64;
        (z / (255.0 - z)).ln() / gamma
    }
    pub(crate) const GAMMAS: [f64; 3] = [0.55, 0.65, 0.8];
    /// One stop apart, 1/64 s … 64 s (like the Memorial stack's spacing).
    pub(crate) const TIMES: [f64; 13] = [
        1.0 / 64.0,
        1.0 / 32.0,
        1.0 / 16.0,
        0.125,
        0.25,
        0.5,
        1.0,
        2.0,
        4.0,
        8.0,
        16.0,
        32.0,
        64.0,
    ];

    /// A 96×64 radiance map log-uniform over [1e-3, 1e3] (deterministic, hashed per pixel), the
    /// stack it produces through the known camera (codes rounded to 8 bits: quantization is the noise).
    pub(crate) fn synthetic() -> (Vec<f64>, ExposureStack) {
        let (w, h) = (96usize, 64usize);
        let mut rng = Pcg64::seed_from_u64(7);
        let e: Vec<f64> = (0..w * h)
            .map(|_| 10f64.powf(rng.random_range(-3.0..3.0)))
            .collect();
        let exposures = TIMES
            .iter()
            .map(|&t| Exposure {
                time: t,
                codes: e
                    .iter()
                    .flat_map(|&ei| GAMMAS.map(|g| true_code(ei * t, g)))
                    .map(|v| v.round().clamp(0.0, 255.0) as u8)
                    .collect(),
            })
            .collect();
        (e, ExposureStack::new(w, h, 3, exposures).unwrap())
    }

    #[test]
    fn recovers_a_known_curve_within_one_percent() {
        let (_, stack) = synthetic();
        let opts = CalibrateOptions {
            samples: 600,
            ..Default::default()
        };
        let curve = calibrate_debevec(&stack, &opts).unwrap();
        for (c, &gamma) in GAMMAS.iter().enumerate() {
            // The free scale: compare up to the constant that best aligns the curves.
            let range = 10..=245usize;
            let off: f64 = range
                .clone()
                .map(|z| curve.g(c)[z] - true_g(z, gamma))
                .sum::<f64>()
                / range.clone().count() as f64;
            let worst = range
                .clone()
                .map(|z| ((curve.g(c)[z] - true_g(z, gamma) - off).exp() - 1.0).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "channel {c}: f⁻¹ worst relative error {:.3}% (z = 10..245)",
                worst * 100.0
            );
            assert!(
                worst < 0.01,
                "channel {c}: f⁻¹ off by {:.3}%",
                worst * 100.0
            );
            assert!(curve.is_monotonic(c, 0, 255));
            assert_eq!(curve.g(c)[128], 0.0);
        }
        // Seeded: the same seed gives the same curve, another seed a different sample.
        assert_eq!(calibrate_debevec(&stack, &opts).unwrap(), curve);
        let other = CalibrateOptions { seed: 1, ..opts };
        assert_ne!(calibrate_debevec(&stack, &other).unwrap(), curve);
    }

    #[test]
    fn monotonic_solution_is_the_constrained_minimum() {
        // A noisy camera with a black-level pedestal (codes 16 + 239 f(X) + noise), few samples
        // and little smoothing: the unconstrained curve is not monotonic at low codes.
        let mut rng = Pcg64::seed_from_u64(3);
        let times = [1.0 / 16.0, 0.25, 1.0, 4.0, 16.0];
        let mut z = Vec::new();
        for _ in 0..60 {
            let e = 10f64.powf(rng.random_range(-2.5..1.5));
            for t in times {
                let code = 16.0
                    + 239.0 * true_code(e * t, 0.6) / 255.0
                    + 3.0 * (rng.random::<f64>() - 0.5);
                z.push(code.round().clamp(0.0, 255.0) as u8);
            }
        }
        let ln_dt: Vec<f64> = times.iter().map(|t: &f64| t.ln()).collect();
        let lambda = 0.5;
        let free = solve_debevec(&z, times.len(), &ln_dt, lambda).unwrap();
        assert!(
            free.windows(2).any(|w| w[1] < w[0]),
            "the test needs a non-monotonic unconstrained curve"
        );
        let mono = solve_debevec_monotonic(&z, times.len(), &ln_dt, lambda).unwrap();
        assert!(mono.windows(2).all(|w| w[1] >= w[0]));
        assert_eq!(mono[128], 0.0);
        let q = |g: &[f64; LEVELS]| debevec_objective(&z, times.len(), &ln_dt, lambda, g).unwrap();
        // Between the unconstrained minimum and any other monotonic curve: here the free curve
        // patched by a running maximum, and by a running minimum from the top.
        let mut up = free;
        for k in 1..LEVELS {
            up[k] = up[k].max(up[k - 1]);
        }
        let mut down = free;
        for k in (0..LEVELS - 1).rev() {
            down[k] = down[k].min(down[k + 1]);
        }
        let (qf, qm) = (q(&free), q(&mono));
        assert!(qf <= qm + 1e-9 * qm.abs(), "{qf} {qm}");
        assert!(qm < q(&up) && qm < q(&down), "{qm} {} {}", q(&up), q(&down));
        // KKT, numerically: no small monotonicity-preserving move lowers the objective.
        for k in [5usize, 40, 128, 200] {
            for d in [-1e-4, 1e-4] {
                let mut t = mono;
                for v in t.iter_mut().skip(k) {
                    *v += d; // shifting a whole upper part keeps the curve monotonic
                }
                assert!(q(&t) >= qm - 1e-9 * qm.abs(), "k {k} d {d}");
            }
        }
        // On clean data the constraint is inactive: the same curve as unconstrained.
        let (_, stack) = synthetic();
        let opts = CalibrateOptions {
            samples: 600,
            ..Default::default()
        };
        let free_opts = CalibrateOptions {
            monotonic: false,
            ..opts.clone()
        };
        let a = calibrate_debevec(&stack, &opts).unwrap();
        let b = calibrate_debevec(&stack, &free_opts).unwrap();
        if (0..3).all(|c| b.is_monotonic(c, 0, 255)) {
            for c in 0..3 {
                for z in 0..LEVELS {
                    assert!((a.g(c)[z] - b.g(c)[z]).abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn degenerate_inputs_are_errors_not_panics() {
        let one = ExposureStack::new(
            1,
            1,
            1,
            vec![Exposure {
                time: 1.0,
                codes: vec![9],
            }],
        )
        .unwrap();
        assert!(calibrate_debevec(&one, &CalibrateOptions::default()).is_err());
        let clipped = ExposureStack::new(
            2,
            1,
            1,
            vec![
                Exposure {
                    time: 1.0,
                    codes: vec![255, 255],
                },
                Exposure {
                    time: 2.0,
                    codes: vec![255, 0],
                },
            ],
        )
        .unwrap();
        let e = calibrate_debevec(&clipped, &CalibrateOptions::default()).unwrap_err();
        assert!(matches!(e, HdrError::Singular(_)), "{e}");
        let (_, stack) = synthetic();
        for lambda in [f64::NAN, -1.0, f64::INFINITY] {
            let o = CalibrateOptions {
                lambda,
                ..Default::default()
            };
            assert!(calibrate_debevec(&stack, &o).is_err());
        }
        let masked = stack.clone().with_mask(vec![true; 96 * 64]).unwrap();
        assert!(calibrate_debevec(&masked, &CalibrateOptions::default()).is_err());
        assert!(ResponseCurve::new(vec![[f64::NAN; LEVELS]]).is_err());
        assert!(ResponseCurve::gamma(0.0, 3).is_err());
    }

    #[test]
    fn sampling_strategies_avoid_masked_pixels() {
        let (_, stack) = synthetic();
        let mask: Vec<bool> = (0..96 * 64).map(|p| p % 96 < 48).collect();
        let stack = stack.with_mask(mask).unwrap();
        for sampling in [Sampling::Random, Sampling::Grid, Sampling::Stratified] {
            let o = CalibrateOptions {
                samples: 200,
                sampling,
                ..Default::default()
            };
            let px = sample_pixels(&stack, &o);
            assert!(px.len() >= 90, "{sampling:?}: {}", px.len());
            assert!(px.iter().all(|&p| !stack.is_masked(p)), "{sampling:?}");
        }
    }

    #[test]
    fn gamma_curve_and_its_inverse() {
        let c = ResponseCurve::gamma(2.2, 1).unwrap();
        assert_eq!(c.g(0)[128], 0.0);
        for z in [1u8, 17, 128, 200, 255] {
            assert_eq!(c.code_for(0, c.g(0)[z as usize]), z);
        }
        assert_eq!(c.code_for(0, -1e9), 0);
        assert_eq!(c.code_for(0, 1e9), 255);
        assert_eq!(c.code_for(0, f64::NAN), 0);
    }
}
