//! What stands around each input: a panic hook that records every panic (also those a reader
//! catches itself and turns into an error — "contained"), a watchdog thread that ends the run
//! when one input takes longer than the time bound (a hang), a global allocator that ends it
//! when one allocation asks for more than the memory bound (a header's claimed size honoured
//! before the data was checked), and a note on stderr naming the input when the process dies
//! of a fatal signal (abort, stack overflow, a fault in C code).
//!
//! A hang or blow-up cannot be recovered from inside the process (a thread cannot be stopped;
//! the allocation would exhaust the machine), so both write the input to the crash folder,
//! print how to reproduce it and exit with status 3 — libFuzzer's `-timeout`/`-rss_limit_mb`
//! behaviour.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, Once, OnceLock};
use std::time::{Duration, Instant};

/// The allocator of every binary linking this crate: [`System`] with the memory bound.
pub struct GuardedAlloc;

static MAX_ALLOC: AtomicUsize = AtomicUsize::new(usize::MAX);
static TRIPPED: AtomicBool = AtomicBool::new(false);

unsafe impl GlobalAlloc for GuardedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        check_size(layout.size());
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        check_size(layout.size());
        System.alloc_zeroed(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        check_size(new_size);
        System.realloc(ptr, layout, new_size)
    }
}

fn check_size(size: usize) {
    if size > MAX_ALLOC.load(Ordering::Relaxed) && !TRIPPED.swap(true, Ordering::SeqCst) {
        // Allocations made while reporting pass (TRIPPED is set).
        fail(
            "blow-up",
            &format!(
                "one allocation of {size} bytes (bound {} bytes)",
                MAX_ALLOC.load(Ordering::Relaxed)
            ),
        );
    }
}

/// The input being run, for the reports of the watchdog, the allocator and the signal note.
struct Current {
    target: String,
    index: u64,
    seed: u64,
    bytes: Vec<u8>,
}

static CURRENT: Mutex<Option<Current>> = Mutex::new(None);
static CRASH_DIR: OnceLock<PathBuf> = OnceLock::new();
/// Milliseconds since [`epoch`] + 1 when the current input started; 0 when idle.
static STARTED: AtomicU64 = AtomicU64::new(0);
static TIMEOUT_MS: AtomicU64 = AtomicU64::new(u64::MAX);
/// The signal note: target name and input index, readable without locks.
static SIGNAL_NOTE: Mutex<Vec<u8>> = Mutex::new(Vec::new());
static INDEX: AtomicU64 = AtomicU64::new(0);

fn epoch() -> Instant {
    static E: OnceLock<Instant> = OnceLock::new();
    *E.get_or_init(Instant::now)
}

fn now_ms() -> u64 {
    epoch().elapsed().as_millis() as u64 + 1
}

/// Panics seen by the hook since the last [`take_panic`], with the first one's message.
static PANICS: AtomicUsize = AtomicUsize::new(0);
static FIRST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Installs the hook, the watchdog and the signal note (once per process) and sets the bounds.
pub fn install(timeout: Duration, max_alloc: usize, crash_dir: PathBuf) {
    TIMEOUT_MS.store(timeout.as_millis() as u64, Ordering::SeqCst);
    MAX_ALLOC.store(max_alloc, Ordering::SeqCst);
    let _ = CRASH_DIR.set(crash_dir);
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        epoch();
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if STARTED.load(Ordering::SeqCst) == 0 {
                // Not inside an input (e.g. a failing assertion of a test): the usual report.
                return previous(info);
            }
            if PANICS.fetch_add(1, Ordering::SeqCst) == 0 {
                let loc = info
                    .location()
                    .map(|l| format!(" at {}:{}", l.file(), l.line()))
                    .unwrap_or_default();
                let msg = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(non-string payload)".into());
                if let Ok(mut f) = FIRST_PANIC.lock() {
                    *f = Some(format!("{msg}{loc}"));
                }
            }
        }));
        std::thread::Builder::new()
            .name("fuzz-watchdog".into())
            .spawn(|| loop {
                std::thread::sleep(Duration::from_millis(25));
                let s = STARTED.load(Ordering::SeqCst);
                if s != 0 && now_ms().saturating_sub(s) > TIMEOUT_MS.load(Ordering::SeqCst) {
                    fail(
                        "hang",
                        &format!("over {} ms", TIMEOUT_MS.load(Ordering::SeqCst)),
                    );
                }
            })
            .expect("watchdog thread");
        install_signal_note();
    });
}

/// Marks the start of input `index` of `target`.
pub fn begin(target: &str, seed: u64, index: u64, bytes: &[u8]) {
    PANICS.store(0, Ordering::SeqCst);
    if let Ok(mut f) = FIRST_PANIC.lock() {
        *f = None;
    }
    if let Ok(mut c) = CURRENT.lock() {
        match c.as_mut() {
            Some(c) if c.target == target => {
                c.index = index;
                c.seed = seed;
                c.bytes.clear();
                c.bytes.extend_from_slice(bytes);
            }
            _ => {
                *c = Some(Current {
                    target: target.to_string(),
                    index,
                    seed,
                    bytes: bytes.to_vec(),
                });
                if let Ok(mut n) = SIGNAL_NOTE.lock() {
                    *n = format!(
                        "\nvfxgraph-fuzz: fatal signal while running target `{target}` (seed {seed}), input #"
                    )
                    .into_bytes();
                }
            }
        }
    }
    INDEX.store(index, Ordering::SeqCst);
    STARTED.store(now_ms(), Ordering::SeqCst);
}

