//! The farm's commands: `exec` (one task), `submit` and `status`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use vfxgraph_engine::exec::{self, default_cache_dir, RunOptions, Target};
use vfxgraph_engine::lease::{self, Holder, Lease};
use vfxgraph_engine::{FrameSet, Graph, Registry};

use super::record::{self, Submission};
use super::{absolute, check_cache_writable, find_program, FarmPlan, InFlight, TaskContext};
use crate::{load_graph, GraphArgs, EXIT_FAILED};

/// `vfxgraph exec`: the arguments.
#[derive(Args)]
pub struct ExecArgs {
    /// The graph file (YAML).
    pub graph: PathBuf,
    /// The node whose instances to run (repeatable).
    #[arg(long = "node", value_name = "ID", required = true)]
    pub nodes: Vec<String>,
    /// Frames of the nodes to run (default: all of the graph's), e.g. 1-4,9.
    #[arg(long)]
    pub frames: Option<String>,
    /// The graph's frame range, as `run --frames` sets it (a farm task gets its submit's).
    #[arg(long, value_name = "R")]
    pub range: Option<String>,
    /// Override a parameter: node.param=value (repeatable).
    #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
    pub set: Vec<String>,
    /// The OpenColorIO config of the submit (a task ignores $OCIO).
    #[arg(long, value_name = "FILE")]
    pub ocio: Option<PathBuf>,
    /// Cache folder (default: .vfxgraph/ beside the graph file).
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Worker threads (default: one per core).
    #[arg(short, long)]
    pub jobs: Option<usize>,
    /// Print the per-instance report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// The submission token `submit` passes to its tasks: the task fails at once unless the
    /// cache holds it (a cache not shared with the submitting host).
    #[arg(long, value_name = "TOKEN")]
    pub token: Option<String>,
}

/// The farms `submit` knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Farm {
    /// Slurm (`sbatch` job arrays).
    Slurm,
    /// Open Job Description (a job template for `openjd run` or AWS Deadline Cloud).
    Openjd,
}

impl Farm {
    /// Its name in records and JSON.
    fn name(self) -> &'static str {
        match self {
            Farm::Slurm => "slurm",
            Farm::Openjd => "openjd",
        }
    }
}

/// `vfxgraph submit`: the arguments.
#[derive(Args)]
pub struct SubmitArgs {
    #[command(flatten)]
    pub graph: GraphArgs,
    /// The farm.
    #[arg(long, value_enum)]
    pub farm: Farm,
    /// Frames per task of a per-frame node.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..))]
    pub chunk: u32,
    /// The shared cache folder (default: .vfxgraph/ beside the graph file).
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// Run a chain of per-frame nodes as one task per chunk (`exec --node A --node B …`):
    /// a node joins its per-frame producer's job when it reads only that job per chunk and
    /// waits for nothing that job does not (the book shot: 131 tasks → 35).
    #[arg(long)]
    pub fuse: bool,
    /// CPUs a task of a per-frame node that uses every core (a render) asks for, instead of
    /// the whole host: several such tasks then share a host, one's start and serial parts
    /// overlapping another's compute.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub task_cpus: Option<u32>,
    /// Print the jobs (Slurm: a sh script that submits them) or the template (OpenJD) without
    /// submitting or writing.
    #[arg(long)]
    pub dry_run: bool,
    /// Print what was submitted as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `vfxgraph status`: the arguments.
#[derive(Args)]
pub struct StatusArgs {
    #[command(flatten)]
    pub graph: GraphArgs,
    /// The shared cache folder (default: .vfxgraph/ beside the graph file).
    #[arg(long, value_name = "DIR")]
    pub cache: Option<PathBuf>,
    /// The submission whose `--frames` and `--set` to use where the command line gives none:
    /// a token, or `none` for the graph's own (default: the graph's latest submission to the
    /// cache).
    #[arg(long, value_name = "TOKEN")]
    pub submission: Option<String>,
    /// Print the status as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The cache folder given, or the graph's default one.
fn cache_or_default(cache: &Option<PathBuf>, graph: &Path) -> PathBuf {
    cache.clone().unwrap_or_else(|| default_cache_dir(graph))
}

/// Runs exactly the named instances on inputs from the cache.
pub fn exec_command(a: ExecArgs, registry: &Registry, quiet: bool) -> Result<u8, String> {
    let cache = cache_or_default(&a.cache, &a.graph);
    if let Some(t) = &a.token {
        // Not a usage error: the task ran where its cache is not the submission's (exit 1,
        // as a failed task; the farm's scheduler cancels the rest).
        if let Err(e) = super::check_token(&cache, t) {
            eprintln!("error: {e}");
            return Ok(1);
        }
    }
    let mut ga = GraphArgs::plain(a.graph.clone(), a.set.clone(), a.range.clone());
    ga.ocio = a.ocio.clone();
    let g = match load_graph(&ga, registry) {
        Ok(g) => g,
        Err(code) => return Ok(code),
    };
    let frames = match &a.frames {
        Some(f) => Some(
            FrameSet::parse(f)
                .map_err(|e| format!("--frames {f}: {e}"))?
                .frames()
                .to_vec(),
        ),
        None => None,
    };
    let only = a
        .nodes
        .iter()
        .map(|n| Target {
            node: n.clone(),
            frames: frames.clone(),
        })
        .collect();
    let opts = RunOptions {
        jobs: a.jobs,
        cache_dir: Some(cache.clone()),
        force: vec![],
        cancel: Some(crate::interrupt::install()),
        only: Some(only),
    };
    let bars = crate::progress::Bars::new(&g, quiet || a.json);
    let rep =
        exec::run(&g, registry, &opts, &bars).map_err(|e| format!("{}: {e}", a.graph.display()))?;
    bars.finish();
    if let Some(t) = &a.token {
        super::touch_token(&cache, t);
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rep).map_err(|e| e.to_string())?
        );
    } else {
        crate::report::print_failures(&rep);
        if !quiet {
            crate::report::print_table(&rep);
        }
    }
    Ok(if rep.failed() { EXIT_FAILED } else { 0 })
}

