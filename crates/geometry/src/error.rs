//! Errors of the camera crates (geometry, matchmove, exchange).
//!
//! Every estimator checks its input and reports a typed error instead of returning NaN or
//! panicking (ARCHITECTURE.md, "Conventions").

use std::path::PathBuf;

/// The error type of every fallible function of this crate.
#[derive(Debug, thiserror::Error)]
pub enum VisionError {
    /// An estimator was given fewer correspondences than its minimal sample.
    #[error("too few points: {needed} needed, {got} given")]
    TooFewPoints {
        /// Minimum number of points the method needs.
        needed: usize,
        /// Number of points given.
        got: usize,
    },
    /// Two lists that must correspond one to one have different lengths.
    #[error("length mismatch: {first} vs {second} points")]
    LengthMismatch {
        /// Length of the first list.
        first: usize,
        /// Length of the second list.
        second: usize,
    },
    /// The input does not determine the model (e.g. coplanar 3D points for the DLT,
    /// a rank-deficient design matrix, a planar scene for the 8-point algorithm).
    #[error("degenerate configuration: {0}")]
    Degenerate(String),
    /// A point is (numerically) at infinity: its homogeneous weight vanishes, or it
    /// projects onto a camera's principal plane.
    #[error("point at infinity")]
    PointsAtInfinity,
    /// The two cameras share their centre (pure rotation): no depth can be recovered.
    #[error("zero baseline: the two views are related by a pure rotation")]
    ZeroBaseline,
    /// An input value is not finite or out of its domain.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A sequence's frames show no parallax (the camera turned about its centre or did not
    /// move): there is no depth to reconstruct, and a rotation-only solve applies.
    #[error("no parallax: {0}")]
    NoParallax(String),
    /// RANSAC found no model with enough inliers.
    #[error(
        "robust estimation failed: best consensus {best} of {total}, at least {needed} needed"
    )]
    NoConsensus {
        /// Best consensus size found.
        best: usize,
        /// Number of data.
        total: usize,
        /// Minimal consensus accepted.
        needed: usize,
    },
    /// A file could not be parsed.
    #[error("{file}:{line}: {message}")]
    Parse {
        /// File name (or `<string>` when parsing text).
        file: String,
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// JSON (de)serialization failed.
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
}

impl From<vfxgraph_lens::LensError> for VisionError {
    fn from(e: vfxgraph_lens::LensError) -> Self {
        VisionError::InvalidInput(e.0)
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, VisionError>;

/// Check that two correspondence lists have equal length and at least `needed` entries.
pub(crate) fn check_pairs(first: usize, second: usize, needed: usize) -> Result<()> {
    if first != second {
        return Err(VisionError::LengthMismatch { first, second });
    }
    if first < needed {
        return Err(VisionError::TooFewPoints { needed, got: first });
    }
    Ok(())
}

/// Check that every coordinate of a list of points is finite.
pub(crate) fn check_finite<'a, I>(what: &str, values: I) -> Result<()>
where
    I: IntoIterator<Item = &'a f64>,
{
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(VisionError::InvalidInput(format!(
            "{what} contain a non-finite coordinate"
        )))
    }
}
