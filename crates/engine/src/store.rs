//! The cache: a content-addressed object store plus an action map (Bazel's CAS + action cache).
//!
//! ```text
//! .vfxgraph/
//!   objects/ab/<digest>   artifact bytes (LZ4-compressed when that pays), named by the
//!                         digest of their uncompressed content
//!   actions/ab/<key>      JSON: the output digests (and written files) of one node instance
//!   records/<node>/       the key components of each node's last run, to explain reruns:
//!                         node.json (type, version, params) and <frame>.json per instance
//!   files/ab/<path hash>  the (path, size, mtime) → digest memo, one file per input file
//!   leases/ab/<key>       the run computing an action now (see [`crate::lease`])
//!   tmp/                  temporaries, renamed into place when complete
//! ```
//!
//! Every write is a temporary file renamed into place, and an action is written only after all
//! its objects, so a crash (even SIGKILL) leaves either a complete entry or none. Reads verify
//! the object's digest; a mismatch is treated as a miss and the object removed. An action,
//! record or memo entry that does not parse is a miss too — which is why the cache's writes
//! skip the fsyncs of the project's other files (`atomic_write_parts_unsynced`): after a power
//! loss a file written just before may be empty or garbage, and reads as absent.
//!
//! Many processes on many hosts may share one cache (NFS semantics: rename within a folder is
//! atomic, no locks across hosts). No file is ever read, modified and written back: objects
//! are content-addressed (racing writers publish identical bytes), an action, record or memo
//! entry is replaced whole by one rename, temporaries are named by host, process and counter,
//! and an LRU touch only sets an action's mtime.

use std::collections::{BTreeMap, HashSet};
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use serde::{Deserialize, Serialize};

use crate::artifact::{content_digest, Digest};
use crate::fsutil::atomic_write_parts_unsynced;
use crate::lease::{self, Holder, Lease};

/// An object whose payload is stored as is.
const OBJECT_MAGIC: &[u8; 5] = b"VFXO1";
/// An object whose payload is an LZ4 block with its uncompressed size prepended (lz4_flex):
/// renders are mostly empty outside the traced pixels, and the cache of a shot's layers
/// shrinks several times over for a few milliseconds a frame.
const OBJECT_MAGIC_LZ4: &[u8; 5] = b"VFXO2";

/// One output of a cached node instance.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ActionOutput {
    /// Output port.
    pub port: String,
    /// Artifact type name.
    pub ty: String,
    /// Content digest (hex).
    pub digest: String,
}

/// A file a writer node wrote, with the digest it had.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct WrittenFile {
    /// Absolute path.
    pub path: PathBuf,
    /// Content digest (hex) of the file as written.
    pub digest: String,
}

/// The cached result of one node instance.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ActionEntry {
    /// Node type.
    pub node_type: String,
    /// Node id in the graph that produced it (informational).
    pub node_id: String,
    /// Frame, for per-frame instances.
    pub frame: Option<i64>,
    /// Outputs by port.
    pub outputs: Vec<ActionOutput>,
    /// Files written.
    #[serde(default)]
    pub files: Vec<WrittenFile>,
    /// Files the node declared reading at run time (`Context::declare_input_file`), with their
    /// digests when read; the entry is valid only while each still has its digest.
    #[serde(default)]
    pub read_files: Vec<WrittenFile>,
    /// Further files the node wrote through `Context::write_file` (beside those its output
    /// path params name), with their digests; the entry is valid only while each still has
    /// its digest. Left out of the JSON when empty, so entries of other nodes are unchanged.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub node_files: Vec<WrittenFile>,
    /// Compute time in seconds.
    pub seconds: f64,
}

/// A summary line of `vfxgraph cache ls`.
#[derive(Clone, Debug, Serialize)]
pub struct EntrySummary {
    /// The cache key (hex).
    pub key: String,
    /// The entry.
    pub entry: ActionEntry,
    /// Bytes of its objects.
    pub bytes: u64,
    /// Last use.
    pub last_used: SystemTime,
}

/// Result of a garbage collection.
#[derive(Clone, Debug, Default, Serialize)]
pub struct GcReport {
    /// Actions removed.
    pub actions_removed: usize,
    /// Objects removed.
    pub objects_removed: usize,
    /// Unreferenced objects kept because they are younger than the grace period.
    pub objects_kept_young: usize,
    /// Bytes freed.
    pub bytes_freed: u64,
    /// Bytes left.
    pub bytes_left: u64,
}

/// The on-disk cache.
#[derive(Debug)]
pub struct Store {
    root: PathBuf,
}

