//! File helpers: atomic writes, and content hashing of files with a (path, size, mtime) memo.

use std::collections::HashMap;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use crate::artifact::Digest;

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A temporary name beside `path`, unique to this process and call.
fn temp_beside(path: &Path) -> PathBuf {
    let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, then a rename.
/// Readers see the old file or the whole new one, never a part; a crash leaves at most a
/// stray temporary. Parent folders are created.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    if let Some(parent) = path.parent() {
        if !parent.as_os_str().is_empty() {
            fs::create_dir_all(parent)?;
        }
    }
    let tmp = temp_beside(path);
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.flush()?;
        drop(f);
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Digest of a file's content (blake3 of the bytes, with a prefix so it differs from artifact
/// digests).
pub fn hash_file(path: &Path) -> io::Result<Digest> {
    let mut h = blake3::Hasher::new();
    h.update(b"file\0");
    h.update_reader(fs::File::open(path)?)?;
    Ok(Digest(*h.finalize().as_bytes()))
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
struct MemoEntry {
    size: u64,
    mtime_ns: u128,
    digest: String,
}

/// Hashes files by content, remembering (path, size, mtime) → digest so that unchanged files
/// are not read again. A file modified within the last two seconds is not memoized (its mtime
/// could still change within the same clock tick: git's "racy" case).
#[derive(Debug, Default)]
pub struct FileHasher {
    memo: Mutex<HashMap<PathBuf, MemoEntry>>,
    dirty: std::sync::atomic::AtomicBool,
    path: Option<PathBuf>,
}

impl FileHasher {
    /// A hasher with no persistent memo.
    pub fn in_memory() -> Self {
        FileHasher::default()
    }

    /// A hasher whose memo is loaded from (and saved to) `path`. A missing or corrupt memo
    /// starts empty.
    pub fn persistent(path: PathBuf) -> Self {
        let memo = fs::read(&path)
            .ok()
            .and_then(|b| serde_json::from_slice::<HashMap<PathBuf, MemoEntry>>(&b).ok())
            .unwrap_or_default();
        FileHasher {
            memo: Mutex::new(memo),
            dirty: Default::default(),
            path: Some(path),
        }
    }

    /// The content digest of `path`.
    pub fn hash(&self, path: &Path) -> io::Result<Digest> {
        let meta = fs::metadata(path)?;
        if !meta.is_file() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{} is not a file", path.display()),
            ));
        }
        let mtime = meta.modified().unwrap_or(UNIX_EPOCH);
        let mtime_ns = mtime
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos();
        let size = meta.len();
        if let Some(e) = self.memo.lock().expect("memo lock").get(path) {
            if e.size == size && e.mtime_ns == mtime_ns {
                if let Some(d) = Digest::from_hex(&e.digest) {
                    return Ok(d);
                }
            }
        }
        let digest = hash_file(path)?;
        let racy = SystemTime::now()
            .duration_since(mtime)
            .map(|age| age < Duration::from_secs(2))
            .unwrap_or(true);
        let mut memo = self.memo.lock().expect("memo lock");
        if racy {
            memo.remove(path);
        } else {
            memo.insert(
                path.to_path_buf(),
                MemoEntry {
                    size,
                    mtime_ns,
                    digest: digest.to_hex(),
                },
            );
        }
        self.dirty.store(true, Ordering::Relaxed);
        Ok(digest)
    }

    /// Saves the memo if it changed (atomically; a failure only costs re-hashing later).
    pub fn save(&self) {
        if let Some(path) = &self.path {
            if self.dirty.load(Ordering::Relaxed) {
                let memo = self.memo.lock().expect("memo lock");
                if let Ok(bytes) = serde_json::to_vec(&*memo) {
                    let _ = atomic_write(path, &bytes);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/a.txt");
        atomic_write(&p, b"one").unwrap();
        atomic_write(&p, b"two!").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two!");
        let stray: Vec<_> = fs::read_dir(dir.path().join("sub"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(stray.len(), 1, "no temporaries left: {stray:?}");
    }

    #[test]
    fn hasher_sees_content_not_mtime() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.bin");
        fs::write(&p, b"abc").unwrap();
        let h = FileHasher::in_memory();
        let d1 = h.hash(&p).unwrap();
        fs::write(&p, b"abc").unwrap();
        assert_eq!(h.hash(&p).unwrap(), d1);
        fs::write(&p, b"abd").unwrap();
        assert_ne!(h.hash(&p).unwrap(), d1);
        assert!(h.hash(&dir.path().join("missing")).is_err());
    }
}
