//! The bundle-adjustment glue of the matchmove (book §7.7 with the sparse solver of
//! [`vfxgraph_bundle`]): posed frames and triangulated tracks, indexed by frame and track, turned
//! into a [`vfxgraph_bundle::Problem`] — one shared intrinsics block (a fixed K, or the lens a
//! solve refines) or one per frame (a zoom, with its priors) — solved, and written back.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_klt::Tracks;

/// The weight of track `t`'s observation in frame `f` in a bundle adjustment: 0 leaves it
/// out, 1 is plain least squares ([`vfxgraph_bundle::Observation::weight`]).
pub(crate) type ObservationWeight<'a> = dyn Fn(usize, usize) -> f64 + Sync + 'a;

/// Bundle adjustment (book §7.7, the sparse solver of [`vfxgraph_bundle`]) of the posed frames and
/// triangulated tracks, K fixed, over the observations of non-zero `weight(track, frame)`
/// (their residuals multiplied by it, [`vfxgraph_bundle::Observation::weight`]). `poses` is
/// indexed by frame index, `points` by track index; `None` entries take no part. The gauge is
/// fixed by the first posed frame and the scale of the first baseline.
pub(crate) fn bundle_adjust_indexed(
    tracks: &Tracks,
    k: &Intrinsics,
    poses: &mut [Option<Pose>],
    points: &mut [Option<Vector3<f64>>],
    weight: &ObservationWeight<'_>,
    loss: vfxgraph_bundle::Loss,
    max_iterations: usize,
) -> Result<vfxgraph_bundle::SolverReport> {
    let gauge = vfxgraph_bundle::Gauge::FixFirstCameraAndScale;
    adjust_with_block(
        tracks,
        pinhole_block(k),
        gauge,
        poses,
        points,
        weight,
        loss,
        max_iterations,
        false,
    )
    .map(|r| r.0)
}

/// [`bundle_adjust_indexed`] with the lens block `[f, k1, k2]` of `k`
/// ([`vfxgraph_bundle::CameraModel::Radial`]: its principal point, aspect, skew and lens model
/// held) free but for `held`, on the observed (distorted) pixels of `tracks`. Returns the
/// solved intrinsics.
#[allow(clippy::too_many_arguments)]
pub(crate) fn bundle_adjust_lens(
    tracks: &Tracks,
    k: &Intrinsics,
    held: Held,
    poses: &mut [Option<Pose>],
    points: &mut [Option<Vector3<f64>>],
    weight: &ObservationWeight<'_>,
    loss: vfxgraph_bundle::Loss,
    max_iterations: usize,
    covariance: bool,
) -> Result<(Intrinsics, Option<BlockCovariance>)> {
    let gauge = vfxgraph_bundle::Gauge::FixFirstCameraAndScale;
    let block = lens_block(k, held);
    let (_, b, cov) = adjust_with_block(
        tracks,
        block,
        gauge,
        poses,
        points,
        weight,
        loss,
        max_iterations,
        covariance,
    )?;
    Ok((intrinsics_of_block(k, &b), cov))
}

/// Which parameters of a lens block `[f, k1, k2, p1, p2, cx, cy]` stay constant
/// ([`vfxgraph_bundle::CameraModel::Radial`]).
pub(crate) type Held = [bool; vfxgraph_bundle::INTRINSICS];

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

/// The solved intrinsics of a lens block for a report: the focal length and every free lens
/// parameter, with their standard deviations where known (`cov`).
pub(crate) fn solved_intrinsics(
    k: &Intrinsics,
    held: Held,
    cov: Option<&BlockCovariance>,
) -> Vec<SolvedIntrinsic> {
    let values = lens_block(k, held).params;
    let names = ["focal_px", "k1", "k2", "p1", "p2", "cx_px", "cy_px"];
    (0..names.len())
        .filter(|&i| i == 0 || !held[i])
        .map(|i| SolvedIntrinsic {
            name: names[i].into(),
            value: values[i],
            held: held[i],
            sd: match cov {
                Some(Ok((c, _))) if !held[i] => Some(c[(i, i)].max(0.0).sqrt()),
                _ => None,
            },
        })
        .collect()
}

