//! Errors of the bundle adjuster.

use thiserror::Error;

/// Everything that can go wrong when reading or solving a bundle adjustment problem
/// (book section 7.7; the problem model follows Ceres' "problem is data" design).
#[derive(Debug, Error)]
pub enum BundleError {
    /// An I/O error while reading or writing a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A malformed BAL file ("Bundle Adjustment in the Large" text format).
    #[error("BAL parse error at token {token} (line {line}): {message}")]
    Parse {
        /// 1-based line of the offending token.
        line: usize,
        /// 0-based index of the offending token.
        token: usize,
        /// What was wrong.
        message: String,
    },
    /// A NaN or infinite value in the input.
    #[error("non-finite value in {what}")]
    NonFinite {
        /// Which input value (e.g. "camera 3 rotation").
        what: String,
    },
    /// An observation or camera refers to a block that does not exist.
    #[error("index out of range: {what}")]
    IndexOutOfRange {
        /// Which reference.
        what: String,
    },
    /// The problem cannot be solved as given (e.g. nothing is free, no observations).
    #[error("invalid problem: {0}")]
    InvalidProblem(String),
    /// The linear solver failed in a way damping cannot fix.
    #[error("linear solver failure: {0}")]
    LinearSolver(String),
}
