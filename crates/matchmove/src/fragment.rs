//! Calibration of one fragment (book §7.9, after the best pair of §7.2–7.6).
//!
//! The best pair's inlier points seed the fragment. Each frame's camera is resected from them
//! (RANSAC on the DLT, factored, K replaced by the known K, then refined with K fixed). Then the
//! refinement cycles: a bundle adjustment of all cameras and points of the fragment (K fixed);
//! then, for each tolerance (10, 5, 3 px), every feature of the fragment is re-triangulated so
//! that its reprojection error is below the tolerance in ALL frames — from all frames, or failing
//! that from one of a few frame pairs — and dropped if none does, followed by another bundle
//! adjustment.

use nalgebra::{Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::calibration::{resect_known_k, resect_p3p};
use vfxgraph_geometry::camera::{Intrinsics, Pose};
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::ransac::RansacParams;
use vfxgraph_geometry::two_view::StartModel;
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::adjust::bundle_adjust_indexed;
use crate::fragments::Fragment;
use crate::pair::{best_pair, InitMethod, PairOptions, PairRejections, AMBIGUITY_RATIO};
use crate::structure::{reprojection_error, through, triangulate_views};

/// The refinement cycles' constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
#[param(check)]
pub struct RefineOptions {
    /// re-triangulation tolerances of the refinement cycles, px (§7.9)
    ///
    /// One cycle each (book: 10, 5, 3).
    #[param(name = "refine_tolerances")]
    pub tolerances: Vec<f64>,
    /// Most Levenberg–Marquardt iterations per bundle adjustment.
    #[param(skip)]
    pub ba_iterations: usize,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            tolerances: vec![10.0, 5.0, 3.0],
            ba_iterations: 30,
        }
    }
}

impl RefineOptions {
    /// Every tolerance is positive.
    pub fn check(&self) -> std::result::Result<(), String> {
        vfxgraph_params::all_positive("refine_tolerances", &self.tolerances)
    }

    /// The last (tightest) tolerance: what counts as an inlier in the reports.
    pub fn final_tolerance(&self) -> f64 {
        self.tolerances.last().copied().unwrap_or(3.0)
    }
}

/// A second motion of the fragment's best pair that, refined, fits the fragment about as well
/// as the one kept (within [`AMBIGUOUS_RMS_RATIO`] of its RMS, with as many features): the
/// tracks do not decide between them, and the cameras are uncertain to the difference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ambiguity {
    /// Features the other solution keeps.
    pub inliers: usize,
    /// Its RMS reprojection error, pixels.
    pub rms: f64,
    /// The largest difference between the two solutions' rotations (relative to the
    /// fragment's first frame), degrees.
    pub rotation_deg: f64,
}

/// Two refined solutions whose RMS errors are within this ratio fit equally well.
pub const AMBIGUOUS_RMS_RATIO: f64 = 1.1;

/// Figures of one fragment's solve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FragmentReport {
    /// First and last frame numbers.
    pub frames: (i64, i64),
    /// Features tracked through the fragment.
    pub features: usize,
    /// Features kept as 3D points at the end.
    pub inliers: usize,
    /// The best pair's frame numbers.
    pub pair: (i64, i64),
    /// The model the best pair's motion came from (E, H, or the book's F).
    pub start: StartModel,
    /// Candidate motions not kept, by reason.
    pub rejections: PairRejections,
    /// Another motion that explains the fragment nearly as well (the solve is then uncertain).
    pub ambiguity: Option<Ambiguity>,
    /// Its inliers.
    pub pair_inliers: usize,
    /// Candidate pairs evaluated, and how many failed the intrinsics test.
    pub candidates: usize,
    /// Pairs rejected by the intrinsics-consistency test.
    pub rejected_by_k: usize,
    /// RMS reprojection error after the last bundle adjustment, pixels.
    pub rms: f64,
    /// Scale relative to the first fragment (filled by the junction).
    pub scale: f64,
}

/// A solved fragment, in its own frame and scale.
#[derive(Clone, Debug)]
pub struct FragmentSolution {
    /// The fragment.
    pub fragment: Fragment,
    /// Poses indexed by frame index over the whole sequence (`None` outside the fragment).
    pub poses: Vec<Option<Pose>>,
    /// Points indexed by track index (`None` for tracks not kept).
    pub points: Vec<Option<Vector3<f64>>>,
    /// Figures.
    pub report: FragmentReport,
}

