//! Graph files: parsing, overrides and validation into a checked [`Graph`].
//!
//! ```yaml
//! version: 1
//! frames: 0..=239          # optional; needed by per-frame nodes
//! seed: 7                  # optional, default 0
//! nodes:
//!   plate: { type: read_image_sequence, params: { path: "plate/%04d.png" } }
//!   bright: { type: exposure, inputs: { image: plate.sequence }, params: { stops: 1 } }
//! ```
//!
//! Validation reports every problem at once, each at its file:line:column.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use petgraph::algo::tarjan_scc;
use petgraph::graphmap::DiGraphMap;

use crate::diagnostic::{suggest, Diagnostics, ErrorKind, Span};
use crate::frames::FrameSet;
use crate::node::{has_frame_pattern, Mode, Node, NodeSpec};
use crate::param::{ParamCheck, ParamValue, Params};
use crate::registry::Registry;
use crate::yaml::{self, resolve_scalar, Scalar, Yaml};

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
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());

    let root = match yaml::parse(text) {
        Ok(r) => r,
        Err(e) => {
            d.push(ErrorKind::Syntax, Some(e.span), e.message);
            return Err(d);
        }
    };
    let Some(top) = root.as_map() else {
        d.push(
            ErrorKind::Structure,
            Some(root.span),
            format!(
                "a graph file is a mapping with `version` and `nodes`, found {}",
                root.shape()
            ),
        );
        return Err(d);
    };

    let mut version = None;
    let mut frames_y = None;
    let mut seed = 0u64;
    let mut nodes_y = None;
    for (k, v) in top {
        match k.as_str().unwrap_or("") {
            "version" => version = Some(v),
            "frames" => frames_y = Some(v),
            "seed" => match v.as_str().map(|t| resolve_scalar(t, true)) {
                Some(Scalar::Int(s)) if s >= 0 => seed = s as u64,
                _ => d.push(
                    ErrorKind::Structure,
                    Some(v.span),
                    "`seed` must be a non-negative integer",
                ),
            },
            "nodes" => nodes_y = Some(v),
            "description" | "doc" => {}
            other => d.push_help(
                ErrorKind::Structure,
                Some(k.span),
                format!("unknown top-level key `{other}`"),
                suggest(other, ["version", "frames", "seed", "nodes", "description"]),
            ),
        }
    }
    match version {
        None => d.push(
            ErrorKind::Structure,
            Some(root.span),
            "missing `version: 1` at the top of the graph file",
        ),
        Some(v) => {
            if !matches!(
                v.as_str().map(|t| resolve_scalar(t, true)),
                Some(Scalar::Int(1))
            ) {
                d.push(
                    ErrorKind::Structure,
                    Some(v.span),
                    "unsupported graph format version (this vfxgraph reads `version: 1`)",
                );
            }
        }
    }

    let mut frames = FrameSet::default();
    if let Some(text) = &overrides.frames {
        match FrameSet::parse(text) {
            Ok(f) => frames = f,
            Err(e) => d.push(ErrorKind::Frames, None, format!("--frames: {e}")),
        }
    } else if let Some(fy) = frames_y {
        match fy.as_str() {
            Some(t) => match FrameSet::parse(t) {
                Ok(f) => frames = f,
                Err(e) => d.push(ErrorKind::Frames, Some(fy.span), e),
            },
            None => d.push(
                ErrorKind::Frames,
                Some(fy.span),
                "`frames` is a range such as `0..=239` or `1-10,15,20-40:2`",
            ),
        }
    }

    let Some(nodes_y) = nodes_y else {
        d.push(
            ErrorKind::Structure,
            Some(root.span),
            "missing `nodes:` mapping",
        );
        return Err(d);
    };
    let Some(node_entries) = nodes_y.as_map() else {
        d.push(
            ErrorKind::Structure,
            Some(nodes_y.span),
            format!(
                "`nodes` must be a mapping of node id to node, found {}",
                nodes_y.shape()
            ),
        );
        return Err(d);
    };

    // Pass 1: ids, types, params, raw input references.
    struct Raw<'y> {
        id: String,
        id_span: Span,
        node: Option<Arc<dyn Node>>,
        params: BTreeMap<String, ParamValue>,
        per_frame: Option<(bool, Span)>,
        inputs: Vec<(&'y Yaml, &'y Yaml)>,
        inputs_span: Span,
    }
    let mut raws: Vec<Raw> = Vec::new();
    let mut first_seen: HashMap<String, Span> = HashMap::new();
    for (k, v) in node_entries {
        let Some(id) = k.as_str() else {
            d.push(
                ErrorKind::Structure,
                Some(k.span),
                "a node id must be a plain name",
            );
            continue;
        };
        if let Some(first) = first_seen.get(id) {
            d.push(
                ErrorKind::DuplicateId,
                Some(k.span),
                format!(
                    "duplicate node id `{id}` (first declared on line {})",
                    first.line
                ),
            );
            continue;
        }
        first_seen.insert(id.to_string(), k.span);
        if id.is_empty()
            || !id
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        {
            d.push(
                ErrorKind::Structure,
                Some(k.span),
                format!("node id `{id}` may use only letters, digits, `_` and `-`"),
            );
        }
        let Some(body) = v.as_map() else {
            d.push(
                ErrorKind::Structure,
                Some(v.span),
                format!(
                    "node `{id}` must be a mapping with `type`, found {}",
                    v.shape()
                ),
            );
            continue;
        };
        let mut raw = Raw {
            id: id.to_string(),
            id_span: k.span,
            node: None,
            params: BTreeMap::new(),
            per_frame: None,
            inputs: Vec::new(),
            inputs_span: k.span,
        };
        let mut type_y = None;
        let mut params_y = None;
        for (bk, bv) in body {
            match bk.as_str().unwrap_or("") {
                "type" => type_y = Some(bv),
                "params" => params_y = Some(bv),
                "inputs" => {
                    raw.inputs_span = bk.span;
                    match bv.as_map() {
                        Some(m) => raw.inputs = m.iter().map(|(a, b)| (a, b)).collect(),
                        None if bv.is_null() => {}
                        None => d.push(
                            ErrorKind::Structure,
                            Some(bv.span),
                            format!("`inputs` of node `{id}` must map input ports to `node.port`"),
                        ),
                    }
                }
                "per_frame" => match bv.as_str().map(|t| resolve_scalar(t, true)) {
                    Some(Scalar::Bool(b)) => raw.per_frame = Some((b, bv.span)),
                    _ => d.push(
                        ErrorKind::Structure,
                        Some(bv.span),
                        "`per_frame` must be true or false",
                    ),
                },
                "doc" | "label" | "description" => {}
                other => d.push_help(
                    ErrorKind::Structure,
                    Some(bk.span),
                    format!("unknown key `{other}` in node `{id}`"),
                    suggest(other, ["type", "params", "inputs", "per_frame", "doc"]),
                ),
            }
        }
        let Some(type_y) = type_y else {
            d.push(
                ErrorKind::Structure,
                Some(k.span),
                format!("node `{id}` has no `type`"),
            );
            raws.push(raw);
            continue;
        };
        let type_name = type_y.as_str().unwrap_or("");
        let Some(node) = registry.node(type_name) else {
            let (message, help) = match registry.unavailable(type_name) {
                Some(why) => (
                    format!("unknown node type `{type_name}` for node `{id}`: {why}"),
                    None,
                ),
                None => (
                    format!("unknown node type `{type_name}` for node `{id}`"),
                    suggest(type_name, registry.nodes().map(|n| n.spec().name))
                        .or(Some("`vfxgraph nodes` lists the node types".to_string())),
                ),
            };
            d.push_help(ErrorKind::UnknownNodeType, Some(type_y.span), message, help);
            raws.push(raw);
            continue;
        };
        let spec = node.spec();
        raw.node = Some(node.clone());

        // Params from the file, then overrides, then defaults.
        let mut given: BTreeMap<String, (ParamValue, Option<Span>)> = BTreeMap::new();
        if let Some(py) = params_y {
            match py.as_map() {
                Some(m) => {
                    for (pk, pv) in m {
                        let pname = pk.as_str().unwrap_or("");
                        let Some(ps) = spec.param_spec(pname) else {
                            d.push_help(
                                ErrorKind::UnknownParam,
                                Some(pk.span),
                                format!("node `{id}` ({}) has no parameter `{pname}`", spec.name),
                                suggest(pname, spec.params.iter().map(|p| p.name)),
                            );
                            continue;
                        };
                        match ParamValue::from_yaml(pv) {
                            Ok(v) => {
                                given.insert(ps.name.to_string(), (v, Some(pv.span)));
                            }
                            Err(e) => d.push(
                                ErrorKind::ParamType,
                                Some(pv.span),
                                format!("parameter `{pname}` of node `{id}`: {e}"),
                            ),
                        }
                    }
                }
                None if py.is_null() => {}
                None => d.push(
                    ErrorKind::Structure,
                    Some(py.span),
                    format!("`params` of node `{id}` must be a mapping"),
                ),
            }
        }
        for (pname, (v, span)) in given {
            let ps = spec.param_spec(&pname).expect("checked above");
            check_param(&mut d, id, &pname, &ps.ty, v, span, &mut raw.params);
        }
        raws.push(raw);
    }

    // Overrides: --set node.param=value.
    for s in &overrides.set {
        let Some((lhs, value)) = s.split_once('=') else {
            d.push(
                ErrorKind::Override,
                None,
                format!("--set `{s}`: expected node.param=value"),
            );
            continue;
        };
        let Some((nid, pname)) = lhs.split_once('.') else {
            d.push(
                ErrorKind::Override,
                None,
                format!("--set `{s}`: expected node.param=value"),
            );
            continue;
        };
        let Some(raw) = raws.iter_mut().find(|r| r.id == nid) else {
            d.push_help(
                ErrorKind::Override,
                None,
                format!("--set `{s}`: no node `{nid}` in the graph"),
                suggest(nid, first_seen.keys().map(String::as_str)),
            );
            continue;
        };
        let Some(node) = &raw.node else { continue };
        let spec = node.spec();
        let Some(ps) = spec.param_spec(pname) else {
            d.push_help(
                ErrorKind::Override,
                None,
                format!(
                    "--set `{s}`: node `{nid}` ({}) has no parameter `{pname}`",
                    spec.name
                ),
                suggest(pname, spec.params.iter().map(|p| p.name)),
            );
            continue;
        };
        match ParamValue::parse_cli(value) {
            Ok(v) => match ps.ty.check(v) {
                Ok(v) => {
                    raw.params.insert(pname.to_string(), v);
                }
                Err(ParamCheck::Type(e) | ParamCheck::Range(e)) => {
                    d.push(ErrorKind::Override, None, format!("--set `{s}`: {e}"))
                }
            },
            Err(e) => d.push(ErrorKind::Override, None, format!("--set `{s}`: {e}")),
        }
    }

    // Defaults and missing required params.
    for raw in &mut raws {
        let Some(node) = &raw.node else { continue };
        for ps in &node.spec().params {
            if raw.params.contains_key(ps.name) {
                continue;
            }
            match &ps.default {
                Some(v) => {
                    raw.params.insert(ps.name.to_string(), v.clone());
                }
                None => d.push(
                    ErrorKind::MissingParam,
                    Some(raw.id_span),
                    format!(
                        "node `{}` ({}) needs parameter `{}` ({})",
                        raw.id,
                        node.spec().name,
                        ps.name,
                        ps.ty
                    ),
                ),
            }
        }
    }

    // Pass 2: input references.
    let index: HashMap<&str, usize> = raws
        .iter()
        .enumerate()
        .map(|(i, r)| (r.id.as_str(), i))
        .collect();
    let mut edges: Vec<Vec<(Edge, Span)>> = vec![Vec::new(); raws.len()];
    for (i, raw) in raws.iter().enumerate() {
        let Some(node) = &raw.node else { continue };
        let spec = node.spec();
        for (ik, iv) in &raw.inputs {
            let port_name = ik.as_str().unwrap_or("");
            let Some(port) = spec.inputs.iter().find(|p| p.name == port_name) else {
                d.push_help(
                    ErrorKind::UnknownPort,
                    Some(ik.span),
                    format!(
                        "node `{}` ({}) has no input port `{port_name}`",
                        raw.id, spec.name
                    ),
                    suggest(port_name, spec.inputs.iter().map(|p| p.name)).or_else(|| {
                        Some(format!(
                            "its inputs are: {}",
                            spec.inputs
                                .iter()
                                .map(|p| p.name)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ))
                    }),
                );
                continue;
            };
            let Some(reference) = iv.as_str() else {
                d.push(
                    ErrorKind::Structure,
                    Some(iv.span),
                    "an input is written `node.port`",
                );
                continue;
            };
            let Some((src_id, src_port)) = reference.split_once('.') else {
                d.push(
                    ErrorKind::Structure,
                    Some(iv.span),
                    format!(
                        "input `{port_name}` of node `{}`: write `node.port`, found `{reference}`",
                        raw.id
                    ),
                );
                continue;
            };
            let Some(&j) = index.get(src_id) else {
                d.push_help(
                    ErrorKind::DanglingReference,
                    Some(iv.span),
                    format!(
                        "input `{port_name}` of node `{}` refers to node `{src_id}`, which does not exist",
                        raw.id
                    ),
                    suggest(src_id, index.keys().copied()),
                );
                continue;
            };
            let Some(src_node) = &raws[j].node else {
                continue;
            };
            let Some(out) = src_node.spec().outputs.iter().find(|p| p.name == src_port) else {
                d.push_help(
                    ErrorKind::UnknownPort,
                    Some(iv.span),
                    format!(
                        "node `{src_id}` ({}) has no output port `{src_port}`",
                        src_node.spec().name
                    ),
                    suggest(src_port, src_node.spec().outputs.iter().map(|p| p.name)),
                );
                continue;
            };
            edges[i].push((
                Edge {
                    port: port.name,
                    from: j,
                    from_port: out.name,
                    whole_sequence: port.sequence,
                },
                iv.span,
            ));
        }
        for p in &spec.inputs {
            let connected = raw.inputs.iter().any(|(k, _)| k.as_str() == Some(p.name));
            if !p.optional && !connected {
                d.push(
                    ErrorKind::MissingInput,
                    Some(raw.id_span),
                    format!(
                        "node `{}` ({}) needs input `{}` ({})",
                        raw.id,
                        spec.name,
                        p.name,
                        p.display_type()
                    ),
                );
            }
        }
    }

    // Cycles.
    let mut g: DiGraphMap<usize, ()> = DiGraphMap::new();
    for i in 0..raws.len() {
        g.add_node(i);
    }
    for (i, es) in edges.iter().enumerate() {
        for (e, _) in es {
            g.add_edge(e.from, i, ());
        }
    }
    let sccs = tarjan_scc(&g);
    let mut cyclic = vec![false; raws.len()];
    for scc in &sccs {
        let self_loop = scc.len() == 1 && g.contains_edge(scc[0], scc[0]);
        if scc.len() > 1 || self_loop {
            let mut members: Vec<usize> = scc.clone();
            members.sort_unstable();
            for &m in &members {
                cyclic[m] = true;
            }
            let names: Vec<&str> = members.iter().map(|&m| raws[m].id.as_str()).collect();
            let first = members[0];
            let span = edges[first]
                .iter()
                .find(|(e, _)| members.contains(&e.from))
                .map(|(_, s)| *s)
                .unwrap_or(raws[first].id_span);
            d.push(
                ErrorKind::Cycle,
                Some(span),
                format!("the graph has a cycle through nodes {}", names.join(" → ")),
            );
        }
    }
    // Topological order that keeps the file's order where dependencies allow (Kahn's
    // algorithm, always taking the earliest-declared ready node); nodes on cycles go last.
    let order: Vec<usize> = {
        let n = raws.len();
        let mut indegree = vec![0usize; n];
        let mut consumers: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, es) in edges.iter().enumerate() {
            for (e, _) in es {
                indegree[i] += 1;
                consumers[e.from].push(i);
            }
        }
        let mut ready: BinaryHeap<Reverse<usize>> =
            (0..n).filter(|&i| indegree[i] == 0).map(Reverse).collect();
        let mut order = Vec::with_capacity(n);
        while let Some(Reverse(i)) = ready.pop() {
            order.push(i);
            for &c in &consumers[i] {
                indegree[c] -= 1;
                if indegree[c] == 0 {
                    ready.push(Reverse(c));
                }
            }
        }
        order.extend((0..n).filter(|&i| cyclic[i]));
        order
    };

    // Per-frame resolution and type checks, in topological order.
    let mut per_frame = vec![false; raws.len()];
    for &i in &order {
        let raw = &raws[i];
        let Some(node) = &raw.node else { continue };
        if cyclic[i] {
            continue;
        }
        let spec = node.spec();
        // Either-mode nodes run per frame when fed one frame of a sequence, or when a path
        // parameter holds a frame pattern (`%04d`, `####`).
        let inferred = edges[i]
            .iter()
            .any(|(e, _)| !e.whole_sequence && per_frame[e.from])
            || spec.params.iter().any(|p| {
                matches!(p.ty, crate::param::ParamType::Path(_))
                    && matches!(raw.params.get(p.name), Some(ParamValue::Str(s)) if has_frame_pattern(s))
            });
        per_frame[i] = match (spec.mode, raw.per_frame) {
            (Mode::Once, Some((true, sp))) => {
                d.push(
                    ErrorKind::Structure,
                    Some(sp),
                    format!("node type `{}` cannot run per frame", spec.name),
                );
                false
            }
            (Mode::PerFrame, Some((false, sp))) => {
                d.push(
                    ErrorKind::Structure,
                    Some(sp),
                    format!("node type `{}` always runs per frame", spec.name),
                );
                true
            }
            (Mode::Once, _) => false,
            (Mode::PerFrame, _) => true,
            (Mode::Either, Some((b, _))) => b,
            (Mode::Either, None) => inferred,
        };
        for (e, span) in &edges[i] {
            let Some(src) = &raws[e.from].node else {
                continue;
            };
            let out = src
                .spec()
                .outputs
                .iter()
                .find(|p| p.name == e.from_port)
                .expect("checked");
            let port = spec
                .inputs
                .iter()
                .find(|p| p.name == e.port)
                .expect("checked");
            let src_type = if per_frame[e.from] {
                format!("sequence<{}>", out.ty)
            } else {
                out.ty.to_string()
            };
            let fits = out.ty == port.ty
                && if port.sequence {
                    per_frame[e.from]
                } else {
                    !per_frame[e.from] || per_frame[i]
                };
            if !fits {
                let mut msg = format!(
                    "type mismatch: input `{}` of node `{}` takes {}, but `{}.{}` gives {}",
                    e.port,
                    raw.id,
                    port.display_type(),
                    raws[e.from].id,
                    e.from_port,
                    src_type
                );
                if out.ty == port.ty && !port.sequence && per_frame[e.from] {
                    msg.push_str(" (a node that runs once cannot take one frame of a sequence)");
                }
                d.push(ErrorKind::TypeMismatch, Some(*span), msg);
            }
        }
        if per_frame[i] && frames.is_empty() && !d.items.iter().any(|x| x.kind == ErrorKind::Frames)
        {
            d.push(
                ErrorKind::Frames,
                Some(raw.id_span),
                format!(
                    "node `{}` runs per frame, but the graph has no `frames:` range",
                    raw.id
                ),
            );
        }
    }

    if !d.is_empty() {
        d.sort();
        return Err(d);
    }

    // Build the checked graph in topological order.
    let mut new_index = vec![0usize; raws.len()];
    for (pos, &i) in order.iter().enumerate() {
        new_index[i] = pos;
    }
    let mut nodes = Vec::with_capacity(raws.len());
    for &i in &order {
        let raw = &raws[i];
        let mut inputs: Vec<Edge> = edges[i]
            .iter()
            .map(|(e, _)| Edge {
                from: new_index[e.from],
                ..e.clone()
            })
            .collect();
        inputs.sort_by_key(|e| e.port);
        nodes.push(GraphNode {
            id: raw.id.clone(),
            node: raw.node.clone().expect("valid graph"),
            params: Params::new(raw.params.clone()),
            per_frame: per_frame[i],
            inputs,
            span: raw.id_span,
        });
    }
    Ok(Graph {
        file: path.to_path_buf(),
        dir,
        source,
        frames,
        seed,
        nodes,
    })
}

fn check_param(
    d: &mut Diagnostics,
    id: &str,
    pname: &str,
    ty: &crate::param::ParamType,
    v: ParamValue,
    span: Option<Span>,
    out: &mut BTreeMap<String, ParamValue>,
) {
    match ty.check(v) {
        Ok(v) => {
            out.insert(pname.to_string(), v);
        }
        Err(ParamCheck::Type(e)) => d.push(
            ErrorKind::ParamType,
            span,
            format!("parameter `{pname}` of node `{id}`: {e}"),
        ),
        Err(ParamCheck::Range(e)) => d.push(
            ErrorKind::ParamRange,
            span,
            format!("parameter `{pname}` of node `{id}`: {e}"),
        ),
    }
}
