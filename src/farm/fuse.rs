//! Fused farm tasks (`submit --fuse`): fewer, larger tasks with the same cache.
//!
//! Every farm task pays the farm's scheduling (on Slurm a dependency is released on the
//! scheduler's next pass, ~0.7 s on the local cluster) and a process start, graph load and
//! cache read. The book shot at `--chunk 10` is 11 once tasks in a chain of dependency hops
//! (readers → solve → relax → ground points → placement) and 24 chunks × 5 per-frame nodes,
//! a render and four cheap consumers (a layer write, a composite, a tonemap, a PNG write):
//! 131 tasks, most of them overhead. Fusing makes it 25:
//!
//! - **The prologue**: every node that runs once and reads no per-frame node (directly or
//!   not) — the readers, the solve, everything before the per-frame work — is one task; one
//!   `exec` runs its independent branches in parallel on the host's cores, and the chain of
//!   hops becomes one. (Independent once branches no longer spread over hosts; per-frame work
//!   that reads one of them waits for the whole prologue.)
//! - **Per-frame chains**: a per-frame node joins the job of its per-frame producer when
//!   every per-frame producer it reads per chunk is in that one job, and every other job it
//!   waits for, that job already waits for, at least as strongly (so fusing adds no wait to
//!   the job's tasks, and the job graph stays acyclic).
//!
//! A fused task runs `exec --node A --node B … [--frames F]`: exec computes the same
//! instances with the same keys as separate tasks would (a member's frame that is already
//! cached is a cache hit), so the cache is the same as unfused or local. A consumer of any
//! member waits for the fused task of its chunk (or the whole fused job). A fused job asks
//! for the most any member needs (every core if one uses them all, the largest memory hint
//! of those that have one) — like Meshroom's node chunks or a Snakemake group job.
//!
//! A job that waits for queued tasks of an earlier submission ([`Job::after`]) joins no
//! prologue, and joins a chain only when its host already waits for those tasks.

use vfxgraph_engine::Threads;

use super::{FarmPlan, Job, Wait};

/// `plan` with its prologue one job and each fusable per-frame job merged into its
/// producer's job (see the module doc); jobs stay in topological order.
pub fn fuse(plan: FarmPlan) -> FarmPlan {
    chains(prologue(plan))
}

/// `plan` with every once job that waits only for once jobs of the same kind (none
/// downstream of a per-frame job) merged into the first of them.
fn prologue(plan: FarmPlan) -> FarmPlan {
    let mut first: Option<usize> = None;
    let mut out: Vec<Job> = Vec::new();
    // The new job of each old job, and whether it is in the prologue.
    let mut job_of: Vec<usize> = Vec::with_capacity(plan.jobs.len());
    let mut in_prologue: Vec<bool> = Vec::with_capacity(plan.jobs.len());
    for mut job in plan.jobs {
        let member =
            !job.per_frame && job.after.is_empty() && job.deps.iter().all(|(p, _)| in_prologue[*p]);
        in_prologue.push(member);
        match first.filter(|_| member) {
            Some(h) => {
                absorb(&mut out[h], job);
                job_of.push(h);
            }
            None => {
                let mut deps: Vec<(usize, Wait)> = Vec::new();
                for &(p, w) in &job.deps {
                    add_dep(&mut deps, job_of[p], w);
                }
                job.deps = deps;
                if member {
                    first = Some(out.len());
                }
                job_of.push(out.len());
                out.push(job);
            }
        }
    }
    FarmPlan {
        jobs: out,
        skipped: plan.skipped,
    }
}

/// `plan` with each fusable per-frame job merged into its producer's job.
fn chains(plan: FarmPlan) -> FarmPlan {
    let mut out: Vec<Job> = Vec::new();
    // The new job of each old job.
    let mut job_of: Vec<usize> = Vec::with_capacity(plan.jobs.len());
    for mut job in plan.jobs {
        let mut deps: Vec<(usize, Wait)> = Vec::new();
        for &(p, w) in &job.deps {
            add_dep(&mut deps, job_of[p], w);
        }
        match host(&job, &deps, &out) {
            Some(h) => {
                absorb(&mut out[h], job);
                job_of.push(h);
            }
            None => {
                job.deps = deps;
                job_of.push(out.len());
                out.push(job);
            }
        }
    }
    FarmPlan {
        jobs: out,
        skipped: plan.skipped,
    }
}