/// The bytes file `m` takes on disk (its blocks), or its length where blocks are unknown.
fn allocated(m: &fs::Metadata) -> u64 {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        m.blocks() * 512
    }
    #[cfg(not(unix))]
    {
        m.len()
    }
}

fn shard(dir: &Path, hex: &str) -> PathBuf {
    dir.join(&hex[..2]).join(hex)
}

impl Store {
    /// Opens (creating) a cache folder, removing temporaries older than an hour (left by a
    /// killed run; younger ones may belong to a concurrent run).
    pub fn open(root: &Path) -> io::Result<Store> {
        for sub in ["objects", "actions", "records", "tmp"] {
            fs::create_dir_all(root.join(sub))?;
        }
        if let Ok(rd) = fs::read_dir(root.join("tmp")) {
            for e in rd.flatten() {
                let old = e
                    .metadata()
                    .and_then(|m| m.modified())
                    .ok()
                    .and_then(|t| t.elapsed().ok())
                    .is_some_and(|age| age > Duration::from_secs(3600));
                if old {
                    let _ = fs::remove_file(e.path());
                }
            }
        }
        Ok(Store {
            root: root.to_path_buf(),
        })
    }

    /// The cache folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where the file-hash memo lives (a folder of one entry per file).
    pub fn file_memo_path(&self) -> PathBuf {
        self.root.join("files")
    }

    /// Writes `bytes` to `dest` with the one atomic writer, its temporary in `tmp/` (swept by
    /// [`Store::open`], never seen by the listings); on any failure (a full disk) the temporary
    /// is removed and the error names `dest`. Not fsynced: every read verifies (module docs).
    fn write_atomic(&self, dest: &Path, bytes: &[&[u8]]) -> io::Result<()> {
        atomic_write_parts_unsynced(dest, bytes, Some(&self.root.join("tmp")))
            .map_err(|e| io::Error::new(e.kind(), format!("cannot write {}: {e}", dest.display())))
    }

    fn object_path(&self, d: &Digest) -> PathBuf {
        shard(&self.root.join("objects"), &d.to_hex())
    }

    fn action_path(&self, key: &Digest) -> PathBuf {
        shard(&self.root.join("actions"), &key.to_hex())
    }

    fn lease_path(&self, key: &Digest) -> PathBuf {
        shard(&self.root.join("leases"), &key.to_hex())
    }

    /// Takes the lease of action `key` (see [`crate::lease`]): `Ok(None)` when another run
    /// computes it.
    pub fn try_lease(&self, key: &Digest) -> io::Result<Option<Lease>> {
        lease::try_take(&self.lease_path(key))
    }

    /// Who holds the lease of action `key`.
    pub fn lease_holder(&self, key: &Digest) -> Holder {
        lease::holder(&self.lease_path(key))
    }

    /// Breaks the stale lease of action `key`.
    pub fn break_lease(&self, key: &Digest) {
        lease::break_stale(&self.lease_path(key))
    }

    /// Stores an encoded artifact under its digest (a no-op if present).
    pub fn put_object(&self, digest: &Digest, type_name: &str, bytes: &[u8]) -> io::Result<()> {
        let path = self.object_path(digest);
        if path.exists() {
            // Present: only its mtime is set, so `gc`'s grace period covers an object about
            // to be named by a new action as well as a freshly written one.
            if let Ok(f) = fs::File::options().append(true).open(&path) {
                let _ = f.set_modified(SystemTime::now());
            }
            return Ok(());
        }
        let name_len = (type_name.len() as u32).to_le_bytes();
        // Compress what compresses (large payloads losing at least an eighth); the rest is
        // stored as is and read without a copy through the decompressor.
        let packed = (bytes.len() >= 4096)
            .then(|| lz4_flex::block::compress_prepend_size(bytes))
            .filter(|p| p.len() < bytes.len() - bytes.len() / 8);
        let (magic, payload) = match &packed {
            Some(p) => (OBJECT_MAGIC_LZ4, p.as_slice()),
            None => (OBJECT_MAGIC, bytes),
        };
        self.write_atomic(&path, &[magic, &name_len, type_name.as_bytes(), payload])
    }

    /// True if an object file exists (not verified).
    pub fn has_object(&self, digest: &Digest) -> bool {
        self.object_path(digest).is_file()
    }

