//! `vfxgraph-fuzz`: a fuzzing campaign over one target or all, or one input reproduced.
//!
//! ```text
//! cargo run --release -p vfxgraph-fuzz -- [--inputs N] [--target NAME]… [--skip NAME]…
//!     [--seed S] [--timeout-ms MS] [--max-alloc-mb MB] [--crash-dir DIR] [--threads N]
//!     [--progress N]
//! cargo run --release -p vfxgraph-fuzz -- --target NAME --index I [--seed S] [--save FILE]
//! cargo run --release -p vfxgraph-fuzz -- --target NAME --file FILE
//! cargo run --release -p vfxgraph-fuzz -- --list
//! ```
//!
//! A campaign runs every target's whole budget whatever it finds (workers in child processes;
//! see `run`), then prints a table per target and the findings, each with its saved input and
//! the command that reproduces it. Exit status: 0 when nothing was found, 1 when something was
//! (a crash, a hang or an over-allocation; for one input reproduced: when it fails), 2 for bad
//! arguments. `--worker DIR --start P` (not for use by hand) is how the campaign starts its
//! workers.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use vfxgraph_fuzz::run::{
    campaign, execute, findings_report, make_input, on_fuzz_thread, table, Options,
};
use vfxgraph_fuzz::targets::{all, find, SeedDirs};

fn usage() -> ExitCode {
    eprintln!(
        "usage: vfxgraph-fuzz [--inputs N] [--target NAME]... [--skip NAME]... [--seed S] [--timeout-ms MS] \
         [--max-alloc-mb MB] [--crash-dir DIR] [--threads N] [--progress N]\n       \
         vfxgraph-fuzz --target NAME --index I [--seed S] [--save FILE]\n       \
         vfxgraph-fuzz --target NAME --file FILE\n       \
         vfxgraph-fuzz --list"
    );
    ExitCode::from(2)
}

