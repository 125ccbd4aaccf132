//! Slurm: one `sbatch` job per node; a per-frame node is a job array over its chunks (array
//! index = the chunk's position in the graph's frames, so chunk k of two per-frame nodes has
//! the same index and `aftercorr` pairs them); a whole-sequence consumer waits `afterok` for
//! the whole array. `--kill-on-invalid-dep=yes` cancels the dependants of a failed task.

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
    match job.threads {
        Threads::One => s.push_str("#SBATCH --cpus-per-task=1\n"),
        Threads::All => s.push_str("#SBATCH --exclusive\n"),
    }
    if job.per_frame {
        let idx: Vec<String> = job.chunks.iter().map(|c| c.index.to_string()).collect();
        let _ = writeln!(s, "#SBATCH --array={}", idx.join(","));
    }
    s.push_str("set -euo pipefail\n");
    let jobs = match job.threads {
        Threads::One => "1",
        Threads::All => "${SLURM_CPUS_ON_NODE:-1}",
    };
    if job.per_frame {
        s.push_str("frames=(");
        for c in &job.chunks {
            let f = FrameSet::from_frames(c.frames.clone()).to_string();
            let _ = write!(s, " [{}]={}", c.index, sh_quote(&f));
        }
        s.push_str(" )\n");
    }
    let frames = job.per_frame.then_some("@FRAMES@");
    let mut line = format!("exec {}", sh_quote(&ctx.exe.display().to_string()));
    for a in ctx.exec_args(&job.node, frames, Some("@JOBS@")) {
        let word = match a.as_str() {
            "@FRAMES@" => "\"${frames[$SLURM_ARRAY_TASK_ID]}\"".to_string(),
            "@JOBS@" => format!("\"{jobs}\""),
            _ => sh_quote(&a),
        };
        line.push(' ');
        line.push_str(&word);
    }
    s.push_str(&line);
    s.push('\n');
    s
}

/// The `--dependency` value of job `i` given its producers' Slurm ids (empty: none).
pub fn dependency(job: &Job, ids: &[String]) -> String {
    job.deps
        .iter()
        .map(|(p, w)| match w {
            Wait::PerChunk => format!("aftercorr:{}", ids[*p]),
            Wait::Whole => format!("afterok:{}", ids[*p]),
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// Prints what [`submit`] would run: each job's `sbatch` line and script.
pub fn dry_run(ctx: &TaskContext, plan: &FarmPlan, dir: &Path) -> String {
    let ids: Vec<String> = plan.jobs.iter().map(|j| format!("${}", j.node)).collect();
    let mut out = String::new();
    for job in &plan.jobs {
        let dep = dependency(job, &ids);
        let dep = if dep.is_empty() {
            String::new()
        } else {
            format!(" --dependency={dep}")
        };
        let _ = writeln!(
            out,
            "# {} ({} task(s))\n{}=$(sbatch --parsable{dep} {})",
            job_name(ctx, job),
            job.chunks.len(),
            job.node,
            dir.join(format!("{}.sh", job.node)).display()
        );
        out.push_str(&script(ctx, job, &dir.join("logs")));
        out.push('\n');
    }
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

/// Tasks of the graph's jobs in the queue, per node: (running, pending), read from
/// `squeue` (array tasks one per line). `None` when `squeue` is not installed or fails.
pub fn queued(graph_name: &str) -> Option<std::collections::BTreeMap<String, (usize, usize)>> {
    let out = Command::new("squeue")
        .args(["-h", "-r", "-o", "%j|%T"])
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    let mut per_node = std::collections::BTreeMap::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Some((name, state)) = line.split_once('|') else {
            continue;
        };
        let mut parts = name.splitn(3, '/');
        if parts.next() != Some(graph_name) {
            continue;
        }
        let Some(node) = parts.next() else { continue };
        let e: &mut (usize, usize) = per_node.entry(node.to_string()).or_default();
        match state {
            "RUNNING" | "COMPLETING" => e.0 += 1,
            "PENDING" | "CONFIGURING" => e.1 += 1,
            _ => {}
        }
    }
    Some(per_node)
}
