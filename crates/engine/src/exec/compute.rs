//! Computing one instance: its inputs materialized, its node run on a [`Context`] (a panic
//! becomes an error), its outputs collected, and the result stored (objects, then the action
//! entry).

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use super::instances::{frame_suffix, DepKind};
use super::keys::uncached_digest;
use super::schedule::Runner;
use super::seed_for;
use super::setup::RunSetup;
use super::RunOptions;
use crate::artifact::{Digest, Value};
use crate::graph::{Graph, GraphNode};
use crate::node::{Context, InputValue, NodeSpec};
use crate::store::{ActionEntry, ActionOutput, WrittenFile};
use crate::stream::Deferred;

/// What a node computed.
pub(super) struct Computed {
    pub(super) outputs: BTreeMap<&'static str, (Value, Vec<u8>)>,
    /// Files declared by the node while running, with their digests.
    pub(super) read_files: Vec<(PathBuf, Digest)>,
    /// Files the node wrote through `Context::write_file`.
    pub(super) written_files: Vec<PathBuf>,
}

impl Runner<'_> {
    /// Runs the node of instance `i` on its (materialized) inputs.
    pub(super) fn compute(&self, i: usize) -> Result<Computed, String> {
        let inst = &self.setup.insts[i];
        let graph = self.setup.graph;
        let gn = &graph.nodes[inst.node];
        let inputs = self.gather_inputs(i)?;
        let (node_idx, frame) = (inst.node, inst.frame);
        let progress = move |f: f32| self.observer.progress(node_idx, frame, f);
        run_on(graph, gn, frame, inputs, &progress, &self.cancel)
    }

    /// The input values of instance `i`, by port: a streamed port's frames are read when
    /// the node asks for them, the others' now.
    fn gather_inputs(&self, i: usize) -> Result<BTreeMap<&'static str, InputValue<'_>>, String> {
        let mut inputs = BTreeMap::new();
        let spec = self.setup.graph.nodes[self.setup.insts[i].node].spec();
        for d in &self.setup.insts[i].deps {
            let streamed = spec.inputs.iter().any(|p| p.name == d.port && p.streamed);
            let v = match &d.kind {
                DepKind::One(j) => InputValue::One(self.value(*j, d.from_port)?),
                DepKind::Seq(r) if streamed => InputValue::Streamed(
                    r.clone()
                        .map(|j| {
                            let read = move || self.value(j, d.from_port);
                            (self.setup.insts[j].frame.unwrap_or(0), Deferred::new(read))
                        })
                        .collect(),
                ),
                // In parallel: values not in memory are loaded or computed (an uncached
                // reader's frames are decoded here).
                DepKind::Seq(r) => InputValue::Sequence(
                    r.clone()
                        .into_par_iter()
                        .map(|j| {
                            self.value(j, d.from_port)
                                .map(|v| (self.setup.insts[j].frame.unwrap_or(0), v))
                        })
                        .collect::<Result<_, _>>()?,
                ),
            };
            inputs.insert(d.port, v);
        }
        Ok(inputs)
    }

    /// Stores a computed instance: its objects (none for an uncached node), then its action
    /// entry. An error (e.g. a full disk) names the file it could not write.
    pub(super) fn store_outputs(
        &self,
        i: usize,
        key: &Digest,
        computed: &Computed,
        seconds: f64,
    ) -> std::io::Result<()> {
        let Some(store) = &self.setup.store else {
            return Ok(());
        };
        let inst = &self.setup.insts[i];
        let gn = &self.setup.graph.nodes[inst.node];
        let mut outs = Vec::new();
        for (port, (v, bytes)) in &computed.outputs {
            store.put_object(&v.digest(), v.type_name(), bytes)?;
            outs.push(ActionOutput {
                port: port.to_string(),
                ty: v.type_name().to_string(),
                digest: v.digest().to_hex(),
            });
        }
        let files = self.written_files(i)?;
        let node_files = computed
            .written_files
            .iter()
            .filter(|p| !files.iter().any(|f| &f.path == *p))
            .map(|p| self.hashed(p))
            .collect::<std::io::Result<_>>()?;
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
                node_files,
                seconds,
            },
        )
    }

    /// Stores the action entry of an uncached instance, its outputs named `digests` (no
    /// objects, no files: an uncached node writes none).
    pub(super) fn store_uncached(
        &self,
        i: usize,
        key: &Digest,
        digests: &BTreeMap<&'static str, Digest>,
    ) -> std::io::Result<()> {
        let Some(store) = &self.setup.store else {
            return Ok(());
        };
        let inst = &self.setup.insts[i];
        let gn = &self.setup.graph.nodes[inst.node];
        let outputs = gn
            .spec()
            .outputs
            .iter()
            .map(|p| ActionOutput {
                port: p.name.to_string(),
                ty: p.ty.to_string(),
                digest: digests[p.name].to_hex(),
            })
            .collect();
        let entry = ActionEntry {
            node_type: gn.spec().name.to_string(),
            node_id: gn.id.clone(),
            frame: inst.frame,
            outputs,
            files: Vec::new(),
            read_files: Vec::new(),
            node_files: Vec::new(),
            seconds: 0.0,
        };
        store.put_action(key, &entry)
    }

    /// The files of instance `i`'s output path params, with their digests.
    fn written_files(&self, i: usize) -> std::io::Result<Vec<WrittenFile>> {
        self.setup
            .output_files(i)
            .iter()
            .map(|p| self.hashed(p))
            .collect()
    }

    /// File `path` with its digest; the error names the file.
    fn hashed(&self, path: &Path) -> std::io::Result<WrittenFile> {
        let d = self.setup.hasher.hash(path).map_err(|e| {
            std::io::Error::new(e.kind(), format!("cannot hash {}: {e}", path.display()))
        })?;
        Ok(WrittenFile {
            path: path.to_path_buf(),
            digest: d.to_hex(),
        })
    }
}

