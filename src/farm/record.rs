//! A submission's record, `CACHE/farm/<graph>-<token>/submission.json` beside its scripts and
//! logs, written atomically once its jobs are submitted: what it selected (the graph,
//! `--frames`, `--set`, chunking, fusing), the farm, the jobs it created (Slurm ids, batch
//! scripts, chunks) and its token, with what each node computes ([`super::recipes`]).
//!
//! - `status GRAPH` shows the latest submission of the graph with its selection, so the
//!   wrangler need not repeat `--frames` and `--set` (explicit flags still win).
//! - `submit` reads the records of the submissions whose tasks are still in Slurm's queue and
//!   leaves out the instances those tasks compute ([`in_flight`]).

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::slurm::QueuedTask;
use super::{Chunk, FarmPlan, InFlight, TaskContext};

/// The record's file name in a submission's folder.
pub const FILE: &str = "submission.json";

/// The record format's version.
const VERSION: u32 = 1;

/// What a submission selected and created.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Submission {
    /// The record format's version.
    pub version: u32,
    /// The submission's token (`CACHE/farm-tokens/<token>`).
    pub token: String,
    /// The graph file (absolute).
    pub graph: PathBuf,
    /// The graph's name in job names.
    pub graph_name: String,
    /// `slurm` or `openjd`.
    pub farm: String,
    /// `--frames`: the graph's frame range override (`None`: the graph's own).
    pub frames: Option<String>,
    /// `--set` overrides.
    pub set: Vec<String>,
    /// `--chunk`: frames per task.
    pub chunk: usize,
    /// `--fuse`.
    pub fuse: bool,
    /// `--task-cpus`.
    pub task_cpus: Option<u32>,
    /// When it was submitted: seconds since the Unix epoch.
    pub submitted: f64,
    /// Its folder: batch scripts, logs, the OpenJD template, this record.
    pub dir: PathBuf,
    /// The OpenJD job template (`None` on Slurm).
    pub template: Option<PathBuf>,
    /// What each node computes ([`super::recipes`]), by node id.
    pub recipes: BTreeMap<String, String>,
    /// Its jobs, in submission order.
    pub jobs: Vec<JobRecord>,
    /// Instances it left to queued tasks of earlier submissions (`node` or `node@frame` →
    /// task).
    #[serde(default)]
    pub left_to_queued: BTreeMap<String, String>,
}

/// One job of a submission.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobRecord {
    /// The job name (`graph/node/frames`).
    pub name: String,
    /// The nodes each task runs.
    pub nodes: Vec<String>,
    /// The Slurm job id (`None`: OpenJD).
    pub job_id: Option<String>,
    /// The batch script (Slurm).
    pub script: Option<PathBuf>,
    /// An array of chunks (per frame), or one task.
    pub per_frame: bool,
    /// Its chunks: array index and frames.
    pub chunks: Vec<Chunk>,
    /// Its `--dependency` (Slurm).
    pub dependency: String,
}

/// What the command line selected, besides the task context.
#[derive(Clone, Copy, Debug)]
pub struct Options<'a> {
    /// `slurm` or `openjd`.
    pub farm: &'a str,
    /// `--chunk`.
    pub chunk: usize,
    /// `--fuse`.
    pub fuse: bool,
}

impl Submission {
    /// The record of `plan` submitted in `dir`, its jobs' Slurm ids `ids` (empty: OpenJD)
    /// and their dependencies `deps`.
    pub fn new(
        ctx: &TaskContext,
        opts: Options,
        plan: &FarmPlan,
        recipes: BTreeMap<String, String>,
        dir: &Path,
        ids: &[String],
        deps: &[String],
    ) -> Submission {
        let jobs = plan
            .jobs
            .iter()
            .enumerate()
            .map(|(i, j)| JobRecord {
                name: super::slurm::job_name(ctx, j),
                nodes: j.nodes.clone(),
                job_id: ids.get(i).cloned(),
                script: (!ids.is_empty()).then(|| dir.join(format!("{}.sh", j.node))),
                per_frame: j.per_frame,
                chunks: j.chunks.clone(),
                dependency: deps.get(i).cloned().unwrap_or_default(),
            })
            .collect();
        let left_to_queued = plan
            .skipped
            .iter()
            .map(|s| {
                let at = s.frame.map_or(String::new(), |f| format!("@{f}"));
                (format!("{}{at}", s.node), s.task.clone())
            })
            .collect();
        Submission {
            version: VERSION,
            token: ctx.token.clone(),
            graph: ctx.graph.clone(),
            graph_name: ctx.graph_name.clone(),
            farm: opts.farm.to_string(),
            frames: ctx.range.clone(),
            set: ctx.set.clone(),
            chunk: opts.chunk,
            fuse: opts.fuse,
            task_cpus: ctx.task_cpus,
            submitted: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64()),
            dir: dir.to_path_buf(),
            template: (opts.farm == "openjd").then(|| dir.join("job.template.json")),
            recipes,
            jobs,
            left_to_queued,
        }
    }

    /// The record as written (pretty JSON).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a record serializes")
    }

    /// Writes the record into its folder, atomically.
    pub fn write(&self) -> Result<PathBuf, String> {
        let path = self.dir.join(FILE);
        vfxgraph_engine::fsutil::atomic_write(&path, self.to_json().as_bytes())
            .map_err(|e| format!("cannot write the submission record {}: {e}", path.display()))?;
        Ok(path)
    }

    /// The selection as command-line flags (`--frames R --set a.b=1 …`), for a person.
    pub fn flags(&self) -> String {
        let mut out: Vec<String> = Vec::new();
        if let Some(f) = &self.frames {
            out.push(format!("--frames {}", super::sh_quote(f)));
        }
        for s in &self.set {
            out.push(format!("--set {}", super::sh_quote(s)));
        }
        if out.is_empty() {
            "the graph's own frames and params".into()
        } else {
            out.join(" ")
        }
    }
}

