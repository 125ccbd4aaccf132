//! A campaign: for each target, its seeds run as they are, then `inputs` mutated inputs, each
//! under the guards of [`crate::guard`], in worker processes ([`crate::worker`]) watched by the
//! supervisor here. A panic is caught in the worker, which goes on; a hang, an allocation over
//! the bound or a fatal signal (abort, stack overflow) ends the worker, and the supervisor
//! records the finding, saves its input and starts a new worker at the next input. So every
//! target runs its whole budget whatever an earlier input found, and input `i` is the same
//! whatever ran before it (a function of run seed, target and `i`). The outcome is a row of
//! counts per target and a list of findings, each with its saved input and the command that
//! reproduces it.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use crate::ipc::{self, slot, Config, EventKind, Status, WorkDir};
use crate::mutate::{input_rng, mutate, Kind};
use crate::targets::{fix_png_crcs, SeedDirs, Target};

/// The default memory bound, 1 GiB: one allocation larger than this, or more bytes than this
/// live at once during one input, is a finding.
pub const MAX_ALLOC: usize = 1 << 30;

/// The default time bound of one input.
pub const TIMEOUT: Duration = Duration::from_secs(2);

/// What a campaign runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Mutated inputs per target (the seeds run first, in addition).
    pub inputs: u64,
    /// The run's seed: input `i` of a target depends only on (seed, target, i).
    pub seed: u64,
    /// One input longer than this is a hang.
    pub timeout: Duration,
    /// One allocation larger than this (bytes), or more bytes than this live at once during
    /// one input, is an over-allocation.
    pub max_alloc: usize,
    /// Where failing inputs are written.
    pub crash_dir: PathBuf,
    /// Where seeds are read from.
    pub dirs: SeedDirs,
    /// Print a progress line every this many inputs (0: never).
    pub progress_every: u64,
    /// Threads of the decoders' rayon pool in the workers.
    pub threads: usize,
    /// The `vfxgraph-fuzz` executable the workers run (`None`: this process's own).
    pub worker_exe: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            inputs: 1000,
            seed: 0,
            timeout: TIMEOUT,
            max_alloc: MAX_ALLOC,
            crash_dir: PathBuf::from("fuzz-crashes"),
            dirs: SeedDirs::default(),
            progress_every: 0,
            threads: 1,
            worker_exe: None,
        }
    }
}

/// The kind of a finding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FindingKind {
    /// A panic that escaped the reader, or the process died (abort, fatal signal, exit).
    Crash,
    /// An input ran past the time bound.
    Hang,
    /// One allocation, or the bytes live during one input, over the memory bound.
    OverAlloc,
}

impl FindingKind {
    /// Its name in reports and saved file names.
    pub fn name(self) -> &'static str {
        match self {
            FindingKind::Crash => "crash",
            FindingKind::Hang => "hang",
            FindingKind::OverAlloc => "over-alloc",
        }
    }
}

/// Which input a finding is about.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InputRef {
    /// A seed as it is (its name).
    Seed(String),
    /// Mutated input `i`.
    Index(u64),
}

impl std::fmt::Display for InputRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InputRef::Seed(name) => write!(f, "seed {name}"),
            InputRef::Index(i) => write!(f, "input #{i}"),
        }
    }
}

/// One finding with its reproducer.
#[derive(Clone, Debug)]
pub struct Finding {
    /// The target.
    pub target: String,
    /// What went wrong.
    pub kind: FindingKind,
    /// On which input (`None`: the worker failed outside of an input).
    pub input: Option<InputRef>,
    /// The panic's message and location, the bound crossed, or the signal and the last lines
    /// the process wrote.
    pub message: String,
    /// Where the input was saved (empty when not saved).
    pub saved: PathBuf,
    /// The command that reproduces it.
    pub command: String,
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
    /// Inputs run (seeds + mutated), the findings' included.
    pub executions: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Crashes: panics that escaped the reader, and deaths of the process.
    pub crashes: u64,
    /// Hangs.
    pub hangs: u64,
    /// Over-allocations.
    pub over_allocs: u64,
    /// The findings with their reproducers (at most [`SAVED_PER_TARGET`]; the counts hold all).
    pub findings: Vec<Finding>,
    /// Panics inside third-party code that the reader caught and turned into an error.
    pub contained: u64,
    /// The first contained panic's message, input and saved file.
    pub contained_example: Option<String>,
    /// Wall time of the target's campaign (every worker, seeds included).
    pub seconds: f64,
    /// The slowest input that finished.
    pub slowest: Duration,
    /// The largest rise of live bytes during one input that finished.
    pub peak_bytes: u64,
    /// Worker processes started.
    pub workers: u64,
}

