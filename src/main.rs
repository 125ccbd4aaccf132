//! `vfxgraph`: the command line. It parses arguments and wires the engine to the node catalog;
//! nothing algorithmic lives here.

mod bench;
mod bench_shot;
mod bench_video;
mod farm;
mod interrupt;
mod probe;
mod progress;
mod reference;
mod report;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use vfxgraph_engine::exec::{self, default_cache_dir, RunOptions};
use vfxgraph_engine::graph::{self, LoadError, Overrides};
use vfxgraph_engine::store::Store;
use vfxgraph_engine::{Graph, ParamValue, Registry};

/// vfxgraph — a dataflow node-graph engine for visual effects.
///
/// Graphs are YAML files of typed nodes; `run` executes them in parallel and caches every
/// node's outputs by content, so a second run only recomputes what changed.
#[derive(Parser)]
#[command(name = "vfxgraph", version, about, long_about = None)]
struct Cli {
    /// More log output (-v info, -vv debug).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only errors; no progress bars or summary table.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// Refuse a graph of more node instances than this (a mistyped frame range).
    #[arg(long, global = true, value_name = "N", default_value_t = graph::DEFAULT_MAX_INSTANCES)]
    max_instances: u64,
    /// Refuse a node whose one instance declares more memory than this, in GiB (a render's
    /// image size).
    #[arg(long, global = true, value_name = "GIB", default_value_t = graph::DEFAULT_MAX_INSTANCE_GIB)]
    max_instance_memory: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a graph (cached nodes are not recomputed).
    Run {
        #[command(flatten)]
        graph: GraphArgs,
        #[command(flatten)]
        cache: CacheArgs,
        /// Worker threads (default: one per core).
        #[arg(short, long)]
        jobs: Option<usize>,
        /// Run NODE even if it is cached (repeatable).
        #[arg(long, value_name = "NODE")]
        force: Vec<String>,
        /// Print the per-instance report as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Validate a graph and report every problem with its line and column.
    Check {
        #[command(flatten)]
        graph: GraphArgs,
    },
    /// Show what a run would do: per node instance, cached / run / blocked and why.
    Plan {
        #[command(flatten)]
        graph: GraphArgs,
        #[command(flatten)]
        cache: CacheArgs,
        /// Treat NODE as not cached (repeatable).
        #[arg(long, value_name = "NODE")]
        force: Vec<String>,
        /// Print the plan as JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// List the node types (`--markdown`: the whole node reference, docs/reference/nodes.md).
    Nodes {
        /// Print the node reference as Markdown: every node's ports, params and defaults.
        #[arg(long)]
        markdown: bool,
    },
    /// What the readers know of image and video files: size, encoding, colour fields, frame
    /// count and rate, and the camera's focal length from EXIF or QuickTime metadata.
    Probe {
        /// The files.
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Describe a node type: ports, params, defaults, ranges.
    Describe {
        /// The node type.
        #[arg(value_name = "TYPE")]
        node_type: String,
    },
    /// Print the graph in Graphviz dot, coloured by plan (green cached, orange run, grey blocked).
    Dot {
        #[command(flatten)]
        graph: GraphArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Inspect or clean the cache.
    Cache {
        #[command(subcommand)]
        action: CacheAction,
    },
    /// Run exactly the named node instances, their inputs from the cache (one farm task).
    Exec(farm::commands::ExecArgs),
    /// Submit the uncached instances to a render farm (Slurm, or an OpenJD job template).
    Submit(farm::commands::SubmitArgs),
    /// Per node: instances cached, farm tasks running and queued, instances missing.
    Status(farm::commands::StatusArgs),
    /// The studio in a browser: the graph live, its frames, the point-cloud definer, the solve.
    Serve {
        /// The graph file (YAML); served even when it does not load (with its diagnostics).
        graph: PathBuf,
        /// Port (0: any free port; the URL is printed).
        #[arg(long, default_value_t = 8080)]
        port: u16,
        /// Address to listen on (off loopback, every request needs the token the URL carries).
        #[arg(long, default_value = "127.0.0.1")]
        bind: std::net::IpAddr,
        /// Cache folder (default: .vfxgraph/ beside the graph file).
        #[arg(long, value_name = "DIR")]
        cache: Option<PathBuf>,
        /// Worker threads of runs (default: one per core).
        #[arg(short, long)]
        jobs: Option<usize>,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: bench::BenchCommand,
    },
}

#[derive(Args)]
struct GraphArgs {
    /// The graph file (YAML).
    graph: PathBuf,
    /// Override a parameter: node.param=value (repeatable).
    #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
    set: Vec<String>,
    /// Override the frame range, e.g. 0..=239 or 1-10,15,20-40:2.
    #[arg(long)]
    frames: Option<String>,
    /// The OpenColorIO config of every node with an `ocio_config` parameter it leaves unset
    /// (above the graph's `defaults:`; its content is part of the cache keys). Default: $OCIO,
    /// else the built-in ACES studio config.
    #[arg(long, value_name = "FILE")]
    ocio: Option<PathBuf>,
    /// Whether $OCIO stands in for a missing `--ocio` (not in a farm task, which gets its
    /// submit's config or none, whatever its host's environment says).
    #[arg(skip = true)]
    ocio_from_env: bool,
}

impl GraphArgs {
    /// The graph file with `--set` and `--frames` (and no `--ocio`, nor $OCIO).
    fn plain(graph: PathBuf, set: Vec<String>, frames: Option<String>) -> GraphArgs {
        GraphArgs {
            graph,
            set,
            frames,
            ocio: None,
            ocio_from_env: false,
        }
    }

    /// `--ocio`, else $OCIO (when allowed and set), as an absolute path.
    fn ocio_config(&self) -> Option<PathBuf> {
        let env = || {
            std::env::var_os("OCIO")
                .filter(|v| self.ocio_from_env && !v.is_empty())
                .map(PathBuf::from)
        };
        let p = self.ocio.clone().or_else(env)?;
        // Relative to where the command runs, as the user typed it (not to the graph).
        Some(std::path::absolute(&p).unwrap_or(p))
    }
}

#[derive(Args)]
struct CacheArgs {
    /// Cache folder (default: .vfxgraph/ beside the graph file).
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Neither read nor write the cache.
    #[arg(long)]
    no_cache: bool,
}

#[derive(Args)]
struct CacheLocation {
    /// Cache folder.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// A graph file whose default cache (.vfxgraph/ beside it) to use.
    graph: Option<PathBuf>,
}

#[derive(Subcommand)]
enum CacheAction {
    /// List cached node instances, most recently used first.
    Ls {
        #[command(flatten)]
        at: CacheLocation,
    },
    /// Disk usage, in total and by artifact type.
    Du {
        #[command(flatten)]
        at: CacheLocation,
    },
    /// Remove unreferenced objects; with --max-size, also the least recently used entries.
    /// Safe while other processes or a farm use the cache: objects younger than --grace are
    /// kept (a writer's objects precede the entry naming them), and --max-size is refused
    /// while a farm submission's lease is younger than a day (its queued tasks need entries
    /// it could evict).
    Gc {
        #[command(flatten)]
        at: CacheLocation,
        /// Size to shrink to, e.g. 500M, 2G, 100000 (bytes).
        #[arg(long, value_parser = parse_size)]
        max_size: Option<u64>,
        /// Keep unreferenced objects younger than this many seconds.
        #[arg(long, value_name = "SECONDS", default_value_t = 3600)]
        grace: u64,
        /// Evict with --max-size even while a farm submission is active.
        #[arg(long)]
        ignore_farm: bool,
    },
    /// Delete the whole cache.
    Clear {
        #[command(flatten)]
        at: CacheLocation,
    },
}

fn parse_size(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => {
            let unit = s[i..].to_ascii_uppercase();
            let m: u64 = match unit.trim_end_matches("IB").trim_end_matches('B') {
                "" => 1,
                "K" => 1 << 10,
                "M" => 1 << 20,
                "G" => 1 << 30,
                "T" => 1 << 40,
                _ => return Err(format!("unknown size unit in `{s}` (use K, M, G, T)")),
            };
            (&s[..i], m)
        }
        None => (s, 1),
    };
    let n: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a size"))?;
    if !(n >= 0.0 && n.is_finite()) {
        return Err(format!("`{s}` is not a size"));
    }
    Ok((n * mult as f64) as u64)
}

/// Exit codes: 0 success, 1 a node failed, 2 the graph or the command line is wrong.
const EXIT_FAILED: u8 = 1;
const EXIT_INVALID: u8 = 2;
const EXIT_INTERRUPTED: u8 = 130;

fn main() -> ExitCode {
    let cli = Cli::parse();
    if prints_listings(&cli.command) {
        default_sigpipe();
    }
    init_logging(cli.verbose, cli.quiet);
    // A farm task runs what its submission was allowed to submit: no limits of its own.
    let _ = LIMITS.set(match cli.command {
        Command::Exec(_) => graph::Limits {
            max_instances: u64::MAX,
            max_instance_gib: u64::MAX,
        },
        _ => graph::Limits {
            max_instances: cli.max_instances,
            max_instance_gib: cli.max_instance_memory,
        },
    });
    let registry = vfxgraph_nodes::registry();
    match dispatch(cli, &registry) {
        Ok(code) => ExitCode::from(code),
        Err(msg) => {
            eprintln!("error: {msg}");
            ExitCode::from(EXIT_INVALID)
        }
    }
}

/// The commands whose output is a listing a user pipes into `head`, `less` or `grep`.
fn prints_listings(c: &Command) -> bool {
    matches!(
        c,
        Command::Plan { .. }
            | Command::Nodes { .. }
            | Command::Describe { .. }
            | Command::Probe { .. }
            | Command::Dot { .. }
            | Command::Cache { .. }
            | Command::Check { .. }
            | Command::Status(_)
    )
}

/// A listing piped into `head` ends quietly when the reader closes the pipe, as `ls | head`
/// does: the default action of SIGPIPE (Rust ignores it, so `println!` would panic on the
/// closed pipe). Not for the commands that write to sockets or to children's pipes, whose
/// errors are handled where they occur.
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: called at the start of main, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn init_logging(verbose: u8, quiet: bool) {
    let level = match (quiet, verbose) {
        (true, _) => tracing::Level::ERROR,
        (false, 0) => tracing::Level::WARN,
        (false, 1) => tracing::Level::INFO,
        (false, _) => tracing::Level::DEBUG,
    };
    tracing_subscriber::fmt()
        .with_max_level(level)
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        .init();
}

/// Loads a graph, printing its diagnostics on failure.
/// The graph limits of the command line (`--max-instances`, `--max-instance-memory`).
static LIMITS: std::sync::OnceLock<graph::Limits> = std::sync::OnceLock::new();

fn load_graph(args: &GraphArgs, registry: &Registry) -> Result<Graph, u8> {
    let mut overrides = Overrides {
        set: args.set.clone(),
        frames: args.frames.clone(),
        ..Overrides::default()
    };
    if let Some(ocio) = args.ocio_config() {
        overrides.defaults.push((
            "ocio_config".into(),
            ParamValue::Str(ocio.to_string_lossy().into_owned()),
        ));
    }
    match graph::load(&args.graph, registry, &overrides) {
        Ok(g) => match g.check_limits(LIMITS.get().unwrap_or(&graph::Limits::default())) {
            Ok(()) => Ok(g),
            Err(e) => {
                eprintln!("error: {}: {e}", args.graph.display());
                Err(EXIT_INVALID)
            }
        },
        Err(LoadError::Io { path, source }) => {
            eprintln!("error: cannot read graph file {}: {source}", path.display());
            Err(EXIT_INVALID)
        }
        Err(LoadError::Invalid(d)) => {
            report::print_diagnostics(&d);
            Err(EXIT_INVALID)
        }
    }
}

fn cache_dir(graph_file: &Path, args: &CacheArgs) -> Option<PathBuf> {
    if args.no_cache {
        None
    } else {
        Some(
            args.cache
                .clone()
                .unwrap_or_else(|| default_cache_dir(graph_file)),
        )
    }
}

fn dispatch(cli: Cli, registry: &Registry) -> Result<u8, String> {
    let quiet = cli.quiet;
    match cli.command {
        Command::Run {
            graph,
            cache,
            jobs,
            force,
            json,
        } => {
            let g = match load_graph(&graph, registry) {
                Ok(g) => g,
                Err(code) => return Ok(code),
            };
            let interrupted = interrupt::install();
            let opts = RunOptions {
                jobs,
                cache_dir: cache_dir(&graph.graph, &cache),
                force,
                cancel: Some(interrupted.clone()),
                only: None,
            };
            let bars = progress::Bars::new(&g, quiet || json);
            let rep = exec::run(&g, registry, &opts, &bars).map_err(|e| e.to_string())?;
            bars.finish();
            if json {
                // Also when interrupted: the cancelled instances show as failed or skipped.
                println!(
                    "{}",
                    serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?
                );
            }
            if interrupted.load(std::sync::atomic::Ordering::SeqCst) {
                eprintln!("interrupted: finished nodes are cached, the rest will run next time");
                return Ok(EXIT_INTERRUPTED);
            }
            if !json {
                report::print_failures(&rep);
                if !quiet {
                    report::print_table(&rep);
                }
            }
            Ok(if rep.failed() { EXIT_FAILED } else { 0 })
        }
        Command::Check { graph } => match load_graph(&graph, registry) {
            Ok(g) => {
                if !quiet {
                    println!(
                        "{}: ok ({} nodes, {} instances, frames {})",
                        graph.graph.display(),
                        g.nodes.len(),
                        g.instance_count(),
                        if g.frames.is_empty() {
                            "none".to_string()
                        } else {
                            g.frames.to_string()
                        }
                    );
                }
                Ok(0)
            }
            Err(code) => Ok(code),
        },
        Command::Plan {
            graph,
            cache,
            force,
            json,
        } => {
            let g = match load_graph(&graph, registry) {
                Ok(g) => g,
                Err(code) => return Ok(code),
            };
            let opts = RunOptions {
                jobs: None,
                cache_dir: cache_dir(&graph.graph, &cache),
                force,
                cancel: None,
                only: None,
            };
            let p = exec::plan(&g, &opts).map_err(|e| e.to_string())?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&p).map_err(|e| e.to_string())?
                );
            } else {
                report::print_plan(&p);
            }
            Ok(0)
        }
        Command::Nodes { markdown } => {
            if markdown {
                print!("{}", reference::nodes_markdown(registry));
            } else {
                report::print_nodes(registry);
            }
            Ok(0)
        }
        Command::Probe { files, json } => probe::run(&files, json),
        Command::Describe { node_type } => match registry.node(&node_type) {
            Some(n) => {
                report::print_describe(n.spec(), registry);
                Ok(0)
            }
            None => Err(match registry.unavailable(&node_type) {
                Some(why) => format!("unknown node type `{node_type}`: {why}"),
                None => format!("unknown node type `{node_type}` (`vfxgraph nodes` lists them)"),
            }),
        },
        Command::Dot { graph, cache } => {
            let g = match load_graph(&graph, registry) {
                Ok(g) => g,
                Err(code) => return Ok(code),
            };
            let opts = RunOptions {
                jobs: None,
                cache_dir: cache_dir(&graph.graph, &cache),
                force: vec![],
                cancel: None,
                only: None,
            };
            let p = exec::plan(&g, &opts).map_err(|e| e.to_string())?;
            print!("{}", report::dot(&g, &p));
            Ok(0)
        }
        Command::Serve {
            graph,
            port,
            bind,
            cache,
            jobs,
        } => {
            let cache_dir = cache.unwrap_or_else(|| default_cache_dir(&graph));
            vfxgraph_serve::serve(
                vfxgraph_serve::ServeOptions {
                    graph,
                    cache_dir,
                    bind,
                    port,
                    jobs,
                },
                vfxgraph_nodes::registry(),
            )?;
            Ok(0)
        }
        Command::Cache { action } => cache_command(action),
        Command::Exec(a) => farm::commands::exec_command(a, registry, quiet),
        Command::Submit(a) => farm::commands::submit_command(a, registry),
        Command::Status(a) => farm::commands::status_command(a, registry),
        Command::Bench { what } => bench::run(what, registry),
    }
}

