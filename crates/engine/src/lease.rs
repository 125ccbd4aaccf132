//! Leases: while one run computes an action, the other runs sharing its cache wait for the
//! entry instead of computing it again (Bazel's remote execution "in-flight deduplication",
//! done with files, as the cache itself is).
//!
//! ```text
//! .vfxgraph/leases/ab/<key>   "host pid": the run computing action <key>, created with
//!                             O_EXCL (atomic on local file systems and NFS v3+), removed
//!                             when the entry is stored or the computation fails
//! ```
//!
//! A lease is *live* while its holder is: on the same host, while its process exists; from
//! another host, while its holder refreshes the file's modification time (every
//! [`HEARTBEAT`], from one thread per process whatever the number of leases held) — a lease
//! older than [`STALE_AFTER`] belongs to a host that died, and is broken. A killed run's
//! leases are therefore broken at once by the next run on its host, and after
//! [`STALE_AFTER`] by runs on other hosts. Two runs breaking the same stale lease at once may
//! both compute the action: work done twice, never a wrong entry (the cache's writes are
//! atomic and content-addressed).

use std::collections::HashSet;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, SystemTime};

/// How often a process refreshes the leases it holds.
pub const HEARTBEAT: Duration = Duration::from_secs(5);
/// A lease from another host not refreshed for this long is stale.
pub const STALE_AFTER: Duration = Duration::from_secs(30);

/// The leases this process holds, refreshed by the heartbeat thread.
fn held() -> &'static Mutex<HashSet<PathBuf>> {
    static HELD: OnceLock<Mutex<HashSet<PathBuf>>> = OnceLock::new();
    HELD.get_or_init(|| {
        // One thread for the whole process, started with the first lease.
        let _ = std::thread::Builder::new()
            .name("vfxgraph-lease-heartbeat".into())
            .spawn(|| loop {
                std::thread::sleep(HEARTBEAT);
                let paths: Vec<PathBuf> = held()
                    .lock()
                    .map(|h| h.iter().cloned().collect())
                    .unwrap_or_default();
                for p in paths {
                    if let Ok(f) = fs::File::options().append(true).open(&p) {
                        let _ = f.set_modified(SystemTime::now());
                    }
                }
            });
        Mutex::new(HashSet::new())
    })
}

/// A lease this process holds; dropping it removes the file.
#[derive(Debug)]
pub struct Lease {
    path: PathBuf,
}

impl Drop for Lease {
    fn drop(&mut self) {
        if let Ok(mut h) = held().lock() {
            h.remove(&self.path);
        }
        let _ = fs::remove_file(&self.path);
    }
}

/// Whether a lease another run holds still counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Holder {
    /// No lease (it was released).
    None,
    /// Its holder is running.
    Live,
    /// Its holder died: the lease may be broken.
    Stale,
}

/// This process's name in a lease: `host pid`.
fn own_id() -> String {
    format!("{} {}", vfxgraph_fsutil::host_name(), std::process::id())
}

/// Takes the lease at `path` if no one holds it: `Ok(None)` when another run (or another
/// instance of this one) does.
pub fn try_take(path: &Path) -> io::Result<Option<Lease>> {
    if let Some(dir) = path.parent() {
        fs::create_dir_all(dir)?;
    }
    let mut f = match fs::File::options().write(true).create_new(true).open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => return Ok(None),
        Err(e) => return Err(e),
    };
    let lease = Lease {
        path: path.to_path_buf(),
    };
    held()
        .lock()
        .map_err(|_| io::Error::other("lease table poisoned"))?
        .insert(path.to_path_buf());
    f.write_all(own_id().as_bytes())?;
    Ok(Some(lease))
}

/// The state of the lease at `path`, judged from this process.
pub fn holder(path: &Path) -> Holder {
    let Ok(meta) = fs::metadata(path) else {
        return Holder::None;
    };
    let age = meta
        .modified()
        .ok()
        .and_then(|t| t.elapsed().ok())
        .unwrap_or_default();
    let text = fs::read_to_string(path).unwrap_or_default();
    let mut words = text.split_whitespace();
    if let (Some(host), Some(pid)) = (words.next(), words.next()) {
        if host == vfxgraph_fsutil::host_name() && Path::new("/proc/self").exists() {
            // Same host: the process is the truth, whatever the file's age.
            return if Path::new("/proc").join(pid).exists() {
                Holder::Live
            } else {
                Holder::Stale
            };
        }
    }
    // Another host (or a lease being written): its heartbeat is the truth.
    if age > STALE_AFTER {
        Holder::Stale
    } else {
        Holder::Live
    }
}

/// Breaks the stale lease at `path` (see the module docs on two breakers).
pub fn break_stale(path: &Path) {
    let _ = fs::remove_file(path);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lease_is_taken_once_released_on_drop_and_broken_when_its_process_is_gone() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ab").join("abcd");
        assert_eq!(holder(&p), Holder::None);
        let lease = try_take(&p).unwrap().expect("free");
        assert!(try_take(&p).unwrap().is_none(), "taken twice");
        assert_eq!(holder(&p), Holder::Live);
        drop(lease);
        assert_eq!(holder(&p), Holder::None);
        assert!(!p.exists());

        // A lease of a process of this host that no longer exists (pids are below 2^22).
        fs::write(
            &p,
            format!("{} {}", vfxgraph_fsutil::host_name(), 1u64 << 40),
        )
        .unwrap();
        assert_eq!(holder(&p), Holder::Stale);
        break_stale(&p);
        assert!(try_take(&p).unwrap().is_some());
    }

    #[test]
    fn another_hosts_lease_is_stale_only_without_heartbeat() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("lease");
        fs::write(&p, "elsewhere.farm 1").unwrap();
        assert_eq!(holder(&p), Holder::Live);
        let f = fs::File::options().append(true).open(&p).unwrap();
        f.set_modified(SystemTime::now() - STALE_AFTER - Duration::from_secs(1))
            .unwrap();
        assert_eq!(holder(&p), Holder::Stale);
    }

    #[test]
    fn the_heartbeat_refreshes_a_held_lease() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("lease");
        let _lease = try_take(&p).unwrap().unwrap();
        let old = SystemTime::now() - Duration::from_secs(3600);
        fs::File::options()
            .append(true)
            .open(&p)
            .unwrap()
            .set_modified(old)
            .unwrap();
        std::thread::sleep(HEARTBEAT + Duration::from_secs(1));
        let m = fs::metadata(&p).unwrap().modified().unwrap();
        assert!(m > old + Duration::from_secs(3000), "not refreshed");
    }
}
