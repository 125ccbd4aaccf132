//! Render farms: a graph's uncached instances compiled into farm jobs (`vfxgraph submit`),
//! and a graph's progress on a shared cache (`vfxgraph status`).
//!
//! Every farm task is one `vfxgraph exec` of one node (or, fused, of a per-frame chain of
//! nodes) over one chunk of frames, reading its inputs from the shared cache and writing its
//! results there; the farm's dependencies follow the graph's edges. The engine knows nothing
//! of farms: this module only reads its plan.
//!
//! - [`FarmPlan`] (here): jobs, chunks and dependencies, farm-neutral.
//! - [`fuse`]: per-frame chains merged into one task per chunk (`submit --fuse`).
//! - [`slurm`]: `sbatch` scripts and submission.
//! - [`openjd`]: an Open Job Description job template.
//! - [`status`]: per-node progress from the cache (and `squeue`).
//! - [`record`]: what a submission selected and created (`submission.json` beside its
//!   scripts), which `status` and the next `submit` read.

pub mod commands;
pub mod fuse;
pub mod openjd;
pub mod record;
pub mod slurm;
pub mod status;

use std::collections::{BTreeSet, HashMap, HashSet};
use std::path::{Path, PathBuf};

use vfxgraph_engine::exec::{PlanReport, PlanStatus};
use vfxgraph_engine::{FrameSet, Graph, Threads};

/// How a job waits for one of its producers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Wait {
    /// Chunk k waits for the producer's chunk k (both per-frame, same chunks).
    PerChunk,
    /// The job waits for the whole producer job.
    Whole,
}

/// One chunk of a job: an array index (the chunk's position in the graph's frames) and the
/// frames of it that must run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Chunk {
    /// Position of the chunk among the graph's chunks.
    pub index: usize,
    /// Uncached frames in it (empty for a node that runs once).
    pub frames: Vec<i64>,
}

/// One farm job: the uncached instances of one node, or of a fused chain of per-frame nodes.
#[derive(Clone, Debug)]
pub struct Job {
    /// The job's name in job names, scripts and logs: its node id, or its nodes' ids joined
    /// by `+` (node ids never hold a `+`).
    pub node: String,
    /// The nodes its tasks run (`exec --node` each), in graph order: one unless fused.
    pub nodes: Vec<String>,
    /// True for a per-frame node (an array of chunks), false for a node that runs once.
    pub per_frame: bool,
    /// The chunks to run (one, with no frames, for a once node).
    pub chunks: Vec<Chunk>,
    /// Producers (indices into [`FarmPlan::jobs`]) and how to wait for each.
    pub deps: Vec<(usize, Wait)>,
    /// Tasks of earlier submissions, still in the farm's queue, that compute instances this
    /// job reads (Slurm `afterok`: a job id, or `job_index` for one array task), sorted.
    pub after: Vec<String>,
    /// The node type's resource hint.
    pub threads: Threads,
    /// The node type's memory hint for this node's params, MiB (`None`: no hint).
    pub memory_mib: Option<u64>,
}

impl Job {
    /// The frames of all chunks, compactly (`1-4,9`), or `once`.
    pub fn frames_label(&self) -> String {
        if self.per_frame {
            let all: Vec<i64> = self.chunks.iter().flat_map(|c| c.frames.clone()).collect();
            FrameSet::from_frames(all).to_string()
        } else {
            "once".into()
        }
    }
}

/// What a farm task needs besides its node and frames: the same for every task.
#[derive(Clone, Debug)]
pub struct TaskContext {
    /// The vfxgraph binary the tasks run (absolute).
    pub exe: PathBuf,
    /// The graph file (absolute).
    pub graph: PathBuf,
    /// The shared cache (absolute).
    pub cache: PathBuf,
    /// `--set` overrides, passed to every task.
    pub set: Vec<String>,
    /// The graph's frame range override (`--frames` of submit), passed as `exec --range`.
    pub range: Option<String>,
    /// The OpenColorIO config of the submit (`--ocio` or $OCIO), passed as `exec --ocio`.
    pub ocio: Option<PathBuf>,
    /// The graph's name in job names (its file stem).
    pub graph_name: String,
    /// The submission's token (see [`write_token`]), passed to every task as `exec --token`.
    pub token: String,
    /// CPUs a task of a per-frame node that uses every core asks for (`submit --task-cpus`),
    /// so several such tasks share a host; `None`: the whole host (Slurm `--exclusive`).
    pub task_cpus: Option<u32>,
}