fn open_cache(at: &CacheLocation) -> Result<Store, String> {
    let dir = match (&at.cache, &at.graph) {
        (Some(d), _) => d.clone(),
        (None, Some(g)) => default_cache_dir(g),
        (None, None) => PathBuf::from(".vfxgraph"),
    };
    if !dir.is_dir() {
        return Err(format!("no cache at {}", dir.display()));
    }
    Store::open(&dir).map_err(|e| format!("cannot open cache {}: {e}", dir.display()))
}

fn cache_command(action: CacheAction) -> Result<u8, String> {
    match action {
        CacheAction::Ls { at } => {
            let store = open_cache(&at)?;
            report::print_cache_ls(&store.list());
        }
        CacheAction::Du { at } => {
            let store = open_cache(&at)?;
            report::print_cache_du(&store);
        }
        CacheAction::Gc {
            at,
            max_size,
            grace,
            ignore_farm,
        } => {
            let store = open_cache(&at)?;
            if max_size.is_some() && !ignore_farm {
                let active = farm::active_submissions(store.root(), farm::LEASE);
                if let Some((token, age)) = active.first() {
                    return Err(format!(
                        "cache {}: a farm run is active (submission {token}, a task started or \
                         ended {} s ago; {} active): --max-size could evict entries its queued \
                         tasks need. Run gc without --max-size (it removes only unreferenced \
                         objects), wait until the run ends, or pass --ignore-farm",
                        store.root().display(),
                        age.as_secs(),
                        active.len()
                    ));
                }
            }
            let r = store.gc(max_size, std::time::Duration::from_secs(grace));
            println!(
                "removed {} entries and {} objects, freed {}; {} left; kept {} unreferenced \
                 object(s) younger than {grace} s",
                r.actions_removed,
                r.objects_removed,
                report::human_bytes(r.bytes_freed),
                report::human_bytes(r.bytes_left),
                r.objects_kept_young
            );
        }
        CacheAction::Clear { at } => {
            let store = open_cache(&at)?;
            store.clear().map_err(|e| e.to_string())?;
            println!("cleared {}", store.root().display());
        }
    }
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes() {
        assert_eq!(parse_size("100"), Ok(100));
        assert_eq!(parse_size("2K"), Ok(2048));
        assert_eq!(parse_size("1.5M"), Ok(1_572_864));
        assert_eq!(parse_size("1GiB"), Ok(1 << 30));
        assert!(parse_size("3X").is_err());
        assert!(parse_size("-1").is_err());
    }
}
