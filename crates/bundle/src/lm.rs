//! The Levenberg–Marquardt trust-region loop (book 3.3.2 and 7.7; Triggs et al. 2000, 4.2;
//! the step control is Ceres' `LevenbergMarquardtStrategy` and `TrustRegionMinimizer`).
//!
//! Each iteration solves the damped normal equations `(JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr` through the
//! Schur complement on the points ([`super::schur`]), with λ = 1/radius. A step is accepted when
//! the actual decrease is at least `min_relative_decrease` of the decrease the linear model
//! predicts (ρ); then radius ← radius / max(1/3, 1 − (2ρ − 1)³), else radius ← radius / v,
//! v ← 2v (Nielsen's rule, as Ceres).

use std::time::Instant;

use nalgebra::Vector3;
use rayon::prelude::*;

use super::camera_model::Intrinsics;
use super::error::BundleError;
use super::evaluate::{self, linearize, Linearization, CHUNK};
use super::linear_solver::pcg::PcgOptions;
use super::linear_solver::{LinearSolver, LinearSolverKind};
use super::loss::Loss;
use super::problem::{CameraPose, Point, Problem};
use super::report::{reprojection_errors, IterationSummary, SolverReport, TerminationReason};
use super::structure::{Structure, NONE};

/// Options of [`solve`]; the defaults are Ceres' defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Maximum number of LM steps (Ceres: `max_num_iterations`, 50).
    pub max_iterations: usize,
    /// Robust loss applied to every observation.
    pub loss: Loss,
    /// Linear solver of the reduced camera system.
    pub linear_solver: LinearSolverKind,
    /// Stop when |Δcost| ≤ this·cost (Ceres: 1e-6).
    pub function_tolerance: f64,
    /// Stop when max |Jᵀr| ≤ this (Ceres: 1e-10).
    pub gradient_tolerance: f64,
    /// Stop when ‖δ‖ ≤ this·(‖x‖ + this) (Ceres: 1e-8).
    pub parameter_tolerance: f64,
    /// Initial trust region radius 1/λ (Ceres: 1e4).
    pub initial_trust_region_radius: f64,
    /// Largest radius (Ceres: 1e16).
    pub max_trust_region_radius: f64,
    /// Smallest radius before giving up (Ceres: 1e-32).
    pub min_trust_region_radius: f64,
    /// Minimum actual/predicted decrease to accept a step (Ceres: 1e-3).
    pub min_relative_decrease: f64,
    /// Conjugate-gradient settings for [`LinearSolverKind::IterativeSchur`].
    pub pcg: PcgOptions,
    /// Run in a rayon pool of this many threads (`None`: the current pool). Results are
    /// identical for every value.
    pub num_threads: Option<usize>,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 50,
            loss: Loss::Trivial,
            linear_solver: LinearSolverKind::Auto,
            function_tolerance: 1e-6,
            gradient_tolerance: 1e-10,
            parameter_tolerance: 1e-8,
            initial_trust_region_radius: 1e4,
            max_trust_region_radius: 1e16,
            min_trust_region_radius: 1e-32,
            min_relative_decrease: 1e-3,
            pcg: PcgOptions::default(),
            num_threads: None,
        }
    }
}

/// Bundle-adjusts `problem` in place: Levenberg–Marquardt with the Schur complement on the
/// points (Triggs et al. 2000; Agarwal et al. 2010; book 7.7). Returns the report; the problem
/// holds the best parameters found.
pub fn solve(problem: &mut Problem, options: &SolverOptions) -> Result<SolverReport, BundleError> {
    problem.validate()?;
    validate_options(options)?;
    match options.num_threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n.max(1))
                .build()
                .map_err(|e| BundleError::InvalidProblem(format!("thread pool: {e}")))?;
            pool.install(|| solve_inner(problem, options))
        }
        None => solve_inner(problem, options),
    }
}

fn validate_options(o: &SolverOptions) -> Result<(), BundleError> {
    let scale_ok = match o.loss {
        Loss::Trivial => true,
        Loss::Huber { scale } | Loss::Cauchy { scale } => scale.is_finite() && scale > 0.0,
    };
    if !scale_ok {
        return Err(BundleError::InvalidProblem(
            "loss scale must be finite and positive".into(),
        ));
    }
    if !(o.initial_trust_region_radius > 0.0 && o.initial_trust_region_radius.is_finite()) {
        return Err(BundleError::InvalidProblem(
            "initial trust region radius must be positive".into(),
        ));
    }
    Ok(())
}

struct Saved {
    cameras: Vec<CameraPose>,
    intrinsics: Vec<Intrinsics>,
    points: Vec<Point>,
}

fn save(p: &Problem) -> Saved {
    Saved {
        cameras: p.cameras.clone(),
        intrinsics: p.intrinsics.clone(),
        points: p.points.clone(),
    }
}

fn restore(p: &mut Problem, s: &Saved) {
    p.cameras.clone_from(&s.cameras);
    p.intrinsics.clone_from(&s.intrinsics);
    p.points.clone_from(&s.points);
}

