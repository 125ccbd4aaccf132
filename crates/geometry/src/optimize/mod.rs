//! Optimization tools of chapter 3: minimization on an interval (golden section §3.1 and Brent),
//! linear least squares (§3.2), min ‖Ax‖ on the unit sphere (§3.4, Theorem 3.2) and
//! Levenberg–Marquardt (§3.3.2).

pub mod brent;
pub mod golden;
pub mod least_squares;
pub mod lm;

pub use brent::brent_minimize;
pub use golden::golden_section_minimize;
pub use least_squares::{linear_least_squares, min_norm_on_sphere, NullVector};
pub use lm::{levenberg_marquardt, LeastSquaresProblem, LmOptions, LmReport, LmTermination};

use serde::{Deserialize, Serialize};

/// Result of a one-dimensional minimization.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Minimum1d {
    /// Abscissa of the minimum found.
    pub x: f64,
    /// f(x).
    pub fx: f64,
    /// Number of iterations.
    pub iterations: usize,
    /// Number of evaluations of f.
    pub evaluations: usize,
}