impl TaskContext {
    /// The `vfxgraph exec` arguments of a task of `nodes`, with `frames` (a frame list, or
    /// `None` for a node that runs once) and `jobs` worker threads (`None`: exec's default).
    pub fn exec_args(
        &self,
        nodes: &[String],
        frames: Option<&str>,
        jobs: Option<&str>,
    ) -> Vec<String> {
        let mut a = vec!["exec".to_string(), self.graph.display().to_string()];
        for n in nodes {
            a.extend(["--node".into(), n.clone()]);
        }
        a.extend(["--cache".into(), self.cache.display().to_string()]);
        if let Some(f) = frames {
            a.extend(["--frames".into(), f.into()]);
        }
        if let Some(r) = &self.range {
            a.extend(["--range".into(), r.clone()]);
        }
        for s in &self.set {
            a.extend(["--set".into(), s.clone()]);
        }
        if let Some(o) = &self.ocio {
            a.extend(["--ocio".into(), o.display().to_string()]);
        }
        if let Some(j) = jobs {
            a.extend(["--jobs".into(), j.into()]);
        }
        a.extend(["--token".into(), self.token.clone()]);
        a
    }
}

/// The instances that tasks of earlier submissions, still in the farm's queue, will compute:
/// (node id, frame) → the task (a Slurm job id, or `job_index` for an array task).
#[derive(Clone, Debug, Default)]
pub struct InFlight {
    /// The task of each instance.
    pub tasks: HashMap<(String, Option<i64>), String>,
    /// The submission (token) of each Slurm job id in `tasks`.
    pub tokens: HashMap<String, String>,
    /// The Slurm arrays all of whose tasks are in the queue: job id → its tasks.
    pub whole: HashMap<String, BTreeSet<String>>,
}

impl InFlight {
    /// The Slurm job id of a task (`123` of `123_4`).
    pub fn job_of(task: &str) -> &str {
        task.split('_').next().unwrap_or(task)
    }

    /// `tasks` with every task of an array all of whose tasks are queued and in `tasks`
    /// replaced by the array's job id (`afterok:123` waits for the same tasks as
    /// `afterok:123_0,afterok:123_1,…`), sorted.
    pub fn compact(&self, mut tasks: BTreeSet<String>) -> Vec<String> {
        for (job, all) in &self.whole {
            if all.len() > 1 && all.is_subset(&tasks) {
                tasks.retain(|t| !all.contains(t));
                tasks.insert(job.clone());
            }
        }
        tasks.into_iter().collect()
    }
}

/// An instance a submission leaves to a queued task of an earlier one.
#[derive(Clone, Debug, PartialEq)]
pub struct Skipped {
    /// Node id.
    pub node: String,
    /// Frame (`None`: a node that runs once).
    pub frame: Option<i64>,
    /// The queued task that computes it.
    pub task: String,
}

/// The jobs of a submission, in graph (topological) order.
#[derive(Clone, Debug, Default)]
pub struct FarmPlan {
    /// Jobs; a job's producers come before it.
    pub jobs: Vec<Job>,
    /// Uncached instances left out because a queued task of an earlier submission computes
    /// them, in graph order.
    pub skipped: Vec<Skipped>,
}

