//! Graph files: parsing, overrides and validation into a checked [`Graph`].
//!
//! ```yaml
//! version: 1
//! frames: 0..=239          # optional; needed by per-frame nodes
//! seed: 7                  # optional, default 0
//! defaults:                # optional: a param's value in every node that has it and
//!   working_space: acescg  #   does not set it (its own params and --set win)
//! nodes:
//!   plate: { type: read_image_sequence, params: { path: "plate/%04d.png" } }
//!   bright: { type: exposure, inputs: { image: plate.sequence }, params: { stops: 1 } }
//! ```
//!
//! Validation reports every problem at once, each at its file:line:column.
//!
//! [`parse`] drives the checks, one concept per module:
//! - `document`: the top-level mapping (`version`, `frames` or `--frames`, `seed`,
//!   `defaults`, `nodes`).
//! - `nodes`: node entries — ids, keys, types.
//! - `params`: params from the file, `--set` overrides, defaults and required params.
//! - `edges`: input references, required inputs, and the type check of each connection.
//! - `order`: cycles, the topological order, and the checked nodes in that order.
//! - `per_frame`: which nodes run per frame, resolved in topological order.

pub use limits::{Limits, DEFAULT_MAX_INSTANCES, DEFAULT_MAX_INSTANCE_GIB};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::diagnostic::{Diagnostics, ErrorKind, Span};
use crate::frames::FrameSet;
use crate::node::{Node, NodeSpec};
use crate::param::{ParamValue, Params};
use crate::registry::Registry;
use crate::yaml;

mod document;
mod edges;
mod limits;
mod nodes;
mod order;
mod params;
mod per_frame;

/// A checked graph, nodes in a topological order.
#[derive(Clone)]
pub struct Graph {
    /// The graph file.
    pub file: PathBuf,
    /// Its folder: relative paths in params resolve against it.
    pub dir: PathBuf,
    /// The file's text.
    pub source: Arc<str>,
    /// Frames of per-frame nodes.
    pub frames: FrameSet,
    /// The graph seed.
    pub seed: u64,
    /// Nodes in topological order (producers before consumers).
    pub nodes: Vec<GraphNode>,
}

/// One node of a checked graph.
#[derive(Clone)]
pub struct GraphNode {
    /// Its id.
    pub id: String,
    /// Its type.
    pub node: Arc<dyn Node>,
    /// Checked params, defaults filled in.
    pub params: Params,
    /// True if it has one instance per frame.
    pub per_frame: bool,
    /// Connected inputs.
    pub inputs: Vec<Edge>,
    /// Where the node is declared.
    pub span: Span,
}

impl GraphNode {
    /// The node type's declaration.
    pub fn spec(&self) -> &NodeSpec {
        self.node.spec()
    }
}

/// A connection into a node's input port.
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    /// The input port.
    pub port: &'static str,
    /// Index of the producing node in [`Graph::nodes`].
    pub from: usize,
    /// The producer's output port.
    pub from_port: &'static str,
    /// True if the input takes the producer's whole sequence.
    pub whole_sequence: bool,
}

impl Graph {
    /// Index of a node by id.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.id == id)
    }

    /// Number of instances of a node: one per frame for a per-frame node, else one.
    pub fn instances_of(&self, node: &GraphNode) -> usize {
        if node.per_frame {
            self.frames.len()
        } else {
            1
        }
    }

    /// Number of instances of the whole graph.
    pub fn instance_count(&self) -> usize {
        self.nodes.iter().map(|n| self.instances_of(n)).sum()
    }
}

/// Command-line changes applied on top of the file.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// `--set node.param=value`, in order.
    pub set: Vec<String>,
    /// `--frames R`.
    pub frames: Option<String>,
    /// Parameter values from the command line for every node that has the parameter and
    /// leaves it unset (e.g. `--ocio FILE`): above the graph's `defaults:`, below a node's own
    /// value and `--set`; a name no node of the graph has is ignored.
    pub defaults: Vec<(String, ParamValue)>,
}

/// Why a graph could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("cannot read graph file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file has problems.
    #[error("{0}")]
    Invalid(Diagnostics),
}

/// Reads and validates a graph file.
pub fn load(path: &Path, registry: &Registry, overrides: &Overrides) -> Result<Graph, LoadError> {
    let text = std::fs::read_to_string(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(path, &text, registry, overrides).map_err(LoadError::Invalid)
}

/// Validates graph text as if it were the file `path`.
pub fn parse(
    path: &Path,
    text: &str,
    registry: &Registry,
    overrides: &Overrides,
) -> Result<Graph, Diagnostics> {
    let source: Arc<str> = Arc::from(text);
    let mut d = Diagnostics::new(path.to_path_buf(), source.clone());
    let dir = graph_dir(path);
    let root = match yaml::parse(text) {
        Ok(r) => r,
        Err(e) => {
            d.push(ErrorKind::Syntax, Some(e.span), e.message);
            return Err(d);
        }
    };
    let Some(doc) = document::read(&root, overrides, &mut d) else {
        return Err(d);
    };
    // Pass 1: ids, types, params, raw input references; then overrides and defaults.
    let (mut raws, ids) = nodes::read(doc.nodes, registry, &mut d);
    params::apply_overrides(&mut raws, &overrides.set, &ids, &mut d);
    params::fill_defaults(&mut raws, &overrides.defaults, &doc.defaults, &mut d);
    // Pass 2: input references, then cycles, order and per-frame resolution.
    let edges = edges::connect(&raws, &mut d);
    let cyclic = order::find_cycles(&raws, &edges, &mut d);
    let order = order::topological(&edges, &cyclic);
    let per_frame = per_frame::resolve(&raws, &edges, &order, &cyclic, &doc.frames, &mut d);
    if !d.is_empty() {
        d.sort();
        return Err(d);
    }
    Ok(Graph {
        file: path.to_path_buf(),
        dir,
        source,
        frames: doc.frames,
        seed: doc.seed,
        nodes: order::checked_nodes(&raws, &edges, &order, &per_frame),
    })
}

/// The folder of graph file `path` (canonical if it can be), against which its relative
/// paths resolve.
fn graph_dir(path: &Path) -> PathBuf {
    let dir = path
        .parent()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .unwrap_or(Path::new("."));
    std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf())
}
