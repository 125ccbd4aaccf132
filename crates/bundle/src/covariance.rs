//! How well a solve determines its intrinsics: the marginal covariance of every free intrinsics
//! block at a solution.
//!
//! The covariance of a least-squares estimate is σ̂²·(JᵀJ)⁻¹ (Hartley & Zisserman, 2nd ed.,
//! §5.2.5 and A6.7), σ̂² = Σ‖r‖² / (m − n) the residual variance. Its intrinsics block is found
//! as the bundle adjustment solves: the points eliminated point by point (the Schur complement
//! of [`super::schur`], here dense over the cameras: S = Σ U − W V⁻¹ Wᵀ), then S inverted. The
//! gauge ([`super::Gauge`]) must be fixed for S to be invertible (Triggs et al. 2000, §9: the
//! covariance is defined in a gauge). A point whose own block is singular — a direction of a
//! rotation-only solve, free along its ray — is eliminated with the pseudo-inverse of V.
//! Observations count with unit weight (the robust loss is ignored: the solve's inliers are the
//! problem's observations), which is the usual approximation at a converged robust solve.

use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};
use rayon::prelude::*;

use super::camera_model::INTRINSICS;
use super::error::BundleError;
use super::problem::Problem;
use super::residual::{project_with_jacobians, CAMERA_COLUMNS as CC};
use super::rotation::rotation_and_left_jacobian;

/// The covariance of an intrinsics block's parameters (in the order of
/// [`super::Intrinsics::params`]; rows and columns of held or unused parameters are zero).
pub type IntrinsicsCovariance = SMatrix<f64, INTRINSICS, INTRINSICS>;

/// Per intrinsics block its covariance (`None` when fixed), and σ̂.
pub type Covariances = (Vec<Option<IntrinsicsCovariance>>, f64);

/// Largest reduced (camera-side) dimension [`intrinsics_covariance`] inverts densely.
pub const MAX_DIMENSION: usize = 2400;

/// The covariance of every intrinsics block's parameters at the problem's current values
/// (`None` for a fixed block; rows and columns of held parameters are zero), and σ̂, the RMS
/// residual per coordinate with the degrees of freedom removed. Errors when the reduced system
/// is larger than [`MAX_DIMENSION`] or singular (a gauge left free).
pub fn intrinsics_covariance(problem: &Problem) -> Result<Covariances, BundleError> {
    let reduced = ReducedCovariance::new(problem)?;
    let sigma2 = reduced.sigma * reduced.sigma;
    let covs = reduced
        .intrinsics
        .iter()
        .zip(&problem.intrinsics)
        .map(|(idx, b)| {
            (!b.fixed).then(|| {
                let x = reduced.columns(idx);
                let mut c = IntrinsicsCovariance::zeros();
                for a in 0..INTRINSICS {
                    for d in 0..INTRINSICS {
                        if idx[a] != usize::MAX {
                            c[(a, d)] = sigma2 * x[(idx[a], d)];
                        }
                    }
                }
                c
            })
        })
        .collect();
    Ok((covs, reduced.sigma))
}

