//! The best frame pair of a fragment (book §7.2–7.6).
//!
//! For every candidate pair (i, j) of the fragment whose features moved more than
//! `min_displacement` pixels: RANSAC on the fundamental matrix, E = KᵀFK, the factorization that
//! puts the points in front of both cameras, triangulation of the features
//! ([`vfxgraph_geometry::two_view::reconstruct_two_view`]). Every frame of the fragment is then resected from
//! those points by RANSAC on the 6-point DLT with a `resection_tolerance` pixel threshold; a
//! feature stays an inlier only if it is one in every frame, and the pair is rejected if any
//! frame's DLT camera, factored as K'[R|t], has a K' farther than `max_k_difference` (largest
//! entry difference) from the known K — unless the known K itself explains the frame
//! ([`known_k_inliers`], for nearly planar sets where K' is poorly determined). The pair with
//! the most inliers wins. Pairs whose inliers can no longer beat the best finished one are
//! not resected further ([`best_pair`]): the same winner, found sooner.
//!
//! The book tries every pair; `stride` restricts the candidates to every `stride`-th frame (plus
//! the last) — with the default 6, about 60 pairs of a 60-frame fragment instead of 1800, at no
//! loss we could measure. Pairs are evaluated in parallel, each with its own seeded stream; ties
//! go to the earlier pair, so the choice does not depend on the thread count.

use nalgebra::{Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use vfxgraph_geometry::calibration::{factor_camera, refine_known_k, resect_ransac, P3pEstimator};
use vfxgraph_geometry::camera::Intrinsics;
use vfxgraph_geometry::error::{Result, VisionError};
use vfxgraph_geometry::ransac::{ransac, RansacParams};
use vfxgraph_geometry::two_view::{
    reconstruct_two_view, relative_pose_calibrated, CalibratedOptions, EpipolarResidual,
    StartModel, TwoViewOptions,
};
use vfxgraph_klt::Tracks;
use vfxgraph_params::Options;

use crate::fragments::{mean_displacement, Fragment};
use crate::structure::{derive_seed, through};

/// How a fragment's reconstruction starts.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, vfxgraph_params::Choice,
)]
#[serde(rename_all = "lowercase")]
pub enum InitMethod {
    /// With K known: the five-point E or the homography's motions for the pair
    /// ([`relative_pose_calibrated`]), P3P for every frame ([`P3pEstimator`]); sound on planar
    /// sets.
    #[default]
    Calibrated,
    /// The book's: the 8-point F, E = KᵀFK (§7.2), the 6-point DLT for every frame and the
    /// intrinsics-consistency test (§7.3–7.6). Degenerate on planar sets.
    Book,
}

/// The best-pair search's constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Options)]
#[serde(default)]
pub struct PairOptions {
    /// how a fragment's reconstruction starts: calibrated (5-point E or H, P3P) or the book's
    /// (8-point F, 6-point DLT)
    pub init: InitMethod,
    /// candidate pairs moved more than this on average, px (§7.2)
    ///
    /// Book: 4.
    #[param(name = "pair_min_displacement", range = 0.0..=1e5)]
    pub min_displacement: f64,
    /// candidate frames of the pair search: every n-th (the book: 1, every pair)
    ///
    /// Every `stride`-th frame of the fragment and its last.
    #[param(name = "pair_stride", range = 1..=10_000)]
    pub stride: usize,
    /// Sampson-distance threshold of the RANSAC on F, px
    #[param(range = 1e-3..=1e3)]
    pub epipolar_threshold: f64,
    /// most RANSAC iterations on F (adaptive below this)
    ///
    /// The book: 60 fixed.
    #[param(range = 1..=1_000_000)]
    pub ransac_iterations: usize,
    /// resection (6-point DLT) RANSAC threshold, px (§7.3)
    ///
    /// Book: 15.
    #[param(range = 1e-3..=1e4)]
    pub resection_tolerance: f64,
    /// resection RANSAC threshold of the calibrated start (P3P), px
    #[param(range = 1e-3..=1e4)]
    pub pnp_tolerance: f64,
    /// intrinsics-consistency test: largest entry difference of a frame's DLT K' from K
    ///
    /// Book: 100.
    #[param(range = 0.0..=1e6)]
    pub max_k_difference: f64,
    /// a frame failing that test passes if the known K keeps this fraction of its inliers
    ///
    /// The consensus pose refined with K fixed (not in the book: [`known_k_inliers`]), for
    /// nearly planar sets where the DLT's K′ is unreliable; above 1 the book's test alone
    /// decides.
    #[param(range = 0.0..=2.0)]
    pub known_k_inlier_ratio: f64,
    /// A pair with fewer inliers than this is not a candidate.
    #[param(skip)]
    pub min_inliers: usize,
    /// A pair whose points' median parallax angle is below this (degrees) has no usable
    /// baseline: counted with the pure rotations (not in the book, whose footage always moved).
    #[param(skip)]
    pub min_parallax_deg: f64,
}

