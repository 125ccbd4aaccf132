//! Tests of the whole solver on real and synthetic data (the BAL figures, the noise floor and the determinism the bundle adjuster promises).

use nalgebra::{Matrix3, Vector2, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;

use super::residual::{project, project_with_jacobians};
use super::rotation::{angle_axis_to_matrix, matrix_to_angle_axis};
use super::synthetic::{video_like, SyntheticModel, VideoConfig};
use super::*;

/// A data file or folder these tests cannot run without (a panic naming it when absent).
fn shared_data(rel: &str) -> std::path::PathBuf {
    vfxgraph_testdata::require(rel)
}

const LADYBUG: &str = "bal_ladybug_49/problem-49-7776-pre.txt";

#[test]
fn ladybug_initial_cost_matches_reference() {
    let p =
        read_bal(shared_data(LADYBUG)).expect("shared/data/bal_ladybug_49 must be beside the repo");
    assert_eq!(
        (p.cameras.len(), p.points.len(), p.observations.len()),
        (49, 7776, 31843)
    );
    let c = p.cost();
    let reference = 850912.4606808;
    assert!(
        ((c - reference) / reference).abs() < 1e-6,
        "initial cost {c}"
    );
}

#[test]
fn ladybug_jacobians_match_finite_differences() {
    let p = read_bal(shared_data(
        "bal_ladybug_49/problem-49-7776-pre-shrink-1800.txt",
    ))
    .unwrap();
    for i in (0..p.observations.len()).step_by(997) {
        let o = &p.observations[i];
        let c = &p.cameras[o.camera];
        let k = &p.intrinsics[c.intrinsics];
        let x = &p.points[o.point].position;
        let (_, jc, jx) = project_with_jacobians(k, &c.rotation, &c.translation, x);
        for col in 0..3 {
            let h = 1e-6;
            let mut wp = c.rotation;
            wp[col] += h;
            let mut wm = c.rotation;
            wm[col] -= h;
            let fd = (project(k, &wp, &c.translation, x) - project(k, &wm, &c.translation, x))
                / (2.0 * h);
            assert!(
                (fd - jc.column(col)).norm() < 1e-5 * (1.0 + fd.norm()),
                "obs {i} ω{col}"
            );
            let mut xp = *x;
            xp[col] += h;
            let mut xm = *x;
            xm[col] -= h;
            let fd = (project(k, &c.rotation, &c.translation, &xp)
                - project(k, &c.rotation, &c.translation, &xm))
                / (2.0 * h);
            assert!(
                (fd - jx.column(col)).norm() < 1e-5 * (1.0 + fd.norm()),
                "obs {i} X{col}"
            );
        }
    }
}

/// Ceres 2.1, SPARSE_SCHUR, default tolerances: 13344.3184 after 31 steps. ~1 s in release;
/// a few seconds in the test profile.
#[test]
fn ladybug_reaches_ceres_cost() {
    let r = solve_bal_file(shared_data(LADYBUG), &BalBenchOptions::default()).unwrap();
    assert!(
        r.final_cost <= 13344.3184 * (1.0 + 1e-4),
        "final cost {}",
        r.final_cost
    );
    assert!(r.final_rms < 0.916, "rms {}", r.final_rms);
    assert_eq!(r.observations, 31843);
}

#[test]
fn nan_input_is_a_typed_error() {
    let mut p = video_like(&VideoConfig {
        cameras: 5,
        points: 50,
        ..VideoConfig::default()
    })
    .problem;
    p.points[3].position.y = f64::NAN;
    assert!(matches!(
        solve(&mut p, &SolverOptions::default()),
        Err(BundleError::NonFinite { .. })
    ));
    p.points[3].position.y = 0.0;
    p.observations[0].camera = 99;
    assert!(matches!(
        solve(&mut p, &SolverOptions::default()),
        Err(BundleError::IndexOutOfRange { .. })
    ));
    p.observations[0].camera = 0;
    let bad = SolverOptions {
        loss: Loss::Huber { scale: -1.0 },
        ..SolverOptions::default()
    };
    assert!(solve(&mut p, &bad).is_err());
}

/// Per-coordinate RMS over the inlier observations.
fn inlier_rms(p: &Problem, outliers: &[bool]) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0;
    for (i, o) in p.observations.iter().enumerate() {
        if !outliers[i] {
            s += (p.predict(i) - o.pixel).norm_squared();
            n += 1;
        }
    }
    ((s / (2 * n) as f64).sqrt(), n)
}