    /// Reads and verifies an object: its type name and encoded bytes. A corrupt object is
    /// removed and reported as absent.
    pub fn get_object(&self, digest: &Digest) -> Option<(String, Vec<u8>)> {
        let path = self.object_path(digest);
        let raw = fs::read(&path).ok()?;
        let parsed = (|| {
            let (compressed, rest) = match raw.strip_prefix(OBJECT_MAGIC_LZ4) {
                Some(rest) => (true, rest),
                None => (false, raw.strip_prefix(OBJECT_MAGIC)?),
            };
            let n = u32::from_le_bytes(rest.get(..4)?.try_into().ok()?) as usize;
            let name = std::str::from_utf8(rest.get(4..4 + n)?).ok()?;
            let stored = rest.get(4 + n..)?;
            let payload = if compressed {
                // A corrupt size prefix must not allocate without bound: LZ4 expands at
                // most 255×.
                let size = u32::from_le_bytes(stored.get(..4)?.try_into().ok()?) as usize;
                if size > stored.len().saturating_mul(255) {
                    return None;
                }
                lz4_flex::block::decompress_size_prepended(stored).ok()?
            } else {
                stored.to_vec()
            };
            (content_digest(name, &payload) == *digest).then(|| (name.to_string(), payload))
        })();
        if parsed.is_none() {
            tracing::warn!("cache object {} is corrupt; removing it", digest.short());
            let _ = fs::remove_file(&path);
        }
        parsed
    }

    /// Looks up an action. An unreadable entry is a miss.
    pub fn get_action(&self, key: &Digest) -> Option<ActionEntry> {
        let bytes = fs::read(self.action_path(key)).ok()?;
        serde_json::from_slice(&bytes).ok()
    }

    /// Records an action (after its objects).
    pub fn put_action(&self, key: &Digest, entry: &ActionEntry) -> io::Result<()> {
        let bytes = serde_json::to_vec_pretty(entry).map_err(io::Error::other)?;
        self.write_atomic(&self.action_path(key), &[&bytes])
    }

    /// Removes an action (e.g. when its objects are gone).
    pub fn remove_action(&self, key: &Digest) {
        let _ = fs::remove_file(self.action_path(key));
    }

    /// Marks an action as used now (for least-recently-used collection): only its mtime is
    /// set (one metadata update; concurrent touches and a concurrent replace are harmless).
    pub fn touch_action(&self, key: &Digest) {
        if let Ok(f) = fs::File::options().append(true).open(self.action_path(key)) {
            let _ = f.set_modified(SystemTime::now());
        }
    }

    /// Reads a record file (see [`crate::exec`]).
    pub fn get_record<T: serde::de::DeserializeOwned>(&self, name: &str) -> Option<T> {
        let bytes = fs::read(self.root.join("records").join(name)).ok()?;
        serde_json::from_slice(&bytes).ok()
    }

    /// Writes a record file.
    pub fn put_record<T: Serialize>(&self, name: &str, value: &T) -> io::Result<()> {
        let bytes = serde_json::to_vec(value).map_err(io::Error::other)?;
        self.write_atomic(&self.root.join("records").join(name), &[&bytes])
    }

    fn walk(dir: &Path) -> Vec<(PathBuf, fs::Metadata)> {
        let mut out = Vec::new();
        if let Ok(shards) = fs::read_dir(dir) {
            for s in shards.flatten() {
                if let Ok(files) = fs::read_dir(s.path()) {
                    for f in files.flatten() {
                        if let Ok(m) = f.metadata() {
                            if m.is_file() {
                                out.push((f.path(), m));
                            }
                        }
                    }
                }
            }
        }
        out
    }

    fn object_size(&self, hex: &str) -> u64 {
        fs::metadata(shard(&self.root.join("objects"), hex))
            .map(|m| m.len())
            .unwrap_or(0)
    }

    /// All actions, most recently used first.
    pub fn list(&self) -> Vec<EntrySummary> {
        let mut out = Vec::new();
        for (path, meta) in Self::walk(&self.root.join("actions")) {
            let Some(entry) = fs::read(&path)
                .ok()
                .and_then(|b| serde_json::from_slice::<ActionEntry>(&b).ok())
            else {
                continue;
            };
            let bytes = entry
                .outputs
                .iter()
                .map(|o| self.object_size(&o.digest))
                .sum::<u64>()
                + meta.len();
            out.push(EntrySummary {
                key: path
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                entry,
                bytes,
                last_used: meta.modified().unwrap_or(SystemTime::UNIX_EPOCH),
            });
        }
        out.sort_by(|a, b| b.last_used.cmp(&a.last_used).then(a.key.cmp(&b.key)));
        out
    }

