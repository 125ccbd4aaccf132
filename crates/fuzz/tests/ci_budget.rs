//! The CI budget of the fuzz targets: every reader of a user file gets its seeds and a fixed
//! number of mutated inputs (seed 0) in a supervised campaign under the harness's guards; none
//! may panic, die, hang or allocate over the bound (1 GiB at once, or live during one input),
//! and every seed — a valid file — must be accepted. The long run is
//! `scripts/bench/fuzz_campaign.sh` (10⁶ inputs per target).

use std::path::PathBuf;
use std::time::Duration;

use vfxgraph_fuzz::run::{campaign, findings_report, table, Options, MAX_ALLOC};
use vfxgraph_fuzz::targets::{all, SeedDirs};

/// Mutated inputs per target in CI (the dev profile; docs/validation/fuzzing.md has the measured cost).
fn budget(target: &str) -> u64 {
    match target {
        // The slowest per input in the dev profile (a few hundred µs to ~1 ms).
        "graph" | "exr" => 5_000,
        _ => 10_000,
    }
}

#[test]
fn every_reader_survives_its_ci_budget() {
    let dirs = SeedDirs::default();
    if !dirs.shared.exists() {
        eprintln!(
            "notice: {} not found: fuzzing from the repository's and generated seeds only",
            dirs.shared.display()
        );
    }
    let crash_dir = std::env::temp_dir().join(format!("vfxgraph-fuzz-ci-{}", std::process::id()));
    let mut outcomes = Vec::new();
    for t in all() {
        let opts = Options {
            inputs: budget(t.name),
            seed: 0,
            // Generous for the dev profile on a loaded 2-core machine: the slowest input of
            // the long run takes well under this (docs/validation/fuzzing.md).
            timeout: Duration::from_secs(10),
            max_alloc: MAX_ALLOC,
            crash_dir: crash_dir.clone(),
            dirs: dirs.clone(),
            progress_every: 0,
            threads: 1,
            worker_exe: Some(PathBuf::from(env!("CARGO_BIN_EXE_vfxgraph-fuzz"))),
        };
        outcomes.push(campaign(&t, &opts));
    }
    eprint!("{}", table(&outcomes));
    eprint!("{}", findings_report(&outcomes));
    for o in &outcomes {
        assert!(o.seeds >= 1, "target {} has no seeds", o.target);
        assert!(
            o.seeds_refused.is_empty(),
            "target {}: valid seeds refused: {:?}",
            o.target,
            o.seeds_refused
        );
        assert_eq!(
            o.finding_count(),
            0,
            "target {}: {} crashes, {} hangs, {} over-allocations, first: {:?}",
            o.target,
            o.crashes,
            o.hangs,
            o.over_allocs,
            o.findings.first()
        );
        // The whole budget ran.
        assert_eq!(o.executions, o.seeds as u64 + budget(&o.target));
        // The mutations keep part of the inputs valid (the readers are reached, not only
        // their first check) and break the rest.
        assert!(
            o.accepted > o.seeds as u64,
            "target {}: only the seeds were accepted",
            o.target
        );
        assert!(
            o.accepted < o.executions,
            "target {}: every input accepted",
            o.target
        );
    }
    let _ = std::fs::remove_dir_all(&crash_dir);
}
