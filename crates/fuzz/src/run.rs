//! A campaign: for each target, its seeds run as they are, then `inputs` mutated inputs, each
//! under the guards of [`crate::guard`]; the outcome is a row of counts per target.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::guard;
use crate::mutate::{input_rng, mutate};
use crate::targets::{fix_png_crcs, SeedDirs, Target};

/// The default memory bound: the largest image the project accepts (`MAX_SAMPLES` f32 samples,
/// 4 GiB) plus 1 MiB. Readers may honour a header's size up to that limit (an EXR's display
/// window is zero-filled outside its data window); one allocation beyond it is a blow-up.
pub const MAX_ALLOC: usize = vfxgraph_imaging::image::MAX_SAMPLES * 4 + (1 << 20);

/// What a campaign runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Mutated inputs per target (the seeds run first, in addition).
    pub inputs: u64,
    /// The run's seed: input `i` of a target depends only on (seed, target, i).
    pub seed: u64,
    /// One input longer than this is a hang.
    pub timeout: Duration,
    /// One allocation larger than this (bytes) is a blow-up.
    pub max_alloc: usize,
    /// Where failing inputs are written.
    pub crash_dir: PathBuf,
    /// Where seeds are read from.
    pub dirs: SeedDirs,
    /// Print a progress line every this many inputs (0: never).
    pub progress_every: u64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            inputs: 1000,
            seed: 0,
            timeout: Duration::from_secs(2),
            max_alloc: MAX_ALLOC,
            crash_dir: PathBuf::from("fuzz-crashes"),
            dirs: SeedDirs::default(),
            progress_every: 0,
        }
    }
}

/// One uncontained panic.
#[derive(Clone, Debug)]
pub struct Crash {
    /// Input index (`None`: a seed as it is).
    pub index: Option<u64>,
    /// The panic message and location.
    pub message: String,
    /// Where the input was saved.
    pub saved: PathBuf,
}

/// The outcome for one target.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// The target's name.
    pub target: String,
    /// Seeds found.
    pub seeds: usize,
    /// Seeds the reader refused (each should be a valid file).
    pub seeds_refused: Vec<String>,
    /// Inputs run (seeds + mutated).
    pub executions: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Panics that escaped the reader (each a bug).
    pub crashes: Vec<Crash>,
    /// Panics inside third-party code that the reader caught and turned into an error.
    pub contained: u64,
    /// The first contained panic's message.
    pub contained_example: Option<String>,
    /// Wall time of the mutated inputs.
    pub seconds: f64,
    /// The slowest input.
    pub slowest: Duration,
}

impl Outcome {
    /// Mutated inputs per second.
    pub fn rate(&self) -> f64 {
        self.executions.saturating_sub(self.seeds as u64) as f64 / self.seconds.max(1e-9)
    }
}

/// The stack inputs run on: 2 MiB, what Rust gives a spawned thread by default and so what a
/// node gets on the engine's rayon workers (a reader that recurses once per nesting level
/// overflows it long before a main thread's 8 MiB).
pub const STACK_SIZE: usize = 2 << 20;

/// Runs `f` on a thread with [`STACK_SIZE`] of stack.
pub fn on_fuzz_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    std::thread::scope(|s| {
        std::thread::Builder::new()
            .name("fuzz".into())
            .stack_size(STACK_SIZE)
            .spawn_scoped(s, f)
            .expect("fuzz thread")
            .join()
            .expect("the fuzz thread panicked outside an input")
    })
}

/// At most this many crashing inputs are saved per target.
const SAVED_PER_TARGET: usize = 20;

/// Input `index` of `target` in a run with `seed`, from its seeds (`None`: no seeds).
pub fn make_input(target: &Target, seeds: &[Vec<u8>], seed: u64, index: u64) -> Option<Vec<u8>> {
    if seeds.is_empty() {
        return None;
    }
    let mut rng = input_rng(seed, target.name, index);
    let mut data = mutate(&mut rng, seeds, target.kind, target.dict);
    if target.name == "png" && rand::Rng::random_bool(&mut rng, 0.5) {
        fix_png_crcs(&mut data);
    }
    Some(data)
}

/// What one input did.
#[derive(Clone, Debug)]
pub struct Exec {
    /// `Ok(accepted)`, or the message of a panic that escaped the reader.
    pub result: Result<bool, String>,
    /// Panics seen while it ran (also those the reader caught).
    pub panics: usize,
    /// The first panic's message and location.
    pub first_panic: Option<String>,
    /// How long it took.
    pub took: Duration,
}

