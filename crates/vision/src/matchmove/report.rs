//! The figures of a solve (the solve report): per-frame reprojection RMS and inlier count,
//! per-track error, overall RMS, time per stage, and the per-fragment figures.

use std::time::Instant;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::fragment::FragmentReport;
use super::reprojection_error;
use super::score::BookScore;
use crate::camera::{Intrinsics, Pose};
use crate::klt::Tracks;

/// Wall time of one stage.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageTime {
    /// Stage name.
    pub stage: String,
    /// Seconds.
    pub seconds: f64,
}

impl StageTime {
    /// The time since `start`, named.
    pub fn new(stage: &str, start: Instant) -> Self {
        StageTime {
            stage: stage.to_string(),
            seconds: start.elapsed().as_secs_f64(),
        }
    }
}

/// One frame's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// Frame number.
    pub frame: i64,
    /// Reconstructed points observed in the frame.
    pub observations: usize,
    /// Those within the inlier tolerance.
    pub inliers: usize,
    /// RMS reprojection error of the inliers, pixels.
    pub rms: f64,
    /// The frame's solved focal length, px, when the lens zooms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal_px: Option<f64>,
}

/// One track's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackReport {
    /// Track id.
    pub id: u64,
    /// Observations in posed frames.
    pub observations: usize,
    /// RMS reprojection error over them, pixels.
    pub rms: f64,
}

/// The report of a solve.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SolveReport {
    /// Inlier tolerance used for the per-frame figures, pixels.
    pub inlier_tolerance: f64,
    /// RMS reprojection error over all inlier observations, pixels.
    pub overall_rms: f64,
    /// Reconstructed points.
    pub points: usize,
    /// Per frame.
    pub frames: Vec<FrameReport>,
    /// Per reconstructed track.
    pub tracks: Vec<TrackReport>,
    /// Time per stage.
    pub stages: Vec<StageTime>,
    /// Per fragment (empty for stages that do not cut fragments).
    pub fragments: Vec<FragmentReport>,
    /// The book-style score over all tracks (see [`super::score`]), when computed.
    pub score: Option<BookScore>,
    /// Fallbacks taken and other remarks, for a person to read.
    pub notes: Vec<String>,
    /// What makes the solve uncertain (an ambiguous start, frames poorly determined): a
    /// person must look before trusting the cameras.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The camera was solved as a nodal pan: rotations only, every centre at the origin
    /// ([`super::tripod`]).
    #[serde(default)]
    pub rotation_only: bool,
    /// The intrinsics the solve refined (focal length, distortion), with their standard
    /// deviations ([`crate::bundle::covariance`]); empty when K was held.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub intrinsics: Vec<SolvedIntrinsic>,
}

/// One intrinsic parameter of a solve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolvedIntrinsic {
    /// `focal_px`, `k1`, `k2`.
    pub name: String,
    /// Its solved value.
    pub value: f64,
    /// Held at its given value.
    pub held: bool,
    /// Its standard deviation (the covariance at the solution scaled by the residual
    /// variance), when free and computed.
    pub sd: Option<f64>,
}

/// Builds the per-frame and per-track figures of a solve; `marks` (by track index and
/// observation) are the solve's inliers at `inlier_tolerance` (`super::inlier_marks`).
pub fn solve_report(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    marks: &[Vec<bool>],
    inlier_tolerance: f64,
) -> SolveReport {
    let n = tracks.frames.len();
    let mut frames: Vec<FrameReport> = tracks
        .frames
        .iter()
        .map(|&f| FrameReport {
            frame: f,
            observations: 0,
            inliers: 0,
            rms: 0.0,
            focal_px: None,
        })
        .collect();
    let mut sq = vec![0.0; n];
    let mut track_reports = Vec::new();
    let (mut total_sq, mut total_n) = (0.0, 0usize);
    for ((t, x), m) in tracks.tracks.iter().zip(points).zip(marks) {
        let Some(x) = x else { continue };
        let (mut s, mut c) = (0.0, 0usize);
        for (j, o) in t.points.iter().enumerate() {
            let f = t.first + j;
            let Some(Some(p)) = poses.get(f) else {
                continue;
            };
            let e = reprojection_error(k, p, x, o);
            frames[f].observations += 1;
            if m[j] {
                frames[f].inliers += 1;
                sq[f] += e * e;
                total_sq += e * e;
                total_n += 1;
            }
            if e.is_finite() {
                s += e * e;
                c += 1;
            }
        }
        track_reports.push(TrackReport {
            id: t.id,
            observations: c,
            rms: if c > 0 {
                (s / c as f64).sqrt()
            } else {
                f64::NAN
            },
        });
    }
    for (fr, s) in frames.iter_mut().zip(&sq) {
        fr.rms = if fr.inliers > 0 {
            (s / fr.inliers as f64).sqrt()
        } else {
            f64::NAN
        };
    }
    SolveReport {
        inlier_tolerance,
        overall_rms: if total_n > 0 {
            (total_sq / total_n as f64).sqrt()
        } else {
            f64::NAN
        },
        points: track_reports.len(),
        frames,
        tracks: track_reports,
        stages: Vec::new(),
        fragments: Vec::new(),
        score: None,
        notes: Vec::new(),
        warnings: Vec::new(),
        rotation_only: false,
        intrinsics: Vec::new(),
    }
}