/// Marks the end of the current input; returns its duration.
pub fn end() -> Duration {
    let s = STARTED.swap(0, Ordering::SeqCst);
    Duration::from_millis(now_ms().saturating_sub(s))
}

/// The number of panics since [`begin`] and the first one's message.
pub fn take_panic() -> (usize, Option<String>) {
    let n = PANICS.swap(0, Ordering::SeqCst);
    let m = FIRST_PANIC.lock().ok().and_then(|mut f| f.take());
    (n, m)
}

/// The file an input of `target` is saved to.
pub fn crash_path(kind: &str, target: &str, bytes: &[u8]) -> PathBuf {
    let dir = CRASH_DIR
        .get()
        .cloned()
        .unwrap_or_else(|| PathBuf::from("fuzz-crashes"));
    let h = blake3::hash(bytes).to_hex();
    dir.join(format!("{kind}-{target}-{}", &h[..16]))
}

/// Writes `bytes` under the crash folder; returns the path.
pub fn save(kind: &str, target: &str, bytes: &[u8]) -> PathBuf {
    let p = crash_path(kind, target, bytes);
    if let Some(d) = p.parent() {
        let _ = std::fs::create_dir_all(d);
    }
    let _ = std::fs::write(&p, bytes);
    p
}

/// Saves the current input, prints the failure and how to reproduce it, and exits (status 3).
fn fail(kind: &str, what: &str) -> ! {
    let cur = CURRENT.try_lock().ok().and_then(|mut c| c.take());
    match cur {
        Some(c) => {
            let p = save(kind, &c.target, &c.bytes);
            eprintln!(
                "\nvfxgraph-fuzz: {kind} in target `{}` on input #{} ({what}); input saved to {} \
                 (reproduce: vfxgraph-fuzz --target {} --seed {} --index {})",
                c.target,
                c.index,
                p.display(),
                c.target,
                c.seed,
                c.index
            );
        }
        None => eprintln!("\nvfxgraph-fuzz: {kind} ({what}) outside of an input"),
    }
    std::process::exit(3);
}

/// On SIGABRT (Rust's abort: stack overflow, a panic while panicking, allocation failure),
/// SIGSEGV, SIGBUS, SIGILL and SIGFPE, writes which input was running (async-signal-safe:
/// one `write` of a prepared note and a number), then lets the previous handler or the
/// default action proceed.
fn install_signal_note() {
    for sig in [
        libc::SIGABRT,
        libc::SIGSEGV,
        libc::SIGBUS,
        libc::SIGILL,
        libc::SIGFPE,
    ] {
        // SAFETY: the handler only reads atomics and a buffer prepared before the input ran
        // (try_lock: never blocks), and calls write(2), sigaction(2) and raise(3).
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_signal as *const () as usize;
            sa.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
            libc::sigemptyset(&mut sa.sa_mask);
            let mut old: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(sig, &sa, &mut old) == 0 {
                PREVIOUS[slot(sig)].store(Box::into_raw(Box::new(old)) as usize, Ordering::SeqCst);
            }
        }
    }
}

static PREVIOUS: [AtomicUsize; 5] = [const { AtomicUsize::new(0) }; 5];

fn slot(sig: libc::c_int) -> usize {
    match sig {
        libc::SIGABRT => 0,
        libc::SIGSEGV => 1,
        libc::SIGBUS => 2,
        libc::SIGILL => 3,
        _ => 4,
    }
}

extern "C" fn on_signal(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
    if STARTED.load(Ordering::SeqCst) != 0 {
        if let Ok(note) = SIGNAL_NOTE.try_lock() {
            let mut buf = [0u8; 24];
            let mut n = INDEX.load(Ordering::SeqCst);
            let mut i = buf.len() - 1;
            buf[i] = b'\n';
            loop {
                i -= 1;
                buf[i] = b'0' + (n % 10) as u8;
                n /= 10;
                if n == 0 {
                    break;
                }
            }
            // SAFETY: write(2) on stderr with valid buffers.
            unsafe {
                libc::write(2, note.as_ptr().cast(), note.len());
                libc::write(2, buf[i..].as_ptr().cast(), buf.len() - i);
            }
        }
    }
    let prev = PREVIOUS[slot(sig)].load(Ordering::SeqCst) as *const libc::sigaction;
    // SAFETY: `prev` was stored by install_signal_note from a valid sigaction.
    unsafe {
        if !prev.is_null() {
            let p = &*prev;
            let h = p.sa_sigaction;
            if h != libc::SIG_DFL && h != libc::SIG_IGN {
                if p.sa_flags & libc::SA_SIGINFO != 0 {
                    let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                        std::mem::transmute(h);
                    f(sig, info, ctx);
                } else {
                    let f: extern "C" fn(libc::c_int) = std::mem::transmute(h);
                    f(sig);
                }
                return;
            }
        }
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
}
