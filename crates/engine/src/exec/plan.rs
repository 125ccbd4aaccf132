//! Planning: which instances are cached, will run, or are blocked, decided without running
//! anything.

use std::collections::BTreeMap;

use super::instances::frame_suffix;
use super::report::{InstanceReport, PlanReport, PlanStatus};
use super::setup::RunSetup;
use super::{ExecError, RunOptions};
use crate::artifact::Digest;
use crate::graph::Graph;
use crate::store::ActionEntry;

/// The output digests of each instance the plan found cached.
type CachedDigests = Vec<Option<BTreeMap<String, Digest>>>;

/// Decides, without running anything, which instances are cached, will run, or are blocked.
pub fn plan(graph: &Graph, opts: &RunOptions) -> Result<PlanReport, ExecError> {
    let c = RunSetup::new(graph, opts)?;
    let n = c.insts.len();
    let mut status = vec![PlanStatus::Blocked; n];
    let mut digests: CachedDigests = vec![None; n];
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let line = plan_instance(&c, i, &status, &mut digests);
        status[i] = line.status;
        out.push(line);
    }
    c.hasher.save();
    Ok(PlanReport { nodes: out })
}

/// The plan of instance `i`, given the plan of the instances before it.
fn plan_instance(
    c: &RunSetup,
    i: usize,
    status: &[PlanStatus],
    digests: &mut CachedDigests,
) -> InstanceReport<PlanStatus> {
    let inst = &c.insts[i];
    let gn = &c.graph.nodes[inst.node];
    let mut line = InstanceReport {
        id: gn.id.clone(),
        node_type: gn.spec().name.to_string(),
        frame: inst.frame,
        status: PlanStatus::Blocked,
        reason: String::new(),
        seconds: 0.0,
    };
    if let Some(&j) = inst
        .upstream
        .iter()
        .find(|&&j| status[j] != PlanStatus::Cached)
    {
        line.reason = format!(
            "waits on `{}`{}",
            c.graph.nodes[c.insts[j].node].id,
            frame_suffix(c.insts[j].frame)
        );
        return line;
    }
    let key = c.key(i, |j, port| {
        digests[j].as_ref().and_then(|m| m.get(port).copied())
    });
    match key {
        Err(e) => line.reason = e,
        Ok(parts) => match c.lookup(i, &parts.key) {
            Ok(entry) => {
                line.status = PlanStatus::Cached;
                line.reason = "cache hit".into();
                line.seconds = entry.seconds;
                digests[i] = Some(output_digests(&entry));
            }
            Err(miss) => {
                line.status = PlanStatus::Run;
                line.reason = c.explain(i, &parts, &miss);
            }
        },
    }
    line
}

/// The output digests of a cache entry, by port.
fn output_digests(entry: &ActionEntry) -> BTreeMap<String, Digest> {
    entry
        .outputs
        .iter()
        .filter_map(|o| Digest::from_hex(&o.digest).map(|d| (o.port.clone(), d)))
        .collect()
}
