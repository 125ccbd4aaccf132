//! File helpers: atomic writes (the project's one writer, `vfxgraph-fsutil`, re-exported), and
//! content hashing of files with a (path, size, mtime) memo.
//!
//! Both are safe for many processes on many hosts sharing one folder (NFS semantics: a rename
//! within a folder is atomic, there are no locks across hosts): temporaries have names unique
//! to the host, process and call, and the memo is one small file per input file, each
//! replaced whole.

use std::collections::HashMap;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use crate::artifact::Digest;

pub use vfxgraph_fsutil::{
    atomic_write, atomic_write_parts, atomic_write_parts_unsynced, unique_token,
};

/// Digest of a file's content (blake3 of the bytes, with a prefix so it differs from artifact
/// digests).
pub fn hash_file(path: &Path) -> io::Result<Digest> {
    let mut h = blake3::Hasher::new();
    h.update(b"file\0");
    h.update_reader(fs::File::open(path)?)?;
    Ok(Digest(*h.finalize().as_bytes()))
}

/// One memoized file: `files/ab/<blake3 of the path>` holds it, replaced whole.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
struct MemoEntry {
    /// The file (the entry's name is a hash of it; kept to rule out a collision).
    #[serde(default)]
    path: PathBuf,
    size: u64,
    mtime_ns: u128,
    digest: String,
}

/// Hashes files by content, remembering (path, size, mtime) → digest so that unchanged files
/// are not read again. A file modified within the last two seconds is not memoized (its mtime
/// could still change within the same clock tick: git's "racy" case).
///
/// A persistent memo is a folder of one entry file per input file, each written atomically
/// when its file is hashed: concurrent processes never merge or rewrite a shared file, and two
/// of them memoizing one file write the same entry.
#[derive(Debug, Default)]
pub struct FileHasher {
    memo: Mutex<HashMap<PathBuf, MemoEntry>>,
    dir: Option<PathBuf>,
}

impl FileHasher {
    /// A hasher with no persistent memo.
    pub fn in_memory() -> Self {
        FileHasher::default()
    }

    /// A hasher whose memo entries live in the folder `dir` (created on the first write). A
    /// missing or corrupt entry is a miss.
    pub fn persistent(dir: PathBuf) -> Self {
        FileHasher {
            memo: Mutex::new(HashMap::new()),
            dir: Some(dir),
        }
    }

    fn entry_path(&self, path: &Path) -> Option<PathBuf> {
        let hex = blake3::hash(path.as_os_str().as_encoded_bytes()).to_hex();
        self.dir
            .as_ref()
            .map(|d| d.join(&hex[..2]).join(&hex[..32]))
    }

    /// The memoized entry for `path`: this process's, else the shared folder's.
    fn remembered(&self, path: &Path) -> Option<MemoEntry> {
        if let Some(e) = self.memo.lock().expect("memo lock").get(path) {
            return Some(e.clone());
        }
        let bytes = fs::read(self.entry_path(path)?).ok()?;
        serde_json::from_slice::<MemoEntry>(&bytes)
            .ok()
            .filter(|e| e.path == path)
    }

    fn remember(&self, entry: MemoEntry) {
        if let Some(p) = self.entry_path(&entry.path) {
            if let Ok(bytes) = serde_json::to_vec(&entry) {
                // A failure only costs re-hashing later; unsynced, as the cache's other files
                // (a damaged entry fails to parse and is re-hashed).
                let _ = atomic_write_parts_unsynced(&p, &[&bytes], None);
            }
        }
        self.memo
            .lock()
            .expect("memo lock")
            .insert(entry.path.clone(), entry);
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
        if let Some(e) = self.remembered(path) {
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
        if racy {
            self.memo.lock().expect("memo lock").remove(path);
        } else {
            self.remember(MemoEntry {
                path: path.to_path_buf(),
                size,
                mtime_ns,
                digest: digest.to_hex(),
            });
        }
        Ok(digest)
    }

    /// Kept for callers of the whole-file memo: entries are now written as they are made.
    pub fn save(&self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

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
