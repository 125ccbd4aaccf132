//! The campaign's own behaviour, on the hidden `probe` target (`targets::probe`): a panic, a
//! hang, an abort, a stack overflow, a stopped process, an `exit(0)`, one allocation over the
//! bound and live bytes over it are each recorded as a finding with its saved input and
//! reproducer, the inputs after each still run, the counts are those of a run without
//! findings, and the command line exits 1 on findings, 0 without, and never lists the probe.

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use vfxgraph_fuzz::run::{campaign, make_input, FindingKind, InputRef, Options};
use vfxgraph_fuzz::targets::{all, find, probe};

const EXE: &str = env!("CARGO_BIN_EXE_vfxgraph-fuzz");

fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("vfxgraph-fuzz-test-{name}-{}", std::process::id()))
}

fn probe_options(inputs: u64, crash_dir: PathBuf) -> Options {
    Options {
        inputs,
        seed: 0,
        timeout: Duration::from_millis(300),
        max_alloc: 64 << 20,
        crash_dir,
        progress_every: 0,
        threads: 1,
        worker_exe: Some(PathBuf::from(EXE)),
        ..Options::default()
    }
}

#[test]
fn every_kind_of_failure_is_a_finding_and_the_campaign_goes_on() {
    let dir = scratch("kinds");
    let opts = probe_options(30, dir.clone());
    let t = find(probe::NAME).expect("probe target");
    let o = campaign(&t, &opts);

    let expected = [
        (
            probe::PANIC,
            FindingKind::Crash,
            "probe: a panic escaping the reader",
        ),
        (probe::HANG, FindingKind::Hang, "over 300 ms"),
        (probe::ABORT, FindingKind::Crash, "SIGABRT"),
        (
            probe::ALLOC,
            FindingKind::OverAlloc,
            "one allocation of 67108865 bytes",
        ),
        (
            probe::PEAK,
            FindingKind::OverAlloc,
            "live at once during the input",
        ),
        (probe::STACK, FindingKind::Crash, "overflowed its stack"),
        (probe::STOP, FindingKind::Hang, "the supervisor killed it"),
        (probe::EXIT, FindingKind::Crash, "exited with status 0"),
    ];
    let got: Vec<_> = o
        .findings
        .iter()
        .map(|f| (f.input.clone(), f.kind))
        .collect();
    let want: Vec<_> = expected
        .iter()
        .map(|&(i, k, _)| (Some(InputRef::Index(i)), k))
        .collect();
    assert_eq!(got, want, "{:#?}", o.findings);
    let seeds = vec![b"seed".to_vec()];
    for (f, (i, _, text)) in o.findings.iter().zip(expected) {
        assert!(f.message.contains(text), "input {i}: {}", f.message);
        // The reproducer: the saved input is input i, and the command rebuilds it.
        let saved = std::fs::read(&f.saved).expect("saved input");
        assert_eq!(Some(saved), make_input(&t, &seeds, 0, i));
        assert!(
            f.command.ends_with(&format!(
                "--target probe --seed 0 --index {i} --timeout-ms 300 --max-alloc-mb 64"
            )),
            "{}",
            f.command
        );
    }
    assert_eq!((o.crashes, o.hangs, o.over_allocs), (4, 2, 2));
    assert_eq!(o.contained, 1);
    assert!(o
        .contained_example
        .as_deref()
        .unwrap()
        .contains("probe: contained"));
    // Every input ran, those after the findings included, with the counts of a clean run: the
    // seed and the even inputs outside the misbehaving ones are accepted.
    assert_eq!(o.executions, 1 + 30);
    let accepted = (0..30u64)
        .filter(|i| i % 2 == 0 && !probe::ALL.contains(i))
        .count() as u64;
    assert_eq!(o.accepted, 1 + accepted);
    assert!(o.seeds_refused.is_empty());
    // One worker at the start, one more after each finding that ends the process.
    assert_eq!(o.workers, 1 + 7);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_command_line_exits_1_on_findings_and_0_without() {
    let dir = scratch("cli");
    let run = |inputs: &str| {
        Command::new(EXE)
            .args(["--target", "probe", "--inputs", inputs, "--crash-dir"])
            .arg(&dir)
            .args(["--timeout-ms", "300", "--max-alloc-mb", "64"])
            .output()
            .expect("vfxgraph-fuzz runs")
    };
    // Inputs 0..3 behave; input 3 panics; input 7 aborts, and input 8 still runs.
    let clean = run("3");
    assert_eq!(clean.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&clean.stdout).contains("findings: none"));
    let found = run("9");
    assert_eq!(found.status.code(), Some(1));
    let out = String::from_utf8_lossy(&found.stdout);
    let row: Vec<&str> = out
        .lines()
        .find(|l| l.starts_with("probe "))
        .expect("table row")
        .split_whitespace()
        .collect();
    // target seeds execs exec/s accepted crashes hangs over-alloc contained …
    assert_eq!((row[2], row[5], row[6]), ("10", "2", "1"));
    assert!(out.contains(
        "reproduce: cargo run --release -p vfxgraph-fuzz -- --target probe --seed 0 --index 7"
    ));
    // Panics inside inputs are counted, not printed.
    let err = String::from_utf8_lossy(&found.stderr);
    assert!(!err.contains("panicked at"), "{err}");
    // The reproducer fails the same way alone.
    let again = Command::new(EXE)
        .args(["--target", "probe", "--seed", "0", "--index", "3"])
        .output()
        .unwrap();
    assert_eq!(again.status.code(), Some(1));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_probe_is_neither_listed_nor_run_by_default() {
    assert!(all().iter().all(|t| t.name != probe::NAME));
    let list = Command::new(EXE).arg("--list").output().unwrap();
    assert!(list.status.success());
    let list = String::from_utf8_lossy(&list.stdout);
    assert!(list.lines().count() >= 17);
    assert!(!list.contains("probe"));
}
