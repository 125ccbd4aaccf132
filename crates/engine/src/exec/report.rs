//! What a run or plan says about each instance (the `--json` schema), per-node totals, and
//! the [`Observer`] that receives a run's progress.

use serde::Serialize;

/// What happened to an instance in a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Served from the cache.
    Cached,
    /// Computed.
    Ran,
    /// Its node failed.
    Failed,
    /// Not run because an input failed.
    Skipped,
}

/// What a plan expects for an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanStatus {
    /// A valid cache entry exists.
    Cached,
    /// It will run (the reason says why).
    Run,
    /// It waits on an upstream instance that runs (early cutoff may still serve it from the
    /// cache), or it cannot run (e.g. a missing input file).
    Blocked,
}

/// One instance's line in a run or plan report (the `--json` schema).
#[derive(Clone, Debug, Serialize)]
pub struct InstanceReport<S> {
    /// Node id.
    pub id: String,
    /// Node type.
    #[serde(rename = "type")]
    pub node_type: String,
    /// Frame, or null for a node that runs once.
    pub frame: Option<i64>,
    /// Status.
    pub status: S,
    /// Why: the cache decision, the changed param or input, or the error.
    pub reason: String,
    /// Compute seconds (run: this run's; plan: the cached entry's, else 0).
    pub seconds: f64,
}

/// The result of a run.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport {
    /// One line per instance, in graph order.
    pub nodes: Vec<InstanceReport<Status>>,
    /// Wall-clock seconds of the whole run.
    pub wall_seconds: f64,
}

impl RunReport {
    /// True if any instance failed or was skipped.
    pub fn failed(&self) -> bool {
        self.nodes
            .iter()
            .any(|n| matches!(n.status, Status::Failed | Status::Skipped))
    }

    /// Instances of node `id` with the given status.
    pub fn count(&self, id: &str, status: Status) -> usize {
        self.nodes
            .iter()
            .filter(|n| n.id == id && n.status == status)
            .count()
    }

    /// Totals per node, in graph order.
    pub fn totals(&self) -> Vec<NodeTotals> {
        let mut out: Vec<NodeTotals> = Vec::new();
        for n in &self.nodes {
            if out.last().is_none_or(|t| t.id != n.id) {
                out.push(NodeTotals {
                    id: n.id.clone(),
                    ..Default::default()
                });
            }
            let t = out.last_mut().expect("pushed");
            t.instances += 1;
            match n.status {
                Status::Cached => t.cached += 1,
                Status::Ran => t.ran += 1,
                Status::Failed | Status::Skipped => t.failed += 1,
            }
            t.seconds += n.seconds;
        }
        out
    }
}

/// The result of planning.
#[derive(Clone, Debug, Serialize)]
pub struct PlanReport {
    /// One line per instance, in graph order.
    pub nodes: Vec<InstanceReport<PlanStatus>>,
}

/// Receives progress from a run (the CLI draws bars with it). All methods may be called from
/// any worker thread.
pub trait Observer: Sync {
    /// An instance starts computing (not called for cached ones).
    fn started(&self, _node: usize, _frame: Option<i64>) {}
    /// An instance reports progress in [0, 1].
    fn progress(&self, _node: usize, _frame: Option<i64>, _fraction: f32) {}
    /// An instance is resolved.
    fn finished(&self, _node: usize, _frame: Option<i64>, _status: Status, _seconds: f64) {}
}

/// An observer that ignores everything.
pub struct Quiet;
impl Observer for Quiet {}

/// Per-node totals of a run, for the closing table.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NodeTotals {
    /// Node id.
    pub id: String,
    /// Instances.
    pub instances: usize,
    /// Served from cache.
    pub cached: usize,
    /// Computed.
    pub ran: usize,
    /// Failed or skipped.
    pub failed: usize,
    /// Compute seconds, summed over instances.
    pub seconds: f64,
}
