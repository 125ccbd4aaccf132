//! Planning and running a graph: node instances, cache keys, the parallel scheduler.
//!
//! A graph expands into **instances**: one per node that runs once, one per frame for a
//! per-frame node. An instance's **cache key** is blake3 of the node type, its version, the
//! canonical values of the params that affect output, the content digests of its inputs (a
//! whole-sequence input contributes the digest of its element digests), the content digests of
//! the files it reads, the frame (per-frame instances) and — for seeded nodes — the graph seed
//! and node id. Keys are built from content digests, so an upstream rerun that produces the
//! same bytes leaves every key below unchanged (early cutoff).
//!
//! The scheduler runs instances on a rayon pool as soon as their inputs are resolved; nothing
//! waits on another instance's compute. Cached instances are resolved from their action entry
//! without loading values; values are loaded only when a consumer actually runs, and dropped
//! when the last consumer finishes.
//!
//! The parts, one concept each:
//! - `report`: what a run or plan says per instance ([`Status`], [`RunReport`], [`Observer`]…).
//! - `instances`: expanding a graph into instances and their dependencies; a selection's roles.
//! - `common`: what planning and running share (instances, store, file hasher, forced nodes).
//! - `keys`: an instance's cache key and the validity of its cache entry.
//! - `records`: the key components kept to explain the next rerun.
//! - `plan`: [`plan()`], deciding without running.
//! - `schedule`: [`run`], the parallel scheduler: each instance skipped, served from the cache
//!   or computed.
//! - `compute`: computing one instance (inputs, the node's run, outputs) and storing it.
//! - `values`: lazy loading of an upstream value (memory, store, else recompute).

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

mod compute;
mod instances;
mod keys;
mod plan;
mod records;
mod report;
mod schedule;
mod setup;
mod values;

pub use compute::recompute_uncached;
pub use plan::plan;
pub use records::last_run_entry;
pub use report::{
    InstanceReport, NodeTotals, Observer, PlanReport, PlanStatus, Quiet, RunReport, Status,
};
pub use schedule::run;

/// How to run or plan.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Worker threads (`None`: one per core).
    pub jobs: Option<usize>,
    /// Cache folder; `None` runs without reading or writing a cache.
    pub cache_dir: Option<PathBuf>,
    /// Node ids whose instances run even if cached.
    pub force: Vec<String>,
    /// Raised by the caller (e.g. on Ctrl-C) to stop the run: instances not yet started are
    /// skipped, running nodes see [`Context::cancelled`](crate::Context::cancelled) and may
    /// stop early (a node that stops reports an error, so nothing partial is cached).
    pub cancel: Option<Arc<AtomicBool>>,
    /// Run exactly these instances (`vfxgraph exec`, one farm task): every other instance
    /// they read must already be in the cache. Such an input is never computed; a miss fails
    /// naming it, and instances nobody selected are not visited. `None` runs the whole graph.
    pub only: Option<Vec<Target>>,
}

/// A selection of instances of one node: all of them, or some frames of a per-frame node.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    /// Node id.
    pub node: String,
    /// Frames (a per-frame node only); `None` selects every instance.
    pub frames: Option<Vec<i64>>,
}

/// Failure to start a run (node failures are reported per instance instead).
#[derive(Debug, thiserror::Error)]
pub enum ExecError {
    /// The cache folder cannot be opened.
    #[error("cannot open cache folder {path}: {source}")]
    Cache {
        /// Folder.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The thread pool cannot be built.
    #[error("cannot start {jobs} worker threads: {reason}")]
    Pool {
        /// Requested threads.
        jobs: usize,
        /// Cause.
        reason: String,
    },
    /// `--force` names no node.
    #[error("--force {0}: no such node in the graph")]
    UnknownForce(String),
    /// A target names no node.
    #[error("no node `{0}` in the graph")]
    UnknownNode(String),
    /// A target's frame is not one of the graph's.
    #[error("node `{node}`: frame {frame} is not in the graph's frames ({range})")]
    FrameOutOfRange {
        /// Node id.
        node: String,
        /// The frame asked for.
        frame: i64,
        /// The graph's frames.
        range: String,
    },
    /// Frames were given for a node that runs once.
    #[error("node `{0}` runs once, not per frame: frames do not apply to it")]
    NotPerFrame(String),
}

/// A 64-bit seed for (graph seed, node id, frame): independent of scheduling.
pub fn seed_for(graph_seed: u64, node_id: &str, frame: Option<i64>) -> u64 {
    let mut h = blake3::Hasher::new();
    h.update(b"vfxgraph-seed\0");
    h.update(&graph_seed.to_le_bytes());
    h.update(node_id.as_bytes());
    h.update(&[0]);
    if let Some(f) = frame {
        h.update(&f.to_le_bytes());
    }
    let b = h.finalize();
    u64::from_le_bytes(b.as_bytes()[..8].try_into().expect("8 bytes"))
}

/// The default cache folder for a graph file: `.vfxgraph/` beside it.
pub fn default_cache_dir(graph_file: &Path) -> PathBuf {
    graph_file
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .join(".vfxgraph")
}
