//! `vfxgraph status`: per node, how many instances the shared cache holds, how many of the
//! missing ones farm tasks are computing now or will (running / queued, from `squeue` where
//! installed; a task's frames from its batch script) and how many are missing — instances,
//! not tasks: a chunk of 10 frames running with 3 of them done counts 7 running. A bar a
//! wrangler reads at a glance.

use std::collections::BTreeMap;

use serde::Serialize;
use vfxgraph_engine::exec::{PlanReport, PlanStatus};
use vfxgraph_engine::Graph;

use super::slurm::Queued;

/// One node's line.
#[derive(Clone, Debug, Serialize)]
pub struct NodeStatus {
    /// Node id.
    pub id: String,
    /// Instances.
    pub instances: usize,
    /// Instances in the cache.
    pub cached: usize,
    /// Instances not in the cache.
    pub missing: usize,
    /// Missing instances a running farm task computes (`None`: no `squeue`).
    pub running: Option<usize>,
    /// Missing instances of farm tasks waiting to start.
    pub queued: Option<usize>,
}

/// The status of every node, in graph order.
pub fn collect(
    graph: &Graph,
    plan: &PlanReport,
    queue: Option<&BTreeMap<String, Queued>>,
) -> Vec<NodeStatus> {
    graph
        .nodes
        .iter()
        .map(|n| {
            let lines: Vec<_> = plan.nodes.iter().filter(|l| l.id == n.id).collect();
            let cached = lines
                .iter()
                .filter(|l| l.status == PlanStatus::Cached)
                .count();
            let missing: Vec<Option<i64>> = lines
                .iter()
                .filter(|l| l.status != PlanStatus::Cached)
                .map(|l| l.frame)
                .collect();
            // Missing instances among `of`, each once.
            let count = |of: &[Option<i64>]| missing.iter().filter(|f| of.contains(*f)).count();
            let q = queue.map(|q| q.get(&n.id).cloned().unwrap_or_default());
            NodeStatus {
                id: n.id.clone(),
                instances: lines.len(),
                cached,
                missing: missing.len(),
                running: q.as_ref().map(|q| count(&q.running)),
                queued: q.as_ref().map(|q| count(&q.pending)),
            }
        })
        .collect()
}

/// The table: node, a 20-character bar of the cached fraction, counts, farm tasks.
pub fn render(lines: &[NodeStatus]) -> String {
    let w = lines.iter().map(|l| l.id.len()).max().unwrap_or(4).max(4);
    let mut out = format!(
        "{:<w$}  {:<22}  {:>13}  {:>7}  {:>7}  {:>6}\n",
        "node", "progress", "cached", "missing", "running", "queued"
    );
    for l in lines {
        let filled = (l.cached * 20).checked_div(l.instances).unwrap_or(20);
        let bar = format!("[{}{}]", "#".repeat(filled), ".".repeat(20 - filled));
        let farm = |x: Option<usize>| x.map_or("-".to_string(), |n| n.to_string());
        out.push_str(&format!(
            "{:<w$}  {bar}  {:>13}  {:>7}  {:>7}  {:>6}\n",
            l.id,
            format!("{}/{}", l.cached, l.instances),
            l.missing,
            farm(l.running),
            farm(l.queued)
        ));
    }
    let (c, t) = lines
        .iter()
        .fold((0, 0), |(c, t), l| (c + l.cached, t + l.instances));
    out.push_str(&format!("{c}/{t} instances cached\n"));
    out
}
