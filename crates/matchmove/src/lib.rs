//! vfxgraph-matchmove: the camera of every frame of a shot, from feature tracks and known
//! intrinsics K, after chapter 7 of *Introduction to Visual Effects: A Computational Approach*
//! (Madeira & Velho, 2023).
//!
//! **The entry** is [`solve`] ([`matchmove_with_lens`]): it decides how the camera moves
//! ([`parallax`]) and solves a zooming lens ([`zoom`]), a nodal pan ([`tripod`], its rotations
//! from [`rotations`]), or a moving camera: the book's pipeline ([`pipeline`]) on tracks
//! undistorted by a known lens ([`lens`]), or rounds of it with the lens adjusted ([`general`])
//! from a focal-length search ([`focal`]).
//!
//! The book's pipeline ([`pipeline::matchmove`], K known) runs stages, each its own module,
//! named as the book's chapter 7 names them:
//!
//! 1. [`fragments`] (§7.11) cuts the sequence into overlapping fragments;
//! 2. [`pair`] (§7.2–7.6) finds each fragment's best frame pair: by default from the calibrated
//!    minimal solvers (five-point E or the homography's motions, P3P for every frame), with
//!    `init: book` the book's RANSAC on F, E, cheirality, triangulation, DLT resection of every
//!    frame and the intrinsics-consistency test;
//! 3. [`fragment`] (§7.9) resects every frame of a fragment and runs the refinement cycles
//!    (bundle adjustment, re-triangulation at 10, 5, 3 px); [`recovery`] retries a fragment
//!    that cannot start and keeps the longest run of solved pieces;
//! 4. [`junction`] (§7.12) finds the scale between neighbouring fragments and chains them into
//!    the first fragment's frame and scale;
//! 5. [`extend`] gives a camera to frames no fragment covers (resection from the joined cloud);
//! 6. [`global`] bundle-adjusts the whole sequence with a robust loss, and [`relax`] (§7.14) is
//!    the book's alternating relaxation;
//! 7. [`score`] measures a solve the way the book's own cameras were scored, and [`report`]
//!    gathers per-frame and per-track figures and the warnings; [`corpus`] generates the
//!    robustness corpus the solve is measured on.
//!
//! [`matchmove`] runs stages 1–6 (fragments in parallel); every constant is in
//! [`MatchmoveOptions`] ([`options`]) with the book's value as default. What every stage
//! measures with cameras and points by index (projection, reprojection error, triangulation)
//! is in [`structure`]; [`adjust`] builds the stages' bundle adjustments; [`refine`] refines a
//! path solved before (the book's relaxation, the global adjustment).

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod adjust;
pub mod corpus;
pub mod extend;
pub mod focal;
pub mod fragment;
pub mod fragments;
pub mod general;
pub mod global;
pub mod grid;
pub mod junction;
pub mod lens;
pub mod options;
pub mod pair;
pub mod parallax;
pub mod pipeline;
pub mod recovery;
pub mod refine;
pub mod relax;
pub mod report;
pub mod rotations;
pub mod score;
pub mod solve;
pub mod structure;
pub mod synthetic;
pub mod track_weights;
pub mod tripod;
pub mod zoom;

pub use focal::estimate_focal;
pub use fragment::{solve_fragment, Ambiguity, FragmentSolution, RefineOptions};
pub use fragments::{split_fragments, Fragment, FragmentOptions};
pub use global::{global_bundle_adjust, GlobalOptions};
pub use junction::{join_fragments, ScaleOptions};
pub use lens::{undistort_tracks, DistortionMode, FocalMode, LensOptions, PrincipalPoint};
pub use options::MatchmoveOptions;
pub use pair::{InitMethod, PairOptions, PairRejections};
pub use parallax::{measure_parallax, MotionOptions, Parallax, SolveMode};
pub use pipeline::{finish_solve, matchmove, solve_progress, Solve};
pub use refine::{
    adjust_path, pinhole_view, relax_path, GlobalPathOptions, RelaxPathOptions, Score,
};
pub use relax::{relax, RelaxOptions};
pub use report::{SolveReport, StageTime};
pub use score::{score_cameras, BookScore};
pub use solve::matchmove_with_lens;
pub use structure::{points_by_track, poses_by_index, Poses, Structure, TrackPoints};
pub use tripod::solve_rotations;

#[cfg(test)]
mod tests;