/// What every task shares, with absolute paths (tasks run on other hosts and folders).
fn task_context(a: &SubmitArgs, cache: &std::path::Path) -> Result<TaskContext, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find vfxgraph itself: {e}"))?;
    Ok(TaskContext {
        exe,
        graph: absolute(&a.graph.graph)?,
        cache: absolute(cache)?,
        set: a.graph.set.clone(),
        range: a.graph.frames.clone(),
        ocio: a.graph.ocio_config(),
        graph_name: a
            .graph
            .graph
            .file_stem()
            .map_or("graph".into(), |s| s.to_string_lossy().into_owned()),
        token: super::new_token(),
        task_cpus: a.task_cpus,
    })
}

/// How long a submit waits for another one to the same cache before giving up.
const LOCK_WAIT: Duration = Duration::from_secs(300);

/// One submit at a time per cache (`CACHE/farm/.submit.lease`): what the queue holds is read
/// and added to at once, so two submits in a row never both submit the same instances. A lease
/// whose holder died is broken.
fn submit_lock(cache: &Path) -> Result<Lease, String> {
    let path = cache.join("farm").join(".submit.lease");
    let start = Instant::now();
    let mut told = false;
    loop {
        match lease::try_take(&path) {
            Ok(Some(l)) => return Ok(l),
            Ok(None) => {}
            Err(e) => return Err(format!("cannot create {}: {e}", path.display())),
        }
        if lease::holder(&path) == Holder::Stale {
            lease::break_stale(&path);
            continue;
        }
        if start.elapsed() > LOCK_WAIT {
            return Err(format!(
                "another submit to this cache has held {} for {} s; nothing submitted (remove \
                 the file if no submit is running)",
                path.display(),
                LOCK_WAIT.as_secs()
            ));
        }
        if !told {
            eprintln!(
                "waiting for another submit to this cache ({})",
                path.display()
            );
            told = true;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The recipes of the graph's nodes, by node id.
fn recipes_by_id(g: &Graph) -> BTreeMap<String, String> {
    g.nodes
        .iter()
        .map(|n| n.id.clone())
        .zip(super::recipes(g))
        .collect()
}

/// The instances queued tasks of earlier Slurm submissions to `cache` compute. A dry run
/// without `squeue` (a host that only prints the script) sees an empty queue.
fn slurm_in_flight(
    cache: &Path,
    recipes: &BTreeMap<String, String>,
    dry_run: bool,
) -> Result<InFlight, String> {
    let queue = match super::slurm::queue() {
        Ok(q) => q,
        Err(e) if dry_run => {
            eprintln!(
                "warning: the dry run leaves in the instances queued tasks would compute: {e}"
            );
            vec![]
        }
        Err(e) => {
            return Err(format!(
                "cannot read Slurm's queue ({e}): it tells which instances earlier submissions \
                 still compute; nothing submitted"
            ))
        }
    };
    Ok(record::in_flight(cache, recipes, &queue))
}

/// Compiles the uncached instances into farm jobs and submits them (or prints them), leaving
/// out those queued tasks of earlier Slurm submissions compute, and records the submission.
pub fn submit_command(a: SubmitArgs, registry: &Registry) -> Result<u8, String> {
    let g = match load_graph(&a.graph, registry) {
        Ok(g) => g,
        Err(code) => return Ok(code),
    };
    let cache = cache_or_default(&a.cache, &a.graph.graph);
    if a.farm == Farm::Slurm && !a.dry_run {
        find_program(
            "sbatch",
            "install Slurm's client (apt-get install slurm-client)",
        )?;
    }
    if !a.dry_run {
        check_cache_writable(&cache)?;
    }
    let ctx = task_context(&a, &cache)?;
    let _lock = if a.dry_run {
        None
    } else {
        Some(submit_lock(&ctx.cache)?)
    };
    let opts = RunOptions {
        cache_dir: Some(cache.clone()),
        ..Default::default()
    };
    let plan = exec::plan(&g, &opts).map_err(|e| e.to_string())?;
    let recipes = recipes_by_id(&g);
    let queued = match a.farm {
        Farm::Slurm => slurm_in_flight(&ctx.cache, &recipes, a.dry_run)?,
        // An OpenJD job cannot wait for Slurm tasks, and OpenJD has no queue to read.
        Farm::Openjd => InFlight::default(),
    };
    let mut farm = FarmPlan::new(&g, &plan, a.chunk as usize, &queued);
    if a.fuse {
        farm = super::fuse::fuse(farm);
    }
    let dir = ctx
        .cache
        .join("farm")
        .join(format!("{}-{}", ctx.graph_name, ctx.token));
    if !a.dry_run && !farm.jobs.is_empty() {
        super::write_token(&ctx.cache, &ctx.token)?;
    }
    let rec = |ids: &[String], deps: &[String]| {
        let opts = record::Options {
            farm: a.farm.name(),
            chunk: a.chunk as usize,
            fuse: a.fuse,
        };
        Submission::new(&ctx, opts, &farm, recipes.clone(), &dir, ids, deps)
    };
    match a.farm {
        Farm::Slurm => submit_slurm(&ctx, &farm, &queued, &dir, &rec, a.dry_run, a.json),
        Farm::Openjd => write_openjd(&ctx, &farm, &dir, &rec, a.chunk as usize, a.dry_run, a.json),
    }
}

/// What a submission left to queued tasks of earlier ones: instances, submissions (tokens)
/// and Slurm job ids.
fn left_to_queued(farm: &FarmPlan, queued: &InFlight) -> serde_json::Value {
    let jobs: BTreeSet<&str> = farm
        .skipped
        .iter()
        .map(|s| InFlight::job_of(&s.task))
        .collect();
    let tokens: BTreeSet<&String> = jobs.iter().filter_map(|j| queued.tokens.get(*j)).collect();
    serde_json::json!({
        "instances": farm.skipped.len(),
        "submissions": tokens,
        "jobs": jobs,
    })
}

/// `left_to_queued` for a person: `N instance(s) that queued tasks of submission T (Slurm
/// jobs 4, 5) compute`.
fn left_to_queued_text(v: &serde_json::Value) -> String {
    let list = |k: &str| {
        v[k].as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|x| x.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default()
    };
    format!(
        "{} instance(s) that queued tasks of submission {} (Slurm jobs {}) compute",
        v["instances"],
        list("submissions"),
        list("jobs")
    )
}

type Record<'a> = dyn Fn(&[String], &[String]) -> Submission + 'a;

fn submit_slurm(
    ctx: &TaskContext,
    farm: &FarmPlan,
    queued: &InFlight,
    dir: &std::path::Path,
    rec: &Record,
    dry_run: bool,
    json: bool,
) -> Result<u8, String> {
    if dry_run {
        // The record's job ids are filled in by the script as it submits.
        let ids: Vec<String> = (0..farm.jobs.len())
            .map(|i| format!("@{}@", super::slurm::job_var(i)))
            .collect();
        let deps: Vec<String> = farm
            .jobs
            .iter()
            .map(|j| super::slurm::dependency(j, &ids))
            .collect();
        let record = rec(&ids, &deps).to_json();
        print!("{}", super::slurm::dry_run(ctx, farm, dir, &record));
        return Ok(0);
    }
    let done = if farm.jobs.is_empty() {
        vec![]
    } else {
        super::slurm::submit(ctx, farm, dir)?
    };
    let written = if done.is_empty() {
        None
    } else {
        let ids: Vec<String> = done.iter().map(|s| s.job_id.clone()).collect();
        let deps: Vec<String> = done.iter().map(|s| s.dependency.clone()).collect();
        // The jobs are submitted: a record that cannot be written is reported after them.
        Some(rec(&ids, &deps).write())
    };
    let record_path = written.as_ref().and_then(|w| w.as_ref().ok());
    let left = left_to_queued(farm, queued);
    if json {
        // No folder is made when nothing is submitted: none is named.
        let dir = (!done.is_empty()).then_some(dir);
        let v = serde_json::json!({
            "farm": "slurm", "dir": dir, "record": record_path, "jobs": done,
            "left_to_queued": left,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?
        );
    } else if done.is_empty() {
        if farm.skipped.is_empty() {
            println!("nothing to submit: every instance is cached");
        } else {
            println!(
                "nothing to submit: every instance is cached, or one of {}",
                left_to_queued_text(&left)
            );
        }
    } else {
        for s in &done {
            let dep = if s.dependency.is_empty() {
                "-"
            } else {
                &s.dependency
            };
            println!("{}  {}  {} task(s)  after {dep}", s.job_id, s.name, s.tasks);
        }
        println!(
            "submitted {} job(s), {} task(s); logs in {}",
            done.len(),
            farm.task_count(),
            dir.join("logs").display()
        );
        if !farm.skipped.is_empty() {
            println!(
                "left out {}; the jobs that read them wait for those tasks",
                left_to_queued_text(&left)
            );
        }
    }
    match written {
        Some(Err(e)) => Err(format!(
            "the {} job(s) above are submitted, but {e}: `status` and the next submit will not \
             know them",
            done.len()
        )),
        _ => Ok(0),
    }
}

fn write_openjd(
    ctx: &TaskContext,
    farm: &FarmPlan,
    dir: &std::path::Path,
    rec: &Record,
    chunk: usize,
    dry_run: bool,
    json: bool,
) -> Result<u8, String> {
    if farm.jobs.is_empty() {
        if json {
            println!("{{\"farm\": \"openjd\", \"template\": null, \"steps\": []}}");
        } else {
            println!("nothing to submit: every instance is cached");
        }
        return Ok(0);
    }
    let t = super::openjd::template(ctx, farm, chunk);
    let text = serde_json::to_string_pretty(&t).map_err(|e| e.to_string())?;
    if dry_run {
        println!("{text}");
        return Ok(0);
    }
    let path = dir.join("job.template.json");
    vfxgraph_engine::fsutil::atomic_write(&path, text.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    let record_path = rec(&[], &[]).write()?;
    let steps: Vec<String> = farm.jobs.iter().map(super::openjd::step_name).collect();
    // The steps no other step depends on: running each with its dependencies runs the whole
    // job (a step shared by two finds its work cached the second time).
    let sinks: Vec<String> = (0..farm.jobs.len())
        .filter(|&i| {
            !farm
                .jobs
                .iter()
                .any(|j| j.deps.iter().any(|(p, _)| *p == i))
        })
        .map(|i| steps[i].clone())
        .collect();
    if json {
        let v = serde_json::json!({
            "farm": "openjd", "template": path, "steps": steps, "sinks": sinks,
            "parameters": super::openjd::parameters(ctx), "record": record_path,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?
        );
    } else {
        println!("wrote {} ({} step(s))", path.display(), steps.len());
        println!("check it:   openjd check {}", path.display());
        let p = super::openjd::parameters(ctx);
        let params: Vec<String> = ["Vfxgraph", "Graph", "Cache"]
            .iter()
            .map(|k| {
                format!(
                    "-p {k}={}",
                    super::sh_quote(p[k].as_str().unwrap_or_default())
                )
            })
            .collect();
        let template = super::sh_quote(&path.display().to_string());
        match sinks.as_slice() {
            [one] => println!(
                "run it here: openjd run {template} --step {} --run-dependencies {}",
                super::sh_quote(one),
                params.join(" ")
            ),
            many => println!(
                "run it here: for step in {}; do openjd run {template} --step \"$step\" \
                 --run-dependencies {} || break; done",
                many.iter()
                    .map(|s| super::sh_quote(s))
                    .collect::<Vec<_>>()
                    .join(" "),
                params.join(" ")
            ),
        }
    }
    Ok(0)
}

/// The submission whose selection `status` uses: the one `--submission` names (`none`: no
/// submission), else the graph's latest in the cache.
fn status_submission(
    a: &StatusArgs,
    cache: &Path,
) -> Result<Option<(PathBuf, Submission)>, String> {
    match a.submission.as_deref() {
        Some("none") => Ok(None),
        Some(token) => record::all(cache)
            .into_iter()
            .find(|(_, s)| s.token == token)
            .map(Some)
            .ok_or_else(|| {
                format!(
                    "no submission {token} in {} (its record, farm/<graph>-{token}/{})",
                    cache.display(),
                    record::FILE
                )
            }),
        None => Ok(record::latest(cache, &absolute(&a.graph.graph)?)),
    }
}

/// Prints per node: cached / running / missing, for the selection (`--frames`, `--set`) of
/// the graph's latest submission unless the command line gives its own.
pub fn status_command(a: StatusArgs, registry: &Registry) -> Result<u8, String> {
    let cache = cache_or_default(&a.cache, &a.graph.graph);
    if !cache.is_dir() {
        return Err(format!("no cache at {}", cache.display()));
    }
    let sub = status_submission(&a, &cache)?;
    let mut ga = GraphArgs::plain(
        a.graph.graph.clone(),
        a.graph.set.clone(),
        a.graph.frames.clone(),
    );
    ga.ocio = a.graph.ocio.clone();
    ga.ocio_from_env = true;
    if let Some((_, s)) = &sub {
        if ga.frames.is_none() {
            ga.frames = s.frames.clone();
        }
        if ga.set.is_empty() {
            ga.set = s.set.clone();
        }
    }
    let g = match load_graph(&ga, registry) {
        Ok(g) => g,
        Err(code) => {
            if let Some((path, s)) = &sub {
                eprintln!(
                    "note: the selection ({}) is submission {}'s ({}); `--submission none` \
                     uses the graph's own",
                    s.flags(),
                    s.token,
                    path.display()
                );
            }
            return Ok(code);
        }
    };
    let opts = RunOptions {
        cache_dir: Some(cache),
        ..Default::default()
    };
    let plan = exec::plan(&g, &opts).map_err(|e| e.to_string())?;
    let name = a
        .graph
        .graph
        .file_stem()
        .map_or("graph".into(), |s| s.to_string_lossy().into_owned());
    let queue = super::slurm::queued(&name);
    let lines = super::status::collect(&g, &plan, queue.as_ref());
    // Where each part of the selection comes from.
    let from = |given: bool| match (given, &sub) {
        (true, _) => "command line",
        (false, Some(_)) => "submission",
        (false, None) => "graph",
    };
    if a.json {
        let submission = sub.as_ref().map(|(path, s)| {
            serde_json::json!({
                "token": s.token, "record": path, "farm": s.farm, "submitted": s.submitted,
                "frames": s.frames, "set": s.set, "chunk": s.chunk, "fuse": s.fuse,
                "jobs": s.jobs.iter().filter_map(|j| j.job_id.clone()).collect::<Vec<_>>(),
            })
        });
        let v = serde_json::json!({
            "nodes": lines, "squeue": queue.is_some(), "submission": submission,
            "selection": {
                "frames": ga.frames, "set": ga.set,
                "frames_from": from(a.graph.frames.is_some()),
                "set_from": from(!a.graph.set.is_empty()),
            },
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?
        );
    } else {
        if let Some((path, s)) = &sub {
            let age = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64())
                - s.submitted;
            let given: Vec<&str> = [
                (a.graph.frames.is_some(), "--frames"),
                (!a.graph.set.is_empty(), "--set"),
            ]
            .iter()
            .filter(|(g, _)| *g)
            .map(|(_, f)| *f)
            .collect();
            println!(
                "submission {} ({}, {} {}, {} ago): {}{}",
                s.token,
                s.farm,
                s.jobs.len(),
                if s.farm == "openjd" {
                    "step(s)"
                } else {
                    "job(s)"
                },
                human_age(age),
                s.flags(),
                if given.is_empty() {
                    String::new()
                } else {
                    format!("; {} from the command line", given.join(" and "))
                }
            );
            println!("record: {}", path.display());
        }
        print!("{}", super::status::render(&lines));
    }
    Ok(0)
}

/// A duration for a person: `40 s`, `12 min`, `3 h`, `2 d`.
fn human_age(secs: f64) -> String {
    let s = secs.max(0.0) as u64;
    match s {
        0..120 => format!("{s} s"),
        120..7200 => format!("{} min", s / 60),
        7200..172_800 => format!("{} h", s / 3600),
        _ => format!("{} d", s / 86_400),
    }
}
