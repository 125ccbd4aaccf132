//! Parallel evaluation of residuals, robustified Jacobians and gradients (Triggs et al. 2000,
//! section 4; Ceres' `ProgramEvaluator`). Every observation is written to its own slot and every
//! sum is reduced in a fixed order, so results are bit-identical for any number of threads.

use rayon::prelude::*;

use super::loss::Loss;
use super::problem::Problem;
use super::residual::{project_rt, project_with_jacobians_rj, CAMERA_COLUMNS as CC};
use super::rotation::{angle_axis_to_matrix, rotation_and_left_jacobian};
use super::structure::Structure;

/// Observations per parallel chunk (fixed, so the reduction order never depends on threads).
pub(crate) const CHUNK: usize = 4096;

/// The linearisation of the problem at one parameter vector.
pub(crate) struct Linearization {
    /// Loss-corrected residuals.
    pub residuals: Vec<[f64; 2]>,
    /// Loss-corrected camera Jacobians, row-major 2×`columns` per observation (see
    /// [`Linearization::jc`]), columns held by the gauge or belonging to fixed blocks zeroed.
    jc: Vec<f64>,
    /// Camera columns stored per Jacobian row ([`Structure::columns`]): the problem's widest
    /// model's, so a pinhole or BAL problem stores 9, not [`CC`].
    pub columns: usize,
    /// Loss-corrected point Jacobians, row-major 2×3 (zero for fixed points).
    pub jp: Vec<[f64; 6]>,
    /// Gradient Jᵀr of the reduced (camera-side) parameters.
    pub g_f: Vec<f64>,
    /// Gradient Jᵀr per point.
    pub g_p: Vec<[f64; 3]>,
    /// Σ Jpᵀ Jp per point (row-major 3×3).
    pub jtj_p: Vec<[f64; 9]>,
    /// Diagonal of JᵀJ on the reduced parameters (squared column norms).
    pub diag_f: Vec<f64>,
    /// The priors' residuals ([`super::Prior`]; their Jacobians are the structure's constant
    /// coefficients).
    pub prior_residuals: Vec<f64>,
}

impl Linearization {
    /// Observation `a`'s camera Jacobian: row 0 at `[0..columns]`, row 1 at
    /// `[columns..2·columns]`.
    #[inline]
    pub fn jc(&self, a: usize) -> &[f64] {
        &self.jc[2 * self.columns * a..2 * self.columns * (a + 1)]
    }

    /// Number of observations.
    pub fn len(&self) -> usize {
        self.residuals.len()
    }
}

/// ½·Σ ρ(‖rᵢ‖²) at the problem's current parameters, reduced in a fixed order.
pub(crate) fn cost(problem: &Problem, loss: &Loss) -> f64 {
    let n = problem.observations.len();
    let rots: Vec<_> = problem
        .cameras
        .par_iter()
        .map(|c| angle_axis_to_matrix(&c.rotation))
        .collect();
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut s = 0.0;
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let o = &problem.observations[i];
                let cam = &problem.cameras[o.camera];
                let k = &problem.intrinsics[cam.intrinsics];
                let pred = project_rt(
                    k,
                    &rots[o.camera],
                    &cam.translation,
                    &problem.points[o.point].position,
                );
                let r = (pred - o.pixel) * o.weight;
                s += loss.evaluate(r.norm_squared())[0];
            }
            s
        })
        .collect();
    0.5 * partial.iter().sum::<f64>() + problem.prior_cost()
}