impl Default for PairOptions {
    fn default() -> Self {
        PairOptions {
            init: InitMethod::Calibrated,
            pnp_tolerance: 4.0,
            min_displacement: 4.0,
            stride: 6,
            epipolar_threshold: 1.5,
            ransac_iterations: 500,
            resection_tolerance: 15.0,
            max_k_difference: 100.0,
            known_k_inlier_ratio: 0.9,
            min_inliers: 12,
            min_parallax_deg: 0.5,
        }
    }
}

/// Why candidate pairs were not kept, by reason (a fragment's report).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PairRejections {
    /// No two-view reconstruction (too few consistent matches).
    pub two_view: usize,
    /// No parallax: a rotation about the camera centre explains the pair.
    pub zero_baseline: usize,
    /// The book's start: a frame's DLT camera failed the intrinsics-consistency test.
    pub intrinsics: usize,
    /// Too few features stayed inliers through every frame of the fragment.
    pub too_few: usize,
    /// Could no longer beat the best pair (not resected further).
    pub beaten: usize,
}

/// The winning pair and its seed reconstruction.
#[derive(Clone, Debug)]
pub struct BestPair {
    /// Frame indices (into `Tracks::frames`) of the pair.
    pub pair: (usize, usize),
    /// The model the pair's motion came from.
    pub model: StartModel,
    /// Inlier features (indices into `Fragment::features`) and their 3D points, in the frame
    /// of camera i (which is [I|0]); camera j has a unit baseline.
    pub points: Vec<(usize, Vector3<f64>)>,
    /// Candidate pairs (all of them were reconstructed from two views).
    pub candidates: usize,
    /// Pairs rejected by the intrinsics-consistency test, of those whose frames were resected
    /// (a pair that could no longer beat the best is not resected further).
    pub rejected_k: usize,
    /// Candidate motions not kept, by reason (a planar pair may give two motions).
    pub rejections: PairRejections,
    /// Another motion of the same pair (a planar pair's second) whose points stay inliers in
    /// every frame nearly as often ([`AMBIGUITY_RATIO`]): its inlier features and points.
    pub alternative: Option<Vec<(usize, Vector3<f64>)>>,
}

/// A second motion keeping this fraction of the winner's features is refined too.
pub const AMBIGUITY_RATIO: f64 = 0.9;

/// Why a pair was not kept.
enum PairFailure {
    TwoView(VisionError),
    IntrinsicsTest,
    TooFew,
    /// Its inliers fell to where it can no longer win (see [`best_pair`]).
    Beaten,
}

/// A pair's two-view reconstruction: its features (indices into the fragment's) and their
/// points, and its random stream, which the frames' resections go on drawing from.
#[derive(Clone)]
struct TwoViewSeed {
    feats: Vec<usize>,
    p3: Vec<Point3<f64>>,
    model: StartModel,
    rng: Pcg64,
}

/// The best result so far of the resection stage: (inliers, candidate index). A pair with
/// `inliers` below it, or equal with a later index, can no longer win.
type Bound = Option<(usize, usize)>;

fn beaten(count: usize, n: usize, bound: Bound) -> bool {
    bound.is_some_and(|(best, at)| count < best || (count == best && n > at))
}

