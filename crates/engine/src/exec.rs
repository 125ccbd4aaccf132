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

use std::collections::{BTreeMap, HashMap};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::artifact::{sequence_digest, Digest, Value};
use crate::fsutil::FileHasher;
use crate::graph::Graph;
use crate::node::{resolve_path, Context, InputValue};
use crate::param::PathRole;
use crate::registry::Registry;
use crate::store::{ActionEntry, ActionOutput, Store, WrittenFile};

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

// ---------------------------------------------------------------------------------------------
// Instances

#[derive(Clone, Debug)]
enum DepKind {
    One(usize),
    Seq(std::ops::Range<usize>),
}

#[derive(Clone, Debug)]
struct Dep {
    port: &'static str,
    from_port: &'static str,
    kind: DepKind,
}

#[derive(Clone, Debug)]
struct Inst {
    node: usize,
    frame: Option<i64>,
    deps: Vec<Dep>,
    /// Distinct instances this one reads.
    upstream: Vec<usize>,
    /// Distinct instances that read this one.
    downstream: Vec<usize>,
}

/// What a run does with an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    /// Served from the cache or computed.
    Compute,
    /// An input of a selected instance: served from the cache only.
    CacheOnly,
    /// Not selected and not read by a selected instance: not visited.
    Unneeded,
}

/// The role of each instance for a selection (`None`: everything computes).
fn roles(graph: &Graph, insts: &[Inst], only: Option<&[Target]>) -> Result<Vec<Role>, ExecError> {
    let Some(targets) = only else {
        return Ok(vec![Role::Compute; insts.len()]);
    };
    let mut role = vec![Role::Unneeded; insts.len()];
    for t in targets {
        let node = graph
            .index_of(&t.node)
            .ok_or_else(|| ExecError::UnknownNode(t.node.clone()))?;
        let frames = check_target_frames(graph, node, t)?;
        for (i, inst) in insts.iter().enumerate().filter(|(_, x)| x.node == node) {
            if frames
                .as_ref()
                .is_none_or(|fs| inst.frame.is_some_and(|f| fs.contains(&f)))
            {
                role[i] = Role::Compute;
            }
        }
    }
    // An instance's upstream comes before it in `insts`: one backward pass closes the set.
    for i in (0..insts.len()).rev() {
        if role[i] != Role::Unneeded {
            for &u in &insts[i].upstream {
                if role[u] == Role::Unneeded {
                    role[u] = Role::CacheOnly;
                }
            }
        }
    }
    Ok(role)
}

/// A target's frames, checked against the node's mode and the graph's frames.
fn check_target_frames(
    graph: &Graph,
    node: usize,
    t: &Target,
) -> Result<Option<Vec<i64>>, ExecError> {
    let Some(frames) = &t.frames else {
        return Ok(None);
    };
    if !graph.nodes[node].per_frame {
        return Err(ExecError::NotPerFrame(t.node.clone()));
    }
    if let Some(&frame) = frames.iter().find(|f| !graph.frames.frames().contains(f)) {
        return Err(ExecError::FrameOutOfRange {
            node: t.node.clone(),
            frame,
            range: graph.frames.to_string(),
        });
    }
    Ok(Some(frames.clone()))
}

fn expand(graph: &Graph) -> (Vec<Inst>, Vec<std::ops::Range<usize>>) {
    let frames = graph.frames.frames();
    let mut ranges = Vec::with_capacity(graph.nodes.len());
    let mut insts: Vec<Inst> = Vec::new();
    for (n, node) in graph.nodes.iter().enumerate() {
        let start = insts.len();
        let frame_list: Vec<Option<i64>> = if node.per_frame {
            frames.iter().map(|&f| Some(f)).collect()
        } else {
            vec![None]
        };
        for (fi, frame) in frame_list.into_iter().enumerate() {
            let mut deps = Vec::with_capacity(node.inputs.len());
            for e in &node.inputs {
                let r: &std::ops::Range<usize> = &ranges[e.from];
                let kind = if e.whole_sequence {
                    DepKind::Seq(r.clone())
                } else if graph.nodes[e.from].per_frame {
                    DepKind::One(r.start + fi)
                } else {
                    DepKind::One(r.start)
                };
                deps.push(Dep {
                    port: e.port,
                    from_port: e.from_port,
                    kind,
                });
            }
            let mut upstream: Vec<usize> = deps
                .iter()
                .flat_map(|d| match &d.kind {
                    DepKind::One(i) => *i..*i + 1,
                    DepKind::Seq(r) => r.clone(),
                })
                .collect();
            upstream.sort_unstable();
            upstream.dedup();
            insts.push(Inst {
                node: n,
                frame,
                deps,
                upstream,
                downstream: Vec::new(),
            });
        }
        ranges.push(start..insts.len());
    }
    for i in 0..insts.len() {
        for k in 0..insts[i].upstream.len() {
            let u = insts[i].upstream[k];
            insts[u].downstream.push(i);
        }
    }
    (insts, ranges)
}