/// x ← x + δ on the free blocks (plain addition, also on the axis–angle vector, as Ceres'
/// bundle_adjuster does without a manifold).
fn apply_step(p: &mut Problem, st: &Structure, df: &[f64], dp: &[[f64; 3]]) {
    for (b, blk) in st.fblocks.iter().enumerate() {
        let d = &df[st.fblock_offset[b]..][..st.fblock_dim[b]];
        for (&col, dv) in st.cols(b).iter().zip(d) {
            let col = col as usize;
            match (col, blk.camera, blk.intrinsics) {
                (0..3, Some(i), _) => p.cameras[i].rotation[col] += dv,
                (3..6, Some(i), _) => p.cameras[i].translation[col - 3] += dv,
                (_, _, Some(k)) => p.intrinsics[k].params[col - 6] += dv,
                _ => {}
            }
        }
    }
    for (pt, d) in p.points.iter_mut().zip(dp) {
        if !pt.fixed {
            pt.position += Vector3::new(d[0], d[1], d[2]);
        }
    }
}

fn free_parameter_norm(p: &Problem, st: &Structure) -> f64 {
    let mut s = 0.0;
    for (b, blk) in st.fblocks.iter().enumerate() {
        let has_pose = st.cols(b).first() == Some(&0);
        if let (Some(i), true) = (blk.camera, has_pose) {
            s += p.cameras[i].rotation.norm_squared() + p.cameras[i].translation.norm_squared();
        }
        if let Some(k) = blk.intrinsics {
            s += p.intrinsics[k].params.iter().map(|v| v * v).sum::<f64>();
        }
    }
    s += p
        .points
        .iter()
        .filter(|q| !q.fixed)
        .map(|q| q.position.norm_squared())
        .sum::<f64>();
    s.sqrt()
}

/// Back-substitution δp = C⁻¹(−g_p − Eᵀ δf) per point.
fn back_substitute(
    st: &Structure,
    lin: &Linearization,
    c_inv: &[[f64; 9]],
    df: &[f64],
) -> Vec<[f64; 3]> {
    (0..c_inv.len())
        .into_par_iter()
        .map(|p| {
            if !st.point_free[p] {
                return [0.0; 3];
            }
            let mut rhs = [-lin.g_p[p][0], -lin.g_p[p][1], -lin.g_p[p][2]];
            for &a in st.point_observations(p) {
                let a = a as usize;
                let jd = camera_jdelta(st, lin, a, df);
                let jp = &lin.jp[a];
                for u in 0..3 {
                    rhs[u] -= jp[u] * jd[0] + jp[3 + u] * jd[1];
                }
            }
            let c = &c_inv[p];
            [
                c[0] * rhs[0] + c[1] * rhs[1] + c[2] * rhs[2],
                c[3] * rhs[0] + c[4] * rhs[1] + c[5] * rhs[2],
                c[6] * rhs[0] + c[7] * rhs[1] + c[8] * rhs[2],
            ]
        })
        .collect()
}

/// Jcₐ δf for observation a (2-vector).
fn camera_jdelta(st: &Structure, lin: &Linearization, a: usize, df: &[f64]) -> [f64; 2] {
    let jc = lin.jc(a);
    let mut out = [0.0; 2];
    for &b in &st.obs_fb[a] {
        if b == NONE {
            continue;
        }
        let o = st.fblock_offset[b as usize];
        for (u, &c) in st.cols(b as usize).iter().enumerate() {
            out[0] += jc[c as usize] * df[o + u];
            out[1] += jc[lin.columns + c as usize] * df[o + u];
        }
    }
    out
}

/// Predicted decrease of the Gauss–Newton model: −(gᵀδ + ½‖Jδ‖²), reduced in a fixed order.
fn model_decrease(st: &Structure, lin: &Linearization, df: &[f64], dp: &[[f64; 3]]) -> f64 {
    let n = lin.len();
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut s = 0.0;
            for a in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let mut jd = camera_jdelta(st, lin, a, df);
                let p = st.obs_point[a] as usize;
                let jp = &lin.jp[a];
                let d = &dp[p];
                jd[0] += jp[0] * d[0] + jp[1] * d[1] + jp[2] * d[2];
                jd[1] += jp[3] * d[0] + jp[4] * d[1] + jp[5] * d[2];
                let r = &lin.residuals[a];
                // ½‖r + Jδ‖² − ½‖r‖² = rᵀJδ + ½‖Jδ‖²
                s += r[0] * jd[0] + r[1] * jd[1] + 0.5 * (jd[0] * jd[0] + jd[1] * jd[1]);
            }
            s
        })
        .collect();
    // The priors' terms: r·(cᵀδ) + ½(cᵀδ)².
    let mut priors = 0.0;
    for ((terms, coefs), r) in st
        .prior_cols
        .iter()
        .zip(&st.prior_coefficients)
        .zip(&lin.prior_residuals)
    {
        let jd: f64 = terms
            .iter()
            .zip(coefs)
            .filter_map(|(t, c)| t.map(|(b, u)| c * df[st.fblock_offset[b] + u]))
            .sum();
        priors += r * jd + 0.5 * jd * jd;
    }
    -(partial.iter().sum::<f64>() + priors)
}

