//! The images of an exposure stack are part of `read_exposure_stack`'s cache key:
//! editing one listed image in place — the list file untouched — reruns the reader and its
//! dependants, for the `list` form (images declared at run time) and the `paths` form (a
//! path-list param). Through the `vfxgraph` binary.

use std::fs;
use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;
use vfxgraph_imaging::color::srgb8_to_linear;
use vfxgraph_imaging::Image;

fn run(dir: &Path, args: &[&str]) -> (bool, Vec<Json>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(dir)
        .args(["run", "--json"])
        .args(args)
        .output()
        .unwrap();
    let v: Json = serde_json::from_slice(&out.stdout).unwrap_or(Json::Null);
    let nodes = v["nodes"].as_array().cloned().unwrap_or_default();
    (
        out.status.success(),
        nodes,
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn status<'a>(nodes: &'a [Json], id: &str) -> &'a str {
    nodes
        .iter()
        .find(|n| n["id"] == id)
        .and_then(|n| n["status"].as_str())
        .unwrap_or("absent")
}

/// Exposure `k` of a gamma-2 camera looking at a horizontal ramp; `gain` brightens the scene.
fn write_exposure(dir: &Path, k: usize, time: f64, gain: f64) {
    let img = Image::from_fn(48, 16, 3, |x, y, c| {
        let e = gain * 0.02 * 1.09f64.powi(x as i32) * (1.0 + 0.01 * y as f64) * [1.0, 0.8, 0.6][c];
        srgb8_to_linear((255.0 * (e * time).min(1.0).sqrt()).round() as u8)
    });
    vfxgraph_imaging::write_image(&dir.join(format!("e{k}.png")), &img).unwrap();
}

const GRAPH: &str = "version: 1
nodes:
  from_list: {type: read_exposure_stack, params: {list: stack/list.txt}}
  from_paths:
    type: read_exposure_stack
    params: {paths: [stack/e0.png, stack/e1.png, stack/e2.png], times: [0.25, 1, 4]}
  curve: {type: hdr_calibrate, inputs: {stack: from_list.stack}, params: {samples: 200}}
  merged: {type: hdr_merge, inputs: {stack: from_list.stack, response: curve.response}}
  exr: {type: write_image, inputs: {image: merged.image}, params: {path: out/list.exr}}
  curve2: {type: hdr_calibrate, inputs: {stack: from_paths.stack}, params: {samples: 150}}
  merged2: {type: hdr_merge, inputs: {stack: from_paths.stack, response: curve2.response}}
  exr2: {type: write_image, inputs: {image: merged2.image}, params: {path: out/paths.exr}}
";

#[test]
fn editing_one_listed_image_reruns_the_reader_and_its_dependants() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    fs::create_dir_all(d.join("stack")).unwrap();
    for (k, t) in [0.25, 1.0, 4.0].iter().enumerate() {
        write_exposure(&d.join("stack"), k, *t, 1.0);
    }
    fs::write(
        d.join("stack/list.txt"),
        "3\ne0.png 1/4\ne1.png 1\ne2.png 4\n",
    )
    .unwrap();
    fs::write(d.join("g.yaml"), GRAPH).unwrap();
    let (ok, r, err) = run(d, &["g.yaml"]);
    assert!(ok, "{err}");
    assert!(r.iter().all(|n| n["status"] == "ran"), "{r:?}");
    let (_, r, _) = run(d, &["g.yaml"]);
    assert!(r.iter().all(|n| n["status"] == "cached"), "{r:?}");
    let before = fs::read(d.join("out/list.exr")).unwrap();

    // New content in one image, the list file untouched.
    write_exposure(&d.join("stack"), 1, 1.0, 1.5);
    let (ok, r, err) = run(d, &["g.yaml"]);
    assert!(ok, "{err}");
    for id in [
        "from_list",
        "from_paths",
        "curve",
        "merged",
        "exr",
        "curve2",
        "merged2",
        "exr2",
    ] {
        assert_eq!(status(&r, id), "ran", "{id}: {r:?}");
    }
    let reason = r.iter().find(|n| n["id"] == "from_list").unwrap()["reason"].to_string();
    assert!(reason.contains("e1.png"), "{reason}");
    assert_ne!(fs::read(d.join("out/list.exr")).unwrap(), before);
    let (_, r, _) = run(d, &["g.yaml"]);
    assert!(r.iter().all(|n| n["status"] == "cached"), "{r:?}");

    // A listed image that disappears: both readers fail naming the param and the file;
    // everything below them is skipped.
    fs::remove_file(d.join("stack/e2.png")).unwrap();
    let (ok, r, _) = run(d, &["g.yaml"]);
    assert!(!ok);
    for id in ["from_list", "from_paths"] {
        let n = r.iter().find(|n| n["id"] == id).unwrap();
        assert_eq!(n["status"], "failed", "{r:?}");
        let reason = n["reason"].as_str().unwrap();
        assert!(reason.contains("e2.png"), "{reason}");
        assert!(
            reason.contains("param `list`") || reason.contains("param `paths`"),
            "{reason}"
        );
    }
    assert_eq!(status(&r, "exr"), "skipped");
}