// ---------------------------------------------------------------------------------------------
// Keys and records

/// The components of a cache key, kept to explain the next rerun.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
struct InstRecord {
    key: String,
    inputs: BTreeMap<String, String>,
    files: BTreeMap<String, String>,
}

/// The node-wide part of the last run's key components (`records/<node>/node.json`); each
/// instance's part is a file of its own beside it (`records/<node>/<frame>.json`), so
/// concurrent runs of different frames never rewrite one shared file.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
struct NodeMeta {
    node_type: String,
    version: u32,
    params: BTreeMap<String, String>,
    seed: Option<u64>,
}

fn frame_key(frame: Option<i64>) -> String {
    frame.map_or_else(|| "once".to_string(), |f| f.to_string())
}

struct KeyParts {
    key: Digest,
    record: InstRecord,
}

struct Common<'a> {
    graph: &'a Graph,
    insts: Vec<Inst>,
    hasher: FileHasher,
    store: Option<Store>,
    forced: Vec<bool>,
    role: Vec<Role>,
    old_records: Mutex<HashMap<usize, Option<NodeMeta>>>,
}

impl<'a> Common<'a> {
    fn new(graph: &'a Graph, opts: &RunOptions) -> Result<Self, ExecError> {
        let (insts, _) = expand(graph);
        let store = match &opts.cache_dir {
            Some(dir) => Some(Store::open(dir).map_err(|source| ExecError::Cache {
                path: dir.clone(),
                source,
            })?),
            None => None,
        };
        let hasher = match &store {
            Some(s) => FileHasher::persistent(s.file_memo_path()),
            None => FileHasher::in_memory(),
        };
        let mut forced = vec![false; graph.nodes.len()];
        for f in &opts.force {
            let i = graph
                .index_of(f)
                .ok_or_else(|| ExecError::UnknownForce(f.clone()))?;
            forced[i] = true;
        }
        let role = roles(graph, &insts, opts.only.as_deref())?;
        Ok(Common {
            graph,
            role,
            insts,
            hasher,
            store,
            forced,
            old_records: Mutex::new(HashMap::new()),
        })
    }

    /// The record folder of a node (per graph file and node id), relative to `records/`.
    fn record_dir(&self, node: usize) -> String {
        record_dir(self.graph, node)
    }

    fn meta_record_name(&self, node: usize) -> String {
        format!("{}/node.json", self.record_dir(node))
    }

    fn inst_record_name(&self, node: usize, frame: Option<i64>) -> String {
        format!("{}/{}.json", self.record_dir(node), frame_key(frame))
    }

    /// The node-wide record of this run: what [`NodeMeta`] stores.
    fn meta(&self, node: usize) -> NodeMeta {
        let spec = self.graph.nodes[node].spec();
        NodeMeta {
            node_type: spec.name.to_string(),
            version: spec.version,
            params: self.param_strings(node),
            seed: spec.seeded.then_some(self.graph.seed),
        }
    }

    fn param_strings(&self, node: usize) -> BTreeMap<String, String> {
        let gn = &self.graph.nodes[node];
        gn.spec()
            .params
            .iter()
            .filter(|p| p.affects_output)
            .filter_map(|p| {
                gn.params
                    .get(p.name)
                    .map(|v| (p.name.to_string(), v.to_string()))
            })
            .collect()
    }