/// The bundle adjuster's lens block `[f, k1, k2, p1, p2, cx, cy]` of `k`
/// ([`vfxgraph_bundle::CameraModel::Radial`]: its aspect, skew and k3 held), free but for `held`.
pub(crate) fn lens_block(k: &Intrinsics, held: Held) -> vfxgraph_bundle::Intrinsics {
    let mut block = vfxgraph_bundle::Intrinsics::radial(k.f1, k.u0, k.v0, k.distortion);
    if let vfxgraph_bundle::CameraModel::Radial { aspect, skew, .. } = &mut block.model {
        *aspect = k.f2 / k.f1;
        *skew = k.s;
    }
    block.held = held;
    block
}

/// `k` with the focal length, lens and principal point of an adjusted [`lens_block`].
pub(crate) fn intrinsics_of_block(k: &Intrinsics, b: &vfxgraph_bundle::Intrinsics) -> Intrinsics {
    let [f, .., cx, cy] = b.params;
    let mut out = k.clone();
    out.f1 = f;
    out.f2 = f * k.f2 / k.f1;
    out.u0 = cx;
    out.v0 = cy;
    out.distortion = b.model.lens_with(&b.params);
    out
}

/// The covariance of a lens block's `[f, k1, k2, p1, p2, cx, cy]` at the solution, with σ̂
/// ([`vfxgraph_bundle::intrinsics_covariance`]), or why it is not available.
pub(crate) type BlockCovariance =
    std::result::Result<(vfxgraph_bundle::IntrinsicsCovariance, f64), String>;

/// The bundle adjustment of [`bundle_adjust_indexed`] with one shared intrinsics block and the
/// given gauge; returns the solver's report, the adjusted block and, when `covariance`, the
/// block's covariance at the solution.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn adjust_with_block(
    tracks: &Tracks,
    block: vfxgraph_bundle::Intrinsics,
    gauge: vfxgraph_bundle::Gauge,
    poses: &mut [Option<Pose>],
    points: &mut [Option<Vector3<f64>>],
    weight: &ObservationWeight<'_>,
    loss: vfxgraph_bundle::Loss,
    max_iterations: usize,
    covariance: bool,
) -> Result<(
    vfxgraph_bundle::SolverReport,
    vfxgraph_bundle::Intrinsics,
    Option<BlockCovariance>,
)> {
    let (report, blocks, cov) = adjust_with_blocks(
        tracks,
        vec![block],
        Vec::new(),
        gauge,
        poses,
        points,
        weight,
        loss,
        max_iterations,
        covariance,
    )?;
    Ok((report, blocks[0], cov))
}

/// The bundle adjustment of [`bundle_adjust_indexed`] with intrinsics `blocks` — one shared by
/// every camera, or one per frame index (a zoom; blocks of frames without a camera are left
/// as they are) — and `priors` on them ([`vfxgraph_bundle::Prior`], indices into `blocks`).
/// Returns the solver's report, the adjusted blocks and, when `covariance`, the first block's
/// covariance at the solution.
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn adjust_with_blocks(
    tracks: &Tracks,
    mut blocks: Vec<vfxgraph_bundle::Intrinsics>,
    priors: Vec<vfxgraph_bundle::Prior>,
    gauge: vfxgraph_bundle::Gauge,
    poses: &mut [Option<Pose>],
    points: &mut [Option<Vector3<f64>>],
    weight: &ObservationWeight<'_>,
    loss: vfxgraph_bundle::Loss,
    max_iterations: usize,
    covariance: bool,
) -> Result<(
    vfxgraph_bundle::SolverReport,
    Vec<vfxgraph_bundle::Intrinsics>,
    Option<BlockCovariance>,
)> {
    let per_frame = blocks.len() > 1;
    if per_frame && blocks.len() != poses.len() {
        return Err(VisionError::InvalidInput(format!(
            "{} intrinsics blocks for {} frames",
            blocks.len(),
            poses.len()
        )));
    }
    if per_frame {
        // A block no camera uses is not determined: held.
        for (b, p) in blocks.iter_mut().zip(poses.iter()) {
            b.fixed |= p.is_none();
        }
    }
    let IndexedProblem {
        mut problem,
        cam_frame,
        pt_track,
    } = indexed_problem(tracks, blocks, priors, gauge, poses, points, weight)?;
    let problem_cameras = problem.cameras.len();
    let options = vfxgraph_bundle::SolverOptions {
        max_iterations,
        loss,
        // Long tracks couple almost every pair of cameras: the reduced camera system of a shot
        // is nearly dense, where dense Cholesky beats the sparse one (measured on the book's
        // 286 frames: 0.54 vs 0.77 s per iteration).
        linear_solver: if problem_cameras <= 600 {
            vfxgraph_bundle::LinearSolverKind::DenseSchur
        } else {
            vfxgraph_bundle::LinearSolverKind::Auto
        },
        ..Default::default()
    };
    let report = vfxgraph_bundle::solve(&mut problem, &options)
        .map_err(|e| VisionError::Degenerate(format!("bundle adjustment: {e}")))?;
    for (c, &f) in problem.cameras.iter().zip(&cam_frame) {
        poses[f] = Some(Pose::new(c.rotation_matrix(), c.translation));
    }
    for (p, &ti) in problem.points.iter().zip(&pt_track) {
        points[ti] = Some(p.position);
    }
    let cov = covariance.then(|| match vfxgraph_bundle::intrinsics_covariance(&problem) {
        Ok((c, sigma)) => c[0]
            .map(|c| (c, sigma))
            .ok_or_else(|| "the lens is held".to_string()),
        Err(e) => Err(e.to_string()),
    });
    Ok((report, problem.intrinsics, cov))
}

