//! Real data with ground truth from `../shared/data` (absent: a notice, or a failure under CI=true):
//! - Oxford VGG "Model House": resect every view from the 3D points and its corners; the
//!   reprojection RMS of the DLT cameras must be within 10 % of the given cameras' 0.625 px.
//! - Oxford VGG "Merton College I": relative pose of every view pair from the VGG matches with the
//!   K of the given cameras; the rotation error against the given R is reported and bounded.

use std::path::PathBuf;

use nalgebra::{Matrix3x4, Point2, Point3};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use vfxgraph_geometry::calibration::{
    calibrate_camera, factor_camera, CalibrationMethod, CalibrationOptions,
};
use vfxgraph_geometry::formats::vgg::{read_nview, read_p_matrix};
use vfxgraph_geometry::formats::{read_points2d, read_points3d};
use vfxgraph_geometry::rotation::rotation_angle_between;
use vfxgraph_geometry::two_view::{reconstruct_two_view, TwoViewOptions};

fn data_dir(name: &str) -> Option<PathBuf> {
    vfxgraph_testdata::path(name)
}

fn reproj(p: &Matrix3x4<f64>, x: &Point3<f64>, u: &Point2<f64>) -> f64 {
    let h = p * x.to_homogeneous();
    ((h.x / h.z - u.x).powi(2) + (h.y / h.z - u.y).powi(2)).sqrt()
}

#[test]
fn model_house_resection_matches_ground_truth_rms() {
    let Some(dir) = data_dir("oxford_vgg_model_house") else {
        return;
    };
    let p3d = read_points3d(&dir.join("3D/house.p3d")).unwrap().0;
    let table = read_nview(&dir.join("2D/house.nview-corners")).unwrap();
    let mut gt_sq = 0.0;
    let mut ours_sq = 0.0;
    let mut dlt_sq = 0.0;
    let mut count = 0usize;
    for v in 0..10 {
        let corners = read_points2d(&dir.join(format!("2D/house.{v:03}.corners")))
            .unwrap()
            .0;
        let p_gt = read_p_matrix(&dir.join(format!("3D/house.{v:03}.P"))).unwrap();
        let (mut x3, mut x2) = (Vec::new(), Vec::new());
        for (i, row) in table.iter().enumerate() {
            if let Some(c) = row[v] {
                x3.push(p3d[i]);
                x2.push(corners[c]);
            }
        }
        let mut rng = Pcg64::seed_from_u64(v as u64);
        let opts = CalibrationOptions {
            method: CalibrationMethod::Restricted,
            ..Default::default()
        };
        let (cam, report) = calibrate_camera(&x3, &x2, &opts, &mut rng).unwrap();
        let dlt_opts = CalibrationOptions {
            method: CalibrationMethod::Dlt,
            ..Default::default()
        };
        let (cam_dlt, dlt_report) = calibrate_camera(&x3, &x2, &dlt_opts, &mut rng).unwrap();
        let gt_view: f64 = x3
            .iter()
            .zip(&x2)
            .map(|(x, u)| reproj(&p_gt, x, u).powi(2))
            .sum();
        let gt_cam = factor_camera(&p_gt).unwrap();
        let rot = rotation_angle_between(&cam.pose.r, &gt_cam.pose.r).to_degrees();
        let centre = (cam.center() - gt_cam.center()).norm();
        println!(
            "house view {v}: {} points, RMS ours (restricted) {:.3} px, ours (DLT) {:.3} px, GT {:.3} px; \
             f {:.1}/{:.1} vs GT {:.1}/{:.1} (GT skew {:.2}, DLT skew {:.2}) {:?}; rotation diff {rot:.3}°, centre diff {centre:.4}",
            x3.len(),
            report.rms,
            dlt_report.rms,
            (gt_view / x3.len() as f64).sqrt(),
            cam.intrinsics.f1,
            cam.intrinsics.f2,
            gt_cam.intrinsics.f1,
            gt_cam.intrinsics.f2,
            gt_cam.intrinsics.s,
            cam_dlt.intrinsics.s,
            report.lm
        );
        assert!(cam_dlt.intrinsics.f1 > 0.0);
        gt_sq += gt_view;
        ours_sq += report.rms.powi(2) * x3.len() as f64;
        dlt_sq += dlt_report.rms.powi(2) * x3.len() as f64;
        count += x3.len();
    }
    let (gt, ours, dlt) = (
        (gt_sq / count as f64).sqrt(),
        (ours_sq / count as f64).sqrt(),
        (dlt_sq / count as f64).sqrt(),
    );
    println!("house: {count} observations, RMS ours (restricted) {ours:.4} px, ours (DLT) {dlt:.4} px, GT {gt:.4} px");
    assert_eq!(count, 2846);
    assert!((gt - 0.625).abs() < 0.001, "GT RMS {gt}");
    // The given P are general projective cameras (views 7–9 have skew −8 to −26 px), so the
    // comparison is with our projective resection (normalized DLT, 11 dof). The zero-skew
    // restricted calibration (10 dof) cannot reach their figure on those views and is reported only.
    assert!((dlt - gt).abs() <= 0.1 * gt, "ours {dlt} vs GT {gt}");
    assert!(ours < 1.0, "restricted {ours}");
}

