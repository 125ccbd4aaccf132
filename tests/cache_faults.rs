//! Faults on the cache, with real kernel failures: a full disk during a
//! run's writes, and several runs of one graph on one cache at once.
//!
//! The full disk is a small tmpfs mounted for the test (root only: CI runs as root; under
//! `CI=true` a failed mount fails the test, elsewhere it prints a notice and passes). The graph
//! is `graphs/tonemap_hdri.yaml` on its embedded dome: cache objects of 3.0 (exposed), 5.3 and
//! 2.8 MB (tone-mapped) — the dome's reader is uncached, so only its action entry is stored;
//! output files of 2.2 MB (EXR) and 0.5 MB (each PNG).

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value as Json;

/// `graphs/tonemap_hdri.yaml` and its data copied into `dir`.
fn tonemap_graph(dir: &Path) -> PathBuf {
    fs::create_dir_all(dir.join("data")).unwrap();
    let g = dir.join("tonemap_hdri.yaml");
    fs::copy(repo().join("graphs/tonemap_hdri.yaml"), &g).unwrap();
    fs::copy(
        repo().join("graphs/data/studio_small_03_1k.hdr"),
        dir.join("data/studio_small_03_1k.hdr"),
    )
    .unwrap();
    g
}

mod common;
use common::vfx;
use vfxgraph_testdata::repo;

/// What `vfxgraph run --json` said: exit code, each node's status and reason, stderr.
struct Run {
    code: Option<i32>,
    status: BTreeMap<String, String>,
    reason: BTreeMap<String, String>,
    stderr: String,
}

/// `vfxgraph run --json GRAPH --cache CACHE` in the graph's folder.
fn run(graph: &Path, cache: &Path) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(graph.parent().unwrap())
        .arg("run")
        .arg("--json")
        .arg(graph)
        .arg("--cache")
        .arg(cache)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let v: Json = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("no JSON on stdout ({e}); stderr: {stderr}"));
    let nodes = v["nodes"].as_array().unwrap();
    let field = |k: &str| {
        nodes
            .iter()
            .map(|n| {
                (
                    n["id"].as_str().unwrap().to_string(),
                    n[k].as_str().unwrap().to_string(),
                )
            })
            .collect()
    };
    Run {
        code: out.status.code(),
        status: field("status"),
        reason: field("reason"),
        stderr,
    }
}

/// [`run`] that must succeed without meeting a corrupt object: the node statuses.
fn run_ok(graph: &Path, cache: &Path) -> BTreeMap<String, String> {
    let r = run(graph, cache);
    assert_eq!(r.code, Some(0), "{}", r.stderr);
    assert!(
        !r.stderr.contains("corrupt") && !r.stderr.contains("recomputing"),
        "{}",
        r.stderr
    );
    r.status
}

/// [`run`] that must fail (exit code 1) at node `id`: the node statuses and `id`'s error.
fn run_failing(graph: &Path, cache: &Path, id: &str) -> (BTreeMap<String, String>, String) {
    let mut r = run(graph, cache);
    assert_eq!(r.code, Some(1), "{:?}\n{}", r.status, r.stderr);
    assert_eq!(r.status[id], "failed", "{:?}", r.status);
    let why = r.reason.remove(id).unwrap();
    (r.status, why)
}

