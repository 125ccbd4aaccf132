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

use super::error::BundleError;
use super::problem::Problem;
use super::residual::{project_with_jacobians, CAMERA_COLUMNS as CC, INTRINSICS};

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
    let partials: Vec<(DMatrix<f64>, f64, usize)> = by_point
        .par_chunks(per_chunk)
        .enumerate()
        .map(|(ci, points)| {
            let mut part = (DMatrix::<f64>::zeros(n, n), 0.0, 0usize);
            for (q, obs) in points.iter().enumerate() {
                let p = ci * per_chunk + q;
                part.2 += eliminate_point(problem, p, obs, &index, &mut part.0, &mut part.1);
            }
            part
        })
        .collect();
    let mut s = DMatrix::<f64>::zeros(n, n);
    let (mut sq, mut point_params) = (0.0, 0usize);
    for (ps, psq, pp) in partials {
        s += ps;
        sq += psq;
        point_params += pp;
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
    let sigma2 = sq / dof;
    // Symmetrize (the elimination accumulates in both triangles) and invert.
    let s = (&s + s.transpose()) * 0.5;
    let chol = s.cholesky().ok_or_else(|| {
        BundleError::InvalidProblem(
            "the information matrix is singular: the gauge or an intrinsic is not determined"
                .into(),
        )
    })?;
    let inv = chol.inverse();
    let covs = intr_index
        .iter()
        .zip(&problem.intrinsics)
        .map(|(idx, b)| {
            (!b.fixed).then(|| {
                let mut c = IntrinsicsCovariance::zeros();
                for a in 0..INTRINSICS {
                    for d in 0..INTRINSICS {
                        if idx[a] != usize::MAX && idx[d] != usize::MAX {
                            c[(a, d)] = sigma2 * inv[(idx[a], idx[d])];
                        }
                    }
                }
                c
            })
        })
        .collect();
    Ok((covs, sigma2.sqrt()))
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
/// squared residuals to `sq`. Returns the rank of V (the point's parameters; 0 when fixed).
fn eliminate_point(
    problem: &Problem,
    p: usize,
    obs: &[usize],
    index: &Index,
    s: &mut DMatrix<f64>,
    sq: &mut f64,
) -> usize {
    let point = &problem.points[p];
    let mut v = Matrix3::<f64>::zeros();
    // W's rows: a global index and Jcᵀ·Jx's row of that column.
    let (mut rows, mut w): (Vec<usize>, Vec<Vector3<f64>>) = (Vec::new(), Vec::new());
    for &i in obs {
        let o = &problem.observations[i];
        let cam = &problem.cameras[o.camera];
        let k = &problem.intrinsics[cam.intrinsics];
        let (pred, jc, jx) =
            project_with_jacobians(k, &cam.rotation, &cam.translation, &point.position);
        let (jc, jx) = (jc * o.weight, jx * o.weight);
        *sq += ((pred - o.pixel) * o.weight).norm_squared();
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
        }
        if !point.fixed {
            v += jx.transpose() * jx;
            let wt = jc.transpose() * jx;
            for &(a, ga) in &free {
                rows.push(ga);
                w.push(wt.row(a).transpose());
            }
        }
    }
    if point.fixed || rows.is_empty() {
        return 0;
    }
    let (v_inv, rank) = pseudo_inverse(&v);
    let t: Vec<Vector3<f64>> = w.iter().map(|r| v_inv * r).collect();
    for (j, &gj) in rows.iter().enumerate() {
        for (ti, &gi) in t.iter().zip(&rows) {
            s[(gi, gj)] -= ti.dot(&w[j]);
        }
    }
    rank
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
    use super::super::problem::{CameraPose, Gauge, Intrinsics, Observation, Point};
    use super::*;
    use nalgebra::{Vector2, Vector3};
    use rand::{Rng, SeedableRng};

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
            for c in 0..p.cameras.len() {
                for j in 0..p.points.len() {
                    let q = super::super::residual::project(
                        &p.intrinsics[0],
                        &p.cameras[c].rotation,
                        &p.cameras[c].translation,
                        &p.points[j].position,
                    );
                    let n = Vector2::new(
                        crate::synthetic::gaussian(&mut rng),
                        crate::synthetic::gaussian(&mut rng),
                    );
                    p.observations.push(Observation {
                        camera: c,
                        point: j,
                        pixel: q + sigma * n,
                        weight: 1.0,
                    });
                }
            }
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
