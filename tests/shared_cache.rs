//! One cache shared by many processes at once: the way farm tasks on many
//! hosts use it. Five processes — two `run`s of the whole shot and three overlapping `exec`s
//! of its renders (frames 1-4, 3-8 and 1-8) — start together on one cache, three rounds on a
//! fresh cache each; then a sixth process must find everything cached. Nothing may be
//! corrupt (every object of every entry reads back verified, every record and memo entry
//! parses), every entry equals a single local run's, and `cache ls`, `du` and `gc` work.

mod common;

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};

use vfxgraph_engine::store::Store;
use vfxgraph_engine::Digest;

/// `graphs/farm_shot.yaml` with its scene and dome copied into `dir`.
fn shot(dir: &Path) -> PathBuf {
    let g = common::farm_shot_copy(dir);
    // Files older than the memo's racy window, so the memo is written (and shared) too.
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    for f in [
        "g/scenes/plate.yaml",
        "g/scenes/cube.obj",
        "g/data/studio_small_03_1k.hdr",
    ] {
        let file = fs::File::options().append(true).open(dir.join(f)).unwrap();
        file.set_modified(old).unwrap();
    }
    g
}

fn spawn(graph: &Path, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_vfxgraph"))
        .current_dir(graph.parent().unwrap())
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
}

fn ok(child: Child, what: &str) -> String {
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{what} failed:\n{err}");
    assert!(
        !err.contains("corrupt"),
        "{what} met a corrupt object:\n{err}"
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// (node, frame) → output digests of every entry, each object verified on the way.
fn entries(cache: &Path) -> BTreeMap<(String, Option<i64>), Vec<String>> {
    let store = Store::open(cache).unwrap();
    let mut out = BTreeMap::new();
    for e in store.list() {
        let d: Vec<String> = e.entry.outputs.iter().map(|o| o.digest.clone()).collect();
        for x in &d {
            assert!(
                store.get_object(&Digest::from_hex(x).unwrap()).is_some(),
                "{x} corrupt"
            );
        }
        out.insert((e.entry.node_id.clone(), e.entry.frame), d);
    }
    out
}

/// Every JSON file under `dir` parses (records, memo entries); their number.
fn all_parse(dir: &Path) -> usize {
    let mut n = 0;
    for e in fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            n += all_parse(&p);
        } else {
            let bytes = fs::read(&p).unwrap();
            serde_json::from_slice::<serde_json::Value>(&bytes)
                .unwrap_or_else(|e| panic!("{} does not parse: {e}", p.display()));
            n += 1;
        }
    }
    n
}

