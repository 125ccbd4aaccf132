//! Fuzzing of every reader of a user file on the stable toolchain (docs/design/fuzzing.md).
//!
//! `cargo fuzz` (libFuzzer) needs a nightly compiler, which cannot be installed here; `afl`
//! needs its own compiler wrapper and a fork server outside `cargo test`; `bolero` on stable
//! only draws random inputs from `arbitrary`. So the harness is this crate: a deterministic,
//! seeded, structure-aware mutator of real seed files ([`mutate`]), one target per reader
//! ([`targets`]), guards ([`guard`]) — `catch_unwind` around each input, a panic hook that
//! also counts the panics a reader contains itself, a watchdog (an input over the time bound is
//! a hang), and a counting global allocator (one allocation over the memory bound, or more
//! bytes than it live during one input, is an over-allocation: a header's claimed size honoured
//! before checking the data) — and a campaign ([`run`]) in which a supervisor runs each
//! target's inputs in worker processes ([`worker`], sharing state through [`ipc`]), so a hang,
//! an over-allocation or a fatal signal is a finding with its reproducer and the campaign goes
//! on with the next input. Every input is a function of (run seed, target, index), so a
//! finding is reproduced by its index alone. Coverage is not measured (no instrumentation on
//! stable): depth comes from mutating valid files.
//!
//! The CI budget is `tests/ci_budget.rs` (part of `cargo test --workspace`); the long run is
//! `scripts/bench/fuzz_campaign.sh` (10⁶ inputs per target, `docs/validation/fuzzing.md`).

pub mod guard;
pub mod ipc;
pub mod mutate;
pub mod run;
pub mod targets;
pub mod worker;

#[global_allocator]
static ALLOC: guard::GuardedAlloc = guard::GuardedAlloc;
