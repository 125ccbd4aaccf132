//! Helpers shared by the end-to-end tests of the `vfxgraph` binary.

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