fn main() -> ExitCode {
    let mut opts = Options {
        inputs: 100_000,
        ..Options::default()
    };
    let mut names: Vec<String> = Vec::new();
    let mut skip: Vec<String> = Vec::new();
    let mut index: Option<u64> = None;
    let mut save: Option<PathBuf> = None;
    let mut file: Option<PathBuf> = None;
    let mut worker: Option<PathBuf> = None;
    let mut start = 0u64;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next();
        macro_rules! num {
            () => {
                match value().and_then(|v| v.parse().ok()) {
                    Some(v) => v,
                    None => return usage(),
                }
            };
        }
        macro_rules! path {
            () => {
                match value() {
                    Some(v) => PathBuf::from(v),
                    None => return usage(),
                }
            };
        }
        match a.as_str() {
            "--inputs" => opts.inputs = num!(),
            "--seed" => opts.seed = num!(),
            "--timeout-ms" => opts.timeout = Duration::from_millis(num!()),
            "--max-alloc-mb" => {
                let mb: usize = num!();
                match mb.checked_mul(1 << 20) {
                    Some(b) if mb > 0 => opts.max_alloc = b,
                    _ => return usage(),
                }
            }
            "--threads" => opts.threads = num!(),
            "--progress" => opts.progress_every = num!(),
            "--index" => index = Some(num!()),
            "--crash-dir" => opts.crash_dir = path!(),
            "--file" => file = Some(path!()),
            "--save" => save = Some(path!()),
            "--target" => match value() {
                Some(v) => names.push(v),
                None => return usage(),
            },
            "--skip" => match value() {
                Some(v) => skip.push(v),
                None => return usage(),
            },
            "--worker" => worker = Some(path!()),
            "--start" => start = num!(),
            "--list" => {
                for t in all() {
                    println!("{:<14} {}", t.name, t.what);
                }
                return ExitCode::SUCCESS;
            }
            _ => return usage(),
        }
    }
    if let Some(dir) = worker {
        return match vfxgraph_fuzz::worker::run(&dir, start) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("vfxgraph-fuzz worker: {e}");
                ExitCode::from(2)
            }
        };
    }
    // Decoders that use rayon get this many threads (the machine is shared).
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads.max(1))
        .build_global();
    let mut targets = Vec::new();
    if names.is_empty() {
        targets = all();
    }
    for n in &names {
        match find(n) {
            Some(t) => targets.push(t),
            None => {
                eprintln!("unknown target `{n}` (see --list)");
                return ExitCode::from(2);
            }
        }
    }
    targets.retain(|t| !skip.iter().any(|n| n == t.name));
    if index.is_some() || file.is_some() {
        let [t] = targets.as_slice() else {
            eprintln!("--index and --file need exactly one --target");
            return ExitCode::from(2);
        };
        return reproduce(t, &opts, index, file, save);
    }
    let mut outcomes = Vec::new();
    for t in &targets {
        eprintln!("{}: {}", t.name, t.what);
        let o = campaign(t, &opts);
        if let Some(m) = &o.contained_example {
            eprintln!("  contained panic: {m}");
        }
        if !o.seeds_refused.is_empty() {
            eprintln!("  seeds refused: {}", o.seeds_refused.join(", "));
        }
        outcomes.push(o);
    }
    print!("{}", table(&outcomes));
    println!(
        "seed {}, {} mutated inputs per target, time bound {} ms per input, memory bound {} MiB \
         (one allocation, and live bytes during one input), {} decoder thread(s)",
        opts.seed,
        opts.inputs,
        opts.timeout.as_millis(),
        opts.max_alloc >> 20,
        opts.threads
    );
    let report = findings_report(&outcomes);
    let refused = outcomes.iter().any(|o| !o.seeds_refused.is_empty());
    if report.is_empty() {
        println!("findings: none");
    } else {
        print!("findings:\n{report}");
    }
    if refused {
        println!("(valid seeds were refused: see stderr)");
    }
    if outcomes.iter().any(|o| o.finding_count() > 0) {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

/// Runs one input in this process under the guards: mutated input `index`, or the file.
fn reproduce(
    t: &vfxgraph_fuzz::targets::Target,
    opts: &Options,
    index: Option<u64>,
    file: Option<PathBuf>,
    save: Option<PathBuf>,
) -> ExitCode {
    vfxgraph_fuzz::guard::install(opts.timeout, opts.max_alloc);
    let (i, input) = match (&file, index) {
        (Some(p), _) => match std::fs::read(p) {
            Ok(b) => (0, b),
            Err(e) => {
                eprintln!("cannot read {}: {e}", p.display());
                return ExitCode::from(2);
            }
        },
        (None, i) => {
            let i = i.unwrap_or(0);
            let seeds: Vec<Vec<u8>> = (t.seeds)(&SeedDirs::default())
                .into_iter()
                .map(|s| s.bytes)
                .collect();
            match make_input(t, &seeds, opts.seed, i) {
                Some(input) => (i, input),
                None => {
                    eprintln!("target `{}` has no seeds", t.name);
                    return ExitCode::from(2);
                }
            }
        }
    };
    if let Some(p) = &save {
        if let Err(e) = std::fs::write(p, &input) {
            eprintln!("cannot write {}: {e}", p.display());
            return ExitCode::from(2);
        }
    }
    let e = on_fuzz_thread(|| execute(t, opts.seed, i, &input));
    let hang = e.took > opts.timeout;
    println!(
        "target {} input {} ({} bytes): {:?}, {} panic(s){}, {:.1} ms{}, peak {:.1} MiB",
        t.name,
        file.as_ref()
            .map_or(format!("#{i}"), |p| p.display().to_string()),
        input.len(),
        e.result,
        e.panics,
        e.first_panic
            .map(|m| format!(" (first: {m})"))
            .unwrap_or_default(),
        e.took.as_secs_f64() * 1e3,
        if hang {
            " (a hang: over the bound)"
        } else {
            ""
        },
        e.peak_bytes as f64 / (1u64 << 20) as f64
    );
    if e.result.is_err() || hang {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}