#[test]
fn merton_college_relative_pose() {
    let Some(dir) = data_dir("oxford_vgg_merton_college_I") else {
        return;
    };
    let table = read_nview(&dir.join("2D/nview-corners")).unwrap();
    let corners: Vec<Vec<Point2<f64>>> = (1..=3)
        .map(|v| {
            read_points2d(&dir.join(format!("2D/{v:03}.corners")))
                .unwrap()
                .0
        })
        .collect();
    let cams: Vec<_> = (1..=3)
        .map(|v| factor_camera(&read_p_matrix(&dir.join(format!("2D/{v:03}.P"))).unwrap()).unwrap())
        .collect();
    for (va, vb) in [(0, 1), (1, 2), (0, 2)] {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for row in &table {
            if let (Some(i), Some(j)) = (row[va], row[vb]) {
                a.push(corners[va][i]);
                b.push(corners[vb][j]);
            }
        }
        let (ka, kb) = (&cams[va].intrinsics, &cams[vb].intrinsics);
        let rec = reconstruct_two_view(
            &a,
            &b,
            ka,
            kb,
            &TwoViewOptions::default(),
            &mut Pcg64::seed_from_u64(1),
        )
        .unwrap();
        let gt_rel = cams[vb].pose.relative_to(&cams[va].pose);
        let rot = rotation_angle_between(&rec.camera_b.pose.r, &gt_rel.r).to_degrees();
        let t_angle = (rec.camera_b.pose.t.dot(&gt_rel.t) / gt_rel.t.norm())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        println!(
            "merton {}-{}: {} matches, {} inliers, rotation error {rot:.4}°, t direction error {t_angle:.3}°, \
             reprojection RMS {:.3} px, median parallax {:.2}°",
            va + 1,
            vb + 1,
            a.len(),
            rec.report.num_inliers,
            rec.report.reprojection_rms,
            rec.report.median_parallax_deg
        );
        assert!(rot < 0.5, "rotation error {rot}°");
        assert!(t_angle < 5.0, "translation direction error {t_angle}°");
    }
}

/// The book's HDR-camera calibration (§10.8) on the library level: the six points marked on the
/// HDR photograph (`book-demo/calib_projs.txt`) with a synthetic 3D set (the real one comes from
/// the point-cloud calibration of a later issue) built by back-projecting them from a known
/// camera at known depths. The calibration must give that camera back.
#[test]
fn book_demo_hdr_camera_from_calib_projs() {
    let Some(file) = data_dir("book-demo/calib_projs.txt") else {
        return;
    };
    let projs = read_points2d(&file).unwrap().0;
    assert_eq!(projs.len(), 6);
    let k = vfxgraph_geometry::Intrinsics::new(3100.0, 3100.0, 2000.0, 1500.0);
    let r = vfxgraph_geometry::rotation::axis_angle_to_r(&nalgebra::Vector3::new(0.1, -0.4, 0.05));
    let truth =
        vfxgraph_geometry::Camera::new(k.clone(), r, nalgebra::Vector3::new(0.2, -0.1, 3.0));
    let inv = truth.pose.inverse();
    let depths = [4.0, 6.5, 5.0, 8.0, 3.5, 7.0];
    let pts: Vec<Point3<f64>> = projs
        .iter()
        .zip(depths)
        .map(|(x, d)| Point3::from(inv.transform(&Point3::from(k.unproject(x) * d))))
        .collect();
    let opts = CalibrationOptions {
        method: CalibrationMethod::Restricted,
        ..Default::default()
    };
    let (cam, report) =
        calibrate_camera(&pts, &projs, &opts, &mut Pcg64::seed_from_u64(0)).unwrap();
    println!(
        "book demo HDR camera: RMS {:.2e} px, f {:.3}",
        report.rms, cam.intrinsics.f1
    );
    assert!(report.rms < 1e-6);
    assert!((cam.intrinsics.f1 - 3100.0).abs() < 1e-4 && (cam.intrinsics.u0 - 2000.0).abs() < 1e-4);
    assert!(rotation_angle_between(&cam.pose.r, &r) < 1e-8);
    // The dome orientation of §10.8 reads rows of R: south = R₂, orig = −R₃.
    let south = cam.pose.r.row(1).transpose();
    assert!((south - r.row(1).transpose()).norm() < 1e-8);
}