/// The covariance of every camera's rotation error at the problem's current values, in the
/// world frame — w_c with `R_trueᵀ·R_c = exp([w_c]ₓ)` to first order — as 3C × 3C matrices
/// (radians²; held rotations have zero rows and columns): the points eliminated, so the
/// uncertainty of the structure every camera shares is in it. Cross terms are kept: a rotation
/// error shared by every camera is the gauge's, and a caller removes it as its alignment does
/// ([`aligned_rotation_sd`]). Errors as [`intrinsics_covariance`].
pub fn rotation_covariance(problem: &Problem) -> Result<RotationCovariance, BundleError> {
    let reduced = ReducedCovariance::new(problem)?;
    let cams = problem.cameras.len();
    // w_c = R_cᵀ·J_l(ω_c)·dω_c (the solver's ω steps are left perturbations J_l·dω, in the
    // camera frame; Rᵀ takes them to the world's).
    let maps: Vec<Matrix3<f64>> = problem
        .cameras
        .iter()
        .map(|c| {
            let (r, jl) = rotation_and_left_jacobian(&c.rotation);
            r.transpose() * jl
        })
        .collect();
    // The rotation parameters' rows of (JᵀJ)⁻¹ (zero for a held one), as its columns.
    let rows: Vec<usize> = reduced.pose.iter().flat_map(|p| p[..3].to_vec()).collect();
    let x = reduced.columns(&rows);
    let row_of = |a: usize, col: usize| -> f64 { x[(col, a)] };
    let mut white = DMatrix::<f64>::zeros(3 * cams, 3 * cams);
    for a in 0..3 * cams {
        for b in 0..3 * cams {
            if rows[b] != usize::MAX {
                white[(a, b)] = row_of(a, rows[b]);
            }
        }
    }
    // The tracks' sandwich Σ_t (S⁻¹g_t)(S⁻¹g_t)ᵀ over the rotation rows, g_t a point's
    // gradient on the camera side (the points are at their optimum: their own is zero).
    let xs: Vec<Vec<f64>> = reduced
        .gradients
        .par_iter()
        .map(|g| {
            (0..3 * cams)
                .map(|a| g.iter().map(|&(i, v)| row_of(a, i) * v).sum())
                .collect()
        })
        .collect();
    let mut tracks = DMatrix::<f64>::zeros(3 * cams, 3 * cams);
    for x in &xs {
        for b in 0..3 * cams {
            if x[b] != 0.0 {
                for a in 0..3 * cams {
                    tracks[(a, b)] += x[a] * x[b];
                }
            }
        }
    }
    let sigma2 = reduced.sigma * reduced.sigma;
    let to_world = |m: &DMatrix<f64>, scale: f64| -> DMatrix<f64> {
        let mut out = DMatrix::<f64>::zeros(3 * cams, 3 * cams);
        for c in 0..cams {
            for d in 0..cams {
                let b: Matrix3<f64> = m.fixed_view::<3, 3>(3 * c, 3 * d).into();
                out.fixed_view_mut::<3, 3>(3 * c, 3 * d)
                    .copy_from(&(maps[c] * b * maps[d].transpose() * scale));
            }
        }
        out
    };
    Ok(RotationCovariance {
        white: to_world(&white, sigma2),
        tracks: to_world(&tracks, 1.0),
        sigma: reduced.sigma,
    })
}

/// [`rotation_covariance`]'s result.
#[derive(Clone, Debug)]
pub struct RotationCovariance {
    /// σ̂²·(JᵀJ)⁻¹: the observations' errors independent, of one variance.
    pub white: DMatrix<f64>,
    /// The sandwich estimate with the tracks as clusters, (JᵀJ)⁻¹·(Σ_t g_t g_tᵀ)·(JᵀJ)⁻¹ with
    /// g_t a track's gradient (Liang & Zeger 1986; White 1980): it holds when a track's errors
    /// are correlated along it (a feature that drifts), which `white` misses; with fewer
    /// tracks than camera parameters it does not see every direction, so use the larger of
    /// the two.
    pub tracks: DMatrix<f64>,
    /// σ̂, the RMS residual per coordinate with the degrees of freedom removed.
    pub sigma: f64,
}

/// Per camera, the standard deviation (radians) of the least-determined axis of its rotation
/// error after the alignment that removes the rotation shared by every camera: `relative_to:
/// None` subtracts the mean error (as a similarity fitted to the cameras' orientations does),
/// `Some(c)` camera c's (a solve compared frame to frame from its first). `cov` is
/// [`rotation_covariance`]'s.
pub fn aligned_rotation_sd(cov: &DMatrix<f64>, relative_to: Option<usize>) -> Vec<f64> {
    aligned_rotation_covariances(cov, relative_to)
        .iter()
        .map(|e| e.symmetric_eigenvalues().max().max(0.0).sqrt())
        .collect()
}