impl FarmPlan {
    /// The jobs for every instance the plan does not find cached, frames cut into chunks of
    /// `chunk` consecutive frames of the graph's range, without the instances `queued` (tasks
    /// of earlier submissions still in the farm's queue) will compute: a job that reads one of
    /// those waits for its task ([`Job::after`]). A queued instance counts only while every
    /// instance it reads is cached or queued too (an earlier task whose producer failed is
    /// about to be cancelled: its instance is submitted again).
    pub fn new(graph: &Graph, plan: &PlanReport, chunk: usize, queued: &InFlight) -> FarmPlan {
        let chunk = chunk.max(1);
        let all = graph.frames.frames();
        let mut job_of: Vec<Option<usize>> = vec![None; graph.nodes.len()];
        let mut jobs: Vec<Job> = Vec::new();
        let mut skipped: Vec<Skipped> = Vec::new();
        // Per node: its uncached instances, and those of them a queued task computes.
        let mut uncached: Vec<HashSet<Option<i64>>> = vec![HashSet::new(); graph.nodes.len()];
        for l in plan.nodes.iter().filter(|l| l.status != PlanStatus::Cached) {
            if let Some(n) = graph.index_of(&l.id) {
                uncached[n].insert(l.frame);
            }
        }
        let mut in_queue: Vec<HashMap<Option<i64>, String>> =
            vec![HashMap::new(); graph.nodes.len()];
        for (n, node) in graph.nodes.iter().enumerate() {
            // Per input: whether all it reads at once (a producer that runs once, a whole
            // sequence) is cached or queued.
            let ready_whole: Vec<bool> = node
                .inputs
                .iter()
                .map(|e| {
                    uncached[e.from]
                        .iter()
                        .all(|f| in_queue[e.from].contains_key(f))
                })
                .collect();
            let mut todo: Vec<Option<i64>> = Vec::new();
            for l in plan
                .nodes
                .iter()
                .filter(|l| l.id == node.id && l.status != PlanStatus::Cached)
            {
                let task = queued.tasks.get(&(node.id.clone(), l.frame)).filter(|_| {
                    node.inputs.iter().zip(&ready_whole).all(|(e, &whole)| {
                        match one_frame(graph, e, l.frame) {
                            Some(f) => {
                                !uncached[e.from].contains(&f) || in_queue[e.from].contains_key(&f)
                            }
                            None => whole,
                        }
                    })
                });
                match task {
                    Some(t) => {
                        in_queue[n].insert(l.frame, t.clone());
                        skipped.push(Skipped {
                            node: node.id.clone(),
                            frame: l.frame,
                            task: t.clone(),
                        });
                    }
                    None => todo.push(l.frame),
                }
            }
            if todo.is_empty() {
                continue;
            }
            let chunks = if node.per_frame {
                chunks_of(all, &todo, chunk)
            } else {
                vec![Chunk {
                    index: 0,
                    frames: vec![],
                }]
            };
            let mut job = Job {
                node: node.id.clone(),
                nodes: vec![node.id.clone()],
                per_frame: node.per_frame,
                chunks,
                deps: Vec::new(),
                after: Vec::new(),
                threads: node.spec().threads,
                memory_mib: node.spec().memory.mib(&node.params),
            };
            job.deps = dependencies(graph, n, &job, &jobs, &job_of);
            // The queued tasks of earlier submissions that compute what this job reads.
            let mut after: BTreeSet<String> = BTreeSet::new();
            for e in &node.inputs {
                let q = &in_queue[e.from];
                if q.is_empty() {
                    continue;
                }
                if todo.iter().any(|&f| one_frame(graph, e, f).is_none()) {
                    after.extend(q.values().cloned());
                } else {
                    let frames = todo.iter().filter_map(|&f| one_frame(graph, e, f));
                    after.extend(frames.filter_map(|f| q.get(&f).cloned()));
                }
            }
            job.after = queued.compact(after);
            job_of[n] = Some(jobs.len());
            jobs.push(job);
        }
        FarmPlan { jobs, skipped }
    }

    /// Number of tasks over all jobs.
    pub fn task_count(&self) -> usize {
        self.jobs.iter().map(|j| j.chunks.len()).sum()
    }
}

/// The one instance of its producer that input `e` of an instance at `frame` reads (the
/// producer's frame, or `Some(None)` for a producer that runs once), or `None` when it reads
/// them all (a whole sequence, or a node that runs once reading a per-frame producer).
fn one_frame(
    graph: &Graph,
    e: &vfxgraph_engine::graph::Edge,
    frame: Option<i64>,
) -> Option<Option<i64>> {
    if !graph.nodes[e.from].per_frame {
        Some(None)
    } else if e.whole_sequence {
        None
    } else {
        frame.map(Some)
    }
}

