//! High dynamic range radiance maps from bracketed exposures (book chapter 10.1–10.6).
//!
//! The pipeline of Debevec & Malik, "Recovering High Dynamic Range Radiance Maps from
//! Photographs" (SIGGRAPH 1997), which the book restates in 10.2–10.4:
//!
//! 1. [`stack`]: an [`ExposureStack`] — the raw 8-bit codes `Z` of several photographs of a static
//!    scene and their exposure times `Δt` — read from a list file in the format of Debevec's
//!    `memorial.hdr_image_list.txt` ([`read_exposure_list`]) or from explicit paths and times
//!    ([`read_exposure_files`]) or from the photographs' EXIF ([`read_exposure_files_exif`],
//!    module [`exif`]), validated (same size, distinct positive exposures), with an optional mask
//!    of pixels to ignore; hand-held brackets aligned by Ward's median threshold bitmaps
//!    ([`align`]).
//! 2. [`response`]: the camera's response `g = ln f⁻¹`, one [`ResponseCurve`] of 256 entries per
//!    channel, recovered by [`calibrate_debevec`] (weighted linear least squares with a smoothness
//!    term and `g(128) = 0`).
//! 3. [`merge`]: the radiance map `ln E = Σ w(Z)(g(Z) − ln Δt) / Σ w(Z)` ([`merge_debevec`]), the
//!    inverse conversion HDR → LDR through a curve or a gamma ([`ldr_from_hdr`], 10.6), and the
//!    exposure-consistency figure used to compare curves ([`consistency_error`]).
//!
//! 4. [`probe`]: mirror-ball light probes to equirectangular images (10.7).
//!
//! Conventions: codes are the file's 8-bit values exactly as stored (no sRGB decoding — the curve
//! *is* the camera's transfer function); radiance is linear and relative (the response has one
//! free scale, fixed by `g(128) = 0` in every channel, see [`merge`] for what that does to colour).

pub mod align;
pub mod exif;
pub mod merge;
pub mod probe;
pub mod response;
pub mod stack;
pub mod stack_files;

use std::path::PathBuf;

use crate::error::ImageError;

pub use align::{
    align_exposures, align_report, apply_shifts, mtb_shifts, AlignChain, AlignOptions, AlignReport,
};
pub use exif::{
    exposure_settings, read_exposure_settings, relative_exposures, with_exposure_exif,
    ExposureSettings,
};
pub use merge::{consistency_error, ldr_from_hdr, merge_debevec, photograph, LdrOptions};
pub use probe::{probe_to_equirect, ProbeCircle, ProbeOptions};
pub use response::{
    calibrate_debevec, debevec_objective, hat_weight, sample_pixels, solve_debevec,
    solve_debevec_monotonic, CalibrateOptions, ResponseCurve, Sampling,
};
pub use stack::{
    decode_codes, exposure_list_files, parse_exposure_list, parse_seconds, read_codes,
    read_exposure_files, read_exposure_files_exif, read_exposure_list, CodeImage, Exposure,
    ExposureStack, ListEntry, StackOptions,
};
pub use stack_files::{StackFiles, StackFilesError};

/// Number of 8-bit code values: the length of a response curve (Debevec & Malik 1997, §2.1).
pub const LEVELS: usize = 256;

/// Everything that can go wrong building a stack, recovering a curve or merging (chapter 10).
/// None of these is a panic: every user input (files, sizes, times, parameters) is checked.
#[derive(thiserror::Error, Debug)]
pub enum HdrError {
    /// An image of the stack could not be read or decoded.
    #[error(transparent)]
    Image(#[from] ImageError),

    /// The list file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },

    /// A photograph's EXIF metadata is missing or lacks what is needed.
    #[error("{}: {message}", path.display())]
    Exif {
        /// The photograph.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },

    /// The list file is malformed (line numbers start at 1).
    #[error("{}:{line}: {message}", path.display())]
    ListSyntax {
        /// The list file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },

    /// The stack has no exposure.
    #[error("the exposure stack is empty")]
    EmptyStack,

    /// An exposure's size or channel count differs from the first one's.
    #[error("exposure {index} is {found}, the first exposure is {expected}")]
    SizeMismatch {
        /// 0-based index in the stack.
        index: usize,
        /// `WxHxC` of the first exposure.
        expected: String,
        /// `WxHxC` of this one.
        found: String,
    },

    /// An exposure time is not a finite positive number.
    #[error("exposure {index}: time {time} is not a finite positive number of seconds")]
    InvalidTime {
        /// 0-based index in the stack.
        index: usize,
        /// The offending time.
        time: f64,
    },

    /// Two exposures have the same time: they add no dynamic range and usually mean a typo.
    #[error("exposures {first} and {second} have the same time {time} s")]
    DuplicateExposure {
        /// The earlier index.
        first: usize,
        /// The later index.
        second: usize,
        /// The shared time.
        time: f64,
    },

    /// An argument is out of its domain (a message says which and why).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),

    /// The least-squares system has no unique solution (too few usable samples, or all of them
    /// saturated or black).
    #[error("response recovery failed: {0}")]
    Singular(String),
}
