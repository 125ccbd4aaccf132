//! Real footage with the defaults (the real-cameras issue's "defaults survive real noise"):
//! `graphs/dev_plate_solve.yaml` tracks and solves the Blender Cycles plate of
//! `../shared/data/blender_plate_dev/pinhole` (48 frames, 960×540, render grain of σ ≈ 10 gray
//! levels) with K known and **no parameter set**, and the cameras are checked against the
//! renderer's own (`cameras_gt.json`) after the similarity that aligns a solve with the truth.
//!
//! Measured (release, this commit): every frame solved, rotation max 0.066°, centre max
//! 0.24 % of the 1.38 m path. Before the noise-adaptive defaults the same graph kept 3 of 150
//! features by frame 8 and failed. Bounds: the issue's < 0.1° and 0.45 % (within 2× of the
//! figures).

mod common;

use vfxgraph_vision::formats::{read_json, CameraPath};

const ROTATION_BOUND_DEG: f64 = 0.1;
const CENTRE_BOUND: f64 = 0.0045;

#[test]
fn the_default_graph_solves_the_grainy_blender_plate() {
    let tmp = tempfile::tempdir().unwrap();
    let graph =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/dev_plate_solve.yaml");
    let Some(g) = vfxgraph_testdata::graph_with_data(&graph, tmp.path()) else {
        return;
    };
    let truth_file = vfxgraph_testdata::require("blender_plate_dev/pinhole/cameras_gt.json");
    let dir = g.parent().unwrap();
    let nodes = common::run_json(dir, &[g.to_str().unwrap()]);
    assert!(nodes.iter().all(|n| n["status"] == "ran"), "{nodes:?}");
    let solved: CameraPath = read_json(&dir.join("out/dev_plate_solve/cameras.json")).unwrap();
    // The truth file carries more per frame (C) and a K matrix; `frames` reads as a camera path.
    let truth: CameraPath = read_json(&truth_file).unwrap();
    let frames = |p: &CameraPath| p.frames.iter().map(|f| f.frame).collect::<Vec<_>>();
    assert_eq!(
        frames(&solved),
        (0..48).collect::<Vec<_>>(),
        "every frame solved"
    );
    assert_eq!(frames(&truth), frames(&solved));
    let (_, rot, cen) = common::aligned_errors(&solved, &truth);
    let (max_rot, max_cen, length) = common::worst_path_errors(&rot, &cen, &truth);
    eprintln!(
        "blender_plate_dev/pinhole with the defaults: rotation max {max_rot:.4}°, centre max \
         {:.3} % of the {length:.2} m path",
        100.0 * max_cen
    );
    assert!(max_rot < ROTATION_BOUND_DEG, "rotation errors (°): {rot:?}");
    assert!(max_cen < CENTRE_BOUND, "centre errors (m): {cen:?}");
}

/// Real cameras with an unknown lens (the real-cameras issue): `graphs/dev_plate_lens.yaml`
/// solves the distorted version of the plate from its tracks and the image size alone
/// (`focal: unknown, distortion: k1k2`), against the renderer's cameras and lens (f = 920 px,
/// k1 = −0.16).
///
/// Measured (this commit, 150 features): focal 908.9 px (−1.2 %), k1 −0.203, rotation max
/// 0.29°, centre max 0.49 % of the path — the same tracks solved as a pinhole with the true K
/// reach 0.56°. With 600 features: focal 919.6 px, k1 −0.183, 0.150°, 0.149 %. The goals
/// (focal 0.5 %, k1 0.01, 0.1°, 0.5 %) are not met yet: the tangential terms and the principal
/// point are not solved. Bounds within 2× of the measured figures.
#[test]
fn an_unknown_lens_is_solved_from_the_distorted_plate() {
    let tmp = tempfile::tempdir().unwrap();
    let graph = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/dev_plate_lens.yaml");
    let Some(g) = vfxgraph_testdata::graph_with_data(&graph, tmp.path()) else {
        return;
    };
    let truth_file = vfxgraph_testdata::require("blender_plate_dev/distorted/cameras_gt.json");
    let dir = g.parent().unwrap();
    let nodes = common::run_json(dir, &[g.to_str().unwrap()]);
    assert!(nodes.iter().all(|n| n["status"] == "ran"), "{nodes:?}");
    let solved: CameraPath = read_json(&dir.join("out/dev_plate_lens/cameras.json")).unwrap();
    let truth: CameraPath = read_json(&truth_file).unwrap();
    assert_eq!(solved.frames.len(), 48, "every frame solved");
    let k = solved.intrinsics.clone().expect("the solved lens");
    let vfxgraph_vision::lens::Distortion::BrownConrady { k1, k2, .. } = k.distortion else {
        panic!("solved lens {:?}", k.distortion)
    };
    let (_, rot, cen) = common::aligned_errors(&solved, &truth);
    let (max_rot, max_cen, length) = common::worst_path_errors(&rot, &cen, &truth);
    let f_err = k.f1 / 920.0 - 1.0;
    eprintln!(
        "blender_plate_dev/distorted, unknown lens: focal {:.2} px ({:+.2} %), k1 {k1:.4}, k2 \
         {k2:.4}, rotation max {max_rot:.4}°, centre max {:.3} % of the {length:.2} m path",
        k.f1,
        100.0 * f_err,
        100.0 * max_cen
    );
    assert!(f_err.abs() < 0.024, "focal {}", k.f1);
    assert!((k1 + 0.16).abs() < 0.086, "k1 {k1}");
    assert!(max_rot < 0.59, "rotation errors (°): {rot:?}");
    assert!(max_cen < 0.0098, "centre errors (m): {cen:?}");
}