    /// What the whole cache folder takes on disk: `(bytes allocated, files)` over every file
    /// (objects, actions, records, the file memo, temporaries, leases). Allocated, not
    /// apparent, sizes: a cache of many small entries takes a block each (a million 200-byte
    /// entries are ~4 GB, not 200 MB).
    pub fn disk_usage_detail(&self) -> (u64, u64) {
        let (mut bytes, mut files) = (0u64, 0u64);
        let mut dirs = vec![self.root.clone()];
        while let Some(d) = dirs.pop() {
            let Ok(rd) = fs::read_dir(&d) else { continue };
            for e in rd.flatten() {
                let Ok(m) = e.metadata() else { continue };
                if m.is_dir() {
                    dirs.push(e.path());
                } else {
                    bytes += allocated(&m);
                    files += 1;
                }
            }
        }
        (bytes, files)
    }

    /// Bytes the whole cache folder takes on disk (see [`Store::disk_usage_detail`]).
    pub fn disk_usage(&self) -> u64 {
        self.disk_usage_detail().0
    }

    /// Removes objects no action refers to, then (with `max_bytes`) the least recently used
    /// actions until the cache fits, and their newly unreferenced objects. Objects written or
    /// re-put within `grace` are kept even when unreferenced: a concurrent writer (another
    /// process, a farm task) writes its objects before the action naming them, so an object
    /// without an action may be one about to get it.
    pub fn gc(&self, max_bytes: Option<u64>, grace: Duration) -> GcReport {
        let mut report = GcReport::default();
        let mut actions = self.list();
        if let Some(max) = max_bytes {
            // Newest first: keep while the running total fits.
            let mut total = 0u64;
            let mut keep = Vec::new();
            for a in actions {
                if total + a.bytes <= max {
                    total += a.bytes;
                    keep.push(a);
                } else if let Some(k) = Digest::from_hex(&a.key) {
                    self.remove_action(&k);
                    report.actions_removed += 1;
                }
            }
            actions = keep;
        }
        let live: HashSet<String> = actions
            .iter()
            .flat_map(|a| a.entry.outputs.iter().map(|o| o.digest.clone()))
            .collect();
        for (path, meta) in Self::walk(&self.root.join("objects")) {
            let name = path
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            if live.contains(&name) {
                continue;
            }
            let young = meta
                .modified()
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_none_or(|age| age < grace);
            if young {
                report.objects_kept_young += 1;
            } else if fs::remove_file(&path).is_ok() {
                report.objects_removed += 1;
                report.bytes_freed += meta.len();
            }
        }
        report.bytes_left = self.disk_usage();
        report
    }

    /// Deletes everything in the cache.
    pub fn clear(&self) -> io::Result<()> {
        for sub in ["objects", "actions", "records", "files", "tmp"] {
            let p = self.root.join(sub);
            if p.exists() {
                fs::remove_dir_all(&p)?;
            }
            fs::create_dir_all(&p)?;
        }
        // The single-file memo of earlier versions.
        let _ = fs::remove_file(self.root.join("files.json"));
        Ok(())
    }