/// Residuals, Jacobians and gradients at the problem's current parameters.
pub(crate) fn linearize(problem: &Problem, loss: &Loss, st: &Structure) -> Linearization {
    let n = problem.observations.len();
    let rots: Vec<_> = problem
        .cameras
        .par_iter()
        .map(|c| rotation_and_left_jacobian(&c.rotation))
        .collect();
    let mut residuals = vec![[0.0; 2]; n];
    let w = st.columns;
    let mut jc = vec![0.0; 2 * w * n];
    let mut jp = vec![[0.0; 6]; n];
    residuals
        .par_chunks_mut(CHUNK)
        .zip(jc.par_chunks_mut(2 * w * CHUNK))
        .zip(jp.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(ci, ((rr, jjc), jjp))| {
            for k in 0..rr.len() {
                let i = ci * CHUNK + k;
                let o = &problem.observations[st.perm[i] as usize];
                let cam = &problem.cameras[o.camera];
                let intr = &problem.intrinsics[cam.intrinsics];
                let x = &problem.points[o.point].position;
                let (rot, jl) = &rots[o.camera];
                let (pred, j_cam, j_pt) =
                    project_with_jacobians_rj(intr, rot, jl, &cam.translation, x);
                // The weight scales the residual and, column by column below, its Jacobians.
                let wt = o.weight;
                let r = (pred - o.pixel) * wt;
                let s = r.norm_squared();
                let (rs, alpha_sq, js) = loss.corrector(s);
                // J ← js·(J − α/s · r rᵀ J): apply to both Jacobians.
                let mut c = [0.0; 2 * CC];
                let mut p = [0.0; 6];
                for col in 0..st.columns {
                    let (a0, a1) = (wt * j_cam[(0, col)], wt * j_cam[(1, col)]);
                    let dot = r.x * a0 + r.y * a1;
                    c[col] = js * (a0 - alpha_sq * r.x * dot);
                    c[w + col] = js * (a1 - alpha_sq * r.y * dot);
                }
                for col in 0..3 {
                    let (a0, a1) = (wt * j_pt[(0, col)], wt * j_pt[(1, col)]);
                    let dot = r.x * a0 + r.y * a1;
                    p[col] = js * (a0 - alpha_sq * r.x * dot);
                    p[3 + col] = js * (a1 - alpha_sq * r.y * dot);
                }
                // Zero the columns that are not optimised.
                let mask = st.obs_mask(st.obs_fb[i]);
                for col in 0..st.columns {
                    if mask[col] {
                        c[col] = 0.0;
                        c[w + col] = 0.0;
                    }
                }
                if !st.point_free[o.point] {
                    p = [0.0; 6];
                }
                rr[k] = [rs * r.x, rs * r.y];
                jjc[2 * w * k..2 * w * (k + 1)].copy_from_slice(&c[..2 * w]);
                jjp[k] = p;
            }
        });

    // Point gradients and JᵀJ blocks: one task per point, observations in stored order.
    let np = problem.points.len();
    let per_point: Vec<([f64; 3], [f64; 9])> = (0..np)
        .into_par_iter()
        .map(|p| {
            let mut g = [0.0; 3];
            let mut h = [0.0; 9];
            if !st.point_free[p] {
                return (g, h);
            }
            for &a in st.point_observations(p) {
                let a = a as usize;
                let (j, r) = (&jp[a], &residuals[a]);
                for u in 0..3 {
                    g[u] += j[u] * r[0] + j[3 + u] * r[1];
                    for v in 0..3 {
                        h[3 * u + v] += j[u] * j[v] + j[3 + u] * j[3 + v];
                    }
                }
            }
            (g, h)
        })
        .collect();
    let (g_p, jtj_p): (Vec<_>, Vec<_>) = per_point.into_iter().unzip();

    // Camera-side gradient and diagonal: one task per reduced block, observations in order.
    let per_block: Vec<(Vec<f64>, Vec<f64>)> = (0..st.num_fblocks())
        .into_par_iter()
        .map(|b| {
            let d = st.fblock_dim[b];
            let mut g = vec![0.0; d];
            let mut dg = vec![0.0; d];
            let cols = st.cols(b);
            for &a in st.row_observations(b) {
                let a = a as usize;
                let (j, r) = (&jc[2 * w * a..2 * w * (a + 1)], &residuals[a]);
                for u in 0..d {
                    let cu = cols[u] as usize;
                    let (j0, j1) = (j[cu], j[w + cu]);
                    g[u] += j0 * r[0] + j1 * r[1];
                    dg[u] += j0 * j0 + j1 * j1;
                }
            }
            (g, dg)
        })
        .collect();
    let mut g_f = Vec::with_capacity(st.n_reduced);
    let mut diag_f = Vec::with_capacity(st.n_reduced);
    for (g, d) in per_block {
        g_f.extend(g);
        diag_f.extend(d);
    }
    // The priors: residual Σ c·x − target, constant Jacobian c.
    let prior_residuals: Vec<f64> = problem
        .priors
        .iter()
        .map(|p| p.residual(&problem.intrinsics))
        .collect();
    for ((terms, coefs), r) in st
        .prior_cols
        .iter()
        .zip(&st.prior_coefficients)
        .zip(&prior_residuals)
    {
        for (t, c) in terms.iter().zip(coefs) {
            if let Some((b, u)) = *t {
                let i = st.fblock_offset[b] + u;
                g_f[i] += c * r;
                diag_f[i] += c * c;
            }
        }
    }
    Linearization {
        residuals,
        jc,
        columns: w,
        jp,
        g_f,
        g_p,
        jtj_p,
        diag_f,
        prior_residuals,
    }
}