/// The output files of the graph (`out/` beside it), by name.
fn outputs(graph: &Path) -> BTreeMap<String, Vec<u8>> {
    let dir = graph.parent().unwrap().join("out");
    fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

/// Every action entry of a cache: (node id, frame) → its output digests.
fn cache_digests(cache: &Path) -> BTreeMap<String, Vec<String>> {
    let mut out = BTreeMap::new();
    for shard in fs::read_dir(cache.join("actions")).unwrap() {
        for f in fs::read_dir(shard.unwrap().path()).unwrap() {
            let v: Json = serde_json::from_slice(&fs::read(f.unwrap().path()).unwrap()).unwrap();
            let id = format!("{}@{}", v["node_id"], v["frame"]);
            let digests = v["outputs"]
                .as_array()
                .unwrap()
                .iter()
                .map(|o| format!("{}={}", o["port"], o["digest"]))
                .collect();
            assert!(out.insert(id, digests).is_none(), "one entry per instance");
        }
    }
    out
}

/// A tmpfs mounted on a folder for the life of the value.
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// Mounts a tmpfs of `size` (e.g. `8m`) on `dir`; `None` when this process cannot mount
    /// (not root, or no mount namespace rights) — a failure under `CI=true`.
    fn mount(dir: &Path, size: &str) -> Option<Tmpfs> {
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .output();
        match out {
            Ok(o) if o.status.success() => Some(Tmpfs(dir.to_path_buf())),
            other => {
                let why = match other {
                    Ok(o) => String::from_utf8_lossy(&o.stderr).trim().to_string(),
                    Err(e) => e.to_string(),
                };
                assert!(
                    !vfxgraph_testdata::required(),
                    "cannot mount a tmpfs on {} for the full-disk test (CI runs it as root): {why}",
                    dir.display()
                );
                eprintln!("notice: cannot mount a tmpfs ({why}); the full-disk test is skipped");
                None
            }
        }
    }

    /// Changes the size of the mounted file system (free space again).
    fn resize(&self, size: &str) {
        let st = Command::new("mount")
            .args(["-o", &format!("remount,size={size}")])
            .arg(&self.0)
            .status()
            .unwrap();
        assert!(st.success(), "remount {}", self.0.display());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// The cache on a file system that fills up during the run: the node whose result does not fit
/// fails with an error naming it and the file, the exit code is 1, the entries stored before
/// stay readable, no temporary is left, and once there is space again the rerun stores the rest
/// and gives the outputs of a run that never met a full disk. Then the same with the graph's
/// output files on the full disk.
#[test]
fn a_full_disk_fails_clearly_and_leaves_the_cache_readable() {
    let tmp = tempfile::tempdir().unwrap();
    // Reference: the whole graph with a cache on the ordinary disk.
    let reference = tonemap_graph(&tmp.path().join("reference"));
    let st = run_ok(&reference, &tmp.path().join("reference_cache"));
    assert!(st.values().all(|s| s == "ran"), "{st:?}");
    let want = outputs(&reference);
    assert_eq!(want.len(), 3);
    let want_digests = cache_digests(&tmp.path().join("reference_cache"));

    // The cache on 2 MB: the dome's entry fits (an uncached reader stores no object), the
    // exposed image after it does not.
    let mnt = tmp.path().join("small");
    fs::create_dir_all(&mnt).unwrap();
    let Some(fs_small) = Tmpfs::mount(&mnt, "2m") else {
        return;
    };
    let cache = mnt.join("cache");
    let graph = tonemap_graph(&tmp.path().join("full_cache"));
    let (st, why) = run_failing(&graph, &cache, "expose");
    assert_eq!(st["dome"], "ran", "{st:?}");
    for id in ["reinhard", "clip", "exr", "png_reinhard", "png_clip"] {
        assert_eq!(st[id], "skipped", "{id}: {st:?}");
    }
    // The reason is the node's error (`run` without --json prints it naming the node).
    assert!(
        why.contains("could not be cached")
            && why.contains("No space left on device")
            && why.contains(&cache.join("objects").display().to_string()),
        "the error names the cause and the cache file: {why}"
    );
    // Readable: `cache ls` lists exactly the stored entry; no temporary is left behind.
    let ls = vfx(
        graph.parent().unwrap(),
        &["cache", "ls", "--cache", cache.to_str().unwrap()],
    );
    assert!(
        ls.status.success(),
        "{}",
        String::from_utf8_lossy(&ls.stderr)
    );
    let ls = String::from_utf8_lossy(&ls.stdout);
    assert!(ls.contains("dome") && ls.contains("1 entries"), "{ls}");
    assert_eq!(fs::read_dir(cache.join("tmp")).unwrap().count(), 0);
    let stored = cache_digests(&cache);
    assert_eq!(
        stored.keys().collect::<Vec<_>>(),
        ["\"dome\"@null"],
        "{stored:?}"
    );
    assert_eq!(stored["\"dome\"@null"], want_digests["\"dome\"@null"]);

    // Space again: the rerun serves the stored entry (verified) and runs the rest.
    fs_small.resize("64m");
    let st = run_ok(&graph, &cache);
    assert_eq!(st["dome"], "cached", "{st:?}");
    assert!(
        st.iter().all(|(id, s)| id == "dome" || s == "ran"),
        "{st:?}"
    );
    assert_eq!(outputs(&graph), want);
    assert_eq!(cache_digests(&cache), want_digests);
    let st = run_ok(&graph, &cache);
    assert!(st.values().all(|s| s == "cached"), "{st:?}");

    // The graph's own output files on a full disk (the cache elsewhere): the writer fails
    // naming its file, nothing is left under that name or as a temporary beside it, and the
    // cache keeps everything the other nodes stored.
    // 3 MB (emptied first: a tmpfs cannot shrink below what it holds): the graph's copy of the
    // dome (1.7 MB) and both PNGs fit, the EXR does not.
    fs::remove_dir_all(&cache).unwrap();
    fs_small.resize("3m");
    let out_graph = tonemap_graph(&mnt.join("graph"));
    let other_cache = tmp.path().join("other_cache");
    let (st, why) = run_failing(&out_graph, &other_cache, "exr");
    let exr = out_graph
        .parent()
        .unwrap()
        .join("out/studio_small_03_exposed.exr");
    assert!(
        why.contains("No space left on device") && why.contains(&exr.display().to_string()),
        "the error names the cause and the file: {why}"
    );
    let left: Vec<_> = fs::read_dir(exr.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        !left
            .iter()
            .any(|n| n.contains("exposed") || n.contains("tmp")),
        "{left:?}"
    );
    for id in ["dome", "expose", "reinhard", "clip"] {
        assert_eq!(st[id], "ran", "{id}: {st:?}");
    }
    fs_small.resize("64m");
    let st = run_ok(&out_graph, &other_cache);
    assert_eq!(st["exr"], "ran", "{st:?}");
    assert_eq!(st["expose"], "cached", "{st:?}");
    assert_eq!(outputs(&out_graph), want);
}

/// Several `vfxgraph run`s of the same graph in the same folder on one cache at once (from an
/// empty cache, so they race on every object, entry, record and output file): every one exits
/// 0, and the outputs and the cache's entries are those of a run alone. Three rounds.
#[test]
fn concurrent_runs_on_one_cache_agree() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = tonemap_graph(&tmp.path().join("reference"));
    let ref_cache = tmp.path().join("reference_cache");
    run_ok(&reference, &ref_cache);
    let want = outputs(&reference);
    let want_digests = cache_digests(&ref_cache);
    for round in 0..3 {
        let dir = tmp.path().join(format!("round{round}"));
        let graph = tonemap_graph(&dir);
        let cache = dir.join("shared_cache");
        let children: Vec<_> = (0..3)
            .map(|_| {
                Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
                    .current_dir(&dir)
                    .arg("run")
                    .arg("--json")
                    .arg(&graph)
                    .arg("--cache")
                    .arg(&cache)
                    .stdout(std::process::Stdio::piped())
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        // How many of the runs computed each instance (a lease makes it one).
        let mut computed = 0;
        for c in children {
            let out = c.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "round {round}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let v: Json = serde_json::from_slice(&out.stdout).unwrap();
            assert!(
                v["nodes"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .all(|n| n["status"] == "ran" || n["status"] == "cached"),
                "round {round}: {v}"
            );
            computed += v["nodes"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|n| {
                    n["status"] == "ran"
                        && !n["reason"]
                            .as_str()
                            .unwrap_or("")
                            .contains("read when a consumer runs")
                })
                .count();
        }
        assert_eq!(
            computed, 6,
            "round {round}: instances computed by the 3 runs"
        );
        assert_eq!(outputs(&graph), want, "round {round}");
        assert_eq!(cache_digests(&cache), want_digests, "round {round}");
        assert_eq!(fs::read_dir(cache.join("tmp")).unwrap().count(), 0);
        // And the cache they made serves a later run whole.
        let st = run_ok(&graph, &cache);
        assert!(st.values().all(|s| s == "cached"), "round {round}: {st:?}");
    }
}
