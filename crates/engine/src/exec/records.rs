//! Rerun records: the components of each instance's last key (`records/<node>/<frame>.json`)
//! and of its node (`records/<node>/node.json`), kept to explain why an instance must run
//! again (read when planning or running, written at the end of a run), and to find the last
//! run's entry of an instance ([`last_run_entry`]).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::instances::DepKind;
use super::keys::{KeyParts, Miss};
use super::schedule::Runner;
use super::setup::RunSetup;
use crate::artifact::Digest;
use crate::graph::Graph;
use crate::store::{ActionEntry, Store};

/// The components of a cache key, kept to explain the next rerun.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub(super) struct InstanceRecord {
    pub(super) key: String,
    pub(super) inputs: BTreeMap<String, String>,
    pub(super) files: BTreeMap<String, String>,
}

/// The node-wide part of the last run's key components (`records/<node>/node.json`); each
/// instance's part is a file of its own beside it (`records/<node>/<frame>.json`), so
/// concurrent runs of different frames never rewrite one shared file.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub(super) struct NodeRecord {
    node_type: String,
    version: u32,
    params: BTreeMap<String, String>,
    seed: Option<u64>,
}

/// The record file stem of an instance: its frame, or `once`.
pub(super) fn frame_key(frame: Option<i64>) -> String {
    frame.map_or_else(|| "once".to_string(), |f| f.to_string())
}

/// Replaces record `name` with `value` unless it already holds it (a failure is only logged:
/// records explain reruns, they never decide them).
pub(super) fn put_if_changed<T>(store: &Store, name: &str, value: &T)
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
/// stale; [`plan`](super::plan()) says whether it still is the current one.
pub fn last_run_entry(
    graph: &Graph,
    store: &Store,
    node: usize,
    frame: Option<i64>,
) -> Option<ActionEntry> {
    let dir = record_dir(graph, node);
    let meta: NodeRecord = store.get_record(&format!("{dir}/node.json"))?;
    if meta.node_type != graph.nodes[node].spec().name {
        return None;
    }
    let rec: InstanceRecord = store.get_record(&format!("{dir}/{}.json", frame_key(frame)))?;
    store.get_action(&Digest::from_hex(&rec.key)?)
}

impl RunSetup<'_> {
    /// The record folder of a node (per graph file and node id), relative to `records/`.
    pub(super) fn record_dir(&self, node: usize) -> String {
        record_dir(self.graph, node)
    }

    pub(super) fn node_record_name(&self, node: usize) -> String {
        format!("{}/node.json", self.record_dir(node))
    }

    fn inst_record_name(&self, node: usize, frame: Option<i64>) -> String {
        format!("{}/{}.json", self.record_dir(node), frame_key(frame))
    }

    /// The node-wide record of this run: what [`NodeRecord`] stores.
    pub(super) fn node_record(&self, node: usize) -> NodeRecord {
        let spec = self.graph.nodes[node].spec();
        NodeRecord {
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
            .filter(|p| !p.cosmetic)
            .filter_map(|p| {
                gn.params
                    .get(p.name)
                    .map(|v| (p.name.to_string(), v.to_string()))
            })
            .collect()
    }

    /// Why instance `i` must run, comparing its key parts with the node's last record.
    pub(super) fn explain(&self, i: usize, parts: &KeyParts, miss: &Miss) -> String {
        if let Some(why) = miss.reason() {
            return why.to_string();
        }
        let node = self.insts[i].node;
        let Some(old) = self.old_node_record(node) else {
            return "no cache entry (first run)".into();
        };
        let mut why = self.node_changes(node, &old);
        let old_inst = self.store.as_ref().and_then(|s| {
            s.get_record::<InstanceRecord>(&self.inst_record_name(node, self.insts[i].frame))
        });
        if let Some(oi) = old_inst {
            self.instance_changes(i, parts, &oi, &mut why);
        } else if why.is_empty() {
            why.push("no cache entry for this frame".into());
        }
        if why.is_empty() {
            "no cache entry (evicted or never stored)".into()
        } else {
            why.join("; ")
        }
    }

    /// The last run's record of node `node`, read from the store once per plan or run.
    fn old_node_record(&self, node: usize) -> Option<NodeRecord> {
        let mut cache = self.old_records.lock().expect("records lock");
        cache
            .entry(node)
            .or_insert_with(|| {
                self.store
                    .as_ref()
                    .and_then(|s| s.get_record::<NodeRecord>(&self.node_record_name(node)))
            })
            .clone()
    }

    /// What changed in node `node` since record `old`: version, params, seed.
    fn node_changes(&self, node: usize, old: &NodeRecord) -> Vec<String> {
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
        why
    }

    /// What changed in instance `i`'s inputs and input files since record `oi`.
    fn instance_changes(
        &self,
        i: usize,
        parts: &KeyParts,
        oi: &InstanceRecord,
        why: &mut Vec<String>,
    ) {
        for (port, d) in &parts.record.inputs {
            if oi.inputs.get(port) != Some(d) {
                let src = self.input_source(i, port);
                why.push(format!("input `{port}` changed{src}"));
            }
        }
        for (path, d) in &parts.record.files {
            if oi.files.get(path) != Some(d) {
                why.push(format!("input file {path} changed"));
            }
        }
    }

    /// ` (from `node.port`)` naming the producer of instance `i`'s input `port`.
    fn input_source(&self, i: usize, port: &str) -> String {
        self.insts[i]
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
            .unwrap_or_default()
    }
}

impl Runner<'_> {
    /// Keeps instance `i`'s key components, to be saved at the end of the run.
    pub(super) fn remember(&self, i: usize, record: InstanceRecord) {
        let inst = &self.setup.insts[i];
        self.new_records
            .lock()
            .expect("records lock")
            .entry(inst.node)
            .or_default()
            .insert(frame_key(inst.frame), record);
    }

    /// Writes the key components of this run's instances: each record file is replaced
    /// whole (atomically) and only when it changed; no file is merged with another run's.
    pub(super) fn save_records(&self) {
        let Some(store) = &self.setup.store else {
            return;
        };
        let new = std::mem::take(&mut *self.new_records.lock().expect("records lock"));
        for (node, instances) in new {
            put_if_changed(
                store,
                &self.setup.node_record_name(node),
                &self.setup.node_record(node),
            );
            let dir = self.setup.record_dir(node);
            for (frame, rec) in instances {
                put_if_changed(store, &format!("{dir}/{frame}.json"), &rec);
            }
        }
    }
}