/// Per camera, the 3 × 3 covariance (radians²) of its rotation error after the alignment of
/// [`aligned_rotation_sd`].
pub fn aligned_rotation_covariances(
    cov: &DMatrix<f64>,
    relative_to: Option<usize>,
) -> Vec<Matrix3<f64>> {
    let cams = cov.nrows() / 3;
    let b = |c: usize, d: usize| -> Matrix3<f64> { cov.fixed_view::<3, 3>(3 * c, 3 * d).into() };
    // e_c = w_c − m, m the mean (or the reference camera's) error:
    // cov(e_c) = Σ_cc − Σ_cm − Σ_mc + Σ_mm.
    let n = cams as f64;
    let (cross, mm): (Vec<Matrix3<f64>>, Matrix3<f64>) = match relative_to {
        Some(r) => ((0..cams).map(|c| b(c, r)).collect(), b(r, r)),
        None => {
            let rows: Vec<Matrix3<f64>> = (0..cams)
                .map(|c| (0..cams).map(|d| b(c, d)).sum::<Matrix3<f64>>() / n)
                .collect();
            let mm = rows.iter().sum::<Matrix3<f64>>() / n;
            (rows, mm)
        }
    };
    (0..cams)
        .map(|c| {
            let e = b(c, c) - cross[c] - cross[c].transpose() + mm;
            (e + e.transpose()) * 0.5
        })
        .collect()
}

/// The inverse of the reduced (camera-side) information matrix at a problem's current values:
/// the points eliminated, the gauge's own `fixed` and held parameters left out.
struct ReducedCovariance {
    /// The Cholesky factor of JᵀJ over the free camera-side parameters.
    cholesky: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    /// Per camera, the index of each pose parameter `[ω, t]` (`usize::MAX`: held).
    pose: Vec<[usize; 6]>,
    /// Per intrinsics block, the index of each parameter (`usize::MAX`: held).
    intrinsics: Vec<[usize; INTRINSICS]>,
    /// σ̂: the RMS residual per coordinate with the degrees of freedom removed.
    sigma: f64,
    /// Per point, the camera-side gradient of its observations with the point eliminated,
    /// sparse ([`eliminate_point`]).
    gradients: Vec<Vec<(usize, f64)>>,
}

impl ReducedCovariance {
    /// The columns `index` of (JᵀJ)⁻¹ (unscaled; a zero column for `usize::MAX`, a held
    /// parameter), solved from the factor rather than inverting the whole matrix.
    fn columns(&self, index: &[usize]) -> DMatrix<f64> {
        let n = self.cholesky.l_dirty().nrows();
        let mut e = DMatrix::<f64>::zeros(n, index.len());
        for (j, &i) in index.iter().enumerate() {
            if i != usize::MAX {
                e[(i, j)] = 1.0;
            }
        }
        let mut x = self.cholesky.solve(&e);
        for (j, &i) in index.iter().enumerate() {
            if i == usize::MAX {
                x.column_mut(j).fill(0.0);
            }
        }
        x
    }