    /// The files named by the path and path-list params of `role`, resolved, with the param
    /// naming each. An empty path (the default of an optional path param) names no file.
    fn role_files(&self, i: usize, role: PathRole) -> Vec<(&'static str, PathBuf)> {
        let inst = &self.insts[i];
        let gn = &self.graph.nodes[inst.node];
        let spec = gn.spec();
        let mut files: Vec<(&'static str, PathBuf)> = spec
            .path_params(role)
            .filter(|p| !gn.params.str(p).is_empty())
            .map(|p| {
                (
                    p,
                    resolve_path(&self.graph.dir, gn.params.str(p), inst.frame),
                )
            })
            .collect();
        for p in spec.path_list_params(role) {
            if gn.params.get(p).is_some() {
                files.extend(
                    gn.params
                        .strs(p)
                        .into_iter()
                        .map(|t| (p, resolve_path(&self.graph.dir, t, None))),
                );
            }
        }
        files
    }

    fn input_files(&self, i: usize) -> Vec<(&'static str, PathBuf)> {
        self.role_files(i, PathRole::Input)
    }

    fn output_files(&self, i: usize) -> Vec<PathBuf> {
        self.role_files(i, PathRole::Output)
            .into_iter()
            .map(|(_, p)| p)
            .collect()
    }

    /// Builds the key of instance `i` given a way to read upstream output digests.
    fn key(
        &self,
        i: usize,
        digest_of: impl Fn(usize, &str) -> Option<Digest>,
    ) -> Result<KeyParts, String> {
        let inst = &self.insts[i];
        let gn = &self.graph.nodes[inst.node];
        let spec = gn.spec();
        let mut h = blake3::Hasher::new();
        h.update(b"vfxgraph-key-v1\0");
        h.update(spec.name.as_bytes());
        h.update(&[0]);
        h.update(&spec.version.to_le_bytes());
        let mut buf = Vec::new();
        for p in spec.params.iter().filter(|p| p.affects_output) {
            if let Some(v) = gn.params.get(p.name) {
                buf.clear();
                v.canonical(&mut buf);
                h.update(p.name.as_bytes());
                h.update(&[0]);
                h.update(&buf);
            }
        }
        let mut record = InstRecord::default();
        for d in &inst.deps {
            let digest = match &d.kind {
                DepKind::One(j) => digest_of(*j, d.from_port)
                    .ok_or_else(|| format!("input `{}` has no value", d.port))?,
                DepKind::Seq(r) => {
                    let mut elems = Vec::with_capacity(r.len());
                    for j in r.clone() {
                        let dg = digest_of(j, d.from_port)
                            .ok_or_else(|| format!("input `{}` has no value", d.port))?;
                        elems.push((self.insts[j].frame.unwrap_or(0), dg));
                    }
                    sequence_digest(elems.iter().map(|(f, d)| (*f, d)))
                }
            };
            h.update(b"in\0");
            h.update(d.port.as_bytes());
            h.update(&[0]);
            h.update(&digest.0);
            record.inputs.insert(d.port.to_string(), digest.to_hex());
        }
        for (param, path) in self.input_files(i) {
            let digest = self.hasher.hash(&path).map_err(|e| {
                format!(
                    "param `{param}`: cannot read input file {}: {e}",
                    path.display()
                )
            })?;
            h.update(b"file\0");
            h.update(&digest.0);
            record
                .files
                .insert(path.display().to_string(), digest.to_hex());
        }
        if let Some(f) = inst.frame {
            h.update(b"frame\0");
            h.update(&f.to_le_bytes());
        }
        if spec.seeded {
            h.update(b"seed\0");
            h.update(&self.graph.seed.to_le_bytes());
            h.update(gn.id.as_bytes());
        }
        let key = Digest(*h.finalize().as_bytes());
        record.key = key.to_hex();
        Ok(KeyParts { key, record })
    }

    /// A valid cache entry for `key`: objects present, written files unchanged.
    fn lookup(&self, i: usize, key: &Digest) -> Result<ActionEntry, String> {
        let Some(store) = &self.store else {
            return Err("cache disabled".into());
        };
        if self.forced[self.insts[i].node] {
            return Err("forced".into());
        }
        let Some(entry) = store.get_action(key) else {
            return Err(String::new());
        };
        for o in &entry.outputs {
            match Digest::from_hex(&o.digest) {
                Some(d) if store.has_object(&d) => {}
                _ => return Err(format!("cached output `{}` is missing", o.port)),
            }
        }
        let expected = self.output_files(i);
        for f in &entry.files {
            match self.hasher.hash(&f.path) {
                Ok(d) if d.to_hex() == f.digest => {}
                Ok(_) => return Err(format!("output file {} was modified", f.path.display())),
                Err(_) => return Err(format!("output file {} is missing", f.path.display())),
            }
        }
        if expected.len() != entry.files.len() {
            return Err("output files differ from the cached entry".into());
        }
        for f in &entry.read_files {
            match self.hasher.hash(&f.path) {
                Ok(d) if d.to_hex() == f.digest => {}
                Ok(_) => return Err(format!("input file {} changed", f.path.display())),
                Err(_) => return Err(format!("input file {} is missing", f.path.display())),
            }
        }
        Ok(entry)
    }

    /// Why instance `i` must run, comparing its key parts with the node's last record.
    fn explain(&self, i: usize, parts: &KeyParts, miss: &str) -> String {
        if !miss.is_empty() {
            return miss.to_string();
        }
        let node = self.insts[i].node;
        let old = {
            let mut cache = self.old_records.lock().expect("records lock");
            cache
                .entry(node)
                .or_insert_with(|| {
                    self.store
                        .as_ref()
                        .and_then(|s| s.get_record::<NodeMeta>(&self.meta_record_name(node)))
                })
                .clone()
        };
        let Some(old) = old else {
            return "no cache entry (first run)".into();
        };
        let spec = self.graph.nodes[node].spec();
        let mut why = Vec::new();
        if old.version != spec.version {
            why.push(format!("node version {} → {}", old.version, spec.version));
        }
        let params = self.param_strings(node);
        for (k, v) in &params {
            match old.params.get(k) {
                Some(o) if o == v => {}
                Some(o) => why.push(format!("param `{k}` changed ({o} → {v})")),
                None => why.push(format!("param `{k}` is new ({v})")),
            }
        }
        if spec.seeded && old.seed != Some(self.graph.seed) {
            why.push("graph seed changed".into());
        }
        let old_inst = self.store.as_ref().and_then(|s| {
            s.get_record::<InstRecord>(&self.inst_record_name(node, self.insts[i].frame))
        });
        if let Some(oi) = old_inst {
            for (port, d) in &parts.record.inputs {
                if oi.inputs.get(port) != Some(d) {
                    let src = self.insts[i]
                        .deps
                        .iter()
                        .find(|x| x.port == port)
                        .map(|x| {
                            let j = match &x.kind {
                                DepKind::One(j) => *j,
                                DepKind::Seq(r) => r.start,
                            };
                            format!(
                                " (from `{}.{}`)",
                                self.graph.nodes[self.insts[j].node].id, x.from_port
                            )
                        })
                        .unwrap_or_default();
                    why.push(format!("input `{port}` changed{src}"));
                }
            }
            for (path, d) in &parts.record.files {
                if oi.files.get(path) != Some(d) {
                    why.push(format!("input file {path} changed"));
                }
            }
        } else if why.is_empty() {
            why.push("no cache entry for this frame".into());
        }
        if why.is_empty() {
            "no cache entry (evicted or never stored)".into()
        } else {
            why.join("; ")
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Plan

/// Decides, without running anything, which instances are cached, will run, or are blocked.
pub fn plan(graph: &Graph, opts: &RunOptions) -> Result<PlanReport, ExecError> {
    let c = Common::new(graph, opts)?;
    let n = c.insts.len();
    let mut status = vec![PlanStatus::Blocked; n];
    let mut digests: Vec<Option<BTreeMap<String, Digest>>> = vec![None; n];
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let inst = &c.insts[i];
        let gn = &graph.nodes[inst.node];
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
                graph.nodes[c.insts[j].node].id,
                c.insts[j]
                    .frame
                    .map(|f| format!(" frame {f}"))
                    .unwrap_or_default()
            );
        } else {
            match c.key(i, |j, port| {
                digests[j].as_ref().and_then(|m| m.get(port).copied())
            }) {
                Err(e) => line.reason = e,
                Ok(parts) => match c.lookup(i, &parts.key) {
                    Ok(entry) => {
                        line.status = PlanStatus::Cached;
                        line.reason = "cache hit".into();
                        line.seconds = entry.seconds;
                        digests[i] = Some(
                            entry
                                .outputs
                                .iter()
                                .filter_map(|o| {
                                    Digest::from_hex(&o.digest).map(|d| (o.port.clone(), d))
                                })
                                .collect(),
                        );
                    }
                    Err(miss) => {
                        line.status = PlanStatus::Run;
                        line.reason = c.explain(i, &parts, &miss);
                    }
                },
            }
        }
        status[i] = line.status;
        out.push(line);
    }
    c.hasher.save();
    Ok(PlanReport { nodes: out })
}

// ---------------------------------------------------------------------------------------------
// Run

struct Done {
    status: Status,
    reason: String,
    seconds: f64,
    digests: BTreeMap<&'static str, Digest>,
}

struct State {
    pending: AtomicUsize,
    consumers_left: AtomicUsize,
    done: OnceLock<Done>,
    values: Mutex<BTreeMap<&'static str, Value>>,
}

struct Runner<'a> {
    c: Common<'a>,
    cancel: Arc<AtomicBool>,
    registry: &'a Registry,
    state: Vec<State>,
    observer: &'a dyn Observer,
    new_records: Mutex<HashMap<usize, BTreeMap<String, InstRecord>>>,
}

