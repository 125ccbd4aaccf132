//! The tests' access to the real third-party data in `../shared/data` (beside the clone).
//!
//! Every file a test reads is listed in `tests/data_manifest.txt` (checked by `.ci/run` before
//! it builds anything). A test asks for a listed file or folder here:
//!
//! - present: its path;
//! - absent, with `CI=true` in the environment: a panic naming the file, so a partial data
//!   folder fails CI instead of passing it unnoticed;
//! - absent otherwise (a developer without the data): a notice on stderr and `None`.
//!
//! Asking for a path the manifest does not list is always a panic: the manifest stays the
//! complete list. `VFXGRAPH_SHARED_DATA` moves the data folder (default: `../shared/data`
//! relative to the repository root).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The manifest: one path a line, relative to the data folder; `#` starts a comment.
const MANIFEST: &str = include_str!("../../../tests/data_manifest.txt");

/// The repository's root folder (the workspace's).
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A Python interpreter the tests check files with in another program's library (a client:
/// OpenImageIO, PyOpenColorIO, COLMAP's, Blender's, USD's).
pub struct Python {
    exe: String,
    hint: &'static str,
}

impl Python {
    /// The interpreter `$var` names, else `fallback` (a leading `~/` is the home folder);
    /// `hint` says how to install the modules the tests import with it.
    pub fn from_env(var: &str, fallback: &str, hint: &'static str) -> Python {
        let exe = std::env::var(var).unwrap_or_else(|_| match fallback.strip_prefix("~/") {
            Some(rest) => format!("{}/{rest}", std::env::var("HOME").unwrap_or_default()),
            None => fallback.to_string(),
        });
        Python { exe, hint }
    }

    /// The interpreter's path or name.
    pub fn exe(&self) -> &str {
        &self.exe
    }

    /// A command running the interpreter.
    pub fn command(&self) -> Command {
        Command::new(&self.exe)
    }

    /// Whether `modules` (an `import` statement's list, e.g. `OpenImageIO, numpy`) import.
    /// When they do not: a panic when the clients are required (`VFXGRAPH_REQUIRE_CLIENTS=1`,
    /// as under CI), else a notice on stderr and `false` (the test skips its check).
    pub fn has(&self, modules: &str) -> bool {
        let ok = self
            .command()
            .args(["-c", &format!("import {modules}")])
            .output()
            .is_ok_and(|o| o.status.success());
        if !ok {
            let msg = format!(
                "python modules `{modules}` not found with `{}` ({})",
                self.exe, self.hint
            );
            assert!(
                !std::env::var("VFXGRAPH_REQUIRE_CLIENTS").is_ok_and(|v| v == "1"),
                "{msg}"
            );
            eprintln!("skipping the check: {msg}");
        }
        ok
    }
}

/// The data folder: `VFXGRAPH_SHARED_DATA` if set, else `../shared/data` beside the clone.
pub fn root() -> PathBuf {
    match std::env::var_os("VFXGRAPH_SHARED_DATA") {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    }
}

/// True when the tests run under CI (`CI=true` or `CI=1`), where missing data is a failure.
pub fn required() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Whether a test's external tool (`what`, e.g. "FFmpeg (ffmpeg, ffprobe)") is `present`: when
/// it is not, a panic under CI, elsewhere a notice and `false` (the test returns).
pub fn tool(present: bool, what: &str) -> bool {
    if !present {
        assert!(!required(), "{what} is required under CI=true");
        eprintln!("notice: {what} is absent; this test is skipped (under CI=true it fails)");
    }
    present
}

/// The files of the manifest, in its order.
pub fn manifest() -> impl Iterator<Item = &'static str> {
    MANIFEST
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
}

/// The manifest's files at or under `rel` (a file, or a folder without trailing slash).
fn listed(rel: &str) -> Vec<&'static str> {
    let rel = rel.trim_end_matches('/');
    manifest()
        .filter(|f| *f == rel || f.strip_prefix(rel).is_some_and(|r| r.starts_with('/')))
        .collect()
}

/// The first file of `files` missing under the data folder.
fn first_missing(files: &[&str]) -> Option<PathBuf> {
    let root = root();
    files.iter().map(|f| root.join(f)).find(|p| !p.is_file())
}

