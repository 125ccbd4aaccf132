//! Slurm: one `sbatch` job per node; a per-frame node is a job array over its chunks (array
//! index = the chunk's position in the graph's frames, so chunk k of two per-frame nodes has
//! the same index and `aftercorr` pairs them); a whole-sequence consumer waits `afterok` for
//! the whole array. `--kill-on-invalid-dep=yes` cancels the dependants of a failed task.
//! Resources from the node type: `--cpus-per-task=1` for a one-core node, `--exclusive` for
//! one that uses every core (or, per frame with `submit --task-cpus N`, `--cpus-per-task=N`,
//! so tasks share a host), `--mem` from its memory hint (`Memory`: a fixed amount for a
//! reader, an image-sized one for a renderer from its width × height). A task's worker threads
//! are its allocation's CPUs (`exec --jobs`).
//!
//! A job that reads instances a queued task of an earlier submission computes waits for that
//! task (`afterok:<job>_<index>`) instead of computing them again ([`super::InFlight`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use vfxgraph_engine::{FrameSet, Threads};

use super::{sh_quote, FarmPlan, Job, TaskContext, Wait};

/// A submitted job.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Submitted {
    /// Node id.
    pub node: String,
    /// Slurm job id.
    pub job_id: String,
    /// Tasks (array elements).
    pub tasks: usize,
    /// The `--dependency` it was given.
    pub dependency: String,
    /// Its job name.
    pub name: String,
}

/// The job name: graph/node/frames (what `squeue` shows and `status` reads).
pub fn job_name(ctx: &TaskContext, job: &Job) -> String {
    format!("{}/{}/{}", ctx.graph_name, job.node, job.frames_label())
}

/// The CPUs a task of `job` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cpus {
    /// This many (`--cpus-per-task`).
    Some(u32),
    /// The whole host (`--exclusive`).
    Host,
}

/// A one-core node's task asks for one CPU; one that uses every core the whole host, or, per
/// frame, `--task-cpus` when given (per-frame tasks are many and independent: sharing a
/// host lets one task's start overlap another's compute).
pub fn cpus(ctx: &TaskContext, job: &Job) -> Cpus {
    match (job.threads, ctx.task_cpus) {
        (Threads::One, _) => Cpus::Some(1),
        (Threads::All, Some(n)) if job.per_frame => Cpus::Some(n.max(1)),
        (Threads::All, _) => Cpus::Host,
    }
}

/// The batch script of `job`, logging each task to `logs/<node>.<job>_<task>.log`.
pub fn script(ctx: &TaskContext, job: &Job, logs: &Path) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let _ = writeln!(s, "#SBATCH --job-name={}", job_name(ctx, job));
    let log = if job.per_frame { "%A_%a" } else { "%j" };
    let _ = writeln!(
        s,
        "#SBATCH --output={}",
        logs.join(format!("{}.{log}.log", job.node)).display()
    );
    let _ = writeln!(s, "#SBATCH --kill-on-invalid-dep=yes");
    let jobs = match cpus(ctx, job) {
        Cpus::Some(n) => {
            let _ = writeln!(s, "#SBATCH --cpus-per-task={n}");
            format!("${{SLURM_CPUS_PER_TASK:-{n}}}")
        }
        Cpus::Host => {
            s.push_str("#SBATCH --exclusive\n");
            "${SLURM_CPUS_ON_NODE:-1}".to_string()
        }
    };
    if let Some(m) = job.memory_mib {
        let _ = writeln!(s, "#SBATCH --mem={m}M");
    }
    if job.per_frame {
        let idx: Vec<String> = job.chunks.iter().map(|c| c.index.to_string()).collect();
        let _ = writeln!(s, "#SBATCH --array={}", idx.join(","));
    }
    s.push_str("set -euo pipefail\n");
    if job.per_frame {
        s.push_str("frames=(");
        for c in &job.chunks {
            let f = FrameSet::from_frames(c.frames.clone()).to_string();
            let _ = write!(s, " [{}]={}", c.index, sh_quote(&f));
        }
        s.push_str(" )\n");
    }
    let frames = job.per_frame.then_some("@FRAMES@");
    // Start and end stamps in the log: a wrangler sees where and when a task ran, with how
    // many threads, and the farm benchmark (scripts/bench/farm_scaling.sh) the time outside
    // `vfxgraph exec`'s run and its CPU time (bash's `time`: user and system seconds).
    let _ = writeln!(
        s,
        "echo \"task start $(date +%s.%N) on $(hostname) threads {jobs}\""
    );
    s.push_str("TIMEFORMAT='task cpu %U user %S sys %R wall'\ntime ");
    let mut line = sh_quote(&ctx.exe.display().to_string());
    for a in ctx.exec_args(&job.nodes, frames, Some("@JOBS@")) {
        let word = match a.as_str() {
            "@FRAMES@" => "\"${frames[$SLURM_ARRAY_TASK_ID]}\"".to_string(),
            "@JOBS@" => format!("\"{jobs}\""),
            _ => sh_quote(&a),
        };
        line.push(' ');
        line.push_str(&word);
    }
    s.push_str(&line);
    s.push_str("\necho \"task end $(date +%s.%N)\"\n");
    s
}

