//! What a campaign's supervisor and its worker processes share, all in one work folder per
//! target: the run's settings (`config.json`), the target's seeds (`seeds.bin`, written once
//! so every worker runs exactly the same seeds), a status block of counters in a shared memory
//! map (`status`: the worker updates it after every input, the supervisor reads it while the
//! worker runs and after it died, whatever killed it), an append-only log of events
//! (`events`: one JSON line per rare event — a panic, the first contained panic, a refused
//! seed, a hang or an allocation over the bound — each written with one `write` so it survives
//! the worker's death), and the worker's stderr (`stderr`, for the message of a fatal signal).
//!
//! Positions: a worker runs positions `start..seeds + inputs`; position `p < seeds` is seed
//! `p` as it is, position `seeds + i` is mutated input `i`.

use std::fs::{File, OpenOptions};
use std::io::{self, Read, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde::{Deserialize, Serialize};

/// The run's settings, as the supervisor hands them to its workers.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Config {
    /// The target's name.
    pub target: String,
    /// The run's seed.
    pub seed: u64,
    /// Mutated inputs (after the seeds).
    pub inputs: u64,
    /// The time bound of one input, ms.
    pub timeout_ms: u64,
    /// The memory bound, bytes.
    pub max_alloc: usize,
    /// Threads of the decoders' rayon pool.
    pub threads: usize,
}

/// The work folder's files.
pub struct WorkDir {
    /// Its path.
    pub path: PathBuf,
}

impl WorkDir {
    /// The settings.
    pub fn config(&self) -> PathBuf {
        self.path.join("config.json")
    }
    /// The seeds.
    pub fn seeds(&self) -> PathBuf {
        self.path.join("seeds.bin")
    }
    /// The status block.
    pub fn status(&self) -> PathBuf {
        self.path.join("status")
    }
    /// The event log.
    pub fn events(&self) -> PathBuf {
        self.path.join("events")
    }
    /// The worker's stderr.
    pub fn stderr(&self) -> PathBuf {
        self.path.join("stderr")
    }
}

/// Writes seeds as `count, then (name length, name, length, bytes)` each, u64 little-endian.
pub fn write_seeds(path: &Path, seeds: &[(String, Vec<u8>)]) -> io::Result<()> {
    let mut out = Vec::new();
    out.extend_from_slice(&(seeds.len() as u64).to_le_bytes());
    for (name, bytes) in seeds {
        out.extend_from_slice(&(name.len() as u64).to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    std::fs::write(path, out)
}

/// The rest of a seeds file being read.
struct Cursor<'a>(&'a [u8]);

impl<'a> Cursor<'a> {
    fn take(&mut self, n: u64) -> io::Result<&'a [u8]> {
        let n = usize::try_from(n)
            .ok()
            .filter(|&n| n <= self.0.len())
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidData, "truncated seeds file"))?;
        let (head, tail) = self.0.split_at(n);
        self.0 = tail;
        Ok(head)
    }
    fn number(&mut self) -> io::Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
}

/// Reads what [`write_seeds`] wrote.
pub fn read_seeds(path: &Path) -> io::Result<Vec<(String, Vec<u8>)>> {
    let data = std::fs::read(path)?;
    let mut c = Cursor(&data);
    let count = c.number()?;
    let mut seeds = Vec::with_capacity(count.min(1 << 16) as usize);
    for _ in 0..count {
        let n = c.number()?;
        let name = String::from_utf8_lossy(c.take(n)?).into_owned();
        let n = c.number()?;
        seeds.push((name, c.take(n)?.to_vec()));
    }
    Ok(seeds)
}

/// The slots of the status block.
pub mod slot {
    /// Position + 1 of the input being made or run (0: none yet).
    pub const CURRENT: usize = 0;
    /// Position + 1 of the last input finished (0: none yet).
    pub const DONE: usize = 1;
    /// Inputs finished.
    pub const EXECUTIONS: usize = 2;
    /// Inputs the reader accepted.
    pub const ACCEPTED: usize = 3;
    /// Inputs with a contained panic.
    pub const CONTAINED: usize = 4;
    /// The slowest finished input, µs.
    pub const SLOWEST_US: usize = 5;
    /// The largest rise of live bytes during one finished input.
    pub const PEAK_BYTES: usize = 6;
    /// How many slots there are.
    pub const COUNT: usize = 7;
}

/// The status block: [`slot::COUNT`] counters in a file mapped shared by both processes.
pub struct Status {
    ptr: *mut AtomicU64,
    _file: File,
}

// SAFETY: the mapping is only accessed through atomics and lives as long as the value.
unsafe impl Send for Status {}
unsafe impl Sync for Status {}

const STATUS_LEN: usize = 4096;