/// Every submission record in `cache` (`CACHE/farm/*/submission.json`) with its path. A record
/// that cannot be read is reported on stderr (naming the file) and left out.
pub fn all(cache: &Path) -> Vec<(PathBuf, Submission)> {
    let Ok(dirs) = std::fs::read_dir(cache.join("farm")) else {
        return vec![];
    };
    let mut out = Vec::new();
    for d in dirs.flatten() {
        if d.file_name().to_string_lossy().starts_with('.') {
            continue;
        }
        let path = d.path().join(FILE);
        match read(&path) {
            Ok(Some(s)) => out.push((path, s)),
            Ok(None) => {}
            Err(e) => eprintln!("warning: {e}; ignored"),
        }
    }
    out
}

/// The record at `path`: `None` when there is none (a folder of a submission that wrote none).
pub fn read(path: &Path) -> Result<Option<Submission>, String> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            return Err(format!(
                "cannot read the submission record {}: {e}",
                path.display()
            ))
        }
    };
    let s: Submission = serde_json::from_str(&text)
        .map_err(|e| format!("{} is not a submission record: {e}", path.display()))?;
    if s.version > VERSION {
        return Err(format!(
            "{}: a submission record of version {} (this vfxgraph reads {VERSION})",
            path.display(),
            s.version
        ));
    }
    Ok(Some(s))
}

/// `p` with its links resolved, when it exists.
fn resolve(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// The same file, as far as this host can tell.
fn same_file(a: &Path, b: &Path) -> bool {
    a == b || resolve(a) == resolve(b)
}

/// The latest submission of `graph` (absolute) in `cache`, with its record's path.
pub fn latest(cache: &Path, graph: &Path) -> Option<(PathBuf, Submission)> {
    all(cache)
        .into_iter()
        .filter(|(_, s)| same_file(&s.graph, graph))
        .max_by(|(_, a), (_, b)| a.submitted.total_cmp(&b.submitted))
}

/// The instances that tasks still in the queue (`queue`) will compute, from the Slurm
/// records in `cache`: each such task's nodes whose recipe is the same in this submission
/// (`recipes`, by node id), at its chunk's frames. A task counts only when its job id, array
/// index and batch script are those of a record (a job id Slurm reuses after a restart is
/// another job).
pub fn in_flight(
    cache: &Path,
    recipes: &BTreeMap<String, String>,
    queue: &[QueuedTask],
) -> InFlight {
    let mut out = InFlight::default();
    if queue.is_empty() {
        return out;
    }
    // The queued tasks by batch script (resolved once each).
    let mut by_script: HashMap<PathBuf, Vec<&QueuedTask>> = HashMap::new();
    for t in queue {
        by_script.entry(resolve(&t.script)).or_default().push(t);
    }
    for (_, s) in all(cache).into_iter().filter(|(_, s)| s.farm == "slurm") {
        for job in &s.jobs {
            let (Some(id), Some(script)) = (&job.job_id, &job.script) else {
                continue;
            };
            let Some(tasks) = by_script.get(&resolve(script)) else {
                continue;
            };
            let nodes: Vec<&String> = job
                .nodes
                .iter()
                .filter(|n| {
                    s.recipes
                        .get(*n)
                        .is_some_and(|r| recipes.get(*n) == Some(r))
                })
                .collect();
            let mut names: BTreeSet<String> = BTreeSet::new();
            for task in tasks.iter().filter(|t| &t.job_id == id) {
                let chunk = if job.per_frame {
                    job.chunks.iter().find(|c| Some(c.index) == task.index)
                } else {
                    job.chunks.first().filter(|_| task.index.is_none())
                };
                let Some(chunk) = chunk else { continue };
                let frames: Vec<Option<i64>> = if job.per_frame {
                    chunk.frames.iter().map(|&f| Some(f)).collect()
                } else {
                    vec![None]
                };
                for node in &nodes {
                    for &f in &frames {
                        out.tasks
                            .entry(((*node).clone(), f))
                            .or_insert_with(|| task.name());
                    }
                }
                names.insert(task.name());
            }
            if names.is_empty() {
                continue;
            }
            out.tokens.insert(id.clone(), s.token.clone());
            if job.per_frame && names.len() == job.chunks.len() {
                out.whole.insert(id.clone(), names);
            }
        }
    }
    out
}