/// Runs one input under the guards.
pub fn execute(target: &Target, seed: u64, index: u64, input: &[u8]) -> Exec {
    guard::begin(target.name, seed, index, input);
    let r = std::panic::catch_unwind(|| (target.run)(input));
    let took = guard::end();
    let (panics, first_panic) = guard::take_panic();
    let result = r.map_err(|_| first_panic.clone().unwrap_or_else(|| "panic".into()));
    Exec {
        result,
        panics,
        first_panic,
        took,
    }
}

/// Runs `target`'s seeds, then `opts.inputs` mutated inputs.
pub fn campaign(target: &Target, opts: &Options) -> Outcome {
    guard::install(opts.timeout, opts.max_alloc, opts.crash_dir.clone());
    let seeds = (target.seeds)(&opts.dirs);
    let mut out = Outcome {
        target: target.name.to_string(),
        seeds: seeds.len(),
        ..Default::default()
    };
    let bytes: Vec<Vec<u8>> = seeds.iter().map(|s| s.bytes.clone()).collect();
    let record = |out: &mut Outcome, index: Option<u64>, input: &[u8], e: Exec| {
        out.executions += 1;
        out.slowest = out.slowest.max(e.took);
        if e.took > opts.timeout {
            // Finished, but past the bound (the watchdog polls): a hang all the same.
            let p = guard::save("hang", target.name, input);
            eprintln!(
                "vfxgraph-fuzz: hang in target `{}` on input {index:?} ({:?}); saved to {}",
                target.name,
                e.took,
                p.display()
            );
            std::process::exit(3);
        }
        match e.result {
            Ok(ok) => {
                out.accepted += ok as u64;
                if e.panics > 0 {
                    out.contained += 1;
                    if out.contained_example.is_none() {
                        let p = guard::save("contained", target.name, input);
                        out.contained_example = Some(format!(
                            "{} (input {index:?}, saved to {})",
                            e.first_panic.unwrap_or_default(),
                            p.display()
                        ));
                    }
                }
            }
            Err(message) => {
                let saved = if out.crashes.len() < SAVED_PER_TARGET {
                    guard::save("crash", target.name, input)
                } else {
                    PathBuf::new()
                };
                out.crashes.push(Crash {
                    index,
                    message,
                    saved,
                });
            }
        }
    };
    for (k, s) in seeds.iter().enumerate() {
        let r = execute(target, opts.seed, u64::MAX - k as u64, &s.bytes);
        if !matches!(r.result, Ok(true)) {
            out.seeds_refused.push(s.name.clone());
        }
        record(&mut out, None, &s.bytes, r);
    }
    let start = Instant::now();
    for i in 0..opts.inputs {
        let Some(input) = make_input(target, &bytes, opts.seed, i) else {
            break;
        };
        let r = execute(target, opts.seed, i, &input);
        record(&mut out, Some(i), &input, r);
        if opts.progress_every > 0 && (i + 1) % opts.progress_every == 0 {
            eprintln!(
                "  {}: {} inputs, {:.0}/s, {} crashes",
                target.name,
                i + 1,
                (i + 1) as f64 / start.elapsed().as_secs_f64(),
                out.crashes.len()
            );
        }
    }
    out.seconds = start.elapsed().as_secs_f64();
    out
}

/// The table of outcomes (one row per target).
pub fn table(outcomes: &[Outcome]) -> String {
    let mut s = format!(
        "{:<14} {:>6} {:>10} {:>9} {:>9} {:>8} {:>6} {:>9} {:>10}\n",
        "target",
        "seeds",
        "execs",
        "exec/s",
        "accepted",
        "crashes",
        "hangs",
        "contained",
        "slowest ms"
    );
    for o in outcomes {
        s += &format!(
            "{:<14} {:>6} {:>10} {:>9.0} {:>8.1}% {:>8} {:>6} {:>9} {:>10.1}\n",
            o.target,
            o.seeds,
            o.executions,
            o.rate(),
            100.0 * o.accepted as f64 / o.executions.max(1) as f64,
            o.crashes.len(),
            0,
            o.contained,
            o.slowest.as_secs_f64() * 1e3,
        );
    }
    s
}