/// Stage one of a pair: its two-view reconstructions (one, or two motions of a planar pair
/// for the frames to tell apart), or why it failed.
fn two_view_stage(
    k: &Intrinsics,
    frag: &Fragment,
    obs: &[&[[f64; 2]]],
    i: usize,
    j: usize,
    options: &PairOptions,
    seed: u64,
) -> std::result::Result<Vec<TwoViewSeed>, PairFailure> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (li, lj) = (i - frag.first, j - frag.first);
    let a: Vec<Point2<f64>> = obs
        .iter()
        .map(|o| Point2::new(o[li][0], o[li][1]))
        .collect();
    let b: Vec<Point2<f64>> = obs
        .iter()
        .map(|o| Point2::new(o[lj][0], o[lj][1]))
        .collect();
    let ransac = RansacParams {
        threshold: options.epipolar_threshold,
        max_iterations: options.ransac_iterations.max(1),
        min_iterations: 20.min(options.ransac_iterations.max(1)),
        ..RansacParams::default()
    };
    if options.init == InitMethod::Calibrated {
        let calibrated = CalibratedOptions {
            ransac,
            min_inliers: options.min_inliers.max(6),
            ..CalibratedOptions::default()
        };
        let rec =
            relative_pose_calibrated(&a, &b, k, &calibrated, options.min_parallax_deg, &mut rng)
                .map_err(PairFailure::TwoView)?;
        let seeds: Vec<TwoViewSeed> = rec
            .candidates
            .into_iter()
            .enumerate()
            .map(|(c, cand)| TwoViewSeed {
                feats: cand.inliers,
                p3: cand.points.into_iter().map(Point3::from).collect(),
                model: cand.model,
                rng: Pcg64::seed_from_u64(derive_seed(seed, 11, c as u64)),
            })
            .collect();
        return Ok(seeds);
    }
    let two_view = TwoViewOptions {
        ransac,
        residual: EpipolarResidual::Sampson,
        refine_pose: true,
        refine_points: true,
        homography_ratio: 0.95,
        min_inliers: options.min_inliers.max(8),
    };
    let rec =
        reconstruct_two_view(&a, &b, k, k, &two_view, &mut rng).map_err(PairFailure::TwoView)?;
    if !(rec.report.median_parallax_deg >= options.min_parallax_deg) {
        return Err(PairFailure::TwoView(VisionError::ZeroBaseline));
    }
    let feats: Vec<usize> = rec.point_indices.clone();
    let p3: Vec<Point3<f64>> = rec.points3d.0.clone();
    if feats.len() < options.min_inliers.max(6) {
        return Err(PairFailure::TooFew);
    }
    Ok(vec![TwoViewSeed {
        feats,
        p3,
        model: StartModel::Fundamental,
        rng,
    }])
}

/// Stage two of pair `n`: every frame of the fragment resected from its points; its inlier
/// features and their points, or why it failed. Stops as [`PairFailure::Beaten`] once its
/// inliers (which only fall, frame by frame) can no longer beat `bound`.
#[allow(clippy::too_many_arguments)]
fn resection_stage(
    k: &Intrinsics,
    frag: &Fragment,
    obs: &[&[[f64; 2]]],
    seed: TwoViewSeed,
    options: &PairOptions,
    n: usize,
    bound: Bound,
) -> std::result::Result<Vec<(usize, Vector3<f64>)>, PairFailure> {
    let TwoViewSeed {
        feats, p3, mut rng, ..
    } = seed;
    let mut inlier = vec![true; feats.len()];
    let pnp = P3pEstimator::new(k);
    let pnp_params = RansacParams {
        threshold: options.pnp_tolerance,
        max_iterations: 200,
        min_iterations: 10,
        refit_rounds: 1,
        local_optimization: false,
        ..RansacParams::default()
    };
    let res_params = RansacParams {
        threshold: options.resection_tolerance,
        max_iterations: 200,
        min_iterations: 10,
        refit_rounds: 1,
        local_optimization: false,
        ..RansacParams::default()
    };
    let kk = k.k();
    for f in frag.first..=frag.last {
        let lf = f - frag.first;
        let p2: Vec<Point2<f64>> = feats
            .iter()
            .map(|&q| Point2::new(obs[q][lf][0], obs[q][lf][1]))
            .collect();
        let frame_inliers = if options.init == InitMethod::Calibrated {
            let data: Vec<_> = p3.iter().copied().zip(p2.iter().copied()).collect();
            ransac(&pnp, &data, &pnp_params, &mut rng)
                .map_err(|_| PairFailure::TooFew)?
                .inliers
        } else {
            let res =
                resect_ransac(&p3, &p2, &res_params, &mut rng).map_err(|_| PairFailure::TooFew)?;
            let cam = factor_camera(&res.p).map_err(|_| PairFailure::IntrinsicsTest)?;
            let diff = (cam.intrinsics.k() - kk).abs().max();
            if diff <= options.max_k_difference {
                res.inliers
            } else {
                known_k_inliers(&p3, &p2, k, &res, options)?
            }
        };
        for (flag, r) in inlier.iter_mut().zip(&frame_inliers) {
            *flag &= *r;
        }
        let count = inlier.iter().filter(|&&x| x).count();
        if count < options.min_inliers {
            return Err(PairFailure::TooFew);
        }
        if beaten(count, n, bound) {
            return Err(PairFailure::Beaten);
        }
    }
    Ok(feats
        .iter()
        .zip(&p3)
        .zip(&inlier)
        .filter(|(_, &ok)| ok)
        .map(|((&q, p), _)| (q, p.coords))
        .collect())
}

