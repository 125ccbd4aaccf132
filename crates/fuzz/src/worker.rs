//! The worker process of a campaign (`vfxgraph-fuzz --worker DIR --start P`, started by the
//! supervisor in [`crate::run`]): runs one target's inputs from position `P` to the end on a
//! [`STACK_SIZE`](crate::run::STACK_SIZE) thread under the guards, counting into the shared
//! status block and logging rare events ([`crate::ipc`]). A panic is recorded and the worker
//! goes on; a hang or an allocation over the bound is logged by the guard's fatal hook, and the
//! process exits; a fatal signal kills it. Either way the supervisor starts the next worker.

use std::borrow::Cow;
use std::fs::File;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::Duration;

use crate::guard::{self, Fatal};
use crate::ipc::{self, slot, Config, Event, EventKind, Status, WorkDir};
use crate::run::{execute, make_input, on_fuzz_thread};
use crate::targets::find;

/// The event log, for the fatal hook.
static EVENTS: OnceLock<File> = OnceLock::new();
/// The number of seeds, to turn the guard's input index into a position.
static SEEDS: AtomicU64 = AtomicU64::new(0);

/// The guard's index of the input at position `pos`: seed `k` is `u64::MAX - k`, mutated
/// input `i` is `i`.
fn index_of(pos: u64, seeds: u64) -> u64 {
    if pos < seeds {
        u64::MAX - pos
    } else {
        pos - seeds
    }
}

/// The inverse of [`index_of`].
fn pos_of(index: u64, seeds: u64) -> u64 {
    if index > u64::MAX - seeds {
        u64::MAX - index
    } else {
        index + seeds
    }
}

fn on_fatal(kind: Fatal, index: Option<u64>, message: &str) {
    if let Some(log) = EVENTS.get() {
        let _ = ipc::write_event(
            log,
            &Event {
                kind: match kind {
                    Fatal::Hang => EventKind::Hang,
                    Fatal::OverAlloc => EventKind::OverAlloc,
                },
                pos: index.map(|i| pos_of(i, SEEDS.load(Ordering::SeqCst))),
                message: message.to_string(),
                fatal: true,
            },
        );
    }
}

/// Runs the worker on the work folder `dir` from position `start`.
pub fn run(dir: &Path, start: u64) -> Result<(), String> {
    let work = WorkDir {
        path: dir.to_path_buf(),
    };
    let config: Config = std::fs::read(work.config())
        .map_err(|e| e.to_string())
        .and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string()))
        .map_err(|e| format!("{}: {e}", work.config().display()))?;
    let target = find(&config.target).ok_or_else(|| format!("no target `{}`", config.target))?;
    let seeds: Vec<Vec<u8>> = ipc::read_seeds(&work.seeds())
        .map_err(|e| format!("{}: {e}", work.seeds().display()))?
        .into_iter()
        .map(|(_, b)| b)
        .collect();
    let status = Status::map(&work.status()).map_err(|e| e.to_string())?;
    let log = ipc::open_events(&work.events()).map_err(|e| e.to_string())?;
    let log = EVENTS.get_or_init(|| log);
    let n = seeds.len() as u64;
    SEEDS.store(n, Ordering::SeqCst);
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads.max(1))
        .build_global();
    let timeout = Duration::from_millis(config.timeout_ms);
    guard::install(timeout, config.max_alloc);
    guard::on_fatal(on_fatal);
    let emit = |kind, pos, message: String| {
        let _ = ipc::write_event(
            log,
            &Event {
                kind,
                pos: Some(pos),
                message,
                fatal: false,
            },
        );
    };
    on_fuzz_thread(|| {
        let mut contained_sent = false;
        for pos in start..n + config.inputs {
            status.set(slot::CURRENT, pos + 1);
            let index = index_of(pos, n);
            let input: Cow<[u8]> = if pos < n {
                Cow::Borrowed(&seeds[pos as usize])
            } else {
                Cow::Owned(make_input(&target, &seeds, config.seed, index).unwrap_or_default())
            };
            let e = execute(&target, config.seed, index, &input);
            drop(input);
            match e.result {
                Ok(accepted) => {
                    status.add(slot::ACCEPTED, accepted as u64);
                    if pos < n && !accepted {
                        emit(EventKind::Refused, pos, String::new());
                    }
                    if e.panics > 0 {
                        status.add(slot::CONTAINED, 1);
                        if !contained_sent {
                            contained_sent = true;
                            emit(EventKind::Contained, pos, e.first_panic.unwrap_or_default());
                        }
                    }
                }
                Err(message) => {
                    if pos < n {
                        emit(EventKind::Refused, pos, String::new());
                    }
                    emit(EventKind::Crash, pos, message);
                }
            }
            if e.took > timeout {
                // Finished, but past the bound before the watchdog looked: a hang all the same.
                emit(
                    EventKind::Hang,
                    pos,
                    format!(
                        "took {} ms, over {} ms",
                        e.took.as_millis(),
                        timeout.as_millis()
                    ),
                );
            }
            status.add(slot::EXECUTIONS, 1);
            status.max(slot::SLOWEST_US, e.took.as_micros() as u64);
            status.max(slot::PEAK_BYTES, e.peak_bytes as u64);
            status.set(slot::DONE, pos + 1);
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_and_guard_indices_are_inverse() {
        for seeds in [0u64, 1, 5] {
            for pos in [0u64, 1, 4, 5, 6, 1_000_000] {
                assert_eq!(pos_of(index_of(pos, seeds), seeds), pos);
            }
        }
        assert_eq!(index_of(0, 3), u64::MAX);
        assert_eq!(index_of(3, 3), 0);
    }
}