/// Runs a graph: every instance is served from the cache or computed, in parallel. Node
/// failures do not abort the run: they are reported, their dependants skipped, and independent
/// branches finish (and are cached).
pub fn run(
    graph: &Graph,
    registry: &Registry,
    opts: &RunOptions,
    observer: &dyn Observer,
) -> Result<RunReport, ExecError> {
    let t0 = Instant::now();
    let c = Common::new(graph, opts)?;
    let state: Vec<State> = c
        .insts
        .iter()
        .map(|inst| State {
            pending: AtomicUsize::new(inst.upstream.len()),
            consumers_left: AtomicUsize::new(
                inst.downstream
                    .iter()
                    .filter(|&&d| c.role[d] != Role::Unneeded)
                    .count(),
            ),
            done: OnceLock::new(),
            values: Mutex::new(BTreeMap::new()),
        })
        .collect();
    let runner = Runner {
        c,
        cancel: opts.cancel.clone().unwrap_or_default(),
        registry,
        state,
        observer,
        new_records: Mutex::new(HashMap::new()),
    };
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(j) = opts.jobs {
        builder = builder.num_threads(j.max(1));
    }
    let pool = builder.build().map_err(|e| ExecError::Pool {
        jobs: opts.jobs.unwrap_or(0),
        reason: e.to_string(),
    })?;
    pool.install(|| {
        rayon::scope(|s| {
            for i in 0..runner.c.insts.len() {
                if runner.c.insts[i].upstream.is_empty() && runner.c.role[i] != Role::Unneeded {
                    runner.schedule(s, i);
                }
            }
        })
    });
    runner.save_records();
    runner.c.hasher.save();
    let nodes = runner
        .c
        .insts
        .iter()
        .enumerate()
        .filter(|(i, _)| runner.c.role[*i] != Role::Unneeded)
        .map(|(i, inst)| {
            let gn = &graph.nodes[inst.node];
            let d = runner.state[i].done.get();
            InstanceReport {
                id: gn.id.clone(),
                node_type: gn.spec().name.to_string(),
                frame: inst.frame,
                status: d.map_or(Status::Skipped, |d| d.status),
                reason: d.map_or_else(|| "not reached".to_string(), |d| d.reason.clone()),
                seconds: d.map_or(0.0, |d| d.seconds),
            }
        })
        .collect();
    Ok(RunReport {
        nodes,
        wall_seconds: t0.elapsed().as_secs_f64(),
    })
}