/// The `--dependency` value of job `i` given its producers' Slurm ids (empty: none), and the
/// queued tasks of earlier submissions it reads.
pub fn dependency(job: &Job, ids: &[String]) -> String {
    job.deps
        .iter()
        .map(|(p, w)| match w {
            Wait::PerChunk => format!("aftercorr:{}", ids[*p]),
            Wait::Whole => format!("afterok:{}", ids[*p]),
        })
        .chain(job.after.iter().map(|t| format!("afterok:{t}")))
        .collect::<Vec<_>>()
        .join(",")
}

/// The shell variable holding the Slurm id of job `i` in a [`dry_run`] script.
pub fn job_var(i: usize) -> String {
    format!("job_{}", i + 1)
}

/// The end of each here-document in a [`dry_run`] script.
const HEREDOC_END: &str = "VFXGRAPH_EOF";

/// What [`submit`] would do, as a POSIX sh script that does it: it writes the token into the
/// cache, each job's batch script into `dir` (a quoted here-document), submits it with
/// `sbatch --parsable` (its id in `$job_1`, `$job_2`, … for the dependencies of the jobs
/// after it), and writes the submission's record (`record`, its job ids `@job_N@`, filled in
/// by `sed`).
pub fn dry_run(ctx: &TaskContext, plan: &FarmPlan, dir: &Path, record: &str) -> String {
    let mut out = String::from("#!/bin/sh\n");
    if plan.jobs.is_empty() {
        out.push_str("# nothing to submit\n");
        return out;
    }
    let _ = writeln!(
        out,
        "# {}: {} job(s), {} task(s) on Slurm; `sh` this file to submit them.\nset -eu",
        ctx.graph_name,
        plan.jobs.len(),
        plan.task_count()
    );
    let _ = writeln!(out, "dir={}", sh_quote(&dir.display().to_string()));
    out.push_str("mkdir -p \"$dir/logs\"\n");
    let token = super::token_path(&ctx.cache, &ctx.token);
    let tokens = token.parent().unwrap_or(&ctx.cache);
    let _ = writeln!(
        out,
        "# The token every task checks its cache holds.\nmkdir -p {}\nprintf '%s\\n' {} > {}",
        sh_quote(&tokens.display().to_string()),
        sh_quote(&ctx.token),
        sh_quote(&token.display().to_string())
    );
    let ids: Vec<String> = (0..plan.jobs.len())
        .map(|i| format!("${}", job_var(i)))
        .collect();
    for (i, job) in plan.jobs.iter().enumerate() {
        let dep = dependency(job, &ids);
        let dep = if dep.is_empty() {
            String::new()
        } else {
            format!(" --dependency={dep}")
        };
        let file = format!("\"$dir\"/{}", sh_quote(&format!("{}.sh", job.node)));
        let var = job_var(i);
        let name = job_name(ctx, job);
        let _ = writeln!(
            out,
            "# {name} ({} task(s))\ncat > {file} <<'{HEREDOC_END}'",
            job.chunks.len()
        );
        out.push_str(&script(ctx, job, &dir.join("logs")));
        let _ = writeln!(
            out,
            "{HEREDOC_END}\n{var}=$(sbatch --parsable{dep} {file})\n{var}=${{{var}%%;*}}\n\
             echo \"${var}  {}  {} task(s)\"",
            name.replace(['"', '$', '`', '\\'], "_"),
            job.chunks.len()
        );
    }
    // The job ids, and the time it is submitted (not printed).
    let fill: Vec<String> = (0..plan.jobs.len())
        .map(|i| format!("-e \"s/@{v}@/${v}/g\"", v = job_var(i)))
        .chain([r#"-e "s/^  \"submitted\": [0-9.]*,/  \"submitted\": $(date +%s),/""#.into()])
        .collect();
    let _ = writeln!(
        out,
        "# The submission's record (what `vfxgraph status` and the next submit read).\n\
         sed {} > \"$dir/.vfxgraph-tmp-submission.json\" <<'{HEREDOC_END}'\n{record}\n{HEREDOC_END}\n\
         mv \"$dir/.vfxgraph-tmp-submission.json\" \"$dir/submission.json\"",
        fill.join(" ")
    );
    out
}

/// Writes every script into `dir` (logs in `dir/logs`), then submits them in order with
/// their dependencies. If an `sbatch` fails, the jobs already submitted are cancelled, so a
/// submission is whole or nothing.
pub fn submit(ctx: &TaskContext, plan: &FarmPlan, dir: &Path) -> Result<Vec<Submitted>, String> {
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).map_err(|e| format!("cannot create {}: {e}", logs.display()))?;
    let mut scripts: Vec<PathBuf> = Vec::new();
    for job in &plan.jobs {
        let p = dir.join(format!("{}.sh", job.node));
        vfxgraph_engine::fsutil::atomic_write(&p, script(ctx, job, &logs).as_bytes())
            .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        scripts.push(p);
    }
    let mut done: Vec<Submitted> = Vec::new();
    for (job, path) in plan.jobs.iter().zip(&scripts) {
        let ids: Vec<String> = done.iter().map(|s| s.job_id.clone()).collect();
        let dep = dependency(job, &ids);
        match sbatch(path, &dep) {
            Ok(id) => done.push(Submitted {
                node: job.node.clone(),
                job_id: id,
                tasks: job.chunks.len(),
                dependency: dep,
                name: job_name(ctx, job),
            }),
            Err(e) => {
                cancel(&done);
                return Err(format!(
                    "sbatch of node `{}` failed: {e}; the {} job(s) submitted before it were \
                     cancelled",
                    job.node,
                    done.len()
                ));
            }
        }
    }
    Ok(done)
}

fn sbatch(script: &Path, dep: &str) -> Result<String, String> {
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable");
    if !dep.is_empty() {
        cmd.arg(format!("--dependency={dep}"));
    }
    let out = cmd
        .arg(script)
        .output()
        .map_err(|e| format!("cannot run sbatch: {e}"))?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).trim().to_string());
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let id = text
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(format!("unexpected sbatch output `{}`", text.trim()));
    }
    Ok(id)
}

