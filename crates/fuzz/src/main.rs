//! `vfxgraph-fuzz`: the long fuzzing run, one target or all, or one input reproduced.
//!
//! ```text
//! cargo run --release -p vfxgraph-fuzz -- [--inputs N] [--target NAME]… [--seed S]
//!     [--skip NAME]…
//!     [--timeout-ms MS] [--max-alloc-mb MB] [--crash-dir DIR] [--threads N] [--progress N]
//! cargo run --release -p vfxgraph-fuzz -- --target NAME --index I [--seed S] [--save FILE]
//! cargo run --release -p vfxgraph-fuzz -- --target NAME --file FILE
//! cargo run --release -p vfxgraph-fuzz -- --list
//! ```
//!
//! Exit status: 0 when no target crashed, 1 when one did (the inputs are in the crash folder),
//! 2 for bad arguments, 3 on a hang or an allocation blow-up (the input is saved and named).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use vfxgraph_fuzz::run::{campaign, execute, make_input, on_fuzz_thread, table, Options};
use vfxgraph_fuzz::targets::{all, SeedDirs};

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
    let mut threads = 1usize;
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
        match a.as_str() {
            "--inputs" => opts.inputs = num!(),
            "--seed" => opts.seed = num!(),
            "--timeout-ms" => opts.timeout = Duration::from_millis(num!()),
            "--max-alloc-mb" => {
                opts.max_alloc = {
                    let mb: usize = num!();
                    mb << 20
                }
            }
            "--threads" => threads = num!(),
            "--progress" => opts.progress_every = num!(),
            "--index" => index = Some(num!()),
            "--crash-dir" => match value() {
                Some(v) => opts.crash_dir = v.into(),
                None => return usage(),
            },
            "--file" => match value() {
                Some(v) => file = Some(v.into()),
                None => return usage(),
            },
            "--save" => match value() {
                Some(v) => save = Some(v.into()),
                None => return usage(),
            },
            "--target" => match value() {
                Some(v) => names.push(v),
                None => return usage(),
            },
            "--skip" => match value() {
                Some(v) => skip.push(v),
                None => return usage(),
            },
            "--list" => {
                for t in all() {
                    println!("{:<14} {}", t.name, t.what);
                }
                return ExitCode::SUCCESS;
            }
            _ => return usage(),
        }
    }
    // Decoders that use rayon get this many threads (the machine is shared).
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let targets: Vec<_> = all()
        .into_iter()
        .filter(|t| names.is_empty() || names.iter().any(|n| n == t.name))
        .filter(|t| !skip.iter().any(|n| n == t.name))
        .collect();
    if let Some(n) = names
        .iter()
        .find(|n| !targets.iter().any(|t| t.name == n.as_str()))
    {
        eprintln!("unknown target `{n}` (see --list)");
        return ExitCode::from(2);
    }
    if index.is_some() || file.is_some() {
        let [t] = targets.as_slice() else {
            eprintln!("--index and --file need exactly one --target");
            return ExitCode::from(2);
        };
        vfxgraph_fuzz::guard::install(opts.timeout, opts.max_alloc, opts.crash_dir.clone());
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
        println!(
            "target {} input {} ({} bytes): {:?}, {} panic(s){}, {:.1} ms",
            t.name,
            file.as_ref()
                .map_or(format!("#{i}"), |p| p.display().to_string()),
            input.len(),
            e.result,
            e.panics,
            e.first_panic
                .map(|m| format!(" (first: {m})"))
                .unwrap_or_default(),
            e.took.as_secs_f64() * 1e3
        );
        return if e.result.is_err() {
            ExitCode::from(1)
        } else {
            ExitCode::SUCCESS
        };
    }
    let mut outcomes = Vec::new();
    for t in &targets {
        eprintln!("{}: {}", t.name, t.what);
        let o = on_fuzz_thread(|| campaign(t, &opts));
        for c in &o.crashes {
            eprintln!(
                "  crash on input {:?}: {} (saved to {})",
                c.index,
                c.message,
                c.saved.display()
            );
        }
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
        "seed {}, {} mutated inputs per target, time bound {} ms per input, allocation bound {} MiB",
        opts.seed,
        opts.inputs,
        opts.timeout.as_millis(),
        opts.max_alloc >> 20
    );
    if outcomes.iter().any(|o| !o.crashes.is_empty()) {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}
