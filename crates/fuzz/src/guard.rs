//! What stands around each input inside the process that runs it: a panic hook that records
//! every panic quietly (also those a reader catches itself and turns into an error —
//! "contained"), a watchdog thread that ends the process when one input takes longer than the
//! time bound (a hang), a counting global allocator that ends it when one allocation asks for
//! more than the memory bound or when the bytes live during one input rise above it (a
//! header's claimed size honoured before the data was checked), and a note on stderr naming the
//! input when the process dies of a fatal signal (abort, stack overflow, a fault in C code).
//!
//! A hang or an allocation over the bound cannot be recovered from inside the process (a thread
//! cannot be stopped; the allocation would exhaust the machine), so both call the hook set with
//! [`on_fatal`] (the campaign's worker records the finding there), print what happened and exit
//! with [`FATAL_EXIT`]. The campaign's supervisor ([`crate::run`]) then starts a new worker at
//! the next input.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, Once, OnceLock};
use std::time::{Duration, Instant};

/// The exit status of a process ended by a hang or an allocation over the bound.
pub const FATAL_EXIT: i32 = 1;

/// A finding that ends the process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fatal {
    /// One input ran past the time bound.
    Hang,
    /// One allocation, or the bytes live during one input, went over the memory bound.
    OverAlloc,
}

impl std::fmt::Display for Fatal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Fatal::Hang => "hang",
            Fatal::OverAlloc => "over-allocation",
        })
    }
}

/// The allocator of every binary linking this crate: [`System`], counting the bytes live, with
/// the memory bound on one allocation and on the rise of live bytes during one input.
pub struct GuardedAlloc;

static MAX_ALLOC: AtomicUsize = AtomicUsize::new(usize::MAX);
static TRIPPED: AtomicBool = AtomicBool::new(false);
/// Bytes allocated and not yet freed, all threads.
static LIVE: AtomicUsize = AtomicUsize::new(0);
/// [`LIVE`] when the current input began.
static BASE: AtomicUsize = AtomicUsize::new(0);
/// The highest [`LIVE`] since the current input began.
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for GuardedAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        check_one(layout.size());
        add(layout.size());
        let p = System.alloc(layout);
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        check_one(layout.size());
        add(layout.size());
        let p = System.alloc_zeroed(layout);
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old {
            check_one(new_size);
            add(new_size - old);
        }
        let p = System.realloc(ptr, layout, new_size);
        if p.is_null() {
            if new_size > old {
                LIVE.fetch_sub(new_size - old, Ordering::Relaxed);
            }
        } else if new_size < old {
            LIVE.fetch_sub(old - new_size, Ordering::Relaxed);
        }
        p
    }
}

/// One allocation of `size` bytes: over the bound, a finding.
fn check_one(size: usize) {
    let max = MAX_ALLOC.load(Ordering::Relaxed);
    if size > max && !TRIPPED.swap(true, Ordering::SeqCst) {
        // Allocations made while reporting pass (TRIPPED is set).
        fail(
            Fatal::OverAlloc,
            running_index(),
            &format!("one allocation of {size} bytes, bound {max} bytes"),
        );
    }
}

/// `size` more bytes live: a rise over the bound during an input is a finding.
fn add(size: usize) {
    let live = LIVE.fetch_add(size, Ordering::Relaxed) + size;
    if live > PEAK.load(Ordering::Relaxed) {
        PEAK.fetch_max(live, Ordering::Relaxed);
        let max = MAX_ALLOC.load(Ordering::Relaxed);
        if STARTED.load(Ordering::Relaxed) != 0
            && live.saturating_sub(BASE.load(Ordering::Relaxed)) > max
            && !TRIPPED.swap(true, Ordering::SeqCst)
        {
            fail(
                Fatal::OverAlloc,
                running_index(),
                &format!(
                    "{} bytes live at once during the input, bound {max} bytes",
                    live.saturating_sub(BASE.load(Ordering::Relaxed))
                ),
            );
        }
    }
}

/// The memory bound in bytes (`usize::MAX` before [`install`]).
pub fn max_alloc() -> usize {
    MAX_ALLOC.load(Ordering::Relaxed)
}

/// The input being run (target and run seed), for the reports of the watchdog and allocator.
static LABEL: Mutex<Option<(String, u64)>> = Mutex::new(None);
/// Milliseconds since [`epoch`] + 1 when the current input started; 0 when idle.
static STARTED: AtomicU64 = AtomicU64::new(0);
static TIMEOUT_MS: AtomicU64 = AtomicU64::new(u64::MAX);
/// The signal note: target name and run seed, readable without locks.
static SIGNAL_NOTE: Mutex<Vec<u8>> = Mutex::new(Vec::new());
/// The index of the current (or last) input.
static INDEX: AtomicU64 = AtomicU64::new(0);
/// Called with a fatal finding before the process exits.
static ON_FATAL: OnceLock<fn(Fatal, Option<u64>, &str)> = OnceLock::new();