/// Adds a wait on job `p`, keeping the strongest of two waits on the same job.
fn add_dep(deps: &mut Vec<(usize, Wait)>, p: usize, w: Wait) {
    match deps.iter_mut().find(|(j, _)| *j == p) {
        Some(d) => d.1 = d.1.max(w),
        None => deps.push((p, w)),
    }
}

/// The job `job` (its dependencies `deps` on jobs of `out`) can join, if any.
fn host(job: &Job, deps: &[(usize, Wait)], out: &[Job]) -> Option<usize> {
    if !job.per_frame {
        return None;
    }
    let per_chunk: Vec<usize> = deps
        .iter()
        .filter(|(_, w)| *w == Wait::PerChunk)
        .map(|(p, _)| *p)
        .collect();
    let [h] = per_chunk[..] else { return None };
    let host = &out[h];
    let waits_already = deps
        .iter()
        .filter(|(p, _)| *p != h)
        .all(|(p, w)| host.deps.iter().any(|(q, v)| q == p && v >= w));
    let same_chunks = job
        .chunks
        .iter()
        .all(|c| host.chunks.iter().any(|hc| hc.index == c.index));
    let after_already = job.after.iter().all(|t| host.after.contains(t));
    (host.per_frame && waits_already && after_already && same_chunks).then_some(h)
}

