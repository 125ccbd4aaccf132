//! End-to-end test of the YAML-scene example graph (`graphs/spheres_dome.yaml`): a YAML scene
//! with an OBJ mesh and a shadow catcher, lit only by the embedded HDR dome.

use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;

fn copy_dir(from: &Path, to: &Path) {
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

fn run(dir: &Path, extra: &[&str]) -> Vec<Json> {
    let mut args = vec!["run", "--json", "spheres_dome.yaml"];
    args.extend_from_slice(extra);
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(dir)
        .args(&args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).unwrap();
    v["nodes"].as_array().unwrap().clone()
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
}