    fn new(problem: &Problem) -> Result<Self, BundleError> {
        problem.validate()?;
        let masks = problem.pose_masks();
        // Index of every free camera-side parameter: per camera its 6 pose components, per
        // intrinsics block its 3 parameters.
        let mut n = 0usize;
        let mut pose_index = vec![[usize::MAX; 6]; problem.cameras.len()];
        for (c, cam) in problem.cameras.iter().enumerate() {
            for u in 0..6 {
                if !cam.fixed && !masks[c][u] {
                    pose_index[c][u] = n;
                    n += 1;
                }
            }
        }
        let mut intr_index = vec![[usize::MAX; INTRINSICS]; problem.intrinsics.len()];
        for (k, b) in problem.intrinsics.iter().enumerate() {
            if b.fixed {
                continue;
            }
            for u in 0..b.num_params() {
                if !b.is_held(u) {
                    intr_index[k][u] = n;
                    n += 1;
                }
            }
        }
        if n > MAX_DIMENSION {
            return Err(BundleError::InvalidProblem(format!(
                "the covariance of {n} camera parameters is not computed (at most {MAX_DIMENSION})"
            )));
        }
        let mut by_point: Vec<Vec<usize>> = vec![Vec::new(); problem.points.len()];
        for (i, o) in problem.observations.iter().enumerate() {
            by_point[o.point].push(i);
        }
        // The points in a fixed number of chunks (whatever the thread count: the sums' order is
        // fixed), each eliminated into its own S in parallel, the partial sums added in order.
        let chunks = (CHUNK_MEMORY / (8 * n * n).max(1)).clamp(1, CHUNKS);
        let per_chunk = by_point.len().div_ceil(chunks).max(1);
        let index = Index {
            pose: &pose_index,
            intrinsics: &intr_index,
        };
        type Partial = (DMatrix<f64>, f64, usize, Vec<Vec<(usize, f64)>>);
        let partials: Vec<Partial> = by_point
            .par_chunks(per_chunk)
            .enumerate()
            .map(|(ci, points)| {
                let mut part = (DMatrix::<f64>::zeros(n, n), 0.0, 0usize, Vec::new());
                for (q, obs) in points.iter().enumerate() {
                    let p = ci * per_chunk + q;
                    let (rank, g) =
                        eliminate_point(problem, p, obs, &index, &mut part.0, &mut part.1);
                    part.2 += rank;
                    part.3.push(g);
                }
                part
            })
            .collect();
        let mut s = DMatrix::<f64>::zeros(n, n);
        let (mut sq, mut point_params) = (0.0, 0usize);
        let mut gradients = Vec::with_capacity(problem.points.len());
        for (ps, psq, pp, pg) in partials {
            s += ps;
            sq += psq;
            point_params += pp;
            gradients.extend(pg);
        }
        // The priors: residuals like the observations' (their coefficients in the same units).
        for p in &problem.priors {
            sq += p.residual(&problem.intrinsics).powi(2);
            for ta in &p.terms {
                let a = intr_index[ta.intrinsics][ta.param];
                for tb in &p.terms {
                    let b = intr_index[tb.intrinsics][tb.param];
                    if a != usize::MAX && b != usize::MAX {
                        s[(a, b)] += ta.coefficient * tb.coefficient;
                    }
                }
            }
        }
        let m = 2 * problem.observations.len() + problem.priors.len();
        let dof = m as f64 - (n + point_params) as f64;
        if dof <= 0.0 {
            return Err(BundleError::InvalidProblem(format!(
                "{m} residuals do not determine {} parameters",
                n + point_params
            )));
        }
        // Symmetrize (the elimination accumulates in both triangles) and invert.
        let s = (&s + s.transpose()) * 0.5;
        let chol = s.cholesky().ok_or_else(|| {
            BundleError::InvalidProblem(
                "the information matrix is singular: the gauge or an intrinsic is not determined"
                    .into(),
            )
        })?;
        Ok(ReducedCovariance {
            cholesky: chol,
            pose: pose_index,
            intrinsics: intr_index,
            sigma: (sq / dof).sqrt(),
            gradients,
        })
    }
}

/// Point chunks of [`intrinsics_covariance`] (each its own n × n sum).
const CHUNKS: usize = 8;
/// Memory the chunks' sums may take, bytes (fewer chunks for a large S).
const CHUNK_MEMORY: usize = 256 << 20;

/// The global index of every free camera-side parameter (`usize::MAX`: not free).
struct Index<'a> {
    pose: &'a [[usize; 6]],
    intrinsics: &'a [[usize; INTRINSICS]],
}

