//! Open Job Description (what AWS Deadline Cloud runs): a `jobtemplate-2023-09` job template
//! in JSON with one step per node. A per-frame step's tasks are a chunked `Frame` parameter
//! (`CHUNK[INT]`, the `TASK_CHUNKING` extension) over the node's uncached frames; steps depend
//! on the steps of their producers (OpenJD dependencies are whole-step); a node type's memory
//! hint is the step's `amount.worker.memory` host requirement (MiB). The vfxgraph binary,
//! the graph and the cache are job parameters, so a farm maps them to its own paths.

use serde_json::{json, Value};

use vfxgraph_engine::Threads;

use super::{FarmPlan, Job, TaskContext};

/// The job template of `plan`, chunks of `chunk` frames.
pub fn template(ctx: &TaskContext, plan: &FarmPlan, chunk: usize) -> Value {
    // No defaults: OpenJD resolves a PATH default against the template's folder, and these
    // are the farm's own paths (see [`parameters`]).
    let path_param = |name: &str, kind: &str, flow: &str, what: &str| {
        json!({
            "name": name, "type": "PATH", "objectType": kind, "dataFlow": flow,
            "description": what,
        })
    };
    json!({
        "specificationVersion": "jobtemplate-2023-09",
        "extensions": ["TASK_CHUNKING"],
        "name": format!("vfxgraph {}", ctx.graph_name),
        "parameterDefinitions": [
            path_param("Vfxgraph", "FILE", "IN", "the vfxgraph binary the tasks run"),
            path_param("Graph", "FILE", "IN", "the graph file"),
            path_param("Cache", "DIRECTORY", "INOUT", "the shared cache folder"),
        ],
        "steps": plan.jobs.iter().map(|j| step(ctx, plan, j, chunk)).collect::<Vec<_>>(),
    })
}

/// The job parameters of this submission (`openjd run -p K=V`, or a farm's submitter).
pub fn parameters(ctx: &TaskContext) -> Value {
    json!({
        "Vfxgraph": ctx.exe.display().to_string(),
        "Graph": ctx.graph.display().to_string(),
        "Cache": ctx.cache.display().to_string(),
    })
}

fn step(ctx: &TaskContext, plan: &FarmPlan, job: &Job, chunk: usize) -> Value {
    let mut args = TaskContext {
        graph: "{{Param.Graph}}".into(),
        cache: "{{Param.Cache}}".into(),
        ..ctx.clone()
    }
    .exec_args(
        &job.nodes,
        job.per_frame.then_some("{{Task.Param.Frame}}"),
        None,
    );
    let cpus = match super::slurm::cpus(ctx, job) {
        super::slurm::Cpus::Some(n) => {
            args.extend(["--jobs".into(), n.to_string()]);
            Some(n)
        }
        super::slurm::Cpus::Host => None,
    };
    let mut s = json!({
        "name": step_name(job),
        "description": format!("{}/{}/{}", ctx.graph_name, job.node, job.frames_label()),
        "script": {"actions": {"onRun": {"command": "{{Param.Vfxgraph}}", "args": args}}},
    });
    let mut amounts = Vec::new();
    if let Some(m) = job.memory_mib {
        amounts.push(json!({"name": "amount.worker.memory", "min": m}));
    }
    // Only a shared-host request (`--task-cpus`) states a vCPU count; one-core tasks and
    // whole-host ones run on any worker.
    if let Some(n) = cpus.filter(|_| job.threads == Threads::All) {
        amounts.push(json!({"name": "amount.worker.vcpu", "min": n}));
    }
    if !amounts.is_empty() {
        s["hostRequirements"] = json!({ "amounts": amounts });
    }
    if job.per_frame {
        s["parameterSpace"] = json!({"taskParameterDefinitions": [{
            "name": "Frame",
            "type": "CHUNK[INT]",
            "range": job.frames_label(),
            "chunks": {"defaultTaskCount": chunk.max(1), "rangeConstraint": "NONCONTIGUOUS"},
        }]});
    }
    if !job.deps.is_empty() {
        s["dependencies"] = job
            .deps
            .iter()
            .map(|(p, _)| json!({"dependsOn": step_name(&plan.jobs[*p])}))
            .collect();
    }
    s
}

/// A step's name: the job's (`a+b+c` when fused), or its first node and how many more when
/// that is longer than OpenJD's 64 characters (unique: a node is in one job only).
pub fn step_name(job: &Job) -> String {
    if job.node.chars().count() <= 64 {
        job.node.clone()
    } else {
        format!("{}+{}more", job.nodes[0], job.nodes.len() - 1)
    }
}