fn noise_floor_case(cameras: usize, points: usize, solver: LinearSolverKind) {
    let cfg = VideoConfig {
        cameras,
        points,
        noise_px: 0.5,
        outlier_fraction: 0.05,
        seed: cameras as u64,
        ..VideoConfig::default()
    };
    let s = video_like(&cfg);
    let mut p = s.problem.clone();
    let opts = SolverOptions {
        loss: Loss::Cauchy { scale: 1.0 },
        linear_solver: solver,
        max_iterations: 100,
        ..SolverOptions::default()
    };
    let r = solve(&mut p, &opts).unwrap();
    let (rms, inliers) = inlier_rms(&p, &s.outliers);
    let floor = cfg.noise_px * (1.0 - p.num_free_parameters() as f64 / (2 * inliers) as f64).sqrt();
    eprintln!(
        "{cameras} cameras, {} obs: inlier RMS {rms:.4} px, floor {floor:.4} px, {} iterations, {:?}, {:.2} s",
        p.observations.len(),
        r.iterations,
        r.termination,
        r.seconds
    );
    assert!(r.termination.converged(), "{:?}", r.termination);
    assert!(
        (rms - floor).abs() <= 0.05 * floor,
        "rms {rms} floor {floor}"
    );
    // The gauge held camera 0.
    assert_eq!(p.cameras[0], s.problem.cameras[0]);
}

#[test]
fn synthetic_video_50_cameras_reaches_noise_floor() {
    noise_floor_case(50, 2000, LinearSolverKind::Auto);
}

#[test]
fn synthetic_video_300_cameras_reaches_noise_floor() {
    noise_floor_case(300, 6000, LinearSolverKind::SparseSchur);
}

#[test]
fn synthetic_video_1000_cameras_reaches_noise_floor() {
    noise_floor_case(1000, 12000, LinearSolverKind::SparseSchur);
}

#[test]
fn all_linear_solvers_agree() {
    let s = video_like(&VideoConfig {
        cameras: 20,
        points: 400,
        model: SyntheticModel::Bal,
        ..VideoConfig::default()
    });
    let mut costs = Vec::new();
    for kind in [
        LinearSolverKind::DenseSchur,
        LinearSolverKind::SparseSchur,
        LinearSolverKind::IterativeSchur,
    ] {
        let mut p = s.problem.clone();
        let r = solve(
            &mut p,
            &SolverOptions {
                linear_solver: kind,
                ..SolverOptions::default()
            },
        )
        .unwrap();
        assert_eq!(r.linear_solver, kind);
        costs.push(r.final_cost);
    }
    for c in &costs {
        assert!((c - costs[0]).abs() <= 1e-4 * costs[0], "{costs:?}");
    }
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let s = video_like(&VideoConfig {
        cameras: 30,
        points: 3000,
        outlier_fraction: 0.05,
        ..VideoConfig::default()
    });
    let run = |threads| {
        let mut p = s.problem.clone();
        let r = solve(
            &mut p,
            &SolverOptions {
                num_threads: Some(threads),
                loss: Loss::Huber { scale: 1.0 },
                linear_solver: LinearSolverKind::SparseSchur,
                ..SolverOptions::default()
            },
        )
        .unwrap();
        (r.final_cost.to_bits(), r.iterations, p)
    };
    let (c1, i1, p1) = run(1);
    let (c3, i3, p3) = run(3);
    assert_eq!((c1, i1), (c3, i3));
    assert_eq!(p1, p3);
}