/// What each node computes, as far as a farm task is concerned: a digest of the graph's
/// folder (relative paths resolve against it), the node's id, type, version and
/// output-affecting params, the graph's seed for a seeded node, its inputs and, recursively,
/// what its producers compute, and the graph's frames when it reads a whole sequence. Two
/// submissions whose recipes of a node match compute the same instances of it (what their
/// `--set` and `--frames` leave unchanged), in graph order.
pub fn recipes(graph: &Graph) -> Vec<String> {
    let dir = std::fs::canonicalize(&graph.dir).unwrap_or_else(|_| graph.dir.clone());
    let mut out: Vec<String> = Vec::with_capacity(graph.nodes.len());
    let mut buf = Vec::new();
    for node in &graph.nodes {
        let spec = node.spec();
        let mut h = blake3::Hasher::new();
        h.update(b"vfxgraph-recipe-v1\0");
        h.update(dir.as_os_str().as_encoded_bytes());
        for part in [node.id.as_bytes(), spec.name.as_bytes()] {
            h.update(&[0]);
            h.update(part);
        }
        h.update(&spec.version.to_le_bytes());
        h.update(&[u8::from(node.per_frame)]);
        for p in spec.params.iter().filter(|p| !p.cosmetic) {
            if let Some(v) = node.params.get(p.name) {
                buf.clear();
                vfxgraph_engine::param::canonical(v, &mut buf);
                h.update(p.name.as_bytes());
                h.update(&[0]);
                h.update(&buf);
            }
        }
        if spec.seeded {
            h.update(b"seed\0");
            h.update(&graph.seed.to_le_bytes());
        }
        for e in &node.inputs {
            h.update(b"in\0");
            for part in [
                e.port.as_bytes(),
                e.from_port.as_bytes(),
                out[e.from].as_bytes(),
            ] {
                h.update(part);
                h.update(&[0]);
            }
            if e.whole_sequence {
                h.update(b"frames\0");
                h.update(graph.frames.to_string().as_bytes());
            }
        }
        out.push(h.finalize().to_hex().to_string());
    }
    out
}

/// The chunks (of `size` consecutive frames of `all`) holding any of the frames `todo`.
fn chunks_of(all: &[i64], todo: &[Option<i64>], size: usize) -> Vec<Chunk> {
    all.chunks(size)
        .enumerate()
        .filter_map(|(index, frames)| {
            let run: Vec<i64> = frames
                .iter()
                .copied()
                .filter(|f| todo.contains(&Some(*f)))
                .collect();
            (!run.is_empty()).then_some(Chunk { index, frames: run })
        })
        .collect()
}

/// How job `job` (node `n`) waits for each producer that has a job: per chunk when both are
/// per-frame, the edge reads one element, and every chunk of `job` has its producer chunk;
/// else the whole producer.
fn dependencies(
    graph: &Graph,
    n: usize,
    job: &Job,
    jobs: &[Job],
    job_of: &[Option<usize>],
) -> Vec<(usize, Wait)> {
    let mut deps: Vec<(usize, Wait)> = Vec::new();
    for e in &graph.nodes[n].inputs {
        let Some(p) = job_of[e.from] else { continue };
        let producer = &jobs[p];
        let per_chunk = !e.whole_sequence
            && job.per_frame
            && producer.per_frame
            && job
                .chunks
                .iter()
                .all(|c| producer.chunks.iter().any(|pc| pc.index == c.index));
        let wait = if per_chunk {
            Wait::PerChunk
        } else {
            Wait::Whole
        };
        match deps.iter_mut().find(|(j, _)| *j == p) {
            Some(d) => d.1 = d.1.max(wait),
            None => deps.push((p, wait)),
        }
    }
    deps
}

/// An absolute form of `p` (relative to the current folder), for paths other hosts read.
pub fn absolute(p: &Path) -> Result<PathBuf, String> {
    std::path::absolute(p).map_err(|e| format!("cannot resolve {}: {e}", p.display()))
}