/// Merges `job` into `host`: its nodes, the union of its frames per chunk, the larger
/// resource hints.
fn absorb(host: &mut Job, job: Job) {
    host.nodes.extend(job.nodes);
    host.node = host.nodes.join("+");
    for c in job.chunks {
        if let Some(hc) = host.chunks.iter_mut().find(|hc| hc.index == c.index) {
            hc.frames.extend(c.frames);
            hc.frames.sort_unstable();
            hc.frames.dedup();
        }
    }
    if job.threads == Threads::All {
        host.threads = Threads::All;
    }
    host.memory_mib = host.memory_mib.max(job.memory_mib);
    host.after.extend(job.after);
    host.after.sort_unstable();
    host.after.dedup();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::farm::Chunk;

    fn job(node: &str, per_frame: bool, chunks: &[(usize, &[i64])], deps: &[(usize, Wait)]) -> Job {
        Job {
            node: node.into(),
            nodes: vec![node.into()],
            per_frame,
            chunks: chunks
                .iter()
                .map(|(index, f)| Chunk {
                    index: *index,
                    frames: f.to_vec(),
                })
                .collect(),
            deps: deps.to_vec(),
            after: vec![],
            threads: Threads::One,
            memory_mib: None,
        }
    }

    fn names(p: &FarmPlan) -> Vec<(&str, Vec<(usize, Wait)>)> {
        p.jobs
            .iter()
            .map(|j| (j.node.as_str(), j.deps.clone()))
            .collect()
    }

    #[test]
    fn the_prologue_and_a_render_with_its_per_frame_consumers_become_one_job_each() {
        use Wait::*;
        let once = &[(0, &[][..])][..];
        let two = &[(0, &[1, 2][..]), (1, &[3][..])][..];
        let mut solve = job("solve", false, once, &[(0, Whole)]);
        solve.threads = Threads::All;
        let mut render = job("render", true, two, &[(2, Whole), (1, Whole)]);
        render.threads = Threads::All;
        render.memory_mib = Some(300);
        let mut grade = job(
            "grade",
            true,
            &[(0, &[2][..]), (1, &[3, 4][..])],
            &[(3, PerChunk)],
        );
        grade.memory_mib = Some(100);
        let plan = FarmPlan {
            jobs: vec![
                job("tracks", false, once, &[]),
                job("scene", false, once, &[]),
                solve,
                render,
                grade,
                // Reads the grade per chunk and the solve, which the render waits for.
                job("write", true, two, &[(4, PerChunk), (2, Whole)]),
                // Whole-sequence consumers stay jobs of their own.
                job("movie", false, once, &[(4, Whole)]),
                job("frames_json", true, two, &[(5, Whole)]),
            ],
            ..Default::default()
        };
        let f = fuse(plan);
        assert_eq!(
            names(&f),
            vec![
                ("tracks+scene+solve", vec![]),
                ("render+grade+write", vec![(0, Whole)]),
                ("movie", vec![(1, Whole)]),
                ("frames_json", vec![(1, Whole)]),
            ]
        );
        assert_eq!(f.jobs[0].threads, Threads::All, "the solve uses every core");
        let r = &f.jobs[1];
        assert_eq!(r.nodes, ["render", "grade", "write"]);
        // Per chunk, the frames any member still has to run.
        let frames: Vec<Vec<i64>> = r.chunks.iter().map(|c| c.frames.clone()).collect();
        assert_eq!(frames, [vec![1, 2], vec![3, 4]]);
        assert_eq!((r.threads, r.memory_mib), (Threads::All, Some(300)));
        assert_eq!(f.task_count(), 1 + 2 + 1 + 2);
    }

    #[test]
    fn a_consumer_that_would_wait_for_more_stays_apart() {
        use Wait::*;
        let once = &[(0, &[][..])][..];
        let two = &[(0, &[1, 2][..]), (1, &[3, 4][..])][..];
        let plan = FarmPlan {
            jobs: vec![
                job("scene", false, once, &[]),
                job("render", true, two, &[(0, Whole)]),
                job("movie", false, once, &[(1, Whole)]),
                // Per chunk on the render, but also on the movie, which waits for the whole
                // render: fused, the render's job would wait for itself.
                job("burn_in", true, two, &[(1, PerChunk), (2, Whole)]),
                // Per chunk on two different jobs: no single host.
                job("plate", true, two, &[]),
                job("comp", true, two, &[(1, PerChunk), (4, PerChunk)]),
                // Only chunk 1 of the render's two chunks: joins it (a subset of its chunks).
                job("late", true, &[(1, &[4][..])], &[(1, PerChunk)]),
            ],
            ..Default::default()
        };
        let f = fuse(plan);
        assert_eq!(
            names(&f),
            vec![
                ("scene", vec![]),
                ("render+late", vec![(0, Whole)]),
                ("movie", vec![(1, Whole)]),
                ("burn_in", vec![(1, PerChunk), (2, Whole)]),
                ("plate", vec![]),
                ("comp", vec![(1, PerChunk), (4, PerChunk)]),
            ]
        );
    }

    #[test]
    fn a_job_waiting_for_queued_tasks_joins_only_a_host_that_waits_for_them() {
        use Wait::*;
        let once = &[(0, &[][..])][..];
        let two = &[(0, &[1, 2][..]), (1, &[3, 4][..])][..];
        let mut scene = job("scene", false, once, &[]);
        scene.after = vec!["7".into()];
        let mut grade = job("grade", true, two, &[(2, PerChunk)]);
        grade.after = vec!["8_0".into()];
        let mut write = job("write", true, two, &[(3, PerChunk)]);
        write.after = vec!["8_0".into()];
        let plan = FarmPlan {
            jobs: vec![
                job("path", false, once, &[]),
                scene,
                job("render", true, two, &[(0, Whole), (1, Whole)]),
                grade,
                write,
            ],
            ..Default::default()
        };
        let f = fuse(plan);
        // The scene waits for a queued task: no prologue member; the grade waits for one the
        // render does not: a job of its own, which the write (waiting for the same) joins.
        assert_eq!(
            names(&f),
            vec![
                ("path", vec![]),
                ("scene", vec![]),
                ("render", vec![(0, Whole), (1, Whole)]),
                ("grade+write", vec![(2, PerChunk)]),
            ]
        );
        assert_eq!(f.jobs[1].after, ["7"]);
        assert_eq!(f.jobs[3].after, ["8_0"]);
    }
}
