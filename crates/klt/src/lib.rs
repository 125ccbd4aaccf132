//! vfxgraph-klt: KLT feature tracking after chapter 6 of *Introduction to Visual Effects: A
//! Computational Approach* (Madeira & Velho, 2023): Shi–Tomasi corners ([`corners`], 6.4), image
//! pyramids ([`pyramid`]), pyramidal Lucas–Kanade ([`lucas_kanade`], 6.2–6.3), the tracks
//! model with the book's `f.txt` format ([`tracks`]) and the sequence tracker with disposal
//! and replacement of windows ([`tracker`], 6.5), optionally drift-corrected against each
//! feature's first window ([`drift`]), with the residual threshold raised to the footage's
//! measured noise ([`noise`]); tracks drawn over their frames or written as text ([`overlay`]);
//! with the `opencv` feature, `opencv`: the same tracker with OpenCV's corners and LK, to
//! cross-check ours.
//!
//! Brightness is on a 0–255 perceptual scale ([`GrayImage::from_image`]); pixel centres are
//! at integer coordinates, (0, 0) the top-left pixel's centre, x right, y down.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod corners;
pub mod drift;
pub mod lucas_kanade;
pub mod noise;
#[cfg(feature = "opencv")]
pub mod opencv;
pub mod overlay;
pub mod pyramid;
pub mod tracker;
pub mod tracks;

pub use corners::{good_features_to_track, min_eigen_map, Corner, CornerOptions};
pub use lucas_kanade::{track_point, track_points, LkOptions, LkResult};
pub use noise::noise_sigma;
pub use overlay::{draw_tracks, DrawTracksOptions, TracksFormat, WriteTracksOptions};
pub use pyramid::{pyr_down, GrayImage, Level, Pyramid};
pub use tracker::{track_loaded, track_sequence, Tracker, TrackerOptions};
pub use tracks::{LostReason, Track, TrackEnd, Tracks};

/// Errors of the tracker (book chapter 6).
#[derive(Debug, thiserror::Error)]
pub enum KltError {
    /// An image or mask that cannot be used (empty, wrong number of values).
    #[error("bad image: {0}")]
    BadImage(String),
    /// Frames of one sequence differ in size.
    #[error("frame size {found:?} differs from the sequence's {expected:?}")]
    SizeMismatch {
        /// Size of the earlier frames.
        expected: (usize, usize),
        /// Size of this frame.
        found: (usize, usize),
    },
    /// A parameter out of range.
    #[error("bad parameter: {0}")]
    BadParam(String),
    /// A tracks file that does not parse.
    #[error("line {line}: {message}")]
    Parse {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Tracks that break the model's invariants.
    #[error("inconsistent tracks: {0}")]
    BadTracks(String),
}

#[cfg(test)]
mod tests;

/// For the tests that compare the AVX2 loops with the portable ones: whether this CPU runs the
/// AVX2 loops. When it does not, the test says so on stderr (the comparison would set the
/// portable loops against themselves) and skips it.
#[cfg(test)]
pub(crate) fn has_avx2_or_say_so(test: &str) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        return true;
    }
    eprintln!("notice: {test}: this CPU has no AVX2, so its AVX2 loops are not compared");
    false
}