/// The second chance of a frame whose DLT failed the intrinsics test: the DLT's K′ is poorly
/// determined when the points are nearly coplanar (a set dominated by its floor: K′'s principal
/// point moved by hundreds of pixels on the Blender dev plate's true reconstructions), so the
/// frame is judged instead by whether the *known* K explains the structure — the consensus
/// pose refined with K fixed ([`refine_known_k`]) must keep at least `known_k_inlier_ratio` of
/// the DLT's inliers within the resection tolerance. A wrong reconstruction (a mirrored or
/// twisted pair) cannot be explained by the true K and fails; a frame that passed the book's test
/// never gets here, so footage the book's test accepts is solved exactly as before.
fn known_k_inliers(
    p3: &[Point3<f64>],
    p2: &[Point2<f64>],
    k: &Intrinsics,
    res: &vfxgraph_geometry::calibration::Resection,
    options: &PairOptions,
) -> std::result::Result<Vec<bool>, PairFailure> {
    let est = refine_known_k(p3, p2, k, res, options.resection_tolerance)
        .map_err(|_| PairFailure::IntrinsicsTest)?;
    let kept = est
        .inliers
        .iter()
        .zip(&res.inliers)
        .filter(|(a, b)| **a && **b)
        .count();
    if (kept as f64) < options.known_k_inlier_ratio * res.num_inliers as f64 {
        return Err(PairFailure::IntrinsicsTest);
    }
    Ok(est.inliers)
}