impl Outcome {
    /// Inputs per second over the target's wall time.
    pub fn rate(&self) -> f64 {
        self.executions as f64 / self.seconds.max(1e-9)
    }

    /// Crashes + hangs + over-allocations.
    pub fn finding_count(&self) -> u64 {
        self.crashes + self.hangs + self.over_allocs
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

/// At most this many findings per target keep their saved input and reproducer.
pub const SAVED_PER_TARGET: usize = 20;

/// Input `index` of `target` in a run with `seed`, from its seeds (`None`: no seeds).
pub fn make_input(target: &Target, seeds: &[Vec<u8>], seed: u64, index: u64) -> Option<Vec<u8>> {
    if seeds.is_empty() {
        return None;
    }
    if target.kind == Kind::Index {
        return Some(index.to_string().into_bytes());
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
    /// The largest rise of live bytes while it ran.
    pub peak_bytes: usize,
}

/// Runs one input under the guards.
pub fn execute(target: &Target, seed: u64, index: u64, input: &[u8]) -> Exec {
    crate::guard::begin(target.name, seed, index);
    let t = Instant::now();
    let r = std::panic::catch_unwind(|| (target.run)(input));
    let took = t.elapsed();
    let peak_bytes = crate::guard::end();
    let (panics, first_panic) = crate::guard::take_panic();
    let result = r.map_err(|_| first_panic.clone().unwrap_or_else(|| "panic".into()));
    Exec {
        result,
        panics,
        first_panic,
        took,
        peak_bytes,
    }
}

/// The file a finding's input is saved to: `DIR/KIND-TARGET-HASH` (the input's BLAKE3, 16 hex
/// digits), so one input is saved once.
pub fn crash_path(dir: &Path, kind: &str, target: &str, bytes: &[u8]) -> PathBuf {
    let h = blake3::hash(bytes).to_hex();
    dir.join(format!("{kind}-{target}-{}", &h[..16]))
}

/// Writes `bytes` under `dir`; returns the path.
pub fn save(dir: &Path, kind: &str, target: &str, bytes: &[u8]) -> PathBuf {
    let p = crash_path(dir, kind, target, bytes);
    let _ = std::fs::create_dir_all(dir);
    let _ = std::fs::write(&p, bytes);
    p
}

/// The command that reproduces a finding: the mutated input rebuilt from its index, a seed run
/// from its saved file; with the bounds and threads when they are not the defaults.
pub fn reproducer(target: &str, input: &InputRef, saved: &Path, opts: &Options) -> String {
    let mut c = format!("cargo run --release -p vfxgraph-fuzz -- --target {target}");
    match input {
        InputRef::Index(i) => c += &format!(" --seed {} --index {i}", opts.seed),
        InputRef::Seed(_) => c += &format!(" --file {}", saved.display()),
    }
    if opts.timeout != TIMEOUT {
        c += &format!(" --timeout-ms {}", opts.timeout.as_millis());
    }
    if opts.max_alloc != MAX_ALLOC {
        c += &format!(" --max-alloc-mb {}", opts.max_alloc >> 20);
    }
    if opts.threads != 1 {
        c += &format!(" --threads {}", opts.threads);
    }
    c
}

/// A campaign's state for one target in the supervisor.
struct Supervisor<'a> {
    target: &'a Target,
    opts: &'a Options,
    seeds: Vec<(String, Vec<u8>)>,
    seed_bytes: Vec<Vec<u8>>,
    out: Outcome,
}

impl Supervisor<'_> {
    /// The input at position `pos` and what it is.
    fn input_at(&self, pos: u64) -> (InputRef, Vec<u8>) {
        let n = self.seeds.len() as u64;
        if pos < n {
            let (name, bytes) = &self.seeds[pos as usize];
            (InputRef::Seed(name.clone()), bytes.clone())
        } else {
            let i = pos - n;
            let bytes =
                make_input(self.target, &self.seed_bytes, self.opts.seed, i).unwrap_or_default();
            (InputRef::Index(i), bytes)
        }
    }

    /// Records a finding on the input at `pos` (`None`: outside of an input).
    fn record(&mut self, kind: FindingKind, pos: Option<u64>, message: String) {
        match kind {
            FindingKind::Crash => self.out.crashes += 1,
            FindingKind::Hang => self.out.hangs += 1,
            FindingKind::OverAlloc => self.out.over_allocs += 1,
        }
        let name = self.target.name;
        let Some(pos) = pos else {
            eprintln!("  {}: {message}", kind.name());
            if self.out.findings.len() < SAVED_PER_TARGET {
                self.out.findings.push(Finding {
                    target: name.to_string(),
                    kind,
                    input: None,
                    message,
                    saved: PathBuf::new(),
                    command: String::new(),
                });
            }
            return;
        };
        let (input, bytes) = self.input_at(pos);
        if self.out.findings.len() < SAVED_PER_TARGET {
            let saved = save(&self.opts.crash_dir, kind.name(), name, &bytes);
            let command = reproducer(name, &input, &saved, self.opts);
            eprintln!(
                "  {} on {input}: {message}\n    saved to {}\n    reproduce: {command}",
                kind.name(),
                saved.display()
            );
            self.out.findings.push(Finding {
                target: name.to_string(),
                kind,
                input: Some(input),
                message,
                saved,
                command,
            });
        } else {
            eprintln!("  {} on {input}: {message}", kind.name());
        }
    }

    /// Reads a finished worker's counters and events.
    fn collect(&mut self, status: &Status, work: &WorkDir) -> Option<ipc::Event> {
        self.out.executions += status.get(slot::EXECUTIONS);
        self.out.accepted += status.get(slot::ACCEPTED);
        self.out.contained += status.get(slot::CONTAINED);
        self.out.slowest = self
            .out
            .slowest
            .max(Duration::from_micros(status.get(slot::SLOWEST_US)));
        self.out.peak_bytes = self.out.peak_bytes.max(status.get(slot::PEAK_BYTES));
        let mut fatal = None;
        for e in ipc::read_events(&work.events()) {
            match e.kind {
                EventKind::Refused => {
                    if let Some((name, _)) = e.pos.and_then(|p| self.seeds.get(p as usize)) {
                        self.out.seeds_refused.push(name.clone());
                    }
                }
                EventKind::Contained => {
                    if self.out.contained_example.is_none() {
                        if let Some(p) = e.pos {
                            let (input, bytes) = self.input_at(p);
                            let saved =
                                save(&self.opts.crash_dir, "contained", self.target.name, &bytes);
                            self.out.contained_example = Some(format!(
                                "{} ({input}, saved to {})",
                                e.message,
                                saved.display()
                            ));
                        }
                    }
                }
                _ if e.fatal => fatal = Some(e),
                EventKind::Crash => self.record(FindingKind::Crash, e.pos, e.message),
                EventKind::Hang => self.record(FindingKind::Hang, e.pos, e.message),
                EventKind::OverAlloc => self.record(FindingKind::OverAlloc, e.pos, e.message),
            }
        }
        fatal
    }
}

/// How long a worker may show no progress on one input before the supervisor ends it: the
/// worker's own watchdog ends a hang after the time bound, so this only acts when the whole
/// process is stuck (stopped, or its watchdog cannot run).
fn backstop(timeout: Duration) -> Duration {
    timeout * 2 + Duration::from_secs(1)
}

/// How long a worker may take to start its first input.
const STARTUP: Duration = Duration::from_secs(120);

/// The name of a fatal signal.
fn signal_name(sig: i32) -> String {
    let name = match sig {
        libc::SIGABRT => "SIGABRT",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGILL => "SIGILL",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGTRAP => "SIGTRAP",
        _ => return format!("signal {sig}"),
    };
    format!("{name} ({sig})")
}

/// Runs `target`'s seeds, then `opts.inputs` mutated inputs, in worker processes; returns its
/// outcome. Never stops early: after each fatal finding a new worker starts at the next input.
pub fn campaign(target: &Target, opts: &Options) -> Outcome {
    let t0 = Instant::now();
    let seeds: Vec<(String, Vec<u8>)> = (target.seeds)(&opts.dirs)
        .into_iter()
        .map(|s| (s.name, s.bytes))
        .collect();
    let mut sup = Supervisor {
        target,
        opts,
        seed_bytes: seeds.iter().map(|s| s.1.clone()).collect(),
        out: Outcome {
            target: target.name.to_string(),
            seeds: seeds.len(),
            ..Default::default()
        },
        seeds,
    };
    if sup.seeds.is_empty() {
        return sup.out;
    }
    static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let run = RUNS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let work = WorkDir {
        path: std::env::temp_dir().join(format!(
            "vfxgraph-fuzz-{}-{run}-{}",
            std::process::id(),
            target.name
        )),
    };
    if let Err(e) = supervise(&mut sup, &work) {
        sup.record(
            FindingKind::Crash,
            None,
            format!("the campaign could not run: {e}"),
        );
    }
    let _ = std::fs::remove_dir_all(&work.path);
    sup.out.seconds = t0.elapsed().as_secs_f64();
    sup.out
}

/// The supervisor's loop: workers from position 0 to the end.
fn supervise(sup: &mut Supervisor, work: &WorkDir) -> std::io::Result<()> {
    let opts = sup.opts;
    std::fs::create_dir_all(&work.path)?;
    let config = Config {
        target: sup.target.name.to_string(),
        seed: opts.seed,
        inputs: opts.inputs,
        timeout_ms: opts.timeout.as_millis() as u64,
        max_alloc: opts.max_alloc,
        threads: opts.threads,
    };
    std::fs::write(
        work.config(),
        serde_json::to_vec(&config).map_err(std::io::Error::other)?,
    )?;
    ipc::write_seeds(&work.seeds(), &sup.seeds)?;
    let status = Status::map(&work.status())?;
    let exe = match &opts.worker_exe {
        Some(p) => p.clone(),
        None => std::env::current_exe()?,
    };
    let end = sup.seeds.len() as u64 + opts.inputs;
    let mut pos = 0u64;
    let mut next_progress = opts.progress_every;
    let started = Instant::now();
    while pos < end {
        status.clear();
        File::create(work.events())?;
        let mut child = Command::new(&exe)
            .arg("--worker")
            .arg(&work.path)
            .arg("--start")
            .arg(pos.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(File::create(work.stderr())?)
            .spawn()?;
        sup.out.workers += 1;
        let base = sup.out.executions;
        let (exit, stuck) = watch(&mut child, &status, opts, |done| {
            let done = base + done;
            if opts.progress_every > 0 && done >= next_progress {
                next_progress = done + opts.progress_every;
                eprintln!(
                    "  {}: {done} inputs, {:.0}/s, {} findings",
                    sup.target.name,
                    done as f64 / started.elapsed().as_secs_f64(),
                    sup.out.finding_count()
                );
            }
        })?;
        let done = status.get(slot::DONE);
        let current = status.get(slot::CURRENT);
        let fatal = sup.collect(&status, work);
        if done >= end {
            break;
        }
        // The worker ended before the end: the input it was on is a finding.
        let at = fatal
            .as_ref()
            .and_then(|e| e.pos)
            .or_else(|| current.checked_sub(1));
        let Some(at) = at else {
            let tail = ipc::tail(&work.stderr(), 6).join(" | ");
            return Err(std::io::Error::other(format!(
                "the worker ended before its first input ({exit}; is the worker executable \
                 vfxgraph-fuzz?){}",
                if tail.is_empty() {
                    String::new()
                } else {
                    format!(": {tail}")
                }
            )));
        };
        let (kind, message) = match (&fatal, stuck) {
            (Some(e), _) => (
                if e.kind == EventKind::Hang {
                    FindingKind::Hang
                } else {
                    FindingKind::OverAlloc
                },
                e.message.clone(),
            ),
            (None, true) => (
                FindingKind::Hang,
                format!(
                    "no progress for {} ms (the worker was stopped or its watchdog could not \
                     run); the supervisor killed it",
                    backstop(opts.timeout).as_millis()
                ),
            ),
            (None, false) => {
                use std::os::unix::process::ExitStatusExt;
                let how = match (exit.signal(), exit.code()) {
                    (Some(s), _) => format!("killed by {}", signal_name(s)),
                    (None, Some(c)) => format!("the process exited with status {c}"),
                    _ => exit.to_string(),
                };
                let tail = ipc::tail(&work.stderr(), 4)
                    .into_iter()
                    .filter(|l| !l.starts_with("vfxgraph-fuzz: fatal signal"))
                    .collect::<Vec<_>>()
                    .join(" | ");
                (
                    FindingKind::Crash,
                    if tail.is_empty() {
                        how
                    } else {
                        format!("{how}: {tail}")
                    },
                )
            }
        };
        if at >= done {
            // The input did not finish; it ran all the same.
            sup.out.executions += 1;
        }
        sup.record(kind, Some(at), message);
        pos = at + 1;
    }
    Ok(())
}

/// Waits for `child`, calling `progress` with the inputs it finished; kills it when it shows
/// no progress for [`backstop`] (returns true then).
fn watch(
    child: &mut std::process::Child,
    status: &Status,
    opts: &Options,
    mut progress: impl FnMut(u64),
) -> std::io::Result<(ExitStatus, bool)> {
    let mut last = (u64::MAX, Instant::now());
    let limit = backstop(opts.timeout);
    let mut poll = Duration::from_millis(1);
    loop {
        if let Some(exit) = child.try_wait()? {
            return Ok((exit, false));
        }
        let current = status.get(slot::CURRENT);
        let done = status.get(slot::DONE);
        if current != last.0 {
            last = (current, Instant::now());
        }
        let waited = last.1.elapsed();
        let stuck = if current == 0 {
            waited > STARTUP
        } else {
            current > done && waited > limit
        };
        if stuck {
            let _ = child.kill();
            return Ok((child.wait()?, true));
        }
        progress(status.get(slot::EXECUTIONS));
        std::thread::sleep(poll);
        poll = (poll * 2).min(Duration::from_millis(20));
    }
}

/// The table of outcomes (one row per target).
pub fn table(outcomes: &[Outcome]) -> String {
    let mut s = format!(
        "{:<14} {:>6} {:>10} {:>9} {:>9} {:>8} {:>6} {:>10} {:>9} {:>10} {:>8}\n",
        "target",
        "seeds",
        "execs",
        "exec/s",
        "accepted",
        "crashes",
        "hangs",
        "over-alloc",
        "contained",
        "slowest ms",
        "peak MiB"
    );
    for o in outcomes {
        s += &format!(
            "{:<14} {:>6} {:>10} {:>9.0} {:>8.1}% {:>8} {:>6} {:>10} {:>9} {:>10.1} {:>8.1}\n",
            o.target,
            o.seeds,
            o.executions,
            o.rate(),
            100.0 * o.accepted as f64 / o.executions.max(1) as f64,
            o.crashes,
            o.hangs,
            o.over_allocs,
            o.contained,
            o.slowest.as_secs_f64() * 1e3,
            o.peak_bytes as f64 / (1u64 << 20) as f64,
        );
    }
    s
}

/// The findings of `outcomes`, each with its input, message, saved file and reproducer
/// (empty when there are none).
pub fn findings_report(outcomes: &[Outcome]) -> String {
    let mut s = String::new();
    for o in outcomes {
        for f in &o.findings {
            let input = f
                .input
                .as_ref()
                .map_or("outside of an input".to_string(), |i| i.to_string());
            s += &format!(
                "{} in {} on {input}: {}\n",
                f.kind.name(),
                f.target,
                f.message
            );
            if !f.command.is_empty() {
                s += &format!(
                    "    saved: {}\n    reproduce: {}\n",
                    f.saved.display(),
                    f.command
                );
            }
        }
        let more = o.finding_count().saturating_sub(o.findings.len() as u64);
        if more > 0 {
            s += &format!("… and {more} more in {} (counted, not saved)\n", o.target);
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproducer_names_the_input_and_the_bounds_that_differ() {
        let mut o = Options::default();
        let saved = Path::new("fuzz-crashes/crash-exr-0123456789abcdef");
        assert_eq!(
            reproducer("exr", &InputRef::Index(42), saved, &o),
            "cargo run --release -p vfxgraph-fuzz -- --target exr --seed 0 --index 42"
        );
        o.seed = 7;
        o.max_alloc = 64 << 20;
        o.timeout = Duration::from_millis(300);
        assert_eq!(
            reproducer("exr", &InputRef::Seed("a.exr".into()), saved, &o),
            "cargo run --release -p vfxgraph-fuzz -- --target exr --file \
             fuzz-crashes/crash-exr-0123456789abcdef --timeout-ms 300 --max-alloc-mb 64"
        );
    }

    #[test]
    fn table_and_findings_show_every_count() {
        let o = Outcome {
            target: "pfm".into(),
            seeds: 2,
            executions: 1002,
            accepted: 501,
            crashes: 2,
            hangs: 1,
            over_allocs: 0,
            findings: vec![Finding {
                target: "pfm".into(),
                kind: FindingKind::Hang,
                input: Some(InputRef::Index(5)),
                message: "over 2000 ms".into(),
                saved: PathBuf::from("d/hang-pfm-00"),
                command: "cargo run … --index 5".into(),
            }],
            seconds: 2.0,
            slowest: Duration::from_millis(12),
            peak_bytes: 3 << 20,
            ..Default::default()
        };
        let t = table(std::slice::from_ref(&o));
        let row = t.lines().nth(1).unwrap();
        let cols: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(
            cols,
            ["pfm", "2", "1002", "501", "50.0%", "2", "1", "0", "0", "12.0", "3.0"]
        );
        let f = findings_report(&[o]);
        assert!(f.starts_with("hang in pfm on input #5: over 2000 ms\n"));
        assert!(f.contains("reproduce: cargo run … --index 5"));
        assert!(f.contains("… and 2 more in pfm"));
    }
}
