//! Our ST-maps in another program: OpenCV's `remap` applies the undistort ST-map to a
//! frame of `blender_plate_dev/distorted` (Cycles' render seen through its Brown–Conrady lens)
//! and must reproduce our `undistort` of it within 0.5 % of the image's range (the goal; the test
//! holds it to 0.01 %)
//! (scripts/check/st_map_remap.py; measured: max 0.0027 %, RMS 0.00007 %).
//!
//! The Python comes from `VFXGRAPH_PYTHON_CV` (default `python3`), with opencv-python(-headless)
//! and numpy. Without `cv2` the test prints a notice and passes, unless
//! `VFXGRAPH_REQUIRE_CLIENTS=1` (set by `.ci/run`), where it fails — as the export clients do.

use std::path::{Path, PathBuf};
use std::process::Command;

use vfxgraph_geometry::lens::Distortion;
use vfxgraph_geometry::st_map::{st_map, StMapDirection};
use vfxgraph_geometry::undistort::{LensWarp, UndistortOptions};
use vfxgraph_geometry::Intrinsics;
use vfxgraph_imaging::io::{read_image, write_image};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn python() -> String {
    std::env::var("VFXGRAPH_PYTHON_CV").unwrap_or_else(|_| "python3".into())
}

/// True when OpenCV imports; otherwise a notice (or a failure when clients are required).
fn have_cv() -> bool {
    let ok = Command::new(python())
        .args(["-c", "import cv2, numpy"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        let msg = format!(
            "python module `cv2` not found with `{}` (pip install opencv-python-headless, or set \
             VFXGRAPH_PYTHON_CV)",
            python()
        );
        if std::env::var("VFXGRAPH_REQUIRE_CLIENTS").is_ok_and(|v| v == "1") {
            panic!("{msg}");
        }
        eprintln!("skipping: {msg}");
    }
    ok
}

/// The lens of `distorted/cameras_gt.json` (K and the Brown–Conrady coefficients it lists).
fn truth_lens(json: &Path) -> Intrinsics {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let k = &v["K"];
    let d = &v["distortion"];
    let f = |x: &serde_json::Value| x.as_f64().unwrap();
    Intrinsics::new(f(&k[0][0]), f(&k[1][1]), f(&k[0][2]), f(&k[1][2]))
        .with_size(
            v["width"].as_u64().unwrap() as u32,
            v["height"].as_u64().unwrap() as u32,
        )
        .with_distortion(Distortion::BrownConrady {
            k1: f(&d["k1"]),
            k2: f(&d["k2"]),
            k3: 0.0,
            p1: f(&d["p1"]),
            p2: f(&d["p2"]),
        })
}

#[test]
fn opencv_remap_of_our_st_map_is_our_undistort() {
    let Some([plate_path, cams]) = vfxgraph_testdata::paths([
        "blender_plate_dev/distorted/plate_linear/frame.0024.exr",
        "blender_plate_dev/distorted/cameras_gt.json",
    ]) else {
        return;
    };
    if !have_cv() {
        return;
    }
    let lens = truth_lens(&cams);
    let warp = LensWarp::new(&lens, &UndistortOptions::default()).unwrap();
    let plate = read_image(&plate_path).unwrap().to_rgb();
    let ours = warp.undistort(&plate).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // The ST-map as write_st_map writes it (float EXR), read back exactly.
    let map = st_map(&warp, StMapDirection::Undistort);
    let exr = dir.path().join("st_undistort.exr");
    write_image(&exr, &map).unwrap();
    assert!(
        read_image(&exr).unwrap() == map,
        "the ST-map EXR does not read back exactly"
    );
    // OpenCV's wheels have no OpenEXR codec: the same f32 values as PFM.
    let (p, m, o) = (
        dir.path().join("plate.pfm"),
        dir.path().join("st_undistort.pfm"),
        dir.path().join("ours.pfm"),
    );
    write_image(&p, &plate).unwrap();
    write_image(&m, &map).unwrap();
    write_image(&o, &ours).unwrap();
    let out = Command::new(python())
        .arg(repo().join("scripts/check/st_map_remap.py"))
        .args([&p, &m, &o])
        .args(["--tolerance", "0.0001"])
        .output()
        .expect("run python");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!("{text}");
    assert!(out.status.success(), "st_map_remap.py failed:\n{text}");
}
