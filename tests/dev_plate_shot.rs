//! Partial reruns of the local-scene shot on the Blender dev plate:
//! `graphs/dev_plate_shot.yaml` (tracking, the solve, the measured marks and box corners, the
//! catcher fit, two box proxies, the catcher texture, the insert added last, the renders)
//! through the engine with a cache folder, at low settings (the texture from 3 frames at 32
//! texels a side, 1-spp renders) — what is checked is what reruns, not the pictures. The
//! once-nodes and frame 24's renders are computed with `exec`; after each change `plan` names
//! the instances whose keys changed (`run`, or `blocked` behind one that must run) and `exec`
//! computes them for frame 24 with everything else cache-only (a miss there would fail). Changing
//! a sphere's material (an edit of the insert's scene file) changes only the insert's reading and
//! placing, `add_objects` and what renders it; changing the texture's frames, the texture, its
//! writers and the textured renders; neither touches tracking, the solve or the catcher fit.
//! Bad input through the engine fails naming the node.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use serde_json::Value as Json;

fn set(ids: &[&str]) -> BTreeSet<String> {
    ids.iter().map(|s| s.to_string()).collect()
}

/// The low settings of this test (see the module doc).
const LOW: [&str; 14] = [
    "--set",
    "fit.spp=1",
    "--set",
    "texture.resolution=32",
    "--set",
    "texture.irradiance_samples=8",
    "--set",
    "texture.others_resolution=4",
    "--set",
    "shot.spp=1",
    "--set",
    "shot_uniform.spp=1",
    "--set",
    "texture.frames=[0,24,47]",
];

/// `vfxgraph CMD --json dev_plate_shot.yaml LOW… EXTRA…`, which must succeed; its node entries.
fn cli(dir: &Path, cmd: &str, extra: &[&str]) -> Vec<Json> {
    let mut a = vec![cmd, "--json", "dev_plate_shot.yaml"];
    a.extend_from_slice(&LOW);
    a.extend_from_slice(extra);
    let out = common::vfx(dir, &a);
    assert!(
        out.status.success(),
        "vfxgraph {a:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Json = serde_json::from_slice(&out.stdout).expect("json on stdout");
    v["nodes"].as_array().unwrap().clone()
}

/// The plan's instances of once-nodes and of frame 24 that are not cached, by node id.
fn changed(dir: &Path, extra: &[&str]) -> BTreeSet<String> {
    cli(dir, "plan", extra)
        .iter()
        .filter(|n| n["frame"].is_null() || n["frame"] == 24)
        .filter(|n| n["status"] != "cached")
        .map(|n| n["id"].as_str().unwrap().to_string())
        .collect()
}

/// `exec` of `nodes`, the once-nodes first, then the per-frame ones (on `frames`, else every
/// frame): every selected instance ran.
fn exec(
    dir: &Path,
    nodes: &BTreeSet<String>,
    per_frame: &BTreeSet<String>,
    extra: &[&str],
    frames: Option<&str>,
) {
    for (group, frames) in [(false, None), (true, frames)] {
        let mut a: Vec<&str> = Vec::new();
        for n in nodes.iter().filter(|n| per_frame.contains(*n) == group) {
            a.extend(["--node", n.as_str()]);
        }
        if a.is_empty() {
            continue;
        }
        if let Some(f) = frames {
            a.extend(["--frames", f]);
        }
        a.extend_from_slice(extra);
        let done = cli(dir, "exec", &a);
        let ran = common::nodes_with(&done, "ran");
        let want: BTreeSet<String> = nodes
            .iter()
            .filter(|n| per_frame.contains(*n) == group)
            .cloned()
            .collect();
        assert_eq!(ran, want, "{done:?}");
    }
}

#[test]
fn a_material_change_reruns_the_renders_and_new_texture_frames_the_texture_never_the_solve() {
    let tmp = tempfile::tempdir().unwrap();
    let g = common::scratch_graphs(tmp.path());
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    if vfxgraph_testdata::graph_with_data(&repo.join("graphs/dev_plate_shot.yaml"), &g).is_none() {
        return;
    }
    let Some(dome) = vfxgraph_testdata::path("polyhaven_hdri_1k/empty_warehouse_01_1k.hdr") else {
        return;
    };
    let set_file = g.join("scenes/dev_plate_set.yaml");
    let text = std::fs::read_to_string(&set_file).unwrap();
    let from = "../../../shared/data/polyhaven_hdri_1k/empty_warehouse_01_1k.hdr";
    assert!(text.contains(from));
    std::fs::write(&set_file, text.replace(from, dome.to_str().unwrap())).unwrap();

    // Everything once, and frame 24.
    let plan = cli(&g, "plan", &[]);
    let per_frame: BTreeSet<String> = plan
        .iter()
        .filter(|n| !n["frame"].is_null())
        .map(|n| n["id"].as_str().unwrap().to_string())
        .collect();
    let all: BTreeSet<String> = plan
        .iter()
        .map(|n| n["id"].as_str().unwrap().to_string())
        .collect();
    assert!(per_frame.contains("shot") && !per_frame.contains("texture"));
    // The plate reader runs per frame and tracking needs every frame.
    let plate = set(&["plate"]);
    exec(&g, &plate, &per_frame, &[], None);
    let rest: BTreeSet<String> = all.difference(&plate).cloned().collect();
    exec(&g, &rest, &per_frame, &[], Some("24"));
    assert!(changed(&g, &[]).is_empty());

    // A sphere's material: the mirror becomes 80 % reflective.
    let cg = g.join("scenes/dev_plate_cg.yaml");
    let text = std::fs::read_to_string(&cg).unwrap();
    let from = "{type: mirror, reflectance: [1, 1, 1]}";
    assert!(text.contains(from));
    std::fs::write(
        &cg,
        text.replace(from, "{type: mirror, reflectance: [0.8, 0.8, 0.8]}"),
    )
    .unwrap();
    let want = set(&[
        "cg",
        "place_cg",
        "insert",
        "insert_uniform",
        "shot",
        "shot_uniform",
        "composite_exr",
        "composite_uniform_exr",
    ]);
    assert_eq!(changed(&g, &[]), want);
    exec(&g, &want, &per_frame, &[], Some("24"));

    // Other texture frames: the texture, what writes it and the textured renders.
    let other = ["--set", "texture.frames=[0,47]"];
    let want = set(&[
        "texture",
        "albedo_exr",
        "texture_report",
        "insert",
        "shot",
        "composite_exr",
    ]);
    assert_eq!(changed(&g, &other), want);
    exec(&g, &want, &per_frame, &other, Some("24"));
    assert!(changed(&g, &other).is_empty());

    // Bad input, with everything upstream cached: the error names the node.
    let fails = |node: &str, extra: &[&str], want: &str| {
        let mut a = vec!["exec", "dev_plate_shot.yaml", "--node", node];
        a.extend_from_slice(&LOW);
        a.extend_from_slice(extra);
        let out = common::vfx(&g, &a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(want), "{err}");
    };
    fails(
        "texture",
        &["--set", "texture.frames=[0,99]"],
        "node `texture` (catcher_texture) failed: param `frames`: the plate has no frame 99 (its \
         frames are 0–47)",
    );
    fails(
        "proxies_merton",
        &["--set", "proxies_merton.tops=[0,1]"],
        "node `proxies_merton` (proxy_from_points) failed: param `tops`: box 0 has 2 point \
         indices, a box needs 3",
    );
}
