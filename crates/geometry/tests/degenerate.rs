//! Degenerate input gives a typed error, never NaN and never a panic: too few points,
//! coplanar 3D points for the DLT, points at infinity, zero baseline, repeated and collinear
//! points, non-finite coordinates.

use nalgebra::{Matrix3, Matrix3x4, Point2, Point3, Vector3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_geometry::calibration::{
    calibrate_camera, calibrate_restricted, dlt, factor_camera, resect_known_k, resect_ransac,
    tsai, CalibrationMethod, CalibrationOptions,
};
use vfxgraph_geometry::optimize::LmOptions;
use vfxgraph_geometry::ransac::RansacParams;
use vfxgraph_geometry::synthetic::two_view_scene_with;
use vfxgraph_geometry::synthetic::{observe, random_camera, random_points_in_frustum};
use vfxgraph_geometry::two_view::{
    decompose_essential, fundamental_8point, reconstruct_two_view, triangulate_linear,
    TwoViewOptions,
};
use vfxgraph_geometry::{Camera, Intrinsics, VisionError};

fn finite_camera(c: &Camera) -> bool {
    c.p_matrix().iter().all(|v| v.is_finite())
}

#[test]
fn one_camera_degenerate_inputs() {
    let mut rng = Pcg64::seed_from_u64(1);
    let cam = random_camera(&mut rng);
    let pts = random_points_in_frustum(&cam, 40, 2.0, 10.0, &mut rng);
    let (obs, _) = observe(&cam, &pts, 0.5, 0.0, &mut rng);
    let lm = LmOptions::default();
    // Fewer than 6 matches.
    for n in 0..6 {
        assert!(matches!(
            dlt(&pts[..n], &obs[..n]),
            Err(VisionError::TooFewPoints { needed: 6, .. })
        ));
        assert!(matches!(
            calibrate_restricted(&pts[..n], &obs[..n], &lm),
            Err(VisionError::TooFewPoints { .. })
        ));
        let opts = CalibrationOptions::default();
        assert!(matches!(
            calibrate_camera(&pts[..n], &obs[..n], &opts, &mut rng),
            Err(VisionError::TooFewPoints { .. })
        ));
        assert!(resect_ransac(&pts[..n], &obs[..n], &RansacParams::default(), &mut rng).is_err());
    }
    // All 3D points coplanar (a plane in general position, not only z = 0).
    let n = Vector3::new(0.3, -0.2, 1.0).normalize();
    let planar: Vec<Point3<f64>> = pts
        .iter()
        .map(|p| p - n * (n.dot(&p.coords) - 5.0))
        .collect();
    let pproj: Vec<Point2<f64>> = planar.iter().map(|p| cam.project(p).unwrap()).collect();
    assert!(matches!(
        dlt(&planar, &pproj),
        Err(VisionError::Degenerate(_))
    ));
    assert!(matches!(
        calibrate_restricted(&planar, &pproj, &lm),
        Err(VisionError::Degenerate(_))
    ));
    // Collinear and repeated points.
    let line: Vec<Point3<f64>> = (0..10)
        .map(|i| Point3::new(i as f64, 2.0 * i as f64, 1.0 + i as f64))
        .collect();
    assert!(dlt(&line, &obs[..10]).is_err());
    let same = vec![pts[0]; 10];
    assert!(dlt(&same, &obs[..10]).is_err());
    let same2 = vec![obs[0]; 10];
    assert!(dlt(&pts[..10], &same2).is_err());
    // Points at infinity / non-finite coordinates.
    let mut inf = pts.clone();
    inf[3] = Point3::new(f64::INFINITY, 0.0, 1.0);
    assert!(matches!(dlt(&inf, &obs), Err(VisionError::InvalidInput(_))));
    let mut nan = obs.clone();
    nan[5] = Point2::new(f64::NAN, 1.0);
    assert!(matches!(
        calibrate_restricted(&pts, &nan, &lm),
        Err(VisionError::InvalidInput(_))
    ));
    // A camera matrix at infinity (zero third row) cannot be factored.
    let mut p = cam.p_matrix();
    p.row_mut(2).fill(0.0);
    assert!(matches!(factor_camera(&p), Err(VisionError::Degenerate(_))));
    assert!(factor_camera(&Matrix3x4::repeat(f64::NAN)).is_err());
    // Tsai: off-plane, too few and collinear targets.
    let pp = Point2::new(cam.intrinsics.u0, cam.intrinsics.v0);
    assert!(tsai(&pts, &obs, pp).is_err());
    assert!(matches!(
        tsai(&planar[..5], &pproj[..5], pp),
        Err(VisionError::TooFewPoints { .. })
    ));
    let opts = CalibrationOptions {
        method: CalibrationMethod::Tsai,
        principal_point: None,
        ..Default::default()
    };
    assert!(calibrate_camera(&pts, &obs, &opts, &mut rng).is_err());
    // Pure noise: RANSAC either fails with a typed error or returns finite numbers.
    let noise: Vec<Point2<f64>> = (0..40)
        .map(|i| Point2::new((i * 37 % 1280) as f64, (i * 91 % 720) as f64))
        .collect();
    if let Ok(r) = resect_known_k(
        &pts,
        &noise,
        &cam.intrinsics,
        &RansacParams::with_threshold(1.0),
        &mut rng,
    ) {
        assert!(finite_camera(&r.camera));
    }
    let opts = CalibrationOptions {
        ransac: Some(RansacParams::with_threshold(1.0)),
        ..Default::default()
    };
    if let Ok((c, rep)) = calibrate_camera(&pts, &noise, &opts, &mut rng) {
        assert!(finite_camera(&c) && rep.rms.is_finite());
    }
}

#[test]
fn two_view_degenerate_inputs() {
    let mut rng = Pcg64::seed_from_u64(2);
    let s = two_view_scene_with(&mut rng, 60, 0.5, 0.0, 1.0);
    let opts = TwoViewOptions::default();
    for n in 0..8 {
        assert!(matches!(
            fundamental_8point(&s.a[..n], &s.b[..n]),
            Err(VisionError::TooFewPoints { needed: 8, .. })
        ));
        assert!(matches!(
            reconstruct_two_view(&s.a[..n], &s.b[..n], &s.k, &s.k, &opts, &mut rng),
            Err(VisionError::TooFewPoints { needed: 8, .. })
        ));
    }
    // Zero baseline (pure rotation), with and without noise and with outliers.
    for (sigma, outliers) in [(0.0, 0.0), (0.5, 0.0), (0.5, 0.3)] {
        let z = two_view_scene_with(&mut rng, 100, sigma, outliers, 0.0);
        let e = reconstruct_two_view(&z.a, &z.b, &z.k, &z.k, &opts, &mut rng);
        assert!(
            matches!(e, Err(VisionError::ZeroBaseline)),
            "sigma {sigma} outliers {outliers}: {e:?}"
        );
    }
    // A planar scene seen with a baseline: F is not determined, H explains every match.
    let cam_a = s.camera_a();
    let cam_b = s.camera_b();
    let plane: Vec<Point3<f64>> =
        s.a.iter()
            .map(|x| Point3::from(s.k.unproject(x) * 6.0))
            .filter(|p| vfxgraph_geometry::synthetic::visible(&cam_b, p))
            .collect();
    assert!(plane.len() >= 20);
    let (pa, _) = observe(&cam_a, &plane, 0.3, 0.0, &mut rng);
    let (pb, _) = observe(&cam_b, &plane, 0.3, 0.0, &mut rng);
    let e = reconstruct_two_view(&pa, &pb, &s.k, &s.k, &opts, &mut rng);
    assert!(matches!(e, Err(VisionError::Degenerate(_))), "{e:?}");
    // Identical images (no motion at all): also a zero baseline.
    let e = reconstruct_two_view(&s.a, &s.a, &s.k, &s.k, &opts, &mut rng);
    assert!(matches!(e, Err(VisionError::ZeroBaseline)), "{e:?}");
    // Non-finite input.
    let mut bad = s.a.clone();
    bad[0].y = f64::INFINITY;
    assert!(matches!(
        reconstruct_two_view(&bad, &s.b, &s.k, &s.k, &opts, &mut rng),
        Err(VisionError::InvalidInput(_))
    ));
    // Random matches: typed error or finite output.
    let noise: Vec<Point2<f64>> = (0..60)
        .map(|i| Point2::new((i * 37 % 1280) as f64, (i * 91 % 720) as f64))
        .collect();
    if let Ok(r) = reconstruct_two_view(&s.a, &noise, &s.k, &s.k, &opts, &mut rng) {
        assert!(finite_camera(&r.camera_b));
        assert!(r
            .points3d
            .0
            .iter()
            .all(|p| p.coords.iter().all(|v| v.is_finite())));
    }
    // Triangulation of parallel rays: a point at infinity.
    let k = Intrinsics::new(1000.0, 1000.0, 640.0, 360.0);
    let ca = Camera::new(k.clone(), Matrix3::identity(), Vector3::zeros());
    let cb = Camera::new(k, Matrix3::identity(), Vector3::new(-1.0, 0.0, 0.0));
    let x = Point2::new(700.0, 400.0);
    assert!(matches!(
        triangulate_linear(&ca.p_matrix(), &cb.p_matrix(), &x, &x),
        Err(VisionError::PointsAtInfinity)
    ));
    assert!(decompose_essential(&Matrix3::zeros()).is_err());
    // Invalid intrinsics.
    let bad_k = Intrinsics::new(0.0, 1000.0, 640.0, 360.0);
    assert!(matches!(
        reconstruct_two_view(&s.a, &s.b, &bad_k, &s.k, &opts, &mut rng),
        Err(VisionError::InvalidInput(_))
    ));
    let nan_k = Intrinsics::new(f64::NAN, 1000.0, 640.0, 360.0);
    assert!(matches!(
        reconstruct_two_view(&s.a, &s.b, &s.k, &nan_k, &opts, &mut rng),
        Err(VisionError::InvalidInput(_))
    ));
}