/// Re-triangulates every feature of the fragment under `tolerance` (module docs).
fn retriangulate(
    tracks: &Tracks,
    k: &Intrinsics,
    frag: &Fragment,
    poses: &[Option<Pose>],
    tolerance: f64,
) -> Vec<Option<Vector3<f64>>> {
    let mut points = vec![None; tracks.tracks.len()];
    let mid = (frag.first + frag.last) / 2;
    let pairs = [(frag.first, frag.last), (frag.first, mid), (mid, frag.last)];
    for &ti in &frag.features {
        let obs = through(&tracks.tracks[ti], frag.first, frag.last).expect("fragment feature");
        let pose = |f: usize| poses[f].as_ref().expect("fragment pose");
        let ok = |x: &Vector3<f64>| {
            (frag.first..=frag.last)
                .all(|f| reprojection_error(k, pose(f), x, &obs[f - frag.first]) <= tolerance)
        };
        let all: Vec<(&Pose, [f64; 2])> = (frag.first..=frag.last)
            .map(|f| (pose(f), obs[f - frag.first]))
            .collect();
        let mut found = triangulate_views(k, &all).filter(|x| ok(x));
        if found.is_none() {
            for &(a, b) in &pairs {
                if a == b {
                    continue;
                }
                let two = [
                    (pose(a), obs[a - frag.first]),
                    (pose(b), obs[b - frag.first]),
                ];
                if let Some(x) = triangulate_views(k, &two).filter(|x| ok(x)) {
                    found = Some(x);
                    break;
                }
            }
        }
        points[ti] = found;
    }
    points
}

/// Cameras and points of a fragment from a seed reconstruction (inlier features, as indices
/// into the fragment's, and their points): every frame resected, then the refinement cycles.
fn refine_seed(
    tracks: &Tracks,
    k: &Intrinsics,
    frag: &Fragment,
    pair: &PairOptions,
    refine: &RefineOptions,
    seed_points: &[(usize, Vector3<f64>)],
    rng: &mut Pcg64,
) -> Result<Refined> {
    let describe = || {
        format!(
            "fragment of frames {}..{}",
            tracks.frames[frag.first], tracks.frames[frag.last]
        )
    };
    let n = tracks.frames.len();
    let mut poses: Vec<Option<Pose>> = vec![None; n];
    let p3: Vec<Point3<f64>> = seed_points.iter().map(|(_, x)| Point3::from(*x)).collect();
    let calibrated = pair.init == InitMethod::Calibrated;
    let resection = RansacParams {
        threshold: if calibrated {
            pair.pnp_tolerance
        } else {
            pair.resection_tolerance
        },
        max_iterations: 500,
        ..RansacParams::default()
    };
    for (f, slot) in poses
        .iter_mut()
        .enumerate()
        .take(frag.last + 1)
        .skip(frag.first)
    {
        let p2: Vec<Point2<f64>> = seed_points
            .iter()
            .map(|(q, _)| {
                let o = tracks.tracks[frag.features[*q]].points
                    [f - tracks.tracks[frag.features[*q]].first];
                Point2::new(o[0], o[1])
            })
            .collect();
        let est = if calibrated {
            resect_p3p(&p3, &p2, k, &resection, rng)
        } else {
            resect_known_k(&p3, &p2, k, &resection, rng)
        };
        let est = est.map_err(|e| {
            VisionError::Degenerate(format!(
                "{}: resection of frame {} failed: {e}",
                describe(),
                tracks.frames[f]
            ))
        })?;
        *slot = Some(est.camera.pose);
    }
    let mut points: Vec<Option<Vector3<f64>>> = vec![None; tracks.tracks.len()];
    for (q, x) in seed_points {
        points[frag.features[*q]] = Some(*x);
    }
    let in_fragment = |_: usize, f: usize| {
        if f >= frag.first && f <= frag.last {
            1.0
        } else {
            0.0
        }
    };
    let mut report = bundle_adjust_indexed(
        tracks,
        k,
        &mut poses,
        &mut points,
        &in_fragment,
        vfxgraph_bundle::Loss::Trivial,
        refine.ba_iterations,
    )?;
    for &tol in &refine.tolerances {
        points = retriangulate(tracks, k, frag, &poses, tol);
        let kept = points.iter().filter(|p| p.is_some()).count();
        if kept < 6 {
            return Err(VisionError::Degenerate(format!(
                "{}: only {kept} features reproject within {tol} px in every frame",
                describe()
            )));
        }
        report = bundle_adjust_indexed(
            tracks,
            k,
            &mut poses,
            &mut points,
            &in_fragment,
            vfxgraph_bundle::Loss::Trivial,
            refine.ba_iterations,
        )?;
    }
    Ok(Refined {
        inliers: points.iter().filter(|p| p.is_some()).count(),
        poses,
        points,
        rms: report.final_rms,
    })
}

