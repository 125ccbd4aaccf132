//! vfxgraph-bundle: sparse bundle adjustment, Levenberg–Marquardt with the Schur complement on
//! the points, after section 7.7 of *Introduction to Visual Effects: A Computational Approach*
//! (Madeira & Velho, 2023).
//!
//! The book's bundle adjustment (section 7.7, code in 7.15.1–7.15.2) is dense with numeric
//! derivatives. This crate is the large-scale version described by Triggs et al., "Bundle
//! Adjustment — A Modern Synthesis" (2000), and Agarwal et al., "Bundle Adjustment in the Large"
//! (ECCV 2010), organised like Ceres Solver: the [`Problem`] is data (camera, intrinsics and point
//! blocks referenced by index from observations), losses are values ([`Loss`]), and one solver
//! ([`solve`]) chooses its linear solver ([`LinearSolverKind`]) automatically unless told.
//!
//! One concept per file:
//! - [`rotation`]: axis–angle rotation with its analytic Jacobian (book 4.5.2);
//! - [`camera_model`]: the intrinsics block and its camera models; [`residual`]: the
//!   reprojection residual with analytic Jacobians;
//! - [`loss`]: robust losses and Triggs' correction;
//! - [`problem`]: parameter blocks, observations, fixed flags, priors and the gauge;
//! - [`structure`]: the problem's fixed block structure; [`schur`]: the reduced camera system
//!   (Schur complement on the points);
//! - [`linear_solver`]: dense / sparse Cholesky and block-Jacobi PCG on the reduced system;
//! - [`lm`]: the Levenberg–Marquardt trust-region loop;
//! - [`report`]: what a solve returns; [`covariance`]: the solved intrinsics' uncertainty;
//! - [`sequence`]: a tracked sequence's cameras and points adjusted as one problem;
//! - [`bal`]: the BAL text format; [`synthetic`]: video-like test problems; [`bench`]: the
//!   `vfxgraph bench ba` entry point.
//!
//! ```no_run
//! use vfxgraph_bundle::{read_bal, solve, Loss, SolverOptions};
//!
//! let mut problem = read_bal("problem-49-7776-pre.txt")?;
//! let report = solve(
//!     &mut problem,
//!     &SolverOptions { loss: Loss::Huber { scale: 1.0 }, ..SolverOptions::default() },
//! )?;
//! println!("{} -> {} in {} steps", report.initial_cost, report.final_cost, report.iterations);
//! # Ok::<(), vfxgraph_bundle::BundleError>(())
//! ```

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Index loops over small fixed-size blocks read like the formulas they implement.
#![allow(clippy::needless_range_loop)]

pub mod bal;
pub mod bench;
pub mod camera_model;
pub mod covariance;
pub mod error;
mod evaluate;
pub mod linear_solver;
pub mod lm;
pub mod loss;
pub mod problem;
pub mod report;
pub mod residual;
pub mod rotation;
pub mod schur;
pub mod sequence;
pub mod structure;
pub mod synthetic;

pub use bal::{read_bal, read_bal_str, write_bal};
pub use bench::{solve_bal_file, BalBenchOptions, BalBenchReport};
pub use camera_model::{CameraModel, Intrinsics, INTRINSICS};
pub use covariance::{intrinsics_covariance, IntrinsicsCovariance};
pub use error::BundleError;
pub use linear_solver::LinearSolverKind;
pub use lm::{solve, SolverOptions};
pub use loss::{Loss, RobustLoss};
pub use problem::{zoom_priors, CameraPose, Gauge, Observation, Point, Prior, PriorTerm, Problem};
pub use report::{SolverReport, TerminationReason};
pub use sequence::{adjust_sequence, AdjustedSequence, SequenceAdjustOptions, SolverChoice};

#[cfg(test)]
mod tests;