/// Checks that the cache folder exists or can be made and is writable by this user: a farm
/// whose tasks cannot write there would fail every task. Nothing is submitted otherwise.
pub fn check_cache_writable(cache: &Path) -> Result<(), String> {
    std::fs::create_dir_all(cache.join("tmp"))
        .map_err(|e| format!("cache folder {} cannot be created: {e}", cache.display()))?;
    let probe = cache
        .join("tmp")
        .join(format!("probe-{}", vfxgraph_engine::fsutil::unique_token()));
    std::fs::write(&probe, b"probe")
        .map_err(|e| format!("cache folder {} is not writable: {e}", cache.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// How long after its last task started or ended a submission counts as active (a queued
/// task may wait behind long renders): `cache gc --max-size` refuses to evict meanwhile.
pub const LEASE: std::time::Duration = std::time::Duration::from_secs(24 * 3600);

/// Where a submission's token lives in a cache.
pub fn token_path(cache: &Path, token: &str) -> PathBuf {
    cache.join("farm-tokens").join(token)
}

/// A new submission token: unique to this host (its name first), process and time.
pub fn new_token() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    format!("{}-{secs}", vfxgraph_engine::fsutil::unique_token())
}

/// The host a token was made on (its first part).
fn token_host(token: &str) -> &str {
    token.split('-').next().unwrap_or(token)
}

/// Writes the submission's token into the cache before anything is submitted: every task
/// checks it ([`check_token`]), so a task whose cache path is not the submitter's cache
/// (not shared, not mounted, another folder) fails at once instead of computing into a cache
/// nobody reads. The token's mtime is the submission's lease: every task sets it when it
/// starts and ends, and `cache gc` will not evict entries while a lease is recent.
pub fn write_token(cache: &Path, token: &str) -> Result<(), String> {
    let p = token_path(cache, token);
    vfxgraph_engine::fsutil::atomic_write(&p, format!("{token}\n").as_bytes())
        .map_err(|e| format!("cache folder {} is not writable: {e}", cache.display()))
}

/// Checks, at the start of a farm task, that `cache` holds the token its submit wrote, and
/// renews the lease (sets the token's mtime).
pub fn check_token(cache: &Path, token: &str) -> Result<(), String> {
    let p = token_path(cache, token);
    let seen = std::fs::read_to_string(&p).is_ok_and(|t| t.trim() == token);
    if !seen {
        return Err(format!(
            "cache {} is not the one submit wrote (no {}: not shared with host {}?)",
            cache.display(),
            p.strip_prefix(cache).unwrap_or(&p).display(),
            token_host(token)
        ));
    }
    touch_token(cache, token);
    Ok(())
}

/// Renews a submission's lease (its token's mtime).
pub fn touch_token(cache: &Path, token: &str) {
    if let Ok(f) = std::fs::File::options()
        .append(true)
        .open(token_path(cache, token))
    {
        let _ = f.set_modified(std::time::SystemTime::now());
    }
}

/// Submissions whose lease is younger than `within`: (token, age), youngest first.
pub fn active_submissions(
    cache: &Path,
    within: std::time::Duration,
) -> Vec<(String, std::time::Duration)> {
    let mut out: Vec<(String, std::time::Duration)> = std::fs::read_dir(cache.join("farm-tokens"))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let age = e
                .metadata()
                .ok()?
                .modified()
                .ok()?
                .elapsed()
                .unwrap_or_default();
            let name = e.file_name().to_string_lossy().into_owned();
            (age < within && !name.starts_with('.')).then_some((name, age))
        })
        .collect();
    out.sort_by_key(|(_, a)| *a);
    out
}

/// The full path of program `name` on `PATH`, or an error saying how to get it.
pub fn find_program(name: &str, hint: &str) -> Result<PathBuf, String> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
        .ok_or_else(|| format!("`{name}` is not installed (not found on PATH): {hint}"))
}

/// A string quoted for a POSIX shell.
pub fn sh_quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_keep_their_index_and_only_uncached_frames() {
        let all: Vec<i64> = (1..=10).collect();
        let todo = [Some(2), Some(3), Some(9)];
        let c = chunks_of(&all, &todo, 4);
        assert_eq!(
            c,
            vec![
                Chunk {
                    index: 0,
                    frames: vec![2, 3]
                },
                Chunk {
                    index: 2,
                    frames: vec![9]
                }
            ]
        );
    }

    #[test]
    fn an_array_all_of_whose_queued_tasks_are_waited_for_is_named_once() {
        let set = |v: &[&str]| {
            v.iter()
                .map(|t| t.to_string())
                .collect::<BTreeSet<String>>()
        };
        let q = InFlight {
            whole: HashMap::from([("54".to_string(), set(&["54_0", "54_1"]))]),
            ..Default::default()
        };
        assert_eq!(q.compact(set(&["54_0", "54_1", "60"])), ["54", "60"]);
        assert_eq!(q.compact(set(&["54_1", "60"])), ["54_1", "60"]);
        assert_eq!(InFlight::job_of("54_1"), "54");
    }

    #[test]
    fn quoting() {
        assert_eq!(sh_quote("a/b-1.yaml"), "a/b-1.yaml");
        assert_eq!(sh_quote("it's x"), r"'it'\''s x'");
        assert_eq!(sh_quote(""), "''");
    }
}