/// A fragment's refined cameras and points.
struct Refined {
    poses: Vec<Option<Pose>>,
    points: Vec<Option<Vector3<f64>>>,
    inliers: usize,
    rms: f64,
}

/// Largest angle, over the fragment's frames, between two solutions' rotations relative to
/// the fragment's first frame, degrees.
fn rotation_difference(a: &Refined, b: &Refined, frag: &Fragment) -> f64 {
    let (Some(a0), Some(b0)) = (&a.poses[frag.first], &b.poses[frag.first]) else {
        return f64::NAN;
    };
    (frag.first..=frag.last)
        .filter_map(|f| {
            let (pa, pb) = (a.poses[f].as_ref()?, b.poses[f].as_ref()?);
            Some(vfxgraph_geometry::rotation::rotation_angle_between(
                &(pa.r * a0.r.transpose()),
                &(pb.r * b0.r.transpose()),
            ))
        })
        .fold(0.0, f64::max)
        .to_degrees()
}

/// Solves one fragment (module docs): best pair, resection, refinement cycles.
pub fn solve_fragment(
    tracks: &Tracks,
    k: &Intrinsics,
    frag: &Fragment,
    pair: &PairOptions,
    refine: &RefineOptions,
    seed: u64,
) -> Result<FragmentSolution> {
    let best = best_pair(tracks, k, frag, pair, seed)?;
    let mut rng = Pcg64::seed_from_u64(crate::structure::derive_seed(seed, 3, 0));
    let mut main = refine_seed(tracks, k, frag, pair, refine, &best.points, &mut rng)?;
    // A second motion of the pair that kept nearly as many features is refined too: the
    // better fit wins, and one that fits about as well makes the fragment ambiguous.
    let mut ambiguity = None;
    if let Some(alt_points) = &best.alternative {
        let mut rng = Pcg64::seed_from_u64(crate::structure::derive_seed(seed, 3, 1));
        if let Ok(alt) = refine_seed(tracks, k, frag, pair, refine, alt_points, &mut rng) {
            let degrees = rotation_difference(&main, &alt, frag);
            let alt_better =
                alt.inliers > main.inliers || (alt.inliers == main.inliers && alt.rms < main.rms);
            let close = alt.inliers as f64 >= AMBIGUITY_RATIO * main.inliers as f64
                && main.inliers as f64 >= AMBIGUITY_RATIO * alt.inliers as f64
                && alt.rms <= AMBIGUOUS_RMS_RATIO * main.rms
                && main.rms <= AMBIGUOUS_RMS_RATIO * alt.rms;
            let (winner, other) = if alt_better { (alt, main) } else { (main, alt) };
            if close && degrees > 0.05 {
                ambiguity = Some(Ambiguity {
                    inliers: other.inliers,
                    rms: other.rms,
                    rotation_deg: degrees,
                });
            }
            main = winner;
        }
    }
    let Refined {
        poses,
        points,
        rms,
        inliers,
    } = main;
    Ok(FragmentSolution {
        fragment: frag.clone(),
        poses,
        points,
        report: FragmentReport {
            frames: (tracks.frames[frag.first], tracks.frames[frag.last]),
            features: frag.features.len(),
            inliers,
            pair: (tracks.frames[best.pair.0], tracks.frames[best.pair.1]),
            start: best.model,
            rejections: best.rejections.clone(),
            ambiguity,
            pair_inliers: best.points.len(),
            candidates: best.candidates,
            rejected_by_k: best.rejected_k,
            rms,
            scale: 1.0,
        },
    })
}