/// The lens model's convention against a lens another program applied: the four ground marks of
/// `blender_plate_dev` (clicked to the nearest pixel on frames 12, 24, 36, 47 of both versions of
/// the plate), projected from their true 3-D points with the renderer's cameras — through the
/// published Brown–Conrady lens (OpenCV's k1, k2, p1, p2 on normalized coordinates) for
/// `distorted/`, as an ideal pinhole for `pinhole/`. Each must land within rounding (√2/2 px) of
/// its click; projecting the distorted marks *without* the lens misses them by pixels (the test
/// can tell the two apart).
#[test]
fn the_lens_model_reproduces_the_blender_plates_distorted_marks() {
    use vfxgraph_geometry::formats::{read_json, read_marked_points, CameraPath};
    use vfxgraph_geometry::lens::Distortion;
    let (Some(pin), Some(dis)) = (
        vfxgraph_testdata::paths([
            "blender_plate_dev/pinhole/marks.txt",
            "blender_plate_dev/pinhole/cameras_gt.json",
        ]),
        vfxgraph_testdata::paths([
            "blender_plate_dev/distorted/marks.txt",
            "blender_plate_dev/distorted/cameras_gt.json",
        ]),
    ) else {
        return;
    };
    let marks3d = [
        [-0.6, -0.6, 0.0],
        [0.6, -0.6, 0.0],
        [0.6, 0.6, 0.0],
        [-0.6, 0.6, 0.0],
    ];
    let (f, cx, cy) = (920.0, 479.5, 269.5);
    let lens = Distortion::BrownConrady {
        k1: -0.16,
        k2: 0.045,
        k3: 0.0,
        p1: 0.0008,
        p2: -0.0005,
    };
    lens.check((479.5f64.hypot(269.5)) / f).unwrap();
    let worst = |files: &[PathBuf; 2], d: &Distortion| {
        let marks = read_marked_points(&files[0]).unwrap();
        let cams: CameraPath = read_json(&files[1]).unwrap();
        let mut worst = 0.0f64;
        for m in &marks.frames {
            let pose = &cams
                .frames
                .iter()
                .find(|c| c.frame == m.frame)
                .unwrap()
                .pose;
            for (x, clicked) in marks3d.iter().zip(&m.points.0) {
                let c = pose.r * nalgebra::Vector3::from(*x) + pose.t;
                let q = d.distort([c.x / c.z, c.y / c.z]).unwrap();
                let (u, v) = (f * q[0] + cx, f * q[1] + cy);
                worst = worst.max((u - clicked.x).hypot(v - clicked.y));
            }
        }
        worst
    };
    let (w_pin, w_dis, w_dis_as_pinhole) = (
        worst(&pin, &Distortion::None),
        worst(&dis, &lens),
        worst(&dis, &Distortion::None),
    );
    eprintln!(
        "marks vs projections: pinhole {w_pin:.3} px, distorted through the lens {w_dis:.3} px, \
         distorted as a pinhole {w_dis_as_pinhole:.1} px"
    );
    assert!(w_pin <= std::f64::consts::FRAC_1_SQRT_2, "{w_pin}");
    assert!(w_dis <= std::f64::consts::FRAC_1_SQRT_2, "{w_dis}");
    assert!(w_dis_as_pinhole > 3.0, "{w_dis_as_pinhole}");
}