/// Runs node `gn` of `graph` for `frame` on `inputs`: what it computed.
fn run_on(
    graph: &Graph,
    gn: &GraphNode,
    frame: Option<i64>,
    inputs: BTreeMap<&'static str, InputValue<'_>>,
    progress: &(dyn Fn(f32) + Sync),
    cancel: &AtomicBool,
) -> Result<Computed, String> {
    let mut ctx = Context {
        node_id: &gn.id,
        frame,
        params: &gn.params,
        spec: gn.spec(),
        graph_dir: &graph.dir,
        inputs,
        seed: seed_for(graph.seed, &gn.id, frame),
        progress,
        cancel,
        outputs: BTreeMap::new(),
        read_files: Vec::new(),
        written_files: Vec::new(),
    };
    run_node(gn, &mut ctx)?;
    collect_outputs(gn.spec(), &mut ctx)
}

/// Runs `gn`'s node on `ctx`; a panic becomes an error.
fn run_node(gn: &GraphNode, ctx: &mut Context) -> Result<(), String> {
    match catch_unwind(AssertUnwindSafe(|| gn.node.run(ctx))) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(e.message),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(format!("internal error (panic) in node: {msg}"))
        }
    }
}

/// What the node on `ctx` computed: every output `spec` declares, and the files it read.
fn collect_outputs(spec: &NodeSpec, ctx: &mut Context) -> Result<Computed, String> {
    let mut out = Computed {
        outputs: BTreeMap::new(),
        read_files: std::mem::take(&mut ctx.read_files),
        written_files: std::mem::take(&mut ctx.written_files),
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

/// Output `port` of instance `frame` of the uncached node `node` (see
/// [`NodeSpec::uncached`]), computed outside a run — for a viewer showing what the last run
/// read — after checking that its files still name the output `digest` that run recorded.
pub fn recompute_uncached(
    graph: &Graph,
    node: usize,
    frame: Option<i64>,
    port: &str,
    digest: &Digest,
) -> Result<Value, String> {
    let gn = graph
        .nodes
        .get(node)
        .ok_or_else(|| format!("no node {node} in the graph"))?;
    if gn.spec().cache_outputs || !gn.spec().inputs.is_empty() {
        return Err(format!("`{}` is not an uncached reader", gn.id));
    }
    let c = RunSetup::new(graph, &RunOptions::default()).map_err(|e| e.to_string())?;
    let i = (0..c.insts.len())
        .find(|&i| c.insts[i].node == node && c.insts[i].frame == frame)
        .ok_or_else(|| format!("`{}` has no instance{}", gn.id, frame_suffix(frame)))?;
    let key = c.key(i, |_, _| None)?.key;
    if uncached_digest(&key, port) != *digest {
        return Err(format!(
            "`{}`'s files changed since the run; run again",
            gn.id
        ));
    }
    let cancel = AtomicBool::new(false);
    let (v, _) = run_on(graph, gn, frame, BTreeMap::new(), &|_| {}, &cancel)?
        .outputs
        .remove(port)
        .ok_or_else(|| format!("`{}` has no output `{port}`", gn.id))?;
    Ok(v.named(*digest))
}