/// A bundle problem ([`vfxgraph_bundle::Problem`]) of the posed frames and triangulated tracks,
/// with the frame of each of its cameras and the track of each of its points.
pub(crate) struct IndexedProblem {
    pub problem: vfxgraph_bundle::Problem,
    /// Per camera, its frame index.
    pub cam_frame: Vec<usize>,
    /// Per point, its track index.
    pub pt_track: Vec<usize>,
}

/// The bundle problem of [`adjust_with_blocks`]: a camera per posed frame (its intrinsics
/// block the shared one, or its frame's when there is one per frame), a point per
/// triangulated track with at least two observations of non-zero `weight(track, frame)`.
/// Errors without two cameras and a point.
pub(crate) fn indexed_problem(
    tracks: &Tracks,
    blocks: Vec<vfxgraph_bundle::Intrinsics>,
    priors: Vec<vfxgraph_bundle::Prior>,
    gauge: vfxgraph_bundle::Gauge,
    poses: &[Option<Pose>],
    points: &[Option<Vector3<f64>>],
    weight: &ObservationWeight<'_>,
) -> Result<IndexedProblem> {
    use vfxgraph_bundle::{CameraPose, Observation, Point, Problem};
    let per_frame = blocks.len() > 1;
    let mut cam_index = vec![usize::MAX; poses.len()];
    let mut cameras = Vec::new();
    let mut cam_frame = Vec::new();
    for (f, p) in poses.iter().enumerate() {
        if let Some(p) = p {
            cam_index[f] = cameras.len();
            cam_frame.push(f);
            cameras.push(CameraPose::from_rt(
                &p.r,
                &p.t,
                if per_frame { f } else { 0 },
            ));
        }
    }
    let mut pts = Vec::new();
    let mut pt_track = Vec::new();
    let mut observations = Vec::new();
    for (ti, (t, x)) in tracks.tracks.iter().zip(points.iter()).enumerate() {
        let Some(x) = x else { continue };
        let pi = pts.len();
        let before = observations.len();
        for (j, o) in t.points.iter().enumerate() {
            let f = t.first + j;
            let w = if f < poses.len() && cam_index[f] != usize::MAX {
                weight(ti, f)
            } else {
                0.0
            };
            if w > 0.0 {
                observations.push(Observation {
                    camera: cam_index[f],
                    point: pi,
                    pixel: nalgebra::Vector2::new(o[0], o[1]),
                    weight: w,
                });
            }
        }
        if observations.len() - before < 2 {
            observations.truncate(before);
            continue;
        }
        pts.push(Point {
            position: *x,
            fixed: false,
        });
        pt_track.push(ti);
    }
    if cameras.len() < 2 || pts.is_empty() {
        return Err(VisionError::Degenerate(format!(
            "bundle adjustment needs 2 cameras and some points ({} cameras, {} points)",
            cameras.len(),
            pts.len()
        )));
    }
    Ok(IndexedProblem {
        problem: Problem {
            cameras,
            intrinsics: blocks,
            points: pts,
            observations,
            gauge,
            priors,
        },
        cam_frame,
        pt_track,
    })
}

/// The fixed pinhole block of K (its aspect and skew kept).
pub(crate) fn pinhole_block(k: &Intrinsics) -> vfxgraph_bundle::Intrinsics {
    let mut block = vfxgraph_bundle::Intrinsics::pinhole(k.f1, k.u0, k.v0, true);
    block.model = vfxgraph_bundle::CameraModel::Pinhole {
        aspect: k.f2 / k.f1,
        skew: k.s,
    };
    block
}
