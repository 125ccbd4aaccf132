//! Ctrl-C. The first SIGINT raises the engine's cancel flag: instances not yet started are
//! skipped and running nodes that poll `Context::cancelled` (the renderer, per tile) stop, so
//! nothing partial is cached and the run ends with exit code 130. The handler resets itself
//! (`SA_RESETHAND`), so a second Ctrl-C ends the process at once — still safe, since every
//! output and cache write is atomic.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();

extern "C" fn on_sigint(_: libc::c_int) {
    // Async-signal-safe: an atomic load of an initialized OnceLock and an atomic store.
    if let Some(f) = FLAG.get() {
        f.store(true, Ordering::SeqCst);
    }
}

/// Installs the handler (once) and returns the flag it raises.
pub fn install() -> Arc<AtomicBool> {
    let flag = FLAG
        .get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone();
    // SAFETY: a plain sigaction with a handler that only touches atomics.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_sigint as *const () as usize;
        sa.sa_flags = libc::SA_RESETHAND;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
    }
    flag
}
