//! Fuzzing of every reader of a user file on the stable toolchain (ARCHITECTURE.md, "Fuzzing").
//!
//! `cargo fuzz` (libFuzzer) needs a nightly compiler, which cannot be installed here; `afl`
//! needs its own compiler wrapper and a fork server outside `cargo test`; `bolero` on stable
//! only draws random inputs from `arbitrary`. So the harness is this crate: a deterministic,
//! seeded, structure-aware mutator of real seed files ([`mutate`]), one target per reader
//! ([`targets`]), and guards ([`guard`]): `catch_unwind` around each input, a panic hook that
//! also counts the panics a reader contains itself, a watchdog (an input over the time bound is
//! a hang), and a global allocator that refuses one allocation over the memory bound (a
//! header's claimed size honoured before checking the data). Every input is a function of
//! (run seed, target, index), so a failure is reproduced by its index alone. Coverage is not
//! measured (no instrumentation on stable): depth comes from mutating valid files.
//!
//! The CI budget is `tests/ci_budget.rs` (part of `cargo test --workspace`); the long run is
//! `cargo run --release -p vfxgraph-fuzz -- --inputs 100000`.

pub mod guard;
pub mod mutate;
pub mod run;
pub mod targets;

#[global_allocator]
static ALLOC: guard::GuardedAlloc = guard::GuardedAlloc;
