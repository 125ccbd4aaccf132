//! What planning and running share: the graph's instances and their roles, the store (if a
//! cache is used), the file hasher, the forced nodes, and the files an instance's path params
//! name.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Mutex;

use super::instances::{expand, roles, Inst, Role};
use super::records::NodeRecord;
use super::{ExecError, RunOptions};
use crate::fsutil::FileHasher;
use crate::graph::Graph;
use crate::node::resolve_path;
use crate::param::PathRole;
use crate::store::Store;

/// The state a plan or a run starts from.
pub(super) struct RunSetup<'a> {
    pub(super) graph: &'a Graph,
    pub(super) insts: Vec<Inst>,
    pub(super) hasher: FileHasher,
    pub(super) store: Option<Store>,
    /// Per node: `--force`d.
    pub(super) forced: Vec<bool>,
    /// Per instance.
    pub(super) role: Vec<Role>,
    /// The last run's node-wide records, read once per node.
    pub(super) old_records: Mutex<HashMap<usize, Option<NodeRecord>>>,
}

impl<'a> RunSetup<'a> {
    pub(super) fn new(graph: &'a Graph, opts: &RunOptions) -> Result<Self, ExecError> {
        let (insts, _) = expand(graph);
        let store = open_store(opts)?;
        let hasher = match &store {
            Some(s) => FileHasher::persistent(s.file_memo_path()),
            None => FileHasher::in_memory(),
        };
        let forced = forced_nodes(graph, opts)?;
        let role = roles(graph, &insts, opts.only.as_deref())?;
        Ok(RunSetup {
            graph,
            role,
            insts,
            hasher,
            store,
            forced,
            old_records: Mutex::new(HashMap::new()),
        })
    }

    /// The files named by the path and path-list params of `role`, resolved, with the param
    /// naming each. An empty path (the default of an optional path param) names no file.
    pub(super) fn role_files(&self, i: usize, role: PathRole) -> Vec<(&'static str, PathBuf)> {
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

    /// The input files of instance `i`, with the param naming each.
    pub(super) fn input_files(&self, i: usize) -> Vec<(&'static str, PathBuf)> {
        self.role_files(i, PathRole::Input)
    }

    /// The files instance `i` writes.
    pub(super) fn output_files(&self, i: usize) -> Vec<PathBuf> {
        self.role_files(i, PathRole::Output)
            .into_iter()
            .map(|(_, p)| p)
            .collect()
    }
}

/// The store of `opts.cache_dir`, if any.
fn open_store(opts: &RunOptions) -> Result<Option<Store>, ExecError> {
    match &opts.cache_dir {
        Some(dir) => Ok(Some(Store::open(dir).map_err(|source| {
            ExecError::Cache {
                path: dir.clone(),
                source,
            }
        })?)),
        None => Ok(None),
    }
}

/// Per node of `graph`: whether `opts.force` names it.
fn forced_nodes(graph: &Graph, opts: &RunOptions) -> Result<Vec<bool>, ExecError> {
    let mut forced = vec![false; graph.nodes.len()];
    for f in &opts.force {
        let i = graph
            .index_of(f)
            .ok_or_else(|| ExecError::UnknownForce(f.clone()))?;
        forced[i] = true;
    }
    Ok(forced)
}
