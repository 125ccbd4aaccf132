//! End-to-end test of the YAML-scene example graph (`graphs/spheres_dome.yaml`): a YAML scene
//! with an OBJ mesh and a shadow catcher, lit only by the embedded HDR dome.

use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;

mod common;
use common::copy_dir;

fn run(dir: &Path, extra: &[&str]) -> Vec<Json> {
    let mut args = vec!["spheres_dome.yaml"];
    args.extend_from_slice(extra);
    common::run_json(dir, &args)
}

#[test]
fn spheres_dome_graph_renders_then_is_cached() {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    copy_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs"), &g);
    let small = [
        "--set",
        "render.spp=2",
        "--set",
        "render.width=64",
        "--set",
        "render.height=36",
    ];
    let nodes = run(&g, &small);
    assert!(nodes.iter().all(|n| n["status"] == "ran"), "{nodes:?}");
    let img = vfxgraph_imaging::read_image(&g.join("out/spheres_dome.exr")).unwrap();
    assert_eq!((img.width, img.height, img.channels), (64, 36, 3));
    assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    // Lit by the dome alone: the top row sees the (dim) studio wall of the dome, the floor in
    // the bottom row is lit by the dome's bright lamps.
    let row_mean = |y: usize| (0..64).map(|x| img.get(x, y, 1)).sum::<f32>() / 64.0;
    let (top, bottom) = (row_mean(0), row_mean(35));
    assert!(top > 0.0 && bottom > 0.1, "{top} {bottom}");
    // Second run: everything cached.
    let nodes = run(&g, &small);
    assert!(nodes.iter().all(|n| n["status"] == "cached"), "{nodes:?}");
    // Editing the OBJ mesh the scene names (not the scene file) reruns the scene reader.
    let obj = g.join("scenes/cube.obj");
    let mut text = std::fs::read_to_string(&obj).unwrap();
    text.push_str("# edited\n");
    std::fs::write(&obj, text).unwrap();
    let nodes = run(&g, &small);
    let scene = nodes.iter().find(|n| n["id"] == "scene").unwrap();
    assert_eq!(scene["status"], "ran", "{nodes:?}");
}

/// Ctrl-C (SIGINT) during a long render: the run stops within a second (docs/guide/command-line.md) with exit
/// code 130, the render is not cached under its own key (a plan of the same run says it must
/// run, while the scene it read is cached), and no output exists under its name.
#[test]
fn sigint_cancels_a_long_render_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path().join("graphs");
    copy_dir(&Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs"), &g);
    let long = ["spheres_dome.yaml", "--set", "render.spp=100000"];
    let child = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(&g)
        .args(["run", "--json"])
        .args(long)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Let the scene load and the render start.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let sent = std::time::Instant::now();
    // SAFETY: signalling our own child process.
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
    let out = child.wait_with_output().unwrap();
    let waited = sent.elapsed();
    eprintln!("stopped {:.3} s after SIGINT", waited.as_secs_f64());
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(waited.as_secs_f64() < 2.0, "stopped after {waited:?}");
    assert!(!g.join("out/spheres_dome.exr").exists());
    // The render was running (it failed on the flag; a skip would test nothing here).
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    let status = |nodes: &Json, id: &str| {
        nodes["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|n| n["id"] == id)
            .map(|n| n["status"].as_str().unwrap().to_string())
    };
    assert_eq!(status(&v, "render").as_deref(), Some("failed"), "{v}");
    // The interrupted instance's own key: the same graph and params plan to run the render
    // (nothing partial was stored under that key), its finished upstream is cached.
    let plan = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(&g)
        .args(["plan", "--json"])
        .args(long)
        .output()
        .unwrap();
    assert!(plan.status.success());
    let p: Json = serde_json::from_slice(&plan.stdout).unwrap();
    assert_eq!(status(&p, "scene").as_deref(), Some("cached"), "{p}");
    assert_eq!(status(&p, "render").as_deref(), Some("run"), "{p}");
}

/// A YAML scene without `camera:` reads and places; rendered with nothing
/// that supplies a camera, the run fails at the node that needs one, naming it and the cause.
#[test]
fn a_scene_without_a_camera_fails_only_where_a_camera_is_needed() {
    let tmp = tempfile::tempdir().unwrap();
    let g = tmp.path();
    std::fs::write(
        g.join("scene.yaml"),
        "objects:\n  - sphere: {center: [0, 0, 0], radius: 1}\ndome: {color: 1}\n",
    )
    .unwrap();
    std::fs::write(
        g.join("g.yaml"),
        "version: 1\nnodes:\n  scene:\n    type: read_scene\n    params: {path: scene.yaml}\n  \
         beauty:\n    type: render\n    inputs: {scene: scene.scene}\n    params: {spp: 1}\n",
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(g)
        .args(["run", "--json", "g.yaml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    let nodes = v["nodes"].as_array().unwrap();
    let by = |id: &str| nodes.iter().find(|n| n["id"] == id).unwrap().clone();
    assert_eq!(by("scene")["status"], "ran", "{nodes:?}");
    let beauty = by("beauty");
    assert_eq!(beauty["status"], "failed");
    let why = beauty["reason"].as_str().unwrap();
    assert!(
        why.contains("no camera") && why.contains("`cameras`"),
        "{why}"
    );
    // Without --json, the error names the node.
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(g)
        .args(["run", "--no-cache", "g.yaml"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("node `beauty` (render) failed: no camera"),
        "{stderr}"
    );
}
