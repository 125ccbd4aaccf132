//! The top-level document: `version`, `frames` (or `--frames`), `seed`, `defaults`, and the
//! `nodes` mapping whose entries the other passes read.

use super::Overrides;
use crate::diagnostic::Span;
use crate::diagnostic::{suggest, Diagnostics, ErrorKind};
use crate::frames::FrameSet;
use crate::param::{self, ParamValue};
use crate::yaml::{resolve_scalar, Scalar, Yaml};

/// The checked top level of a graph file.
pub(super) struct Document<'y> {
    /// The graph's frames (`--frames` wins over the file's).
    pub(super) frames: FrameSet,
    pub(super) seed: u64,
    /// `defaults:`, parameter name to value as written, with where: the value of that
    /// parameter in every node that has it and does not set it.
    pub(super) defaults: Vec<(String, ParamValue, Span)>,
    /// The entries of `nodes:`, node id to node.
    pub(super) nodes: &'y [(Yaml, Yaml)],
}

/// The values of the top-level keys, as written.
#[derive(Default)]
struct TopKeys<'y> {
    version: Option<&'y Yaml>,
    frames: Option<&'y Yaml>,
    seed: u64,
    defaults: Option<&'y Yaml>,
    nodes: Option<&'y Yaml>,
}

/// Reads the top level of `root`; `None` if there are no node entries to check further.
pub(super) fn read<'y>(
    root: &'y Yaml,
    overrides: &Overrides,
    d: &mut Diagnostics,
) -> Option<Document<'y>> {
    let Some(top) = root.as_map() else {
        d.push(
            ErrorKind::Structure,
            Some(root.span),
            format!(
                "a graph file is a mapping with `version` and `nodes`, found {}",
                root.shape()
            ),
        );
        return None;
    };
    let keys = top_keys(top, d);
    check_version(root, keys.version, d);
    let frames = frames(overrides, keys.frames, d);
    let defaults = defaults(keys.defaults, d);
    let nodes = node_entries(root, keys.nodes, d)?;
    Some(Document {
        frames,
        seed: keys.seed,
        defaults,
        nodes,
    })
}

/// Sorts the top-level keys out; the seed is checked here, unknown keys reported.
fn top_keys<'y>(top: &'y [(Yaml, Yaml)], d: &mut Diagnostics) -> TopKeys<'y> {
    let mut keys = TopKeys::default();
    for (k, v) in top {
        match k.as_str().unwrap_or("") {
            "version" => keys.version = Some(v),
            "frames" => keys.frames = Some(v),
            "seed" => match v.as_str().map(|t| resolve_scalar(t, true)) {
                Some(Scalar::Int(s)) if s >= 0 => keys.seed = s as u64,
                _ => d.push(
                    ErrorKind::Structure,
                    Some(v.span),
                    "`seed` must be a non-negative integer",
                ),
            },
            "nodes" => keys.nodes = Some(v),
            "defaults" => keys.defaults = Some(v),
            "description" | "doc" => {}
            other => d.push_help(
                ErrorKind::Structure,
                Some(k.span),
                format!("unknown top-level key `{other}`"),
                suggest(
                    other,
                    [
                        "version",
                        "frames",
                        "seed",
                        "defaults",
                        "nodes",
                        "description",
                    ],
                ),
            ),
        }
    }
    keys
}

/// The entries of `defaults:` (a mapping of parameter names to values), as written; each is
/// checked against the parameters it reaches when the nodes are read.
fn defaults(y: Option<&Yaml>, d: &mut Diagnostics) -> Vec<(String, ParamValue, Span)> {
    let Some(y) = y else { return Vec::new() };
    let Some(m) = y.as_map() else {
        if !y.is_null() {
            d.push(
                ErrorKind::Structure,
                Some(y.span),
                "`defaults` is a mapping of parameter names to values, the value of that \
                 parameter in every node that has it and does not set it",
            );
        }
        return Vec::new();
    };
    let mut out = Vec::new();
    for (k, v) in m {
        let name = k.as_str().unwrap_or("");
        match param::from_yaml(v) {
            Ok(pv) => out.push((name.to_string(), pv, v.span)),
            Err(e) => d.push(
                ErrorKind::ParamType,
                Some(v.span),
                format!("default of parameter `{name}`: {e}"),
            ),
        }
    }
    out
}

/// Checks that the file says `version: 1`.
fn check_version(root: &Yaml, version: Option<&Yaml>, d: &mut Diagnostics) {
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
}

/// The graph's frames: `--frames` if given, else the file's `frames:`, else none.
fn frames(overrides: &Overrides, frames_y: Option<&Yaml>, d: &mut Diagnostics) -> FrameSet {
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
    frames
}

/// The entries of the `nodes:` mapping, or `None` (reported) if it is missing or not one.
fn node_entries<'y>(
    root: &Yaml,
    nodes_y: Option<&'y Yaml>,
    d: &mut Diagnostics,
) -> Option<&'y [(Yaml, Yaml)]> {
    let Some(nodes_y) = nodes_y else {
        d.push(
            ErrorKind::Structure,
            Some(root.span),
            "missing `nodes:` mapping",
        );
        return None;
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
        return None;
    };
    Some(node_entries)
}