/// Adds point `p`'s observations `obs` to S — their `Jcᵀ Jc` and, for a free point, minus
/// `W V⁺ Wᵀ` (W: the free camera columns' `Jcᵀ Jx` stacked over the observations) — and their
/// squared residuals to `sq`. Returns the rank of V (the point's parameters; 0 when fixed) and
/// the point's camera-side gradient with the point eliminated, by global index:
/// `Σ Jcᵀ·r − W·V⁺·Σ Jxᵀ·r` (the cost's gradient with the point moved to its best position as
/// the cameras move; `Σ Jcᵀ·r` alone at a point's least-squares optimum).
fn eliminate_point(
    problem: &Problem,
    p: usize,
    obs: &[usize],
    index: &Index,
    s: &mut DMatrix<f64>,
    sq: &mut f64,
) -> (usize, Vec<(usize, f64)>) {
    let point = &problem.points[p];
    let (mut v, mut gx) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    // W's rows: a global index and Jcᵀ·Jx's row of that column.
    let (mut rows, mut w): (Vec<usize>, Vec<Vector3<f64>>) = (Vec::new(), Vec::new());
    let mut g: Vec<(usize, f64)> = Vec::new();
    for &i in obs {
        let o = &problem.observations[i];
        let cam = &problem.cameras[o.camera];
        let k = &problem.intrinsics[cam.intrinsics];
        let (pred, jc, jx) =
            project_with_jacobians(k, &cam.rotation, &cam.translation, &point.position);
        let (jc, jx) = (jc * o.weight, jx * o.weight);
        let r = (pred - o.pixel) * o.weight;
        *sq += r.norm_squared();
        let mut idx = [usize::MAX; CC];
        idx[..6].copy_from_slice(&index.pose[o.camera]);
        idx[6..].copy_from_slice(&index.intrinsics[cam.intrinsics]);
        let free: Vec<(usize, usize)> = (0..CC)
            .filter(|&a| idx[a] != usize::MAX)
            .map(|a| (a, idx[a]))
            .collect();
        for &(b, gb) in &free {
            for &(a, ga) in &free {
                s[(ga, gb)] += jc.column(a).dot(&jc.column(b));
            }
            g.push((gb, jc.column(b).dot(&r)));
        }
        if !point.fixed {
            v += jx.transpose() * jx;
            gx += jx.transpose() * r;
            let wt = jc.transpose() * jx;
            for &(a, ga) in &free {
                rows.push(ga);
                w.push(wt.row(a).transpose());
            }
        }
    }
    let mut rank = 0;
    if !point.fixed && !rows.is_empty() {
        let v_inv;
        (v_inv, rank) = pseudo_inverse(&v);
        let t: Vec<Vector3<f64>> = w.iter().map(|r| v_inv * r).collect();
        for (j, &gj) in rows.iter().enumerate() {
            for (ti, &gi) in t.iter().zip(&rows) {
                s[(gi, gj)] -= ti.dot(&w[j]);
            }
        }
        let dx = v_inv * gx;
        g.extend(rows.iter().zip(&w).map(|(&ga, row)| (ga, -row.dot(&dx))));
    }
    g.sort_unstable_by_key(|e| e.0);
    g.dedup_by(|b, a| {
        if a.0 == b.0 {
            a.1 += b.1;
            true
        } else {
            false
        }
    });
    (rank, g)
}

/// The pseudo-inverse of a symmetric positive semi-definite 3×3 block (eigenvalues below
/// 1e-9 of the largest dropped) and its rank.
fn pseudo_inverse(v: &Matrix3<f64>) -> (Matrix3<f64>, usize) {
    let e = v.symmetric_eigen();
    let top = e.eigenvalues.max();
    let (mut out, mut rank) = (Matrix3::zeros(), 0);
    for i in 0..3 {
        let l = e.eigenvalues[i];
        if l > 1e-9 * top && l > 0.0 {
            let q = e.eigenvectors.column(i);
            out += q * q.transpose() / l;
            rank += 1;
        }
    }
    (out, rank)
}

