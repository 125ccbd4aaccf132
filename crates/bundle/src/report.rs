//! What a bundle adjustment returns (Ceres' `Solver::Summary`, plus per-camera and per-point
//! reprojection errors as the book's matchmove (7.9) needs to judge a solution).

use serde::{Deserialize, Serialize};

use super::linear_solver::LinearSolverKind;
use rayon::prelude::*;

use super::problem::Problem;
use super::residual::project_rt;
use super::rotation::angle_axis_to_matrix;

/// Why the Levenberg–Marquardt loop stopped (Ceres' termination types).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TerminationReason {
    /// |Δcost| ≤ function_tolerance·cost.
    FunctionTolerance,
    /// max |gradient| ≤ gradient_tolerance.
    GradientTolerance,
    /// ‖δ‖ ≤ parameter_tolerance·(‖x‖ + parameter_tolerance).
    ParameterTolerance,
    /// The iteration cap was reached.
    MaxIterations,
    /// The trust region shrank below its minimum: no step decreases the cost.
    TrustRegionTooSmall,
    /// Nothing to optimise.
    NoFreeParameters,
}

impl TerminationReason {
    /// True for the three convergence criteria.
    pub fn converged(self) -> bool {
        matches!(
            self,
            TerminationReason::FunctionTolerance
                | TerminationReason::GradientTolerance
                | TerminationReason::ParameterTolerance
        )
    }
}

/// One LM step (Ceres' `IterationSummary`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IterationSummary {
    /// Cost after the step (the previous cost when rejected).
    pub cost: f64,
    /// Trust region radius used (1/λ).
    pub radius: f64,
    /// Actual / predicted decrease.
    pub relative_decrease: f64,
    /// Whether the step was accepted.
    pub accepted: bool,
    /// Seconds since the solve started, at the end of this step (not serialized: a report
    /// is the same on every machine).
    #[serde(skip_serializing, default)]
    pub elapsed_seconds: f64,
}

/// The result of [`solve`](super::solve).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverReport {
    /// ½·Σρ(‖r‖²) at the start (with the robust loss, as Ceres reports it).
    pub initial_cost: f64,
    /// ½·Σρ(‖r‖²) at the end.
    pub final_cost: f64,
    /// √(Σ‖r‖²/observations) at the start, in pixels, without the loss.
    pub initial_rms: f64,
    /// √(Σ‖r‖²/observations) at the end.
    pub final_rms: f64,
    /// LM steps tried (accepted + rejected).
    pub iterations: usize,
    /// Accepted steps.
    pub successful_steps: usize,
    /// Wall-clock seconds of the solve (not serialized: a report is the same on every
    /// machine).
    #[serde(skip_serializing, default)]
    pub seconds: f64,
    /// Why it stopped.
    pub termination: TerminationReason,
    /// The linear solver actually used (never `Auto`).
    pub linear_solver: LinearSolverKind,
    /// Number of observations (residual blocks).
    pub observations: usize,
    /// Number of free scalar parameters.
    pub parameters: usize,
    /// Unknowns of the reduced camera system.
    pub reduced_size: usize,
    /// RMS of ‖r‖ per camera at the end (0 for cameras without observations).
    pub camera_rms: Vec<f64>,
    /// RMS of ‖r‖ per point at the end (0 for points without observations).
    pub point_rms: Vec<f64>,
    /// Per-step log.
    pub steps: Vec<IterationSummary>,
}

/// √(Σ‖r‖²/n) overall, per camera and per point, at the problem's current parameters.
pub fn reprojection_errors(problem: &Problem) -> (f64, Vec<f64>, Vec<f64>) {
    let mut cam = vec![(0.0, 0usize); problem.cameras.len()];
    let mut pt = vec![(0.0, 0usize); problem.points.len()];
    let mut total = 0.0;
    let rots: Vec<_> = problem
        .cameras
        .par_iter()
        .map(|c| angle_axis_to_matrix(&c.rotation))
        .collect();
    let errors: Vec<f64> = problem
        .observations
        .par_iter()
        .map(|o| {
            let c = &problem.cameras[o.camera];
            let k = &problem.intrinsics[c.intrinsics];
            let x = &problem.points[o.point].position;
            (project_rt(k, &rots[o.camera], &c.translation, x) - o.pixel).norm_squared()
        })
        .collect();
    for (o, &e) in problem.observations.iter().zip(&errors) {
        total += e;
        cam[o.camera].0 += e;
        cam[o.camera].1 += 1;
        pt[o.point].0 += e;
        pt[o.point].1 += 1;
    }
    let rms = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
    (
        (total / problem.observations.len().max(1) as f64).sqrt(),
        cam.into_iter().map(rms).collect(),
        pt.into_iter().map(rms).collect(),
    )
}