fn epoch() -> Instant {
    static E: OnceLock<Instant> = OnceLock::new();
    *E.get_or_init(Instant::now)
}

fn now_ms() -> u64 {
    epoch().elapsed().as_millis() as u64 + 1
}

/// The index of the input running now, if one is.
fn running_index() -> Option<u64> {
    (STARTED.load(Ordering::SeqCst) != 0).then(|| INDEX.load(Ordering::SeqCst))
}

/// Panics seen by the hook since the last [`take_panic`], with the first one's message.
static PANICS: AtomicUsize = AtomicUsize::new(0);
static FIRST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Sets the hook called (once, on the thread that found it) with a hang or an allocation over
/// the bound — its kind, the input's index, what happened — before the process exits.
pub fn on_fatal(hook: fn(Fatal, Option<u64>, &str)) {
    let _ = ON_FATAL.set(hook);
}

/// Installs the hook, the watchdog and the signal note (once per process) and sets the bounds.
pub fn install(timeout: Duration, max_alloc: usize) {
    TIMEOUT_MS.store(timeout.as_millis() as u64, Ordering::SeqCst);
    MAX_ALLOC.store(max_alloc, Ordering::SeqCst);
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        epoch();
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if STARTED.load(Ordering::SeqCst) == 0 {
                // Not inside an input (e.g. a failing assertion of a test): the usual report.
                return previous(info);
            }
            // Inside an input: counted and kept, never printed (contained panics are expected).
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
                // STARTED read twice around INDEX: an equal non-zero stamp means no input ended
                // in between, so INDEX is the index of the input that started then.
                let s = STARTED.load(Ordering::SeqCst);
                let index = INDEX.load(Ordering::SeqCst);
                let limit = TIMEOUT_MS.load(Ordering::SeqCst);
                if s != 0
                    && STARTED.load(Ordering::SeqCst) == s
                    && now_ms().saturating_sub(s) > limit
                    && !TRIPPED.swap(true, Ordering::SeqCst)
                {
                    fail(Fatal::Hang, Some(index), &format!("over {limit} ms"));
                }
            })
            .expect("watchdog thread");
        install_signal_note();
    });
}

/// Marks the start of input `index` of `target` in the run with `seed`.
pub fn begin(target: &str, seed: u64, index: u64) {
    PANICS.store(0, Ordering::SeqCst);
    if let Ok(mut f) = FIRST_PANIC.lock() {
        *f = None;
    }
    if let Ok(mut l) = LABEL.lock() {
        if l.as_ref().is_none_or(|(t, s)| t != target || *s != seed) {
            *l = Some((target.to_string(), seed));
            if let Ok(mut n) = SIGNAL_NOTE.lock() {
                *n = format!(
                    "\nvfxgraph-fuzz: fatal signal while running target `{target}` (seed {seed}), input #"
                )
                .into_bytes();
            }
        }
    }
    let live = LIVE.load(Ordering::SeqCst);
    BASE.store(live, Ordering::SeqCst);
    PEAK.store(live, Ordering::SeqCst);
    INDEX.store(index, Ordering::SeqCst);
    STARTED.store(now_ms(), Ordering::SeqCst);
}

/// Marks the end of the current input; returns the largest rise of live bytes during it.
pub fn end() -> usize {
    STARTED.store(0, Ordering::SeqCst);
    PEAK.load(Ordering::SeqCst)
        .saturating_sub(BASE.load(Ordering::SeqCst))
}

/// The number of panics since [`begin`] and the first one's message.
pub fn take_panic() -> (usize, Option<String>) {
    let n = PANICS.swap(0, Ordering::SeqCst);
    let m = FIRST_PANIC.lock().ok().and_then(|mut f| f.take());
    (n, m)
}

/// Reports a fatal finding (stderr, then the [`on_fatal`] hook) and exits with [`FATAL_EXIT`].
fn fail(kind: Fatal, index: Option<u64>, what: &str) -> ! {
    let label = LABEL.try_lock().ok().and_then(|l| l.clone());
    match (label, index) {
        (Some((target, seed)), Some(i)) => eprintln!(
            "\nvfxgraph-fuzz: {kind} in target `{target}` (seed {seed}) on input #{i} ({what})"
        ),
        _ => eprintln!("\nvfxgraph-fuzz: {kind} ({what}) outside of an input"),
    }
    if let Some(hook) = ON_FATAL.get() {
        hook(kind, index, what);
    }
    std::process::exit(FATAL_EXIT);
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
