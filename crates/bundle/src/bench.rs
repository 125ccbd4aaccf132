//! The library side of `vfxgraph bench ba FILE`: solve a BAL file with every camera and point
//! free, as Ceres' `bundle_adjuster` example does (Agarwal et al. 2010), and report the figures
//! the Ceres comparison needs.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::bal::read_bal;
use super::error::BundleError;
use super::linear_solver::LinearSolverKind;
use super::lm::{solve, SolverOptions};
use super::loss::Loss;
use super::report::TerminationReason;

/// Options of [`solve_bal_file`] (the flags of `vfxgraph bench ba`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BalBenchOptions {
    /// `--solver auto|dense|sparse|iterative`.
    pub solver: LinearSolverKind,
    /// `--loss none|huber[:a]|cauchy[:a]`.
    pub loss: Loss,
    /// `--max-iterations N`.
    pub max_iterations: usize,
    /// Threads (`None`: rayon's default, one per core).
    pub num_threads: Option<usize>,
}

impl Default for BalBenchOptions {
    fn default() -> Self {
        BalBenchOptions {
            solver: LinearSolverKind::Auto,
            loss: Loss::Trivial,
            max_iterations: 50,
            num_threads: None,
        }
    }
}

/// What `vfxgraph bench ba --json` prints. The first five fields are a stable contract (scripts read them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BalBenchReport {
    /// ½·Σρ(‖r‖²) at the file's parameters.
    pub initial_cost: f64,
    /// ½·Σρ(‖r‖²) at the end.
    pub final_cost: f64,
    /// LM steps (accepted + rejected).
    pub iterations: usize,
    /// Wall-clock seconds of the solve (parsing excluded, as in Ceres' summary).
    pub seconds: f64,
    /// Number of observations.
    pub observations: usize,
    /// Accepted steps.
    pub successful_steps: usize,
    /// Seconds spent reading the file.
    pub parse_seconds: f64,
    /// √(2·final_cost/observations) for the trivial loss: RMS of ‖r‖ per observation, pixels.
    pub final_rms: f64,
    /// Cameras, points.
    pub cameras: usize,
    /// Points.
    pub points: usize,
    /// The linear solver used.
    pub linear_solver: LinearSolverKind,
    /// Why it stopped.
    pub termination: TerminationReason,
    /// `[seconds since the solve started, cost]` at the start and after every step, to measure
    /// the time to reach a given cost.
    pub trace: Vec<[f64; 2]>,
}

/// Reads a BAL file and bundle-adjusts it with everything free (the `vfxgraph bench ba` command).
pub fn solve_bal_file(
    path: impl AsRef<Path>,
    options: &BalBenchOptions,
) -> Result<BalBenchReport, BundleError> {
    let t0 = Instant::now();
    let mut problem = read_bal(path)?;
    let parse_seconds = t0.elapsed().as_secs_f64();
    let opts = SolverOptions {
        max_iterations: options.max_iterations,
        loss: options.loss,
        linear_solver: options.solver,
        num_threads: options.num_threads,
        ..SolverOptions::default()
    };
    let report = solve(&mut problem, &opts)?;
    Ok(BalBenchReport {
        initial_cost: report.initial_cost,
        final_cost: report.final_cost,
        iterations: report.iterations,
        seconds: report.seconds,
        observations: report.observations,
        successful_steps: report.successful_steps,
        parse_seconds,
        final_rms: report.final_rms,
        cameras: problem.cameras.len(),
        points: problem.points.len(),
        linear_solver: report.linear_solver,
        termination: report.termination,
        trace: std::iter::once([0.0, report.initial_cost])
            .chain(report.steps.iter().map(|s| [s.elapsed_seconds, s.cost]))
            .collect(),
    })
}