/// The path of `rel` (a file or a folder of the data, as listed in the manifest) when it and
/// every listed file under it are present. See the module doc for what happens when not.
pub fn path(rel: &str) -> Option<PathBuf> {
    let files = listed(rel);
    assert!(
        !files.is_empty(),
        "test data `{rel}` is not listed in tests/data_manifest.txt: add it there"
    );
    match first_missing(&files) {
        None => Some(root().join(rel)),
        Some(p) if required() => panic!(
            "test data missing: {} (CI=true requires every file of tests/data_manifest.txt)",
            p.display()
        ),
        Some(p) => {
            eprintln!(
                "notice: test data {} is absent; this test is skipped (under CI=true it fails)",
                p.display()
            );
            None
        }
    }
}

/// [`path`] of several files or folders at once: all present, or `None` (after the notice of
/// the first absent one).
pub fn paths<const N: usize>(rels: [&str; N]) -> Option<[PathBuf; N]> {
    let mut out = Vec::with_capacity(N);
    for r in rels {
        out.push(path(r)?);
    }
    out.try_into().ok()
}

/// [`path`] for a test that cannot run without the file at all: a panic naming it when absent,
/// with or without `CI=true`.
pub fn require(rel: &str) -> PathBuf {
    let files = listed(rel);
    assert!(
        !files.is_empty(),
        "test data `{rel}` is not listed in tests/data_manifest.txt: add it there"
    );
    if let Some(p) = first_missing(&files) {
        panic!("test data missing: {}", p.display());
    }
    root().join(rel)
}

/// The data folders an example graph names (`../../shared/data/<folder>/…`), in order.
fn graph_folders(text: &str) -> Vec<&str> {
    let mut out: Vec<&str> = Vec::new();
    for (i, _) in text.match_indices(GRAPH_DATA) {
        let rest = &text[i + GRAPH_DATA.len()..];
        let folder = rest.split(['/', '"', '\'', ' ', '\n']).next().unwrap_or("");
        if !folder.is_empty() && !out.contains(&folder) {
            out.push(folder);
        }
    }
    out
}

/// How the example graphs (in `graphs/`) name the data folder.
const GRAPH_DATA: &str = "../../shared/data/";

/// Copies an example graph into the folder `dir` with its `../../shared/data` paths pointing
/// at [`root`], so a graph run from a test reads the data the tests use; `None` (see [`path`])
/// when a data folder it names is incomplete. Returns the copy's path.
pub fn graph_with_data(graph: &Path, dir: &Path) -> Option<PathBuf> {
    let text = std::fs::read_to_string(graph)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", graph.display()));
    for folder in graph_folders(&text) {
        path(folder)?;
    }
    let root = root();
    let root = root.canonicalize().unwrap_or(root);
    let out = dir.join(graph.file_name().expect("a graph file"));
    std::fs::create_dir_all(dir)
        .and_then(|()| {
            std::fs::write(
                &out,
                text.replace(
                    &GRAPH_DATA[..GRAPH_DATA.len() - 1],
                    &root.display().to_string(),
                ),
            )
        })
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn manifest_entries_are_relative_files_listed_once() {
        let all: Vec<&str> = manifest().collect();
        assert!(all.len() > 20, "{} entries", all.len());
        let mut sorted = all.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), all.len(), "an entry is listed twice");
        for f in all {
            assert!(
                !f.starts_with('/') && !f.contains("..") && !f.ends_with('/'),
                "{f}"
            );
        }
        assert_eq!(listed("book-demo/f.txt"), ["book-demo/f.txt"]);
        assert!(listed("book-demo").len() > 3);
        // A prefix of a name is not a folder.
        assert!(listed("book-dem").is_empty());
        let yaml = "a: {path: ../../shared/data/book-demo/f.txt}\n\
                    b: {path: \"../../shared/data/middlebury_flow_RubberWhale/frame%02d.png\"}\n\
                    c: {list: ../../shared/data/book-demo/g7cam.txt}\n";
        assert_eq!(
            graph_folders(yaml),
            ["book-demo", "middlebury_flow_RubberWhale"]
        );
    }

    #[test]
    #[should_panic(expected = "not listed in tests/data_manifest.txt")]
    fn an_unlisted_path_is_refused() {
        path("nowhere/nothing.txt");
    }
}
