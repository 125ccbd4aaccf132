//! Helpers shared by the end-to-end tests of the `vfxgraph` binary: running the CLI, copying
//! the example graphs into a scratch folder, reading a measured-points report.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value as Json;

/// Runs `vfxgraph ARGS…` in `dir`.
pub fn vfx(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

/// `vfxgraph run --json ARGS…` in `dir`, which must succeed; its node entries.
pub fn run_json(dir: &Path, args: &[&str]) -> Vec<Json> {
    let mut a = vec!["run", "--json"];
    a.extend_from_slice(args);
    let out = vfx(dir, &a);
    assert!(
        out.status.success(),
        "vfxgraph {a:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).expect("json on stdout");
    v["nodes"].as_array().unwrap().clone()
}

/// The ids of the nodes with at least one instance of `status` in a `run_json` result.
pub fn nodes_with(nodes: &[Json], status: &str) -> BTreeSet<String> {
    nodes
        .iter()
        .filter(|n| n["status"] == status)
        .map(|n| n["id"].as_str().unwrap().to_string())
        .collect()
}

/// A solved camera path against the true one after the similarity that best aligns them (a
/// solve is defined up to one): the similarity, each frame's rotation error (°) and camera-centre
/// error (true units).
pub fn aligned_errors(
    solved: &vfxgraph_geometry::formats::CameraPath,
    truth: &vfxgraph_geometry::formats::CameraPath,
) -> (
    vfxgraph_geometry::camera_path::Similarity,
    Vec<f64>,
    Vec<f64>,
) {
    let poses = |p: &vfxgraph_geometry::formats::CameraPath| {
        p.frames.iter().map(|f| f.pose.clone()).collect::<Vec<_>>()
    };
    vfxgraph_geometry::camera_path::aligned_pose_errors(&poses(solved), &poses(truth)).unwrap()
}

/// The worst errors of [`aligned_errors`]: rotation (°) and camera centre as a fraction of the
/// true path's length, with that length (true units).
pub fn worst_path_errors(
    rot: &[f64],
    cen: &[f64],
    truth: &vfxgraph_geometry::formats::CameraPath,
) -> (f64, f64, f64) {
    let centres: Vec<nalgebra::Point3<f64>> =
        truth.frames.iter().map(|f| f.pose.center()).collect();
    let length: f64 = centres.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    let max_rot = rot.iter().cloned().fold(0.0, f64::max);
    let max_cen = cen.iter().cloned().fold(0.0, f64::max) / length;
    (max_rot, max_cen, length)
}

/// The 3-D points of a `point_cloud_calibrate` report (`points`), mapped by `sim` (e.g. into
/// the truth's frame).
pub fn aligned_points(
    report: &Path,
    sim: &vfxgraph_geometry::camera_path::Similarity,
) -> Vec<nalgebra::Point3<f64>> {
    let text = std::fs::read_to_string(report).unwrap();
    let j: Json = serde_json::from_str(&text).unwrap();
    j["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let v: Vec<f64> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            sim.apply(&nalgebra::Point3::new(v[0], v[1], v[2]))
        })
        .collect()
}

/// Copies a folder recursively, leaving out caches (`.vfxgraph`) and outputs (`out`).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let name = e.file_name();
        if name == ".vfxgraph" || name == "out" {
            continue;
        }
        if e.path().is_dir() {
            copy_dir(&e.path(), &to.join(&name));
        } else {
            std::fs::copy(e.path(), to.join(&name)).unwrap();
        }
    }
}

/// The repo's `graphs/` copied into `dir/graphs` (returned).
pub fn scratch_graphs(dir: &Path) -> std::path::PathBuf {
    let g = dir.join("graphs");
    copy_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs"), &g);
    g
}

/// `graphs/farm_shot.yaml` with its scene and dome copied into `dir/g/` (the render-farm
/// tests' small shot); the copied graph's path.
pub fn farm_shot_copy(dir: &Path) -> std::path::PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::create_dir_all(dir.join("g/scenes")).unwrap();
    std::fs::create_dir_all(dir.join("g/data")).unwrap();
    for f in ["plate.yaml", "cube.obj"] {
        std::fs::copy(
            repo.join("graphs/scenes").join(f),
            dir.join("g/scenes").join(f),
        )
        .unwrap();
    }
    std::fs::copy(
        repo.join("graphs/data/studio_small_03_1k.hdr"),
        dir.join("g/data/studio_small_03_1k.hdr"),
    )
    .unwrap();
    let g = dir.join("g/farm_shot.yaml");
    std::fs::copy(repo.join("graphs/farm_shot.yaml"), &g).unwrap();
    g
}