impl Status {
    /// Maps the block at `path` (created, zero-filled, when missing).
    pub fn map(path: &Path) -> io::Result<Status> {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)?;
        if file.metadata()?.len() < STATUS_LEN as u64 {
            file.set_len(STATUS_LEN as u64)?;
        }
        // SAFETY: a shared read-write mapping of a file at least STATUS_LEN long; page-aligned,
        // so each slot is an aligned u64.
        let ptr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                STATUS_LEN,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if ptr == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        Ok(Status {
            ptr: ptr.cast(),
            _file: file,
        })
    }

    fn at(&self, i: usize) -> &AtomicU64 {
        assert!(i < slot::COUNT);
        // SAFETY: in bounds of the live mapping, aligned; AtomicU64 has u64's layout.
        unsafe { &*self.ptr.add(i) }
    }

    /// The value of slot `i`.
    pub fn get(&self, i: usize) -> u64 {
        self.at(i).load(Ordering::SeqCst)
    }

    /// Sets slot `i`.
    pub fn set(&self, i: usize, v: u64) {
        self.at(i).store(v, Ordering::SeqCst)
    }

    /// Adds to slot `i`.
    pub fn add(&self, i: usize, v: u64) {
        self.at(i).fetch_add(v, Ordering::SeqCst);
    }

    /// Raises slot `i` to `v`.
    pub fn max(&self, i: usize, v: u64) {
        self.at(i).fetch_max(v, Ordering::SeqCst);
    }

    /// Sets every slot to 0 (before a worker starts).
    pub fn clear(&self) {
        for i in 0..slot::COUNT {
            self.set(i, 0);
        }
    }
}

impl Drop for Status {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `map`.
        unsafe {
            libc::munmap(self.ptr.cast(), STATUS_LEN);
        }
    }
}

/// What an event reports.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum EventKind {
    /// A panic escaped the reader (the worker goes on).
    Crash,
    /// The worker's first contained panic.
    Contained,
    /// A seed the reader refused.
    Refused,
    /// An input ran past the time bound.
    Hang,
    /// An allocation over the bound.
    OverAlloc,
}

/// One line of the event log.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Event {
    /// What happened.
    pub kind: EventKind,
    /// The input's position (`None`: outside of an input).
    pub pos: Option<u64>,
    /// The message (a panic's message and location, the bound crossed…).
    pub message: String,
    /// Whether the worker exits after it.
    pub fatal: bool,
}

/// Opens the event log for appending.
pub fn open_events(path: &Path) -> io::Result<File> {
    OpenOptions::new().create(true).append(true).open(path)
}

/// Appends `event` as one line with one `write`.
pub fn write_event(log: &File, event: &Event) -> io::Result<()> {
    let mut line = serde_json::to_vec(event).map_err(io::Error::other)?;
    line.push(b'\n');
    let mut log = log;
    log.write_all(&line)
}

/// The events of the log at `path` (lines that do not parse, e.g. a last line cut by a
/// kill, are skipped).
pub fn read_events(path: &Path) -> Vec<Event> {
    let mut s = String::new();
    if let Ok(mut f) = File::open(path) {
        let _ = f.read_to_string(&mut s);
    }
    s.lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// The last `lines` non-empty lines of the file at `path` (from its last 4 KiB).
pub fn tail(path: &Path, lines: usize) -> Vec<String> {
    use std::io::{Seek, SeekFrom};
    let mut buf = Vec::new();
    if let Ok(mut f) = File::open(path) {
        let len = f.metadata().map(|m| m.len()).unwrap_or(0);
        let _ = f.seek(SeekFrom::Start(len.saturating_sub(4096)));
        let _ = f.read_to_end(&mut buf);
    }
    let text = String::from_utf8_lossy(&buf);
    let all: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    all[all.len().saturating_sub(lines)..]
        .iter()
        .map(|s| s.to_string())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("vfxgraph-fuzz-ipc-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn seeds_round_trip_and_truncation_is_refused() {
        let d = scratch("seeds");
        let p = d.join("seeds.bin");
        let seeds = vec![
            ("a.png".to_string(), vec![0u8, 1, 2, 255]),
            ("generated:empty".to_string(), Vec::new()),
        ];
        write_seeds(&p, &seeds).unwrap();
        assert_eq!(read_seeds(&p).unwrap(), seeds);
        let mut b = std::fs::read(&p).unwrap();
        b.pop();
        std::fs::write(&p, b).unwrap();
        assert!(read_seeds(&p).is_err());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn status_block_is_shared_between_two_mappings() {
        let d = scratch("status");
        let a = Status::map(&d.join("status")).unwrap();
        let b = Status::map(&d.join("status")).unwrap();
        a.set(slot::CURRENT, 7);
        a.add(slot::EXECUTIONS, 3);
        a.max(slot::SLOWEST_US, 9);
        a.max(slot::SLOWEST_US, 4);
        assert_eq!(b.get(slot::CURRENT), 7);
        assert_eq!(b.get(slot::EXECUTIONS), 3);
        assert_eq!(b.get(slot::SLOWEST_US), 9);
        b.clear();
        assert_eq!(a.get(slot::EXECUTIONS), 0);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn events_survive_a_cut_last_line() {
        let d = scratch("events");
        let p = d.join("events");
        let log = open_events(&p).unwrap();
        let e = Event {
            kind: EventKind::Crash,
            pos: Some(4),
            message: "index out of bounds\nat x.rs:1".into(),
            fatal: false,
        };
        write_event(&log, &e).unwrap();
        (&log).write_all(b"{\"kind\":\"hang\",\"po").unwrap();
        assert_eq!(read_events(&p), vec![e]);
        let _ = std::fs::remove_dir_all(&d);
    }
}