#[test]
fn report_has_per_camera_and_per_point_errors() {
    let s = video_like(&VideoConfig {
        cameras: 10,
        points: 300,
        ..VideoConfig::default()
    });
    let mut p = s.problem;
    let r = solve(&mut p, &SolverOptions::default()).unwrap();
    assert_eq!(r.camera_rms.len(), 10);
    assert_eq!(r.point_rms.len(), p.points.len());
    assert!(r.final_cost < r.initial_cost && r.final_rms < r.initial_rms);
    assert!(r.camera_rms.iter().all(|e| *e > 0.0 && *e < 2.0));
    assert_eq!(r.steps.len(), r.iterations);
}

// ---------------------------------------------------------------- Oxford VGG Model House

/// RQ decomposition of a 3×3 matrix: M = K·R with K upper triangular (positive diagonal)
/// and R a rotation (Hartley & Zisserman A4.1.1). M must have det > 0.
fn rq3(m: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let j = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
    let qr = (j * m).transpose().qr();
    let (q, r) = (qr.q(), qr.r());
    let mut k = j * r.transpose() * j;
    let mut rot = j * q.transpose();
    let d = Matrix3::from_diagonal(&Vector3::new(
        k[(0, 0)].signum(),
        k[(1, 1)].signum(),
        k[(2, 2)].signum(),
    ));
    k *= d;
    rot = d * rot;
    (k, rot)
}

fn read_numbers(path: &std::path::Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>())
        .filter(|l| !l.is_empty())
        .collect()
}

/// Ground-truth Model House as a problem: K[R|t] factored from each P (fixed intrinsics).
fn model_house() -> Problem {
    let dir = shared_data("oxford_vgg_model_house");
    let mut cameras = Vec::new();
    let mut intrinsics = Vec::new();
    let mut corners = Vec::new();
    for v in 0..10 {
        let rows = read_numbers(&dir.join(format!("3D/house.{v:03}.P")));
        let p: Vec<f64> = rows.iter().flatten().map(|s| s.parse().unwrap()).collect();
        let mut m = Matrix3::from_fn(|r, c| p[4 * r + c]);
        let mut p4 = Vector3::new(p[3], p[7], p[11]);
        if m.determinant() < 0.0 {
            m = -m;
            p4 = -p4;
        }
        let (k, r) = rq3(&m);
        let t = k.try_inverse().unwrap() * p4;
        let k = k / k[(2, 2)];
        intrinsics.push(Intrinsics {
            model: CameraModel::Pinhole {
                aspect: k[(1, 1)] / k[(0, 0)],
                skew: k[(0, 1)],
            },
            params: [k[(0, 0)], k[(0, 2)], k[(1, 2)], 0.0, 0.0, 0.0, 0.0],
            fixed: true,
            held: [false; super::INTRINSICS],
        });
        cameras.push(CameraPose {
            rotation: matrix_to_angle_axis(&r),
            translation: t,
            intrinsics: v,
            fixed: false,
        });
        corners.push(
            read_numbers(&dir.join(format!("2D/house.{v:03}.corners")))
                .iter()
                .map(|l| Vector2::new(l[0].parse().unwrap(), l[1].parse().unwrap()))
                .collect::<Vec<Vector2<f64>>>(),
        );
    }
    let points: Vec<Point> = read_numbers(&dir.join("3D/house.p3d"))
        .iter()
        .map(|l| Point {
            position: Vector3::new(
                l[0].parse().unwrap(),
                l[1].parse().unwrap(),
                l[2].parse().unwrap(),
            ),
            fixed: false,
        })
        .collect();
    let mut observations = Vec::new();
    for (i, row) in read_numbers(&dir.join("2D/house.nview-corners"))
        .iter()
        .enumerate()
    {
        for (v, e) in row.iter().enumerate() {
            if let Ok(idx) = e.parse::<usize>() {
                observations.push(Observation {
                    camera: v,
                    point: i,
                    pixel: corners[v][idx],
                    weight: 1.0,
                });
            }
        }
    }
    Problem {
        cameras,
        intrinsics,
        points,
        observations,
        gauge: Gauge::FixFirstCameraAndScale,
        priors: Vec::new(),
    }
}

