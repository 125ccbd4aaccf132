//! Fused farm tasks (`submit --fuse`): a chain of per-frame nodes run as one task per chunk.
//!
//! Every farm task pays the farm's scheduling (on Slurm a dependency is released on the
//! scheduler's next pass, ~0.7 s on the local cluster) and a process start, graph load and
//! cache read. A render followed by cheap per-frame consumers (a layer write, a composite, a
//! tonemap, a PNG write) is then mostly overhead: the book shot at `--chunk 10` is 24 chunks ×
//! 5 nodes = 120 per-frame tasks. Fusing puts a per-frame node into the job of its per-frame
//! producer when
//!
//! - every per-frame producer it reads per chunk is in that one job, and
//! - every other job it waits for, that job already waits for, at least as strongly (so
//!   fusing adds no wait to the job's tasks, and the job graph stays acyclic);
//!
//! its tasks then run `exec --node A --node B … --frames F` over the chunk: exec computes the
//! same instances with the same keys as separate tasks would (a member's frame that is
//! already cached is a cache hit), so the cache is the same as unfused or local. A consumer
//! of any member waits for the fused task of its chunk (or the whole fused job). A fused
//! job asks for the most any member needs (every core if one uses them all, the largest
//! memory hint of those that have one) — like Meshroom's node chunks or a Snakemake group
//! job.

use vfxgraph_engine::Threads;

use super::{FarmPlan, Job, Wait};

/// `plan` with each fusable per-frame job merged into its producer's job (see the module
/// doc); jobs stay in topological order.
pub fn fuse(plan: FarmPlan) -> FarmPlan {
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
    FarmPlan { jobs: out }
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
    (host.per_frame && waits_already && same_chunks).then_some(h)
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
    fn a_render_and_its_per_frame_consumers_become_one_job() {
        use Wait::*;
        let once = &[(0, &[][..])][..];
        let two = &[(0, &[1, 2][..]), (1, &[3][..])][..];
        let mut render = job("render", true, two, &[(0, Whole), (1, Whole)]);
        render.threads = Threads::All;
        render.memory_mib = Some(300);
        let mut grade = job(
            "grade",
            true,
            &[(0, &[2][..]), (1, &[3, 4][..])],
            &[(2, PerChunk)],
        );
        grade.memory_mib = Some(100);
        let plan = FarmPlan {
            jobs: vec![
                job("cameras", false, once, &[]),
                job("scene", false, once, &[]),
                render,
                grade,
                // Reads the render per chunk and the cameras, which the render waits for.
                job("write", true, two, &[(3, PerChunk), (0, Whole)]),
                // Whole-sequence consumers stay jobs of their own.
                job("movie", false, once, &[(3, Whole)]),
                job("frames_json", true, two, &[(4, Whole)]),
            ],
        };
        let f = fuse(plan);
        assert_eq!(
            names(&f),
            vec![
                ("cameras", vec![]),
                ("scene", vec![]),
                ("render+grade+write", vec![(0, Whole), (1, Whole)]),
                ("movie", vec![(2, Whole)]),
                ("frames_json", vec![(2, Whole)]),
            ]
        );
        let r = &f.jobs[2];
        assert_eq!(r.nodes, ["render", "grade", "write"]);
        // Per chunk, the frames any member still has to run.
        let frames: Vec<Vec<i64>> = r.chunks.iter().map(|c| c.frames.clone()).collect();
        assert_eq!(frames, [vec![1, 2], vec![3, 4]]);
        assert_eq!((r.threads, r.memory_mib), (Threads::All, Some(300)));
        assert_eq!(f.task_count(), 2 + 2 + 1 + 2);
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
}