/// Finds the fragment's best pair (module docs).
pub fn best_pair(
    tracks: &Tracks,
    k: &Intrinsics,
    frag: &Fragment,
    options: &PairOptions,
    seed: u64,
) -> Result<BestPair> {
    let obs: Vec<&[[f64; 2]]> = frag
        .features
        .iter()
        .map(|&t| through(&tracks.tracks[t], frag.first, frag.last).expect("fragment feature"))
        .collect();
    let stride = options.stride.max(1);
    let mut grid: Vec<usize> = (frag.first..=frag.last).step_by(stride).collect();
    if *grid.last().unwrap() != frag.last {
        grid.push(frag.last);
    }
    let mut pairs = Vec::new();
    for (x, &i) in grid.iter().enumerate() {
        for &j in &grid[x + 1..] {
            if mean_displacement(tracks, &frag.features, i, j) > options.min_displacement {
                pairs.push((i, j));
            }
        }
    }
    let describe = || {
        format!(
            "fragment of frames {}..{} ({} features)",
            tracks.frames[frag.first],
            tracks.frames[frag.last],
            frag.features.len()
        )
    };
    if pairs.is_empty() {
        return Err(VisionError::NoParallax(format!(
            "{}: no frame pair whose features moved more than {} px",
            describe(),
            options.min_displacement
        )));
    }
    // Stage one, every pair: the two-view reconstructions. A pair may give more than one
    // candidate motion (a planar pair's two): candidate `c` of pair `p` is numbered
    // p·MAX_CANDIDATES + c, the order ties are broken in.
    const MAX_CANDIDATES: usize = 4;
    let mut rejections = PairRejections::default();
    let stage_one: Vec<(usize, std::result::Result<Vec<TwoViewSeed>, PairFailure>)> = pairs
        .par_iter()
        .enumerate()
        .map(|(n, &(i, j))| {
            let s = two_view_stage(k, frag, &obs, i, j, options, derive_seed(seed, 7, n as u64));
            (n, s)
        })
        .collect();
    let mut staged: Vec<(usize, TwoViewSeed)> = Vec::new();
    // Kept to test the winner against its pair's other motions: the seeds of the pairs that
    // gave more than one.
    let mut siblings: Vec<(usize, TwoViewSeed)> = Vec::new();
    for (n, r) in stage_one {
        match r {
            Ok(seeds) if seeds.len() > 1 => {
                let numbered = seeds
                    .into_iter()
                    .take(MAX_CANDIDATES)
                    .enumerate()
                    .map(|(c, s)| (n * MAX_CANDIDATES + c, s));
                siblings.extend(numbered.clone());
                staged.extend(numbered);
            }
            Ok(seeds) => staged.extend(
                seeds
                    .into_iter()
                    .take(MAX_CANDIDATES)
                    .enumerate()
                    .map(|(c, s)| (n * MAX_CANDIDATES + c, s)),
            ),
            Err(PairFailure::TwoView(VisionError::ZeroBaseline)) => rejections.zero_baseline += 1,
            Err(PairFailure::TooFew) => rejections.too_few += 1,
            Err(_) => rejections.two_view += 1,
        }
    }
    // Stage two, the frames' resections, most two-view inliers first, a batch of candidates
    // at a time: a candidate's inliers only fall as its frames are resected, so one that
    // starts (or falls) below the best finished one's — or level with it and later in the
    // order, as ties go to the earlier — cannot win and is dropped. The batches are fixed
    // (not the thread count), so the winner — the candidate with the most inliers after every
    // frame, the earliest on ties — is the one evaluating every candidate would find, on any
    // machine.
    const BATCH: usize = 4;
    staged.sort_by_key(|(n, s)| (std::cmp::Reverse(s.feats.len()), *n));
    siblings.sort_by_key(|(n, s)| (std::cmp::Reverse(s.feats.len()), *n));
    type Seed = Vec<(usize, Vector3<f64>)>;
    let mut best: Option<(usize, Seed, StartModel)> = None;
    let mut rest = staged.into_iter().peekable();
    while rest.peek().is_some() {
        let bound: Bound = best.as_ref().map(|(n, p, _)| (p.len(), *n));
        let batch: Vec<_> = rest.by_ref().take(BATCH).collect();
        let results: Vec<(usize, StartModel, std::result::Result<Seed, PairFailure>)> = batch
            .into_par_iter()
            .map(|(n, s)| {
                let model = s.model;
                if beaten(s.feats.len(), n, bound) {
                    return (n, model, Err(PairFailure::Beaten));
                }
                (
                    n,
                    model,
                    resection_stage(k, frag, &obs, s, options, n, bound),
                )
            })
            .collect();
        for (n, model, r) in results {
            match r {
                Ok(points) => {
                    if best
                        .as_ref()
                        .is_none_or(|b| !beaten(points.len(), n, Some((b.1.len(), b.0))))
                    {
                        if best.is_some() {
                            rejections.beaten += 1;
                        }
                        best = Some((n, points, model));
                    } else {
                        rejections.beaten += 1;
                    }
                }
                Err(PairFailure::IntrinsicsTest) => rejections.intrinsics += 1,
                Err(PairFailure::Beaten) => rejections.beaten += 1,
                Err(PairFailure::TooFew) => rejections.too_few += 1,
                Err(PairFailure::TwoView(_)) => rejections.two_view += 1,
            }
        }
    }
    let rejected_k = rejections.intrinsics;
    let zero_baseline = rejections.zero_baseline;
    // The winning pair's other motions, resected through every frame without the bound: one
    // that keeps nearly as many features may explain the fragment as well (a plane seen along
    // a straight path keeps the homography's twofold ambiguity in every frame); the fragment's
    // refinement decides ([`crate::fragment`]).
    let alternative = best.as_ref().and_then(|(bn, points, _)| {
        siblings
            .iter()
            .filter(|(n, _)| n / MAX_CANDIDATES == bn / MAX_CANDIDATES && n != bn)
            .filter_map(|(n, s)| resection_stage(k, frag, &obs, s.clone(), options, *n, None).ok())
            .filter(|kept| kept.len() as f64 >= AMBIGUITY_RATIO * points.len() as f64)
            .max_by_key(|kept| kept.len())
    });
    match best {
        Some((n, points, model)) => Ok(BestPair {
            pair: pairs[n / MAX_CANDIDATES],
            model,
            points,
            candidates: pairs.len(),
            rejected_k,
            rejections,
            alternative,
        }),
        None if zero_baseline * 2 >= pairs.len() => Err(VisionError::NoParallax(format!(
            "{}: {} of {} frame pairs are explained by a rotation about the camera \
             centre (a tripod pan cannot be matchmoved in 3D)",
            describe(),
            zero_baseline,
            pairs.len()
        ))),
        None => Err(VisionError::Degenerate(format!(
            "{}: none of {} frame pairs gave a consistent reconstruction (no two-view \
             reconstruction: {}, no parallax: {}, too few features consistent through every \
             frame: {}, intrinsics test: {})",
            describe(),
            pairs.len(),
            rejections.two_view,
            rejections.zero_baseline,
            rejections.too_few,
            rejected_k
        ))),
    }
}
