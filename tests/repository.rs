//! The repository as a reader meets it: the node reference in `docs/reference/nodes.md` is what
//! `vfxgraph nodes --markdown` prints today, and no file speaks of how it was made (work
//! sessions, issue numbers, the people or agents who wrote it, "this machine") — the product
//! speaks of itself; history goes in CHANGELOG.md, figures name the machine class and the
//! command that measures them.

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use vfxgraph_testdata::repo;

#[test]
fn the_node_reference_is_generated_from_the_registry() {
    let out = common::vfx(&repo(), &["nodes", "--markdown"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let generated = String::from_utf8(out.stdout).unwrap();
    let path = repo().join("docs/reference/nodes.md");
    let checked_in = fs::read_to_string(&path).unwrap_or_default();
    assert!(
        generated == checked_in,
        "{} is out of date: regenerate it with `cargo run -- nodes --markdown > docs/reference/nodes.md`",
        path.display()
    );
}

/// Phrases about the making rather than the product, lower-case; a line holding one fails.
const MAKING: &[&str] = &[
    "this machine",
    "this 2-core",
    "this 4-core",
    "this session",
    "earlier session",
    "previous session",
    "last session",
    "a helper's",
    "helper session",
    "(issue",
    "issue #",
    "the issue's",
    "the issue asks",
];

/// "session 12", "issue 9", "stop 44": a word of the making followed by a number.
fn numbered(line: &str) -> Option<&'static str> {
    for word in ["session ", "sessions ", "issue ", "issues "] {
        let mut rest = line;
        while let Some(i) = rest.find(word) {
            let after = &rest[i + word.len()..];
            let word_start = i == 0 || !rest.as_bytes()[i - 1].is_ascii_alphanumeric();
            if word_start && after.starts_with(|c: char| c.is_ascii_digit()) {
                return Some(word);
            }
            rest = after;
        }
    }
    None
}

/// Text files of the repository, without build output, vendored code and the lock file.
fn text_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if e.file_type().unwrap().is_dir() {
            if !matches!(name.as_str(), "target" | ".git" | "vendor" | "node_modules") {
                text_files(&p, out);
            }
        } else if [
            "rs", "md", "yaml", "yml", "toml", "py", "sh", "cc", "js", "html", "css", "txt",
        ]
        .iter()
        .any(|x| name.ends_with(&format!(".{x}")))
            || name == "run"
        {
            out.push(p);
        }
    }
}

#[test]
fn no_file_speaks_of_how_it_was_made() {
    let root = repo();
    let mut files = Vec::new();
    text_files(&root, &mut files);
    // This file names the phrases it looks for; CHANGELOG.md is the history.
    let skip = [root.join("tests/repository.rs"), root.join("CHANGELOG.md")];
    let mut found = Vec::new();
    for f in files.iter().filter(|f| !skip.contains(f)) {
        let Ok(text) = fs::read_to_string(f) else {
            continue;
        };
        for (n, line) in text.lines().enumerate() {
            let lower = line.to_lowercase();
            let hit = MAKING
                .iter()
                .copied()
                .find(|p| lower.contains(p))
                .or_else(|| numbered(&lower));
            if let Some(p) = hit {
                found.push(format!(
                    "{}:{}: \"{p}\": {}",
                    f.strip_prefix(&root).unwrap().display(),
                    n + 1,
                    line.trim()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "{} line(s) speak of the making, not the product:\n{}",
        found.len(),
        found.join("\n")
    );
}

#[test]
fn the_making_check_finds_what_it_looks_for() {
    assert_eq!(numbered("as measured in session 12"), Some("session "));
    assert_eq!(numbered("see issue 9, point 6"), Some("issue "));
    assert_eq!(numbered("a webdriver session id"), None);
    assert_eq!(numbered("tissue 3"), None);
    assert!(MAKING.iter().any(|p| "on this machine".contains(p)));
}
