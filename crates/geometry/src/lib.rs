//! vfxgraph-geometry: cameras and their geometry after chapters 2–5 and 8 of *Introduction to
//! Visual Effects: A Computational Approach* (Madeira & Velho, 2023).
//!
//! - [`camera`]: the K[R|t] camera of chapter 2, [`rotation`]: axis–angle (§4.5.2), [`points`]:
//!   point sets and clouds, [`normalize`]: Hartley's normalisation;
//! - [`optimize`]: chapter 3's tools (golden section, Brent, least squares, min ‖Ax‖, LM) and
//!   [`ransac`] (§3.6) generic over an [`ransac::Estimator`];
//! - [`calibration`]: one camera (chapter 4): DLT, factoring, restricted LM, Tsai, resection;
//! - [`two_view`]: two cameras (chapter 5): F, E, relative pose, triangulation;
//! - [`modeling`]: points a person marked on solved frames, triangulated (chapter 8);
//! - [`formats`]: the book's text files (cameras, points, intrinsics, marked points) and their
//!   JSON forms;
//! - [`camera_path`]: synthetic camera paths (orbit/dolly) and similarity alignment of a solve;
//!   [`synthetic`]: synthetic scenes for the tests and benchmarks;
//! - [`lens`]: lens distortion models (the `vfxgraph-lens` crate); [`undistort`]: plates
//!   undistorted (with overscan) and redistorted; [`st_map`]: the same warps as Nuke ST-maps.
//!
//! Conventions: f64; pixels with the origin at the top-left pixel's centre, x right, y down;
//! a camera maps X to K(RX + t) and looks down +z.

#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod calibration;
pub mod camera;
pub mod camera_path;
pub mod error;
pub mod formats;
/// Lens distortion models: the `vfxgraph-lens` crate (shared with the render crate).
pub use vfxgraph_lens as lens;
pub mod modeling;
pub mod normalize;
pub mod optimize;
pub mod points;
pub mod ransac;
pub mod rotation;
pub mod st_map;
pub mod synthetic;
pub mod two_view;
pub mod undistort;

pub use camera::{Camera, Frustum, Intrinsics, Pose};
pub use error::{Result, VisionError};
pub use points::{Points2d, Points3d};
