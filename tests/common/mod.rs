//! Helpers shared by the end-to-end tests: copying the example graphs into a scratch folder and
//! running the CLI on them.
#![allow(dead_code)]

use std::path::Path;
use std::process::Command;

use serde_json::Value as Json;

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

/// `vfxgraph run --json GRAPH ARGS…` in `dir`: asserts success and returns (node id, frame,
/// status) of every instance.
pub fn run_json(dir: &Path, graph: &str, args: &[&str]) -> Vec<(String, Option<i64>, String)> {
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(dir)
        .args(["run", "--json", graph])
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "vfxgraph run {graph} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: Json = serde_json::from_slice(&out.stdout).unwrap();
    j["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            (
                n["id"].as_str().unwrap().to_string(),
                n["frame"].as_i64(),
                n["status"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

/// The ids of the nodes with at least one instance of `status` in a `run_json` result.
pub fn nodes_with(
    st: &[(String, Option<i64>, String)],
    status: &str,
) -> std::collections::BTreeSet<String> {
    st.iter()
        .filter(|(_, _, s)| s == status)
        .map(|(id, _, _)| id.clone())
        .collect()
}