fn outputs(graph: &Path) -> BTreeMap<String, Vec<u8>> {
    fs::read_dir(graph.parent().unwrap().join("out/farm_shot"))
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

#[test]
fn many_processes_share_one_cache() {
    let tmp = tempfile::tempdir().unwrap();
    let r = shot(&tmp.path().join("ref"));
    ok(
        spawn(&r, &["run", "-q", "farm_shot.yaml", "--cache", "cache"]),
        "reference run",
    );
    let want = entries(&r.parent().unwrap().join("cache"));
    assert_eq!(want.len(), 27);
    let g = shot(&tmp.path().join("shared"));
    let cache = g.parent().unwrap().join("cache");
    for round in 0..3 {
        let _ = fs::remove_dir_all(&cache);
        // The renders' inputs, which an `exec` of the renders only reads.
        ok(
            spawn(
                &g,
                &[
                    "exec",
                    "-q",
                    "farm_shot.yaml",
                    "--node",
                    "path",
                    "--node",
                    "plate_scene",
                    "--cache",
                    "cache",
                ],
            ),
            "exec of the inputs",
        );
        let exec = |frames: &str| {
            spawn(
                &g,
                &[
                    "exec",
                    "-q",
                    "farm_shot.yaml",
                    "--node",
                    "plate",
                    "--frames",
                    frames,
                    "--cache",
                    "cache",
                ],
            )
        };
        let run = || {
            spawn(
                &g,
                &[
                    "run",
                    "-q",
                    "farm_shot.yaml",
                    "--cache",
                    "cache",
                    "--jobs",
                    "1",
                ],
            )
        };
        let procs = vec![run(), exec("1-4"), exec("3-8"), run(), exec("1-8")];
        for (i, p) in procs.into_iter().enumerate() {
            ok(p, &format!("round {round}, process {i}"));
        }
        assert_eq!(
            entries(&cache),
            want,
            "round {round}: entries differ from one run's"
        );
        assert_eq!(
            outputs(&g),
            outputs(&r),
            "round {round}: output files differ"
        );
        assert!(all_parse(&cache.join("records")) >= 27 + 6);
        assert!(all_parse(&cache.join("files")) >= 1);
        let json = ok(
            spawn(&g, &["run", "--json", "farm_shot.yaml", "--cache", "cache"]),
            "check run",
        );
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert!(
            v["nodes"]
                .as_array()
                .unwrap()
                .iter()
                .all(|n| n["status"] == "cached"),
            "{v}"
        );
    }
    let ls = ok(spawn(&g, &["cache", "ls", "--cache", "cache"]), "cache ls");
    assert!(ls.trim_end().ends_with("27 entries"), "{ls}");
    ok(spawn(&g, &["cache", "du", "--cache", "cache"]), "cache du");
    let gc = ok(spawn(&g, &["cache", "gc", "--cache", "cache"]), "cache gc");
    assert!(gc.starts_with("removed 0 entries and 0 objects"), "{gc}");
    assert_eq!(entries(&cache), want);
}

/// The instances a `run --json` computed (an uncached reader's "ran" only names its outputs).
fn computed(json: &str) -> Vec<(String, Option<i64>)> {
    let v: serde_json::Value = serde_json::from_str(json).unwrap();
    v["nodes"]
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
        .map(|n| (n["id"].as_str().unwrap().to_string(), n["frame"].as_i64()))
        .collect()
}

/// Eight `run`s of one graph started together on one empty cache compute each instance
/// exactly once between them (the others wait for its lease and take the entry), and their
/// outputs are a single run's.
#[test]
fn eight_concurrent_runs_compute_each_instance_once() {
    let tmp = tempfile::tempdir().unwrap();
    let r = shot(&tmp.path().join("ref"));
    let alone = ok(
        spawn(&r, &["run", "--json", "farm_shot.yaml", "--cache", "cache"]),
        "reference run",
    );
    let mut want = computed(&alone);
    want.sort();
    assert!(want.len() >= 20, "{want:?}");
    let g = shot(&tmp.path().join("shared"));
    let runs: Vec<Child> = (0..8)
        .map(|_| spawn(&g, &["run", "--json", "farm_shot.yaml", "--cache", "cache"]))
        .collect();
    let mut all = Vec::new();
    let mut served = 0;
    for (k, p) in runs.into_iter().enumerate() {
        let json = ok(p, &format!("run {k}"));
        all.extend(computed(&json));
        served += json.matches("computed by a concurrent run").count();
    }
    all.sort();
    eprintln!(
        "8 runs: {} computations for {} instances; {served} served by a concurrent run's lease",
        all.len(),
        want.len()
    );
    assert_eq!(all, want, "each instance computed exactly once");
    assert_eq!(outputs(&g), outputs(&r), "output files differ");
    assert_eq!(
        entries(&g.parent().unwrap().join("cache")),
        entries(&r.parent().unwrap().join("cache"))
    );
    let leases = g.parent().unwrap().join("cache/leases");
    let left: usize = fs::read_dir(&leases)
        .map(|d| {
            d.flatten()
                .map(|s| fs::read_dir(s.path()).map_or(0, |f| f.count()))
                .sum()
        })
        .unwrap_or(0);
    assert_eq!(left, 0, "leases left behind");
}
