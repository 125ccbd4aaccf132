//! The farm's commands: `exec` (one task), `submit` and `status`.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use vfxgraph_engine::exec::{self, default_cache_dir, RunOptions, Target};
use vfxgraph_engine::{FrameSet, Registry};

use super::{absolute, check_cache_writable, find_program, FarmPlan, TaskContext};
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
    /// Print the jobs (Slurm) or the template (OpenJD) without submitting or writing.
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
    let ga = GraphArgs {
        graph: a.graph.clone(),
        set: a.set.clone(),
        frames: a.range.clone(),
    };
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
        graph_name: a
            .graph
            .graph
            .file_stem()
            .map_or("graph".into(), |s| s.to_string_lossy().into_owned()),
        token: super::new_token(),
        task_cpus: a.task_cpus,
    })
}

/// Compiles the uncached instances into farm jobs and submits them (or prints them).
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
    let opts = RunOptions {
        cache_dir: Some(cache.clone()),
        ..Default::default()
    };
    let plan = exec::plan(&g, &opts).map_err(|e| e.to_string())?;
    let mut farm = FarmPlan::new(&g, &plan, a.chunk as usize);
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
    match a.farm {
        Farm::Slurm => submit_slurm(&ctx, &farm, &dir, a.dry_run, a.json),
        Farm::Openjd => write_openjd(&ctx, &farm, &dir, a.chunk as usize, a.dry_run, a.json),
    }
}

fn submit_slurm(
    ctx: &TaskContext,
    farm: &FarmPlan,
    dir: &std::path::Path,
    dry_run: bool,
    json: bool,
) -> Result<u8, String> {
    if dry_run {
        print!("{}", super::slurm::dry_run(ctx, farm, dir));
        return Ok(0);
    }
    let done = if farm.jobs.is_empty() {
        vec![]
    } else {
        super::slurm::submit(ctx, farm, dir)?
    };
    if json {
        // No folder is made when nothing is submitted: none is named.
        let dir = (!done.is_empty()).then_some(dir);
        let v = serde_json::json!({"farm": "slurm", "dir": dir, "jobs": done});
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?
        );
    } else if done.is_empty() {
        println!("nothing to submit: every instance is cached");
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
    }
    Ok(0)
}

fn write_openjd(
    ctx: &TaskContext,
    farm: &FarmPlan,
    dir: &std::path::Path,
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
            "parameters": super::openjd::parameters(ctx),
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

/// Prints per node: cached / running / missing.
pub fn status_command(a: StatusArgs, registry: &Registry) -> Result<u8, String> {
    let g = match load_graph(&a.graph, registry) {
        Ok(g) => g,
        Err(code) => return Ok(code),
    };
    let cache = cache_or_default(&a.cache, &a.graph.graph);
    if !cache.is_dir() {
        return Err(format!("no cache at {}", cache.display()));
    }
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
    if a.json {
        let v = serde_json::json!({"nodes": lines, "squeue": queue.is_some()});
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| e.to_string())?
        );
    } else {
        print!("{}", super::status::render(&lines));
    }
    Ok(0)
}