#[test]
fn model_house_recovers_from_perturbation() {
    let truth = model_house();
    assert_eq!(truth.observations.len(), 2846);
    let (gt_rms, _, _) = report::reprojection_errors(&truth);
    let gt_per_coord = gt_rms / 2f64.sqrt();
    eprintln!(
        "ground truth RMS: {gt_rms:.4} px per observation, {gt_per_coord:.4} px per coordinate"
    );
    assert!((gt_rms - 0.625).abs() < 0.01 || (gt_per_coord - 0.625).abs() < 0.01);
    // Perturb poses (except the gauge camera) and points.
    let mut p = truth.clone();
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    use rand::Rng;
    let mut g = |s: f64| {
        Vector3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        )
    };
    let extent = truth
        .points
        .iter()
        .map(|q| q.position.norm())
        .fold(0.0, f64::max);
    for c in p.cameras.iter_mut().skip(1) {
        c.rotation = matrix_to_angle_axis(
            &(angle_axis_to_matrix(&g(0.01)) * angle_axis_to_matrix(&c.rotation)),
        );
        c.translation += g(0.01 * extent);
    }
    for q in p.points.iter_mut() {
        q.position += g(0.01 * extent);
    }
    let before = report::reprojection_errors(&p).0;
    let r = solve(&mut p, &SolverOptions::default()).unwrap();
    let after_per_coord = r.final_rms / 2f64.sqrt();
    eprintln!(
        "model house: RMS {before:.3} -> {:.4} px per observation ({after_per_coord:.4} per coordinate), {} iterations, {:?}",
        r.final_rms, r.iterations, r.termination
    );
    let comparable = if (gt_rms - 0.625).abs() < 0.01 {
        r.final_rms
    } else {
        after_per_coord
    };
    assert!(comparable <= 0.65, "final RMS {comparable}");
    assert!(r.termination.converged());
}

#[test]
fn shared_free_intrinsics_are_recovered() {
    let cfg = VideoConfig {
        cameras: 30,
        points: 600,
        noise_px: 0.5,
        ..VideoConfig::default()
    };
    let s = video_like(&cfg);
    let mut p = s.problem.clone();
    p.intrinsics[0].fixed = false;
    p.intrinsics[0].params[0] *= 1.02;
    let r = solve(
        &mut p,
        &SolverOptions {
            max_iterations: 100,
            ..SolverOptions::default()
        },
    )
    .unwrap();
    let f_err = (p.intrinsics[0].params[0] - cfg.focal).abs() / cfg.focal;
    eprintln!(
        "shared intrinsics: f error {f_err:.2e}, rms {:.4}, {} it",
        r.final_rms, r.iterations
    );
    // f is weakly observable on a short, mostly translating path (focal length / depth
    // ambiguity), so the test checks that the optimum is at least as good as the truth.
    assert!(r.termination.converged());
    assert!(
        r.final_cost <= s.truth.cost(),
        "{} > {}",
        r.final_cost,
        s.truth.cost()
    );
    assert!(f_err < 0.05, "f = {}", p.intrinsics[0].params[0]);
}

#[test]
fn fixed_points_give_resection_and_gauge_component_is_held() {
    let s = video_like(&VideoConfig {
        cameras: 12,
        points: 400,
        ..VideoConfig::default()
    });
    let mut p = s.problem.clone();
    for (q, t) in p.points.iter_mut().zip(&s.truth.points) {
        *q = Point {
            position: t.position,
            fixed: true,
        };
    }
    let masks = p.pose_masks();
    let held = (0..6).find(|&k| masks[1][k]).unwrap();
    let before = p.cameras[1];
    let r = solve(&mut p, &SolverOptions::default()).unwrap();
    assert!(r.termination.converged());
    assert!(r.final_rms < 0.75, "rms {}", r.final_rms);
    assert_eq!(
        p.cameras[1].translation[held - 3],
        before.translation[held - 3]
    );
    assert_ne!(p.cameras[1].rotation, before.rotation);
    for (q, t) in p.points.iter().zip(&s.truth.points) {
        assert_eq!(q.position, t.position);
    }
}