struct Computed {
    outputs: BTreeMap<&'static str, (Value, Vec<u8>)>,
    /// Files declared by the node while running, with their digests.
    read_files: Vec<(PathBuf, Digest)>,
}

impl<'a> Runner<'a> {
    fn schedule<'s>(&'s self, s: &rayon::Scope<'s>, i: usize) {
        s.spawn(move |s| {
            self.resolve(i);
            for &u in &self.c.insts[i].upstream {
                if self.state[u].consumers_left.fetch_sub(1, Ordering::AcqRel) == 1 {
                    self.state[u].values.lock().expect("values lock").clear();
                }
            }
            for &d in &self.c.insts[i].downstream {
                if self.c.role[d] != Role::Unneeded
                    && self.state[d].pending.fetch_sub(1, Ordering::AcqRel) == 1
                {
                    self.schedule(s, d);
                }
            }
        });
    }

    fn finish(&self, i: usize, done: Done) {
        let inst = &self.c.insts[i];
        self.observer
            .finished(inst.node, inst.frame, done.status, done.seconds);
        let _ = self.state[i].done.set(done);
    }

    fn resolve(&self, i: usize) {
        let inst = &self.c.insts[i];
        let graph = self.c.graph;
        if self.cancel.load(Ordering::Relaxed) {
            self.finish(
                i,
                Done {
                    status: Status::Skipped,
                    reason: "run cancelled".into(),
                    seconds: 0.0,
                    digests: BTreeMap::new(),
                },
            );
            return;
        }
        // Skip if an input failed.
        if let Some(&j) = inst.upstream.iter().find(|&&j| {
            self.state[j]
                .done
                .get()
                .is_none_or(|d| matches!(d.status, Status::Failed | Status::Skipped))
        }) {
            let up = &self.c.insts[j];
            let reason = format!(
                "upstream `{}`{} did not complete",
                graph.nodes[up.node].id,
                up.frame.map(|f| format!(" frame {f}")).unwrap_or_default()
            );
            self.finish(
                i,
                Done {
                    status: Status::Skipped,
                    reason,
                    seconds: 0.0,
                    digests: BTreeMap::new(),
                },
            );
            return;
        }
        let parts = match self.c.key(i, |j, port| {
            self.state[j]
                .done
                .get()
                .and_then(|d| d.digests.get(port).copied())
        }) {
            Ok(p) => p,
            Err(e) => {
                self.finish(
                    i,
                    Done {
                        status: Status::Failed,
                        reason: e,
                        seconds: 0.0,
                        digests: BTreeMap::new(),
                    },
                );
                return;
            }
        };
        let miss = match self.c.lookup(i, &parts.key) {
            Ok(entry) => {
                if let Some(store) = &self.c.store {
                    store.touch_action(&parts.key);
                }
                let spec = graph.nodes[inst.node].spec();
                let digests = spec
                    .outputs
                    .iter()
                    .filter_map(|p| {
                        entry
                            .outputs
                            .iter()
                            .find(|o| o.port == p.name)
                            .and_then(|o| Digest::from_hex(&o.digest))
                            .map(|d| (p.name, d))
                    })
                    .collect();
                self.remember(i, parts.record);
                self.finish(
                    i,
                    Done {
                        status: Status::Cached,
                        reason: "cache hit".into(),
                        seconds: 0.0,
                        digests,
                    },
                );
                return;
            }
            Err(m) => m,
        };
        if self.c.role[i] == Role::CacheOnly {
            let why = if miss.is_empty() { "no entry" } else { &miss };
            self.finish(
                i,
                Done {
                    status: Status::Failed,
                    reason: format!(
                        "an input of the selected instances is not in the cache ({why}); \
                         it must run first (a missing farm dependency, or a cleaned cache)"
                    ),
                    seconds: 0.0,
                    digests: BTreeMap::new(),
                },
            );
            return;
        }
        let reason = self.c.explain(i, &parts, &miss);
        self.observer.started(inst.node, inst.frame);
        let t = Instant::now();
        match self.compute(i) {
            Ok(computed) => {
                let seconds = t.elapsed().as_secs_f64();
                let digests = computed
                    .outputs
                    .iter()
                    .map(|(k, (v, _))| (*k, v.digest()))
                    .collect();
                if let Err(e) = self.store_outputs(i, &parts.key, &computed, seconds) {
                    // The cache stays as it was (writes are atomic; an entry is written after
                    // its objects), and the run says so: exit code 1, not a silent miss.
                    self.finish(
                        i,
                        Done {
                            status: Status::Failed,
                            reason: format!("ran, but its result could not be cached: {e}"),
                            seconds,
                            digests: BTreeMap::new(),
                        },
                    );
                    return;
                }
                let outputs = computed.outputs;
                {
                    let mut vals = self.state[i].values.lock().expect("values lock");
                    if self.state[i].consumers_left.load(Ordering::Acquire) > 0 {
                        for (k, (v, _)) in outputs {
                            vals.insert(k, v);
                        }
                    }
                }
                self.remember(i, parts.record);
                self.finish(
                    i,
                    Done {
                        status: Status::Ran,
                        reason,
                        seconds,
                        digests,
                    },
                );
            }
            Err(e) => self.finish(
                i,
                Done {
                    status: Status::Failed,
                    reason: e,
                    seconds: t.elapsed().as_secs_f64(),
                    digests: BTreeMap::new(),
                },
            ),
        }
    }

    /// Runs the node of instance `i` on its (materialized) inputs.
    fn compute(&self, i: usize) -> Result<Computed, String> {
        let inst = &self.c.insts[i];
        let graph = self.c.graph;
        let gn = &graph.nodes[inst.node];
        let spec = gn.spec();
        let mut inputs = BTreeMap::new();
        for d in &inst.deps {
            let v = match &d.kind {
                DepKind::One(j) => InputValue::One(self.value(*j, d.from_port)?),
                DepKind::Seq(r) => InputValue::Sequence(
                    r.clone()
                        .map(|j| {
                            self.value(j, d.from_port)
                                .map(|v| (self.c.insts[j].frame.unwrap_or(0), v))
                        })
                        .collect::<Result<_, _>>()?,
                ),
            };
            inputs.insert(d.port, v);
        }
        let (node_idx, frame) = (inst.node, inst.frame);
        let progress = move |f: f32| self.observer.progress(node_idx, frame, f);
        let mut ctx = Context {
            node_id: &gn.id,
            frame: inst.frame,
            params: &gn.params,
            spec,
            graph_dir: &graph.dir,
            inputs,
            seed: seed_for(graph.seed, &gn.id, inst.frame),
            progress: &progress,
            cancel: &self.cancel,
            outputs: BTreeMap::new(),
            read_files: Vec::new(),
        };
        let result = catch_unwind(AssertUnwindSafe(|| gn.node.run(&mut ctx)));
        match result {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(e.message),
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "unknown panic".into());
                return Err(format!("internal error (panic) in node: {msg}"));
            }
        }
        let mut out = Computed {
            outputs: BTreeMap::new(),
            read_files: std::mem::take(&mut ctx.read_files),
        };
        for p in &spec.outputs {
            let Some(encoded) = ctx.outputs.remove(p.name) else {
                return Err(format!(
                    "node did not produce output `{}` (a bug in the node)",
                    p.name
                ));
            };
            out.outputs.insert(p.name, encoded);
        }
        Ok(out)
    }

    /// Stores a computed instance: its objects, then its action entry. An error (e.g. a full
    /// disk) names the file it could not write.
    fn store_outputs(
        &self,
        i: usize,
        key: &Digest,
        computed: &Computed,
        seconds: f64,
    ) -> std::io::Result<()> {
        let Some(store) = &self.c.store else {
            return Ok(());
        };
        let inst = &self.c.insts[i];
        let gn = &self.c.graph.nodes[inst.node];
        let mut outs = Vec::new();
        for (port, (v, bytes)) in &computed.outputs {
            store.put_object(&v.digest(), v.type_name(), bytes)?;
            outs.push(ActionOutput {
                port: port.to_string(),
                ty: v.type_name().to_string(),
                digest: v.digest().to_hex(),
            });
        }
        let mut files = Vec::new();
        for path in self.c.output_files(i) {
            let d = self.c.hasher.hash(&path).map_err(|e| {
                std::io::Error::new(e.kind(), format!("cannot hash {}: {e}", path.display()))
            })?;
            files.push(WrittenFile {
                path,
                digest: d.to_hex(),
            });
        }
        store.put_action(
            key,
            &ActionEntry {
                node_type: gn.spec().name.to_string(),
                node_id: gn.id.clone(),
                frame: inst.frame,
                outputs: outs,
                files,
                read_files: computed
                    .read_files
                    .iter()
                    .map(|(path, d)| WrittenFile {
                        path: path.clone(),
                        digest: d.to_hex(),
                    })
                    .collect(),
                seconds,
            },
        )
    }

    /// The value of output `port` of a resolved instance: in memory, else loaded from the
    /// store (verified), else recomputed.
    fn value(&self, j: usize, port: &str) -> Result<Value, String> {
        if let Some(v) = self.state[j].values.lock().expect("values lock").get(port) {
            return Ok(v.clone());
        }
        let done = self.state[j]
            .done
            .get()
            .ok_or_else(|| "internal: input read before it was resolved".to_string())?;
        let digest = *done
            .digests
            .get(port)
            .ok_or_else(|| format!("internal: no output `{port}`"))?;
        let keep = |k: &'static str, v: &Value| {
            if self.state[j].consumers_left.load(Ordering::Acquire) > 1 {
                self.state[j]
                    .values
                    .lock()
                    .expect("values lock")
                    .insert(k, v.clone());
            }
        };
        let static_port = self.c.graph.nodes[self.c.insts[j].node]
            .spec()
            .outputs
            .iter()
            .find(|p| p.name == port)
            .map(|p| p.name)
            .ok_or_else(|| format!("internal: unknown port `{port}`"))?;
        if let Some(store) = &self.c.store {
            if let Some((ty, bytes)) = store.get_object(&digest) {
                match self.registry.decode(&ty, &bytes) {
                    Ok(data) => {
                        let v = Value::from_parts(data, digest);
                        keep(static_port, &v);
                        return Ok(v);
                    }
                    Err(e) => tracing::warn!("cached {ty} {} does not decode: {e}", digest.short()),
                }
            }
        }
        // Lost from the cache (deleted or corrupt): recompute it. Deterministic nodes give the
        // same bytes; anything else is reported rather than silently mixed.
        let up = &self.c.insts[j];
        let id = &self.c.graph.nodes[up.node].id;
        if self.c.role[j] == Role::CacheOnly {
            return Err(format!(
                "the cached output `{port}` of `{id}`{} is missing from the cache, and only the \
                 selected instances may run",
                up.frame.map(|f| format!(" frame {f}")).unwrap_or_default()
            ));
        }
        tracing::info!("recomputing `{id}` (its cached output was lost)");
        let outputs = self.compute(j)?;
        let (v, bytes) = outputs
            .outputs
            .get(port)
            .ok_or_else(|| format!("internal: no output `{port}`"))?;
        if v.digest() != digest {
            return Err(format!(
                "the cached output of `{id}` was lost, and recomputing it gave different bytes \
                 (is the node deterministic?); run again"
            ));
        }
        if let Some(store) = &self.c.store {
            let _ = store.put_object(&digest, v.type_name(), bytes);
        }
        keep(static_port, v);
        Ok(v.clone())
    }

    fn remember(&self, i: usize, record: InstRecord) {
        let inst = &self.c.insts[i];
        self.new_records
            .lock()
            .expect("records lock")
            .entry(inst.node)
            .or_default()
            .insert(frame_key(inst.frame), record);
    }

    /// Writes the key components of this run's instances: each record file is replaced
    /// whole (atomically) and only when it changed; no file is merged with another run's.
    fn save_records(&self) {
        let Some(store) = &self.c.store else { return };
        let new = std::mem::take(&mut *self.new_records.lock().expect("records lock"));
        for (node, instances) in new {
            put_if_changed(store, &self.c.meta_record_name(node), &self.c.meta(node));
            let dir = self.c.record_dir(node);
            for (frame, rec) in instances {
                put_if_changed(store, &format!("{dir}/{frame}.json"), &rec);
            }
        }
    }
}