fn solve_inner(problem: &mut Problem, o: &SolverOptions) -> Result<SolverReport, BundleError> {
    let start = Instant::now();
    let st = Structure::new(problem);
    let linear_kind = o.linear_solver.resolve(st.n_reduced);
    let parameters = problem.num_free_parameters();
    let (initial_rms, _, _) = reprojection_errors(problem);
    let mut cost = evaluate::cost(problem, &o.loss);
    if !cost.is_finite() {
        return Err(BundleError::NonFinite {
            what: "initial cost (a point projects at infinity?)".into(),
        });
    }
    let initial_cost = cost;
    let mut steps = Vec::new();
    let mut successful_steps = 0;
    let finish = |problem: &Problem,
                  cost: f64,
                  termination: TerminationReason,
                  steps: Vec<IterationSummary>,
                  successful_steps: usize| {
        let (final_rms, camera_rms, point_rms) = reprojection_errors(problem);
        SolverReport {
            initial_cost,
            final_cost: cost,
            initial_rms,
            final_rms,
            iterations: steps.len(),
            successful_steps,
            seconds: start.elapsed().as_secs_f64(),
            termination,
            linear_solver: linear_kind,
            observations: problem.observations.len(),
            parameters,
            reduced_size: st.n_reduced,
            camera_rms,
            point_rms,
            steps,
        }
    };
    if parameters == 0 {
        return Ok(finish(
            problem,
            cost,
            TerminationReason::NoFreeParameters,
            steps,
            0,
        ));
    }
    let mut solver = LinearSolver::new(linear_kind, &st, o.pcg)?;
    let mut lin = linearize(problem, &o.loss, &st);
    let mut radius = o.initial_trust_region_radius;
    let mut decrease_factor = 2.0;
    let grad_max = |lin: &Linearization| {
        lin.g_f
            .iter()
            .chain(lin.g_p.iter().flatten())
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    if grad_max(&lin) <= o.gradient_tolerance {
        return Ok(finish(
            problem,
            cost,
            TerminationReason::GradientTolerance,
            steps,
            0,
        ));
    }
    let termination = loop {
        if steps.len() >= o.max_iterations {
            break TerminationReason::MaxIterations;
        }
        if radius < o.min_trust_region_radius {
            break TerminationReason::TrustRegionTooSmall;
        }
        let lambda = 1.0 / radius;
        let sys = st.assemble(&lin, lambda);
        let Some(df) = solver.solve(&st, &sys) else {
            steps.push(IterationSummary {
                cost,
                radius,
                relative_decrease: 0.0,
                accepted: false,
                elapsed_seconds: start.elapsed().as_secs_f64(),
            });
            radius /= decrease_factor;
            decrease_factor *= 2.0;
            continue;
        };
        let dp = back_substitute(&st, &lin, &sys.c_inv, &df);
        let predicted = model_decrease(&st, &lin, &df, &dp);
        let step_norm = (df.iter().map(|v| v * v).sum::<f64>()
            + dp.iter().flatten().map(|v| v * v).sum::<f64>())
        .sqrt();
        let x_norm = free_parameter_norm(problem, &st);
        if step_norm <= o.parameter_tolerance * (x_norm + o.parameter_tolerance) {
            break TerminationReason::ParameterTolerance;
        }
        let saved = save(problem);
        apply_step(problem, &st, &df, &dp);
        let new_cost = evaluate::cost(problem, &o.loss);
        let rho = if predicted > 0.0 && new_cost.is_finite() {
            (cost - new_cost) / predicted
        } else {
            f64::NEG_INFINITY
        };
        let converged_f =
            new_cost.is_finite() && (cost - new_cost).abs() <= o.function_tolerance * cost;
        if rho > o.min_relative_decrease {
            steps.push(IterationSummary {
                cost: new_cost,
                radius,
                relative_decrease: rho,
                accepted: true,
                elapsed_seconds: start.elapsed().as_secs_f64(),
            });
            successful_steps += 1;
            cost = new_cost;
            if converged_f {
                break TerminationReason::FunctionTolerance;
            }
            let f = (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
            radius = (radius / f).min(o.max_trust_region_radius);
            decrease_factor = 2.0;
            lin = linearize(problem, &o.loss, &st);
            if grad_max(&lin) <= o.gradient_tolerance {
                break TerminationReason::GradientTolerance;
            }
        } else {
            restore(problem, &saved);
            steps.push(IterationSummary {
                cost,
                radius,
                relative_decrease: rho,
                accepted: false,
                elapsed_seconds: start.elapsed().as_secs_f64(),
            });
            if converged_f {
                break TerminationReason::FunctionTolerance;
            }
            radius /= decrease_factor;
            decrease_factor *= 2.0;
        }
    };
    Ok(finish(problem, cost, termination, steps, successful_steps))
}