#[test]
fn only_points_free_and_forced_sparse_solver() {
    let s = video_like(&VideoConfig {
        cameras: 8,
        points: 200,
        ..VideoConfig::default()
    });
    let mut p = s.problem.clone();
    for (c, t) in p.cameras.iter_mut().zip(&s.truth.cameras) {
        *c = CameraPose { fixed: true, ..*t };
    }
    for kind in [
        LinearSolverKind::SparseSchur,
        LinearSolverKind::IterativeSchur,
    ] {
        let mut q = p.clone();
        let r = solve(
            &mut q,
            &SolverOptions {
                linear_solver: kind,
                ..SolverOptions::default()
            },
        )
        .unwrap();
        assert_eq!(r.reduced_size, 0);
        assert!(r.termination.converged() && r.final_rms < 0.75, "{r:?}");
        assert_eq!(q.cameras, p.cameras);
    }
    let c = CameraPose::from_rt(
        &s.truth.cameras[3].rotation_matrix(),
        &s.truth.cameras[3].translation,
        0,
    );
    assert!((c.rotation - s.truth.cameras[3].rotation).norm() < 1e-12);
}

/// A zoom as bundle adjustment sees it: a camera travelling and panning past a cloud of points
/// (a dolly alone, or an orbit, would not determine the focal lengths), one free
/// focal length per camera, 900 → 1400 px along the shot, observed with σ = 0.5 px. Returns
/// the problem (started 3 % off the true focal lengths, from perturbed poses and points), the
/// true focal lengths and the true problem with the same observations.
fn zoom_problem(cameras: usize) -> (Problem, Vec<f64>, Problem) {
    use rand::Rng;
    let mut rng = Pcg64Mcg::seed_from_u64(3);
    let mut gauss = move || {
        let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let (cx, cy) = (639.5, 359.5);
    let truth_f: Vec<f64> = (0..cameras)
        .map(|i| 900.0 + 500.0 * i as f64 / (cameras - 1) as f64)
        .collect();
    let mut uniform = {
        let mut rng = Pcg64Mcg::seed_from_u64(4);
        move |lo: f64, hi: f64| rng.random_range(lo..hi)
    };
    // A deep scene (depths 4–20): perspective is what tells the focal length from the depth.
    let points: Vec<Point> = (0..600)
        .map(|_| Point {
            position: Vector3::new(uniform(-9.0, 9.0), uniform(-3.0, 3.0), uniform(-5.0, 10.0)),
            fixed: false,
        })
        .collect();
    let cams: Vec<CameraPose> = (0..cameras)
        .map(|i| {
            let s = i as f64 / (cameras - 1) as f64;
            // A curved path with pan and tilt, optical axes not meeting at one point and
            // centres off any line (an orbit, a dolly or a straight track are critical for a
            // varying focal length: Kahl, Triggs & Åström 2000).
            let tau = std::f64::consts::TAU;
            let centre = Vector3::new(
                -4.0 + 8.0 * s,
                1.5 * (tau * s).sin(),
                -10.0 + 4.0 * (0.5 * tau * s).sin(),
            );
            let omega = Vector3::new(0.15 * (tau * s).cos(), 0.2 - 0.5 * s, 0.05 * s);
            let r = angle_axis_to_matrix(&omega);
            CameraPose::from_rt(&r, &(-(r * centre)), i)
        })
        .collect();
    let mut truth = Problem {
        cameras: cams,
        intrinsics: truth_f
            .iter()
            .map(|&f| Intrinsics::pinhole(f, cx, cy, false))
            .collect(),
        points,
        observations: Vec::new(),
        gauge: Gauge::FixFirstCameraAndScale,
        priors: Vec::new(),
    };
    for c in 0..cameras {
        for p in 0..truth.points.len() {
            let cam = &truth.cameras[c];
            let depth = (cam.rotation_matrix() * truth.points[p].position + cam.translation).z;
            truth.observations.push(Observation {
                camera: c,
                point: p,
                pixel: Vector2::zeros(),
                weight: 1.0,
            });
            let i = truth.observations.len() - 1;
            let q = truth.predict(i);
            if depth < 1.0 || q.x < 0.0 || q.y < 0.0 || q.x > 1279.0 || q.y > 719.0 {
                truth.observations.pop();
                continue;
            }
            truth.observations[i].pixel = q + Vector2::new(gauss(), gauss()) * 0.5;
        }
    }
    let mut problem = truth.clone();
    for (k, f) in problem.intrinsics.iter_mut().zip(&truth_f) {
        k.params[0] = 1.03 * f;
    }
    for c in problem.cameras.iter_mut().skip(1) {
        c.rotation += Vector3::new(gauss(), gauss(), gauss()) * 0.002;
        c.translation += Vector3::new(gauss(), gauss(), gauss()) * 0.02;
    }
    for p in &mut problem.points {
        p.position += Vector3::new(gauss(), gauss(), gauss()) * 0.05;
    }
    (problem, truth_f, truth)
}

/// The smoothness prior of a zoom (the matchmove's, one block per camera).
use crate::problem::zoom_priors as second_differences;

/// A solve with priors stops where the gradient of the whole cost (observations and priors,
/// by finite differences of [`Problem::cost`]) vanishes in every focal length — the priors'
/// residuals, gradients and normal-equation blocks are the ones the cost has — and a smooth
/// zoom is recovered better with the prior than without.
#[test]
fn a_zoom_prior_is_solved_as_part_of_the_cost() {
    let n = 60;
    let (mut free, truth_f, mut truth) = zoom_problem(n);
    truth.priors = second_differences(n, 0.5);
    let mut smooth = free.clone();
    smooth.priors = second_differences(n, 0.5);
    let options = SolverOptions {
        max_iterations: 300,
        function_tolerance: 1e-12,
        ..SolverOptions::default()
    };
    solve(&mut free, &options).unwrap();
    let report = solve(&mut smooth, &options).unwrap();
    // Converged at least as far as the truth's own cost (the noise floor is below it).
    assert!(
        report.final_cost <= truth.cost(),
        "{} vs {}",
        report.final_cost,
        truth.cost()
    );
    let worst = |p: &Problem| {
        p.intrinsics
            .iter()
            .zip(&truth_f)
            .map(|(k, f)| (k.params[0] / f - 1.0).abs())
            .fold(0.0f64, f64::max)
    };
    // Jitter: RMS of the second differences of the focal errors (a smooth zoom has none).
    let jitter = |p: &Problem| {
        let e: Vec<f64> = p
            .intrinsics
            .iter()
            .zip(&truth_f)
            .map(|(k, f)| k.params[0] - f)
            .collect();
        let d2: Vec<f64> = e.windows(3).map(|w| w[0] - 2.0 * w[1] + w[2]).collect();
        (d2.iter().map(|v| v * v).sum::<f64>() / d2.len() as f64).sqrt()
    };
    let (e_free, e_smooth) = (worst(&free), worst(&smooth));
    let (j_free, j_smooth) = (jitter(&free), jitter(&smooth));
    eprintln!(
        "worst focal error: free {e_free:.5}, smooth {e_smooth:.5}; jitter (px): free \
         {j_free:.3}, smooth {j_smooth:.3}"
    );
    assert!(e_smooth < 0.01, "{e_smooth}");
    assert!(j_smooth < 0.2 * j_free, "{j_smooth} vs {j_free}");
    // Stationary: ∂cost/∂fᵢ ≈ 0 against the size of one prior term's gradient.
    for k in 0..n {
        let h = 1e-3;
        let mut p = smooth.clone();
        p.intrinsics[k].params[0] += h;
        let up = p.cost();
        p.intrinsics[k].params[0] -= 2.0 * h;
        let down = p.cost();
        let g = (up - down) / (2.0 * h);
        assert!(g.abs() < 1e-2, "camera {k}: ∂cost/∂f = {g}");
    }
}