#[cfg(test)]
mod tests {
    use super::super::camera_model::Intrinsics;
    use super::super::problem::{CameraPose, Gauge, Observation, Point};
    use super::*;
    use nalgebra::{Vector2, Vector3};
    use rand::{Rng, SeedableRng};

    /// Adds an observation of every point in every camera, its pixel off by Gaussian noise σ.
    fn observe_with_noise(p: &mut Problem, sigma: f64, rng: &mut rand_pcg::Pcg64) {
        for c in 0..p.cameras.len() {
            for j in 0..p.points.len() {
                let q = super::super::residual::project(
                    &p.intrinsics[0],
                    &p.cameras[c].rotation,
                    &p.cameras[c].translation,
                    &p.points[j].position,
                );
                let e = Vector2::new(
                    vfxgraph_geometry::synthetic::gaussian(rng),
                    vfxgraph_geometry::synthetic::gaussian(rng),
                );
                p.observations.push(Observation {
                    camera: c,
                    point: j,
                    pixel: q + sigma * e,
                    weight: 1.0,
                });
            }
        }
    }

    /// Every camera's world-frame rotation error of `est` against `truth`, their mean removed
    /// (as [`aligned_rotation_covariances`] with no reference camera).
    fn aligned_rotation_errors(truth: &Problem, est: &Problem) -> Vec<Vector3<f64>> {
        let w: Vec<Vector3<f64>> = truth
            .cameras
            .iter()
            .zip(&est.cameras)
            .map(|(t, e)| {
                let r = t.rotation_matrix().transpose() * e.rotation_matrix();
                super::super::rotation::matrix_to_angle_axis(&r)
            })
            .collect();
        let mean = w.iter().sum::<Vector3<f64>>() / w.len() as f64;
        w.iter().map(|x| x - mean).collect()
    }