fn cancel(done: &[Submitted]) {
    if done.is_empty() {
        return;
    }
    let _ = Command::new("scancel")
        .args(done.iter().map(|s| s.job_id.as_str()))
        .status();
}

/// A task in Slurm's queue that has yet to finish: running, or waiting to (not one whose
/// dependency can never be met, which Slurm is about to cancel).
#[derive(Clone, Debug, PartialEq)]
pub struct QueuedTask {
    /// Its job id (an array's).
    pub job_id: String,
    /// Its array index (`None`: not an array task).
    pub index: Option<usize>,
    /// Its batch script.
    pub script: PathBuf,
}

impl QueuedTask {
    /// How a dependency names it: `job` or `job_index`.
    pub fn name(&self) -> String {
        match self.index {
            Some(k) => format!("{}_{k}", self.job_id),
            None => self.job_id.clone(),
        }
    }
}

/// Every task in Slurm's queue that has yet to finish (`squeue -r`: one line per array task).
pub fn queue() -> Result<Vec<QueuedTask>, String> {
    let out = Command::new("squeue")
        .args(["-h", "-r", "-o", "%F|%K|%T|%r|%o"])
        .output()
        .map_err(|e| format!("cannot run squeue: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "squeue failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(parse_queue(&String::from_utf8_lossy(&out.stdout)))
}

/// [`queue`]'s lines: `job|index|state|reason|script`.
fn parse_queue(text: &str) -> Vec<QueuedTask> {
    text.lines()
        .filter_map(|line| {
            let f: Vec<&str> = line.splitn(5, '|').collect();
            let [job, index, state, reason, script] = f[..] else {
                return None;
            };
            let waiting = matches!(
                state,
                "PENDING" | "CONFIGURING" | "REQUEUED" | "REQUEUE_HOLD" | "REQUEUE_FED"
            ) && reason != "DependencyNeverSatisfied";
            // A completing task has ended: its instances are cached, or it failed.
            let running = matches!(state, "RUNNING" | "SUSPENDED" | "RESIZING" | "SIGNALING");
            (waiting || running).then(|| QueuedTask {
                job_id: job.to_string(),
                index: index.parse().ok(),
                script: PathBuf::from(script),
            })
        })
        .collect()
}

/// The graph's instances in the farm's queue, per node.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Queued {
    /// Instances of running tasks (frame, or `None` for a node that runs once).
    pub running: Vec<Option<i64>>,
    /// Instances of tasks waiting to start.
    pub pending: Vec<Option<i64>>,
}

/// The graph's instances in the queue, per node, read from `squeue` (one line per array
/// task: its job name, state, array index and batch script; a task's frames are the ones
/// its script gives its index). `None` when `squeue` is not installed or fails.
pub fn queued(graph_name: &str) -> Option<std::collections::BTreeMap<String, Queued>> {
    let out = Command::new("squeue")
        .args(["-h", "-r", "-o", "%j|%T|%K|%o"])
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    let mut per_node = std::collections::BTreeMap::new();
    let mut scripts: std::collections::HashMap<String, Vec<(usize, Vec<i64>)>> = Default::default();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let f: Vec<&str> = line.splitn(4, '|').collect();
        let [name, state, index, command] = f[..] else {
            continue;
        };
        let mut parts = name.splitn(3, '/');
        if parts.next() != Some(graph_name) {
            continue;
        }
        let Some(job_nodes) = parts.next() else {
            continue;
        };
        let frames: Vec<Option<i64>> = match index.parse::<usize>() {
            // An array task: the frames of its chunk.
            Ok(k) => scripts
                .entry(command.to_string())
                .or_insert_with(|| {
                    std::fs::read_to_string(command)
                        .map(|t| script_chunks(&t))
                        .unwrap_or_default()
                })
                .iter()
                .find(|(i, _)| *i == k)
                .map(|(_, fr)| fr.iter().map(|&f| Some(f)).collect())
                .unwrap_or_default(),
            Err(_) => vec![None],
        };
        // A fused job's name holds its nodes joined by `+`: its task runs each of them.
        for node in job_nodes.split('+') {
            let e: &mut Queued = per_node.entry(node.to_string()).or_default();
            match state {
                "RUNNING" | "COMPLETING" => e.running.extend(frames.iter().copied()),
                "PENDING" | "CONFIGURING" | "REQUEUED" | "SUSPENDED" => {
                    e.pending.extend(frames.iter().copied())
                }
                _ => {}
            }
        }
    }
    Some(per_node)
}