/// Replaces record `name` with `value` unless it already holds it (a failure is only logged:
/// records explain reruns, they never decide them).
fn put_if_changed<T>(store: &Store, name: &str, value: &T)
where
    T: Serialize + serde::de::DeserializeOwned + PartialEq,
{
    if store.get_record::<T>(name).as_ref() == Some(value) {
        return;
    }
    if let Err(e) = store.put_record(name, value) {
        tracing::warn!("cannot save rerun record: {e}");
    }
}

/// The record folder of `graph`'s node `node` (per graph file and node id), relative to the
/// store's `records/`.
fn record_dir(graph: &Graph, node: usize) -> String {
    let mut h = blake3::Hasher::new();
    h.update(graph.file.to_string_lossy().as_bytes());
    h.update(&[0]);
    h.update(graph.nodes[node].id.as_bytes());
    h.finalize().to_hex()[..32].to_string()
}

/// The action entry of the last run that resolved node `node`'s instance at `frame` (`None`
/// for a node that runs once), if that entry is still in the store: the outputs a viewer shows
/// (`vfxgraph serve`). It is the last *run*'s, which a later edit of the graph may have made
/// stale; [`plan`] says whether it still is the current one.
pub fn last_run_entry(
    graph: &Graph,
    store: &Store,
    node: usize,
    frame: Option<i64>,
) -> Option<ActionEntry> {
    let dir = record_dir(graph, node);
    let meta: NodeMeta = store.get_record(&format!("{dir}/node.json"))?;
    if meta.node_type != graph.nodes[node].spec().name {
        return None;
    }
    let rec: InstRecord = store.get_record(&format!("{dir}/{}.json", frame_key(frame)))?;
    store.get_action(&Digest::from_hex(&rec.key)?)
}

/// The default cache folder for a graph file: `.vfxgraph/` beside it.
pub fn default_cache_dir(graph_file: &Path) -> PathBuf {
    graph_file
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .join(".vfxgraph")
}

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

impl RunReport {
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