    /// A crane over a shallow scene (its depth a twelfth of its distance), observed with
    /// Gaussian noise σ: the
    /// predicted rotation errors after removing their mean ([`aligned_rotation_covariances`]
    /// of [`rotation_covariance`], the points free) match the errors of the cameras solved
    /// over many noise draws (Monte Carlo, per camera and in total), with K held and with the
    /// focal length free (never better determined than with it held).
    #[test]
    fn aligned_rotation_covariance_matches_monte_carlo() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let pts: Vec<Vector3<f64>> = (0..80)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(9.6..10.4),
                )
            })
            .collect();
        let cams: Vec<CameraPose> = (0..10)
            .map(|i| {
                let u = i as f64 / 9.0;
                let r = super::super::rotation::angle_axis_to_matrix(&Vector3::new(
                    0.08 * u,
                    -0.05 * u,
                    0.02,
                ));
                let c = Vector3::new(0.3 * u, -0.6 * u, 1.2 * u);
                CameraPose::from_rt(&r, &(-(r * c)), 0)
            })
            .collect();
        let sigma = 0.5;
        let mut totals = Vec::new();
        for free_focal in [false, true] {
            let mut block = Intrinsics::pinhole(900.0, 480.0, 270.0, !free_focal);
            block.held[1] = true;
            block.held[2] = true;
            let truth = Problem {
                cameras: cams.clone(),
                intrinsics: vec![block],
                points: pts
                    .iter()
                    .map(|&p| Point {
                        position: p,
                        fixed: false,
                    })
                    .collect(),
                observations: Vec::new(),
                gauge: Gauge::FixFirstCameraAndScale,
                priors: Vec::new(),
            };
            let n = truth.cameras.len();
            let draws = 100;
            let (mut measured, mut predicted) = (vec![0.0; n], vec![0.0; n]);
            let mut by_tracks = vec![0.0; n];
            for seed in 0..draws {
                let mut rng = rand_pcg::Pcg64::seed_from_u64(1000 + seed);
                let mut p = truth.clone();
                observe_with_noise(&mut p, sigma, &mut rng);
                super::super::solve(&mut p, &Default::default()).unwrap();
                let cov = rotation_covariance(&p).unwrap();
                let aligned = aligned_rotation_covariances(&cov.white, None);
                let sandwich = aligned_rotation_covariances(&cov.tracks, None);
                // The world-frame errors, their mean removed.
                let e = aligned_rotation_errors(&truth, &p);
                for c in 0..n {
                    measured[c] += e[c].norm_squared() / draws as f64;
                    predicted[c] += aligned[c].trace() / draws as f64;
                    by_tracks[c] += sandwich[c].trace() / draws as f64;
                }
            }
            for c in 0..n {
                let ratio = (measured[c] / predicted[c]).sqrt();
                assert!(
                    (ratio - 1.0).abs() < 0.3,
                    "free focal {free_focal}, camera {c}: measured/predicted {ratio}"
                );
            }
            let total = (measured.iter().sum::<f64>() / predicted.iter().sum::<f64>()).sqrt();
            // With white noise the tracks' sandwich estimates the same, on average.
            let sandwich = (by_tracks.iter().sum::<f64>() / predicted.iter().sum::<f64>()).sqrt();
            eprintln!("free focal {free_focal}: measured/predicted {total:.3}, sandwich/predicted {sandwich:.3}");
            assert!(
                (sandwich - 1.0).abs() < 0.15,
                "free focal {free_focal}: {sandwich}"
            );
            assert!(
                (total - 1.0).abs() < 0.12,
                "free focal {free_focal}: {total}"
            );
            totals.push(predicted.iter().sum::<f64>().sqrt());
        }
        eprintln!(
            "aligned rotation σ, total: K held {}, focal free {}",
            totals[0], totals[1]
        );
        assert!(totals[1] >= totals[0], "{totals:?}");
    }

    /// Tracks that drift (each feature's error grows along the shot, at a rate of its own):
    /// the errors along a track are correlated, the white-noise covariance sees a fraction of
    /// the rotations' scatter over many draws (Monte Carlo), the tracks' sandwich sees it.
    #[test]
    fn the_tracks_sandwich_sees_drifting_tracks() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let pts: Vec<Vector3<f64>> = (0..150)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(7.0..12.0),
                )
            })
            .collect();
        let n = 12;
        let cams: Vec<CameraPose> = (0..n)
            .map(|i| {
                let u = i as f64 / (n - 1) as f64;
                let r = super::super::rotation::angle_axis_to_matrix(&Vector3::new(
                    0.03 * u,
                    -0.12 * u,
                    0.0,
                ));
                let c = Vector3::new(1.5 * u, -0.2 * u, 0.3 * u);
                CameraPose::from_rt(&r, &(-(r * c)), 0)
            })
            .collect();
        let truth = Problem {
            cameras: cams,
            intrinsics: vec![Intrinsics::pinhole(900.0, 480.0, 270.0, true)],
            points: pts
                .iter()
                .map(|&p| Point {
                    position: p,
                    fixed: false,
                })
                .collect(),
            observations: Vec::new(),
            gauge: Gauge::FixFirstCameraAndScale,
            priors: Vec::new(),
        };
        let draws = 60;
        let (mut measured, mut white, mut tracks) = (0.0, 0.0, 0.0);
        for seed in 0..draws {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(2000 + seed);
            let mut p = truth.clone();
            for j in 0..p.points.len() {
                let rate = Vector2::new(
                    vfxgraph_geometry::synthetic::gaussian(&mut rng),
                    vfxgraph_geometry::synthetic::gaussian(&mut rng),
                ) * 0.6;
                for c in 0..n {
                    let q = super::super::residual::project(
                        &p.intrinsics[0],
                        &p.cameras[c].rotation,
                        &p.cameras[c].translation,
                        &p.points[j].position,
                    );
                    let e = Vector2::new(
                        vfxgraph_geometry::synthetic::gaussian(&mut rng),
                        vfxgraph_geometry::synthetic::gaussian(&mut rng),
                    );
                    let u = c as f64 / (n - 1) as f64;
                    p.observations.push(Observation {
                        camera: c,
                        point: j,
                        pixel: q + rate * u + 0.1 * e,
                        weight: 1.0,
                    });
                }
            }
            super::super::solve(&mut p, &Default::default()).unwrap();
            let cov = rotation_covariance(&p).unwrap();
            let e = aligned_rotation_errors(&truth, &p);
            let a = aligned_rotation_covariances(&cov.white, None);
            let b = aligned_rotation_covariances(&cov.tracks, None);
            for c in 0..n {
                measured += e[c].norm_squared();
                white += a[c].trace();
                tracks += b[c].trace();
            }
        }
        let (white, tracks) = ((white / measured).sqrt(), (tracks / measured).sqrt());
        eprintln!("predicted / measured rotation scatter: white {white:.3}, tracks {tracks:.3}");
        assert!(white < 0.7, "{white}");
        assert!((tracks - 1.0).abs() < 0.25, "{tracks}");
    }

    /// A shot with a free focal length observed with Gaussian noise σ: the covariance's focal
    /// standard deviation matches the spread of the focal lengths solved over many noise draws
    /// (Monte Carlo), within the sampling error of 40 draws (±25 %).
    #[test]
    fn focal_deviation_matches_monte_carlo() {
        let f_true = 1000.0;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let pts: Vec<Vector3<f64>> = (0..120)
            .map(|_| {
                Vector3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(6.0..12.0),
                )
            })
            .collect();
        let cams: Vec<CameraPose> = (0..8)
            .map(|i| {
                let a = 0.06 * i as f64;
                let r = super::super::rotation::angle_axis_to_matrix(&Vector3::new(0.0, -a, 0.0));
                let c = Vector3::new(0.5 * i as f64, 0.1 * (i as f64).sin(), 0.0);
                CameraPose::from_rt(&r, &(-(r * c)), 0)
            })
            .collect();
        let block = Intrinsics::pinhole(f_true, 640.0, 360.0, false);
        let mut block = block;
        block.held[1] = true;
        block.held[2] = true;
        let truth = Problem {
            cameras: cams,
            intrinsics: vec![block],
            points: pts
                .iter()
                .map(|&p| Point {
                    position: p,
                    fixed: false,
                })
                .collect(),
            observations: Vec::new(),
            gauge: Gauge::FixFirstCameraAndScale,
            priors: Vec::new(),
        };
        let sigma = 0.5;
        let draw = |seed: u64| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let mut p = truth.clone();
            observe_with_noise(&mut p, sigma, &mut rng);
            p
        };
        let mut fs = Vec::new();
        let mut predicted = Vec::new();
        for seed in 0..40 {
            let mut p = draw(100 + seed);
            super::super::solve(&mut p, &Default::default()).unwrap();
            let (cov, s) = intrinsics_covariance(&p).unwrap();
            assert!((s / sigma - 1.0).abs() < 0.1, "σ̂ {s}");
            predicted.push(cov[0].unwrap()[(0, 0)].sqrt());
            fs.push(p.intrinsics[0].params[0]);
        }
        let mean = fs.iter().sum::<f64>() / fs.len() as f64;
        let sd =
            (fs.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / (fs.len() - 1) as f64).sqrt();
        let pred = predicted.iter().sum::<f64>() / predicted.len() as f64;
        eprintln!("focal sd: Monte Carlo {sd:.4} px, covariance {pred:.4} px");
        assert!(
            (pred / sd - 1.0).abs() < 0.25,
            "predicted {pred}, observed {sd}"
        );
    }
}