/// The chunks of a batch script [`script`] wrote: (array index, frames).
fn script_chunks(text: &str) -> Vec<(usize, Vec<i64>)> {
    let Some(list) = text
        .lines()
        .find_map(|l| l.strip_prefix("frames=("))
        .and_then(|l| l.strip_suffix(')'))
    else {
        return vec![];
    };
    list.split_whitespace()
        .filter_map(|w| {
            let (k, v) = w.strip_prefix('[')?.split_once("]=")?;
            let frames = FrameSet::parse(v.trim_matches('\'')).ok()?;
            Some((k.parse().ok()?, frames.frames().to_vec()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scripts_chunks_read_back() {
        let t = "#!/bin/bash\nset -e\nframes=( [0]=1-4 [2]='9,11' )\nexec x\n";
        assert_eq!(
            script_chunks(t),
            vec![(0, vec![1, 2, 3, 4]), (2, vec![9, 11])]
        );
        assert!(script_chunks("exec x\n").is_empty());
    }

    #[test]
    fn the_queue_keeps_tasks_that_will_run() {
        let q = parse_queue(
            "54|0|RUNNING|None|/c/farm/g-t/plate.sh\n\
             54|1|PENDING|Dependency|/c/farm/g-t/plate.sh\n\
             55|N/A|PENDING|DependencyNeverSatisfied|/c/farm/g-t/movie.sh\n\
             56|N/A|COMPLETING|None|/c/farm/g-t/path.sh\n\
             57|N/A|PENDING|JobHeldUser|/c/farm/g-t/a|b.sh\n",
        );
        let names: Vec<String> = q.iter().map(QueuedTask::name).collect();
        assert_eq!(names, ["54_0", "54_1", "57"]);
        assert_eq!(q[2].script, Path::new("/c/farm/g-t/a|b.sh"));
    }
}