    /// Number of objects per type, for `cache du`.
    pub fn usage_by_type(&self) -> BTreeMap<String, (usize, u64)> {
        let mut out: BTreeMap<String, (usize, u64)> = BTreeMap::new();
        for a in self.list() {
            for o in &a.entry.outputs {
                let e = out.entry(o.ty.clone()).or_default();
                e.0 += 1;
                e.1 += self.object_size(&o.digest);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_objects_are_compressed_and_corruption_is_a_miss() {
        let dir = tempfile::tempdir().unwrap();
        let s = Store::open(dir.path()).unwrap();
        // A render: mostly zero, some varied values.
        let payload: Vec<u8> = (0..1_000_000u32)
            .flat_map(|i| {
                let v = if i % 10 == 0 { (i as f32).sin() } else { 0.0 };
                v.to_le_bytes()
            })
            .collect();
        let d = content_digest("image", &payload);
        s.put_object(&d, "image", &payload).unwrap();
        let p = s.object_path(&d);
        let size = fs::metadata(&p).unwrap().len() as usize;
        assert!(size < payload.len() / 3, "{size} bytes on disk");
        assert_eq!(s.get_object(&d), Some(("image".into(), payload.clone())));
        // Incompressible payloads are stored as they are.
        let mut noise = vec![0u8; 100_000];
        blake3::Hasher::new()
            .update(b"noise")
            .finalize_xof()
            .fill(&mut noise);
        let dn = content_digest("bytes", &noise);
        s.put_object(&dn, "bytes", &noise).unwrap();
        assert!(fs::read(s.object_path(&dn))
            .unwrap()
            .starts_with(OBJECT_MAGIC));
        assert_eq!(s.get_object(&dn), Some(("bytes".into(), noise)));
        // A flipped byte inside the compressed stream, a huge size prefix, a truncation: a
        // miss each time (never a panic), and the object is removed.
        let raw = fs::read(&p).unwrap();
        let header = OBJECT_MAGIC_LZ4.len() + 4 + "image".len();
        let mut flipped = raw.clone();
        flipped[raw.len() / 2] ^= 0x55;
        let mut huge = raw.clone();
        huge[header..header + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let truncated = raw[..raw.len() - 7].to_vec();
        for bad in [flipped, huge, truncated] {
            fs::write(&p, &bad).unwrap();
            assert_eq!(s.get_object(&d), None);
            assert!(!s.has_object(&d));
        }
    }

    #[test]
    fn objects_round_trip_and_corruption_is_a_miss() {
        let dir = tempfile::tempdir().unwrap();
        let s = Store::open(dir.path()).unwrap();
        let d = content_digest("float", b"1.5");
        s.put_object(&d, "float", b"1.5").unwrap();
        assert_eq!(s.get_object(&d), Some(("float".into(), b"1.5".to_vec())));
        // Corrupt it: the read is a miss and the object is gone.
        let p = s.object_path(&d);
        let mut raw = fs::read(&p).unwrap();
        let last = raw.len() - 1;
        raw[last] ^= 1;
        fs::write(&p, raw).unwrap();
        assert_eq!(s.get_object(&d), None);
        assert!(!s.has_object(&d));
    }

    /// The usage `cache du` reports is what `du` sees: many small entries take a block each.
    #[test]
    #[cfg(target_os = "linux")]
    fn disk_usage_counts_blocks_of_every_file_as_du_does() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        for i in 0..500u32 {
            let bytes = i.to_le_bytes();
            let d = content_digest("t", &bytes);
            store.put_object(&d, "t", &bytes).unwrap();
        }
        let (ours, files) = store.disk_usage_detail();
        assert_eq!(files, 500);
        let du = std::process::Command::new("du")
            .args(["-s", "--block-size=1"])
            .arg(dir.path())
            .output()
            .unwrap();
        let du: u64 = String::from_utf8_lossy(&du.stdout)
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap();
        // `du` also counts the folders (root, 4 subfolders, up to 256 shards).
        let dirs = fs::read_dir(dir.path().join("objects")).unwrap().count() as u64 + 5;
        assert!(
            ours <= du && du - ours <= dirs * 4096,
            "ours {ours}, du {du}"
        );
        assert!(ours >= 500 * 512, "{ours}: apparent sizes, not blocks");
    }

    #[test]
    fn gc_keeps_live_objects() {
        let dir = tempfile::tempdir().unwrap();
        let s = Store::open(dir.path()).unwrap();
        let live = content_digest("string", b"\"a\"");
        let dead = content_digest("string", b"\"b\"");
        s.put_object(&live, "string", b"\"a\"").unwrap();
        s.put_object(&dead, "string", b"\"b\"").unwrap();
        let key = Digest::of(b"key");
        s.put_action(
            &key,
            &ActionEntry {
                node_type: "t".into(),
                node_id: "n".into(),
                frame: None,
                outputs: vec![ActionOutput {
                    port: "out".into(),
                    ty: "string".into(),
                    digest: live.to_hex(),
                }],
                files: vec![],
                read_files: vec![],
                node_files: vec![],
                seconds: 0.0,
            },
        )
        .unwrap();
        // Within the grace period the unreferenced object stays (a writer may be about to
        // name it); past it, it goes.
        let r = s.gc(None, Duration::from_secs(3600));
        assert_eq!((r.objects_removed, r.objects_kept_young), (0, 1));
        assert!(s.has_object(&dead));
        let r = s.gc(None, Duration::ZERO);
        assert_eq!(r.objects_removed, 1);
        assert!(s.has_object(&live) && !s.has_object(&dead));
        // An old unreferenced object put again (a writer about to name it) is young again.
        s.put_object(&dead, "string", b"\"b\"").unwrap();
        let old = SystemTime::now() - Duration::from_secs(7200);
        fs::File::options()
            .append(true)
            .open(s.object_path(&dead))
            .unwrap()
            .set_modified(old)
            .unwrap();
        s.put_object(&dead, "string", b"\"b\"").unwrap();
        let r = s.gc(None, Duration::from_secs(3600));
        assert_eq!((r.objects_removed, r.objects_kept_young), (0, 1));
        let r = s.gc(None, Duration::ZERO);
        assert_eq!(r.objects_removed, 1);
        let r = s.gc(Some(0), Duration::ZERO);
        assert_eq!(r.actions_removed, 1);
        assert!(!s.has_object(&live));
        assert_eq!(s.list().len(), 0);
    }
}
