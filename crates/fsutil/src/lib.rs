//! The one atomic file writer of vfxgraph: every file the engine, a node or an algorithm crate
//! writes (cache objects, action entries, records, images, videos, camera files, plots) goes
//! through [`atomic_write`] or [`atomic_write_parts`] (the cache through
//! [`atomic_write_parts_unsynced`], the same without the fsyncs: it verifies what it reads).
//!
//! A write creates the file's folders, writes a temporary with a name unique to the host,
//! process and call ([`unique_token`]) on the same file system, fsyncs it, renames it over the
//! file and fsyncs the folder (where the platform and file system allow it). Readers see the
//! old file or the whole new one, never a part; after a crash the file is the old one or the
//! new one, and at most a stray temporary (named `.vfxgraph-tmp-…`) is left.
//!
//! Safe for many processes on many hosts sharing one folder (NFS semantics: a rename within a
//! file system is atomic, there are no locks across hosts): no two writers ever share a
//! temporary.
//!
//! Its own crate because both the engine and the algorithm crates (imaging, geometry, video, …)
//! write files, and neither may depend on the other; it depends on nothing. For the same reason it
//! holds the frame patterns of file names ([`frame_pattern`]), which graphs and exports share.

pub mod frame_pattern;

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

/// The prefix of every temporary: a stray one left by a killed process is recognisable.
pub const TEMP_PREFIX: &str = ".vfxgraph-tmp-";

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A name unique to this host, process and call: `host-pid-n`. Process ids repeat across the
/// hosts of a farm writing into one shared folder; host names do not.
pub fn unique_token() -> String {
    let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    format!("{}-{}-{n}", host_name(), std::process::id())
}

/// This host's name, reduced to ASCII letters, digits, `.` and `_` (`host` when unknown).
pub fn host_name() -> &'static str {
    static HOST: OnceLock<String> = OnceLock::new();
    HOST.get_or_init(|| {
        let raw = fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let clean: String = raw
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '.' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if clean.is_empty() {
            "host".into()
        } else {
            clean
        }
    })
}

/// A temporary name beside `path`, unique to this host, process and call:
/// `.vfxgraph-tmp-<token>.<file name>` (the name cut to 100 bytes, so the temporary's name stays
/// within the file system's limit).
fn temp_beside(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut cut = name.len().min(100);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    path.with_file_name(format!("{TEMP_PREFIX}{}.{}", unique_token(), &name[..cut]))
}

/// The folder `path` is in (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Writes `bytes` to `path` atomically (see the crate's documentation): folders created,
/// temporary beside the file, fsync, rename, folder fsync.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    atomic_write_parts(path, &[bytes], None)
}

/// [`atomic_write`] of the concatenation of `parts`, with the temporary in `temp_dir` instead of
/// beside the file when given: a folder on the same file system that its owner sweeps (the
/// cache's `tmp/`, whose stale temporaries the store removes, and which keeps them out of the
/// folders it lists). On failure the temporary is removed.
pub fn atomic_write_parts(path: &Path, parts: &[&[u8]], temp_dir: Option<&Path>) -> io::Result<()> {
    write_parts(path, parts, temp_dir, true)
}

/// [`atomic_write_parts`] without the two fsyncs: readers still see the old file or the whole
/// new one, and a killed process leaves no part of a file, but after a power loss or an
/// operating-system crash the new file may be empty or garbage. Only for stores that verify
/// what they read and treat a bad file as absent — the cache, whose objects are named by the
/// digest of their content and checked on every read, and whose actions, records and memo
/// entries are JSON that a damaged file fails to parse — where an fsync per file would cost a
/// node's run more than its work (a 48-frame track and solve wrote 149 files: 0.1 s of 1.2 s).
pub fn atomic_write_parts_unsynced(
    path: &Path,
    parts: &[&[u8]],
    temp_dir: Option<&Path>,
) -> io::Result<()> {
    write_parts(path, parts, temp_dir, false)
}

fn write_parts(
    path: &Path,
    parts: &[&[u8]],
    temp_dir: Option<&Path>,
    sync: bool,
) -> io::Result<()> {
    let folder = folder_of(path);
    fs::create_dir_all(folder)?;
    let tmp = match temp_dir {
        Some(dir) => dir.join(format!("{TEMP_PREFIX}{}", unique_token())),
        None => temp_beside(path),
    };
    let result = (|| {
        let mut f = fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)?;
        for part in parts {
            f.write_all(part)?;
        }
        if sync {
            f.sync_all()?;
        }
        drop(f);
        fs::rename(&tmp, path)?;
        if sync {
            sync_folder(folder);
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Makes a rename in `folder` durable: fsync of the folder on Unix. Some file systems refuse it
/// (the rename itself has succeeded and is atomic either way), so a failure is ignored.
fn sync_folder(folder: &Path) {
    #[cfg(unix)]
    if let Ok(dir) = fs::File::open(folder) {
        let _ = dir.sync_all();
    }
    #[cfg(not(unix))]
    let _ = folder;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/a.txt");
        atomic_write(&p, b"one").unwrap();
        atomic_write(&p, b"two!").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two!");
        // The unsynced form replaces the same way, its temporary in a given folder.
        let tmp = dir.path().join("tmp");
        fs::create_dir_all(&tmp).unwrap();
        atomic_write_parts_unsynced(&p, &[b"thr", b"ee"], Some(&tmp)).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"three");
        assert_eq!(fs::read_dir(&tmp).unwrap().count(), 0, "temporary renamed");
        let stray: Vec<_> = fs::read_dir(dir.path().join("sub"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(stray.len(), 1, "no temporaries left: {stray:?}");
    }

    #[test]
    fn parts_are_concatenated_and_the_temporary_can_live_elsewhere() {
        let dir = tempfile::tempdir().unwrap();
        let tmp = dir.path().join("tmp");
        fs::create_dir_all(&tmp).unwrap();
        let p = dir.path().join("objects/ab/x");
        atomic_write_parts(&p, &[b"ab", b"", b"cd"], Some(&tmp)).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"abcd");
        assert!(names(&tmp).is_empty());
    }

    #[test]
    fn a_failed_write_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        // The target is a folder: the rename fails.
        let p = dir.path().join("taken");
        fs::create_dir_all(p.join("inside")).unwrap();
        assert!(atomic_write(&p, b"x").is_err());
        assert_eq!(names(dir.path()), ["taken"]);
    }

    #[test]
    fn temporaries_are_unique_and_marked() {
        let long = "n".repeat(250);
        let a = temp_beside(Path::new(&long));
        let b = temp_beside(Path::new(&long));
        assert_ne!(a, b);
        let name = a.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with(TEMP_PREFIX) && name.len() < 200, "{name}");
        assert!(unique_token().contains(&format!("-{}-", std::process::id())));
    }
}
